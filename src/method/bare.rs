//! Rung 0 of the kernel ladder on the CPU, the twin of `shaders/bare.wgsl`: the bare RK4 step
//! of the model over [`LANES`] points at once, the least an integrator of it must do per step.
//! `rattle bench` measures the production backends as fractions of it. The Coulomb field in
//! the slip mode its friction sign is held in (no mode switch, no events, no detector, no
//! observables), the forcing rotated by half a step; the results are not the model's.

use super::lanes::LANES;
use crate::model::Params;
use crate::real::Real;
use rayon::prelude::*;

/// What the bare step folds in as constants (the kernel's literal block `BARE_*`).
#[derive(Clone, Copy, Debug)]
pub struct BareConsts<F> {
    pub b1: F,
    pub delta: F,
    /// The friction force, held at +fk (slip in the positive direction).
    pub t: F,
    pub inv_mu: F,
    /// eta of a point that does not vary it.
    pub eta: F,
    /// Phase of one step, 2 pi / N.
    pub dphi: F,
    /// cos and sin of half a step's phase.
    pub half: [F; 2],
}

impl BareConsts<f64> {
    /// The constants of `p` at `steps` steps per forcing period, in f64 (every value rounds
    /// once to the kernel's precision).
    pub fn new(p: &Params<f64>, steps: u32) -> BareConsts<f64> {
        let dphi = 2.0 * std::f64::consts::PI / f64::from(steps);
        BareConsts {
            b1: p.b1,
            delta: p.delta,
            t: p.fk,
            inv_mu: 1.0 / p.mu,
            eta: p.eta,
            dphi,
            half: [(0.5 * dphi).cos(), (0.5 * dphi).sin()],
        }
    }

    /// The same constants rounded to `F`.
    pub fn cast<F: Real>(&self) -> BareConsts<F> {
        BareConsts {
            b1: F::of(self.b1),
            delta: F::of(self.delta),
            t: F::of(self.t),
            inv_mu: F::of(self.inv_mu),
            eta: F::of(self.eta),
            dphi: F::of(self.dphi),
            half: self.half.map(F::of),
        }
    }
}

/// The state of [`LANES`] points, component by component.
type Lanes<F> = [[F; LANES]; 4];

/// model.rs `field` in slip with the friction force held at `k.t`, on every lane; `c`: cos
/// of the forcing (the same for every lane: they step together).
#[inline(always)]
fn bare_field<F: Real>(k: &BareConsts<F>, y: &Lanes<F>, c: F) -> Lanes<F> {
    let mut f = [[F::zero(); LANES]; 4];
    for l in 0..LANES {
        let d = k.b1 * k.delta * (y[1][l] - y[3][l]);
        f[0][l] = y[1][l];
        f[1][l] = c - k.b1 * y[1][l] - y[0][l] - d - k.t;
        f[2][l] = y[3][l];
        f[3][l] = (d + k.t) * k.inv_mu;
    }
    f
}

/// events.rs `mid_step`: the forcing half a step on.
#[inline(always)]
fn bare_rotate<F: Real>(k: &BareConsts<F>, cs: [F; 2]) -> [F; 2] {
    let [hc, hs] = k.half;
    [cs[0] * hc - cs[1] * hs, cs[1] * hc + cs[0] * hs]
}

/// `y + a * x` on every lane, with a per-lane `a`.
#[inline(always)]
fn axpy<F: Real>(y: &Lanes<F>, a: &[F; LANES], x: &Lanes<F>) -> Lanes<F> {
    std::array::from_fn(|c| std::array::from_fn(|l| y[c][l] + a[l] * x[c][l]))
}

/// Runs every point (`etas`, from `y0`) for `periods` periods of `steps` steps, [`LANES`]
/// points per grid step and the lanes over the cores; the final states. Compiled for AVX2
/// where the CPU has it, as the production lanes are (`lanes::run_lanes`).
pub fn bare<F: Real>(
    k: &BareConsts<f64>,
    etas: &[f64],
    y0: [f64; 4],
    periods: u32,
    steps: u32,
) -> Vec<[f64; 4]> {
    let kf: BareConsts<F> = k.cast();
    etas.par_chunks(LANES)
        .flat_map_iter(|chunk| {
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2, checked just above.
                return unsafe { bare_lanes_avx2(&kf, chunk, y0, periods, steps) };
            }
            bare_lanes(&kf, chunk, y0, periods, steps)
        })
        .collect()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn bare_lanes_avx2<F: Real>(
    kf: &BareConsts<F>,
    chunk: &[f64],
    y0: [f64; 4],
    periods: u32,
    steps: u32,
) -> Vec<[f64; 4]> {
    bare_lanes(kf, chunk, y0, periods, steps)
}

/// The points of `chunk` (at most [`LANES`]) in lanes; the final states.
#[inline(always)]
fn bare_lanes<F: Real>(
    kf: &BareConsts<F>,
    chunk: &[f64],
    y0: [f64; 4],
    periods: u32,
    steps: u32,
) -> Vec<[f64; 4]> {
    let h: [F; LANES] =
        std::array::from_fn(|l| kf.dphi / chunk.get(l).map_or(kf.eta, |&e| F::of(e)));
    let half_h = h.map(|v| F::of(0.5) * v);
    let sixth = h.map(|v| v / F::of(6.0));
    let mut y: Lanes<F> = std::array::from_fn(|c| [F::of(y0[c]); LANES]);
    for _ in 0..periods {
        // Phase 0 at the start of every period, as the forcing table has it.
        let mut cs = [F::one(), F::zero()];
        let mut f0 = bare_field(kf, &y, cs[0]);
        for _ in 0..steps {
            let cm = bare_rotate(kf, cs);
            let c1 = bare_rotate(kf, cm);
            let k2 = bare_field(kf, &axpy(&y, &half_h, &f0), cm[0]);
            let k3 = bare_field(kf, &axpy(&y, &half_h, &k2), cm[0]);
            let k4 = bare_field(kf, &axpy(&y, &h, &k3), c1[0]);
            for c in 0..4 {
                for l in 0..LANES {
                    let two = F::of(2.0);
                    y[c][l] += sixth[l] * (f0[c][l] + two * (k2[c][l] + k3[c][l]) + k4[c][l]);
                }
            }
            // First same as last: the end's field is the next step's first stage.
            f0 = bare_field(kf, &y, c1[0]);
            cs = c1;
        }
    }
    (0..chunk.len())
        .map(|l| std::array::from_fn(|c| y[c][l].to_f64()))
        .collect()
}
