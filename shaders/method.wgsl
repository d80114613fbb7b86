// twin: src/method/mod.rs
// The step and the period: RK4 in the current mode, quiet steps, events, the section.

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

// shader-only: the CPU computes the step ends in its own loop (grid_step).
// Forcing (cos, sin) at the end of step k - 1, the start of step k: table(2k).
fn step_start(k: u32) -> vec2<F> {
    if (UNIFORM_TABLE) {
        return utab[k].xy;
    }
    return table(2u * k);
}

// shader-only: the CPU reads its forcing table as a slice.
// Forcing (cos, sin) at grid point j (phase j/2 of a step: the table has half steps).
fn table(j: u32) -> vec2<F> {
    let t = min(j, 2u * ctl.steps);
    return vec2<F>(consts[C_TABLE + 2u * t], consts[C_TABLE + 2u * t + 1u]);
}

// Stage points 2-4 of the last RK4 step (the first is its start): the tangent evaluates its
// Jacobian there.
var<private> stage1: vec4<F>;
var<private> stage2: vec4<F>;
var<private> stage3: vec4<F>;

// The energy friction dissipated over the last RK4 step (the second value of the twin's
// `rk4_stages`), computed in sampled periods only (`observing`, uniform over the dispatch):
// a transient period's losses are reset where sampling starts.
var<private> stage_work: F;
var<private> observing: bool;

// method/mod.rs `rk4_stages` (its `rk4` is the same without the stages). c2, c4: forcing at the
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
    let out = y + sixth * (k1 + F(2.0) * (k2 + k3) + k4);
    if (observing) {
        let w2 = friction_power(s1, k2);
        let w3 = friction_power(s2, k3);
        let w4 = friction_power(s3, k4);
        let w1 = friction_power(y, k1);
        stage_work = sixth * (w1 + F(2.0) * (w2 + w3) + w4);
    }
    return out;
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
            if (clearance() - z0 <= F(0.0) && zd0 > F(0.0)) {
                return Hit(F(0.0), EV_IMPACT_POS);
            }
            if (clearance() + z0 <= F(0.0) && zd0 < F(0.0)) {
                return Hit(F(0.0), EV_IMPACT_NEG);
            }
            b0 = bracket(clearance() - z0, clearance() - z1, -zd0, -zd1, F(0.0), EV_IMPACT_POS);
            b1 = bracket(clearance() + z0, clearance() + z1, zd0, zd1, F(0.0), EV_IMPACT_NEG);
        }
        let s = select(F(-1.0), F(1.0), mode == MODE_SLIP_POS);
        let g0 = s * (y0.y - y0.w);
        let g1 = s * (y1.y - y1.w);
        let m0 = s * (f0.y - f0.w) * dt;
        // A slip past v = 0, or at it and turning against the mode for the step: a reversal
        // now (method/mod.rs `locate`).
        if (m0 < F(0.0) && (g0 < F(0.0) || (g0 == F(0.0) && g1 < F(0.0)))) {
            return Hit(F(0.0), EV_REVERSAL);
        }
        // v = y2 - y4 rounds at a few units of the velocities' last place (tol = 16 units).
        let floor = F(0.25) * tol * (fabs(y0.y) + fabs(y0.w));
        b2 = bracket(g0, g1, m0, s * (f1.y - f1.w) * dt, floor, EV_REVERSAL);
    } else {
        let tn0 = needed_force(y0, cs0.x);
        let tn1 = needed_force(y1, cs1.x);
        let td0 = needed_force_rate(y0, f0.y, cs0.y) * dt;
        let td1 = needed_force_rate(y1, f1.y, cs1.y) * dt;
        // A holding inequality already failed, or at its limit and failing for the step, and
        // failing further: a release now.
        let gp0 = fs() - tn0;
        let gp1 = fs() - tn1;
        let gn0 = fs() + tn0;
        let gn1 = fs() + tn1;
        if (mode != MODE_LOCK_NEG && td0 > F(0.0) && (gp0 < F(0.0) || (gp0 == F(0.0) && gp1 < F(0.0)))) {
            return Hit(F(0.0), EV_RELEASE_POS);
        }
        if (mode != MODE_LOCK_POS && td0 < F(0.0) && (gn0 < F(0.0) || (gn0 == F(0.0) && gn1 < F(0.0)))) {
            return Hit(F(0.0), EV_RELEASE_NEG);
        }
        if (mode != MODE_LOCK_NEG) {
            b0 = bracket(gp0, gp1, -td0, -td1, F(0.0), EV_RELEASE_POS);
        }
        if (mode != MODE_LOCK_POS) {
            b1 = bracket(gn0, gn1, td0, td1, F(0.0), EV_RELEASE_NEG);
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

// method/mod.rs `quiet`: no guard of the mode can reach zero in the full step from y0 to y1, so
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

// shader-only: Diagnostics::count_impact (method/result.rs): an impact whose relative
// velocity went from vb to va, taking `loss` of kinetic energy.
fn count_impact(vb: F, loss: F) {
    let v = fabs(vb);
    st.impact_speed = vec2<F>(st.impact_speed.x + v, fmax(st.impact_speed.y, v));
    st.loss.x += loss;
}

// shader-only: Diagnostics::count_step (method/result.rs): an accepted (sub)step of `span`
// grid steps in `mode` that dissipated `work` by friction.
fn count_step(mode: u32, work: F, span: F) {
    st.loss.y += work;
    if (!is_slip(mode)) {
        st.stuck += span;
    }
}

fn apply_event(ev: u32, c: F) {
    if (ev == EV_IMPACT_POS || ev == EV_IMPACT_NEG) {
        let vb = st.y.y - st.y.w;
        st.y = impact(st.y);
        st.impacts += 1u;
        after_impact(select(-1, 1, ev == EV_IMPACT_POS), c);
        let va = st.y.y - st.y.w;
        count_impact(vb, impact_loss(vb, va));
    } else if (ev == EV_REVERSAL) {
        let left = st.mode;
        st.y = co_move(st.y);
        st.mode = mode_at_rest(0, needed_force(st.y, c));
        // Back into the slip it left: a tie with the static limit that rounding split.
        if (st.mode == left) {
            st.mode = MODE_STICK;
        }
        if (st.mode == MODE_STICK) {
            st.sticks += 1u;
        }
    } else if (ev == EV_RELEASE_POS) {
        st.mode = MODE_SLIP_POS;
    } else {
        st.mode = MODE_SLIP_NEG;
    }
}

// method/mod.rs `wrong_slip`: a slip mode whose slip velocity has the opposite sign.
fn wrong_slip() -> bool {
    let v = st.y.y - st.y.w;
    return (st.mode == MODE_SLIP_POS && v < F(0.0)) || (st.mode == MODE_SLIP_NEG && v > F(0.0));
}

fn naive_impact(k: u32) -> bool {
    if (!is_slip(st.mode)) {
        return false;
    }
    let z = st.y.z - st.y.x;
    let zd = st.y.w - st.y.y;
    var stop = 0;
    if (z > clearance() && zd > F(0.0)) {
        stop = 1;
    } else if (z < -clearance() && zd < F(0.0)) {
        stop = -1;
    } else {
        return false;
    }
    st.y.z = st.y.x + select(-clearance(), clearance(), stop > 0);
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
                count_step(st.mode, stage_work, span);
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
        count_step(st.mode, stage_work, span);
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
    if (wrong_slip()) {
        st.wrong_slips += 1u;
    }
    if (LADDER_FINITE && !finite_state(st.y)) {
        st.nonfinite = 1u;
    }
}

// Returns false when the period did not run to its end (non-finite state or a loop cut short).
// Quiet steps (no guard near zero: almost all) run in the inner loop, which holds only the RK4
// step and the guard bounds; a lane leaves it at a step that may hold an event, and that step
// goes through `step`. On SIMD adapters the code of `step` then runs once per event rather
// than masked in every step (method/mod.rs `period_observed` is the twin).
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
                count_step(st.mode, stage_work, F(1.0));
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
