//! The impact oscillator with dry friction, as specified in the project's model page:
//! parameters, the vector field of each mode, the impact map and the stick/lock conditions.
//!
//! Friction is stored in the Stribeck form `T = ((fs - fk)/(1 + l1|v|) + fk + l2 v^2) * s`;
//! Coulomb friction with coefficient lambda is the special case `fs = fk = lambda, l1 = l2 = 0`,
//! so the CPU integrator and the shader need one friction law only.

use crate::real::Real;
use serde::{Deserialize, Serialize};

/// Motion mode. The mode, not sign(v), fixes the friction direction inside a step.
/// The numeric values are shared with the shader (`MODE_*` constants).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[repr(u32)]
pub enum Mode {
    /// m2 slips with v = y2 - y4 > 0 (friction on m2 is +T).
    SlipPos = 0,
    /// m2 slips with v < 0.
    SlipNeg = 1,
    /// Masses move together away from the stops (v = 0).
    Stick = 2,
    /// m2 pressed against the stop z = +r, moving with m1.
    LockPos = 3,
    /// m2 pressed against the stop z = -r, moving with m1.
    LockNeg = 4,
}

impl Mode {
    pub fn from_u32(m: u32) -> Mode {
        match m {
            0 => Mode::SlipPos,
            1 => Mode::SlipNeg,
            2 => Mode::Stick,
            3 => Mode::LockPos,
            _ => Mode::LockNeg,
        }
    }
    /// Slip mode with friction direction `s` (s > 0 => SlipPos).
    pub fn slip<F: Real>(s: F) -> Mode {
        if s > F::zero() {
            Mode::SlipPos
        } else {
            Mode::SlipNeg
        }
    }
    pub fn is_slip(self) -> bool {
        matches!(self, Mode::SlipPos | Mode::SlipNeg)
    }
}

/// The model's parameters, declared once: each row is the [`Params`] field, its [`Param`]
/// variant, the config and command-line key, the default (the paper's value), the allowed
/// range (as text and as a test), and what it is. [`model_params!`] hands the table to a macro that generates from it: here
/// `Params`, its checks and conversions and the `Param` vocabulary; in `config` the `[model]`
/// keys; in `gpu::layout` the kernel's slots, its `Params` struct, accessors and `set_param`.
/// A new parameter is one row here plus its physics.
macro_rules! model_params {
    ($then:ident) => {
        $then! {
            eta, Eta, "eta", 1.5, "(0, inf)", |v| v > 0.0, "Forcing frequency.";
            restitution, Restitution, "R", 0.6, "[0, 1]", |v| (0.0..=1.0).contains(&v), "Restitution coefficient.";
            fs, Fs, "fs", 0.25, "[0, inf)", |v| v >= 0.0, "Static friction limit (Stribeck).";
            fk, Fk, "fk", 0.05, "[0, inf)", |v| v >= 0.0, "Kinetic friction level (Stribeck).";
            l1, L1, "l1", 1.42, "[0, inf)", |v| v >= 0.0, "Stribeck decay rate.";
            l2, L2, "l2", 0.005, "[0, inf)", |v| v >= 0.0, "Quadratic (viscous-like) friction growth.";
            clearance, Clearance, "r", 0.8, "(0, inf)", |v| v > 0.0, "Clearance: |z| <= r.";
            delta, Delta, "delta", 0.5, "[0, inf)", |v| v >= 0.0, "Damper ratio c2/c1 between the masses.";
            b1, B1, "b1", 0.1, "[0, inf)", |v| v >= 0.0, "Damping of m1.";
            mu, Mu, "mu", 0.693, "(0, inf)", |v| v > 0.0, "Mass ratio m2/m1.";
        }
    };
}
pub(crate) use model_params;

macro_rules! define_params {
    ($($field:ident, $variant:ident, $key:literal, $default:literal, $range:literal, |$v:ident| $ok:expr, $doc:literal;)*) => {
        /// Number of fields of [`Params`].
        pub const N_PARAMS: usize = [$(stringify!($field)),*].len();

        /// Model parameters in the precision of the integrator (the rows of [`model_params!`]).
        #[derive(Clone, Copy, Debug, Serialize)]
        pub struct Params<F> {
            $(#[doc = $doc] pub $field: F,)*
        }

        impl<F: Copy> Params<F> {
            /// Field names in declaration order (the kernel's `Params` and slots).
            pub const FIELDS: &'static [&'static str] = &[$(stringify!($field)),*];

            /// Values in the order of [`Params::FIELDS`].
            pub fn values(&self) -> Vec<F> {
                vec![$(self.$field),*]
            }
        }

        impl<F: Real> Params<F> {
            pub fn is_finite(&self) -> bool {
                [$(self.$field),*].iter().all(|v| v.is_finite())
            }
        }

        impl Params<f64> {
            /// Checks every parameter; the error names the first one out of range.
            pub fn check(&self) -> Result<(), ParamError> {
                $(
                    let $v = self.$field;
                    if !($v.is_finite() && $ok) {
                        return Err(ParamError { name: $key, value: $v, range: $range });
                    }
                )*
                Ok(())
            }

            /// Every parameter at its default (the paper's values; Stribeck friction levels).
            pub fn defaults() -> Self {
                Params { $($field: $default,)* }
            }

            pub fn cast<F: Real>(&self) -> Params<F> {
                Params { $($field: F::of(self.$field),)* }
            }
        }

        /// A model parameter that sweeps and maps vary: the one vocabulary of config keys,
        /// command line, kernel codes and plot labels. The code of a field's variant is its
        /// position in [`Params::FIELDS`]; `Lambda` (the Coulomb coefficient) sets fs and fk.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
        #[repr(u32)]
        pub enum Param {
            $(#[doc = $doc] #[serde(rename = $key)] $variant,)*
            /// Coulomb coefficient: sets both Stribeck levels fs and fk.
            #[serde(rename = "lambda")]
            Lambda,
        }

        impl Param {
            pub const ALL: [Param; N_PARAMS + 1] = [$(Param::$variant,)* Param::Lambda];

            /// The config and command-line name.
            pub fn name(self) -> &'static str {
                match self {
                    $(Param::$variant => $key,)*
                    Param::Lambda => "lambda",
                }
            }

            /// Sets this parameter of `p` (the host twin of the kernel's `set_param`).
            pub fn set<F: Copy>(self, p: &mut Params<F>, v: F) {
                match self {
                    $(Param::$variant => p.$field = v,)*
                    Param::Lambda => {
                        p.fs = v;
                        p.fk = v;
                    }
                }
            }

            /// This parameter's value in `p` (`Lambda`: the static coefficient).
            pub fn get<F: Copy>(self, p: &Params<F>) -> F {
                match self {
                    $(Param::$variant => p.$field,)*
                    Param::Lambda => p.fs,
                }
            }

            /// The [`Params`] field this parameter sets (`None` for `Lambda`, which sets two).
            pub fn field(self) -> Option<&'static str> {
                match self {
                    $(Param::$variant => Some(stringify!($field)),)*
                    Param::Lambda => None,
                }
            }
        }
    };
}
model_params!(define_params);

/// A parameter that is out of its allowed range.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("parameter `{name}` = {value} is outside the allowed range {range}")]
pub struct ParamError {
    pub name: &'static str,
    pub value: f64,
    pub range: &'static str,
}

impl<F: Real> Params<F> {
    /// Coulomb friction (l1 = l2 = 0, fs = fk): [`friction`] is fk for every finite speed.
    #[inline(always)]
    pub fn is_coulomb(&self) -> bool {
        self.l1 == F::zero() && self.l2 == F::zero() && self.fs == self.fk
    }
}

impl Params<f64> {
    /// The paper's Fig. 2 point (Coulomb friction, lambda = 0.02), at the given eta.
    pub fn paper(eta: f64) -> Self {
        let mut p = Params::defaults();
        p.eta = eta;
        Param::Lambda.set(&mut p, 0.02);
        p.l1 = 0.0;
        p.l2 = 0.0;
        p
    }
}

impl Param {
    /// Axis label of plots.
    pub fn label(self) -> String {
        match self {
            Param::Eta => "eta (forcing frequency)".into(),
            Param::Restitution => "R (restitution)".into(),
            Param::Lambda => "lambda (Coulomb friction)".into(),
            p => p.name().into(),
        }
    }

    /// Why varying `self` cannot change the motion, where it cannot. The friction law
    /// `fs - (fs - fk) m/(1 + m) + l2 w^2`, m = l1 w ([`friction`]), never reads fk while
    /// l1 = 0, nor l1 while fs = fk (Coulomb friction is both). `p` holds the fixed values,
    /// `varied` every parameter the run varies (its axes, swept or uncertain parameters).
    pub fn without_effect(self, p: &Params<f64>, varied: &[Param]) -> Option<String> {
        let varies = |q: Param| varied.contains(&q);
        match self {
            Param::Fk if p.l1 == 0.0 && !varies(Param::L1) => Some(
                "fk has no effect: the friction law reads fk only through l1 |v|, and l1 = 0 \
                 (Coulomb friction sets fs = fk = lambda, l1 = l2 = 0)"
                    .into(),
            ),
            Param::L1 if p.fs == p.fk && !varies(Param::Fs) && !varies(Param::Fk) => Some(format!(
                "l1 has no effect: the friction law reads l1 only through fs - fk, and fs = fk \
                 = {} (Coulomb friction sets fs = fk = lambda, l1 = l2 = 0)",
                p.fs
            )),
            _ => None,
        }
    }

    /// Code of the parameter in the kernel's `set_param` (`VARY_*` in the shader): a field's
    /// position in [`Params::FIELDS`], then `Lambda`.
    pub fn code(self) -> u32 {
        self as u32
    }

    /// Whether a map over `self` and `other` varies one quantity twice (lambda is fs and fk).
    pub fn overlaps(self, other: Param) -> bool {
        let fric = |p: Param| matches!(p, Param::Lambda | Param::Fs | Param::Fk);
        self == other
            || (fric(self) && fric(other) && (self == Param::Lambda || other == Param::Lambda))
    }
}

impl std::fmt::Display for Param {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown parameter name.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("unknown parameter `{0}` (one of {names})", names = Param::ALL.iter().map(|p| p.name()).collect::<Vec<_>>().join(", "))]
pub struct UnknownParam(pub String);

impl std::str::FromStr for Param {
    type Err = UnknownParam;
    fn from_str(s: &str) -> Result<Param, UnknownParam> {
        Param::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| UnknownParam(s.to_string()))
    }
}

/// Slip friction in slip mode with direction `s` (+1 or -1), as a function of the signed slip
/// speed w = s*v: the Stribeck law `(fs - fk)/(1 + l1 w) + fk + l2 w^2` is smooth in w and
/// is continued past w = 0 (until the reversal event ends the mode), so a step that crosses
/// v = 0 sees no kink and keeps fourth order; |v| would put a kink in the step. The divisor is
/// kept from vanishing far below any overshoot a step can make. Coulomb friction
/// (fs = fk, l1 = l2 = 0) is the constant fk. Written as `fs - (fs - fk) m/(1 + m)` with
/// `m = l1 w`, so that at w = 0 it is fs to the last bit, the static limit the stick and lock
/// tests use (`(fs - fk) + fk` may round off fs, and then a slip that starts at rest can
/// accelerate against the direction the needed force chose), with the old form's latency.
///
/// With Coulomb friction the law's value is `fk + 0 w` bit for bit (fk for a finite w, NaN
/// for an infinite or NaN one), taken without the division: the test is one branch the CPU
/// predicts (the CPU lanes compile it away per batch, `lanes::slip_field`).
#[inline(always)]
pub fn friction<F: Real>(p: &Params<F>, w: F) -> F {
    if p.is_coulomb() {
        return coulomb_friction(p.fk, w);
    }
    let m = (p.l1 * w).max(F::of(-0.5));
    p.fs - (p.fs - p.fk) * m / (F::one() + m) + p.l2 * w * w
}

/// d[`friction`]/dw: zero where the divisor is clamped. With Coulomb friction q is 1 for a
/// finite w (and the sum NaN otherwise), so the decay is `-(fs - fk) l1` bit for bit without
/// the division (as in [`friction`]).
#[inline(always)]
pub fn friction_slope<F: Real>(p: &Params<F>, w: F) -> F {
    if p.is_coulomb() {
        return coulomb_slope(p.fs, p.fk, p.l1, p.l2, w);
    }
    let q = F::one() + p.l1 * w;
    let decay = if q > F::of(0.5) {
        -(p.fs - p.fk) * p.l1 / (q * q)
    } else {
        F::zero()
    };
    decay + F::of(2.0) * p.l2 * w
}

/// [`friction`]'s value with Coulomb parameters, `fk + 0 w` (the CPU lanes' Coulomb batches
/// call it too).
#[inline(always)]
pub fn coulomb_friction<F: Real>(fk: F, w: F) -> F {
    fk + F::zero() * w
}

/// [`friction_slope`]'s value with Coulomb parameters (q = 1), `-(fs - fk) l1 + 2 l2 w`.
#[inline(always)]
pub fn coulomb_slope<F: Real>(fs: F, fk: F, l1: F, l2: F, w: F) -> F {
    -(fs - fk) * l1 + F::of(2.0) * l2 * w
}

/// `1/mu`, so that the field multiplies where it would divide: a division costs several
/// multiplications on SIMD adapters, and this one is loop-invariant (the kernel computes it
/// once per point; here the compiler hoists it).
#[inline(always)]
pub fn inv_mu<F: Real>(p: &Params<F>) -> F {
    F::one() / p.mu
}

/// `1/(1 + mu)`, see [`inv_mu`].
#[inline(always)]
pub fn inv_one_plus_mu<F: Real>(p: &Params<F>) -> F {
    F::one() / (F::one() + p.mu)
}

#[inline(always)]
pub fn field<F: Real>(p: &Params<F>, y: &[F; 4], mode: Mode, c: F) -> [F; 4] {
    match mode {
        Mode::SlipPos | Mode::SlipNeg => {
            let v = y[1] - y[3];
            // Friction direction s of the mode; the law is evaluated at the signed speed s*v.
            let s = if mode == Mode::SlipPos {
                F::one()
            } else {
                -F::one()
            };
            let t = s * friction(p, s * v);
            let d = p.b1 * p.delta * v;
            [
                y[1],
                c - p.b1 * y[1] - y[0] - d - t,
                y[3],
                (d + t) * inv_mu(p),
            ]
        }
        _ => {
            // Masses move together: same acceleration for both, so v stays exactly 0.
            let a = (c - p.b1 * y[1] - y[0]) * inv_one_plus_mu(p);
            [y[1], a, y[3], a]
        }
    }
}

/// Power dissipated by friction at state `y` with field `k` in any mode: `T * v`, with `T`
/// recovered from the field (`mu * y4' = b1*delta*v + T`) so that no mode or law is evaluated
/// twice; zero while the masses move together (v = 0 exactly there).
#[inline(always)]
pub fn friction_power<F: Real>(p: &Params<F>, y: &[F; 4], k: &[F; 4]) -> F {
    let v = y[1] - y[3];
    (p.mu * k[3] - p.b1 * p.delta * v) * v
}

/// Jacobian of [`field`] with respect to the state (row i: d y_i' / d y_j), in a fixed mode.
/// The forcing is additive, so it does not enter. In slip the friction force s*T(s*v) has
/// slope T'(w) in v (the two signs cancel); together the masses share one acceleration.
#[inline(always)]
pub fn jacobian<F: Real>(p: &Params<F>, y: &[F; 4], mode: Mode) -> [[F; 4]; 4] {
    let (o, z) = (F::one(), F::zero());
    match mode {
        Mode::SlipPos | Mode::SlipNeg => {
            let s = if mode == Mode::SlipPos { o } else { -o };
            let e = p.b1 * p.delta + friction_slope(p, s * (y[1] - y[3]));
            [
                [z, o, z, z],
                [-o, -p.b1 - e, z, e],
                [z, z, z, o],
                [z, e / p.mu, z, -e / p.mu],
            ]
        }
        _ => {
            let q = inv_one_plus_mu(p);
            let row = [-q, -p.b1 * q, z, z];
            [[z, o, z, z], row, [z, z, z, o], row]
        }
    }
}

/// `J(y) x` for one tangent vector, without forming [`jacobian`] (the kernel's form; its rows
/// written out, with the zeros left out).
#[inline(always)]
pub fn jacobian_times<F: Real>(p: &Params<F>, y: &[F; 4], mode: Mode, x: &[F; 4]) -> [F; 4] {
    match mode {
        Mode::SlipPos | Mode::SlipNeg => {
            let s = if mode == Mode::SlipPos {
                F::one()
            } else {
                -F::one()
            };
            let e = p.b1 * p.delta + friction_slope(p, s * (y[1] - y[3]));
            let rel = e * (x[1] - x[3]);
            [x[1], -x[0] - p.b1 * x[1] - rel, x[3], rel / p.mu]
        }
        _ => {
            let a = -(x[0] + p.b1 * x[1]) / (F::one() + p.mu);
            [x[1], a, x[3], a]
        }
    }
}

/// Force m2 needs from m1 to move with it (v = 0): `Tn = mu * a`.
#[inline(always)]
pub fn needed_force<F: Real>(p: &Params<F>, y: &[F; 4], c: F) -> F {
    p.mu * (c - p.b1 * y[1] - y[0]) * inv_one_plus_mu(p)
}

/// Time derivative of [`needed_force`] along the common motion, with `sn = sin(eta*tau)`
/// and `a` the common acceleration; used to interpolate the release guard.
#[inline(always)]
pub fn needed_force_rate<F: Real>(p: &Params<F>, y: &[F; 4], a: F, sn: F) -> F {
    p.mu * (-p.eta * sn - p.b1 * a - y[1]) * inv_one_plus_mu(p)
}

/// Impact map: momentum `y2 + mu*y4` conserved, relative velocity reversed with factor R.
#[inline(always)]
pub fn impact<F: Real>(p: &Params<F>, y: &mut [F; 4]) {
    let inv = inv_one_plus_mu(p);
    let vc = (y[1] + p.mu * y[3]) * inv;
    let w = p.restitution * (y[1] - y[3]);
    y[1] = vc - p.mu * inv * w;
    y[3] = vc + inv * w;
}

/// Sets both velocities to the common (momentum-preserving) velocity: v = 0 exactly.
#[inline(always)]
pub fn co_move<F: Real>(p: &Params<F>, y: &mut [F; 4]) {
    let vc = (y[1] + p.mu * y[3]) / (F::one() + p.mu);
    y[1] = vc;
    y[3] = vc;
}

/// Kinetic energy lost when the relative velocity jumps from `vb` to `va` with momentum
/// conserved (an impact, or co-motion): `mu / (2 (1 + mu)) (vb^2 - va^2)`, in units of m1.
#[inline(always)]
pub fn impact_loss<F: Real>(p: &Params<F>, vb: F, va: F) -> F {
    F::of(0.5) * p.mu * inv_one_plus_mu(p) * (vb * vb - va * va)
}

/// Mode entered at rest (v = 0) given the needed force `tn` and the stop m2 touches
/// (`stop` = +1 at z = +r, -1 at z = -r, 0 away from the stops).
/// A stop can push m2 inward but not pull it, so a lock holds on one side only.
#[inline(always)]
pub fn mode_at_rest<F: Real>(p: &Params<F>, stop: i32, tn: F) -> Mode {
    if stop > 0 {
        if tn <= p.fs {
            Mode::LockPos
        } else {
            Mode::SlipPos
        }
    } else if stop < 0 {
        if tn >= -p.fs {
            Mode::LockNeg
        } else {
            Mode::SlipNeg
        }
    } else if tn.abs() <= p.fs {
        Mode::Stick
    } else {
        Mode::slip(tn)
    }
}

/// Initial mode of a state: slip by the sign of v, or the at-rest rule when v = 0.
pub fn initial_mode<F: Real>(p: &Params<F>, y: &[F; 4], c: F) -> Mode {
    let v = y[1] - y[3];
    if v != F::zero() {
        return Mode::slip(v);
    }
    let z = y[2] - y[0];
    let stop = if z >= p.clearance {
        1
    } else if z <= -p.clearance {
        -1
    } else {
        0
    };
    mode_at_rest(p, stop, needed_force(p, y, c))
}
