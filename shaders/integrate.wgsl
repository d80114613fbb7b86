// The integration method of src/method/ (its twin: same names, same order, same event rules;
// the tangent functions are those of src/method/tangent.rs), one invocation per parameter
// point. Read the Rust side for the reasoning; comments here
// only note what differs in form.
//
// The host prepends `alias F = f32;` or `alias F = f64;`, the constants (MODE_*, EV_*, slots
// U_*, R_*, Y_*, C_*, codes VARY_*) and the `Control` uniform, all generated from
// src/gpu/layout.rs, so nothing of the host/kernel contract is declared here. In F only
// + - * / sqrt, comparisons and conversions are used (no cos/exp: unreliable in f64 on some
// drivers): the forcing comes from a host-computed table, and abs/min/max are selects.

// Rungs of the kernel ladder (`rattle bench --ladder`): each piece of the kernel can be left
// out at pipeline creation, so that a rung is compiled without the pieces above it (on
// llvmpipe the code present costs even where it does not run). The production kernel has
// every piece (the defaults); without LADDER_QUIET every step goes through `step`.
override LADDER_FINITE: bool = true;
override LADDER_DETECTOR: bool = true;
override LADDER_GUARDS: bool = true;
override LADDER_EVENTS: bool = true;
override LADDER_QUIET: bool = true;
// Every point of the job has Coulomb friction (l1 = l2 = 0, fs = fk): the law is fk, bit for
// bit for any finite slip speed, without the division the general law needs in every stage.
override COULOMB: bool = false;
// The job estimates the largest Lyapunov exponent: one tangent vector follows the state through
// its RK4 stages and events (tangent.rs `Leading`). Off, none of its code is compiled in, so the
// plain kernel computes and costs what it did without it.
override TANGENT: bool = false;
// The quiet loop reads the step ends from `utab` (set by the host on CPU adapters, for jobs
// with fewer than UTAB_LEN steps per period).
override UNIFORM_TABLE: bool = false;

@group(0) @binding(0) var<uniform> ctl: Control;
@group(0) @binding(1) var<storage, read> consts: array<F>;
@group(0) @binding(2) var<storage, read> pvals: array<F>;
@group(0) @binding(3) var<storage, read_write> ys: array<F>;
@group(0) @binding(4) var<storage, read_write> us: array<u32>;
@group(0) @binding(5) var<storage, read_write> samples: array<F>;
@group(0) @binding(6) var<storage, read_write> ring: array<F>;
// The forcing table's entries 2k and 2k + 1 (step end k, middle of step k + 1) in a uniform
// buffer, read where UNIFORM_TABLE: on llvmpipe a storage read at a per-lane index runs a loop
// over the lanes, a uniform read is one gather instruction. On GPUs a uniform read at
// divergent indices is serialized, so there the table stays in storage.
@group(0) @binding(7) var<uniform> utab: array<vec4<F>, UTAB_LEN>;

// Parameters of this point (model.rs `Params`); scalars rather than an array so that the
// per-point override below does not force every access through dynamically indexed memory.
struct Params {
    eta: F,
    restitution: F,
    fs: F,
    fk: F,
    l1: F,
    l2: F,
    r: F,
    delta: F,
    b1: F,
    mu: F,
}
var<private> prm: Params;
var<private> h: F;
var<private> dphi: F;
var<private> zeno: F;
var<private> tol: F;
// model.rs `inv_mu`, `inv_one_plus_mu`: the field multiplies where it would divide.
var<private> inv_mu: F;
var<private> inv_1pmu: F;
// cos and sin of half a step's forcing phase (method.rs `half_step`).
var<private> half: vec2<F>;

struct PointState {
    y: vec4<F>,
    mode: u32,
    impacts: u32,
    sticks: u32,
    locks: u32,
    overflows: u32,
    nonfinite: u32,
}
var<private> st: PointState;

fn eta() -> F { return prm.eta; }
fn restitution() -> F { return prm.restitution; }
fn fs() -> F { return prm.fs; }
fn fk() -> F { return prm.fk; }
fn l1() -> F { return prm.l1; }
fn l2() -> F { return prm.l2; }
fn r() -> F { return prm.r; }
fn delta() -> F { return prm.delta; }
fn b1() -> F { return prm.b1; }
fn mu() -> F { return prm.mu; }

fn fabs(x: F) -> F { return select(-x, x, x >= F(0.0)); }
fn fmax(a: F, b: F) -> F { return select(b, a, a > b); }
fn fmin(a: F, b: F) -> F { return select(b, a, a < b); }

// ---- model.rs ----

fn is_slip(mode: u32) -> bool { return mode <= MODE_SLIP_NEG; }

fn slip(s: F) -> u32 { return select(MODE_SLIP_NEG, MODE_SLIP_POS, s > F(0.0)); }

// model.rs `friction`: the Stribeck law as a smooth function of the signed slip speed w.
fn friction(w: F) -> F {
    if (COULOMB) {
        return fk();
    }
    return (fs() - fk()) / fmax(F(1.0) + l1() * w, F(0.5)) + fk() + l2() * w * w;
}

// model.rs `friction_slope`: d friction / dw, zero where the divisor is clamped.
fn friction_slope(w: F) -> F {
    if (COULOMB) {
        return F(0.0);
    }
    let q = F(1.0) + l1() * w;
    let decay = select(F(0.0), -(fs() - fk()) * l1() / (q * q), q > F(0.5));
    return decay + F(2.0) * l2() * w;
}

// Both modes' values, then a select: llvmpipe runs both arms of a branch on the mode anyway
// (with lane masks), and the select saves the masking (about +3% steps/s).
fn field(y: vec4<F>, mode: u32, c: F) -> vec4<F> {
    let v = y.y - y.w;
    // Friction direction s of a slip mode; the law is evaluated at the signed speed s*v.
    let s = select(F(-1.0), F(1.0), mode == MODE_SLIP_POS);
    let t = s * friction(s * v);
    let d = b1() * delta() * v;
    // Stick or lock: the masses move together with one acceleration, so v stays exactly 0.
    let a = (c - b1() * y.y - y.x) * inv_1pmu;
    let slip = is_slip(mode);
    return vec4<F>(y.y, select(a, c - b1() * y.y - y.x - d - t, slip), y.w,
                   select(a, (d + t) * inv_mu, slip));
}

// model.rs `jacobian_times`: J(y) x, the field's Jacobian in a fixed mode times x.
fn jacobian_times(y: vec4<F>, mode: u32, x: vec4<F>) -> vec4<F> {
    if (is_slip(mode)) {
        let s = select(F(-1.0), F(1.0), mode == MODE_SLIP_POS);
        let e = b1() * delta() + friction_slope(s * (y.y - y.w));
        let rel = e * (x.y - x.w);
        return vec4<F>(x.y, -x.x - b1() * x.y - rel, x.w, rel / mu());
    }
    let a = -(x.x + b1() * x.y) / (F(1.0) + mu());
    return vec4<F>(x.y, a, x.w, a);
}

fn needed_force(y: vec4<F>, c: F) -> F {
    return mu() * (c - b1() * y.y - y.x) * inv_1pmu;
}

fn needed_force_rate(y: vec4<F>, a: F, sn: F) -> F {
    return mu() * (-eta() * sn - b1() * a - y.y) * inv_1pmu;
}

fn impact(y: vec4<F>) -> vec4<F> {
    let inv = inv_1pmu;
    let vc = (y.y + mu() * y.w) * inv;
    let w = restitution() * (y.y - y.w);
    return vec4<F>(y.x, vc - mu() * inv * w, y.z, vc + inv * w);
}

fn co_move(y: vec4<F>) -> vec4<F> {
    let vc = (y.y + mu() * y.w) / (F(1.0) + mu());
    return vec4<F>(y.x, vc, y.z, vc);
}

fn mode_at_rest(stop: i32, tn: F) -> u32 {
    if (stop > 0) {
        return select(MODE_SLIP_POS, MODE_LOCK_POS, tn <= fs());
    }
    if (stop < 0) {
        return select(MODE_SLIP_NEG, MODE_LOCK_NEG, tn >= -fs());
    }
    if (fabs(tn) <= fs()) {
        return MODE_STICK;
    }
    return slip(tn);
}

// ---- method.rs ----

fn cos_sin_small(d: F) -> vec2<F> {
    let d2 = d * d;
    let o = F(1.0);
    let c = o - d2 / F(2.0) * (o - d2 / F(12.0) * (o - d2 / F(30.0) * (o - d2 / F(56.0)
        * (o - d2 / F(90.0) * (o - d2 / F(132.0))))));
    let s = d * (o - d2 / F(6.0) * (o - d2 / F(20.0) * (o - d2 / F(42.0) * (o - d2 / F(72.0)
        * (o - d2 / F(110.0))))));
    return vec2<F>(c, s);
}

fn hermite(a0: F, a1: F, a2: F, a3: F, t: F) -> F {
    return a0 + t * (a1 + t * (a2 + t * a3));
}

struct Bracket {
    a0: F,
    a1: F,
    a2: F,
    a3: F,
    lo: F,
    hi: F,
    plo: F,
    phi: F,
    ev: u32,
}

fn no_bracket() -> Bracket {
    return Bracket(F(0.0), F(0.0), F(0.0), F(0.0), F(2.0), F(2.0), F(0.0), F(0.0), EV_NONE);
}

fn bracket(g0: F, g1: F, m0: F, m1: F, ev: u32) -> Bracket {
    let d = g1 - g0;
    let bound = F(0.25) * fmax(fabs(m0 - d), fabs(m1 - d));
    if (fmin(g0, g1) > bound || fmax(g0, g1) < -bound) {
        return no_bracket();
    }
    let a1 = m0;
    let a2 = F(3.0) * d - F(2.0) * m0 - m1;
    let a3 = m0 + m1 - F(2.0) * d;
    let qa = F(3.0) * a3;
    let qb = F(2.0) * a2;
    let none = F(2.0);
    var t1 = none;
    var t2 = none;
    if (qa != F(0.0)) {
        let disc = qb * qb - F(4.0) * qa * a1;
        if (disc >= F(0.0)) {
            let sq = sqrt(disc);
            var q = F(-0.5) * (qb - sq);
            if (qb >= F(0.0)) {
                q = F(-0.5) * (qb + sq);
            }
            t1 = q / qa;
            t2 = select(t1, a1 / q, q != F(0.0));
        }
    } else if (qb != F(0.0)) {
        t1 = -a1 / qb;
    }
    if (t1 > t2) {
        let t = t1;
        t1 = t2;
        t2 = t;
    }
    // The three monotone pieces, unrolled: llvmpipe caps the loop iterations of one
    // invocation, so the hot path has no loops with a small fixed trip count.
    let b1 = select(F(1.0), t1, t1 > F(0.0) && t1 < F(1.0));
    let b2 = select(F(1.0), t2, t2 > b1 && t2 < F(1.0));
    let p1 = hermite(g0, a1, a2, a3, b1);
    if (g0 > F(0.0) && p1 <= F(0.0)) {
        return Bracket(g0, a1, a2, a3, F(0.0), b1, g0, p1, ev);
    }
    if (b1 >= F(1.0)) {
        return no_bracket();
    }
    let p2 = hermite(g0, a1, a2, a3, b2);
    if (p1 > F(0.0) && p2 <= F(0.0)) {
        return Bracket(g0, a1, a2, a3, b1, b2, p1, p2, ev);
    }
    if (b2 >= F(1.0)) {
        return no_bracket();
    }
    let p3 = hermite(g0, a1, a2, a3, F(1.0));
    if (p2 > F(0.0) && p3 <= F(0.0)) {
        return Bracket(g0, a1, a2, a3, b2, F(1.0), p2, p3, ev);
    }
    return no_bracket();
}

fn illinois(b: Bracket) -> F {
    var lo = b.lo;
    var hi = b.hi;
    var plo = b.plo;
    var phi = b.phi;
    var side = 0;
    for (var it = 0u; it < MAX_ROOT_ITERS; it++) {
        if (hi - lo <= tol) {
            break;
        }
        var m = (lo * phi - hi * plo) / (phi - plo);
        if (!(m > lo && m < hi)) {
            m = F(0.5) * (lo + hi);
        }
        let pm = hermite(b.a0, b.a1, b.a2, b.a3, m);
        if (pm <= F(0.0)) {
            hi = m;
            phi = pm;
            if (side == -1) {
                plo = plo * F(0.5);
            }
            side = -1;
            if (pm == F(0.0)) {
                break;
            }
        } else {
            lo = m;
            plo = pm;
            if (side == 1) {
                phi = phi * F(0.5);
            }
            side = 1;
        }
    }
    return hi;
}

fn forcing(k: u32, theta: F) -> vec2<F> {
    let t2 = theta * F(2.0);
    let jf = u32(t2);
    let j = min(2u * k + jf, 2u * ctl.steps);
    let cj = consts[C_TABLE + 2u * j];
    let sj = consts[C_TABLE + 2u * j + 1u];
    let rem = (t2 - F(jf)) * F(0.5);
    if (rem == F(0.0)) {
        return vec2<F>(cj, sj);
    }
    let cs = cos_sin_small(rem * dphi);
    return vec2<F>(cj * cs.x - sj * cs.y, sj * cs.x + cj * cs.y);
}

// Stage points 2-4 of the last RK4 step (the first is its start): the tangent evaluates its
// Jacobian there.
var<private> stage1: vec4<F>;
var<private> stage2: vec4<F>;
var<private> stage3: vec4<F>;

// method.rs `rk4_stages` (its `rk4` is the same without the stages). c2, c4: forcing at the
// middle and the end of the (sub)step, computed by the caller.
fn rk4_stages(y: vec4<F>, mode: u32, dt: F, k1: vec4<F>, c2: F, c4: F) -> vec4<F> {
    let half = F(0.5) * dt;
    let s1 = y + half * k1;
    let k2 = field(s1, mode, c2);
    let s2 = y + half * k2;
    let k3 = field(s2, mode, c2);
    let s3 = y + dt * k3;
    let k4 = field(s3, mode, c4);
    if (TANGENT) {
        stage1 = s1;
        stage2 = s2;
        stage3 = s3;
    }
    let sixth = dt / F(6.0);
    return y + sixth * (k1 + F(2.0) * (k2 + k3) + k4);
}

struct Hit {
    t: F,
    ev: u32,
}

// cs0, cs1: forcing (cos, sin) at the start and the end of the step.
fn locate(y0: vec4<F>, y1: vec4<F>, f0: vec4<F>, f1: vec4<F>, mode: u32, cs0: vec2<F>,
          cs1: vec2<F>, dtheta: F) -> Hit {
    let dt = dtheta * h;
    // Up to three guards: (impact+, impact-, reversal) in slip, (release+, release-) else.
    var b0 = no_bracket();
    var b1 = no_bracket();
    var b2 = no_bracket();
    if (is_slip(mode)) {
        if (ctl.naive == 0u) {
            let z0 = y0.z - y0.x;
            let z1 = y1.z - y1.x;
            let zd0 = (y0.w - y0.y) * dt;
            let zd1 = (y1.w - y1.y) * dt;
            if (r() - z0 <= F(0.0) && zd0 > F(0.0)) {
                return Hit(F(0.0), EV_IMPACT_POS);
            }
            if (r() + z0 <= F(0.0) && zd0 < F(0.0)) {
                return Hit(F(0.0), EV_IMPACT_NEG);
            }
            b0 = bracket(r() - z0, r() - z1, -zd0, -zd1, EV_IMPACT_POS);
            b1 = bracket(r() + z0, r() + z1, zd0, zd1, EV_IMPACT_NEG);
        }
        let s = select(F(-1.0), F(1.0), mode == MODE_SLIP_POS);
        b2 = bracket(s * (y0.y - y0.w), s * (y1.y - y1.w), s * (f0.y - f0.w) * dt,
                     s * (f1.y - f1.w) * dt, EV_REVERSAL);
    } else {
        let tn0 = needed_force(y0, cs0.x);
        let tn1 = needed_force(y1, cs1.x);
        let td0 = needed_force_rate(y0, f0.y, cs0.y) * dt;
        let td1 = needed_force_rate(y1, f1.y, cs1.y) * dt;
        if (mode != MODE_LOCK_NEG) {
            b0 = bracket(fs() - tn0, fs() - tn1, -td0, -td1, EV_RELEASE_POS);
        }
        if (mode != MODE_LOCK_POS) {
            b1 = bracket(fs() + tn0, fs() + tn1, td0, td1, EV_RELEASE_NEG);
        }
    }
    // Refine brackets in order of their left end while one can still hold an earlier root
    // than the best so far. Almost every step has no bracket and skips this.
    var best = Hit(F(2.0), EV_NONE);
    if (b0.ev == EV_NONE && b1.ev == EV_NONE && b2.ev == EV_NONE) {
        return best;
    }
    for (var round = 0u; round < 3u; round++) {
        var pick = 3u;
        var lo = best.t;
        if (b0.ev != EV_NONE && b0.lo < lo) {
            pick = 0u;
            lo = b0.lo;
        }
        if (b1.ev != EV_NONE && b1.lo < lo) {
            pick = 1u;
            lo = b1.lo;
        }
        if (b2.ev != EV_NONE && b2.lo < lo) {
            pick = 2u;
            lo = b2.lo;
        }
        if (pick == 3u) {
            break;
        }
        var b = b0;
        if (pick == 1u) {
            b = b1;
        } else if (pick == 2u) {
            b = b2;
        }
        let t = illinois(b);
        if (t < best.t) {
            best = Hit(t, b.ev);
        }
        if (pick == 0u) {
            b0.ev = EV_NONE;
        } else if (pick == 1u) {
            b1.ev = EV_NONE;
        } else {
            b2.ev = EV_NONE;
        }
    }
    return best;
}

fn after_impact(stop: i32, c: F) {
    let v = st.y.y - st.y.w;
    if (fabs(v) < zeno) {
        st.y = co_move(st.y);
        st.mode = mode_at_rest(stop, needed_force(st.y, c));
        if (st.mode == MODE_LOCK_POS || st.mode == MODE_LOCK_NEG) {
            st.locks += 1u;
        }
    } else {
        st.mode = slip(v);
    }
}

fn apply_event(ev: u32, c: F) {
    if (ev == EV_IMPACT_POS || ev == EV_IMPACT_NEG) {
        st.y = impact(st.y);
        st.impacts += 1u;
        after_impact(select(-1, 1, ev == EV_IMPACT_POS), c);
    } else if (ev == EV_REVERSAL) {
        st.y = co_move(st.y);
        st.mode = mode_at_rest(0, needed_force(st.y, c));
        if (st.mode == MODE_STICK) {
            st.sticks += 1u;
        }
    } else if (ev == EV_RELEASE_POS) {
        st.mode = MODE_SLIP_POS;
    } else {
        st.mode = MODE_SLIP_NEG;
    }
}

fn naive_impact(k: u32) -> bool {
    if (!is_slip(st.mode)) {
        return false;
    }
    let z = st.y.z - st.y.x;
    let zd = st.y.w - st.y.y;
    var stop = 0;
    if (z > r() && zd > F(0.0)) {
        stop = 1;
    } else if (z < -r() && zd < F(0.0)) {
        stop = -1;
    } else {
        return false;
    }
    st.y.z = st.y.x + select(-r(), r(), stop > 0);
    apply_event(select(EV_IMPACT_NEG, EV_IMPACT_POS, stop > 0), forcing(k, F(1.0)).x);
    return true;
}

// Field at the start of the current step (first-same-as-last), carried between steps.
var<private> f0: vec4<F>;

// One grid step. The loop alternates a trial to the end of the step and, after an event was
// located, the sub-step up to it; written with one call of rk4_stages and of forcing per stage
// (the CPU twin calls them where they are needed), because llvmpipe inlines every call site
// into one function and its size, not the work executed, decides the speed of the whole
// kernel. The tangent advances before the state is overwritten (it needs the step's start).
fn step(k: u32) {
    var theta0 = F(0.0);
    var events = 0u;
    // Sub-step to the located event, as a fraction of the step; < 0 while on a trial.
    var de = F(-1.0);
    var hit = Hit(F(2.0), EV_NONE);
    // Forcing at the start of the (sub)step.
    var cs0 = forcing(k, F(0.0));
    loop {
        let dtheta = F(1.0) - theta0;
        let trial = de < F(0.0);
        let span = select(de, dtheta, trial);
        let c2 = forcing(k, theta0 + F(0.5) * span).x;
        let cs4 = forcing(k, theta0 + span);
        let y1 = rk4_stages(st.y, st.mode, span * h, f0, c2, cs4.x);
        if (trial) {
            // forcing(k, 1) is a table entry: theta0 + dtheta may miss 1 by an ulp.
            let f1 = field(y1, st.mode, consts[C_TABLE + 2u * min(2u * k + 2u, 2u * ctl.steps)]);
            if (LADDER_GUARDS) {
                hit = locate(st.y, y1, f0, f1, st.mode, cs0, cs4, dtheta);
            }
            if (hit.ev == EV_NONE || events >= ctl.max_events || !LADDER_EVENTS) {
                if (hit.ev != EV_NONE) {
                    st.overflows += 1u;
                }
                if (TANGENT && tan_on) {
                    tangent_substep(st.y, st.mode, span * h);
                }
                st.y = y1;
                f0 = f1;
                break;
            }
            de = hit.t * dtheta;
            continue;
        }
        if (TANGENT && tan_on) {
            tangent_substep(st.y, st.mode, span * h);
        }
        st.y = y1;
        let mode_before = st.mode;
        theta0 = select(theta0 + de, F(1.0), hit.t >= F(1.0));
        cs0 = forcing(k, theta0);
        apply_event(hit.ev, cs0.x);
        if (TANGENT && tan_on) {
            tangent_event(hit.ev, y1, mode_before, cs0);
        }
        events += 1u;
        f0 = field(st.y, st.mode, cs0.x);
        de = F(-1.0);
        if (theta0 >= F(1.0)) {
            break;
        }
    }
    if (LADDER_EVENTS && ctl.naive != 0u && naive_impact(k)) {
        f0 = field(st.y, st.mode, forcing(k, F(1.0)).x);
    }
    if (LADDER_FINITE && !finite_state(st.y)) {
        st.nonfinite = 1u;
    }
}

// Finiteness by the bits of the f32 value (f64 values beyond f32's range become infinite and
// fail, as they fail the bound above): NaN and infinity have every exponent bit set. A float
// comparison such as `x != x` is not a NaN test on drivers that assume IEEE special values
// never occur (llvmpipe folds it to false).
fn finite4(y: vec4<F>) -> bool {
    let e = bitcast<vec4<u32>>(vec4<f32>(y)) & vec4<u32>(0x7f800000u);
    return all(e != vec4<u32>(0x7f800000u));
}

// method.rs `clear_of`: the guard g stays above the bound of `bracket` over the whole step, so
// it cannot reach zero there.
fn clear_of(g0: F, g1: F, m0: F, m1: F) -> bool {
    let d = g1 - g0;
    let bound = F(0.25) * fmax(fabs(m0 - d), fabs(m1 - d));
    return fmin(g0, g1) > bound;
}

// events.rs `clear_of_stops`: both impact guards r -+ z stay above the bound of `bracket`
// (their chords have opposite slopes and the same bound).
fn clear_of_stops(z0: F, z1: F, zd0: F, zd1: F) -> bool {
    let d = z1 - z0;
    let bound = F(0.25) * fmax(fabs(zd0 - d), fabs(zd1 - d));
    return r() - fmax(fabs(z0), fabs(z1)) > bound;
}

// method.rs `quiet`: no guard of the mode can reach zero in the full step from y0 to y1, so
// `locate` would find no event and the trial step is the step. `&` rather than `&&`: no
// branches on the hot path.
fn quiet(y0: vec4<F>, y1: vec4<F>, f0: vec4<F>, f1: vec4<F>, mode: u32, cs0: vec2<F>,
         cs1: vec2<F>) -> bool {
    if (ctl.naive != 0u) {
        return false;
    }
    if (is_slip(mode)) {
        let z0 = y0.z - y0.x;
        let z1 = y1.z - y1.x;
        let zd0 = (y0.w - y0.y) * h;
        let zd1 = (y1.w - y1.y) * h;
        let s = select(F(-1.0), F(1.0), mode == MODE_SLIP_POS);
        return clear_of_stops(z0, z1, zd0, zd1)
            & clear_of(s * (y0.y - y0.w), s * (y1.y - y1.w), s * (f0.y - f0.w) * h,
                       s * (f1.y - f1.w) * h);
    }
    let tn0 = needed_force(y0, cs0.x);
    let tn1 = needed_force(y1, cs1.x);
    let td0 = needed_force_rate(y0, f0.y, cs0.y) * h;
    let td1 = needed_force_rate(y1, f1.y, cs1.y) * h;
    return (mode == MODE_LOCK_NEG | clear_of(fs() - tn0, fs() - tn1, -td0, -td1))
        & (mode == MODE_LOCK_POS | clear_of(fs() + tn0, fs() + tn1, td0, td1));
}

// events.rs `mid_step`: the forcing at the middle of a step from the forcing cs at its start,
// as the table's mid-step entries hold it (bit for bit where the compiler does not contract
// the products into fma), without a read of the table.
fn mid_step(cs: vec2<F>) -> vec2<F> {
    return vec2<F>(cs.x * half.x - cs.y * half.y, cs.y * half.x + cs.x * half.y);
}

// Forcing (cos, sin) at the end of step k - 1, the start of step k: table(2k).
fn step_start(k: u32) -> vec2<F> {
    if (UNIFORM_TABLE) {
        return utab[k].xy;
    }
    return table(2u * k);
}

// Forcing (cos, sin) at grid point j (phase j/2 of a step: the table has half steps).
fn table(j: u32) -> vec2<F> {
    let t = min(j, 2u * ctl.steps);
    return vec2<F>(consts[C_TABLE + 2u * t], consts[C_TABLE + 2u * t + 1u]);
}

// NaN or infinity (tested on the bits), or a state beyond any physical scale.
fn finite_state(y: vec4<F>) -> bool {
    let big = F(1e30);
    return finite4(y) && fmax(fmax(fabs(y.x), fabs(y.y)), fmax(fabs(y.z), fabs(y.w))) <= big;
}

// Returns false when the period did not run to its end (non-finite state or a loop cut short).
// Quiet steps (no guard near zero: almost all) run in the inner loop, which holds only the RK4
// step and the guard bounds; a lane leaves it at a step that may hold an event, and that step
// goes through `step`. On SIMD adapters the code of `step` then runs once per event rather
// than masked in every step (method.rs `period_observed` is the twin).
fn period() -> bool {
    f0 = field(st.y, st.mode, forcing(0u, F(0.0)).x);
    var k = 0u;
    loop {
        if (LADDER_QUIET) {
            // Forcing at the start of the step: the end of the step before.
            var cs0 = table(2u * k);
            loop {
                if (k >= ctl.steps) {
                    break;
                }
                let cs1 = step_start(k + 1u);
                // The middle of the step from its start: one table read (a gather: each lane
                // is at its own step) less per step, +7% steps/s.
                let y1 = rk4_stages(st.y, st.mode, h, f0, mid_step(cs0).x, cs1.x);
                let f1 = field(y1, st.mode, cs1.x);
                if (!quiet(st.y, y1, f0, f1, st.mode, cs0, cs1)) {
                    break;
                }
                if (TANGENT && tan_on) {
                    tangent_substep(st.y, st.mode, h);
                }
                st.y = y1;
                f0 = f1;
                cs0 = cs1;
                k++;
            }
        }
        if (k >= ctl.steps) {
            break;
        }
        step(k);
        k++;
        if (st.nonfinite != 0u) {
            return false;
        }
    }
    // The quiet loop has no finiteness test of its own: a non-finite state fails the quiet
    // test (its comparisons are false), so the lane's next step is `step`, which tests it;
    // a state that does not enter any guard (or is finite beyond 1e30) is caught here, at the
    // end of the period (+12% steps/s; the CPU twin tests every step, with the same outcome:
    // the point fails in the same period).
    if (LADDER_FINITE && !finite_state(st.y)) {
        st.nonfinite = 1u;
        return false;
    }
    return k == ctl.steps;
}

// ---- tangent.rs: one tangent vector for the largest Lyapunov exponent (`Leading`) ----

var<private> tvec: vec4<F>;
// The tangent runs in this period (a sampled one, the vector still finite).
var<private> tan_on: bool;

// tangent.rs `Jump`.
const JUMP_IDENTITY: u32 = 0u;
const JUMP_IMPACT: u32 = 1u;
const JUMP_CO_MOVE: u32 = 2u;

fn jump_apply(jump: u32, x: vec4<F>) -> vec4<F> {
    if (jump == JUMP_IMPACT) {
        return impact(x);
    }
    if (jump == JUMP_CO_MOVE) {
        return co_move(x);
    }
    return x;
}

fn dot4(a: vec4<F>, b: vec4<F>) -> F {
    return a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w;
}

// RK4 of the variational equation on the stage points of the state's last RK4 step, from its
// start y (before the state is overwritten).
fn tangent_substep(y: vec4<F>, mode: u32, dt: F) {
    let half = F(0.5) * dt;
    let k1 = jacobian_times(y, mode, tvec);
    let k2 = jacobian_times(stage1, mode, tvec + half * k1);
    let k3 = jacobian_times(stage2, mode, tvec + half * k2);
    let k4 = jacobian_times(stage3, mode, tvec + dt * k3);
    let sixth = dt / F(6.0);
    tvec = tvec + sixth * (k1 + F(2.0) * (k2 + k3) + k4);
}

// The saltation of event ev (tangent.rs `Saltation::at`, then `apply`), called after
// `apply_event`: `before` and `mode_before` are the state just before the jump, `st` the state
// after it, cs the forcing (cos, sin) at the event.
fn tangent_event(ev: u32, before: vec4<F>, mode_before: u32, cs: vec2<F>) {
    let o = F(1.0);
    let z = F(0.0);
    // Release: h = Fs -+ Tn, Tn = kf (c - b1 y2 - y1), time rate -kf eta sin.
    let kf = mu() / (o + mu());
    var jump = JUMP_IDENTITY;
    var n = vec4<F>(kf, kf * b1(), z, z);
    var ht = kf * eta() * cs.y;
    if (ev == EV_IMPACT_POS || ev == EV_IMPACT_NEG) {
        // h = r -+ z; an impact that ended in co-motion (below the Zeno speed) projects.
        let s = select(-o, o, ev == EV_IMPACT_POS);
        jump = select(JUMP_IMPACT, JUMP_CO_MOVE, st.y.y == st.y.w);
        n = vec4<F>(s, z, -s, z);
        ht = z;
    } else if (ev == EV_REVERSAL) {
        let s = select(-o, o, mode_before == MODE_SLIP_POS);
        jump = JUMP_CO_MOVE;
        n = vec4<F>(z, s, z, -s);
        ht = z;
    } else if (ev == EV_RELEASE_NEG) {
        n = -n;
        ht = -ht;
    }
    let fm = field(before, mode_before, cs.x);
    let fp = field(st.y, st.mode, cs.x);
    let u = fp - jump_apply(jump, fm);
    let d = dot4(n, fm) + ht;
    let a = dot4(n, tvec) / d;
    tvec = jump_apply(jump, tvec) + u * a;
}

// Unit length, and the log of the length before, in f32 even in the f64 kernel (f64 log is
// unreliable on some drivers). A collapsed vector restarts along y1 and counts at the floor.
fn tangent_renormalize() -> f32 {
    let norm = sqrt(dot4(tvec, tvec));
    let floor = consts[C_TAN_FLOOR];
    if (norm <= floor) {
        tvec = vec4<F>(F(1.0), F(0.0), F(0.0), F(0.0));
        return log(f32(floor));
    }
    tvec = tvec / norm;
    return log(f32(norm));
}

// ---- classify.rs: PeriodDetector::push on the section value y1 ----

fn detector_push(i: u32, x: F) {
    let n = ctl.n_points;
    let count = us[U_DET_COUNT * n + i];
    var lo = x;
    var hi = x;
    if (count > 0u) {
        lo = fmin(ring[R_LO * n + i], x);
        hi = fmax(ring[R_HI * n + i], x);
    }
    let tl = consts[C_PERIOD_TOL] * fmax(hi - lo, F(1.0));
    var plo = us[U_DET_LO * n + i];
    var phi = us[U_DET_HI * n + i];
    let lags = min(count, MAX_PERIOD);
    for (var m = 1u; m <= lags; m++) {
        let past = ring[((count - m) % TAIL) * n + i];
        if (!(fabs(x - past) <= tl)) {
            if (m <= 32u) {
                plo &= ~(1u << (m - 1u));
            } else {
                phi &= ~(1u << (m - 33u));
            }
        }
    }
    ring[(count % TAIL) * n + i] = x;
    ring[R_LO * n + i] = lo;
    ring[R_HI * n + i] = hi;
    us[U_DET_COUNT * n + i] = count + 1u;
    us[U_DET_LO * n + i] = plo;
    us[U_DET_HI * n + i] = phi;
}

// ---- classify.rs: Growth::push (batch means of the log growth; the sum is log_sum) ----

fn growth_push(i: u32, s: u32, l: F) {
    let n = ctl.n_points;
    let len = max(ctl.samples / BLOCKS, 1u);
    var block = ring[R_BLOCK * n + i] + l;
    if ((s + 1u) % len == 0u) {
        let k = (s + 1u) / len;
        if (k <= BLOCKS) {
            let mean = ring[R_BLOCK_MEAN * n + i];
            let d = block - mean;
            let m = mean + d / F(k);
            ring[R_BLOCK_MEAN * n + i] = m;
            ring[R_BLOCK_M2 * n + i] += d * (block - m);
        }
        block = F(0.0);
    }
    ring[R_BLOCK * n + i] = block;
}

// ---- classify.rs: Birkhoff::push (the torus test; weights in f32 on both sides) ----

fn birkhoff_push(i: u32, s: u32, x: F) {
    let n = ctl.n_points;
    let half = ctl.samples / 2u;
    if (half == 0u || s >= 2u * half) {
        return;
    }
    let t = (f32(s % half) + 1.0) / (f32(half) + 1.0);
    let w = F(exp(f32(-1.0 / (t * (1.0 - t)))));
    let num = ring[R_WB_NUM * n + i] + w * x;
    let den = ring[R_WB_DEN * n + i] + w;
    if (s + 1u == half) {
        ring[R_WB_FIRST * n + i] = num / den;
        ring[R_WB_NUM * n + i] = F(0.0);
        ring[R_WB_DEN * n + i] = F(0.0);
    } else {
        if (s + 1u == 2u * half) {
            ring[R_WB_SECOND * n + i] = num / den;
        }
        ring[R_WB_NUM * n + i] = num;
        ring[R_WB_DEN * n + i] = den;
    }
}

// A vector in `ys` from slot `base` on (Y_MAIN or Y_TAN).
fn load_y(base: u32, i: u32) -> vec4<F> {
    let n = ctl.n_points;
    return vec4<F>(ys[base * n + i], ys[(base + 1u) * n + i], ys[(base + 2u) * n + i],
                   ys[(base + 3u) * n + i]);
}

fn store_y(base: u32, i: u32, y: vec4<F>) {
    let n = ctl.n_points;
    ys[base * n + i] = y.x;
    ys[(base + 1u) * n + i] = y.y;
    ys[(base + 2u) * n + i] = y.z;
    ys[(base + 3u) * n + i] = y.w;
}

fn set_param(code: u32, v: F) {
    switch code {
        case VARY_ETA: { prm.eta = v; }
        case VARY_RESTITUTION: { prm.restitution = v; }
        case VARY_FS: { prm.fs = v; }
        case VARY_FK: { prm.fk = v; }
        case VARY_L1: { prm.l1 = v; }
        case VARY_L2: { prm.l2 = v; }
        case VARY_R: { prm.r = v; }
        case VARY_DELTA: { prm.delta = v; }
        case VARY_B1: { prm.b1 = v; }
        case VARY_MU: { prm.mu = v; }
        case VARY_LAMBDA: {
            prm.fs = v;
            prm.fk = v;
        }
        default: {}
    }
}

@compute @workgroup_size(WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * ctl.row;
    let n = ctl.n_points;
    if (i >= n) {
        return;
    }
    prm = Params(consts[C_ETA], consts[C_RESTITUTION], consts[C_FS], consts[C_FK], consts[C_L1],
                 consts[C_L2], consts[C_R], consts[C_DELTA], consts[C_B1], consts[C_MU]);
    if (ctl.n_vary > 0u) {
        set_param(ctl.vary0, pvals[i * ctl.n_vary]);
    }
    if (ctl.n_vary > 1u) {
        set_param(ctl.vary1, pvals[i * ctl.n_vary + 1u]);
    }
    zeno = consts[C_ZENO];
    tol = consts[C_TOL];
    dphi = consts[C_DPHI];
    half = vec2<F>(consts[C_HALF_COS], consts[C_HALF_SIN]);
    h = dphi / eta();
    inv_mu = F(1.0) / mu();
    inv_1pmu = F(1.0) / (F(1.0) + mu());

    st.y = load_y(Y_MAIN, i);
    st.mode = us[U_MODE * n + i];
    st.impacts = us[U_IMPACTS * n + i];
    st.sticks = us[U_STICKS * n + i];
    st.locks = us[U_LOCKS * n + i];
    st.overflows = us[U_OVERFLOWS * n + i];
    st.nonfinite = us[U_NONFINITE * n + i];
    var sample_impacts = us[U_SAMPLE_IMPACTS * n + i];
    var tan_bad = 1u;
    var log_sum = F(0.0);
    if (TANGENT) {
        tvec = load_y(Y_TAN, i);
        tan_bad = us[U_TAN_BAD * n + i];
        log_sum = ring[R_LOG_SUM * n + i];
    }

    var q = 0u;
    for (; q < ctl.periods; q++) {
        if (st.nonfinite != 0u) {
            break;
        }
        let idx = ctl.period0 + q;
        if (TANGENT && idx == ctl.transient) {
            // The tangent vector starts along y1 with sampling.
            tvec = vec4<F>(F(1.0), F(0.0), F(0.0), F(0.0));
            tan_bad = 0u;
            log_sum = F(0.0);
        }
        tan_on = TANGENT && idx >= ctl.transient && tan_bad == 0u;
        let before = st.impacts;
        if (!period() && st.nonfinite == 0u) {
            us[U_TRUNCATED * n + i] = 1u;
            break;
        }
        if (idx >= ctl.transient && st.nonfinite == 0u) {
            let s = idx - ctl.transient;
            sample_impacts += st.impacts - before;
            if (LADDER_DETECTOR && ctl.store != 0u) {
                let o = (i * ctl.samples + s) * STATE_DIM;
                samples[o] = st.y.x;
                samples[o + 1u] = st.y.y;
                samples[o + 2u] = st.y.z;
                samples[o + 3u] = st.y.w;
            }
            if (LADDER_DETECTOR) {
                detector_push(i, st.y.x);
                birkhoff_push(i, s, st.y.x);
            }
            if (tan_on) {
                if (finite_state(tvec)) {
                    let l = F(tangent_renormalize());
                    log_sum += l;
                    growth_push(i, s, l);
                } else {
                    tan_bad = 1u;
                }
            }
        }
    }
    if (q != ctl.periods && st.nonfinite == 0u) {
        us[U_TRUNCATED * n + i] = 1u;
    }

    store_y(Y_MAIN, i, st.y);
    if (ctl.lyap != 0u) {
        // Without the tangent compiled in (ladder rungs below it) the point has no exponent.
        if (TANGENT) {
            store_y(Y_TAN, i, tvec);
            ring[R_LOG_SUM * n + i] = log_sum;
        }
        us[U_TAN_BAD * n + i] = tan_bad;
    }
    us[U_MODE * n + i] = st.mode;
    us[U_IMPACTS * n + i] = st.impacts;
    us[U_SAMPLE_IMPACTS * n + i] = sample_impacts;
    us[U_STICKS * n + i] = st.sticks;
    us[U_LOCKS * n + i] = st.locks;
    us[U_OVERFLOWS * n + i] = st.overflows;
    us[U_NONFINITE * n + i] = st.nonfinite;
}
