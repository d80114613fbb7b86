// twin: src/method/bare.rs
// Rung 0 of the kernel ladder: the bare RK4 step of the model, the least a kernel of it must
// do per step, so that `rattle bench` can say what fraction of it the production kernel
// reaches on the same adapter. The Coulomb field in the slip mode its friction sign is held
// in (no mode switch, no events, no detector, no observables), the parameters as literals
// the compiler folds, the forcing (cos, sin) rotated by half a step rather than read from a
// table, the state in registers. Its results are not the model's (m2 never stops or hits a
// stop); they are written back only so that the compiler keeps the work.
//
// The host prepends the prelude of src/gpu/layout.rs (F, Control, the slots) and the literal
// block of `gpu::kernel::bare_source`: BARE_B1, BARE_DELTA, BARE_T (the held friction force,
// +fk), BARE_INV_MU, BARE_ETA (eta where no point varies it), BARE_DPHI (2 pi / N) and
// BARE_HALF (cos, sin of half a step's phase).

@group(0) @binding(0) var<uniform> ctl: Control;
@group(0) @binding(2) var<storage, read> pvals: array<F>;
@group(0) @binding(3) var<storage, read_write> ys: array<F>;

// model.rs `field` in slip with the friction force held at BARE_T; c: cos of the forcing.
fn bare_field(y: vec4<F>, c: F) -> vec4<F> {
    let d = BARE_B1 * BARE_DELTA * (y.y - y.w);
    return vec4<F>(y.y, c - BARE_B1 * y.y - y.x - d - BARE_T, y.w, (d + BARE_T) * BARE_INV_MU);
}

// events.rs `mid_step`: the forcing half a step on.
fn bare_rotate(cs: vec2<F>) -> vec2<F> {
    return vec2<F>(cs.x * BARE_HALF.x - cs.y * BARE_HALF.y, cs.y * BARE_HALF.x + cs.x * BARE_HALF.y);
}

// shader-only: the entry point; the CPU twin runs the same loops over 8 lanes (`bare`).
@compute @workgroup_size(WORKGROUP)
fn bare(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * ctl.row;
    let n = ctl.n_points;
    if (i >= n) {
        return;
    }
    var eta = BARE_ETA;
    if (ctl.n_vary > 0u && ctl.vary0 == VARY_ETA) {
        eta = pvals[i * ctl.n_vary];
    }
    let h = BARE_DPHI / eta;
    let half_h = F(0.5) * h;
    let sixth = h / F(6.0);
    var y = vec4<F>(ys[Y_MAIN * n + i], ys[(Y_MAIN + 1u) * n + i], ys[(Y_MAIN + 2u) * n + i],
                    ys[(Y_MAIN + 3u) * n + i]);
    for (var q = 0u; q < ctl.periods; q++) {
        // Phase 0 at the start of every period, as the forcing table has it.
        var cs = vec2<F>(F(1.0), F(0.0));
        var f0 = bare_field(y, cs.x);
        for (var k = 0u; k < ctl.steps; k++) {
            let cm = bare_rotate(cs);
            let c1 = bare_rotate(cm);
            let k2 = bare_field(y + half_h * f0, cm.x);
            let k3 = bare_field(y + half_h * k2, cm.x);
            let k4 = bare_field(y + h * k3, c1.x);
            y = y + sixth * (f0 + F(2.0) * (k2 + k3) + k4);
            // First same as last: the end's field is the next step's first stage.
            f0 = bare_field(y, c1.x);
            cs = c1;
        }
    }
    ys[Y_MAIN * n + i] = y.x;
    ys[(Y_MAIN + 1u) * n + i] = y.y;
    ys[(Y_MAIN + 2u) * n + i] = y.z;
    ys[(Y_MAIN + 3u) * n + i] = y.w;
}
