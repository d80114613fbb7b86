//! The CPU backend: the integrator of [`crate::method`] over many points, in parallel on the
//! machine's cores (rayon), in f32 or f64.

use crate::config::Precision;
use crate::method::{Integrator, LANES, RunResult, run_lanes};
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
    // Batches of LANES points share each grid step (method::lanes); rayon spreads the batches
    // over the cores.
    let idx: Vec<usize> = (0..points.len()).collect();
    idx.par_chunks(LANES)
        .flat_map_iter(|chunk| {
            let its: Vec<Integrator<F>> = chunk
                .iter()
                .map(|&i| Integrator::<F>::new(&points.params(&spec.params, i), &spec.settings))
                .collect();
            let y0s: Vec<[f64; 4]> = chunk.iter().map(|&i| points.y0(spec, i)).collect();
            let r = run_lanes(&its, &y0s, spec.transient, spec.samples);
            progress.advance(chunk.len() as u64);
            r
        })
        .collect()
}
