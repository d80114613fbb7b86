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
    /// No period <= 64 found, no Lyapunov estimate to tell quasi-periodic from chaotic.
    Aperiodic,
    /// No period <= 64 and a Lyapunov exponent of about zero.
    QuasiPeriodic,
    /// No period <= 64 and a positive Lyapunov exponent.
    Chaotic,
    /// Period detector and Lyapunov exponent disagree (e.g. still converging, period > 64).
    Unresolved,
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
            Class::QuasiPeriodic => "quasi_periodic".into(),
            Class::Chaotic => "chaotic".into(),
            Class::Unresolved => "unresolved".into(),
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
    /// Compact numeric code for arrays: n > 0 period-n, 0 aperiodic, -1 no impact, -2 failed,
    /// -3 quasi-periodic, -4 chaotic, -5 unresolved.
    pub fn code(&self) -> i32 {
        match self {
            Class::Periodic(n) => *n as i32,
            Class::Aperiodic => 0,
            Class::NoImpact => -1,
            Class::Failed => -2,
            Class::QuasiPeriodic => -3,
            Class::Chaotic => -4,
            Class::Unresolved => -5,
        }
    }

    pub fn from_code(c: i32) -> Class {
        match c {
            n if n > 0 => Class::Periodic(n as u32),
            0 => Class::Aperiodic,
            -1 => Class::NoImpact,
            -3 => Class::QuasiPeriodic,
            -4 => Class::Chaotic,
            -5 => Class::Unresolved,
            _ => Class::Failed,
        }
    }

    /// Splits `Aperiodic` by the Lyapunov exponent `lyap` (per unit time): above `tol`
    /// chaotic, within +-tol quasi-periodic, below -tol unresolved (contracting but no period
    /// <= 64 found). A periodic class with a clearly positive exponent is unresolved too. A
    /// NaN exponent (not computed, twin failed) leaves the class as it is.
    pub fn with_lyapunov(self, lyap: f64, tol: f64) -> Class {
        if lyap.is_nan() {
            return self;
        }
        match self {
            Class::Periodic(_) if lyap > tol => Class::Unresolved,
            Class::Aperiodic if lyap > tol => Class::Chaotic,
            Class::Aperiodic if lyap >= -tol => Class::QuasiPeriodic,
            Class::Aperiodic => Class::Unresolved,
            c => c,
        }
    }
}

/// Incremental period detector over the stroboscopic section value y1, the twin of the
/// kernel's on-GPU classification: a ring of the last 64 values, and one "still possible" bit
/// per candidate period n. Each new value is compared with the values 1..64 samples back,
/// within `rel_tol * max(1, span)` where span is the range of y1 seen so far (a period-n orbit
/// has shown its whole range after n samples, before any lag-n comparison matters).
#[derive(Clone, Debug)]
pub struct PeriodDetector {
    ring: [f64; MAX_PERIOD],
    count: u32,
    lo: f64,
    hi: f64,
    /// Bit n-1 set: period n not yet contradicted.
    possible: u64,
    rel_tol: f64,
}

impl PeriodDetector {
    pub fn new(rel_tol: f64) -> Self {
        PeriodDetector {
            ring: [0.0; MAX_PERIOD],
            count: 0,
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
            possible: u64::MAX,
            rel_tol,
        }
    }

    pub fn push(&mut self, x: f64) {
        self.lo = self.lo.min(x);
        self.hi = self.hi.max(x);
        let tol = self.rel_tol * (self.hi - self.lo).max(1.0);
        let lags = (self.count as usize).min(MAX_PERIOD);
        for n in 1..=lags {
            let past = self.ring[(self.count as usize - n) % MAX_PERIOD];
            // Written so that NaN counts as a mismatch.
            let close = (x - past).abs() <= tol;
            if !close {
                self.possible &= !(1u64 << (n - 1));
            }
        }
        self.ring[self.count as usize % MAX_PERIOD] = x;
        self.count += 1;
    }

    /// Smallest period not contradicted and seen at least twice over.
    pub fn period(&self) -> Option<u32> {
        Self::period_from(self.possible, self.count)
    }

    /// [`PeriodDetector::period`] from the detector's bits and sample count (as the kernel
    /// leaves them).
    pub fn period_from(possible: u64, count: u32) -> Option<u32> {
        (1..=MAX_PERIOD as u32).find(|&n| possible & (1u64 << (n - 1)) != 0 && count >= 2 * n)
    }
}

/// Period of a sample sequence by [`PeriodDetector`] on y1.
pub fn detect_period(samples: &[[f64; 4]], rel_tol: f64) -> Option<u32> {
    let mut d = PeriodDetector::new(rel_tol);
    for s in samples {
        d.push(s[0]);
    }
    d.period()
}

/// Classifies a run.
pub fn classify(samples: &[[f64; 4]], sample_impacts: u64, nonfinite: bool, rel_tol: f64) -> Class {
    let bad = nonfinite || samples.iter().flatten().any(|v| !v.is_finite());
    class_of(bad, samples.len(), sample_impacts, || {
        detect_period(samples, rel_tol)
    })
}

/// The class rule shared by the CPU and the GPU detector.
pub fn class_of(
    nonfinite: bool,
    n_samples: usize,
    sample_impacts: u64,
    period: impl FnOnce() -> Option<u32>,
) -> Class {
    if nonfinite || n_samples < 2 {
        return Class::Failed;
    }
    if sample_impacts == 0 {
        return Class::NoImpact;
    }
    period().map_or(Class::Aperiodic, Class::Periodic)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quasi_periodic_rotation_is_aperiodic() {
        // Points on a circle rotated by an irrational angle never repeat.
        let s: Vec<[f64; 4]> = (0..200)
            .map(|i| {
                let a = i as f64 * 2.0 * std::f64::consts::PI * 0.618_034;
                [a.cos(), a.sin(), 0.0, 0.0]
            })
            .collect();
        assert_eq!(detect_period(&s, 1e-4), None);
    }

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
