// twin: src/classify.rs
// The classifier's evidence, gathered as the section values arrive.

// twin: Growth::push
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

// twin: Birkhoff::push
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

// twin: PeriodDetector::push
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
