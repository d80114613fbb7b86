//! Cost of the tangent dynamics on the CPU: steps/s of one thread integrating a Fig. 2 point
//! plainly, with one tangent vector (largest exponent) and with four (monodromy, spectrum),
//! and of 4 such points with four vectors each on the lanes of `method::run_flows` (the
//! schedule of Newton's method in `stability`), per point-step.
//! `cargo run --release --example tangent_cost`; best of three runs of 2000 periods each.

use rattle::cycles::Tangent;
use rattle::method::{FlowTask, Integrator, NEWTON_LANES, PointState, Settings, run_flows};
use rattle::model::Params;
use std::time::Instant;

/// One flow of `n` periods with four tangent vectors.
struct Flow {
    it: Integrator<f64>,
    st: PointState<f64>,
    n: u32,
    done: bool,
}

impl FlowTask for Flow {
    fn flow(&self) -> Option<(PointState<f64>, u32)> {
        (!self.done).then_some((self.st, self.n))
    }

    fn integrator(&self) -> &Integrator<f64> {
        &self.it
    }

    fn ended(&mut self, end: &PointState<f64>, _: &Tangent<f64>) {
        self.st = *end;
        self.done = true;
    }
}

fn main() {
    let periods = 2000;
    for eta in [1.1, 1.4] {
        let p = Params::paper(eta);
        let it = Integrator::<f64>::new(&p, &Settings::default());
        for m in [0usize, 1, 4] {
            let mut best = f64::MAX;
            for _ in 0..3 {
                let mut st = it.start([0.0; 4]);
                let t = Instant::now();
                if m == 0 {
                    (0..periods).for_each(|_| it.period(&mut st));
                } else {
                    let mut tan = Tangent::<f64>::identity(m);
                    (0..periods).for_each(|_| it.period_observed(&mut st, &mut tan));
                }
                best = best.min(t.elapsed().as_secs_f64());
            }
            let steps = f64::from(periods * it.steps_per_period());
            println!(
                "eta {eta}: {m} tangent vectors: {:.3e} steps/s (f64, one thread)",
                steps / best
            );
        }
        // Neighbouring values of eta on the lanes, as the Newton trials of a sweep.
        let mut best = f64::MAX;
        for _ in 0..3 {
            let mut tasks: Vec<Flow> = (0..NEWTON_LANES)
                .map(|l| {
                    let it = Integrator::<f64>::new(
                        &Params::paper(eta + 1e-4 * l as f64),
                        &Settings::default(),
                    );
                    Flow {
                        st: it.start([0.0; 4]),
                        it,
                        n: periods,
                        done: false,
                    }
                })
                .collect();
            let t = Instant::now();
            run_flows(&mut tasks);
            best = best.min(t.elapsed().as_secs_f64());
        }
        let steps = f64::from(periods * it.steps_per_period()) * NEWTON_LANES as f64;
        println!(
            "eta {eta}: 4 tangent vectors, {NEWTON_LANES} points on the lanes: {:.3e} steps/s (f64, one thread)",
            steps / best
        );
    }
}
