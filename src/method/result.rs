//! What a run is told (the method's [`Settings`]) and what it gives back (the per-point
//! [`PointState`], [`Diagnostics`] and [`RunResult`]).

use crate::model::Mode;
use serde::{Deserialize, Serialize};

/// How impacts are handled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ImpactMethod {
    /// Locate the impact inside the step (fourth order).
    #[default]
    Located,
    /// Apply the impact at the end of the step and clamp the position (first order);
    /// kept only as a comparison method.
    Naive,
}

/// Numerical settings of the method.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Settings {
    pub steps_per_period: u32,
    pub max_events: u32,
    pub zeno_speed: f64,
    pub impacts: ImpactMethod,
    /// Estimate the largest Lyapunov exponent over the sampled periods (one tangent vector
    /// carried through the state's RK4 stages and events).
    pub lyapunov: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            steps_per_period: 256,
            max_events: 32,
            zeno_speed: 1e-4,
            impacts: ImpactMethod::Located,
            lyapunov: false,
        }
    }
}

/// Per-point diagnostics.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Diagnostics {
    pub impacts: u64,
    /// Entries into STICK.
    pub sticks: u64,
    /// Entries into LOCK+ or LOCK- (end of a chattering sequence).
    pub locks: u64,
    /// Steps whose event budget ran out (finished without further event handling).
    pub overflows: u64,
    /// Steps that ended in a slip mode with the slip velocity against the mode's direction
    /// (friction pushing the wrong way): an event the integrator missed. Zero is the invariant.
    pub wrong_slips: u64,
    /// The state became non-finite; integration stopped there.
    pub nonfinite: bool,
    /// Computed by the CPU twin because the GPU driver cut the kernel's loops short.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub cpu_rerun: bool,
    /// Sum and largest of the impact speeds |y2 - y4| just before each impact since sampling
    /// started ([`RunResult::impact_speed`] reports them per sampled window).
    #[serde(skip)]
    pub impact_speed: [f64; 2],
    /// Energy dissipated since sampling started, in units of m1 (as the state): by impacts
    /// (the kinetic energy of the relative motion they take, also where one ends in
    /// co-motion) and by friction (the integral of T v, by the RK4 stages).
    #[serde(skip)]
    pub dissipated: [f64; 2],
    /// Time the masses moved together (stick or lock) since sampling started, in grid steps.
    #[serde(skip)]
    pub stuck_steps: f64,
}

/// Mean and largest impact speed of `impacts` impacts counted in `d` (NaN without any).
pub fn impact_speed(d: &Diagnostics, impacts: u64) -> [f64; 2] {
    if impacts == 0 {
        return [f64::NAN; 2];
    }
    [d.impact_speed[0] / impacts as f64, d.impact_speed[1]]
}

/// Energy dissipated per sampled period by impacts and by friction, and the fraction of the
/// time the masses moved together, over `periods` sampled periods of `steps` grid steps each
/// (NaN without a sampled period).
pub fn energy(d: &Diagnostics, periods: usize, steps: u32) -> ([f64; 2], f64) {
    if periods == 0 {
        return ([f64::NAN; 2], f64::NAN);
    }
    let n = periods as f64;
    (
        d.dissipated.map(|e| e / n),
        d.stuck_steps / (n * steps as f64),
    )
}

impl Diagnostics {
    /// Counts an impact whose relative velocity went from `vb` to `va` (`va` = 0 where it ended
    /// in co-motion) and which took `loss` of kinetic energy (the kernel's twin:
    /// `count_impact`).
    pub fn count_impact(&mut self, vb: f64, loss: f64) {
        let v = vb.abs();
        self.impact_speed[0] += v;
        self.impact_speed[1] = self.impact_speed[1].max(v);
        self.dissipated[0] += loss;
    }

    /// Counts an accepted (sub)step of `dtheta` grid steps in `mode` that dissipated `work`
    /// by friction (the kernel's twin: `count_step`).
    pub fn count_step(&mut self, mode: Mode, work: f64, dtheta: f64) {
        self.dissipated[1] += work;
        if !mode.is_slip() {
            self.stuck_steps += dtheta;
        }
    }

    /// Starts the sampled window's observables (impact speeds, dissipation, time stuck).
    pub fn start_sampling(&mut self) {
        self.impact_speed = [0.0; 2];
        self.dissipated = [0.0; 2];
        self.stuck_steps = 0.0;
    }
}
/// State of one parameter point.
#[derive(Clone, Copy, Debug)]
pub struct PointState<F> {
    pub y: [F; 4],
    pub mode: Mode,
    pub diag: Diagnostics,
}

/// Result of a run: stroboscopic samples (phase 0 of the forcing) and diagnostics.
#[derive(Clone, Debug)]
pub struct RunResult {
    pub samples: Vec<[f64; 4]>,
    /// Impacts during the sampled periods only.
    pub sample_impacts: u64,
    pub diag: Diagnostics,
    pub final_y: [f64; 4],
    pub final_mode: Mode,
    /// Largest Lyapunov exponent per unit time over the sampled periods and its standard
    /// error by batch means (NaN when not computed or when the tangent vector overflowed).
    pub lyapunov: crate::classify::Exponent,
    /// The exponent was asked for but the tangent vector left the finite range while the state
    /// did not (f32 overflows first): no exponent, and none of the conclusions drawn from
    /// its absence ([`crate::classify::Rule::ExponentLost`]).
    pub exponent_lost: bool,
    /// Agreeing digits of the torus test over the sampled window
    /// ([`crate::classify::Birkhoff`]); NaN without two full halves.
    pub torus: f64,
    /// The last section values of y1 (at most [`crate::classify::TAIL`], oldest first):
    /// they propose the candidate periods, also where the samples are not kept.
    pub tail: Vec<f64>,
    /// Where the samples are not kept, what the kernel's period detector saw: the samples it
    /// counted and the period it found ([`crate::classify::PeriodDetector`]).
    pub detector: Option<(usize, Option<u32>)>,
    /// Mean and largest impact speed (relative velocity of the masses just before an impact,
    /// |y2 - y4|) over the sampled periods; NaN without impacts there.
    pub impact_speed: [f64; 2],
    /// Energy dissipated per sampled period by impacts and by friction, in units of m1
    /// (the state's units: m1 = 1, time 1/omega1); NaN without sampled periods.
    pub dissipation: [f64; 2],
    /// Fraction of the sampled time the masses moved together (stick or lock).
    pub stick_fraction: f64,
}

impl RunResult {
    /// Whether the window repeats without impacts (decided `no_impact` at once in an early
    /// round): by the samples, or where they were not kept by the kernel's detector.
    pub fn repeats_without_impacts(&self, period_tol: f64) -> bool {
        self.sample_impacts == 0
            && !self.diag.nonfinite
            && match self.detector {
                Some((_, period)) => period.is_some(),
                None => crate::classify::detect_period(&self.samples, period_tol).is_some(),
            }
    }

    /// The strict period detector's class of the run (period, impacts, finiteness): by its
    /// samples, or where they were not kept by what the kernel's detector saw.
    pub fn class(&self, period_tol: f64) -> crate::class::Class {
        match self.detector_class() {
            Some(c) if self.samples.is_empty() => c,
            _ => crate::classify::classify(
                &self.samples,
                self.sample_impacts,
                self.diag.nonfinite,
                period_tol,
            ),
        }
    }

    /// The class the kernel's detector saw (GPU runs only), whether or not samples were kept.
    pub fn detector_class(&self) -> Option<crate::class::Class> {
        self.detector.map(|(count, period)| {
            crate::classify::class_of(self.diag.nonfinite, count, self.sample_impacts, || period)
        })
    }

    /// The failure rule shared by every backend: a run whose state or samples left the finite
    /// range is non-finite, and a failed run has no exponent.
    pub fn enforce_failure_rule(&mut self) {
        let bad = |y: &[f64; 4]| y.iter().any(|v| !v.is_finite());
        if bad(&self.final_y) || self.samples.iter().any(bad) {
            self.diag.nonfinite = true;
        }
        if self.diag.nonfinite {
            self.lyapunov = crate::classify::Exponent::NONE;
        }
    }

    /// What the classifier reads of this run, with `detected` the strict detector's class.
    pub fn evidence(&self, detected: crate::class::Class) -> crate::classify::Evidence<'_> {
        crate::classify::Evidence {
            detected,
            tail: &self.tail,
            lyapunov: self.lyapunov,
            torus: self.torus,
            exponent_lost: self.exponent_lost,
        }
    }

    /// Pools this window's exponent with the windows before it (`pool`), keeping the pooled
    /// exponent and error.
    pub fn pool(&mut self, pool: &mut crate::classify::Pool) {
        self.lyapunov = pool.add(self.lyapunov);
    }

    /// Mean impacts per sampled period.
    pub fn impacts_per_period(&self) -> f64 {
        self.sample_impacts as f64 / self.samples.len().max(1) as f64
    }
}

/// Timings of a run, seconds (the setup, readback and kernel times are the GPU's; the CPU
/// reports its integration time only).
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Timings {
    pub setup_s: f64,
    pub integration_s: f64,
    pub readback_s: f64,
    /// Kernel time from timestamp queries, when the adapter has them.
    pub kernel_s: Option<f64>,
    pub dispatches: u32,
    pub batches: u32,
    /// Host work between the engine's runs of an adaptive run: deciding the points (the
    /// classifier's proposals, Newton's trials and multipliers on the CPU) and the bookkeeping
    /// of the live points; zero for a plain run.
    #[serde(default)]
    pub host_s: f64,
    /// Newton's flows on the device between the engine's runs (`run.decide`; not in
    /// `host_s`).
    #[serde(default)]
    pub decide_s: f64,
    /// Streams of an overlapped run ([`crate::adaptive::run_summaries`]; 0 or 1: none): the
    /// seconds above are then the streams' sums, which ran at once.
    #[serde(default)]
    pub streams: u32,
    /// What crossed between the host and the device ([`Transfers`]; zero on the CPU).
    #[serde(default)]
    pub transfers: Transfers,
    /// Where an adaptive run's wall time went, part by part ([`Parts`]; zero for a plain run).
    #[serde(default)]
    pub parts: Parts,
}

/// The parts of an adaptive run ([`crate::adaptive`]), each its wall seconds and the points it
/// took: the configured stages (with the adaptive horizon), the long look's stages, the
/// recurrence search on the host, the carried cycles with the escapes. Each part's seconds hold its integration and its deciding
/// (the split of [`Timings`] cuts across them); in an overlapped run the configured part is the
/// streams' sum.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Parts {
    /// The configured stages: the early rounds, the configured stretch, the adaptive horizon.
    pub configured_s: f64,
    /// The long look's stages ([`crate::adaptive::look::look`]).
    pub look_s: f64,
    /// Points the look went on with.
    pub looked: u64,
    /// The recurrence search ([`crate::recurrence`]): its windows and Newton's trials.
    pub search_s: f64,
    /// Points searched.
    pub searched: u64,
    /// Of those, points whose search found the stable cycle they approach.
    pub found: u64,
    /// Stable cycles carried between points and the copies of chaotic-looking motions beside
    /// them ([`crate::escape`]); a map's over its whole grid once its parts are joined.
    #[serde(default)]
    pub carry_s: f64,
}

impl Parts {
    /// Adds another run's parts.
    pub fn add(&mut self, o: &Parts) {
        self.configured_s += o.configured_s;
        self.look_s += o.look_s;
        self.looked += o.looked;
        self.search_s += o.search_s;
        self.searched += o.searched;
        self.found += o.found;
        self.carry_s += o.carry_s;
    }
}

/// What crossed between the host and a device adapter (docs/performance.md, "Round trips"):
/// on a card each wait is a fence, and a readback whose contents the host must see before it
/// can say what the device does next leaves the device idle until the host has answered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Transfers {
    /// Readbacks whose contents decide what the device does next: a batch's results (which
    /// points run on, what Newton tries), Newton's trials (what the host ends or starts
    /// again).
    pub round_trips: u64,
    /// Waits for progress and interrupts between the dispatches of one piece of work (the
    /// device's work does not depend on them).
    pub polls: u64,
    /// Bytes read back from the device, in all.
    pub readback_bytes: u64,
}

impl Transfers {
    /// What crossed since `before` (counts of the same device).
    pub fn since(&self, before: &Transfers) -> Transfers {
        Transfers {
            round_trips: self.round_trips - before.round_trips,
            polls: self.polls - before.polls,
            readback_bytes: self.readback_bytes - before.readback_bytes,
        }
    }

    pub fn add(&mut self, o: &Transfers) {
        self.round_trips += o.round_trips;
        self.polls += o.polls;
        self.readback_bytes += o.readback_bytes;
    }
}

/// Where a command's wall time went: the keys every command's JSON `timings` shares (the map's
/// and the diagram's add their own beside them), and the split its summary line prints.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct Split {
    /// The engine's runs (on a GPU adapter the device's integration with its setup and
    /// readbacks).
    pub integration_s: f64,
    /// Newton's iterations on the device (`run.decide`).
    pub device_decide_s: f64,
    /// The host's deciding and bookkeeping: Newton's trials and multipliers on the host, the
    /// classifier, the command's own CPU f64 work.
    pub host_s: f64,
    /// Writing the output files (the JSON, written last, not included); null where the
    /// command writes none.
    pub files_s: Option<f64>,
    /// The computation's wall time up to its files (`files_s` is theirs).
    pub wall_s: f64,
    /// What crossed between the host and the device.
    #[serde(flatten)]
    pub transfers: Transfers,
    /// The adaptive run's parts ([`Parts`]; zero where the command ran none).
    pub parts: Parts,
}

impl Split {
    /// The split of a computation that took `wall_s`, whose runs and deciding took `t`, plus
    /// `host_s` seconds of the command's own host work outside them.
    pub fn of(t: &Timings, host_s: f64, wall_s: f64) -> Split {
        Split {
            integration_s: t.integration_s,
            device_decide_s: t.decide_s,
            host_s: t.host_s + host_s,
            files_s: None,
            wall_s,
            transfers: t.transfers,
            parts: t.parts,
        }
    }

    /// "W s (I s integration, D s device deciding, H s host deciding)", for summary lines.
    pub fn line(&self) -> String {
        format!(
            "{:.2} s ({:.2} s integration, {:.2} s device deciding, {:.2} s host deciding)",
            self.wall_s, self.integration_s, self.device_decide_s, self.host_s
        )
    }
}

impl Timings {
    /// Adds the times of another run (kernel time only where both have it).
    pub fn add(&mut self, o: &Timings) {
        self.setup_s += o.setup_s;
        self.integration_s += o.integration_s;
        self.readback_s += o.readback_s;
        self.kernel_s = match (self.kernel_s, o.kernel_s) {
            (Some(a), Some(b)) => Some(a + b),
            (None, b) if self.dispatches == 0 => b,
            _ => None,
        };
        self.dispatches += o.dispatches;
        self.batches += o.batches;
        self.host_s += o.host_s;
        self.decide_s += o.decide_s;
        self.streams = self.streams.max(o.streams);
        self.transfers.add(&o.transfers);
        self.parts.add(&o.parts);
    }
}
