// twin: src/method/tangent.rs
// The tangent vectors: TANGENTS of them (the host's constant before the pieces): one for the
// largest Lyapunov exponent (tangent.rs `Leading`), four for the flows of Newton's method
// (tangent.rs `Tangent`, flows.wgsl).

var<private> tvec: array<vec4<F>, TANGENTS>;

// The tangent runs in this period (a sampled one, the vector still finite).
var<private> tan_on: bool;

// tangent.rs `Jump`.
const JUMP_IDENTITY: u32 = 0u;
const JUMP_IMPACT: u32 = 1u;
const JUMP_CO_MOVE: u32 = 2u;

fn dot4(a: vec4<F>, b: vec4<F>) -> F {
    return a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w;
}

fn jump_apply(jump: u32, x: vec4<F>) -> vec4<F> {
    if (jump == JUMP_IMPACT) {
        return impact(x);
    }
    if (jump == JUMP_CO_MOVE) {
        return co_move(x);
    }
    return x;
}

// RK4 of the variational equation on the stage points of the state's last RK4 step, from its
// start y (before the state is overwritten), for each vector.
fn tangent_substep(y: vec4<F>, mode: u32, dt: F) {
    let half = F(0.5) * dt;
    let sixth = dt / F(6.0);
    for (var v = 0u; v < TANGENTS; v++) {
        let x = tvec[v];
        let k1 = jacobian_times(y, mode, x);
        let k2 = jacobian_times(stage1, mode, x + half * k1);
        let k3 = jacobian_times(stage2, mode, x + half * k2);
        let k4 = jacobian_times(stage3, mode, x + dt * k3);
        tvec[v] = x + sixth * (k1 + F(2.0) * (k2 + k3) + k4);
    }
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
    for (var v = 0u; v < TANGENTS; v++) {
        let a = dot4(n, tvec[v]) / d;
        tvec[v] = jump_apply(jump, tvec[v]) + u * a;
    }
}

// Unit length, and the log of the length before, in f32 even in the f64 kernel (f64 log is
// unreliable on some drivers). A collapsed vector restarts along y1 and counts at the floor.
fn tangent_renormalize() -> f32 {
    let norm = sqrt(dot4(tvec[0], tvec[0]));
    let floor = consts[C_TAN_FLOOR];
    if (norm <= floor) {
        tvec[0] = vec4<F>(F(1.0), F(0.0), F(0.0), F(0.0));
        return log(f32(floor));
    }
    tvec[0] = tvec[0] / norm;
    return log(f32(norm));
}
