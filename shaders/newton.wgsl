// twin: src/cycles.rs
// Newton's method on the device (cycles.rs `Refine`): x <- x - (M - I)^-1 (P^n(x) - x) for
// each trial, its flows those of flows.wgsl (resumable across dispatches), until a step would
// end the iteration (converged, diverging, stalled, singular, out of iterations): that step is
// the host's (`Refine::resume`), from the state before it, so that the host's arithmetic ends
// every trial (its multipliers) and the device only iterates and integrates. A converged
// iterate first gets the least-period pass (`least_return`) here: where it returns after a
// proper divisor d of the period, the trial starts again at period d (as `step` does with
// `refine`). A trial pauses after the iterations of one call (U_NEWTON_PAUSE), between two
// flows.

// The trial's iteration: cycles.rs `Refine`'s iterate `st`, `out.iterations`, `out.residual`
// and `before` (the last two meaningless while `iters` is below 1 and 2: the host's NaN).
struct Newton {
    x: vec4<F>,
    mode: u32,
    iters: u32,
    residual: F,
    before: F,
}
var<private> nt: Newton;

// What a step of the iteration says (`newton_step`).
const STEP_ON: u32 = 0u;
const STEP_ENDS: u32 = 1u;
const STEP_CONVERGED: u32 = 2u;

// shader-only: the dispatches of a call run without the host between them.
// Whether trial `i` goes on in a dispatch: open, not cut short, not paused.
fn newton_open(i: u32) -> bool {
    let n = ctl.n_points;
    return i < n && us[U_NEWTON_DONE * n + i] == NEWTON_OPEN && us[U_TRUNCATED * n + i] == 0u
        && us[U_NEWTON_ITERS * n + i] < us[U_NEWTON_PAUSE * n + i];
}

// twin: refine
@compute @workgroup_size(WORKGROUP)
fn newton(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * ctl.row;
    let n = ctl.n_points;
    // The dispatches of one call are queued without the host between them: a trial that
    // has ended or paused stays as it is.
    if (!newton_open(i)) {
        return;
    }
    flow_load(i);
    var periods = us[U_NEWTON_PERIOD * n + i];
    var left = us[U_FLOW_LEFT * n + i];
    var phase = us[U_NEWTON_PHASE * n + i];
    var least = us[U_LEAST_DONE * n + i];
    if (phase == PHASE_LEAST) {
        // The pass runs in `st`; the flow's end waits in the buffers for the host.
        newton_load(i);
        st.y = load_y(Y_LEAST, i);
        st.mode = us[U_LEAST_MODE * n + i];
        st.nonfinite = 0u;
        tan_on = false;
    }
    // Periods this dispatch may still integrate (llvmpipe's loop limit), over every flow.
    var budget = ctl.periods;
    var handed = NEWTON_OPEN;
    loop {
        if (phase == PHASE_LEAST) {
            if (budget == 0u) {
                break;
            }
            budget -= 1u;
            let done = period();
            if (!done && st.nonfinite == 0u) {
                us[U_TRUNCATED * n + i] = 1u;
                break;
            }
            least += 1u;
            if (least_return(periods, least)) {
                // A cycle of period `least`: Newton again at that period from the iterate
                // (`*out = refine(it, st, d)`).
                periods = least;
                nt.iters = 0u;
                newton_store(i);
                phase = PHASE_FLOW;
                tan_on = true;
                left = newton_flow(periods);
                continue;
            }
            // A non-finite pass never returns (the host's comparisons with NaN fail).
            if (least >= periods / 2u || st.nonfinite != 0u) {
                handed = NEWTON_NO_DIVISOR;
                break;
            }
            continue;
        }
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
        let said = newton_step();
        if (said == STEP_ENDS) {
            handed = NEWTON_HANDED;
            break;
        }
        if (said == STEP_CONVERGED) {
            if (periods < 2u) {
                handed = NEWTON_NO_DIVISOR;
                break;
            }
            // The least-period pass from the iterate; the flow's end stays in the buffers.
            flow_store(i);
            phase = PHASE_LEAST;
            least = 0u;
            st.y = nt.x;
            st.mode = nt.mode;
            tan_on = false;
            continue;
        }
        newton_store(i);
        left = newton_flow(periods);
        // The call's iterations are done: the trial pauses until the host's next call.
        if (nt.iters >= us[U_NEWTON_PAUSE * n + i]) {
            break;
        }
    }
    if (phase == PHASE_FLOW) {
        flow_store(i);
        us[U_FLOW_LEFT * n + i] = left;
    } else if (handed == NEWTON_OPEN) {
        store_y(Y_LEAST, i, st.y);
        us[U_LEAST_MODE * n + i] = st.mode;
    }
    us[U_NEWTON_PERIOD * n + i] = periods;
    us[U_NEWTON_PHASE * n + i] = phase;
    us[U_LEAST_DONE * n + i] = least;
    us[U_NEWTON_DONE * n + i] = handed;
}

// shader-only: the host's Refine starts each flow from its iterate (`FlowTask::flow`).
// The next flow of the iteration: from the iterate, the vectors at the identity; returns its
// periods.
fn newton_flow(periods: u32) -> u32 {
    st.y = nt.x;
    st.mode = nt.mode;
    st.nonfinite = 0u;
    for (var v = 0u; v < TANGENTS; v++) {
        tvec[v] = unit(v);
    }
    return periods;
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

// shader-only: the host's `scale`, max(1, |x|) over the components.
fn newton_scale(x: vec4<F>) -> F {
    return fmax(F(1.0), amax4(x));
}

// twin: step
// `Refine::step` after the flow from nt.x ended at `st` with the vectors `tvec`: STEP_ON with
// the next iterate in `nt`; otherwise `nt` untouched: STEP_CONVERGED where the step converges
// (the least-period pass comes next), STEP_ENDS where it ends the iteration otherwise.
fn newton_step() -> u32 {
    if (st.nonfinite != 0u) {
        return STEP_ENDS;
    }
    for (var v = 0u; v < TANGENTS; v++) {
        if (!finite4(tvec[v])) {
            return STEP_ENDS;
        }
    }
    let r = st.y - nt.x;
    let residual = amax4(r);
    // The host's residual before the first iteration, and the one two back before the
    // second, are NaN: no comparison with them holds.
    if (nt.iters >= 1u && residual > F(1e3) * nt.residual) {
        return STEP_ENDS;
    }
    let x = nt.x;
    if (residual <= NEWTON_TOL * newton_scale(x)) {
        return STEP_CONVERGED;
    }
    if (nt.iters >= 2u && residual >= nt.before) {
        return STEP_ENDS;
    }
    // (M - I) dx = -r, M's columns the vectors.
    var a: array<vec4<F>, 4>;
    for (var row = 0u; row < 4u; row++) {
        a[row] = vec4<F>(tvec[0][row], tvec[1][row], tvec[2][row], tvec[3][row]) - unit(row);
    }
    if (!lu_solve(a, -r) || !finite4(lu_x) || nt.iters + 1u >= NEWTON_ITERS) {
        return STEP_ENDS;
    }
    nt.before = nt.residual;
    nt.residual = residual;
    nt.iters += 1u;
    nt.x = x + lu_x;
    nt.mode = mode_after_update(nt.x, nt.mode);
    if (!is_slip(nt.mode)) {
        nt.x = co_move(nt.x);
    }
    return STEP_ON;
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

// One period of the pass from the converged iterate nt.x, `d` periods done (in `st`): true
// where d divides the period `periods` and the pass is back at nt.x within the Newton
// tolerance.
fn least_return(periods: u32, d: u32) -> bool {
    if (st.nonfinite != 0u || periods % d != 0u || d > periods / 2u) {
        return false;
    }
    let e = st.y - nt.x;
    let bound = F(1e3) * NEWTON_TOL * newton_scale(nt.x);
    return amax4(e) <= bound;
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
