// twin: src/method/tangent.rs
// Newton's flows on the device: periods of the state with the four tangent vectors from the
// identity (tangent.rs `flow`), for the cycles the host refines (cycles.rs `Refine`). One
// invocation per flow, each with its own parameters (every one of them, in `pvals`) and
// periods (U_FLOW_LEFT); a flow longer than one dispatch's `ctl.periods` resumes where the
// dispatch before left it (state, mode and vectors in `ys` and `us`).

// twin: flow
@compute @workgroup_size(WORKGROUP)
fn flows(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * ctl.row;
    let n = ctl.n_points;
    if (i >= n) {
        return;
    }
    let left = us[U_FLOW_LEFT * n + i];
    if (left == 0u || us[U_NONFINITE * n + i] != 0u || us[U_TRUNCATED * n + i] != 0u) {
        return;
    }
    flow_load(i);
    let periods = min(left, ctl.periods);
    var q = 0u;
    for (; q < periods; q++) {
        let done = period();
        if (st.nonfinite != 0u) {
            break;
        }
        if (!done) {
            us[U_TRUNCATED * n + i] = 1u;
            break;
        }
    }
    flow_store(i);
    us[U_FLOW_LEFT * n + i] = left - q;
}

// shader-only: buffer access (the host side is src/gpu/flows.rs).
// A flow's parameters (all per flow), state, mode and vectors, as the dispatch before left them.
fn flow_load(i: u32) {
    let n = ctl.n_points;
    prm = load_params();
    for (var c = 0u; c < ctl.n_vary; c++) {
        set_param(c, pvals[i * ctl.n_vary + c]);
    }
    derive_constants();
    st.y = load_y(Y_MAIN, i);
    st.mode = us[U_MODE * n + i];
    st.nonfinite = us[U_NONFINITE * n + i];
    for (var v = 0u; v < TANGENTS; v++) {
        tvec[v] = load_y(Y_TAN + v * STATE_DIM, i);
    }
    tan_on = true;
    observing = false;
}

// shader-only: buffer access.
fn flow_store(i: u32) {
    let n = ctl.n_points;
    store_y(Y_MAIN, i, st.y);
    for (var v = 0u; v < TANGENTS; v++) {
        store_y(Y_TAN + v * STATE_DIM, i, tvec[v]);
    }
    us[U_MODE * n + i] = st.mode;
    us[U_NONFINITE * n + i] = st.nonfinite;
}
