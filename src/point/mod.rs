//! One parameter point: its class, exponent, diagnostics and samples, as text or JSON; and its
//! figure ([`plot`]).

mod caption;
pub mod laminar;
pub mod plot;

use crate::class::Class;
use crate::config::{Config, Tangent};
use crate::cycles::{Cycle, modulus, spectrum};
use crate::engine::Engine;
use crate::error::Result;
use crate::method::{Diagnostics, Integrator, PointState, Split};
use crate::model::{Mode, Params};
use crate::observables::{Distribution, Observables, impact_speeds};
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
    /// Impact speeds, dissipated energies and the stick fraction over the sampled periods
    /// (their keys at this level of the JSON).
    #[serde(flatten)]
    pub observables: Observables,
    /// The speed of every impact, in order, over `run.sample_periods` periods from the run's
    /// end (CPU, f64), and their distribution: how hard the parts hit, impact by impact.
    pub impact_speeds: Vec<f64>,
    pub impact_speed_distribution: Distribution,
    /// The largest Lyapunov exponent per unit time: of a confirmed stable cycle, the cycle's
    /// own (ln |mu_1| over its period, exact: `lyapunov_se` 0); otherwise the run's over its
    /// last sampled windows.
    pub lyapunov: f64,
    /// Standard error of `lyapunov` by batch means over the last sampled window (0 for a
    /// cycle's own).
    pub lyapunov_se: f64,
    /// The run's exponent and its standard error over its last sampled windows, whatever the
    /// class (of a cycle still approached, it holds the transient).
    pub run_lyapunov: [f64; 2],
    /// Agreeing digits of the torus test (weighted Birkhoff averages of y1 over the two
    /// halves of the last sampled window).
    pub torus_digits: f64,
    /// The rule that decided the class.
    pub rule: crate::classify::Rule,
    /// The periods Newton tried, in order.
    pub tried_periods: Vec<u32>,
    /// Forcing periods integrated (more than configured where the point was undecided, or
    /// looked chaotic and got the long look, docs/classes.md).
    pub periods: u32,
    /// Periods until the motion was on its attractor: for a chaotic point the length of its
    /// look (chaos is known to last that long, no longer); otherwise the periods before the
    /// window that showed the attractor (an upper bound).
    pub settle: u32,
    /// Where the motion still looked chaotic after the look and copies of it landed on a
    /// stable cycle (rule `escaped`): the standard error of `settle`, the copies' mean
    /// lifetime's. Null elsewhere.
    pub settle_se: Option<f64>,
    /// The long look asked for (`run.look`; 0: none, the configured run decides).
    pub look: u32,
    /// All four Lyapunov exponents per unit time (tangent dynamics, CPU f64, over the sampled
    /// periods from the final state), largest first; a stick or lock removes directions
    /// exactly, and the exponents of removed directions then only say "very negative".
    pub lyapunov_spectrum: Option<Vec<f64>>,
    /// Floquet multipliers of the confirmed cycle ([re, im], modulus descending); null without
    /// one. An unstable cycle that Newton found (round-off or transient) is not confirmed: its
    /// multipliers are in `cycle` only.
    pub multipliers: Option<Vec<[f64; 2]>>,
    /// The refined cycle (section point, mode, residual); null where none was tried.
    pub cycle: Option<Cycle>,
    pub diagnostics: Diagnostics,
    pub samples: Vec<[f64; 4]>,
    pub final_mode: Mode,
    pub params: Params<f64>,
    pub backend: &'static str,
    pub device: String,
    pub precision: &'static str,
    /// The wall time of the computation (`timings.wall_s`).
    pub seconds: f64,
    /// Where it went: the run and its deciding; host_s includes the CPU f64 runs of the
    /// impact speeds and the spectrum.
    pub timings: Split,
}

/// Integrates the configured point, with the exponents `run.tangent` asks for (default: the
/// spectrum).
pub fn run(engine: &Engine, cfg: &Config, progress: &dyn Progress) -> Result<PointReport> {
    let tangent = cfg.tangent(Tangent::Spectrum);
    let spec = RunSpec::new(cfg).with_tangent(tangent);
    let t = Instant::now();
    // The configured run, then the adaptive horizon where it is undecided, as a map cell.
    // A single point's neighbours are unknown: a chaotic-looking point gets the whole look.
    let nb = crate::carry::Neighbours::none(1);
    let a = crate::adaptive::run_samples(
        engine,
        &spec,
        &Points::single(),
        (false, crate::adaptive::look::Copies::Every),
        &nb,
        progress,
    )?;
    let (r, verdict) = (a.results[0].clone(), a.verdicts[0].clone());
    let t_host = Instant::now();
    let class: Class = verdict.class;
    // The CPU f64 runs from the run's end: every impact's speed, and the spectrum.
    let it = Integrator::<f64>::new(&spec.params, &spec.settings);
    let end = PointState {
        y: r.final_y,
        mode: r.final_mode,
        diag: Default::default(),
    };
    let speeds = if r.diag.nonfinite {
        Vec::new()
    } else {
        impact_speeds(&it, &end, spec.samples)
    };
    let lyapunov_spectrum = if tangent != Tangent::Spectrum {
        None
    } else if r.diag.nonfinite {
        Some(vec![f64::NAN; 4])
    } else {
        Some(spectrum(&it, &mut end.clone(), spec.samples, 4).exponents)
    };
    // A confirmed cycle's exponent is its own: ln |mu_1| per unit time over its period (none
    // where `run.tangent = "none"` asks for no exponent).
    let own = verdict
        .cycle
        .as_ref()
        .filter(|c| class.period().is_some() && c.is_stable() && tangent != Tangent::None)
        .map(|c| crate::cycles::exponent(c.leading_modulus(), c.period, spec.params.eta));
    let wall_s = t.elapsed().as_secs_f64();
    let timings = Split::of(&a.timings, t_host.elapsed().as_secs_f64(), wall_s);
    Ok(PointReport {
        class: class.name(),
        period: class.period(),
        impacts_per_period: r.impacts_per_period(),
        observables: crate::observables::Observables::of_run(&r),
        impact_speed_distribution: Distribution::of(
            "impact_speed",
            speeds.iter().map(|&v| Some(v)),
        ),
        impact_speeds: speeds,
        lyapunov: own.map_or(r.lyapunov.value, |e| e),
        lyapunov_se: own.map_or(r.lyapunov.se, |_| 0.0),
        run_lyapunov: [r.lyapunov.value, r.lyapunov.se],
        torus_digits: r.torus,
        rule: verdict.rule,
        tried_periods: verdict.tried.clone(),
        periods: a.periods[0],
        settle: a.settle[0],
        settle_se: a.settle_se[0],
        look: cfg.run.look,
        lyapunov_spectrum,
        multipliers: verdict
            .cycle
            .as_ref()
            .filter(|c| c.is_stable())
            .map(|c| c.multipliers.clone()),
        cycle: verdict.cycle,
        diagnostics: r.diag,
        final_mode: r.final_mode,
        params: spec.params,
        backend: engine.name(),
        device: engine.device(),
        precision: cfg.method.precision.name(),
        seconds: wall_s,
        timings,
        samples: r.samples,
    })
}

impl fmt::Display for PointReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "class              {}", self.class)?;
        writeln!(
            f,
            "period             {}",
            self.period.map_or("-".into(), |n| n.to_string())
        )?;
        writeln!(f, "impacts per period {:.4}", self.impacts_per_period)?;
        self.fmt_observables(f)?;
        self.fmt_evidence(f)?;
        self.fmt_exponents_and_cycle(f)?;
        let d = &self.diagnostics;
        writeln!(
            f,
            "diagnostics        impacts {} sticks {} locks {} overflows {} wrong slips {} nonfinite {}",
            d.impacts, d.sticks, d.locks, d.overflows, d.wrong_slips, d.nonfinite
        )?;
        writeln!(
            f,
            "backend            {} on {} ({}), {}",
            self.backend,
            self.device,
            self.precision,
            self.timings.line()
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

impl PointReport {
    /// The impact speeds, dissipation and stick fraction lines.
    fn fmt_observables(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let o = &self.observables;
        if let (Some(m), Some(x)) = (o.impact_speed_mean, o.impact_speed_max) {
            writeln!(f, "impact speed       mean {m:.6}, max {x:.6}")?;
        }
        let sd = &self.impact_speed_distribution;
        if sd.defined > 0 {
            writeln!(
                f,
                "impact speeds      5% {:.6}, median {:.6}, 95% {:.6} ({} impacts, CPU f64, \
             from the end)",
                sd.p05, sd.median, sd.p95, sd.defined
            )?;
        }
        if let (Some(i), Some(r), Some(s)) = (
            o.dissipation_impacts,
            o.dissipation_friction,
            o.stick_fraction,
        ) {
            writeln!(
                f,
                "dissipated/period  impacts {i:.6}, friction {r:.6} (energy, units of the state)"
            )?;
            writeln!(f, "stick fraction     {s:.6} (of the sampled time)")?;
        }
        Ok(())
    }

    /// The exponent, torus test and deciding rule lines: the evidence of the class.
    fn fmt_evidence(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.lyapunov.is_nan() && self.rule == crate::classify::Rule::ExponentLost {
            writeln!(
                f,
                "lyapunov exponent  - (lost: the tangent vector overflowed; use f64)"
            )?;
        } else if self.lyapunov.is_nan() {
            writeln!(
                f,
                "lyapunov exponent  - (none: run.tangent = \"none\", or a failed run)"
            )?;
        } else if self.multipliers.is_some() && self.lyapunov_se == 0.0 {
            writeln!(
                f,
                "lyapunov exponent  {:.5} (the cycle's: ln|mu_1| over its period; the run's \
                 last window {:.5} +- {:.5})",
                self.lyapunov, self.run_lyapunov[0], self.run_lyapunov[1]
            )?;
        } else {
            writeln!(
                f,
                "lyapunov exponent  {:.5} +- {:.5} (per unit time, standard error)",
                self.lyapunov, self.lyapunov_se
            )?;
        }
        if self.torus_digits.is_nan() {
            writeln!(f, "torus test         - (no two halves of the window)")?;
        } else {
            writeln!(f, "torus test         {:.1} digits", self.torus_digits)?;
        }
        writeln!(
            f,
            "decided by         {} after {} periods (Newton tried {:?})",
            self.rule.name(),
            self.periods,
            self.tried_periods
        )?;
        if self.class == "chaotic" && self.look == 0 {
            writeln!(
                f,
                "settled            still chaotic after {} periods (no long look: run.look = 0)",
                self.settle
            )?;
        } else if self.class == "chaotic" {
            writeln!(
                f,
                "settled            still chaotic after a look of {} periods",
                self.settle
            )?;
        } else if let Some(se) = self.settle_se {
            writeln!(
                f,
                "settled            on its attractor after {} +- {se:.0} periods (a \
                 transient: the {} periods run, then the mean lifetime of {} copies of it)",
                self.settle,
                self.periods,
                crate::escape::COPIES
            )?;
        } else {
            writeln!(
                f,
                "settled            on its attractor within {} periods",
                self.settle
            )?;
        }
        Ok(())
    }

    /// The spectrum, the refined cycle and its multipliers.
    fn fmt_exponents_and_cycle(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(s) = &self.lyapunov_spectrum {
            let spec: Vec<String> = s.iter().map(|l| format!("{l:.5}")).collect();
            writeln!(
                f,
                "lyapunov spectrum  {} (tangent dynamics)",
                spec.join(" ")
            )?;
        }
        if let Some(c) = &self.cycle {
            let m: Vec<String> = c
                .multipliers
                .iter()
                .map(|z| format!("{:.6}{:+.6}i (|{:.6}|)", z[0], z[1], modulus(z)))
                .collect();
            writeln!(
                f,
                "cycle              period {} {} (Newton: {} iterations, residual {:.1e})",
                c.period,
                match (c.converged, c.is_stable()) {
                    (true, true) => "stable",
                    (true, false) => "unstable",
                    _ => "not converged",
                },
                c.iterations,
                c.residual
            )?;
            if !m.is_empty() {
                writeln!(f, "multipliers        {}", m.join(", "))?;
            }
        }
        Ok(())
    }
}
