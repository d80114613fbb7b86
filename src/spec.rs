//! One run description shared by every backend: what to integrate (base parameters, the
//! parameters that vary per point, initial states), how (method settings, precision) and for
//! how long. Callers build a [`RunSpec`] from a [`Config`] once instead of cloning and mutating
//! whole configurations.

use crate::config::{Config, Decide, Precision};
use crate::method::Settings;
use crate::model::{Mode, Param, Params};

/// How every point of a run is integrated.
#[derive(Clone, Debug)]
pub struct RunSpec {
    /// Parameters shared by every point (the varying ones are overwritten per point).
    pub params: Params<f64>,
    /// Initial state of every point that has no state of its own.
    pub y0: [f64; 4],
    pub settings: Settings,
    pub transient: u32,
    pub samples: u32,
    /// Period test tolerance relative to the attractor size.
    pub period_tol: f64,
    /// An undecided point may run this many times the configured periods in all
    /// (`run.horizon`, [`crate::adaptive::extensions`]).
    pub horizon: u32,
    /// The longest look at a point that looks chaotic, in forcing periods from its start
    /// (`run.look`, [`crate::adaptive::look_stages`]).
    pub look: u32,
    /// Where Newton's flows run (`run.decide`), and in what on the device
    /// (`run.decide_precision`).
    pub decide: Decide,
    pub decide_precision: Option<Precision>,
    /// Streams run at once (`run.overlap`; unset: the engine's choice,
    /// [`crate::engine::Engine::overlap`]).
    pub overlap: Option<u32>,
    pub precision: Precision,
}

impl RunSpec {
    pub fn new(cfg: &Config) -> RunSpec {
        RunSpec {
            params: cfg.params(),
            y0: cfg.initial.y,
            settings: cfg.settings(),
            transient: cfg.run.transient_periods,
            samples: cfg.run.sample_periods,
            period_tol: cfg.run.period_tol,
            horizon: cfg.run.horizon,
            look: cfg.run.look,
            decide: cfg.run.decide,
            decide_precision: cfg.run.decide_precision,
            overlap: cfg.run.overlap,
            precision: cfg.method.precision,
        }
    }

    /// The same run with the Lyapunov estimate on.
    pub fn with_lyapunov(mut self) -> RunSpec {
        self.settings.lyapunov = true;
        self
    }

    /// The same run with the largest exponent estimated or not, as `tangent` says.
    pub fn with_tangent(mut self, tangent: crate::config::Tangent) -> RunSpec {
        self.settings.lyapunov = tangent != crate::config::Tangent::None;
        self
    }

    /// Forcing periods of each point (transient + sampled).
    pub fn periods(&self) -> u32 {
        self.transient + self.samples
    }
}

/// Most parameters a point set varies (the kernel's `Control.vary0..2`).
pub const MAX_VARY: usize = 3;

/// The points of a run: per-point values of up to [`MAX_VARY`] varying parameters and,
/// optionally, one initial state per point.
#[derive(Clone, Copy, Debug)]
pub struct Points<'a> {
    pub vary: &'a [Param],
    /// `len() * vary.len()` numbers, point-major.
    pub values: &'a [f64],
    pub y0s: Option<&'a [[f64; 4]]>,
    /// Optionally the motion mode each initial state is in (a continued run resumes in the
    /// mode it stopped in, so that it follows the same path as one uninterrupted run); without
    /// it, the at-rest rule decides from the state.
    pub modes: Option<&'a [Mode]>,
}

impl<'a> Points<'a> {
    /// The base point alone.
    pub fn single() -> Points<'static> {
        Points {
            vary: &[],
            values: &[],
            y0s: None,
            modes: None,
        }
    }

    /// One point per value of one parameter.
    pub fn along(vary: &'a [Param], values: &'a [f64]) -> Points<'a> {
        Points {
            vary,
            values,
            y0s: None,
            modes: None,
        }
    }

    /// One point per initial state, all at the base parameters.
    pub fn states(y0s: &'a [[f64; 4]]) -> Points<'a> {
        Points {
            vary: &[],
            values: &[],
            y0s: Some(y0s),
            modes: None,
        }
    }

    pub fn with_states(self, y0s: &'a [[f64; 4]]) -> Points<'a> {
        Points {
            y0s: Some(y0s),
            ..self
        }
    }

    pub fn len(&self) -> usize {
        if self.vary.is_empty() {
            self.y0s.map_or(1, |y| y.len())
        } else {
            self.values.len() / self.vary.len()
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Points `[a, b)`.
    pub fn slice(&self, a: usize, b: usize) -> Points<'a> {
        let nv = self.vary.len();
        Points {
            vary: self.vary,
            values: if nv == 0 {
                self.values
            } else {
                &self.values[a * nv..b * nv]
            },
            y0s: self.y0s.map(|y| &y[a..b]),
            modes: self.modes.map(|m| &m[a..b]),
        }
    }

    /// Parameters of point `i`.
    pub fn params(&self, base: &Params<f64>, i: usize) -> Params<f64> {
        let mut p = *base;
        for (k, v) in self.vary.iter().enumerate() {
            v.set(&mut p, self.values[i * self.vary.len() + k]);
        }
        p
    }

    /// Initial state of point `i`.
    pub fn y0(&self, spec: &RunSpec, i: usize) -> [f64; 4] {
        self.y0s.map_or(spec.y0, |y| y[i])
    }

    /// Mode of point `i`'s initial state, where given.
    pub fn mode0(&self, i: usize) -> Option<Mode> {
        self.modes.map(|m| m[i])
    }
}
