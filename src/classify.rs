//! Classification of stroboscopic samples: period-n, aperiodic, no impact, failed.
//! The GPU kernel applies the same rule to a ring of the last 64 section values.

use serde::Serialize;

/// Largest period the detector looks for.
pub const MAX_PERIOD: usize = 64;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(tag = "class", content = "period", rename_all = "snake_case")]
pub enum Class {
    /// The section repeats after `n` forcing periods.
    Periodic(u32),
    /// No period <= 64 found (quasi-periodic or chaotic).
    Aperiodic,
    /// No impact during the sampled periods.
    NoImpact,
    /// Non-finite state, or too few samples to decide.
    Failed,
}

impl Class {
    pub fn name(&self) -> String {
        match self {
            Class::Periodic(n) => format!("period-{n}"),
            Class::Aperiodic => "aperiodic".into(),
            Class::NoImpact => "no_impact".into(),
            Class::Failed => "failed".into(),
        }
    }
    pub fn period(&self) -> Option<u32> {
        match self {
            Class::Periodic(n) => Some(*n),
            _ => None,
        }
    }
    /// Compact numeric code for arrays: n > 0 period, 0 aperiodic, -1 no impact, -2 failed.
    pub fn code(&self) -> i32 {
        match self {
            Class::Periodic(n) => *n as i32,
            Class::Aperiodic => 0,
            Class::NoImpact => -1,
            Class::Failed => -2,
        }
    }
}

/// Tolerance of the period test: `rel_tol` times the attractor size (largest range of any
/// state component over the samples), floored so that a fixed point still gets a tolerance.
pub fn tolerance(samples: &[[f64; 4]], rel_tol: f64) -> f64 {
    let mut span: f64 = 0.0;
    for c in 0..4 {
        let (lo, hi) = samples
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
                (lo.min(s[c]), hi.max(s[c]))
            });
        span = span.max(hi - lo);
    }
    rel_tol * span.max(1.0)
}

/// Smallest n <= 64 with |x[i+n] - x[i]| <= tol for every sample pair and component.
/// Only the last `min(len, 2*64)` samples are used, as in the kernel's ring buffer.
pub fn detect_period(samples: &[[f64; 4]], rel_tol: f64) -> Option<u32> {
    let tol = tolerance(samples, rel_tol);
    let len = samples.len();
    (1..=MAX_PERIOD.min(len / 2))
        .find(|&n| {
            (0..len - n).all(|i| (0..4).all(|c| (samples[i + n][c] - samples[i][c]).abs() <= tol))
        })
        .map(|n| n as u32)
}

/// Classifies a run.
pub fn classify(samples: &[[f64; 4]], sample_impacts: u64, nonfinite: bool, rel_tol: f64) -> Class {
    if nonfinite || samples.len() < 2 || samples.iter().flatten().any(|v| !v.is_finite()) {
        return Class::Failed;
    }
    if sample_impacts == 0 {
        return Class::NoImpact;
    }
    match detect_period(samples, rel_tol) {
        Some(n) => Class::Periodic(n),
        None => Class::Aperiodic,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn orbit(n: usize, len: usize, noise: f64) -> Vec<[f64; 4]> {
        (0..len)
            .map(|i| {
                let k = (i % n) as f64;
                let e = noise * ((i * i) as f64 * 0.618_034).fract();
                [k + e, -k, 0.5 * k, 1.0]
            })
            .collect()
    }

    #[test]
    fn finds_smallest_period() {
        assert_eq!(detect_period(&orbit(3, 200, 0.0), 1e-4), Some(3));
        assert_eq!(detect_period(&orbit(1, 200, 0.0), 1e-4), Some(1));
        assert_eq!(detect_period(&orbit(17, 200, 1e-6), 1e-4), Some(17));
    }

    #[test]
    fn noise_above_tolerance_is_aperiodic() {
        assert_eq!(detect_period(&orbit(3, 200, 1e-2), 1e-4), None);
        assert_eq!(
            classify(&orbit(3, 200, 1e-2), 10, false, 1e-4),
            Class::Aperiodic
        );
    }

    #[test]
    fn no_impact_and_failed() {
        assert_eq!(
            classify(&orbit(2, 10, 0.0), 0, false, 1e-4),
            Class::NoImpact
        );
        assert_eq!(classify(&orbit(2, 10, 0.0), 5, true, 1e-4), Class::Failed);
        let mut s = orbit(2, 10, 0.0);
        s[3][1] = f64::NAN;
        assert_eq!(classify(&s, 5, false, 1e-4), Class::Failed);
    }
}
