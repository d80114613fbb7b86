//! The pieces of an event-located step that need no integrator: the forcing table and its
//! small-angle rotation, the guard bracket on the cubic Hermite interpolant, the quiet-step
//! bound and the Illinois root refinement (`shaders/events.wgsl` is the twin).

use super::{EV_NONE, MAX_ROOT_ITERS};
use crate::real::Real;
use std::any::Any;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

/// cos and sin of half a step's forcing phase, pi/N, computed in f64 and rounded once to F.
pub fn half_step<F: Real>(n: u32) -> (F, F) {
    let a = std::f64::consts::PI / n as f64;
    (F::of(a.cos()), F::of(a.sin()))
}

/// The forcing (cos, sin) at the middle of a step from the forcing (c, s) at its start: one
/// rotation by [`half_step`]. The table's mid-step entries are this, so that the kernel's quiet
/// loop can compute them from the step's start instead of reading them from the table (a
/// gather, lane by lane, on SIMD adapters); error 1-2 units in the last place instead of half
/// a unit. Products and difference rounded separately, as llvmpipe evaluates the kernel's
/// twin (it does not fuse them), so that both give the same bits there.
#[inline(always)]
pub fn mid_step<F: Real>(c: F, s: F, half: (F, F)) -> (F, F) {
    (c * half.0 - s * half.1, s * half.0 + c * half.1)
}

/// [`forcing_table`] of `n` steps in F, computed once per process and shared by every
/// integrator: a map's Newton trials each hold one (a quarter of a million of them at
/// 512 x 512, 4 KiB and 2N + 1 sines and cosines apiece when each computed its own).
pub fn shared_forcing_table<F: Real>(n: u32) -> Arc<[[F; 2]]> {
    type Tables = HashMap<(u32, &'static str), Box<dyn Any + Send + Sync>>;
    static TABLES: OnceLock<Mutex<Tables>> = OnceLock::new();
    let mut tables = TABLES.get_or_init(Default::default).lock().unwrap();
    tables
        .entry((n, F::NAME))
        .or_insert_with(|| Box::new(Arc::<[[F; 2]]>::from(forcing_table::<F>(n))))
        .downcast_ref::<Arc<[[F; 2]]>>()
        .expect("one table type per precision name")
        .clone()
}

/// cos and sin of the forcing at the grid's stage phases 2*pi*j/(2N), j = 0..=2N, in F, on CPU
/// and GPU alike: at the step ends (j even) computed in f64 and rounded once; at the middles
/// (j odd) [`mid_step`] of the entry before.
pub fn forcing_table<F: Real>(n: u32) -> Vec<[F; 2]> {
    let half = half_step::<F>(n);
    let mut t: Vec<[F; 2]> = Vec::with_capacity(2 * n as usize + 1);
    for j in 0..=2 * n {
        if j % 2 == 0 {
            let phi = std::f64::consts::PI * j as f64 / n as f64;
            t.push([F::of(phi.cos()), F::of(phi.sin())]);
        } else {
            let [c, s] = t[j as usize - 1];
            let (cm, sm) = mid_step(c, s, half);
            t.push([cm, sm]);
        }
    }
    t
}

/// cos and sin of a small angle (|d| <= pi/N) by their Taylor series, exact to f64 round-off
/// for N >= 8. Only + - * / are used, as in the f64 shader.
#[inline(always)]
pub fn cos_sin_small<F: Real>(d: F) -> (F, F) {
    let d2 = d * d;
    let o = F::one();
    let c = o - d2 / F::of(2.0)
        * (o - d2 / F::of(12.0)
            * (o - d2 / F::of(30.0)
                * (o - d2 / F::of(56.0) * (o - d2 / F::of(90.0) * (o - d2 / F::of(132.0))))));
    let s = d
        * (o - d2 / F::of(6.0)
            * (o - d2 / F::of(20.0)
                * (o - d2 / F::of(42.0) * (o - d2 / F::of(72.0) * (o - d2 / F::of(110.0))))));
    (c, s)
}

/// The piece of a guard's cubic Hermite interpolant (power form `a0 + a1 t + a2 t^2 + a3 t^3`
/// on the step, t in [0, 1]) that holds its first crossing from > 0 to <= 0: p(lo) > 0 >= p(hi).
/// `ev` is the event the guard signals, EV_NONE when there is no crossing.
#[derive(Clone, Copy, Debug)]
pub struct Bracket<F> {
    pub a0: F,
    pub a1: F,
    pub a2: F,
    pub a3: F,
    pub lo: F,
    pub hi: F,
    pub plo: F,
    pub phi: F,
    pub ev: u32,
}

impl<F: Real> Bracket<F> {
    pub(crate) fn none() -> Self {
        let z = F::zero();
        Bracket {
            a0: z,
            a1: z,
            a2: z,
            a3: z,
            lo: F::of(2.0),
            hi: F::of(2.0),
            plo: z,
            phi: z,
            ev: EV_NONE,
        }
    }
}

/// Brackets the first crossing of a guard: `g0, g1` are the guard at both ends of the step,
/// `m0, m1` its time derivatives times the step length. The cubic is split at its extrema so
/// that each piece is monotone: a grazing double crossing inside one step is not missed. Cheap
/// when there is no crossing, which is almost every step; the root itself is refined only for
/// the guards that can be the earliest event ([`Integrator::locate`]). A dip inside the step
/// counts only where it reaches `-floor`, the guard's rounding level: a dip shallower than
/// that is the interpolant bridging values the precision cannot tell apart (a sub-step far
/// shorter than a step, whose end the state rounds to the start), not a crossing.
#[inline(always)]
pub fn bracket<F: Real>(g0: F, g1: F, m0: F, m1: F, floor: F, ev: u32) -> Bracket<F> {
    let mut b = Bracket::none();
    let d = g1 - g0;
    // The Hermite cubic stays within max(|m0-d|,|m1-d|)/4 of its chord.
    let bound = F::of(0.25) * (m0 - d).abs().max((m1 - d).abs());
    if g0.min(g1) > bound || g0.max(g1) < -bound {
        return b;
    }
    let a1 = m0;
    let a2 = F::of(3.0) * d - F::of(2.0) * m0 - m1;
    let a3 = m0 + m1 - F::of(2.0) * d;
    // Extrema: roots of 3 a3 t^2 + 2 a2 t + a1 (stable quadratic formula).
    let qa = F::of(3.0) * a3;
    let qb = F::of(2.0) * a2;
    let none = F::of(2.0);
    let mut t1 = none;
    let mut t2 = none;
    if qa != F::zero() {
        let disc = qb * qb - F::of(4.0) * qa * a1;
        if disc >= F::zero() {
            let sq = disc.sqrt();
            let q = if qb >= F::zero() {
                F::of(-0.5) * (qb + sq)
            } else {
                F::of(-0.5) * (qb - sq)
            };
            t1 = q / qa;
            t2 = if q != F::zero() { a1 / q } else { t1 };
        }
    } else if qb != F::zero() {
        t1 = -a1 / qb;
    }
    if t1 > t2 {
        std::mem::swap(&mut t1, &mut t2);
    }
    // An extremum before the step does not bound a piece: the later one must still split it
    // (a slip that starts at v = 0, turns back and reverses a fraction of a step later).
    if t1 <= F::zero() {
        t1 = t2;
        t2 = none;
    }
    // The three monotone pieces, unrolled as in the shader.
    let (mut lo, mut plo) = (F::zero(), g0);
    let b1 = if t1 > F::zero() && t1 < F::one() {
        t1
    } else {
        F::one()
    };
    let b2 = if t2 > b1 && t2 < F::one() {
        t2
    } else {
        F::one()
    };
    for hi in [b1, b2, F::one()] {
        // At the step's end the guard itself: the power form's rounding could lift a guard
        // that ends at zero above it, and the event would be lost. A guard that ends at zero
        // while rising has not crossed (a sub-step too short for the precision to resolve).
        let end = hi >= F::one();
        let phi = if end { g1 } else { hermite(g0, a1, a2, a3, hi) };
        let crossed = if end {
            g1 < F::zero() || (g1 == F::zero() && m1 < F::zero())
        } else {
            phi <= -floor
        };
        if plo > F::zero() && crossed {
            b = Bracket {
                a0: g0,
                a1,
                a2,
                a3,
                lo,
                hi,
                plo,
                phi,
                ev,
            };
            return b;
        }
        if hi >= F::one() {
            break;
        }
        lo = hi;
        plo = phi;
    }
    b
}

/// The guard stays above the bound of [`bracket`] over the whole step, so it cannot reach zero.
#[inline(always)]
pub fn clear_of<F: Real>(g0: F, g1: F, m0: F, m1: F) -> bool {
    let d = g1 - g0;
    let bound = F::of(0.25) * (m0 - d).abs().max((m1 - d).abs());
    g0.min(g1) > bound
}

/// Both impact guards `r - z` and `r + z` at once: their chords have opposite slopes and the
/// same bound of [`clear_of`], so both stay above it when the distance to the nearer stop,
/// `r - max(|z0|, |z1|)`, does (one bound and one comparison instead of two).
#[inline(always)]
pub fn clear_of_stops<F: Real>(r: F, z0: F, z1: F, zd0: F, zd1: F) -> bool {
    let d = z1 - z0;
    let bound = F::of(0.25) * (zd0 - d).abs().max((zd1 - d).abs());
    r - z0.abs().max(z1.abs()) > bound
}

/// NaN, infinity, or a state beyond any physical scale fail the point (as in the shader).
#[inline(always)]
pub(crate) fn finite_state<F: Real>(y: &[F; 4]) -> bool {
    let big = F::of(1e30);
    y.iter().all(|v| v.abs() <= big)
}

#[inline(always)]
fn hermite<F: Real>(a0: F, a1: F, a2: F, a3: F, t: F) -> F {
    a0 + t * (a1 + t * (a2 + t * a3))
}

/// Illinois (modified regula falsi) on a bracket; returns the right end of the final bracket,
/// where the event condition already holds.
#[inline(always)]
pub fn illinois<F: Real>(b: &Bracket<F>, tol: F) -> F {
    let (mut lo, mut hi, mut plo, mut phi) = (b.lo, b.hi, b.plo, b.phi);
    let mut side = 0i32;
    for _ in 0..MAX_ROOT_ITERS {
        if hi - lo <= tol {
            break;
        }
        let mut m = (lo * phi - hi * plo) / (phi - plo);
        if !(m > lo && m < hi) {
            m = F::of(0.5) * (lo + hi);
        }
        let pm = hermite(b.a0, b.a1, b.a2, b.a3, m);
        if pm <= F::zero() {
            hi = m;
            phi = pm;
            if side == -1 {
                plo = plo * F::of(0.5);
            }
            side = -1;
            if pm == F::zero() {
                break;
            }
        } else {
            lo = m;
            plo = pm;
            if side == 1 {
                phi = phi * F::of(0.5);
            }
            side = 1;
        }
    }
    hi
}
