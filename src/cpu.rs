//! The CPU backend: the integrator of [`crate::method`] over many points, in parallel on the
//! machine's cores (rayon), in f32 or f64, [`LANES`] points per batch.

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
            // A report of nothing before each batch: an interrupt raised by the progress (a
            // Python caller's Ctrl-C) ends every batch not yet begun at once, instead of after
            // the whole run (rayon finishes the other tasks before it rethrows).
            progress.advance(0);
            let its: Vec<Integrator<F>> = chunk
                .iter()
                .map(|&i| Integrator::<F>::new(&points.params(&spec.params, i), &spec.settings))
                .collect();
            let y0s: Vec<[f64; 4]> = chunk.iter().map(|&i| points.y0(spec, i)).collect();
            let modes: Option<Vec<_>> = points
                .modes
                .map(|_| chunk.iter().filter_map(|&i| points.mode0(i)).collect());
            let r = run_lanes(&its, &y0s, modes.as_deref(), spec.transient, spec.samples);
            progress.advance(chunk.len() as u64 * u64::from(spec.transient + spec.samples));
            r
        })
        .collect()
}

/// Every point by the scalar `Integrator::run`, one point per task: the schedule the batches
/// replaced, with the same results; `rattle bench` measures it as the twin's scalar speed.
pub fn run_scalar(spec: &RunSpec, points: &Points) -> Vec<RunResult> {
    fn typed<F: Real>(spec: &RunSpec, points: &Points) -> Vec<RunResult> {
        (0..points.len())
            .into_par_iter()
            .map(|i| {
                let it = Integrator::<F>::new(&points.params(&spec.params, i), &spec.settings);
                let mut st = it.start_in(points.y0(spec, i), points.mode0(i));
                it.run_from(&mut st, spec.transient, spec.samples)
            })
            .collect()
    }
    match spec.precision {
        Precision::F32 => typed::<f32>(spec, points),
        Precision::F64 => typed::<f64>(spec, points),
    }
}
