//! The CPU backend: the integrator of [`crate::method`] over many points, in parallel on the
//! machine's cores (rayon), in f32 or f64.

use crate::config::Precision;
use crate::method::{Integrator, RunResult};
use crate::progress::Progress;
use crate::real::Real;
use crate::spec::{Points, RunSpec};
use rayon::prelude::*;

/// Integrates every point; one unit of progress per finished point.
pub fn run(spec: &RunSpec, points: &Points, progress: &dyn Progress) -> Vec<RunResult> {
    match spec.precision {
        Precision::F32 => run_typed::<f32>(spec, points, progress),
        Precision::F64 => run_typed::<f64>(spec, points, progress),
    }
}

fn run_typed<F: Real>(spec: &RunSpec, points: &Points, progress: &dyn Progress) -> Vec<RunResult> {
    (0..points.len())
        .into_par_iter()
        .map(|i| {
            let p = points.params(&spec.params, i);
            let r = Integrator::<F>::new(&p, &spec.settings).run(
                points.y0(spec, i),
                spec.transient,
                spec.samples,
            );
            progress.advance(1);
            r
        })
        .collect()
}
