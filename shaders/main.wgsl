// twin: none (the entry point: one invocation runs one point for the periods of one dispatch)
// Loads a point's state and parameters, runs its periods, stores what the host reads back.

// shader-only: the entry point; its host side is gpu/batch.rs (buffers) and gpu/dispatch.rs.
@compute @workgroup_size(WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * ctl.row;
    let n = ctl.n_points;
    if (i >= n) {
        return;
    }
    prm = load_params();
    if (ctl.n_vary > 0u) {
        set_param(ctl.vary0, pvals[i * ctl.n_vary]);
    }
    if (ctl.n_vary > 1u) {
        set_param(ctl.vary1, pvals[i * ctl.n_vary + 1u]);
    }
    if (ctl.n_vary > 2u) {
        set_param(ctl.vary2, pvals[i * ctl.n_vary + 2u]);
    }
    derive_constants();

    st.y = load_y(Y_MAIN, i);
    st.mode = us[U_MODE * n + i];
    st.impacts = us[U_IMPACTS * n + i];
    st.sticks = us[U_STICKS * n + i];
    st.locks = us[U_LOCKS * n + i];
    st.overflows = us[U_OVERFLOWS * n + i];
    st.wrong_slips = us[U_WRONG_SLIPS * n + i];
    st.nonfinite = us[U_NONFINITE * n + i];
    var sample_impacts = us[U_SAMPLE_IMPACTS * n + i];
    // The observables per sampled period, as running means over the periods since sampling
    // started: (impact speeds' sum, impact loss, friction loss, steps stuck). A period sums
    // into `st`, and its sums update the means at its end; the host multiplies by the periods.
    // In f32 a running sum of every step's term lost 7e-4 of the friction loss over 4000
    // periods (each term rounded against the total), a running sum of the periods' sums 3e-5;
    // the means change by little once settled (nothing on a cycle), so they keep the digits.
    var means = vec4<F>(ring[R_IMPACT_SPEED_SUM * n + i], ring[R_LOSS_IMPACTS * n + i],
                       ring[R_LOSS_FRICTION * n + i], ring[R_STUCK * n + i]);
    st.impact_speed.y = ring[R_IMPACT_SPEED_MAX * n + i];
    var tan_bad = 1u;
    var log_sum = F(0.0);
    if (TANGENT) {
        tvec[0] = load_y(Y_TAN, i);
        tan_bad = us[U_TAN_BAD * n + i];
        log_sum = ring[R_LOG_SUM * n + i];
    }

    var q = 0u;
    for (; q < ctl.periods; q++) {
        if (st.nonfinite != 0u) {
            break;
        }
        let idx = ctl.period0 + q;
        if (idx == ctl.transient) {
            // The observables are those of the sampled periods (Diagnostics::start_sampling).
            means = vec4<F>(F(0.0));
            st.impact_speed.y = F(0.0);
        }
        if (TANGENT && idx == ctl.transient) {
            // The tangent vector starts along y1 with sampling.
            tvec[0] = vec4<F>(F(1.0), F(0.0), F(0.0), F(0.0));
            tan_bad = 0u;
            log_sum = F(0.0);
        }
        tan_on = TANGENT && idx >= ctl.transient && tan_bad == 0u;
        observing = idx >= ctl.transient;
        st.impact_speed.x = F(0.0);
        st.loss = vec2<F>(F(0.0));
        st.stuck = F(0.0);
        let before = st.impacts;
        let done = period();
        if (observing) {
            let period_sums = vec4<F>(st.impact_speed.x, st.loss.x, st.loss.y, st.stuck);
            means += (period_sums - means) / F(idx - ctl.transient + 1u);
        }
        if (!done && st.nonfinite == 0u) {
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
                if (finite_state(tvec[0])) {
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
            store_y(Y_TAN, i, tvec[0]);
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
    us[U_WRONG_SLIPS * n + i] = st.wrong_slips;
    us[U_NONFINITE * n + i] = st.nonfinite;
    ring[R_IMPACT_SPEED_SUM * n + i] = means.x;
    ring[R_IMPACT_SPEED_MAX * n + i] = st.impact_speed.y;
    ring[R_LOSS_IMPACTS * n + i] = means.y;
    ring[R_LOSS_FRICTION * n + i] = means.z;
    ring[R_STUCK * n + i] = means.w;
}
