//! The laminar-phase view of `point --plot`: returns of the section states to their value p
//! periods earlier, the episodes they form, and the histogram of episode lengths.

use serde::Serialize;

/// Longest lag tried for a point without a confirmed period.
const MAX_LAG: u32 = 16;
/// The smallest lag with at least this share of the best lag's returns is taken (a multiple of
/// the laminar period returns about as often).
const LAG_SHARE: f64 = 0.9;
/// Histogram bins at most.
const MAX_BINS: u32 = 30;

/// A nearly periodic episode: the returns of sampled periods `first..=last` (from 1).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Episode {
    pub first: u32,
    pub last: u32,
    pub length: u32,
    /// Touches the start or the end of the record: its true length may be longer.
    pub censored: bool,
}

/// Histogram bin: episodes with length in [from, to).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Bin {
    pub from: u32,
    pub to: u32,
    pub count: u32,
}

/// The laminar-phase analysis of the section states.
#[derive(Clone, Debug, Serialize)]
pub struct Laminar {
    pub lag: u32,
    pub lag_rule: String,
    pub tol: f64,
    /// s: the largest range of a section coordinate over the sampled periods.
    pub span: f64,
    /// max(1, s).
    pub scale: f64,
    /// tol * scale.
    pub threshold: f64,
    pub rule: &'static str,
    /// Returns among the comparisons k = p+1..=S.
    pub returns: usize,
    pub comparisons: usize,
    pub episodes: Vec<Episode>,
    pub histogram: Vec<Bin>,
}

const RULE: &str = "sampled period k is a return when max_i |x_i(k) - x_i(k-p)| <= threshold, \
                    x = (y1, y2, y3, y4) at the section, threshold = tol * max(1, s), s the \
                    largest range of a section coordinate over the sampled periods; an episode \
                    is a maximal run of consecutive returns, its length the number of periods \
                    in it (a periodic point: one episode of all sampled periods but the first \
                    p)";

/// Max-norm distance of two states.
pub(crate) fn dist(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    (0..4).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max)
}

/// Whether each sampled period from the (p+1)-th on returns within `thr` of p periods before.
fn returns(samples: &[[f64; 4]], p: usize, thr: f64) -> Vec<bool> {
    (p..samples.len())
        .map(|j| dist(&samples[j], &samples[j - p]) <= thr)
        .collect()
}

/// The laminar-phase analysis of `samples` with the confirmed period, or the best lag.
pub fn laminar(samples: &[[f64; 4]], period: Option<u32>, tol: f64) -> Laminar {
    let len = samples.len();
    let s = (0..4)
        .map(|i| {
            let (lo, hi) = samples
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |a, y| {
                    (a.0.min(y[i]), a.1.max(y[i]))
                });
            hi - lo
        })
        .fold(0.0, f64::max);
    let scale = s.max(1.0);
    let thr = tol * scale;
    let most = (len.saturating_sub(1) as u32).clamp(1, MAX_LAG);
    let (lag, lag_rule) = match period.filter(|&n| (n as usize) < len) {
        Some(n) => (
            n,
            format!("p = {n}, the period of the Newton-confirmed cycle"),
        ),
        None => {
            let counts: Vec<usize> = (1..=most)
                .map(|p| {
                    returns(samples, p as usize, thr)
                        .iter()
                        .filter(|r| **r)
                        .count()
                })
                .collect();
            let best = counts.iter().copied().max().unwrap_or(0);
            let p = counts
                .iter()
                .position(|&c| c > 0 && c as f64 >= LAG_SHARE * best as f64)
                .map_or(1, |i| i as u32 + 1);
            (
                p,
                format!(
                    "p = {p}: no confirmed period, so the smallest lag in 1..={most} with at \
                     least {:.0}% of the most returns of any lag there",
                    100.0 * LAG_SHARE
                ),
            )
        }
    };
    let p = lag as usize;
    let ret = returns(samples, p, thr);
    let mut episodes = Vec::new();
    let mut i = 0;
    while i < ret.len() {
        if !ret[i] {
            i += 1;
            continue;
        }
        let a = i;
        while i < ret.len() && ret[i] {
            i += 1;
        }
        let b = i - 1;
        // Return i is sampled period k = i + p + 1 (periods count from 1).
        episodes.push(Episode {
            first: (a + p) as u32 + 1,
            last: (b + p) as u32 + 1,
            length: (b - a + 1) as u32,
            censored: a == 0 || b + 1 == ret.len(),
        });
    }
    Laminar {
        lag,
        lag_rule,
        tol,
        span: s,
        scale,
        threshold: thr,
        rule: RULE,
        returns: ret.iter().filter(|r| **r).count(),
        comparisons: ret.len(),
        histogram: histogram(&episodes),
        episodes,
    }
}

/// Bins of equal integer width covering the episode lengths, at most [`MAX_BINS`].
fn histogram(episodes: &[Episode]) -> Vec<Bin> {
    let (Some(lo), Some(hi)) = (
        episodes.iter().map(|e| e.length).min(),
        episodes.iter().map(|e| e.length).max(),
    ) else {
        return Vec::new();
    };
    let w = (hi - lo + 1).div_ceil(MAX_BINS).max(1);
    let start = lo / w * w;
    let n = (hi - start) / w + 1;
    let mut bins: Vec<Bin> = (0..n)
        .map(|k| Bin {
            from: start + k * w,
            to: start + (k + 1) * w,
            count: 0,
        })
        .collect();
    for e in episodes {
        bins[((e.length - start) / w) as usize].count += 1;
    }
    bins
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(y1: f64) -> [f64; 4] {
        [y1, 0.0, 0.0, 0.0]
    }

    #[test]
    fn periodic_record_is_one_episode() {
        let s: Vec<[f64; 4]> = (0..50).map(|k| state((k % 2) as f64)).collect();
        let l = laminar(&s, Some(2), 1e-3);
        assert_eq!(l.episodes.len(), 1);
        assert_eq!(l.episodes[0].length, 48);
        assert_eq!((l.episodes[0].first, l.episodes[0].last), (3, 50));
        assert!(l.episodes[0].censored);
        assert_eq!(l.histogram.iter().map(|b| b.count).sum::<u32>(), 1);
    }

    #[test]
    fn bursts_split_episodes_and_the_lag_is_found() {
        // Period 1 near 0.5 for 10 points, a burst, then 20 points: lag 1 is found.
        let mut s: Vec<[f64; 4]> = vec![state(0.5); 10];
        s.extend([state(0.1), state(0.9), state(0.3)]);
        s.extend(vec![state(0.7); 20]);
        let l = laminar(&s, None, 1e-3);
        assert_eq!(l.lag, 1);
        let lens: Vec<u32> = l.episodes.iter().map(|e| e.length).collect();
        assert_eq!(lens, [9, 19]);
        assert_eq!((l.episodes[0].first, l.episodes[0].last), (2, 10));
        assert_eq!((l.episodes[1].first, l.episodes[1].last), (15, 33));
        assert_eq!(l.histogram.iter().map(|b| b.count).sum::<u32>(), 2);
    }
}
