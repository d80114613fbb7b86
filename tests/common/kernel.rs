//! The GPU kernel's shared fixtures: one device per test binary, Fig. 2's points on the GPU
//! and on the CPU twin.

use rattle::config::Precision;
use rattle::gpu::{Gpu, GpuOutput, Job};
use rattle::method::{Integrator, RunResult, Settings};
use rattle::model::{Param, Params};
use rattle::progress::Silent;
use rattle::real::Real;
use rattle::spec::{Points, RunSpec};
use std::sync::{Mutex, OnceLock};

/// One device for all tests of this binary (adapters are slow to open; tests run serially
/// on it through the mutex).
pub fn gpu() -> Option<&'static Mutex<Gpu>> {
    static GPU: OnceLock<Option<Mutex<Gpu>>> = OnceLock::new();
    GPU.get_or_init(|| {
        super::open_gpu().map(|g| {
            eprintln!("GPU tests on {}", rattle::gpu::describe(&g.info));
            Mutex::new(g)
        })
    })
    .as_ref()
}

pub fn eta_spec(s: Settings, transient: u32, samples: u32, f64: bool) -> RunSpec {
    RunSpec {
        params: Params::paper(1.5),
        y0: [0.0; 4],
        settings: s,
        transient,
        samples,
        period_tol: 1e-4,
        horizon: 1,
        look: 0,
        decide: Default::default(),
        decide_precision: None,
        overlap: None,
        precision: if f64 { Precision::F64 } else { Precision::F32 },
    }
}

pub fn run_job(job: &Job) -> Option<GpuOutput> {
    let g = gpu()?.lock().unwrap();
    Some(g.run(job, &Silent).expect("GPU run"))
}

/// Points of the paper's Fig. 2 at the given eta values, samples kept.
pub fn run_gpu(
    etas: &[f64],
    s: Settings,
    transient: u32,
    samples: u32,
    f64: bool,
) -> Option<GpuOutput> {
    let spec = eta_spec(s, transient, samples, f64);
    run_job(&Job::new(&spec, Points::along(&[Param::Eta], etas), true))
}

pub fn run_cpu<F: Real>(eta: f64, s: &Settings, transient: u32, samples: u32) -> RunResult {
    Integrator::<F>::new(&Params::paper(eta), s).run([0.0; 4], transient, samples)
}

pub fn max_diff(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    (0..4).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max)
}
