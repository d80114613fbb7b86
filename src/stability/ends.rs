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
use crate::method::{EV_IMPACT_NEG, EV_IMPACT_POS, EV_REVERSAL, Event, Integrator, StepObserver};
use crate::model::{Mode, Params};

/// The smallest of each vanishing candidate over one cycle (infinity where the cycle has none).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Structure {
    /// Relative speed |z'| of the slowest impact.
    pub impact_speed: f64,
    /// Least clearance r - |z| of a free flight's closest approach to a stop (a local minimum
    /// of the clearance with no impact: where the relative velocity passes zero).
    pub gap: f64,
    /// Shortest stick or lock phase, in time units.
    pub stick: f64,
    /// Least |v| of a slip's closest approach to v = 0 without reversing.
    pub slip_speed: f64,
    /// The cycle's events over one cycle: impacts, reversals, stick or lock phases begun. A
    /// cycle whose events change between two parameter values has met a switching surface
    /// (a stop or the friction law's) between them.
    pub events: [u32; 3],
}

impl Structure {
    /// The vanishing candidates' names, in the order of [`Structure::values`].
    pub const NAMES: [&'static str; 4] = [
        "impact speed",
        "clearance at a closest approach",
        "stick phase",
        "slip speed at a closest approach to v = 0",
    ];

    pub fn values(&self) -> [(f64, Kind); 4] {
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
        eta: it.p.eta,
        t: 0.0,
        from: f64::INFINITY,
        last: None,
        stick_from: None,
        out: Structure {
            impact_speed: f64::INFINITY,
            gap: f64::INFINITY,
            stick: f64::INFINITY,
            slip_speed: f64::INFINITY,
            events: [0; 3],
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
    vanishing_feature(near, far, contrast).map(|(k, _)| k)
}

/// [`vanishing`] with the index of the feature that vanishes (in [`Structure::values`]).
pub fn vanishing_feature(
    near: &Structure,
    far: &Structure,
    contrast: f64,
) -> Option<(Kind, usize)> {
    let bound = 2.0 * contrast.sqrt();
    near.values()
        .iter()
        .zip(far.values())
        .enumerate()
        .filter(|(_, ((n, _), (f, _)))| n.is_finite() && f.is_finite() && *f > 0.0)
        .map(|(i, ((n, k), (f, _)))| (n / f, *k, i))
        .filter(|(ratio, _, _)| *ratio < bound)
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, k, i)| (k, i))
}

/// Where the feature `i` of [`Structure::values`] reaches zero, from its values `near` and
/// `far` at distances `d_near` and `d_far` from the end: its distance from the end towards
/// the cycle's side (negative: beyond the end). A clearance, a stick's length or a slip's
/// least speed shrinks linearly with the distance, an impact's speed like its square root.
pub fn zero_distance(i: usize, (near, d_near): (f64, f64), (far, d_far): (f64, f64)) -> f64 {
    let (a, b) = if i == 0 {
        (far * far, near * near)
    } else {
        (far, near)
    };
    d_near - b * (d_far - d_near) / (a - b)
}

/// A sample of a slip: time, the relative velocity v = y2 - y4 and its derivative.
#[derive(Clone, Copy)]
struct Sample {
    t: f64,
    v: f64,
    vd: f64,
}

struct Observer {
    r: f64,
    eta: f64,
    t: f64,
    /// Features count from this time on (the second pass).
    from: f64,
    /// The last sample of the current piece of free flight (none after an event or in stick).
    last: Option<Sample>,
    stick_from: Option<f64>,
    out: Structure,
}

/// The cubic Hermite interpolant on one sub-step (values `g0, g1`, derivatives times the
/// sub-step `m0, m1`) in power form on s in [0, 1]: the integrator's own event guards
/// ([`crate::method::events::bracket`]) are this cubic, so that a feature read from it
/// vanishes exactly where the integrator's map grazes (a parabola through three samples is off
/// by the step's cube, far more than a feature near its end).
fn cubic(g0: f64, g1: f64, m0: f64, m1: f64) -> [f64; 4] {
    let d = g1 - g0;
    [g0, m0, 3.0 * d - 2.0 * m0 - m1, m0 + m1 - 2.0 * d]
}

/// The interior extrema of the cubic `a` on [0, 1]: (value, second derivative) at each.
fn extrema(a: [f64; 4]) -> impl Iterator<Item = (f64, f64)> {
    let (qa, qb, qc) = (3.0 * a[3], 2.0 * a[2], a[1]);
    let roots = if qa.abs() > 1e-300 {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc < 0.0 {
            [f64::NAN; 2]
        } else {
            let q = -0.5 * (qb + qb.signum() * disc.sqrt());
            [q / qa, if q != 0.0 { qc / q } else { f64::NAN }]
        }
    } else if qb != 0.0 {
        [-qc / qb, f64::NAN]
    } else {
        [f64::NAN; 2]
    };
    roots
        .into_iter()
        .filter(|s| (0.0..=1.0).contains(s))
        .map(move |s| {
            let value = a[0] + s * (a[1] + s * (a[2] + s * a[3]));
            (value, 2.0 * a[2] + 6.0 * a[3] * s)
        })
}

impl Observer {
    fn counts(&self) -> bool {
        self.t >= self.from
    }

    /// The slip speed's closest approach to zero (a local minimum of |v|) inside the sub-step
    /// from `a` to `b`.
    fn minima(&mut self, a: Sample, b: Sample) {
        let h = b.t - a.t;
        if !self.counts() || h <= 0.0 {
            return;
        }
        for (v, curv) in extrema(cubic(a.v, b.v, h * a.vd, h * b.vd)) {
            if v * curv > 0.0 && v * a.v > 0.0 {
                self.out.slip_speed = self.out.slip_speed.min(v.abs());
            }
        }
    }
}

impl StepObserver<f64> for Observer {
    const ACTIVE: bool = true;

    fn substep(&mut self, p: &Params<f64>, stages: &[[f64; 4]; 4], mode: Mode, dt: f64) {
        let y = stages[0];
        if matches!(mode, Mode::SlipPos | Mode::SlipNeg) {
            // The forcing's phase from the observer's own clock, which starts at phase 0.
            let f = crate::model::field(p, &y, mode, (self.eta * self.t).cos());
            let s = Sample {
                t: self.t,
                v: y[1] - y[3],
                vd: f[1] - f[3],
            };
            if let Some(a) = self.last {
                self.minima(a, s);
            }
            self.last = Some(s);
        } else {
            self.last = None;
        }
        self.t += dt;
    }

    fn event(&mut self, _: &Integrator<f64>, e: &Event<f64>) {
        let counts = self.counts();
        if (e.ev == EV_IMPACT_POS || e.ev == EV_IMPACT_NEG) && counts {
            let speed = (e.before[3] - e.before[1]).abs();
            self.out.impact_speed = self.out.impact_speed.min(speed);
            self.out.events[0] += 1;
        }
        if e.ev == EV_REVERSAL && counts {
            self.out.events[1] += 1;
        }
        // z' = -v: the clearance r - |z| has its local minima where v passes zero, at a
        // reversal or a stick's start, never inside a slip. Where |z| peaks there (z > 0 after
        // v rose through zero, z < 0 after it fell) is a closest approach to a stop.
        let z = e.before[2] - e.before[0];
        let rising = e.mode_before == Mode::SlipNeg;
        let at_rest = matches!(e.after.mode, Mode::Stick);
        if counts
            && matches!(e.mode_before, Mode::SlipPos | Mode::SlipNeg)
            && (e.ev == EV_REVERSAL || at_rest)
            && (z > 0.0) == rising
        {
            self.out.gap = self.out.gap.min((self.r - z.abs()).max(0.0));
        }
        let held = |m: Mode| matches!(m, Mode::Stick | Mode::LockPos | Mode::LockNeg);
        match (held(e.mode_before), held(e.after.mode)) {
            (false, true) => {
                self.stick_from = Some(self.t);
                self.out.events[2] += u32::from(counts);
            }
            (true, false) => {
                if let (Some(s), true) = (self.stick_from.take(), counts) {
                    self.out.stick = self.out.stick.min(self.t - s);
                }
            }
            _ => {}
        }
        // The motion after an event is a new piece: minima do not span it.
        self.last = None;
    }
}
