//! Exact (closed-form, f64) reference solution of the impact oscillator in its frictionless
//! limit, used to measure the convergence order of the numerical integrators.
//!
//! State `y = (y1, y2, y3, y4)` = (m1 position, m1 velocity, m2 position, m2 velocity):
//! `y1'' + b1 y1' + y1 = cos(eta t)`, `y4' = 0`, impacts when `z = y3 - y1` reaches `±r`
//! while approaching the stop. Between impacts the motion is known in closed form, so the only
//! numerical work is locating the impact times, which is done to (near) machine precision.

use std::f64::consts::TAU;

pub mod dry;

/// The closed-form reference could not follow the motion.
#[derive(Debug, thiserror::Error)]
#[error("frictionless reference: {0}")]
pub struct ReferenceError(pub String);

/// Parameters of the frictionless model (same meaning as in the full model).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrictionlessParams {
    /// Forcing frequency, > 0.
    pub eta: f64,
    /// Damping of m1, in [0, 2) (underdamped).
    pub b1: f64,
    /// Restitution coefficient R in [0, 1].
    pub restitution: f64,
    /// Clearance, > 0.
    pub r: f64,
    /// Mass ratio m2/m1, > 0.
    pub mu: f64,
}

/// One impact of the exact solution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExactEvent {
    pub time: f64,
    /// +1 for the stop z = +r, -1 for z = -r.
    pub stop: i8,
}

/// More impacts than this is treated as an accumulation (chattering).
pub const MAX_IMPACTS: usize = 10_000;
/// Relative speed below which an impact with the stop pressed counts as sticking.
const STICK_SPEED: f64 = 1e-9;
/// Excursion beyond a stop (relative to [`scale`]) that counts as a graze, not an impact.
const GRAZE_TOL: f64 = 1e-14;
/// Smallest excursion (relative to [`scale`]) of a bounce off a pressed stop that is still
/// resolved; shorter bounces mean an accumulation of impacts that rounding cannot follow.
const BOUNCE_TOL: f64 = 1e-12;
/// Samples per period of the fastest free oscillation when scanning for impacts.
const SAMPLES_PER_PERIOD: f64 = 200.0;

/// Size of the rounding errors in `z = y3 - y1` is about 1e-16 times this.
fn scale(r: f64, y: &[f64; 4]) -> f64 {
    r + y[0].abs() + y[2].abs()
}

/// Free motion from `(t0, y0)`: m1 = particular + homogeneous solution, m2 uniform.
#[derive(Clone, Copy, Debug)]
struct Segment {
    eta: f64,
    b1: f64,
    alpha: f64,
    wd: f64,
    t0: f64,
    c: f64,
    d: f64,
    y3: f64,
    y4: f64,
}

impl Segment {
    fn new(eta: f64, b1: f64, y0: [f64; 4], t0: f64) -> Self {
        let (alpha, wd) = (0.5 * b1, (1.0 - 0.25 * b1 * b1).sqrt());
        let (xp, vp) = particular(eta, b1, t0);
        let c = y0[0] - xp;
        let d = (y0[1] - vp + alpha * c) / wd;
        let (y3, y4) = (y0[2], y0[3]);
        Self {
            eta,
            b1,
            alpha,
            wd,
            t0,
            c,
            d,
            y3,
            y4,
        }
    }

    fn state(&self, t: f64) -> [f64; 4] {
        // Homogeneous part in local time, so its accuracy does not degrade with t0.
        let s = t - self.t0;
        let e = (-self.alpha * s).exp();
        let (sn, cs) = (self.wd * s).sin_cos();
        let (a, w) = (self.alpha, self.wd);
        let xh = e * (self.c * cs + self.d * sn);
        let vh = e * ((w * self.d - a * self.c) * cs - (w * self.c + a * self.d) * sn);
        let (xp, vp) = particular(self.eta, self.b1, t);
        [xp + xh, vp + vh, self.y3 + self.y4 * s, self.y4]
    }

    fn z(&self, t: f64) -> f64 {
        let y = self.state(t);
        y[2] - y[0]
    }

    fn dz(&self, t: f64) -> f64 {
        let y = self.state(t);
        y[3] - y[1]
    }
}

/// Particular solution (position, velocity) of `x'' + b1 x' + x = cos(eta t)`.
fn particular(eta: f64, b1: f64, t: f64) -> (f64, f64) {
    let den = (1.0 - eta * eta).powi(2) + (b1 * eta).powi(2);
    if den == 0.0 {
        // Exact resonance (b1 = 0, eta = 1): x = t sin(t) / 2.
        let (sn, cs) = t.sin_cos();
        return (0.5 * t * sn, 0.5 * (sn + t * cs));
    }
    let (a, b) = ((1.0 - eta * eta) / den, b1 * eta / den);
    let (sn, cs) = (eta * t).sin_cos();
    (a * cs + b * sn, eta * (b * cs - a * sn))
}

/// Solution of the linear forced oscillator `x'' + b1 x' + x = cos(eta t)` (0 <= b1 < 2):
/// `(x, x')` at time `t` given `(x0, v0)` at time `t0`.
pub fn linear_oscillator(eta: f64, b1: f64, x0: f64, v0: f64, t0: f64, t: f64) -> [f64; 2] {
    let y = Segment::new(eta, b1, [x0, v0, 0.0, 0.0], t0).state(t);
    [y[0], y[1]]
}

/// Full state at `t` of the motion without impacts (m1 oscillator, m2 uniform) from `y0` at `t0`.
pub fn free_flight(p: &FrictionlessParams, y0: [f64; 4], t0: f64, t: f64) -> [f64; 4] {
    Segment::new(p.eta, p.b1, y0, t0).state(t)
}

/// Impact map: positions kept, momentum `y2 + mu y4` conserved, relative velocity times `-R`.
pub fn impact_map(p: &FrictionlessParams, y: [f64; 4]) -> [f64; 4] {
    let m = 1.0 + p.mu;
    let vc = (y[1] + p.mu * y[3]) / m;
    let rel = p.restitution * (y[1] - y[3]);
    [y[0], vc - p.mu / m * rel, y[2], vc + rel / m]
}

/// Bisection on `[lo, hi]` with `inside(lo)` and `!inside(hi)` until the two are adjacent floats.
fn bisect(mut lo: f64, mut hi: f64, inside: impl Fn(f64) -> bool) -> (f64, f64) {
    loop {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            return (lo, hi);
        }
        if inside(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
}

/// First impact in `(ta, tb]` of `seg`, given `|z(ta)| <= r` (or `ta` an impact, moving away).
///
/// The step is a small fraction of the fastest period, so `z` has at most one turning point
/// inside (two would need a near-tangency, i.e. a graze). Probes: the turning point, if `z'`
/// changes sign, then `tb`; the first probe beyond a stop brackets the crossing.
fn first_impact(seg: &Segment, r: f64, ta: f64, tb: f64) -> Option<(f64, i8)> {
    let (va, vb) = (seg.dz(ta), seg.dz(tb));
    let mut probes = vec![(ta, 0.0)];
    if va * vb < 0.0 {
        let (_, b) = bisect(ta, tb, |t| seg.dz(t) * va > 0.0);
        let y = seg.state(b);
        // An excursion beyond the stop within a few ulps at a turning point is a graze (or the
        // rounding echo of the impact just processed, e.g. for R = 0), not an impact.
        let tol = GRAZE_TOL * scale(r, &y);
        probes.push((b, tol));
    }
    probes.push((tb, 0.0));
    for w in probes.windows(2) {
        let (lo, (hi, tol)) = (w[0].0, w[1]);
        for stop in [1i8, -1] {
            let f = |t: f64| f64::from(stop) * seg.z(t) - r;
            if f(lo) <= 0.0 && f(hi) > tol {
                let (a, b) = bisect(lo, hi, |t| f(t) <= 0.0);
                let t = if f(a).abs() <= f(b).abs() { a } else { b };
                return Some((t, stop));
            }
        }
    }
    None
}

impl From<&crate::model::Params<f64>> for FrictionlessParams {
    /// The parameters the frictionless model reads (friction and the damper are not in it).
    fn from(p: &crate::model::Params<f64>) -> Self {
        FrictionlessParams {
            eta: p.eta,
            b1: p.b1,
            restitution: p.restitution,
            r: p.clearance,
            mu: p.mu,
        }
    }
}

/// The test problem with a closed-form solution that the accuracy study and the convergence
/// tests share: a frictionless impacting motion (eta 0.9, R 0.7, r 1, b1 0.2, mu 0.5, no
/// damper between the masses) started from rest.
pub fn frictionless_case() -> crate::model::Params<f64> {
    crate::model::Params {
        eta: 0.9,
        restitution: 0.7,
        fs: 0.0,
        fk: 0.0,
        l1: 0.0,
        l2: 0.0,
        clearance: 1.0,
        delta: 0.0,
        b1: 0.2,
        mu: 0.5,
    }
}

/// The exact state of [`frictionless_case`] after `periods` forcing periods from rest, and the
/// number of impacts on the way.
pub fn frictionless_case_exact(periods: u32) -> Result<([f64; 4], usize), ReferenceError> {
    let p = frictionless_case();
    let fp = FrictionlessParams::from(&p);
    let t_end = f64::from(periods) * TAU / p.eta;
    let (y, events) = exact_frictionless(&fp, [0.0; 4], 0.0, t_end)?;
    Ok((y, events.len()))
}

/// Exact solution from `y0` at `t0` (with `|y3 - y1| <= r`) to `t_end`: the state at `t_end`
/// (after the impact if one falls exactly on it) and the list of impacts.
///
/// Errors on invalid input, on more than [`MAX_IMPACTS`] impacts, and when an impact leaves m2
/// pressed against the stop with a relative speed below 1e-9 or a bounce too small to resolve
/// (height < 1e-12 relative): chattering into sticking, which this reference does not model.
pub fn exact_frictionless(
    p: &FrictionlessParams,
    y0: [f64; 4],
    t0: f64,
    t_end: f64,
) -> Result<([f64; 4], Vec<ExactEvent>), ReferenceError> {
    let valid = p.eta > 0.0
        && (0.0..2.0).contains(&p.b1)
        && (0.0..=1.0).contains(&p.restitution)
        && p.r > 0.0
        && p.mu > 0.0
        && p.eta.is_finite()
        && p.r.is_finite()
        && p.mu.is_finite();
    if !valid {
        return Err(ReferenceError(format!(
            "invalid frictionless parameters {p:?}"
        )));
    }
    if !(t0.is_finite() && t_end.is_finite() && t_end >= t0) || y0.iter().any(|v| !v.is_finite()) {
        return Err(ReferenceError(format!(
            "invalid time span [{t0}, {t_end}] or initial state {y0:?}"
        )));
    }
    if (y0[2] - y0[0]).abs() > p.r * (1.0 + 1e-12) {
        return Err(ReferenceError(format!(
            "initial state {y0:?} violates |y3 - y1| <= r = {}",
            p.r
        )));
    }
    let wd = (1.0 - 0.25 * p.b1 * p.b1).sqrt();
    let h = TAU / p.eta.max(wd) / SAMPLES_PER_PERIOD;
    let mut seg = Segment::new(p.eta, p.b1, y0, t0);
    let mut events = Vec::new();
    // Starting on a stop while approaching it: the first impact is at t0.
    let z0 = y0[2] - y0[0];
    let stop0 = if z0 > 0.0 { 1 } else { -1 };
    let mut hit = (z0.abs() >= p.r && z0 * (y0[3] - y0[1]) > 0.0).then_some((t0, stop0));
    let mut ta = t0;
    loop {
        if let Some((t, stop)) = hit {
            if events.len() >= MAX_IMPACTS {
                return Err(ReferenceError(format!(
                    "more than {MAX_IMPACTS} impacts by t = {t}: accumulation of impacts (chattering)"
                )));
            }
            let y = impact_map(p, seg.state(t));
            // A relative acceleration z'' = -y2' that pushes m2 into the stop brings it back
            // after a bounce of height v^2 / (2|z''|); too slow (or too small) a bounce means
            // chattering into sticking, which this reference does not model.
            let zdd = -(f64::cos(p.eta * t) - p.b1 * y[1] - y[0]);
            let v = (y[1] - y[3]).abs();
            let tiny = v < STICK_SPEED || v * v < 2.0 * zdd.abs() * BOUNCE_TOL * scale(p.r, &y);
            if tiny && f64::from(stop) * zdd >= 0.0 {
                return Err(ReferenceError(format!(
                    "impact at t = {t} leaves relative speed {v:e} with the stop {stop:+} \
                     pressed: sticking/chattering, not covered by the frictionless reference"
                )));
            }
            events.push(ExactEvent { time: t, stop });
            seg = Segment::new(p.eta, p.b1, y, t);
            ta = t;
        }
        if ta >= t_end {
            break;
        }
        let tb = (ta + h).min(t_end);
        if tb <= ta {
            return Err(ReferenceError(format!("time step underflow at t = {ta}")));
        }
        hit = first_impact(&seg, p.r, ta, tb);
        let y = seg.state(tb);
        if hit.is_none() && (y[2] - y[0]).abs() > p.r + BOUNCE_TOL * scale(p.r, &y) {
            // Cannot happen unless a crossing escaped the scan; never return a wrong answer.
            return Err(ReferenceError(format!(
                "missed an impact before t = {tb}: y = {y:?}"
            )));
        }
        ta = tb;
    }
    Ok((seg.state(t_end), events))
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: FrictionlessParams = FrictionlessParams {
        eta: 1.3,
        b1: 0.1,
        restitution: 0.8,
        r: 0.5,
        mu: 0.5,
    };

    fn rhs(p: &FrictionlessParams, t: f64, y: [f64; 4]) -> [f64; 4] {
        [y[1], (p.eta * t).cos() - p.b1 * y[1] - y[0], y[3], 0.0]
    }

    fn rk4(p: &FrictionlessParams, t: f64, y: [f64; 4], dt: f64) -> [f64; 4] {
        let add = |y: [f64; 4], k: [f64; 4], c: f64| std::array::from_fn(|i| y[i] + c * k[i]);
        let k1 = rhs(p, t, y);
        let k2 = rhs(p, t + 0.5 * dt, add(y, k1, 0.5 * dt));
        let k3 = rhs(p, t + 0.5 * dt, add(y, k2, 0.5 * dt));
        let k4 = rhs(p, t + dt, add(y, k3, dt));
        std::array::from_fn(|i| y[i] + dt / 6.0 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]))
    }

    /// Brute force: RK4 at fixed step, each impact located by bisection on the step length.
    /// Time is kept as `t_imp + k dt` since summing 1e6 steps would drift by ~1e-9.
    fn brute(
        p: &FrictionlessParams,
        mut y: [f64; 4],
        t0: f64,
        t_end: f64,
        dt: f64,
    ) -> ([f64; 4], Vec<f64>) {
        let out = |y: [f64; 4]| (y[2] - y[0]).abs() > p.r && (y[2] - y[0]) * (y[3] - y[1]) > 0.0;
        let (mut t_imp, mut k, mut times) = (t0, 0.0, Vec::new());
        loop {
            let t = t_imp + k * dt;
            let h = dt.min(t_end - t);
            if h <= 0.0 {
                return (y, times);
            }
            if !out(rk4(p, t, y, h)) {
                y = rk4(p, t, y, h);
                k += 1.0;
                continue;
            }
            let (_, hi) = bisect(0.0, h, |s| !out(rk4(p, t, y, s)));
            y = impact_map(p, rk4(p, t, y, hi));
            (t_imp, k) = (t + hi, 0.0);
            times.push(t_imp);
        }
    }

    fn max_diff(a: [f64; 4], b: [f64; 4]) -> f64 {
        (0..4).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max)
    }

    #[test]
    fn free_flight_matches_rk4() {
        let cases = [(1.3, 0.1), (1.0, 0.0), (0.4, 1.9), (3.0, 0.0)];
        for (eta, b1) in cases {
            let p = FrictionlessParams {
                eta,
                b1,
                r: 1e9,
                ..P
            };
            let (y0, t0, t1) = ([0.3, -0.2, 0.1, 0.05], 0.7, 20.7);
            let (y, events) = exact_frictionless(&p, y0, t0, t1).unwrap();
            assert!(events.is_empty());
            assert_eq!(y, free_flight(&p, y0, t0, t1));
            assert_eq!(linear_oscillator(eta, b1, 0.3, -0.2, t0, t1), [y[0], y[1]]);
            let (mut yr, n) = (y0, 20_000);
            for k in 0..n {
                yr = rk4(&p, t0 + 20.0 * k as f64 / n as f64, yr, 20.0 / n as f64);
            }
            assert!(max_diff(y, yr) < 1e-9, "eta {eta} b1 {b1}: {y:?} vs {yr:?}");
        }
    }

    #[test]
    fn impacts_are_exact_and_match_brute_force() {
        let t_end = 5.0 * TAU / P.eta;
        let (y_end, events) = exact_frictionless(&P, [0.0; 4], 0.0, t_end).unwrap();
        assert_eq!(events.len(), 17);
        // Replay the free flights between the reported impacts and check each impact.
        let (mut y, mut t) = ([0.0; 4], 0.0);
        for e in &events {
            let pre = free_flight(&P, y, t, e.time);
            let (z, dz) = (pre[2] - pre[0], pre[3] - pre[1]);
            assert!(
                (z - f64::from(e.stop) * P.r).abs() < 1e-12,
                "z = {z} at {e:?}"
            );
            assert!(z * dz > 0.0, "not approaching at {e:?}");
            let post = impact_map(&P, pre);
            let mom = |y: [f64; 4]| y[1] + P.mu * y[3];
            assert!((mom(post) - mom(pre)).abs() < 1e-14);
            let (rel_pre, rel_post) = (pre[1] - pre[3], post[1] - post[3]);
            assert!((rel_post + P.restitution * rel_pre).abs() < 1e-14);
            (y, t) = (post, e.time);
        }
        assert_eq!(free_flight(&P, y, t, t_end), y_end);
        // Brute force converges to the reference at 4th order (until roundoff, dt ~ 1e-3).
        let err = |dt: f64| {
            let (yb, times) = brute(&P, [0.0; 4], 0.0, t_end, dt);
            assert_eq!(times.len(), events.len());
            let dt_ev = times.iter().zip(&events).map(|(a, e)| (a - e.time).abs());
            max_diff(y_end, yb).max(dt_ev.fold(0.0, f64::max))
        };
        let (e1, e2) = (err(4e-3), err(2e-3));
        assert!((12.0..20.0).contains(&(e1 / e2)), "ratio {e1:e} / {e2:e}");
        let e3 = err(2.5e-4);
        assert!(e3 < 1e-8, "brute force dt = 2.5e-4 differs by {e3:e}");
    }

    #[test]
    fn continuous_in_t_end() {
        let mut checked = 0;
        for k in 0..200 {
            let t = 0.123 * k as f64;
            let (ya, ea) = exact_frictionless(&P, [0.0; 4], 0.0, t).unwrap();
            let (yb, eb) = exact_frictionless(&P, [0.0; 4], 0.0, t + 1e-7).unwrap();
            if ea == eb {
                assert!(max_diff(ya, yb) < 1e-6, "t = {t}");
                checked += 1;
            }
        }
        assert!(checked >= 190);
    }

    #[test]
    fn starting_on_a_stop() {
        // Approaching: impact at t0. Moving away: the contact at t0 is not an impact.
        for z0 in [0.5, 0.5 + 1e-14] {
            let (_, e) = exact_frictionless(&P, [0.0, 0.0, z0, 1.0], 0.0, 1.0).unwrap();
            assert!(e[0].stop == 1 && e[0].time < 1e-15, "{e:?}");
        }
        let (_, e) = exact_frictionless(&P, [0.0, 0.0, 0.5, -1.0], 0.0, 1.0).unwrap();
        assert!(e.is_empty() || e[0].time > 0.1, "{e:?}");
    }

    #[test]
    fn rejects_bad_input_and_sticking() {
        assert!(exact_frictionless(&P, [0.0, 0.0, 0.6, 0.0], 0.0, 1.0).is_err());
        assert!(
            exact_frictionless(&FrictionlessParams { b1: 2.0, ..P }, [0.0; 4], 0.0, 1.0).is_err()
        );
        let plastic = FrictionlessParams {
            restitution: 0.0,
            ..P
        };
        // R = 0: the first impact separates (handled), a later one sticks (refused).
        let err = exact_frictionless(&plastic, [0.0; 4], 0.0, 50.0).unwrap_err();
        assert!(err.to_string().contains("sticking"), "{err}");
        let (_, events) = exact_frictionless(&plastic, [0.0; 4], 0.0, 2.0).unwrap();
        assert_eq!(events.len(), 1);
    }
}
