//! One parameter point: its class, exponent, diagnostics and samples, as text or JSON.

use crate::classify::Class;
use crate::config::Config;
use crate::engine::Engine;
use crate::error::Result;
use crate::method::{Diagnostics, RunResult};
use crate::model::{Mode, Params};
use crate::progress::Progress;
use crate::spec::{Points, RunSpec};
use serde::Serialize;
use std::fmt;
use std::time::Instant;

/// What `rattle point` reports (the JSON keys of `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct PointReport {
    pub class: String,
    pub period: Option<u32>,
    pub impacts_per_period: f64,
    pub lyapunov: f64,
    pub diagnostics: Diagnostics,
    pub samples: Vec<[f64; 4]>,
    pub final_mode: Mode,
    pub params: Params<f64>,
    pub backend: &'static str,
    pub device: String,
    pub precision: &'static str,
    pub seconds: f64,
}

/// Integrates the configured point, with the Lyapunov estimate.
pub fn run(engine: &Engine, cfg: &Config, progress: &dyn Progress) -> Result<PointReport> {
    let spec = RunSpec::new(cfg).with_lyapunov();
    let t = Instant::now();
    let (mut rs, _) = engine.run(&spec, &Points::single(), progress)?;
    let r: RunResult = rs.pop().expect("one point, one result");
    let class: Class = r.class(cfg.run.period_tol);
    Ok(PointReport {
        class: class.name(),
        period: class.period(),
        impacts_per_period: r.impacts_per_period(),
        lyapunov: r.lyapunov,
        diagnostics: r.diag,
        final_mode: r.final_mode,
        params: spec.params,
        backend: engine.name(),
        device: engine.device(),
        precision: cfg.method.precision.name(),
        seconds: t.elapsed().as_secs_f64(),
        samples: r.samples,
    })
}

impl fmt::Display for PointReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d = &self.diagnostics;
        writeln!(f, "class              {}", self.class)?;
        writeln!(
            f,
            "period             {}",
            self.period.map_or("-".into(), |n| n.to_string())
        )?;
        writeln!(f, "impacts per period {:.4}", self.impacts_per_period)?;
        writeln!(f, "lyapunov exponent  {:.5} (per unit time)", self.lyapunov)?;
        writeln!(
            f,
            "diagnostics        impacts {} sticks {} locks {} overflows {} nonfinite {}",
            d.impacts, d.sticks, d.locks, d.overflows, d.nonfinite
        )?;
        writeln!(
            f,
            "backend            {} on {} ({}), {:.3} s",
            self.backend, self.device, self.precision, self.seconds
        )?;
        writeln!(f, "samples (phase 0 of the forcing):")?;
        writeln!(
            f,
            "{:>5} {:>14} {:>14} {:>14} {:>14}",
            "k", "y1", "y2", "y3", "y4"
        )?;
        for (i, s) in self.samples.iter().enumerate() {
            writeln!(
                f,
                "{i:>5} {:>14.8} {:>14.8} {:>14.8} {:>14.8}",
                s[0], s[1], s[2], s[3]
            )?;
        }
        Ok(())
    }
}
