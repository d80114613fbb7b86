//! The uncertain parameters of a study: how each is distributed (normal, truncated at its
//! physical bounds, or uniform), parsed from `--uncertain`, and the draws of the design.

use crate::error::{OptionError, Result};
use crate::model::Param;
use serde::Serialize;
use statrs::distribution::{ContinuousCDF, Normal};

/// How an uncertain parameter is distributed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "distribution", rename_all = "lowercase")]
pub enum Dist {
    /// Normal with this mean and standard deviation, truncated at the parameter's bounds.
    Normal { mean: f64, sd: f64 },
    /// Uniform between `lo` and `hi`.
    Uniform { lo: f64, hi: f64 },
}

/// One uncertain parameter.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Uncertain {
    pub param: Param,
    #[serde(flatten)]
    pub dist: Dist,
}

/// The physical bounds of a parameter (where the truncated normal is cut).
pub(super) fn bounds(p: Param) -> (f64, f64) {
    match p {
        Param::Restitution => (0.0, 1.0),
        _ => (0.0, f64::INFINITY),
    }
}

impl Uncertain {
    /// Parses `R=0.60+-0.02` (normal: mean and standard deviation) or `R=0.58..0.62` (uniform).
    pub fn parse(s: &str) -> Result<Uncertain> {
        let bad = |why: &str| OptionError::Range {
            option: "uncertain",
            value: s.to_string(),
            allowed: format!(
                "NAME=MEAN+-SD (normal) or NAME=LO..HI (uniform) with NAME a model parameter; \
                 {why}"
            ),
        };
        let (name, rest) = s.split_once('=').ok_or_else(|| bad("no `=`"))?;
        let param: Param = name.trim().parse().map_err(|_| bad("unknown parameter"))?;
        let num = |t: &str| t.trim().parse::<f64>().map_err(|_| bad("not a number"));
        let dist = if let Some((m, sd)) = rest.split_once("+-") {
            Dist::Normal {
                mean: num(m)?,
                sd: num(sd)?,
            }
        } else if let Some((lo, hi)) = rest.split_once("..") {
            Dist::Uniform {
                lo: num(lo)?,
                hi: num(hi)?,
            }
        } else {
            return Err(bad("neither `+-` nor `..`").into());
        };
        let (lo, hi) = bounds(param);
        let ok = match dist {
            Dist::Normal { mean, sd } => {
                mean.is_finite() && sd.is_finite() && sd > 0.0 && mean >= lo && mean <= hi
            }
            Dist::Uniform { lo: a, hi: b } => {
                a.is_finite() && b.is_finite() && a < b && a >= lo && b <= hi
            }
        };
        if !ok {
            return Err(bad(&format!(
                "finite, SD > 0 or LO < HI, inside the parameter's bounds [{lo}, {hi}]"
            ))
            .into());
        }
        Ok(Uncertain { param, dist })
    }

    /// The nominal value (mean, or the middle of the uniform range).
    pub fn nominal(&self) -> f64 {
        match self.dist {
            Dist::Normal { mean, .. } => mean,
            Dist::Uniform { lo, hi } => 0.5 * (lo + hi),
        }
    }

    /// The values the draws span: the nominal and the extremes (6 standard deviations either
    /// side, which no draw of 65536 passes, cut at the parameter's bounds; or the range).
    pub fn span(&self) -> [f64; 3] {
        let (lo, hi) = bounds(self.param);
        match self.dist {
            Dist::Normal { mean, sd } => {
                [mean, (mean - 6.0 * sd).max(lo), (mean + 6.0 * sd).min(hi)]
            }
            Dist::Uniform { lo, hi } => [0.5 * (lo + hi), lo, hi],
        }
    }

    /// The scale distances are reported in: the standard deviation, or half the range.
    pub fn scale(&self) -> f64 {
        match self.dist {
            Dist::Normal { sd, .. } => sd,
            Dist::Uniform { lo, hi } => 0.5 * (hi - lo),
        }
    }

    /// The value at quantile `u` in (0, 1).
    pub fn quantile(&self, u: f64) -> f64 {
        match self.dist {
            Dist::Uniform { lo, hi } => lo + u * (hi - lo),
            Dist::Normal { mean, sd } => {
                let n = Normal::standard();
                let (lo, hi) = bounds(self.param);
                let (a, b) = (n.cdf((lo - mean) / sd), n.cdf((hi - mean) / sd));
                let q = (a + u * (b - a)).clamp(1e-15, 1.0 - 1e-15);
                (mean + sd * n.inverse_cdf(q)).clamp(lo, hi)
            }
        }
    }
}

/// The values of one draw: quantiles of the Sobol point `row` in dimensions `dims..dims + d`
/// (A: 0, B: d).
pub fn draw(u: &[Uncertain], row: usize, dims: usize, seed: u32) -> Vec<f64> {
    u.iter()
        .enumerate()
        .map(|(j, x)| {
            // Half a unit of the last bit keeps the quantile off 0 and 1.
            let v = f64::from(sobol_burley::sample(row as u32, (dims + j) as u32, seed));
            x.quantile((v + 0.5 / 16_777_216.0).min(1.0 - 1e-9))
        })
        .collect()
}
