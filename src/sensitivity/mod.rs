//! `rattle sensitivity`: how the motion at a measured point depends on parameters known only
//! within their measurement error. The uncertain parameters (normal, truncated at their physical
//! bounds, or uniform) are sampled by an Owen-scrambled Sobol sequence in a Saltelli design
//! (matrices A, B and A with one column from B per parameter), integrated as one ensemble on
//! the chosen engine and decided by the same adaptive loop and classifier as a map. From it:
//! the class probabilities with Wilson intervals and their convergence as the sample grows, the
//! probability of the nominal point's class, first-order and total Sobol indices of the largest
//! exponent and of "same class as nominal" with bootstrap intervals, and per parameter the
//! distance from the nominal to the nearest class change (a scan out to 4 standard deviations,
//! then four rounds of cutting its bracket into eight, 2^-12 of a scan step).

mod output;
mod uncertain;
use crate::stats;

use uncertain::bounds;
pub use uncertain::{Dist, Uncertain, draw};

pub use output::{caption, write_outputs};

use crate::class::Class;
use crate::config::{Config, Tangent};
use crate::decide::Summary;
use crate::engine::{Engine, Timings};
use crate::error::{OptionError, Result};
use crate::method::Split;
use crate::model::Param;
use crate::observables::{Distribution, Observables};
use crate::progress::Progress;
use crate::spec::{Points, RunSpec};
use serde::Serialize;
use std::collections::BTreeMap;

/// Most uncertain parameters: the kernel varies at most this many per point.
pub const MAX_UNCERTAIN: usize = crate::spec::MAX_VARY;
/// Steps of the scan for the nearest class change, per side, out to [`SCAN_SIGMAS`].
pub const SCAN_STEPS: usize = 32;
/// How far the scan looks, in standard deviations (uniform: half-widths).
pub const SCAN_SIGMAS: f64 = 4.0;
/// The interval where the scan saw the class change is cut into this many parts per round, all
/// of its inner points in one ensemble (fewer, larger runs than a bisection's one point each:
/// a run's stages cost latency, whatever its size).
pub const SECTIONS: usize = 8;
/// Rounds of that sectioning: the bracket ends at SECTIONS^-ROUNDS = 2^-12 of a scan step.
pub const ROUNDS: u32 = 4;
/// The draws per matrix a study may take.
const SAMPLES_ALLOWED: &str = "16 to 65536 (the Sobol sequence's length)";

/// Bootstrap resamples of the Sobol indices.
pub const RESAMPLES: usize = 200;

/// Options of a study.
#[derive(Clone, Debug)]
pub struct Options {
    pub uncertain: Vec<Uncertain>,
    /// Rows of each of the matrices A and B (base sample size N; the study runs N (d + 2)
    /// points plus the scan).
    pub samples: usize,
    pub seed: u32,
}

impl Options {
    /// The options of `cfg`'s `[sensitivity]` section, with `uncertain`, `samples` and `seed`
    /// given instead where they are, checked as the command checks them (the options, the
    /// config's tangent, the draws' values and the memory) before anything runs.
    pub fn from_config(
        cfg: &Config,
        uncertain: Option<&[String]>,
        samples: Option<i64>,
        seed: Option<i64>,
    ) -> Result<Options> {
        let s = &cfg.sensitivity;
        // Any integer a caller gives (negative, beyond 32 bits) is named by its option.
        let samples = match samples {
            None => s.samples as usize,
            Some(v) => usize::try_from(v).map_err(|_| OptionError::Range {
                option: "samples",
                value: v.to_string(),
                allowed: SAMPLES_ALLOWED.into(),
            })?,
        };
        let seed = match seed {
            None => s.seed,
            Some(v) => u32::try_from(v).map_err(|_| OptionError::Range {
                option: "seed",
                value: v.to_string(),
                allowed: format!("0 to {}", u32::MAX),
            })?,
        };
        let o = Options {
            uncertain: uncertain
                .unwrap_or(&s.uncertain)
                .iter()
                .map(|u| Uncertain::parse(u))
                .collect::<std::result::Result<_, _>>()?,
            samples,
            seed,
        };
        o.check()?;
        cfg.check_tangent("`sensitivity`")?;
        o.check_values(cfg)?;
        check_memory(&o)?;
        Ok(o)
    }

    /// Refuses what cannot run, before anything is computed.
    /// Refuses uncertain parameters whose nominal value or draws `cfg` would not accept as
    /// its own values ([`Config::check_value`]), before anything runs.
    pub fn check_values(&self, cfg: &Config) -> Result<()> {
        for u in &self.uncertain {
            for v in u.span() {
                if let Err(crate::config::ConfigError::Range { key, value, range }) =
                    cfg.check_value(u.param.name(), u.param, v)
                {
                    return Err(OptionError::Range {
                        option: "uncertain",
                        value: format!("{} (its draws reach `{key}` = {value})", u.param.name()),
                        allowed: format!("draws a config accepts: {range}"),
                    }
                    .into());
                }
            }
        }
        Ok(())
    }

    pub fn check(&self) -> Result<()> {
        let d = self.uncertain.len();
        if !(1..=MAX_UNCERTAIN).contains(&d) {
            return Err(OptionError::Range {
                option: "uncertain",
                value: format!("{d} parameters"),
                allowed: format!("1 to {MAX_UNCERTAIN}"),
            }
            .into());
        }
        for (i, u) in self.uncertain.iter().enumerate() {
            if self.uncertain[..i]
                .iter()
                .any(|v| v.param.overlaps(u.param))
            {
                return Err(OptionError::Range {
                    option: "uncertain",
                    value: u.param.name().into(),
                    allowed: "each parameter once (lambda sets fs and fk)".into(),
                }
                .into());
            }
        }
        if !(16..=65536).contains(&self.samples) {
            return Err(OptionError::Range {
                option: "samples",
                value: self.samples.to_string(),
                allowed: SAMPLES_ALLOWED.into(),
            }
            .into());
        }
        Ok(())
    }
}

/// One sampled point and what it is.
#[derive(Clone, Debug, Serialize)]
pub struct Sample {
    /// `A`, `B`, or `AB<j>` (A with parameter j from B).
    pub set: String,
    pub row: usize,
    pub values: Vec<f64>,
    pub class: Class,
    pub lyapunov: f64,
    pub lyapunov_se: f64,
    pub impacts_per_period: f64,
    /// Impact speeds, dissipated energies and the stick fraction over the sampled periods.
    pub observables: Observables,
    pub same_as_nominal: bool,
}

/// A probability with its 95% Wilson interval.
#[derive(Clone, Debug, Serialize)]
pub struct Probability {
    pub name: String,
    pub count: usize,
    pub of: usize,
    pub p: f64,
    pub low: f64,
    pub high: f64,
}

impl Probability {
    fn new(name: impl Into<String>, count: usize, of: usize) -> Probability {
        let (p, low, high) = stats::wilson(count, of);
        Probability {
            name: name.into(),
            count,
            of,
            p,
            low,
            high,
        }
    }
}

/// Where the class first changes on one side of the nominal along one parameter.
#[derive(Clone, Debug, Serialize)]
pub struct Change {
    /// Signed distance from the nominal in the parameter's units.
    pub distance: f64,
    /// The same in standard deviations (uniform: half-widths).
    pub scales: f64,
    /// The class beyond the change.
    pub beyond: Class,
    /// Width of the bracket left by the sectioning, in the parameter's units.
    pub bracket: f64,
}

/// The nearest class change along one parameter.
#[derive(Clone, Debug, Serialize)]
pub struct Distance {
    pub param: Param,
    pub below: Option<Change>,
    pub above: Option<Change>,
    /// How far the scan looked on each side, in scales.
    pub searched_scales: f64,
}

/// Sobol indices of one parameter with bootstrap intervals.
#[derive(Clone, Debug, Serialize)]
pub struct Sobol {
    pub param: Param,
    pub exponent: stats::Indices,
    /// [first low, first high, total low, total high].
    pub exponent_interval: [f64; 4],
    /// Of the indicator "same class as nominal"; null where fewer than [`MIN_CHANGES`] draws
    /// of A and B left the nominal class (the estimators then apportion a handful of events:
    /// one changed draw in 8192 gave total indices of 1 and 2).
    pub same_class: Option<stats::Indices>,
    pub same_class_interval: Option<[f64; 4]>,
}

/// Draws of A and B of another class than the nominal's that the indices of the class need;
/// where every draw keeps the class, no parameter matters and the indices are 0.
pub const MIN_CHANGES: usize = 25;

/// Cells per side of the class map of the two most influential parameters.
pub const PLANE_CELLS: usize = 48;

/// The class map of the plane of the two most influential parameters (the others at their
/// nominal values), over nominal +- 3 scales (uniform: the range).
#[derive(Clone, Debug, Serialize)]
pub struct PlaneMap {
    /// Indices into the uncertain parameters of the x and y axes.
    pub x: usize,
    pub y: usize,
    pub x_range: (f64, f64),
    pub y_range: (f64, f64),
    pub cells: usize,
    /// Row-major, y outer, first row at y_range.0; cell centres.
    pub classes: Vec<Class>,
}

/// A finished study.
#[derive(Clone, Debug, Serialize)]
pub struct Study {
    pub uncertain: Vec<Uncertain>,
    pub samples: usize,
    pub seed: u32,
    /// Points integrated in all (design, nominal, scan and bisection).
    pub runs: usize,
    pub nominal: Class,
    pub nominal_lyapunov: f64,
    /// The nominal point's impact speeds, dissipated energies and stick fraction.
    pub nominal_observables: Observables,
    /// Their distributions over the 2N independent draws (A and B).
    pub observables: Vec<Distribution>,
    /// Probability of each class over the 2N independent draws (A and B).
    pub classes: Vec<Probability>,
    /// Probability that the motion is of the nominal point's class.
    pub same_as_nominal: Probability,
    /// `same_as_nominal` over the first 2n draws, n = 16, 32, ... N.
    pub convergence: Vec<Probability>,
    pub distances: Vec<Distance>,
    /// Rows of the design with a finite exponent in A, B and every AB (the exponent's indices
    /// use these).
    pub exponent_rows: usize,
    pub sobol: Vec<Sobol>,
    #[serde(skip)]
    pub draws: Vec<Sample>,
    pub plane: Option<PlaneMap>,
    /// In the JSON with the files' seconds (`output::write_outputs`).
    #[serde(skip)]
    pub timings: Split,
    /// Uncertain parameters the model does not read ([`Config::without_effect`]).
    pub warnings: Vec<String>,
}

/// The range a plane axis spans for parameter `x`.
fn plane_range(x: &Uncertain) -> (f64, f64) {
    let (lo, hi) = bounds(x.param);
    match x.dist {
        Dist::Uniform { lo, hi } => (lo, hi),
        Dist::Normal { mean, sd } => ((mean - 3.0 * sd).max(lo), (mean + 3.0 * sd).min(hi)),
    }
}

/// Points (parameter values, row-major) classified in one ensemble.
fn decide_points(
    engine: &Engine,
    cfg: &Config,
    vary: &[Param],
    values: &[f64],
    progress: &dyn Progress,
) -> Result<(Vec<Summary>, Timings)> {
    let spec = RunSpec::new(cfg).with_tangent(cfg.tangent(Tangent::Largest));
    let points = Points::along(vary, values);
    Ok(crate::adaptive::run_summaries(
        engine,
        &spec,
        &points,
        cfg.run.early_stop,
        (&crate::carry::Neighbours::none(points.len()), points.len()),
        progress,
    )?)
}

/// Points a study integrates, for progress and memory: the design and the scan.
pub fn points(o: &Options) -> usize {
    let (per_sample, fixed) = points_per_sample(o);
    o.samples * per_sample + fixed
}

/// Points of the design per sample (the rows of A, B and each AB_j), and those that do not
/// depend on the samples (the nominal point, the scan and its sectioning, the plane).
fn points_per_sample(o: &Options) -> (usize, usize) {
    let d = o.uncertain.len();
    let plane = if d >= 2 { PLANE_CELLS * PLANE_CELLS } else { 0 };
    (
        d + 2,
        1 + 2 * d * SCAN_STEPS + 2 * d * (SECTIONS - 1) * ROUNDS as usize + plane,
    )
}

/// Refuses a study whose results would not fit in memory, advising the samples that fit.
pub fn check_memory(o: &Options) -> Result<()> {
    let (per_sample, fixed) = points_per_sample(o);
    crate::memory::check_option_scaled(
        "samples",
        o.samples as u64,
        per_sample as u64,
        fixed as u64,
        1,
    )
}

/// Runs the study at the configuration's nominal point.
pub fn run(engine: &Engine, cfg: &Config, o: &Options, progress: &dyn Progress) -> Result<Study> {
    o.check()?;
    let t0 = std::time::Instant::now();
    let u = &o.uncertain;
    let d = u.len();
    let n = o.samples;
    let vary: Vec<Param> = u.iter().map(|x| x.param).collect();
    let nominal: Vec<f64> = u.iter().map(Uncertain::nominal).collect();
    // A parameter the model does not read would get an index of 0 as if it did not matter.
    let warnings = cfg.without_effect(&vary);
    for w in &warnings {
        log::warn!("{w}");
    }
    let (values, sets) = saltelli_design(u, n, o.seed);
    let (sum, mut timings) = decide_points(engine, cfg, &vary, &values, progress)?;
    let nominal_class = sum[0].class;
    let draws: Vec<Sample> = sets
        .iter()
        .zip(&sum)
        .enumerate()
        .skip(1)
        .map(|(k, ((set, row), s))| Sample {
            set: set.clone(),
            row: *row,
            values: values[k * d..(k + 1) * d].to_vec(),
            class: s.class,
            lyapunov: s.lyapunov.value,
            lyapunov_se: s.lyapunov.se,
            impacts_per_period: s.impacts_per_period,
            observables: s.observables(),
            same_as_nominal: s.class == nominal_class,
        })
        .collect();

    // Class probabilities and the observables' distributions over the 2N draws of A and B.
    let ab_draws = &draws[..2 * n];
    let observables = Observables::NAMES
        .iter()
        .enumerate()
        .map(|(k, name)| Distribution::of(name, ab_draws.iter().map(|s| s.observables.values()[k])))
        .collect();
    let mut counts = BTreeMap::<String, usize>::new();
    for s in ab_draws {
        *counts.entry(s.class.name()).or_default() += 1;
    }
    let mut classes: Vec<Probability> = counts
        .into_iter()
        .map(|(c, k)| Probability::new(c, k, 2 * n))
        .collect();
    classes.sort_by(|x, y| y.count.cmp(&x.count).then(x.name.cmp(&y.name)));
    let same = |m: usize| {
        // The first m rows of A and of B.
        let k = (0..m).filter(|&i| draws[i].same_as_nominal).count()
            + (0..m).filter(|&i| draws[n + i].same_as_nominal).count();
        Probability::new("same class as nominal", k, 2 * m)
    };
    let same_as_nominal = same(n);
    let mut convergence = Vec::new();
    let mut m = 16;
    while m < n {
        convergence.push(same(m));
        m *= 2;
    }
    convergence.push(same(n));

    let changes = 2 * n - same_as_nominal.count;
    let (sobol, exponent_rows) = sobol_indices(&draws, &vary, n, changes, o.seed);

    // The nearest class change along each parameter: a scan, then sectioning of its bracket.
    let (distances, t, scan_runs) = nearest_changes(engine, cfg, u, nominal_class, progress)?;
    timings.add(&t);
    let mut runs = values.len() / d + scan_runs;
    let plane = if d >= 2 {
        let (p, t) = plane_map(engine, cfg, u, &nominal, &sobol, changes, progress)?;
        timings.add(&t);
        runs += PLANE_CELLS * PLANE_CELLS;
        Some(p)
    } else {
        None
    };
    // The host's seconds: everything but the engine's runs and Newton on the device (the
    // design, the indices and the sectioning besides the adaptive runs' deciding).
    let wall_s = t0.elapsed().as_secs_f64();
    let own = wall_s - timings.integration_s - timings.decide_s - timings.host_s;
    let timings = Split::of(&timings, own.max(0.0), wall_s);
    Ok(Study {
        uncertain: u.clone(),
        samples: n,
        seed: o.seed,
        runs,
        nominal: nominal_class,
        nominal_lyapunov: sum[0].lyapunov.value,
        nominal_observables: sum[0].observables(),
        observables,
        classes,
        same_as_nominal,
        convergence,
        distances,
        exponent_rows,
        sobol,
        draws,
        plane,
        timings,
        warnings,
    })
}

/// The Saltelli design: the nominal point, then the rows of A, B and each AB_j (A with column
/// j from B), `n` rows each; the values row-major, and each row's (set, row).
fn saltelli_design(u: &[Uncertain], n: usize, seed: u32) -> (Vec<f64>, Vec<(String, usize)>) {
    let d = u.len();
    let a: Vec<Vec<f64>> = (0..n).map(|i| draw(u, i, 0, seed)).collect();
    let b: Vec<Vec<f64>> = (0..n).map(|i| draw(u, i, d, seed)).collect();
    let mut values: Vec<f64> = u.iter().map(Uncertain::nominal).collect();
    let mut sets: Vec<(String, usize)> = vec![("nominal".into(), 0)];
    for (name, m) in [("A", &a), ("B", &b)] {
        for (i, row) in m.iter().enumerate() {
            values.extend(row);
            sets.push((name.into(), i));
        }
    }
    for j in 0..d {
        for i in 0..n {
            let mut row = a[i].clone();
            row[j] = b[i][j];
            values.extend(&row);
            sets.push((format!("AB{j}"), i));
        }
    }
    (values, sets)
}

/// Sobol indices per parameter of the exponent (over the rows finite in A, B and every AB, whose
/// number is returned too) and of "same class as nominal" (where `changes`, the draws of A and
/// B of another class, are none or enough to apportion).
fn sobol_indices(
    draws: &[Sample],
    vary: &[Param],
    n: usize,
    changes: usize,
    seed: u32,
) -> (Vec<Sobol>, usize) {
    let d = vary.len();
    let pick = |set: usize, f: &dyn Fn(&Sample) -> f64| -> Vec<f64> {
        draws[set * n..(set + 1) * n].iter().map(f).collect()
    };
    let lyap = |s: &Sample| s.lyapunov;
    let ind = |s: &Sample| f64::from(u8::from(s.same_as_nominal));
    let (fa, fb) = (pick(0, &lyap), pick(1, &lyap));
    let fab: Vec<Vec<f64>> = (0..d).map(|j| pick(2 + j, &lyap)).collect();
    let rows: Vec<usize> = (0..n)
        .filter(|&i| fa[i].is_finite() && fb[i].is_finite() && fab.iter().all(|f| f[i].is_finite()))
        .collect();
    let keep = |v: &[f64]| rows.iter().map(|&i| v[i]).collect::<Vec<f64>>();
    let (ga, gb) = (pick(0, &ind), pick(1, &ind));
    let apportion = changes == 0 || changes >= MIN_CHANGES;
    let sobol = (0..d)
        .map(|j| {
            let (ea, eb, eab) = (keep(&fa), keep(&fb), keep(&fab[j]));
            let all: Vec<usize> = (0..ea.len()).collect();
            let gab = pick(2 + j, &ind);
            let every: Vec<usize> = (0..n).collect();
            Sobol {
                param: vary[j],
                exponent: stats::indices(&ea, &eb, &eab, &all),
                exponent_interval: stats::bootstrap(&ea, &eb, &eab, RESAMPLES, u64::from(seed)),
                same_class: apportion.then(|| stats::indices(&ga, &gb, &gab, &every)),
                same_class_interval: apportion
                    .then(|| stats::bootstrap(&ga, &gb, &gab, RESAMPLES, u64::from(seed))),
            }
        })
        .collect();
    (sobol, rows.len())
}

/// The class map of the plane of the two parameters with the largest total index of "same
/// class as nominal" (first the one with the larger; of the exponent where the class indices
/// are 0 or not estimated), the others at their nominal values.
fn plane_map(
    engine: &Engine,
    cfg: &Config,
    u: &[Uncertain],
    nominal: &[f64],
    sobol: &[Sobol],
    changes: usize,
    progress: &dyn Progress,
) -> Result<(PlaneMap, Timings)> {
    let d = u.len();
    let vary: Vec<Param> = u.iter().map(|x| x.param).collect();
    let mut order: Vec<usize> = (0..d).collect();
    order.sort_by(|&i, &j| {
        let t = |k: usize| {
            let s: &Sobol = &sobol[k];
            match s.same_class {
                Some(c) if changes > 0 => c.total,
                _ => s.exponent.total,
            }
        };
        t(j).total_cmp(&t(i)).then(i.cmp(&j))
    });
    let (x, y) = (order[0], order[1]);
    let (xr, yr) = (plane_range(&u[x]), plane_range(&u[y]));
    let c = PLANE_CELLS;
    let mut values = Vec::with_capacity(c * c * d);
    for iy in 0..c {
        for ix in 0..c {
            let mut r = nominal.to_vec();
            r[x] = xr.0 + (xr.1 - xr.0) * (ix as f64 + 0.5) / c as f64;
            r[y] = yr.0 + (yr.1 - yr.0) * (iy as f64 + 0.5) / c as f64;
            values.extend(r);
        }
    }
    let (s, t) = decide_points(engine, cfg, &vary, &values, progress)?;
    let plane = PlaneMap {
        x,
        y,
        x_range: xr,
        y_range: yr,
        cells: c,
        classes: s.iter().map(|x| x.class).collect(),
    };
    Ok((plane, t))
}

/// The scan and sectioning of [`run`]: points along each parameter from the nominal (the other
/// parameters at their nominal values), both sides at once, as one ensemble per stage.
fn nearest_changes(
    engine: &Engine,
    cfg: &Config,
    u: &[Uncertain],
    nominal_class: Class,
    progress: &dyn Progress,
) -> Result<(Vec<Distance>, Timings, usize)> {
    let d = u.len();
    let vary: Vec<Param> = u.iter().map(|x| x.param).collect();
    let nominal: Vec<f64> = u.iter().map(Uncertain::nominal).collect();
    let mut timings = Timings::default();
    let mut runs = 0;
    // A change is a decided class other than the nominal's: an undecided point (unresolved at
    // the horizon) is no evidence of a change and counts with the nominal side.
    let changed = |c: Class| c != nominal_class && c != Class::Unresolved;
    // Value of parameter j at signed offset t (in scales), clamped to the physical bounds.
    let at = |j: usize, t: f64| {
        let (lo, hi) = bounds(u[j].param);
        (nominal[j] + t * u[j].scale()).clamp(lo, hi)
    };
    let row = |j: usize, v: f64| {
        let mut r = nominal.clone();
        r[j] = v;
        r
    };
    // Lines: (parameter, side); scan steps k = 1..=SCAN_STEPS at k / SCAN_STEPS * SCAN_SIGMAS.
    let lines: Vec<(usize, f64)> = (0..d).flat_map(|j| [(j, -1.0), (j, 1.0)]).collect();
    let step = SCAN_SIGMAS / SCAN_STEPS as f64;
    let mut values = Vec::new();
    for &(j, side) in &lines {
        for k in 1..=SCAN_STEPS {
            values.extend(row(j, at(j, side * k as f64 * step)));
        }
    }
    let (s, t) = decide_points(engine, cfg, &vary, &values, progress)?;
    timings.add(&t);
    runs += values.len() / d;
    // Per line: the bracket (inside, outside) in scales and the class outside.
    let mut brackets: Vec<Option<(f64, f64, Class)>> = lines
        .iter()
        .enumerate()
        .map(|(l, _)| {
            let cls = &s[l * SCAN_STEPS..(l + 1) * SCAN_STEPS];
            cls.iter().position(|c| changed(c.class)).map(|k| {
                let out = (k + 1) as f64 * step;
                (out - step, out, cls[k].class)
            })
        })
        .collect();
    // Each round: the SECTIONS - 1 inner points of every bracket in one ensemble; the new
    // bracket ends at the first of them (from the nominal side) whose class changed.
    let inner = SECTIONS - 1;
    let cut = |a: f64, b: f64, k: usize| a + (b - a) * k as f64 / SECTIONS as f64;
    for _ in 0..ROUNDS {
        let live: Vec<usize> = (0..lines.len())
            .filter(|&l| brackets[l].is_some())
            .collect();
        if live.is_empty() {
            break;
        }
        let mut values = Vec::new();
        for &l in &live {
            let (j, side) = lines[l];
            let (a, b, _) = brackets[l].expect("live lines have a bracket");
            for k in 1..=inner {
                values.extend(row(j, at(j, side * cut(a, b, k))));
            }
        }
        let (s, t) = decide_points(engine, cfg, &vary, &values, progress)?;
        timings.add(&t);
        runs += values.len() / d;
        for (&l, xs) in live.iter().zip(s.chunks(inner)) {
            let (a, b, beyond) = brackets[l].expect("live lines have a bracket");
            brackets[l] = Some(match xs.iter().position(|x| changed(x.class)) {
                Some(k) => (cut(a, b, k), cut(a, b, k + 1), xs[k].class),
                None => (cut(a, b, inner), b, beyond),
            });
        }
    }
    let distances = distances(u, &lines, &brackets, at);
    Ok((distances, timings, runs))
}

/// The distance to the nearest class change along each parameter, below and above, from the
/// final brackets of its two lines (`lines[l]`: parameter and side; `at(j, t)`: parameter j's
/// value t scales from the nominal).
fn distances(
    u: &[Uncertain],
    lines: &[(usize, f64)],
    brackets: &[Option<(f64, f64, Class)>],
    at: impl Fn(usize, f64) -> f64,
) -> Vec<Distance> {
    let nominal: Vec<f64> = u.iter().map(Uncertain::nominal).collect();
    let change = |l: usize| {
        let (j, side) = lines[l];
        brackets[l].map(|(a, b, beyond)| {
            let distance = at(j, side * b) - nominal[j];
            Change {
                distance,
                scales: distance / u[j].scale(),
                beyond,
                bracket: (b - a) * u[j].scale(),
            }
        })
    };
    (0..u.len())
        .map(|j| Distance {
            param: u[j].param,
            below: change(2 * j),
            above: change(2 * j + 1),
            searched_scales: SCAN_SIGMAS,
        })
        .collect()
}
