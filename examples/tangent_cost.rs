//! Cost of the tangent dynamics on the CPU: steps/s of one thread integrating a Fig. 2 point
//! plainly, with one tangent vector (largest exponent) and with four (monodromy, spectrum).
//! `cargo run --release --example tangent_cost`; best of three runs of 2000 periods each.

use rattle::method::{Integrator, Settings};
use rattle::model::Params;
use rattle::tangent::Tangent;
use std::time::Instant;

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
    }
}
