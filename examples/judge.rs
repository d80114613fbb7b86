//! The independent judge of a map's classes: long f64 runs of a stratified sample of cells,
//! decided without the map's classifier, written as the fixture that tests/classes.rs scores
//! the classifier against.
//!
//! `cargo run --release --example judge -- CONFIG CLASS_NPY SAMPLE SEED OUT_CSV`
//!
//! CLASS_NPY is a map's `PREFIX-class.npy` over the config's [map] grid. SAMPLE `s30` draws 30
//! cells of each map class group (chaotic, periodic, quasi-periodic, unresolved; fewer where
//! the map has fewer), `u100` 100 cells uniformly over the grid (each class in proportion to
//! its share), with a fixed-seed generator. Each is judged from the map's start state by a
//! run of 10^4 forcing periods at the map's steps per period, in f64 (the same discrete
//! system, so that a long chaotic transient is not judged on another path):
//! - periodic: the last 256 sections repeat with the smallest lag n <= 128 to 1e-7 of the range,
//!   and Newton's method at n (f64, the judge's N) converges to a cycle with every multiplier
//!   inside the unit circle;
//! - otherwise two exponent estimators over the last 3000 periods: the tangent vector
//!   (Benettin) and a second trajectory 1e-8 away in y1, renormalised every period;
//!   chaotic where both exceed 0.002 per unit time; quasi-periodic where both are within
//!   0.001 of zero and weighted Birkhoff averages of y1 over two halves of 1500 periods agree to
//!   8 digits; anything else is `unclear` (left out of the score).

use rattle::classify::{Birkhoff, Class};
use rattle::config::Config;
use rattle::cycles::refine;
use rattle::method::{Integrator, PointState, Settings};
use rattle::model::Params;
use std::io::Write;
use std::path::Path;

const TOTAL: u32 = 10_000;
const TAIL: u32 = 3_000;

/// The fixed-seed generator of the sample: the same on every machine.
use rattle::sensitivity::stats::SplitMix as Mix;

fn group(code: i32) -> Option<&'static str> {
    match Class::from_code(code) {
        Class::Chaotic => Some("chaotic"),
        Class::Periodic(_) => Some("periodic"),
        Class::QuasiPeriodic => Some("quasi_periodic"),
        Class::Unresolved => Some("unresolved"),
        _ => None,
    }
}

/// The judge's verdict: (class name, period, tangent exponent, two-trajectory exponent,
/// Birkhoff digits).
fn judge(p: &Params<f64>, plain: &Settings, y0: [f64; 4]) -> (String, u32, f64, f64, f64) {
    let settings = Settings {
        lyapunov: true,
        ..*plain
    };
    let it = Integrator::<f64>::new(p, &settings);
    let mut st = it.start(y0);
    for _ in 0..TOTAL - TAIL {
        it.period(&mut st);
    }
    // The reference run over the tail, with the tangent vector.
    let mut copy = st;
    let r = it.sample(&mut copy, TAIL);
    if r.diag.nonfinite {
        return ("failed".into(), 0, f64::NAN, f64::NAN, f64::NAN);
    }
    if r.sample_impacts == 0 {
        return ("no_impact".into(), 0, f64::NAN, f64::NAN, f64::NAN);
    }
    let s = &r.samples;
    let (lo, hi) = s
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x[0]), b.max(x[0]))
        });
    let tol = 1e-7 * (hi - lo).max(1.0);
    let len = s.len();
    let lag = (1..=128usize)
        .find(|&n| (len - 256..len).all(|k| (0..4).all(|c| (s[k][c] - s[k - n][c]).abs() <= tol)));
    if let Some(n) = lag {
        let start = PointState {
            y: r.final_y,
            mode: r.final_mode,
            diag: Default::default(),
        };
        let c = refine(&it, &start, n as u32);
        if c.is_stable() {
            return (
                format!("period-{}", c.period),
                c.period,
                r.lyapunov,
                f64::NAN,
                f64::NAN,
            );
        }
    }
    // Second estimator: a neighbour 1e-8 away in y1, renormalised each period.
    let period = 2.0 * std::f64::consts::PI / p.eta;
    let plain = Integrator::<f64>::new(p, plain);
    let d0 = 1e-8;
    let (mut a, mut b) = (st, st);
    b.y[0] += d0;
    let mut logs = 0.0;
    for _ in 0..TAIL {
        plain.period(&mut a);
        plain.period(&mut b);
        let d = (0..4)
            .map(|i| (a.y[i] - b.y[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        logs += (d / d0).ln();
        for i in 0..4 {
            b.y[i] = a.y[i] + (b.y[i] - a.y[i]) * d0 / d;
        }
        b.mode = a.mode;
    }
    let two = logs / (f64::from(TAIL) * period);
    let mut wb = Birkhoff::new(TAIL);
    s.iter().for_each(|x| wb.push(x[0]));
    let digits = wb.digits();
    let l = r.lyapunov;
    let class = if l > 0.002 && two > 0.002 {
        "chaotic"
    } else if l.abs() < 0.001 && two.abs() < 0.001 && digits >= 8.0 {
        "quasi_periodic"
    } else {
        "unclear"
    };
    (class.into(), 0, l, two, digits)
}

fn main() -> anyhow::Result<()> {
    let a: Vec<String> = std::env::args().collect();
    anyhow::ensure!(
        a.len() == 6,
        "usage: judge CONFIG CLASS_NPY PER_CLASS SEED OUT_CSV"
    );
    let cfg = Config::load(Path::new(&a[1]), &[])?;
    let bytes = std::fs::read(&a[2])?;
    let classes: Vec<i32> = npyz::NpyFile::new(&bytes[..])?.into_vec()?;
    let (how, count) = a[3].split_at(1);
    let count: usize = count.parse()?;
    let mut rng = Mix(a[4].parse()?);
    let (nx, ny) = (cfg.map.x_points as usize, cfg.map.y_points as usize);
    anyhow::ensure!(
        classes.len() == nx * ny,
        "the class array is not the config's grid"
    );
    let xs = Config::map_axis(cfg.map.x_from, cfg.map.x_to, cfg.map.x_points);
    let ys = Config::map_axis(cfg.map.y_from, cfg.map.y_to, cfg.map.y_points);
    let settings = cfg.settings();
    let mut picked: Vec<(usize, &str)> = Vec::new();
    let groups: &[&str] = if how == "u" {
        &["any"]
    } else {
        &["chaotic", "periodic", "quasi_periodic", "unresolved"]
    };
    for &g in groups {
        let mut cells: Vec<usize> = (0..classes.len())
            .filter(|&c| g == "any" || group(classes[c]) == Some(g))
            .collect();
        // Fisher-Yates with the fixed generator, then the first `count`.
        for i in (1..cells.len()).rev() {
            let j = (rng.next_u64() % (i as u64 + 1)) as usize;
            cells.swap(i, j);
        }
        picked.extend(
            cells
                .into_iter()
                .take(count)
                .map(|c| (c, group(classes[c]).unwrap_or("other"))),
        );
    }
    let rows: Vec<String> = {
        use rayon::prelude::*;
        picked
            .par_iter()
            .map(|&(c, g)| {
                let (ix, iy) = (c % nx, c / nx);
                let mut p = cfg.params();
                cfg.map.x.set(&mut p, xs[ix]);
                cfg.map.y.set(&mut p, ys[iy]);
                let (class, period, l, two, digits) = judge(&p, &settings, cfg.initial.y);
                format!(
                    "{ix},{iy},{:.9},{:.9},{g},{class},{period},{l:.6},{two:.6},{digits:.2}",
                    xs[ix], ys[iy]
                )
            })
            .collect()
    };
    let mut f = std::fs::File::create(&a[5])?;
    writeln!(
        f,
        "ix,iy,x,y,map_group,judge,judge_period,lyapunov_tangent,lyapunov_two_trajectories,birkhoff_digits"
    )?;
    for r in rows {
        writeln!(f, "{r}")?;
    }
    Ok(())
}
