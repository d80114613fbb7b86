//! `rattle._rattle`: the library's commands for the Python package (`rattle/__init__.py` wraps
//! them). Every computation runs on a thread of its own while the interpreter lock is released;
//! the calling thread waits on it, reports progress and watches for Ctrl-C (an interrupt ends
//! the computation at its next progress report). Results cross as JSON (reports) and NPY bytes
//! (arrays, the bytes the command line's files hold); errors as the package's exceptions.

use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use rattle::config::{Backend, Config, ConfigError};
use rattle::engine::Engine;
use rattle::request::{Command, Request, Source};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

/// The payload that unwinds a computation interrupted from Python.
struct Cancelled;

/// The library's progress, counted for the waiting thread: units done of `units` (the
/// engine's units, set by the work once its engine is open), and the interrupt flag.
#[derive(Default)]
struct Reporter {
    done: AtomicU64,
    /// The engine's units first counted, and those found since ([`Progress::more`]).
    units: AtomicU64,
    found: AtomicU64,
    cancel: AtomicBool,
}

impl Reporter {
    fn set_units(&self, n: u64) {
        self.units.store(n.max(1), Ordering::Relaxed);
    }

    /// (done, total) in the caller's units (cells, points), `total` counted first: the total
    /// grows with the work the run finds it needs (the adaptive stages), `done` never goes back
    /// and never passes the total.
    fn scaled(&self, total: u64) -> (u64, u64) {
        let (d, u, f) = (
            self.done.load(Ordering::Relaxed),
            self.units.load(Ordering::Relaxed),
            self.found.load(Ordering::Relaxed),
        );
        if u == 0 {
            return (0, total);
        }
        let scale = |x: u64| (x as u128 * total as u128 / u as u128) as u64;
        let all = scale(u + f).max(total);
        (scale(d).min(all), all)
    }
}

impl rattle::progress::Progress for Reporter {
    fn advance(&self, n: u64) {
        if self.cancel.load(Ordering::Relaxed) {
            std::panic::panic_any(Cancelled);
        }
        self.done.fetch_add(n, Ordering::Relaxed);
    }

    fn more(&self, n: u64) {
        self.found.fetch_add(n, Ordering::Relaxed);
    }
}

/// The request of a config: a TOML file or TOML text, with `key=value` overrides. Every
/// command loads it through the library's one validation path ([`Request::load`]), as the
/// command line does.
fn request(path: Option<String>, text: Option<String>, sets: Vec<String>) -> Request {
    let source = match (path, text) {
        (Some(p), _) => Source::File(p.into()),
        (None, Some(t)) => Source::Text(t),
        (None, None) => Source::Text(String::new()),
    };
    Request::new(source, sets)
}

/// The config for `cmd`, and its notes and warnings for Python's `warnings`.
fn load(py: Python, r: &Request, cmd: Command) -> PyResult<(Config, Vec<String>)> {
    let l = r.load(cmd).map_err(|e| to_py(py, e.into()))?;
    Ok((l.cfg, said(l.notes, l.warnings)))
}

/// Notes and warnings, in the order the command line prints them.
fn said(notes: Vec<String>, warnings: Vec<String>) -> Vec<String> {
    notes
        .into_iter()
        .map(|n| format!("note: {n}"))
        .chain(warnings)
        .collect()
}

/// An integer option as a Python caller gives it: any int (out of 64 bits saturated, so that
/// the library names it as out of range), else `ConfigError` naming the option.
fn int_arg(py: Python, name: &'static str, v: Option<&Bound<PyAny>>) -> PyResult<Option<i64>> {
    let Some(v) = v.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    // Python ints and numpy integers (anything with `__index__`), not bools.
    let is_int = !v.is_instance_of::<pyo3::types::PyBool>() && v.hasattr("__index__")?;
    if !is_int {
        let kind = v.get_type().name()?.to_string();
        return Err(to_py(
            py,
            rattle::Error::Option(rattle::error::OptionError::Unsuitable {
                option: name,
                why: format!("an integer is wanted, not {kind}"),
            }),
        ));
    }
    let v = v.call_method0("__index__")?;
    Ok(Some(match v.extract::<i64>() {
        Ok(n) => n,
        Err(_) if v.gt(0)? => i64::MAX,
        Err(_) => i64::MIN,
    }))
}

/// The package's exception for an error of the library: a config or option outside its range
/// is `ConfigError` (a `ValueError`), one too large for memory `TooLargeError` (also a
/// `MemoryError`), anything else `RattleError` (a `RuntimeError`).
fn to_py(py: Python, e: rattle::Error) -> PyErr {
    use rattle::Error as E;
    let kind = match &e {
        E::Config(ConfigError::Range { value, .. }) if value.contains("in memory") => {
            "TooLargeError"
        }
        E::Option(o) if o.to_string().contains("in memory") => "TooLargeError",
        E::Config(_) | E::Option(_) | E::Param(_) => "ConfigError",
        _ => "RattleError",
    };
    let msg = match &e {
        // Python's keywords spell the options with underscores.
        E::Option(o) => o.render(&|name| format!("`{}`", name.replace('-', "_"))),
        _ => {
            // With its causes, as the command line prints them ("cannot read config x: Is a
            // directory").
            let mut m = e.to_string();
            let mut cause = std::error::Error::source(&e);
            while let Some(c) = cause {
                let c_text = c.to_string();
                if !m.ends_with(&c_text) {
                    m = format!("{m}: {c_text}");
                }
                cause = c.source();
            }
            m
        }
    };
    match py
        .import("rattle._errors")
        .and_then(|m| m.getattr(kind))
        .and_then(|c| c.call1((msg.clone(),)))
    {
        Ok(exc) => PyErr::from_value(exc),
        Err(err) => err,
    }
}

/// Runs `work` off the interpreter lock on a thread of its own; `progress(done, total)` is
/// called from the calling thread (with the lock) about ten times a second; Ctrl-C raises
/// `KeyboardInterrupt` once the computation has stopped. A panic becomes `RattleError`.
fn detached<T: Send + 'static>(
    py: Python,
    total: u64,
    progress: Option<Py<PyAny>>,
    work: impl FnOnce(&Reporter) -> rattle::Result<T> + Send + 'static,
) -> PyResult<T> {
    quiet_cancel_panics();
    // This computation's own interrupt: another thread's Ctrl-C or raising callback stops
    // only its own.
    let stop = rattle::progress::Stop::new();
    let reporter = Arc::new(Reporter::default());
    let (tx, rx) = std::sync::mpsc::channel();
    {
        let reporter = reporter.clone();
        let stop = stop.clone();
        std::thread::spawn(move || {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                rattle::progress::stoppable(&stop, || work(&reporter))
            }));
            let _ = tx.send(r);
        });
    }
    let rx = std::sync::Mutex::new(rx);
    let mut interrupted = None;
    loop {
        let got = py.detach(|| {
            rx.lock()
                .unwrap_or_else(|e| e.into_inner())
                .recv_timeout(Duration::from_millis(100))
        });
        match got {
            Ok(r) => {
                if let Some(e) = interrupted {
                    return Err(e);
                }
                return match r {
                    Ok(Ok(v)) => Ok(v),
                    Ok(Err(e)) => Err(to_py(py, e)),
                    Err(p) if p.is::<Cancelled>() || p.is::<rattle::progress::Interrupted>() => {
                        Err(PyKeyboardInterrupt::new_err(()))
                    }
                    Err(p) => Err(PyRuntimeError::new_err(format!(
                        "rattle failed: {}",
                        p.downcast_ref::<String>()
                            .cloned()
                            .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                            .unwrap_or_default()
                    ))),
                };
            }
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                return Err(PyRuntimeError::new_err("rattle's computation thread ended"));
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                if interrupted.is_none() {
                    if let Err(e) = py.check_signals() {
                        // Stop the work at its next report or integrator period, then raise.
                        reporter.cancel.store(true, Ordering::Relaxed);
                        stop.stop();
                        interrupted = Some(e);
                        continue;
                    }
                    if let Some(cb) = &progress
                        && let Err(e) = cb.call1(py, reporter.scaled(total))
                    {
                        // A callback that raises ends the computation as an interrupt does.
                        reporter.cancel.store(true, Ordering::Relaxed);
                        stop.stop();
                        interrupted = Some(e);
                    }
                }
            }
        }
    }
}

/// Runs `f` off the interpreter lock on the calling thread; a panic comes back as
/// `RattleError`, never as a crash or a `PanicException`.
fn guarded<T: Send>(py: Python, f: impl FnOnce() -> rattle::Result<T> + Send) -> PyResult<T> {
    match py.detach(|| std::panic::catch_unwind(std::panic::AssertUnwindSafe(f))) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(to_py(py, e)),
        Err(_) => Err(to_py(
            py,
            rattle::Error::Merge("rattle failed while writing files".into()),
        )),
    }
}

/// The default panic message is not printed for an interrupted computation.
fn quiet_cancel_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let p = info.payload();
            if !p.is::<Cancelled>() && !p.is::<rattle::progress::Interrupted>() {
                previous(info);
            }
        }));
    });
}

/// The engine of `cfg`, and the warning of a GPU request that fell back to the CPU.
fn engine(cfg: &Config) -> rattle::Result<(Engine, Vec<String>)> {
    let engine = Engine::open(cfg.method.backend)?;
    let mut warnings = Vec::new();
    if cfg.method.backend == Backend::Gpu && matches!(engine, Engine::Cpu) {
        warnings.push(
            "no GPU adapter: falling back to the cpu backend (set method.backend = \"cpu\" to \
             silence this)"
                .to_string(),
        );
    }
    Ok((engine, warnings))
}

/// `rattle point`: the report's JSON, and warnings.
#[pyfunction]
#[pyo3(signature = (path, text, sets, progress=None))]
fn point(
    py: Python,
    path: Option<String>,
    text: Option<String>,
    sets: Vec<String>,
    progress: Option<Py<PyAny>>,
) -> PyResult<(String, Vec<String>)> {
    let (cfg, mut said) = load(py, &request(path, text, sets), Command::Point)?;
    let (report, warnings) = detached(py, 1, progress, move |p| {
        let (engine, warnings) = engine(&cfg)?;
        p.set_units(engine.progress_per_point(&rattle::spec::RunSpec::new(&cfg)));
        let r = rattle::point::run(&engine, &cfg, p)?;
        Ok((serde_json::to_string(&r)?, warnings))
    })?;
    said.extend(warnings);
    Ok((report, said))
}

/// A computed map: its layers as NPY bytes, its report, and its files on request.
#[pyclass(frozen)]
struct MapData {
    result: rattle::map::MapResult,
    warnings: Vec<String>,
}

#[pymethods]
impl MapData {
    /// Layer name -> the bytes of its NPY file.
    fn layers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (name, bytes) in rattle::map::npy_layers(&self.result.cfg, &self.result.fields) {
            d.set_item(name, PyBytes::new(py, &bytes))?;
        }
        Ok(d)
    }

    /// The report (backend, device, precision, cells, timings) with the caption, the config,
    /// the class counts and the axes' values, as JSON.
    fn report(&self) -> PyResult<String> {
        let r = &self.result;
        let m = &r.cfg.map;
        let j = serde_json::json!({
            "report": r.report,
            "caption": rattle::map::map_caption(&r.cfg, &r.fields, &r.report),
            "config": r.cfg,
            "class_counts": r.fields.counts(),
            "rule_counts": r.fields.rule_counts(),
            "x": { "param": m.x.name(), "label": m.x.label(), "values": axis(m.x_from, m.x_to, m.x_points) },
            "y": { "param": m.y.name(), "label": m.y.label(), "values": axis(m.y_from, m.y_to, m.y_points) },
            "z": r.cfg.z_axis().map(|z| serde_json::json!({
                "param": z.param.name(), "label": z.param.label(), "values": z.values(),
            })),
        });
        Ok(j.to_string())
    }

    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    /// The typed boundaries between the map's classes (`rattle map --boundaries`), as the
    /// JSON of PREFIX-boundaries.json without its caption and files.
    fn boundaries(&self, py: Python) -> PyResult<String> {
        // On a thread of its own, as every computation: Ctrl-C stops it at the integrator's
        // next period.
        let (cfg, f) = (self.result.cfg.clone(), self.result.fields.clone());
        let b = detached(py, 1, None, move |_| {
            use rattle::map::boundaries::{VolumeBoundaries, of_map};
            // The sides' motions at the edges' midpoints run on the map's engine.
            let (engine, _) = engine(&cfg)?;
            let b = of_map(&engine, &cfg, &f)?;
            // A volume's points and curves carry their slice's z; those between slices
            // their own.
            Ok(match (cfg.z_axis(), &b.slices[..]) {
                (None, [one]) => serde_json::to_string(one)?,
                _ => serde_json::to_string(&VolumeBoundaries::of(&cfg, &b))?,
            })
        })?;
        Ok(b)
    }

    /// Writes the command line's files under `prefix`; returns their paths.
    fn save(&self, py: Python, prefix: PathBuf) -> PyResult<Vec<PathBuf>> {
        rattle::output::check_prefix(&prefix, &["png", "json"]).map_err(|e| to_py(py, e.into()))?;
        guarded(py, || self.result.write(&prefix))
    }
}

/// The values of a map axis, as the map's cells take them.
fn axis(from: f64, to: f64, n: u32) -> Vec<f64> {
    Config::map_axis(from, to, n)
}

#[pyfunction]
#[pyo3(signature = (path, text, sets, progress=None))]
fn map(
    py: Python,
    path: Option<String>,
    text: Option<String>,
    sets: Vec<String>,
    progress: Option<Py<PyAny>>,
) -> PyResult<MapData> {
    let (cfg, mut warnings) = load(py, &request(path, text, sets), Command::Map)?;
    let o = rattle::map::MapOptions::default();
    o.check(&cfg).map_err(|e| to_py(py, e))?;
    let cells = rattle::map::cell_count(&cfg) as u64;
    let (result, w) = detached(py, cells, progress, move |p| {
        let (engine, warnings) = engine(&cfg)?;
        p.set_units(rattle::map::work(&engine, &cfg, &o));
        Ok((rattle::map::compute_map(&engine, &cfg, &o, p)?, warnings))
    })?;
    warnings.extend(w);
    Ok(MapData { result, warnings })
}

/// A computed bifurcation diagram.
#[pyclass(frozen)]
struct BifurcationData {
    b: rattle::bifurcation::Bifurcation,
    warnings: Vec<String>,
}

#[pymethods]
impl BifurcationData {
    /// The section samples as the CSV holds them: the direction ("" without continuation),
    /// the parameter value, the sample index and the state (n x 4), one row per sample.
    #[allow(clippy::type_complexity)]
    fn samples<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(
        Vec<String>,
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray1<i64>>,
        Bound<'py, PyArray2<f64>>,
    )> {
        let (mut d, mut v, mut k, mut y) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (dir, points) in &self.b.runs {
            for pt in points {
                for (i, s) in pt.result.samples.iter().enumerate() {
                    d.push(dir.map_or(String::new(), |x| x.name().to_string()));
                    v.push(pt.value);
                    k.push(i as i64);
                    y.extend_from_slice(s);
                }
            }
        }
        let rows = v.len();
        let y = PyArray1::from_vec(py, y).reshape([rows, 4])?;
        Ok((d, PyArray1::from_vec(py, v), PyArray1::from_vec(py, k), y))
    }

    /// The points (value, class, periods integrated) and the located bifurcation points of
    /// each chain, the timings and the caption, as JSON.
    fn report(&self) -> PyResult<String> {
        rattle::bifurcation::report_json(&self.b)
            .map_err(|e| PyRuntimeError::new_err(e.to_string()))
    }

    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    fn save(&self, py: Python, prefix: PathBuf) -> PyResult<Vec<PathBuf>> {
        rattle::output::check_prefix(&prefix, &["csv", "png", "json"])
            .map_err(|e| to_py(py, e.into()))?;
        guarded(py, || rattle::bifurcation::write_outputs(&prefix, &self.b))
    }
}

#[pyfunction]
#[pyo3(signature = (path, text, sets, progress=None))]
fn bifurcation(
    py: Python,
    path: Option<String>,
    text: Option<String>,
    sets: Vec<String>,
    progress: Option<Py<PyAny>>,
) -> PyResult<BifurcationData> {
    let (cfg, mut warnings) = load(py, &request(path, text, sets), Command::Sweep)?;
    let total = cfg.sweep.points as u64;
    let (b, w) = detached(py, total, progress, move |p| {
        let (engine, warnings) = engine(&cfg)?;
        p.set_units(rattle::bifurcation::work(&engine, &cfg, None));
        Ok((rattle::bifurcation::run(&engine, &cfg, None, p)?, warnings))
    })?;
    warnings.extend(w);
    Ok(BifurcationData { b, warnings })
}

/// The draws' columns: set, row, the uncertain parameters' values, class name, exponent.
type Draws = (Vec<String>, Vec<u32>, Vec<Vec<f64>>, Vec<String>, Vec<f64>);

/// A finished sensitivity study.
#[pyclass(frozen)]
struct SensitivityData {
    study: rattle::sensitivity::Study,
    cfg: Config,
    backend: String,
    device: String,
    warnings: Vec<String>,
}

#[pymethods]
impl SensitivityData {
    /// The study (probabilities with intervals, distances, Sobol indices) and its caption,
    /// as JSON.
    fn report(&self) -> PyResult<String> {
        let j = serde_json::json!({
            "study": self.study,
            "timings": self.study.timings,
            "nominal": self.study.nominal.name(),
            "caption": rattle::sensitivity::caption(&self.study),
            "backend": self.backend,
            "device": self.device,
        });
        Ok(j.to_string())
    }

    /// The draws as the CSV holds them: the set and row, the uncertain parameters' values,
    /// the class name and the exponent of each draw.
    fn draws(&self) -> Draws {
        let s = &self.study;
        let mut out = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for d in &s.draws {
            out.0.push(d.set.clone());
            out.1.push(d.row as u32);
            out.2.push(d.values.clone());
            out.3.push(d.class.name());
            out.4.push(d.lyapunov);
        }
        out
    }

    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    fn save(&self, py: Python, prefix: PathBuf) -> PyResult<Vec<PathBuf>> {
        rattle::output::check_prefix(&prefix, &["json", "csv", "png", "svg"])
            .map_err(|e| to_py(py, e.into()))?;
        guarded(py, || {
            rattle::sensitivity::write_outputs(
                &prefix,
                &self.cfg,
                &self.study,
                &self.backend,
                &self.device,
            )
        })
    }
}

#[pyfunction]
#[pyo3(signature = (path, text, sets, uncertain=None, samples=None, seed=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn sensitivity(
    py: Python,
    path: Option<String>,
    text: Option<String>,
    sets: Vec<String>,
    uncertain: Option<Vec<String>>,
    samples: Option<Bound<PyAny>>,
    seed: Option<Bound<PyAny>>,
    progress: Option<Py<PyAny>>,
) -> PyResult<SensitivityData> {
    let samples = int_arg(py, "samples", samples.as_ref())?;
    let seed = int_arg(py, "seed", seed.as_ref())?;
    let (l, o) = request(path, text, sets)
        .sensitivity(uncertain.as_deref(), samples, seed)
        .map_err(|e| to_py(py, e))?;
    let said = said(l.notes, l.warnings);
    let cfg = l.cfg;
    let total = rattle::sensitivity::points(&o) as u64;
    let c = cfg.clone();
    let (study, backend, device, warnings) = detached(py, total, progress, move |p| {
        let (engine, warnings) = engine(&c)?;
        let spec = rattle::spec::RunSpec::new(&c);
        p.set_units(rattle::sensitivity::points(&o) as u64 * engine.progress_per_point(&spec));
        let study = rattle::sensitivity::run(&engine, &c, &o, p)?;
        Ok((study, engine.name().to_string(), engine.device(), warnings))
    })?;
    let warnings = said.into_iter().chain(warnings).collect();
    Ok(SensitivityData {
        study,
        cfg,
        backend,
        device,
        warnings,
    })
}

/// Computed basins of attraction.
#[pyclass(frozen)]
struct BasinData {
    b: rattle::basin::Basin,
    cfg: Config,
    warnings: Vec<String>,
}

#[pymethods]
impl BasinData {
    /// The attractor id of every cell as the bytes of the command line's NPY file.
    fn ids(&self) -> Vec<u8> {
        let g = &self.b.grid;
        let shape = [g.y_values.len() as u64, g.x_values.len() as u64];
        rattle::output::npy_bytes(&shape, &self.b.ids)
    }

    /// The grid, the attractors (class, period, section points, multipliers), the failed
    /// cells, the timings and the caption, as JSON.
    fn report(&self) -> PyResult<String> {
        let b = &self.b;
        let j = serde_json::json!({
            "grid": b.grid,
            "attractors": b.attractors,
            "failed": b.failed,
            "backend": b.backend,
            "device": b.device,
            "timings": b.timings,
            "caption": rattle::basin::caption(&self.cfg, b),
        });
        Ok(j.to_string())
    }

    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    fn save(&self, py: Python, prefix: PathBuf) -> PyResult<Vec<PathBuf>> {
        rattle::output::check_prefix(&prefix, &["png", "npy", "json"])
            .map_err(|e| to_py(py, e.into()))?;
        guarded(py, || {
            rattle::basin::write_outputs(&prefix, &self.cfg, &self.b)
        })
    }
}

#[pyfunction]
#[pyo3(signature = (path, text, sets, progress=None))]
fn basin(
    py: Python,
    path: Option<String>,
    text: Option<String>,
    sets: Vec<String>,
    progress: Option<Py<PyAny>>,
) -> PyResult<BasinData> {
    let (cfg, said) = load(py, &request(path, text, sets), Command::Basin)?;
    let cells = u64::from(cfg.basin.x_points) * u64::from(cfg.basin.y_points);
    let c = cfg.clone();
    let (b, warnings) = detached(py, cells, progress, move |p| {
        let (engine, warnings) = engine(&c)?;
        p.set_units(rattle::basin::work(&engine, &c));
        Ok((rattle::basin::compute(&engine, &c, p)?, warnings))
    })?;
    let warnings = said.into_iter().chain(warnings).collect();
    Ok(BasinData { b, cfg, warnings })
}

/// `rattle bench`: the rows of every backend and precision (JSON list; a row that could not be
/// measured is `{"error": ...}`).
#[pyfunction]
#[pyo3(name = "bench", signature = (path, text, sets, points=None, periods=None, backends=None))]
fn bench_rows(
    py: Python,
    path: Option<String>,
    text: Option<String>,
    sets: Vec<String>,
    points: Option<Bound<PyAny>>,
    periods: Option<Bound<PyAny>>,
    backends: Option<Vec<String>>,
) -> PyResult<(String, Vec<String>)> {
    let (cfg, said) = load(py, &request(path, text, sets), Command::Sweep)?;
    let points = int_arg(py, "points", points.as_ref())?.unwrap_or(2000);
    let periods = int_arg(py, "periods", periods.as_ref())?.unwrap_or(100);
    let (points, periods) = rattle::bench::sizes(points, periods).map_err(|e| to_py(py, e))?;
    let backends: Vec<Backend> = match backends {
        None => Backend::ALL.to_vec(),
        Some(b) => b
            .iter()
            .map(|n| n.parse::<Backend>())
            .collect::<Result<_, _>>()
            .map_err(|e| to_py(py, ConfigError::Parse(format!("backends: {e}")).into()))?,
    };
    // The reporter is the bench's progress, so that Ctrl-C stops it at its next report.
    let rows = detached(py, 1, None, move |p| {
        let rows = rattle::bench::bench(&cfg, points, periods, &backends, false, p)?;
        let rows: Vec<serde_json::Value> = rows
            .into_iter()
            .map(|r| match r {
                Ok(row) => serde_json::to_value(row).unwrap_or_default(),
                Err(e) => serde_json::json!({ "error": e.to_string() }),
            })
            .collect();
        Ok(serde_json::to_string(&rows)?)
    })?;
    Ok((rows, said))
}

/// `rattle validate`: the agreement table of GPU and CPU, as text.
#[pyfunction]
#[pyo3(signature = (path, text, sets, state_points=None))]
fn validate(
    py: Python,
    path: Option<String>,
    text: Option<String>,
    sets: Vec<String>,
    state_points: Option<Bound<PyAny>>,
) -> PyResult<(String, Vec<String>)> {
    let (cfg, said) = load(py, &request(path, text, sets), Command::Sweep)?;
    let state_points = int_arg(py, "state-points", state_points.as_ref())?.unwrap_or(64);
    let table = detached(py, 1, None, move |_| {
        rattle::validate::validate(&cfg, state_points)
    })?;
    Ok((table, said))
}

#[pymodule]
fn _rattle(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(point, m)?)?;
    m.add_function(wrap_pyfunction!(map, m)?)?;
    m.add_function(wrap_pyfunction!(bifurcation, m)?)?;
    m.add_function(wrap_pyfunction!(sensitivity, m)?)?;
    m.add_function(wrap_pyfunction!(basin, m)?)?;
    m.add_function(wrap_pyfunction!(bench_rows, m)?)?;
    m.add_function(wrap_pyfunction!(validate, m)?)?;
    m.add_class::<MapData>()?;
    m.add_class::<BasinData>()?;
    m.add_class::<BifurcationData>()?;
    m.add_class::<SensitivityData>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
