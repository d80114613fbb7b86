//! What a point's motion is, declared once: [`Class`] with its array code and name, and for
//! the class map its category code, legend label, colour and period family ([`Shown`]). The
//! classes other than `period-n` are the lines of [`other_classes!`]; the map files, the
//! palette, the sensitivity figure and the JSON's code list all read them from here.

use serde::Serialize;

/// Longest period the detector looks for, and the palette colours one by one.
pub const MAX_PERIOD: u32 = 64;

/// Period families of the class map's legend: (first, last), in legend order.
pub const PERIOD_FAMILIES: [(u32, u32); 7] =
    [(1, 1), (2, 2), (3, 3), (4, 4), (5, 8), (9, 16), (17, 64)];

macro_rules! other_classes {
    ($( #[doc = $doc:literal] $variant:ident = $code:literal, $name:literal, $label:literal,
        category $category:literal, $rgb:expr; )*) => {
        /// The motion a point shows.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
        #[serde(tag = "class", content = "period", rename_all = "snake_case")]
        pub enum Class {
            /// The section repeats after `n` forcing periods.
            Periodic(u32),
            $( #[doc = $doc] $variant, )*
        }

        impl Class {
            /// The classes other than `period-n`, in legend order.
            pub const OTHERS: &[Class] = &[$(Class::$variant),*];

            /// Compact numeric code for arrays: n > 0 period-n, the others as declared.
            pub fn code(&self) -> i32 {
                match self {
                    Class::Periodic(n) => *n as i32,
                    $( Class::$variant => $code, )*
                }
            }

            pub fn name(&self) -> String {
                match self {
                    Class::Periodic(n) => format!("period-{n}"),
                    $( Class::$variant => $name.into(), )*
                }
            }

            /// The class of an array code; codes no class has are `failed`.
            pub fn from_code(c: i32) -> Class {
                match c {
                    n if n > 0 => Class::Periodic(n as u32),
                    $( $code => Class::$variant, )*
                    _ => Class::Failed,
                }
            }

            /// The class map's legend label of a class other than `period-n`.
            fn label(&self) -> &'static str {
                match self {
                    Class::Periodic(_) => "periodic",
                    $( Class::$variant => $label, )*
                }
            }

            /// The class map's category code of a class other than `period-n`.
            fn category_code(&self) -> u16 {
                match self {
                    Class::Periodic(_) => LONG_PERIOD,
                    $( Class::$variant => $category, )*
                }
            }

            /// The class map's colour of a class other than `period-n` (sRGB).
            fn rgb(&self) -> [u8; 3] {
                match self {
                    Class::Periodic(_) => LONG_PERIOD_RGB,
                    $( Class::$variant => $rgb, )*
                }
            }
        }
    };
}

other_classes! {
    /// No period <= 64 and a Lyapunov exponent of about zero.
    QuasiPeriodic = -3, "quasi_periodic", "quasi-periodic", category 100, [0x99, 0xdd, 0x55];
    /// No period <= 64 and a positive Lyapunov exponent.
    Chaotic = -4, "chaotic", "chaotic", category 101, [0x1a, 0x1a, 0x1a];
    /// No period <= 64 found, no Lyapunov estimate to tell quasi-periodic from chaotic.
    Aperiodic = 0, "aperiodic", "aperiodic (no exponent)", category 105, [0x7a, 0x7a, 0x7a];
    /// Undecided: no confirmed cycle, no exponent clearly positive, no passed torus test, even after the extra time the adaptive horizon gives (slow transients, long cycles, chaos with an exponent within its error of zero).
    Unresolved = -5, "unresolved", "unresolved", category 103, [0xff, 0xcc, 0xee];
    /// No impact during the sampled periods.
    NoImpact = -1, "no_impact", "no impact", category 102, [0xe8, 0xe8, 0xe8];
    /// Non-finite state, or too few samples to decide.
    Failed = -2, "failed", "failed", category 104, [0xff, 0x00, 0xff];
}

/// Category code of cells whose starts ended on different attractors (`--starts`).
const COEXISTING: u16 = 106;
/// Category code of cells with a confirmed cycle longer than the detector's 64 periods.
const LONG_PERIOD: u16 = 107;
const LONG_PERIOD_RGB: [u8; 3] = [0x00, 0x55, 0x55];
const COEXISTING_RGB: [u8; 3] = [0x33, 0xcc, 0xee];

impl Class {
    pub fn period(&self) -> Option<u32> {
        match self {
            Class::Periodic(n) => Some(*n),
            _ => None,
        }
    }

    /// The smallest code of a class (the codes are n > 0 and the others').
    pub fn min_code() -> i32 {
        Class::OTHERS.iter().map(Class::code).min().unwrap_or(0)
    }

    /// The codes as the JSON files state them: "n > 0 period-n, 0 aperiodic, -1 no_impact, ...".
    pub fn code_list() -> String {
        let mut others: Vec<&Class> = Class::OTHERS.iter().collect();
        others.sort_by_key(|c| -c.code());
        std::iter::once("n > 0 period-n".to_string())
            .chain(others.iter().map(|c| format!("{} {}", c.code(), c.name())))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// What a cell of a class map shows: a period the palette colours one by one, a longer one,
/// another class, or coexisting attractors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shown {
    Period(u32),
    /// A confirmed cycle of period 65-1024 (a candidate period beyond the detector's, or a
    /// recurrence of the host's search, [`crate::recurrence`]), one
    /// colour for all.
    LongPeriod,
    /// A class other than `period-n`.
    Other(Class),
    Coexisting,
}

impl Shown {
    /// What a cell of class `c` shows (`attractors` > 1: coexisting).
    pub fn of(c: Class, attractors: u8) -> Shown {
        match c {
            _ if attractors > 1 => Shown::Coexisting,
            Class::Periodic(n) if n <= MAX_PERIOD => Shown::Period(n),
            Class::Periodic(_) => Shown::LongPeriod,
            c => Shown::Other(c),
        }
    }

    /// Every kind a class map can show, in legend order.
    pub fn all() -> Vec<Shown> {
        let mut v: Vec<Shown> = (1..=MAX_PERIOD).map(Shown::Period).collect();
        v.push(Shown::LongPeriod);
        v.extend(Class::OTHERS.iter().map(|&c| Shown::Other(c)));
        v.push(Shown::Coexisting);
        v
    }

    /// The category code of the class map (periods keep their number).
    pub fn code(self) -> u16 {
        match self {
            Shown::Period(n) => n as u16,
            Shown::LongPeriod => LONG_PERIOD,
            Shown::Other(c) => c.category_code(),
            Shown::Coexisting => COEXISTING,
        }
    }

    pub fn label(self) -> String {
        match self {
            Shown::Period(n) => format!("period {n}"),
            Shown::LongPeriod => "periods 65-1024".into(),
            Shown::Other(c) => c.label().into(),
            Shown::Coexisting => "coexisting attractors".into(),
        }
    }

    /// The family of a period (`None` for the other kinds).
    pub fn family(self) -> Option<(u32, u32)> {
        match self {
            Shown::Period(n) => PERIOD_FAMILIES
                .iter()
                .copied()
                .find(|&(a, b)| (a..=b).contains(&n)),
            _ => None,
        }
    }

    /// The colour (sRGB); periods take `period_color`, the palette's (`render::period_color`).
    pub fn rgb(self, period_color: fn(u32) -> [u8; 3]) -> [u8; 3] {
        match self {
            Shown::Period(n) => period_color(n),
            Shown::LongPeriod => LONG_PERIOD_RGB,
            Shown::Other(c) => c.rgb(),
            Shown::Coexisting => COEXISTING_RGB,
        }
    }
}
