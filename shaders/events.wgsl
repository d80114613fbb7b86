// twin: src/method/events.rs
// Event location: the forcing inside a step, guard brackets and their roots.

// events.rs `mid_step`: the forcing at the middle of a step from the forcing cs at its start,
// as the table's mid-step entries hold it (bit for bit where the compiler does not contract
// the products into fma), without a read of the table.
fn mid_step(cs: vec2<F>) -> vec2<F> {
    return vec2<F>(cs.x * half.x - cs.y * half.y, cs.y * half.x + cs.x * half.y);
}

fn cos_sin_small(d: F) -> vec2<F> {
    let d2 = d * d;
    let o = F(1.0);
    let c = o - d2 / F(2.0) * (o - d2 / F(12.0) * (o - d2 / F(30.0) * (o - d2 / F(56.0)
        * (o - d2 / F(90.0) * (o - d2 / F(132.0))))));
    let s = d * (o - d2 / F(6.0) * (o - d2 / F(20.0) * (o - d2 / F(42.0) * (o - d2 / F(72.0)
        * (o - d2 / F(110.0))))));
    return vec2<F>(c, s);
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

// shader-only: the Rust side returns Option<Bracket>; WGSL has no Option.
fn no_bracket() -> Bracket {
    return Bracket(F(0.0), F(0.0), F(0.0), F(0.0), F(2.0), F(2.0), F(0.0), F(0.0), EV_NONE);
}

fn bracket(g0: F, g1: F, m0: F, m1: F, floor: F, ev: u32) -> Bracket {
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
    // An extremum before the step does not bound a piece: the later one must still split it.
    if (t1 <= F(0.0)) {
        t1 = t2;
        t2 = none;
    }
    // The three monotone pieces, unrolled: llvmpipe caps the loop iterations of one
    // invocation, so the hot path has no loops with a small fixed trip count.
    let b1 = select(F(1.0), t1, t1 > F(0.0) && t1 < F(1.0));
    let b2 = select(F(1.0), t2, t2 > b1 && t2 < F(1.0));
    // At the step's end the guard itself (the power form's rounding could lift a zero); a
    // guard that ends at zero while rising has not crossed (events.rs `bracket`).
    let crossed_end = g1 < F(0.0) || (g1 == F(0.0) && m1 < F(0.0));
    let end1 = b1 >= F(1.0);
    let p1 = select(hermite(g0, a1, a2, a3, b1), g1, end1);
    if (g0 > F(0.0) && select(p1 <= -floor, crossed_end, end1)) {
        return Bracket(g0, a1, a2, a3, F(0.0), b1, g0, p1, ev);
    }
    if (end1) {
        return no_bracket();
    }
    let end2 = b2 >= F(1.0);
    let p2 = select(hermite(g0, a1, a2, a3, b2), g1, end2);
    if (p1 > F(0.0) && select(p2 <= -floor, crossed_end, end2)) {
        return Bracket(g0, a1, a2, a3, b1, b2, p1, p2, ev);
    }
    if (end2) {
        return no_bracket();
    }
    if (p2 > F(0.0) && crossed_end) {
        return Bracket(g0, a1, a2, a3, b2, F(1.0), p2, g1, ev);
    }
    return no_bracket();
}

// events.rs `clear_of`: the guard g stays above the bound of `bracket` over the whole step, so
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
    return clearance() - fmax(fabs(z0), fabs(z1)) > bound;
}

// NaN or infinity (tested on the bits), or a state beyond any physical scale.
fn finite_state(y: vec4<F>) -> bool {
    let big = F(1e30);
    return finite4(y) && fmax(fmax(fabs(y.x), fabs(y.y)), fmax(fabs(y.z), fabs(y.w))) <= big;
}

// shader-only: the Rust side tests is_finite(); WGSL needs the bits (see below).
// Finiteness by the bits of the f32 value (f64 values beyond f32's range become infinite and
// fail, as they fail the bound above): NaN and infinity have every exponent bit set. A float
// comparison such as `x != x` is not a NaN test on drivers that assume IEEE special values
// never occur (llvmpipe folds it to false).
fn finite4(y: vec4<F>) -> bool {
    let e = bitcast<vec4<u32>>(vec4<f32>(y)) & vec4<u32>(0x7f800000u);
    return all(e != vec4<u32>(0x7f800000u));
}

fn hermite(a0: F, a1: F, a2: F, a3: F, t: F) -> F {
    return a0 + t * (a1 + t * (a2 + t * a3));
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
