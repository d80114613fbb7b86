//! The one classifier of every command (map, bifurcation, point, basin): what a run's evidence
//! says the motion is, and by which rule.
//!
//! Evidence, gathered alike by the GPU kernel and its CPU twin: the period detector over the
//! section value y1 ([`PeriodDetector`], strict tolerance), the last [`MAX_PERIOD`] section
//! values (they propose candidate periods with a relaxed tolerance, [`candidate_lags`]), the
//! largest Lyapunov exponent with its batch-means standard error ([`Growth`]) and a torus test,
//! weighted Birkhoff averages of y1 over the two halves of the sampled window ([`Birkhoff`]).
//! [`decide`] turns it into a class; only a Newton-confirmed stable cycle is periodic, only an
//! exponent positive by [`CHAOS_MARGIN`] standard errors is chaotic, only a passed torus test
//! is quasi-periodic, and everything else is undecided (the adaptive loop gives it more time).

use crate::class::Class;
use serde::Serialize;

/// Largest period the detector looks for.
pub const MAX_PERIOD: usize = crate::class::MAX_PERIOD as usize;

/// Section values of y1 kept per point for the candidate periods (the kernel's ring; the
/// detector reads the last MAX_PERIOD of them).
pub const TAIL: usize = 256;

/// Batches of the exponent's standard error: the sampled periods are cut into this many blocks
/// of equal length (the rest of a window that does not divide is left out of the error, not of
/// the exponent), and the spread of the block estimates gives the error of their mean.
pub const BLOCKS: u32 = 10;

/// Periods per block of a window of `samples` sampled periods.
pub fn block_len(samples: u32) -> u32 {
    (samples / BLOCKS).max(1)
}

/// A cell is chaotic only where its exponent exceeds this many standard errors (a one-sided
/// 99% bound for the mean of 10 batch means has t = 2.82 on 9 degrees of freedom).
pub const CHAOS_MARGIN: f64 = 3.0;

/// Log growth of the Lyapunov tangent vector per sampled period, summed for the exponent and in
/// blocks for its standard error (batch means, Welford's update of the blocks' mean and
/// spread). The kernel keeps the same sums in its ring (R_LOG_SUM, R_BLOCK*).
#[derive(Clone, Copy, Debug)]
pub struct Growth {
    sum: f64,
    count: u32,
    len: u32,
    block: f64,
    blocks: u32,
    mean: f64,
    m2: f64,
}

impl Growth {
    /// Accumulator for a window of `samples` periods.
    pub fn new(samples: u32) -> Growth {
        Growth {
            sum: 0.0,
            count: 0,
            len: block_len(samples),
            block: 0.0,
            blocks: 0,
            mean: 0.0,
            m2: 0.0,
        }
    }

    /// The log growth of one more period.
    pub fn push(&mut self, log: f64) {
        self.sum += log;
        self.count += 1;
        self.block += log;
        if self.count.is_multiple_of(self.len) {
            if self.blocks < BLOCKS {
                self.blocks += 1;
                let d = self.block - self.mean;
                self.mean += d / f64::from(self.blocks);
                self.m2 += d * (self.block - self.mean);
            }
            self.block = 0.0;
        }
    }

    /// The exponent and its standard error per unit time, for forcing period `period`, from
    /// the sums as the kernel leaves them: `sum` over `count` periods, `blocks` blocks of
    /// `len` periods with Welford's `m2`. NaN error with fewer than two blocks.
    pub fn exponent_from(
        sum: f64,
        count: u32,
        len: u32,
        blocks: u32,
        m2: f64,
        period: f64,
    ) -> Exponent {
        if count == 0 {
            return Exponent::NONE;
        }
        let lyap = sum / (f64::from(count) * period);
        let se = if blocks >= 2 {
            let var = m2.max(0.0) / f64::from(blocks - 1);
            (var / f64::from(blocks)).sqrt() / (f64::from(len) * period)
        } else {
            f64::NAN
        };
        Exponent { value: lyap, se }
    }

    /// [`Growth::exponent_from`] of this accumulator.
    pub fn exponent(&self, period: f64) -> Exponent {
        Self::exponent_from(self.sum, self.count, self.len, self.blocks, self.m2, period)
    }
}

/// The exponent pooled over the sampled windows a point ran (the configured one and those of the
/// adaptive horizon), each estimate weighted by its inverse variance: the error shrinks with
/// every window instead of starting again.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pool {
    weight: f64,
    weighted: f64,
}

impl Pool {
    /// Adds a window's exponent; returns the pooled one. A window without a finite error
    /// (no exponent) leaves the pool as it was and gives its own exponent back.
    pub fn add(&mut self, e: Exponent) -> Exponent {
        if !(e.value.is_finite() && e.se.is_finite()) {
            return e;
        }
        // A zero error (a window whose blocks agree to round-off) counts as a tiny one.
        let w = 1.0 / e.se.max(1e-12).powi(2);
        self.weight += w;
        self.weighted += w * e.value;
        Exponent {
            value: self.weighted / self.weight,
            se: self.weight.sqrt().recip(),
        }
    }
}

/// The largest Lyapunov exponent per unit time and its standard error by batch means
/// ([`Growth`]); both NaN where it was not computed, or lost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Exponent {
    pub value: f64,
    pub se: f64,
}

impl Exponent {
    /// No exponent.
    pub const NONE: Exponent = Exponent {
        value: f64::NAN,
        se: f64::NAN,
    };

    /// Whether the exponent is positive by [`CHAOS_MARGIN`] standard errors.
    pub fn clearly_positive(&self) -> bool {
        self.se.is_finite() && self.value > CHAOS_MARGIN * self.se
    }

    /// Whether the exponent is negative by [`CHAOS_MARGIN`] standard errors.
    pub fn clearly_negative(&self) -> bool {
        self.se.is_finite() && self.value < -CHAOS_MARGIN * self.se
    }
}

/// The torus test: weighted Birkhoff averages of the section value y1 over the first and the
/// second half of the sampled window, with the smooth bump weight exp(-1/(t(1-t))) of Das,
/// Sander, Saiki and Yorke (2017). On a quasi-periodic orbit (and on a settled cycle) such
/// averages converge faster than any power of the window; on chaos like 1/sqrt(window); a
/// transient drifts between the halves. [`Birkhoff::digits`] says how many digits of the
/// averages agree, relative to the range of y1. The weights are computed in f32 on both sides
/// (f64 `exp` is unreliable in kernels); the kernel keeps the same sums (R_WB_*).
#[derive(Clone, Copy, Debug)]
pub struct Birkhoff {
    half: u32,
    k: u32,
    num: f64,
    den: f64,
    first: f64,
    second: f64,
    lo: f64,
    hi: f64,
}

/// Weight of the k-th value (from 0) of a half window of `half` values.
pub fn birkhoff_weight(k: u32, half: u32) -> f64 {
    let t = (k as f32 + 1.0) / (half as f32 + 1.0);
    f64::from((-1.0 / (t * (1.0 - t))).exp())
}

/// The digits [`Birkhoff`] reports from the two halves' averages and the range of y1: the
/// range floors at 1e-9 (a fixed point: agreement to round-off counts as many digits); NaN
/// without two full halves.
pub fn birkhoff_digits(first: f64, second: f64, lo: f64, hi: f64) -> f64 {
    let scale = (hi - lo).max(1e-9);
    let d = (first - second).abs() / scale;
    if !d.is_finite() {
        return f64::NAN;
    }
    -(d.max(1e-16)).log10()
}

impl Birkhoff {
    /// Test over a window of `samples` values (halves of samples / 2; an odd last value is
    /// left out).
    pub fn new(samples: u32) -> Birkhoff {
        Birkhoff {
            half: samples / 2,
            k: 0,
            num: 0.0,
            den: 0.0,
            first: f64::NAN,
            second: f64::NAN,
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
        }
    }

    pub fn push(&mut self, x: f64) {
        if self.half == 0 || self.k >= 2 * self.half {
            return;
        }
        self.lo = self.lo.min(x);
        self.hi = self.hi.max(x);
        let w = birkhoff_weight(self.k % self.half, self.half);
        self.num += w * x;
        self.den += w;
        self.k += 1;
        if self.k == self.half {
            self.first = self.num / self.den;
            (self.num, self.den) = (0.0, 0.0);
        } else if self.k == 2 * self.half {
            self.second = self.num / self.den;
        }
    }

    /// Agreeing digits of the two halves' averages (NaN before both are complete).
    pub fn digits(&self) -> f64 {
        birkhoff_digits(self.first, self.second, self.lo, self.hi)
    }
}

/// A torus test passes at this many agreeing digits. Measured separation (tests/classes.rs and
/// docs/classes.md): an invariant circle of a map passes with 8-16 digits over a window of 100,
/// chaos gives 1-3, a cycle still converging gives what its drift leaves.
pub const TORUS_DIGITS: f64 = 5.0;

/// Longest candidate period proposed from the last [`TAIL`] section values (a lag needs as many
/// values again to be seen twice). The judged sample of docs/classes.md has stable cycles of
/// periods 40 to 120 that only a candidate beyond 32 confirms.
pub const MAX_TRIAL_PERIOD: u32 = TAIL as u32 / 2;

/// Relaxed tolerance of the candidate periods, relative to the range of y1 over the last values:
/// a cycle still converging repeats to within it long before the strict detector accepts it (a
/// period-2 cycle with multiplier -0.98 at R = 0.696, lambda = 0.068 repeats to 0.036 of its range
/// after 400 periods), while chaos differs at every lag by a good part of its range.
pub const CANDIDATE_TOL: f64 = 0.1;

/// A lag whose last 32 differences are at most this fraction of its first 32 (where the tail
/// holds both) is converging: a candidate even beyond [`CANDIDATE_TOL`], up to half the range
/// (a slow spiral into a cycle with a complex multiplier pair differs at every lag by a good part
/// of its shrinking range, at Fig. 2's eta = 1.71 for instance), while a torus's near-returns
/// and chaos's do not shrink.
pub const CONVERGING: f64 = 0.5;

/// Candidate periods at most this many are tried by Newton per point, besides the detector's
/// (a second candidate confirmed 16 cycles in 1,350 trials on the 128 x 128 R x lambda map).
pub const MAX_CANDIDATES: usize = 1;

/// A lag that repeats to this fraction of the range is a candidate, converging or not (a cycle
/// of period > 64 that has settled, which the strict detector cannot see).
pub const SETTLED: f64 = 1e-3;

/// A lag that the last values suggest, and how its near-repeat evolved over the tail.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    pub period: u32,
    /// Largest |x_k - x_(k-n)| over the last values, relative to their range.
    pub recent: f64,
    /// The same over the first values of the tail and the number of periods between the two
    /// windows; None where the tail holds only one window.
    pub decay: Option<(f64, u32)>,
}

/// Lag `n` scored on the last values `tail` (None where the tail is shorter than 2n or flat):
/// the largest |x_k - x_(k-n)| over the last w = min(32, len - n) values relative to their
/// range, and over the first w where the two windows are apart.
pub fn candidate_at(tail: &[f64], n: usize) -> Option<Candidate> {
    scored(tail, n, range(tail))
}

/// Range of the values (the scale of the candidates' differences: relative to the range
/// itself, a small attractor, a young torus, does not repeat at every lag by scale alone).
fn range(tail: &[f64]) -> f64 {
    let (lo, hi) = tail
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    hi - lo
}

/// [`candidate_at`] with the tail's range `span`.
fn scored(tail: &[f64], n: usize, span: f64) -> Option<Candidate> {
    let len = tail.len();
    if n == 0 || len < 2 * n || span.is_nan() || span <= 0.0 {
        return None;
    }
    let worst = |ks: std::ops::Range<usize>| {
        ks.map(|k| (tail[k] - tail[k - n]).abs())
            .fold(
                0.0f64,
                |a, b| if b.is_nan() { f64::INFINITY } else { a.max(b) },
            )
            / span
    };
    let w = (len - n).min(32);
    Some(Candidate {
        period: n as u32,
        recent: worst(len - w..len),
        decay: (len - n >= 2 * w).then(|| (worst(n..n + w), (len - w - n) as u32)),
    })
}

/// Periods that the last section values `tail` (oldest first) suggest: each lag n <=
/// [`MAX_TRIAL_PERIOD`] with at least 2n values, scored by the largest |x_k - x_(k-n)| over the
/// last w = min(32, len - n) values (and over the first w, where the two windows are apart),
/// counts where it is [`SETTLED`], [`CONVERGING`] within half of the range, or not growing
/// within [`CANDIDATE_TOL`] (within [`CANDIDATE_TOL`] where the tail is too short for two
/// windows). Best
/// (smallest recent difference) first, at most [`MAX_CANDIDATES`].
pub fn candidate_lags(tail: &[f64]) -> Vec<Candidate> {
    lags(tail, 1.0)
}

/// [`candidate_lags`] where a near-repeat may grow by `growth` over the tail and still count as
/// not growing.
fn lags(tail: &[f64], growth: f64) -> Vec<Candidate> {
    let span = range(tail);
    let mut found: Vec<Candidate> = (1..=MAX_TRIAL_PERIOD as usize)
        .filter_map(|n| {
            let c = scored(tail, n, span)?;
            let converging = c
                .decay
                .is_some_and(|(early, _)| c.recent <= CONVERGING * early);
            // Near-repeats that do not grow: a weakly stable cycle spirals in slower than the
            // tail shows (|mu| = 0.998 near Fig. 2's Neimark-Sacker point).
            let steady = c.decay.is_some_and(|(early, _)| c.recent <= growth * early);
            let ok = if c.decay.is_some() {
                converging && c.recent <= 0.5
                    || steady && c.recent <= CANDIDATE_TOL
                    || c.recent <= SETTLED
            } else {
                c.recent <= CANDIDATE_TOL
            };
            ok.then_some(c)
        })
        .collect();
    found.sort_by(|a, b| a.recent.total_cmp(&b.recent).then(a.period.cmp(&b.period)));
    found.truncate(MAX_CANDIDATES);
    found
}

/// A cycle that Newton found at a candidate period (not the strict detector's) counts only where
/// the run is seen to approach it: its final state lies within this of the cycle point, relative
/// to the range of the last section values (every component), or the candidate's near-repeat
/// shrank over the tail as the cycle's leading multiplier predicts, to within a factor of
/// [`DECAY_FACTOR`]. A trajectory that merely passes a stable cycle of another basin is not on
/// it; a cycle approached from farther away is confirmed in a later window.
pub const NEAR: f64 = 1e-2;
/// See [`NEAR`].
pub const DECAY_FACTOR: f64 = 3.0;

/// Whether the run with the last values `tail`, final state `y` and the candidate `cand` is on
/// the stable cycle through `c` of leading multiplier modulus `mu`.
pub fn approaches(tail: &[f64], y: &[f64; 4], cand: &Candidate, c: &[f64; 4], mu: f64) -> bool {
    let (lo, hi) = tail
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let tol = NEAR * (hi - lo);
    if (0..4).all(|i| (y[i] - c[i]).abs() <= tol) {
        return true;
    }
    cand.decay.is_some_and(|(early, gap)| {
        let predicted = mu.powf(f64::from(gap) / f64::from(cand.period));
        let observed = cand.recent / early;
        observed <= DECAY_FACTOR * predicted
    })
}

/// Which rule decided a point (counted in the map's caption).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Hash)]
#[serde(rename_all = "snake_case")]
pub enum Rule {
    /// Non-finite state or too few samples.
    Failed,
    /// No impact in the sampled window.
    NoImpact,
    /// Newton converged to a cycle with every multiplier inside the unit circle.
    StableCycle,
    /// Exponent above CHAOS_MARGIN standard errors.
    PositiveExponent,
    /// Torus test passed with an exponent within its error of zero.
    Torus,
    /// No exponent was computed (run.tangent = "none"): aperiodic.
    NoExponent,
    /// Nothing decided it.
    Undecided,
    /// An exponent was asked for but the tangent vector overflowed (f32): unresolved, not
    /// aperiodic ([`NoExponent`](Rule::NoExponent) is for runs that asked for none).
    ExponentLost,
    /// The motion looked chaotic beside a stable cycle carried from a neighbour, and copies of
    /// it landed on that cycle ([`crate::escape`]): the chaos was a transient.
    Escaped,
}

impl Rule {
    pub const ALL: [Rule; 9] = [
        Rule::StableCycle,
        Rule::PositiveExponent,
        Rule::Torus,
        Rule::NoImpact,
        Rule::Failed,
        Rule::NoExponent,
        Rule::Undecided,
        Rule::ExponentLost,
        Rule::Escaped,
    ];
    /// Compact code for arrays: the position in [`Rule::ALL`] (an inferred cell keeps its
    /// corners' rule).
    pub fn code(self) -> u8 {
        Rule::ALL.iter().position(|&r| r == self).unwrap_or(0) as u8
    }

    pub fn name(self) -> &'static str {
        match self {
            Rule::Failed => "failed",
            Rule::NoImpact => "no_impact",
            Rule::StableCycle => "stable_cycle",
            Rule::PositiveExponent => "positive_exponent",
            Rule::Torus => "torus",
            Rule::NoExponent => "no_exponent",
            Rule::Undecided => "undecided",
            Rule::ExponentLost => "exponent_lost",
            Rule::Escaped => "escaped",
        }
    }
}

/// What a run shows, as every backend gathers it.
#[derive(Clone, Copy, Debug)]
pub struct Evidence<'a> {
    /// The class by the strict detector, impacts and finiteness ([`class_of`]).
    pub detected: Class,
    /// The last section values of y1, oldest first.
    pub tail: &'a [f64],
    /// Largest exponent and its standard error per unit time (NaN when not computed).
    pub lyapunov: Exponent,
    /// Agreeing digits of the torus test (NaN when the window had no two halves).
    pub torus: f64,
    /// The exponent was asked for and lost ([`crate::method::RunResult::exponent_lost`]).
    pub exponent_lost: bool,
}

/// The periods Newton is to try, in order: the strict detector's (its cycle needs no more than
/// stability), then the candidates (not where the exponent is clearly positive: a chaotic
/// window's near-repeats are not cycles, and trying them cost more than the map's integration),
/// then period 1 where nothing else could decide the point and `last_resort` is set.
pub fn proposals(e: &Evidence, last_resort: bool) -> Vec<(u32, Option<Candidate>)> {
    let mut out = match e.detected {
        Class::Failed | Class::NoImpact => return Vec::new(),
        Class::Periodic(n) => vec![(n, None)],
        _ => Vec::new(),
    };
    if e.lyapunov.clearly_positive() {
        return out;
    }
    // Without an exponent (sweeps) nothing else can decide the point, and a weakly stable
    // cycle's near-repeats (|mu| = 0.9997 next to Fig. 2's Neimark-Sacker point) fluctuate
    // with the phase of its spiral: they may grow by half and still propose the lag, whose
    // cycle must then still show the decay its multiplier predicts ([`approaches`]).
    let growth = if e.lyapunov.value.is_nan() { 1.5 } else { 1.0 };
    for c in lags(e.tail, growth) {
        if !out.iter().any(|t| t.0 == c.period) {
            out.push((c.period, Some(c)));
        }
    }
    // Without an exponent, or with one clearly negative (a stable cycle not yet settled enough
    // for the detector), also period 1: Newton at a long lag may not converge from a wide
    // spiral that Newton at period 1 follows in. Only as a `last_resort`: in a map's early
    // rounds (no exponent, 32 periods) it found no cycle the run was on in 36,554 trials of
    // the 256 x 256 R x lambda map, a third of their Newton time.
    if last_resort
        && (e.lyapunov.value.is_nan() || e.lyapunov.clearly_negative())
        && !out.iter().any(|t| t.0 == 1)
        && let Some(c) = candidate_at(e.tail, 1)
    {
        out.push((1, Some(c)));
    }
    out
}

/// A torus's exponent is zero: quasi-periodic needs the exponent shown to be within this of
/// zero (per unit time), |exponent| + [`CHAOS_MARGIN`] standard errors. Weak chaos that the
/// torus test lets through over a short window has errors of 0.0025-0.0055 (the judged sample of
/// docs/classes.md), the tori there 0.0001-0.0004, and a stable cycle of period 72 with
/// |mu| = 0.003 at eta = 1.26 has an exponent of -0.016.
pub const TORUS_BOUND: f64 = 2e-3;

/// The class, and the rule that gave it, once Newton tried the [`proposals`]: `stable` is the
/// least period of a stable cycle it found.
pub fn conclude(e: &Evidence, stable: Option<u32>) -> (Class, Rule) {
    match e.detected {
        Class::Failed => return (Class::Failed, Rule::Failed),
        Class::NoImpact => return (Class::NoImpact, Rule::NoImpact),
        _ => {}
    }
    if let Some(n) = stable {
        return (Class::Periodic(n), Rule::StableCycle);
    }
    let (l, se) = (e.lyapunov.value, e.lyapunov.se);
    if l.is_nan() && e.exponent_lost {
        return (Class::Unresolved, Rule::ExponentLost);
    }
    if l.is_nan() {
        return (Class::Aperiodic, Rule::NoExponent);
    }
    if e.lyapunov.clearly_positive() {
        return (Class::Chaotic, Rule::PositiveExponent);
    }
    let near_zero = se.is_finite() && l.abs() + CHAOS_MARGIN * se <= TORUS_BOUND;
    if near_zero && e.torus >= TORUS_DIGITS {
        return (Class::QuasiPeriodic, Rule::Torus);
    }
    (Class::Unresolved, Rule::Undecided)
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

/// The last [`TAIL`] values of y1 of `samples`, oldest first.
pub fn tail_of(samples: &[[f64; 4]]) -> Vec<f64> {
    samples[samples.len().saturating_sub(TAIL)..]
        .iter()
        .map(|s| s[0])
        .collect()
}

/// Classifies a run by the strict detector.
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
