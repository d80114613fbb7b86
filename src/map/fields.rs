//! The map's layers, declared once: each line of [`map_layers!`] gives a layer's name, its
//! per-cell type and width, what it holds and how it is read off a point's [`Summary`]. The
//! [`Fields`] struct, its construction, merging, length check, NPY files and the JSON's layer
//! list are generated from it; adding a layer is one line here (plus its computation).

use crate::class::Class;
use crate::classify::Rule;
use crate::decide::Summary;
use crate::method::Diagnostics;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A per-cell value as stored in a part (JSON) and written to its NPY file: NaN stands for a
/// missing value in NPY, null in JSON.
pub trait Layer: Copy {
    type Npy: npyz::AutoSerialize + Copy;
    /// The NPY element type's name, for the JSON's layer list.
    const DTYPE: &'static str;
    fn npy(self) -> Self::Npy;
}

macro_rules! plain_layer {
    ($($t:ty => $name:literal),*) => {$(
        impl Layer for $t {
            type Npy = $t;
            const DTYPE: &'static str = $name;
            fn npy(self) -> $t {
                self
            }
        }
    )*};
}
plain_layer!(u8 => "uint8", u32 => "uint32", u64 => "uint64", i32 => "int32", f64 => "float64");

impl Layer for Option<f64> {
    type Npy = f64;
    const DTYPE: &'static str = "float64";
    fn npy(self) -> f64 {
        self.unwrap_or(f64::NAN)
    }
}

/// A finite value, or None (null in a part, NaN in its NPY file).
fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// One entry of the JSON's layer list.
#[derive(Clone, Debug, Serialize)]
pub struct LayerInfo {
    pub name: &'static str,
    pub file: String,
    pub dtype: &'static str,
    /// Values per cell (the NPY's third axis where 2).
    pub per_cell: usize,
    pub holds: &'static str,
}

macro_rules! map_layers {
    ($( #[doc = $doc:literal] $name:ident: [$t:ty; $w:literal] = |$s:ident| $from:expr; )*) => {
        /// Per-cell fields as stored in partial outputs and NPY files (`PREFIX-NAME.npy`,
        /// shape (y_points, x_points) or (y_points, x_points, 2); a volume's with z_points
        /// first).
        #[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
        pub struct Fields {
            $( #[doc = $doc] #[serde(default)] pub $name: Vec<$t>, )*
        }

        impl Fields {
            /// Every layer: (name, values per cell, what it holds).
            pub const LAYERS: &[(&'static str, usize, &'static str)] =
                &[$((stringify!($name), $w, $doc.trim_ascii())),*];

            /// The fields of the summaries `s`, one cell each (one attractor, not inferred).
            pub fn from_summaries(s: &[Summary]) -> Fields {
                Fields {
                    $( $name: s.iter().flat_map(|$s: &Summary| -> [$t; $w] { $from }).collect(), )*
                }
            }

            pub(crate) fn append(&mut self, o: Fields) {
                $( self.$name.extend(o.$name); )*
            }

            /// The cells `r` of every layer (a slice of a volume, a shard's share).
            pub fn range(&self, r: std::ops::Range<usize>) -> Fields {
                Fields {
                    $( $name: self.$name.get(r.start * $w..r.end * $w).map_or_else(Vec::new, |v| v.to_vec()), )*
                }
            }

            /// Cells of each layer (its length over its values per cell; usize::MAX where that
            /// does not divide).
            pub fn lengths(&self) -> Vec<(&'static str, usize)> {
                let cells = |len: usize, w: usize| if len % w == 0 { len / w } else { usize::MAX };
                vec![$((stringify!($name), cells(self.$name.len(), $w))),*]
            }

            /// The JSON's layer list, files named after `prefix`'s file name.
            pub fn layer_list(prefix: &str) -> Vec<LayerInfo> {
                vec![$(LayerInfo {
                    name: stringify!($name),
                    file: format!("{prefix}-{}.npy", stringify!($name)),
                    dtype: <$t as Layer>::DTYPE,
                    per_cell: $w,
                    holds: $doc.trim_ascii(),
                }),*]
            }

            /// Each layer as the bytes of its NPY file ([`crate::output::npy_bytes`]), in the
            /// order of [`Fields::layer_list`].
            pub fn npy_bytes(&self, dims: &[usize]) -> Vec<(&'static str, Vec<u8>)> {
                let mut out = Vec::new();
                $({
                    let v: Vec<_> = self.$name.iter().map(|x| x.npy()).collect();
                    let shape = layer_shape(dims, $w);
                    out.push((stringify!($name), crate::output::npy_bytes(&shape, &v)));
                })*
                out
            }

            /// Calls `write(name, save)` for each layer, where `save(path)` writes its NPY file
            /// of shape `dims` (`(ny, nx)`, a volume's `(nz, ny, nx)`), with the values per cell
            /// as a last axis where more than one.
            pub fn each_npy<E>(
                &self,
                dims: &[usize],
                write: &mut dyn FnMut(&'static str, &dyn Fn(&Path) -> std::io::Result<()>) -> Result<(), E>,
            ) -> Result<(), E> {
                $({
                    let v: Vec<_> = self.$name.iter().map(|x| x.npy()).collect();
                    let shape = layer_shape(dims, $w);
                    write(stringify!($name), &|p| crate::output::save_npy(p, &shape, &v))?;
                })*
                Ok(())
            }
        }
    };
}

/// A layer's NPY shape: the grid's `dims` (`(ny, nx)` or `(nz, ny, nx)`), then `w` where a
/// cell holds `w` > 1 values.
fn layer_shape(dims: &[usize], w: u64) -> Vec<u64> {
    let mut shape: Vec<u64> = dims.iter().map(|&d| d as u64).collect();
    if w > 1 {
        shape.push(w);
    }
    shape
}

map_layers! {
    /// The class code (n > 0 period-n; the others as the JSON's `class_codes` lists them, from `class::Class`).
    class: [i32; 1] = |c| [c.class.code()];
    /// The period of a periodic cell, 0 otherwise.
    period: [i32; 1] = |c| [c.class.period().map_or(0, |p| p as i32)];
    /// Mean impacts per sampled forcing period.
    impacts_per_period: [f64; 1] = |c| [c.impacts_per_period];
    /// Largest Lyapunov exponent per unit time: of a cell with a confirmed stable cycle the cycle's own (ln |mu_1| over its period, its standard error 0), otherwise the run's over its last windows; NaN where no estimate exists.
    lyapunov: [Option<f64>; 1] = |c| [finite(c.lyapunov.value)];
    /// Largest Floquet multiplier modulus of the cell's stable cycle; NaN where not periodic.
    multiplier: [Option<f64>; 1] = |c| [finite(c.multiplier)];
    /// Impacts over the run.
    impacts: [u64; 1] = |c| [c.diag.impacts];
    /// Entries into stick.
    sticks: [u64; 1] = |c| [c.diag.sticks];
    /// Entries into lock (end of a chattering sequence).
    locks: [u64; 1] = |c| [c.diag.locks];
    /// Steps whose event budget ran out.
    overflows: [u64; 1] = |c| [c.diag.overflows];
    /// Steps ending in slip against the mode's direction (an event missed; 0 is the invariant).
    wrong_slips: [u64; 1] = |c| [c.diag.wrong_slips];
    /// 1 where the state became non-finite.
    nonfinite: [u8; 1] = |c| [u8::from(c.diag.nonfinite)];
    /// 1 where the GPU driver cut the kernel short and the CPU twin computed the cell.
    cpu_rerun: [u8; 1] = |c| [u8::from(c.diag.cpu_rerun)];
    /// Distinct attractors reached from the `--starts` initial states (1 without).
    attractors: [u8; 1] = |_c| [1];
    /// Forcing periods integrated (fewer where early termination confirmed the cycle; 0 for inferred cells).
    periods: [u32; 1] = |c| [c.periods];
    /// 1 where `--refine` filled the cell from the corners of a uniform block.
    inferred: [u8; 1] = |_c| [0];
    /// Standard error of the exponent (batch means); NaN where the exponent is NaN.
    lyapunov_se: [Option<f64>; 1] = |c| [finite(c.lyapunov.se)];
    /// Agreeing digits of the torus test over the cell's last window; NaN without one.
    torus: [Option<f64>; 1] = |c| [finite(c.torus)];
    /// The rule that decided the cell: 0 stable cycle, 1 positive exponent, 2 torus, 3 no impact, 4 failed, 5 no exponent, 6 undecided, 7 exponent lost, 8 escaped (docs/classes.md).
    rule: [u8; 1] = |c| [c.rule.code()];
    /// The two periods Newton tried (0: none).
    tried: [u32; 2] = |c| c.tried;
    /// Mean and largest impact speed over the sampled periods (NaN: no impact).
    impact_speed: [Option<f64>; 2] = |c| c.impact_speed.map(finite);
    /// Energy dissipated per sampled period by impacts and by friction.
    dissipation: [Option<f64>; 2] = |c| c.dissipation.map(finite);
    /// Fraction of the sampled time the masses moved together.
    stick_fraction: [Option<f64>; 1] = |c| [finite(c.stick_fraction)];
    /// Periods until the motion was on its attractor: for a chaotic cell the length of its look (docs/classes.md), for an escaped one (rule 8) the periods before the copies of its motion plus their mean lifetime, otherwise the periods before the window that showed the attractor (an upper bound); 0 for inferred cells.
    settle: [u32; 1] = |c| [c.settle];
    /// The standard error of the settle time where it is an estimate: of a cell whose chaotic-looking motion was a transient (rule 8, escaped), the settle time is the periods run before the copies of its motion started plus their mean lifetime, this its standard error; NaN elsewhere.
    settle_se: [Option<f64>; 1] = |_c| [None];
    /// The period of a stable cycle carried from a neighbouring cell that exists at this cell's parameters beside the attractor its trajectory reached (0: none found).
    coexist: [i32; 1] = |c| [c.coexist.map_or(0, |k| k.period as i32)];
    /// The state (y1..y4) at the end of the cell's run, on its attractor: the start of a boundary's Newton continuation (`--boundaries`); NaN for inferred cells.
    state: [Option<f64>; 4] = |c| c.final_y.map(finite);
    /// The motion's mode at the end of the run (0 slip with v > 0, 1 slip with v < 0, 2 stick, 3 and 4 locked at the stop z = +r, -r).
    mode: [u8; 1] = |c| [c.final_mode as u8];
    /// The long look after the cell looked chaotic or quasi-periodic: 0 none (it did not, or the look is off), 1 its first stage, to 3 x the configured periods (the cell and its four neighbours all looked chaotic), 2 all of it, up to `run.look` periods (a chaotic-looking cell beside another class, or a quasi-periodic-looking one); each left as soon as a window showed a confirmed cycle or impact-free motion.
    looked: [u8; 1] = |c| [c.looked.code()];
}

impl Fields {
    pub fn from_cells(cells: &[(Summary, u8)]) -> Fields {
        let s: Vec<Summary> = cells.iter().map(|c| c.0).collect();
        Fields {
            attractors: cells.iter().map(|c| c.1).collect(),
            ..Fields::from_summaries(&s)
        }
    }

    pub fn len(&self) -> usize {
        self.class.len()
    }

    pub fn is_empty(&self) -> bool {
        self.class.is_empty()
    }

    /// Cells per deciding rule, by the rule's name.
    pub fn rule_counts(&self) -> std::collections::BTreeMap<String, usize> {
        let mut m = std::collections::BTreeMap::new();
        for &r in &self.rule {
            let name = Rule::ALL
                .iter()
                .find(|x| x.code() == r)
                .map_or(format!("unknown rule {r}"), |x| x.name().to_string());
            *m.entry(name).or_default() += 1;
        }
        m
    }

    pub fn classes(&self) -> Vec<Class> {
        self.class.iter().map(|&c| Class::from_code(c)).collect()
    }

    /// Counts per class name.
    pub fn counts(&self) -> std::collections::BTreeMap<String, usize> {
        let mut m = std::collections::BTreeMap::new();
        for c in self.classes() {
            *m.entry(c.name()).or_default() += 1;
        }
        m
    }

    pub fn diagnostics(&self, i: usize) -> Diagnostics {
        Diagnostics {
            impacts: self.impacts[i],
            sticks: self.sticks[i],
            locks: self.locks[i],
            overflows: self.overflows[i],
            wrong_slips: self.wrong_slips[i],
            nonfinite: self.nonfinite[i] != 0,
            cpu_rerun: self.cpu_rerun[i] != 0,
            ..Diagnostics::default()
        }
    }
}
