//! The engineering observables as the reports give them: per run (impact speed, energy
//! dissipated per period by impacts and by friction, stick fraction; the integrators compute
//! them, `method::Diagnostics`), their distributions over many runs or impacts, and the impact
//! speeds of every impact of a CPU run (the distribution `point` reports).

use crate::method::{EV_IMPACT_NEG, EV_IMPACT_POS, Event, Integrator, PointState, StepObserver};
use crate::model::{Mode, Params};
use serde::Serialize;

/// The engineering observables of a run over its sampled periods, as the reports write them
/// (null where undefined: no impact, no sampled period). Energies are dimensionless, in the
/// units of the state (mass m1 = 1, time 1/omega1).
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Observables {
    /// Mean and largest relative velocity of the masses just before an impact.
    pub impact_speed_mean: Option<f64>,
    pub impact_speed_max: Option<f64>,
    /// Kinetic energy the impacts took, per forcing period.
    pub dissipation_impacts: Option<f64>,
    /// Work of the friction force against the slip, per forcing period.
    pub dissipation_friction: Option<f64>,
    /// Fraction of the time the masses moved together (stick, or lock at a stop).
    pub stick_fraction: Option<f64>,
}

impl Observables {
    /// From the raw values (NaN where undefined): impact speed mean and max, dissipation per
    /// period by impacts and by friction, stick fraction.
    pub fn new(impact_speed: [f64; 2], dissipation: [f64; 2], stick_fraction: f64) -> Self {
        let f = |v: f64| v.is_finite().then_some(v);
        Observables {
            impact_speed_mean: f(impact_speed[0]),
            impact_speed_max: f(impact_speed[1]),
            dissipation_impacts: f(dissipation[0]),
            dissipation_friction: f(dissipation[1]),
            stick_fraction: f(stick_fraction),
        }
    }

    /// The observables of a run.
    pub fn of_run(r: &crate::method::RunResult) -> Self {
        Observables::new(r.impact_speed, r.dissipation, r.stick_fraction)
    }

    /// The observables' names (their JSON keys and CSV columns), in the struct's order.
    pub const NAMES: [&'static str; 5] = [
        "impact_speed_mean",
        "impact_speed_max",
        "dissipation_impacts",
        "dissipation_friction",
        "stick_fraction",
    ];

    /// The values, in the order of [`Observables::NAMES`].
    pub fn values(&self) -> [Option<f64>; 5] {
        [
            self.impact_speed_mean,
            self.impact_speed_max,
            self.dissipation_impacts,
            self.dissipation_friction,
            self.stick_fraction,
        ]
    }
}

/// The distribution of one engineering observable over the points (or impacts) where it is
/// defined (the impact speeds need impacts).
#[derive(Clone, Debug, Serialize)]
pub struct Distribution {
    pub name: &'static str,
    /// Values it is over (a sensitivity study's draws of A and B with a value).
    pub defined: usize,
    pub mean: f64,
    pub p05: f64,
    pub median: f64,
    pub p95: f64,
    pub max: f64,
}

impl Distribution {
    /// The distribution of `values` (the defined ones), named `name`.
    pub fn of(name: &'static str, values: impl Iterator<Item = Option<f64>>) -> Distribution {
        let mut v: Vec<f64> = values.flatten().collect();
        v.sort_by(f64::total_cmp);
        // Nearest-rank quantiles: a value some draw had.
        let q = |u: f64| match v.len() {
            0 => f64::NAN,
            n => v[((u * n as f64).ceil() as usize).clamp(1, n) - 1],
        };
        Distribution {
            name,
            defined: v.len(),
            mean: v.iter().sum::<f64>() / v.len() as f64,
            p05: q(0.05),
            median: q(0.5),
            p95: q(0.95),
            max: v.last().copied().unwrap_or(f64::NAN),
        }
    }
}

/// Collects the speed |y2 - y4| just before each impact.
struct Speeds(Vec<f64>);

impl StepObserver<f64> for Speeds {
    const ACTIVE: bool = true;
    fn substep(&mut self, _: &Params<f64>, _: &[[f64; 4]; 4], _: Mode, _: f64) {}
    fn event(&mut self, _: &Integrator<f64>, e: &Event<f64>) {
        if e.ev == EV_IMPACT_POS || e.ev == EV_IMPACT_NEG {
            self.0.push((e.before[1] - e.before[3]).abs());
        }
    }
}

/// The speed of every impact, in order, of `periods` periods of `it` from `start` (a CPU f64
/// run; the located impacts, which are all of them unless the method is the naive one).
pub fn impact_speeds(it: &Integrator<f64>, start: &PointState<f64>, periods: u32) -> Vec<f64> {
    let mut st = *start;
    let mut speeds = Speeds(Vec::new());
    for _ in 0..periods {
        if st.diag.nonfinite {
            break;
        }
        it.period_observed(&mut st, &mut speeds);
    }
    speeds.0
}
