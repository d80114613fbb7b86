//! Helpers shared by the integration tests: the binary, scratch directories, NPY files.
#![allow(dead_code)] // each test binary uses a subset

pub mod kernel;
pub mod points;

use std::path::{Path, PathBuf};
use std::process::Command;

/// The `rattle` binary of this build.
pub fn rattle() -> Command {
    Command::new(env!("CARGO_BIN_EXE_rattle"))
}

/// A shipped configuration.
pub fn config(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("configs")
        .join(name)
}

/// An empty directory of this test process, removed when the test ends well (kept after a
/// failure, to be looked at).
pub fn scratch(name: &str) -> Scratch {
    let d = std::env::temp_dir().join(format!("rattle-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    Scratch(d)
}

/// See [`scratch`].
pub struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = PathBuf;
    fn deref(&self) -> &PathBuf {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for Scratch {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// Runs a command that must succeed; returns its stdout.
pub fn ok(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The values of an NPY file.
pub fn npy<T: npyz::Deserialize>(path: &Path) -> Vec<T> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    npyz::NpyFile::new(&bytes[..]).unwrap().into_vec().unwrap()
}

/// A JSON file.
pub fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// A GPU engine, or None (the test then reports SKIPPED) when no adapter is found. With
/// RATTLE_REQUIRE_GPU=1 (set by CI) a missing adapter fails the test instead.
pub fn gpu_engine() -> Option<rattle::engine::Engine> {
    open_gpu().map(|g| rattle::engine::Engine::Gpu(Box::new(g)))
}

/// The adapter, or None (the test then reports SKIPPED); with RATTLE_REQUIRE_GPU=1 a missing
/// adapter fails the test. The one place that decides whether a GPU test may skip.
pub fn open_gpu() -> Option<rattle::gpu::Gpu> {
    match rattle::gpu::Gpu::new() {
        Ok(g) => Some(g),
        Err(e) => {
            if std::env::var("RATTLE_REQUIRE_GPU").is_ok_and(|v| v == "1") {
                panic!("RATTLE_REQUIRE_GPU=1 but no adapter: {e}");
            }
            eprintln!("SKIPPED: no GPU adapter ({e})");
            None
        }
    }
}

/// One point `p` from `y0` on `engine`, sampled from the start for `samples` periods.
pub fn run_point(
    engine: &rattle::engine::Engine,
    p: &rattle::model::Params<f64>,
    y0: [f64; 4],
    settings: rattle::method::Settings,
    samples: u32,
    precision: rattle::config::Precision,
) -> rattle::method::RunResult {
    let spec = rattle::spec::RunSpec {
        params: *p,
        y0,
        settings,
        transient: 0,
        samples,
        period_tol: 1e-4,
        horizon: 1,
        look: 0,
        decide: Default::default(),
        decide_precision: None,
        overlap: None,
        precision,
    };
    let (mut rs, _) = engine
        .run(
            &spec,
            &rattle::spec::Points::single(),
            &rattle::progress::Silent,
        )
        .unwrap();
    rs.pop().expect("one point, one result")
}

// Helpers of the command-line reliability tests (tests/reliability.rs, parts.rs, memory.rs,
// outputs.rs).

/// 1 x 3 cells at eta = 1.33, R = 0.59: the middle cell has two attractors (see tests/map.rs).
pub const COEXIST: &str = "[model]\neta = 1.33\n[method]\nsteps_per_period = 64\n[run]\n\
    transient_periods = 300\nsample_periods = 50\n[map]\nx = \"R\"\nx_from = 0.58\n\
    x_to = 0.60\nx_points = 1\ny = \"lambda\"\ny_from = 0.085\ny_to = 0.115\ny_points = 3\n";

pub fn setup(name: &str) -> (Scratch, PathBuf) {
    let d = scratch(name);
    let cfg = d.join("c.toml");
    std::fs::write(&cfg, COEXIST).unwrap();
    (d, cfg)
}

/// Fig. 2's model (its config without the sweep), to which a test adds its own `[map]`.
pub fn fig2_model() -> String {
    let fig2 = std::fs::read_to_string(config("fig2.toml")).unwrap();
    fig2.split("[sweep]").next().unwrap().to_string()
}

/// `rattle map` on the CPU in f64 (deterministic across machines), its output.
pub fn map(cfg: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    rattle()
        .args(["map", "--backend", "cpu", "--precision", "f64", "--config"])
        .arg(cfg)
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

pub fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs `cmd`, which must be refused before computing: exit 2 with every key in the message.
pub fn refused(cmd: &mut std::process::Command, keys: &[&str]) {
    let out = cmd.output().unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{cmd:?}: {err}");
    assert!(keys.iter().all(|k| err.contains(k)), "{cmd:?}: {err}");
}

pub fn bifurcation(out: &Path, points: u32) -> std::process::Command {
    let mut c = rattle();
    c.args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(config("fig2.toml"))
        .args(["--set", &format!("sweep.points={points}")])
        .args([
            "--set",
            "run.transient_periods=5",
            "--set",
            "run.sample_periods=4",
        ])
        .args(["--set", "method.steps_per_period=16"])
        .arg("--out")
        .arg(out);
    c
}

pub fn point(args: &[&str]) -> std::process::Output {
    rattle()
        .args(["point", "--backend", "cpu", "--config"])
        .arg(config("fig2.toml"))
        .args([
            "--set",
            "run.transient_periods=10",
            "--set",
            "run.sample_periods=5",
        ])
        .args(args)
        .output()
        .unwrap()
}

/// A map of 4 x 4 cells over 2 + 2 periods: cheap enough to run where only the checks matter.
pub const CHEAP_MAP: [&str; 8] = [
    "--set",
    "map.x_points=4",
    "--set",
    "map.y_points=4",
    "--set",
    "run.transient_periods=2",
    "--set",
    "run.sample_periods=2",
];

/// Runs `cmd` and kills it if it has not ended within `secs`; the output, or None if killed.
pub fn within(cmd: &mut std::process::Command, secs: f64) -> Option<std::process::Output> {
    use std::process::Stdio;
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t = std::time::Instant::now();
    while t.elapsed().as_secs_f64() < secs {
        if child.try_wait().unwrap().is_some() {
            return Some(child.wait_with_output().unwrap());
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    None
}

/// The independent reference's verdict at the point of `cfg` (`reference::dry`: exact motion
/// between events, its own Newton and multipliers), from the config's start: the lag at which
/// its stroboscopic states repeat to 1e-6 after 2 x 10^4 periods, and its own cycle there
/// (least period, leading |mu|, stable).
pub fn reference_cycle(cfg: &rattle::config::Config) -> (Option<usize>, u32, f64, bool) {
    let zeno = rattle::spec::RunSpec::new(cfg).settings.zeno_speed;
    let r = rattle::reference::dry::DryReference::new(&cfg.params(), 1024, zeno).unwrap();
    let mut st = r.start(cfg.initial.y);
    r.run(&mut st, 20_000, None).unwrap();
    let s = r.run(&mut st, 2 * 1024 + 8, None).unwrap();
    let scale = s.iter().flatten().fold(1.0f64, |a, v| a.max(v.abs()));
    let lag = (1..=1024).find(|&m| {
        (m..s.len()).all(|k| (0..4).all(|c| (s[k][c] - s[k - m][c]).abs() < 1e-6 * scale))
    });
    let c = r
        .cycle(*s.last().unwrap(), lag.unwrap_or(1) as u32)
        .unwrap();
    let lead = c.lead()[0].hypot(c.lead()[1]);
    (lag, c.period, lead, c.stable())
}
