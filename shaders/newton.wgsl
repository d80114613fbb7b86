// twin: src/cycles.rs
// Newton's method on the device (cycles.rs `Refine`): x <- x - (M - I)^-1 (P^n(x) - x) for
// each trial, its flows those of flows.wgsl (resumable across dispatches), until a step would
// end the iteration (converged, diverging, stalled, singular, out of iterations): that step is
// the host's (`Refine::resume`), from the state before it, so that the host's arithmetic ends
// every trial (its least period and multipliers) and the device only iterates. A trial pauses
// after the iterations of one call (U_NEWTON_PAUSE), between two flows.

// The trial's iteration: cycles.rs `Refine`'s iterate `st`, `out.iterations`, `out.residual`
// and `before`.
struct Newton {
    x: vec4<F>,
    mode: u32,
    iters: u32,
    residual: F,
    before: F,
}
var<private> nt: Newton;

// twin: refine
@compute @workgroup_size(WORKGROUP)
fn newton(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * ctl.row;
    let n = ctl.n_points;
    if (i >= n) {
        return;
    }
    if (us[U_NEWTON_DONE * n + i] != 0u || us[U_TRUNCATED * n + i] != 0u) {
        return;
    }
    flow_load(i);
    let periods = us[U_NEWTON_PERIOD * n + i];
    var left = us[U_FLOW_LEFT * n + i];
    // Periods this dispatch may still integrate (llvmpipe's loop limit), over every flow.
    var budget = ctl.periods;
    var handed = 0u;
    loop {
        // The flow's periods, as flows.wgsl runs them, as many as the dispatch has left.
        let todo = min(left, budget);
        var q = 0u;
        var cut = false;
        for (; q < todo; q++) {
            let done = period();
            if (st.nonfinite != 0u) {
                break;
            }
            if (!done) {
                cut = true;
                break;
            }
        }
        left -= q;
        budget -= q;
        if (cut) {
            us[U_TRUNCATED * n + i] = 1u;
            break;
        }
        if (left > 0u && st.nonfinite == 0u) {
            break;
        }
        // The flow ended (or failed): the iteration's step, on the iteration as `ys` and `us`
        // hold it (nothing of it is live across the flows).
        newton_load(i);
        if (!newton_step()) {
            handed = 1u;
            break;
        }
        newton_store(i);
        st.y = nt.x;
        st.mode = nt.mode;
        for (var v = 0u; v < TANGENTS; v++) {
            tvec[v] = unit(v);
        }
        left = periods;
        // The call's iterations are done: the host gathers the trials still open for the
        // next (a lane whose trial has ended waits for the others of its SIMD group).
        if (nt.iters >= us[U_NEWTON_PAUSE * n + i]) {
            break;
        }
    }
    flow_store(i);
    us[U_FLOW_LEFT * n + i] = left;
    us[U_NEWTON_DONE * n + i] = handed;
}

// shader-only: buffer access (the host side is src/gpu/flows.rs).
fn newton_load(i: u32) {
    let n = ctl.n_points;
    nt = Newton(load_y(Y_ITER, i), us[U_ITER_MODE * n + i], us[U_NEWTON_ITERS * n + i],
                ys[Y_RESIDUAL * n + i], ys[Y_BEFORE * n + i]);
}

// shader-only: buffer access.
fn newton_store(i: u32) {
    let n = ctl.n_points;
    store_y(Y_ITER, i, nt.x);
    us[U_ITER_MODE * n + i] = nt.mode;
    us[U_NEWTON_ITERS * n + i] = nt.iters;
    ys[Y_RESIDUAL * n + i] = nt.residual;
    ys[Y_BEFORE * n + i] = nt.before;
}

// shader-only: the host's Tangent::identity.
fn unit(v: u32) -> vec4<F> {
    return vec4<F>(select(F(0.0), F(1.0), v == 0u), select(F(0.0), F(1.0), v == 1u),
                   select(F(0.0), F(1.0), v == 2u), select(F(0.0), F(1.0), v == 3u));
}

// twin: step
// `Refine::step` after the flow from nt.x ended at `st` with the vectors `tvec`: true with the
// next iterate in `nt`; false, `nt` untouched, where the host's step would end the iteration.
fn newton_step() -> bool {
    if (st.nonfinite != 0u) {
        return false;
    }
    for (var v = 0u; v < TANGENTS; v++) {
        if (!finite4(tvec[v])) {
            return false;
        }
    }
    let r = st.y - nt.x;
    let residual = fmax(fmax(fabs(r.x), fabs(r.y)), fmax(fabs(r.z), fabs(r.w)));
    // Against NaN (the first iteration) every comparison is false, as on the host.
    if (residual > F(1e3) * nt.residual) {
        return false;
    }
    let x = nt.x;
    let scale = fmax(F(1.0), fmax(fmax(fabs(x.x), fabs(x.y)), fmax(fabs(x.z), fabs(x.w))));
    if (residual <= NEWTON_TOL * scale || residual >= nt.before) {
        return false;
    }
    // (M - I) dx = -r, M's columns the vectors.
    var a: array<vec4<F>, 4>;
    for (var row = 0u; row < 4u; row++) {
        a[row] = vec4<F>(tvec[0][row], tvec[1][row], tvec[2][row], tvec[3][row]) - unit(row);
    }
    if (!lu_solve(a, -r) || !finite4(lu_x) || nt.iters + 1u >= NEWTON_ITERS) {
        return false;
    }
    nt.before = nt.residual;
    nt.residual = residual;
    nt.iters += 1u;
    nt.x = x + lu_x;
    nt.mode = mode_after_update(nt.x, nt.mode);
    if (!is_slip(nt.mode)) {
        nt.x = co_move(nt.x);
    }
    return true;
}

// The solution of the last `lu_solve`.
var<private> lu_x: vec4<F>;

// shader-only: the host solves with nalgebra's LU (`Matrix4::lu().solve`).
// Gaussian elimination with partial pivoting of the rows `m`, as nalgebra's LU: false where a
// pivot is zero (nalgebra's solve returns None there).
fn lu_solve(m: array<vec4<F>, 4>, rhs: vec4<F>) -> bool {
    var a = m;
    var b = rhs;
    for (var c = 0u; c < 4u; c++) {
        var p = c;
        for (var row = c + 1u; row < 4u; row++) {
            if (fabs(a[row][c]) > fabs(a[p][c])) {
                p = row;
            }
        }
        if (a[p][c] == F(0.0)) {
            return false;
        }
        let ra = a[c];
        a[c] = a[p];
        a[p] = ra;
        let rb = b[c];
        b[c] = b[p];
        b[p] = rb;
        let inv = F(1.0) / a[c][c];
        for (var row = c + 1u; row < 4u; row++) {
            let f = a[row][c] * inv;
            a[row] -= f * a[c];
            b[row] -= f * b[c];
        }
    }
    for (var k = 0u; k < 4u; k++) {
        let c = 3u - k;
        var s = b[c];
        for (var j = c + 1u; j < 4u; j++) {
            s -= a[c][j] * lu_x[j];
        }
        lu_x[c] = s / a[c][c];
    }
    return true;
}

// twin: mode_after_update
fn mode_after_update(y: vec4<F>, mode: u32) -> u32 {
    let v = y.y - y.w;
    if ((mode == MODE_SLIP_POS && v > F(0.0)) || (mode == MODE_SLIP_NEG && v < F(0.0))) {
        return mode;
    }
    if (is_slip(mode)) {
        return initial_mode(y, table(0u).x);
    }
    return mode;
}
