//! How a cycle ends where no multiplier crosses the circle: from its event structure. A
//! smooth bifurcation is seen in the multipliers; the non-smooth ones of this model are seen
//! in what the cycle's events do as the parameter nears the end: an impact whose speed goes to
//! zero or a free flight that comes ever closer to a stop (grazing), a stick phase whose length
//! goes to zero (stick loss) or a slip whose relative velocity comes ever closer to zero
//! without reversing (stick onset: at the end it touches zero and a stick or reversal begins).
//!
//! Each feature is measured on the cycle at two distances from the end, `near` and `far`
//! (`far` >= 16 x `near`): a feature that vanishes at the end shrinks like the distance (a
//! gap, a duration) or its square root (an impact speed), so that near/far is at most about
//! sqrt(near/far); a feature that does not vanish keeps near/far close to 1.

use super::Kind;
use crate::cycles::Cycle;
use crate::method::{EV_IMPACT_NEG, EV_IMPACT_POS, Event, Integrator, StepObserver};
use crate::model::{Mode, Params};

/// The smallest of each vanishing candidate over one cycle (infinity where the cycle has none).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Structure {
    /// Relative speed |z'| of the slowest impact.
    pub impact_speed: f64,
    /// Least clearance r - |z| of a free flight's closest approach to a stop (a local minimum
    /// of the clearance with no impact).
    pub gap: f64,
    /// Shortest stick or lock phase, in time units.
    pub stick: f64,
    /// Least |v| of a slip's closest approach to v = 0 without reversing.
    pub slip_speed: f64,
}

impl Structure {
    fn values(&self) -> [(f64, Kind); 4] {
        [
            (self.impact_speed, Kind::Grazing),
            (self.gap, Kind::Grazing),
            (self.stick, Kind::StickLoss),
            (self.slip_speed, Kind::StickOnset),
        ]
    }
}

/// The structure of the cycle `c` (its period at `it`'s parameters): two passes, the features
/// read in the second (a stick phase running through phase 0 has its start in the first).
pub fn structure(it: &Integrator<f64>, c: &Cycle) -> Structure {
    let mut obs = Observer {
        r: it.p.clearance,
        t: 0.0,
        from: f64::INFINITY,
        samples: Vec::new(),
        stick_from: None,
        out: Structure {
            impact_speed: f64::INFINITY,
            gap: f64::INFINITY,
            stick: f64::INFINITY,
            slip_speed: f64::INFINITY,
        },
    };
    let mut st = c.state();
    for pass in 0..2 {
        if pass == 1 {
            obs.from = obs.t;
        }
        for _ in 0..c.period {
            it.period_observed(&mut st, &mut obs);
        }
    }
    obs.out
}

/// What vanishes at the end of a cycle followed from `far` to `near`: the kind of the feature
/// with the smallest near/far ratio, where that ratio is below twice sqrt(`contrast`) (the
/// distances' ratio near/far, at most 1/16) and the feature at `near` is small against its
/// scale at `far`.
pub fn vanishing(near: &Structure, far: &Structure, contrast: f64) -> Option<Kind> {
    let bound = 2.0 * contrast.sqrt();
    near.values()
        .iter()
        .zip(far.values())
        .filter(|((n, _), (f, _))| n.is_finite() && f.is_finite() && *f > 0.0)
        .map(|((n, k), (f, _))| (n / f, *k))
        .filter(|(ratio, _)| *ratio < bound)
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, k)| k)
}

/// A sample of the motion: time, clearance, |v| in slip (NaN otherwise).
type Sample = (f64, f64, f64);

struct Observer {
    r: f64,
    t: f64,
    /// Features count from this time on (the second pass).
    from: f64,
    /// Samples since the last event (local minima are looked for among them).
    samples: Vec<Sample>,
    stick_from: Option<f64>,
    out: Structure,
}

/// The least value of the parabola through three samples (t, value), where its vertex lies
/// between the outer two; the middle value otherwise.
fn vertex(a: (f64, f64), b: (f64, f64), c: (f64, f64)) -> f64 {
    let (d1, d2) = ((b.1 - a.1) / (b.0 - a.0), (c.1 - b.1) / (c.0 - b.0));
    let curv = (d2 - d1) / (c.0 - a.0);
    if curv <= 0.0 || !curv.is_finite() {
        return b.1;
    }
    // The slope at b from the parabola, then its vertex.
    let slope = d1 + curv * (b.0 - a.0);
    let v = b.1 - slope * slope / (4.0 * curv);
    v.clamp(0.0, b.1)
}

impl Observer {
    fn counts(&self) -> bool {
        self.t >= self.from
    }

    /// Local minima of the clearance and of the slip speed among the last three samples.
    fn minima(&mut self) {
        let n = self.samples.len();
        if n < 3 || !self.counts() {
            return;
        }
        let [a, b, c] = [
            self.samples[n - 3],
            self.samples[n - 2],
            self.samples[n - 1],
        ];
        if b.1 < a.1 && b.1 <= c.1 {
            let g = vertex((a.0, a.1), (b.0, b.1), (c.0, c.1));
            self.out.gap = self.out.gap.min(g);
        }
        if b.2 < a.2 && b.2 <= c.2 {
            let s = vertex((a.0, a.2), (b.0, b.2), (c.0, c.2));
            self.out.slip_speed = self.out.slip_speed.min(s);
        }
    }
}

impl StepObserver<f64> for Observer {
    const ACTIVE: bool = true;

    fn substep(&mut self, _: &Params<f64>, stages: &[[f64; 4]; 4], mode: Mode, dt: f64) {
        let y = stages[0];
        let slip = matches!(mode, Mode::SlipPos | Mode::SlipNeg);
        let gap = if slip {
            self.r - (y[2] - y[0]).abs()
        } else {
            f64::NAN
        };
        let speed = if slip { (y[1] - y[3]).abs() } else { f64::NAN };
        self.samples.push((self.t, gap, speed));
        self.minima();
        self.t += dt;
    }

    fn event(&mut self, _: &Integrator<f64>, e: &Event<f64>) {
        let counts = self.counts();
        if (e.ev == EV_IMPACT_POS || e.ev == EV_IMPACT_NEG) && counts {
            let speed = (e.before[3] - e.before[1]).abs();
            self.out.impact_speed = self.out.impact_speed.min(speed);
        }
        let held = |m: Mode| matches!(m, Mode::Stick | Mode::LockPos | Mode::LockNeg);
        match (held(e.mode_before), held(e.after.mode)) {
            (false, true) => self.stick_from = Some(self.t),
            (true, false) => {
                if let (Some(s), true) = (self.stick_from.take(), counts) {
                    self.out.stick = self.out.stick.min(self.t - s);
                }
            }
            _ => {}
        }
        // The motion after an event is a new piece: minima do not span it.
        self.samples.clear();
    }
}
