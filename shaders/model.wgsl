// twin: src/model.rs
// The model: friction law, vector field of each mode, impact map and stick/lock conditions.

fn slip(s: F) -> u32 { return select(MODE_SLIP_NEG, MODE_SLIP_POS, s > F(0.0)); }
fn is_slip(mode: u32) -> bool { return mode <= MODE_SLIP_NEG; }

// model.rs `friction`: the Stribeck law as a smooth function of the signed slip speed w.
fn friction(w: F) -> F {
    if (COULOMB) {
        return fk();
    }
    // fs to the last bit at w = 0 (the static limit of the stick and lock tests).
    let m = fmax(l1() * w, F(-0.5));
    return fs() - (fs() - fk()) * m / (F(1.0) + m) + l2() * w * w;
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

// model.rs `friction_power`: T v, T from the field (zero while the masses move together).
fn friction_power(y: vec4<F>, k: vec4<F>) -> F {
    let v = y.y - y.w;
    return (mu() * k.w - b1() * delta() * v) * v;
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

// model.rs `impact_loss`: kinetic energy lost as the relative velocity jumps from vb to va.
fn impact_loss(vb: F, va: F) -> F {
    return F(0.5) * mu() * inv_1pmu * (vb * vb - va * va);
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

// model.rs `initial_mode`: the mode of a state, from its slip velocity, or at rest from the
// stop it touches and the force it needs (c: forcing at its time).
fn initial_mode(y: vec4<F>, c: F) -> u32 {
    let v = y.y - y.w;
    if (v != F(0.0)) {
        return slip(v);
    }
    let z = y.z - y.x;
    var stop = 0;
    if (z >= clearance()) {
        stop = 1;
    } else if (z <= -clearance()) {
        stop = -1;
    }
    return mode_at_rest(stop, needed_force(y, c));
}
