//! Cycles longer than the kernel's tail can show: a point that ends torus-looking or undecided
//! is run on, on the host in f64, for [`WINDOW`] periods whose stroboscopic states are kept; a
//! lag of up to [`MAX_LONG_PERIOD`] at which they recur (converging onto a cycle, or settled)
//! is tried by Newton's method at that period from the window's last state. A stable cycle
//! that the motion is seen to approach is the point's attractor.
//!
//! The kernel keeps [`TAIL`](crate::classify::TAIL) section values per point, enough for lags
//! up to 128 seen twice; a tail of 2048 for every point would hold 8 KiB of a 512 x 512 map's
//! every cell on the device. The few points left torus-looking or undecided run here instead.

use crate::classify::{Candidate, SETTLED, approaches};
use crate::cycles::{Cycle, refine};
use crate::method::{Integrator, PointState};
use crate::progress::Progress;

/// The longest cycle looked for.
pub const MAX_LONG_PERIOD: u32 = 1024;

/// Differences compared at each end of the window for a lag (as the kernel's candidates: the
/// last 32 values, and the first 32).
const W: usize = 32;

/// Periods a search runs and keeps: every lag up to [`MAX_LONG_PERIOD`] is seen over two
/// windows of [`W`] values that lie apart.
pub const WINDOW: u32 = 2 * MAX_LONG_PERIOD + 2 * W as u32;

/// Whether a run of `spec` searches: its look allows [`WINDOW`] periods (`run.look`, the
/// periods a point may be followed for in all) and its sampled window holds the two windows
/// of [`W`] values that a lag is judged by. A run of a few periods (a quick survey, a memory
/// measurement) is not followed for thousands more, nor one whose look is off.
pub fn asked(spec: &crate::spec::RunSpec) -> bool {
    spec.look >= WINDOW && spec.samples >= 2 * W as u32
}

/// A lag whose recent differences are at most this fraction of its early ones converges (as
/// [`crate::classify::CONVERGING`] for the kernel's candidates).
const CONVERGING: f64 = 0.5;

/// A converging lag is proposed only where its recent differences are within this fraction of
/// the range: over 1024 lags chaos converges at one by chance, to 0.2-0.35 of the range (Fig.
/// 2's eta 1.72-1.76), where Newton at a long period would be tried in vain.
const NEAR_REPEAT: f64 = 0.05;

/// The lag the search proposes first ([`lags`]).
pub fn best_lag(states: &[[f64; 4]]) -> Option<Candidate> {
    lags(states).into_iter().next()
}

/// The lags the search tries, in order: among the lags that converge (recent differences at most
/// [`CONVERGING`] of the early ones, within [`NEAR_REPEAT`] of the range) or have settled (within
/// [`SETTLED`] of the range), the least divisor that qualifies of the one of the smallest recent
/// difference, then that one itself. A cycle recurs at its multiples as well, and a transient's
/// rotation can suit a multiple better; but a long cycle that winds close round a shorter
/// unstable one (a period-168 round a period-21) qualifies at the short lag too, where Newton
/// finds the unstable cycle, not the motion's.
pub fn lags(states: &[[f64; 4]]) -> Vec<Candidate> {
    let len = states.len();
    let mut span = [0.0f64; 4];
    for (i, s) in span.iter_mut().enumerate() {
        let (lo, hi) = states
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, x| {
                (a.0.min(x[i]), a.1.max(x[i]))
            });
        *s = hi - lo;
    }
    if !span.iter().all(|s| s.is_finite()) || span.iter().all(|&s| s <= 0.0) {
        return Vec::new();
    }
    // Each component relative to its own range (a flat one, the stuck relative motion, is
    // left out).
    let diff = |k: usize, n: usize| {
        (0..4)
            .filter(|&i| span[i] > 0.0)
            .map(|i| (states[k][i] - states[k - n][i]).abs() / span[i])
            .fold(
                0.0f64,
                |a, b| if b.is_nan() { f64::INFINITY } else { a.max(b) },
            )
    };
    let worst = |ks: std::ops::Range<usize>, n: usize| ks.map(|k| diff(k, n)).fold(0.0, f64::max);
    let most = (MAX_LONG_PERIOD as usize).min(len.saturating_sub(2 * W) / 2);
    if log::log_enabled!(log::Level::Trace) {
        let mut all: Vec<(usize, f64, f64)> = (1..=most)
            .map(|n| (n, worst(len - W..len, n), worst(n..n + W, n)))
            .collect();
        all.sort_by(|a, b| a.1.total_cmp(&b.1));
        log::trace!(
            "recurrence: closest returns (lag, recent, early): {:?}",
            &all[..all.len().min(6)]
        );
    }
    let found: Vec<Candidate> = (1..=most)
        .filter_map(|n| {
            let recent = worst(len - W..len, n);
            let early = worst(n..n + W, n);
            let converging = recent <= CONVERGING * early && recent <= NEAR_REPEAT;
            (converging || recent <= SETTLED).then_some(Candidate {
                period: n as u32,
                recent,
                decay: Some((early, (len - W - n) as u32)),
            })
        })
        .collect();
    let Some(best) = found
        .iter()
        .min_by(|a, b| a.recent.total_cmp(&b.recent))
        .copied()
    else {
        return Vec::new();
    };
    let least = found
        .into_iter()
        .find(|c| best.period.is_multiple_of(c.period))
        .unwrap_or(best);
    if least.period == best.period {
        vec![best]
    } else {
        vec![least, best]
    }
}

/// What a search came to.
#[derive(Clone, Debug, Default)]
pub struct Search {
    /// The stable cycle the motion approaches, where one was found.
    pub found: Option<Cycle>,
    /// Periods run (the motion's settle time grows by them where a cycle was found).
    pub periods: u32,
    /// The lag proposed, where one was: the period Newton tried.
    pub best: Option<Candidate>,
}

/// Runs [`WINDOW`] periods from `from` and tries Newton at the lags [`lags`] proposes, in
/// order, from the window's last state: the first stable cycle found, where the motion is seen
/// to approach it ([`approaches`] over the window's y1 values).
pub fn search(it: &Integrator<f64>, from: &PointState<f64>, progress: &dyn Progress) -> Search {
    let mut st = *from;
    st.diag = Default::default();
    let mut states = Vec::with_capacity(WINDOW as usize);
    // The window's periods as they run, a few at a time (the caller counted them all).
    const REPORT: u32 = 64;
    for k in 0..WINDOW {
        crate::progress::poll();
        it.period(&mut st);
        if (k + 1) % REPORT == 0 {
            progress.advance(u64::from(REPORT));
        }
        if st.diag.nonfinite {
            progress.advance(u64::from(WINDOW - (k + 1) / REPORT * REPORT));
            return Search::default();
        }
        states.push(st.y);
    }
    progress.advance(u64::from(WINDOW % REPORT));
    let mut out = Search {
        periods: WINDOW,
        ..Search::default()
    };
    let y1: Vec<f64> = states.iter().map(|s| s[0]).collect();
    for cand in lags(&states) {
        out.best = Some(cand);
        let c = refine(it, &st, cand.period);
        log::trace!(
            "recurrence: lag {}: Newton converged {} stable {} |mu| {:.6} at {:.3e} of the state",
            cand.period,
            c.converged,
            c.is_stable(),
            c.leading_modulus(),
            (0..4)
                .map(|i| (c.point[i] - st.y[i]).abs())
                .fold(0.0, f64::max)
        );
        if c.is_stable() && approaches(&y1, &st.y, &cand, &c.point, c.leading_modulus()) {
            out.found = Some(c);
            break;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// Section states of a period-`n` cycle whose points go round a closed curve by `p` of `n`
    /// steps each period (a locked torus), approached at the rate 0.995 per period.
    fn converging(n: usize, p: usize, len: usize) -> Vec<[f64; 4]> {
        (0..len)
            .map(|k| {
                let phase = (k * p % n) as f64 / n as f64;
                let base = (TAU * phase).sin() + 0.3 * (2.0 * TAU * phase).cos();
                let off = 0.05 * 0.995f64.powi(k as i32) * (k as f64 * 0.7).sin();
                [
                    base + off,
                    (TAU * phase).cos(),
                    0.5 * base - off,
                    base * base,
                ]
            })
            .collect()
    }

    #[test]
    fn a_long_cycle_is_proposed_at_its_period_not_a_multiple() {
        for (n, p) in [(5, 2), (168, 65), (244, 93), (1000, 381)] {
            let s = converging(n, p, WINDOW as usize);
            let c = best_lag(&s).expect("a lag");
            assert_eq!(c.period, n as u32, "{c:?}");
        }
    }

    /// A period-168 cycle winding round a period-21 orbit (rotation 3/8 a round, 3% of the
    /// range), approached at 0.995 a period: a shorter lag, a divisor of 168, converges too
    /// (the approach dies out there as well), so the search tries it first and 168 after it,
    /// not the shorter one alone.
    #[test]
    fn a_long_cycle_round_a_short_one_is_tried_at_its_own_period_too() {
        let s: Vec<[f64; 4]> = (0..WINDOW as usize)
            .map(|k| {
                let base = TAU * (k % 21) as f64 / 21.0;
                let wind = TAU * (k / 21 * 3 % 8) as f64 / 8.0 + base;
                let off = 0.3 * 0.995f64.powi(k as i32) * (k as f64 * 0.7).sin();
                let x = base.sin() + 0.03 * wind.cos() + off;
                [x, base.cos() + 0.03 * wind.sin(), 0.5 * x, x * x]
            })
            .collect();
        let tried: Vec<u32> = lags(&s).iter().map(|c| c.period).collect();
        assert!(
            tried.len() == 2 && tried[0] < 168 && 168 % tried[0] == 0 && tried[1] == 168,
            "{tried:?}"
        );
    }

    #[test]
    fn a_quasi_periodic_motion_proposes_no_lag() {
        // An irrational rotation: near-returns at some lags, none converging or settled.
        let w = (5f64.sqrt() - 1.0) / 2.0;
        let s: Vec<[f64; 4]> = (0..WINDOW as usize)
            .map(|k| {
                let t = TAU * w * k as f64;
                [t.cos(), t.sin(), (2.0 * t).cos(), 0.3 * t.sin()]
            })
            .collect();
        assert_eq!(best_lag(&s), None);
    }
}
