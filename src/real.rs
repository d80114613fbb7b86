//! The floating-point type the integrator is generic over.
//!
//! The CPU integrator runs in f64 (the reference) and in f32 (to separate precision effects
//! from GPU bugs). The shader does the same with a type alias. A tiny trait keeps the step
//! function readable without pulling in a numeric-traits crate for a dozen operations.

use std::fmt::Debug;
use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

pub trait Real:
    Copy
    + Debug
    + PartialOrd
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
{
    /// "f32" or "f64", as printed in tables and JSON.
    const NAME: &'static str;
    const EPSILON: Self;
    fn of(x: f64) -> Self;
    fn to_f64(self) -> f64;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn is_finite(self) -> bool;
    fn zero() -> Self {
        Self::of(0.0)
    }
    fn one() -> Self {
        Self::of(1.0)
    }
    fn max(self, o: Self) -> Self {
        if self > o { self } else { o }
    }
    fn min(self, o: Self) -> Self {
        if self < o { self } else { o }
    }
}

macro_rules! impl_real {
    ($t:ty, $name:expr) => {
        impl Real for $t {
            const NAME: &'static str = $name;
            const EPSILON: Self = <$t>::EPSILON;
            #[inline(always)]
            fn of(x: f64) -> Self {
                x as $t
            }
            #[inline(always)]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
        }
    };
}
impl_real!(f32, "f32");
impl_real!(f64, "f64");
