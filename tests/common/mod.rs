//! Helpers shared by the integration tests: the binary, scratch directories, NPY files.
#![allow(dead_code)] // each test binary uses a subset

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
