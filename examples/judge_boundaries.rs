//! The independent judge of a map's located boundary points (`rattle map --boundaries`): for
//! a fixed-seed sample of located points, the reference of `rattle::reference::dry` (exact
//! motion between events under Coulomb friction; no code of the integrator, the classifier or
//! Newton's method) runs on each side of the point, a quarter of a cell away along the edge,
//! from that side's cell's final state (the map's `state` layer), and says whether the side's
//! attractor is the one the map put there.
//!
//! `cargo run --release --example judge_boundaries -- CONFIG PREFIX COUNT SEED`
//!
//! A located point is where the cycle of period n (the point's `period`) continued from one
//! side stops being stable. Right: on that side the reference settles on a cycle whose sections
//! repeat at lag n and at no shorter lag (2 x 10^4 periods, then 256 sections to 1e-6 of their
//! scale), and on the other side not at lag n; for a period doubling, at lag 2n there (n/2
//! where the doubled cycle was continued), and
//! beyond a Neimark-Sacker point at no lag <= 128 (a torus), the kinds' local signatures. The
//! cells' own classes, half a cell from the edge, can differ from what holds a quarter of a
//! cell from the point (a period-doubling cascade to chaos within the cell): they are printed,
//! not judged. Prints one line per point and the share of points judged right.

use rattle::config::Config;
use rattle::reference::dry::DryReference;
use std::path::Path;

fn main() -> anyhow::Result<()> {
    let a: Vec<String> = std::env::args().collect();
    anyhow::ensure!(
        a.len() == 5,
        "usage: judge_boundaries CONFIG PREFIX COUNT SEED"
    );
    let cfg = Config::load(Path::new(&a[1]), &[])?;
    let prefix = &a[2];
    let count: usize = a[3].parse()?;
    let mut rng = rattle::stats::SplitMix(a[4].parse()?);
    let b: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(format!(
        "{prefix}-boundaries.json"
    ))?)?;
    let bytes = std::fs::read(format!("{prefix}-state.npy"))?;
    let state: Vec<f64> = npyz::NpyFile::new(&bytes[..])?.into_vec()?;
    let m = &cfg.map;
    let xs = Config::map_axis(m.x_from, m.x_to, m.x_points);
    let ys = Config::map_axis(m.y_from, m.y_to, m.y_points);
    let zeno = cfg.settings().zeno_speed;
    let mut located: Vec<&serde_json::Value> = b["points"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["located"] == true)
        .collect();
    // Fisher-Yates with the fixed generator, then the first `count`.
    for i in (1..located.len()).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        located.swap(i, j);
    }
    located.truncate(count);
    let judge = |p: &serde_json::Value| -> [(String, Option<usize>); 2] {
        let cells = [0, 1].map(|k| p["cells"][k].as_u64().unwrap() as usize);
        let along_x = cells[1] == cells[0] + 1;
        let (x, y) = (p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap());
        let quarter = if along_x {
            0.25 * (xs[1] - xs[0])
        } else {
            0.25 * (ys[1] - ys[0])
        };
        [0, 1].map(|side| {
            let sign = if side == 0 { -1.0 } else { 1.0 };
            let (px, py) = if along_x {
                (x + sign * quarter, y)
            } else {
                (x, y + sign * quarter)
            };
            let mut params = cfg.params();
            m.x.set(&mut params, px);
            m.y.set(&mut params, py);
            let class = p["classes"][side].as_str().unwrap().to_string();
            let cell = cells[side];
            let r = match DryReference::new(&params, 1024, zeno) {
                Ok(r) => r,
                Err(_) => return (class, None),
            };
            let mut y0 = [0.0; 4];
            y0.copy_from_slice(&state[4 * cell..4 * cell + 4]);
            let mut st = r.start(y0);
            let run = r
                .run(&mut st, 20_000, None)
                .and_then(|_| r.run(&mut st, 256, None));
            let Ok(s) = run else {
                return (class, None);
            };
            let scale = s.iter().flatten().fold(1.0f64, |a, v| a.max(v.abs()));
            let lag = (1..=128).find(|&n| {
                (n..s.len()).all(|k| (0..4).all(|c| (s[k][c] - s[k - n][c]).abs() < 1e-6 * scale))
            });
            (class, lag)
        })
    };
    // The side the cycle was continued from: the one whose class has the point's period.
    let right = |p: &serde_json::Value, v: &[(String, Option<usize>); 2]| -> bool {
        let n = p["period"].as_u64().unwrap() as usize;
        let name = format!("period-{n}");
        let Some(from) = (0..2).find(|&k| v[k].0 == name) else {
            return false;
        };
        let other = v[1 - from].1;
        let kind = match p["type"].as_str().unwrap() {
            // From the single side the cycle doubles; from the doubled side (n even) it
            // merges into the cycle of half its period.
            "period_doubling" => {
                other == Some(2 * n) || (n.is_multiple_of(2) && other == Some(n / 2))
            }
            "neimark_sacker" => other.is_none(),
            _ => true,
        };
        v[from].1 == Some(n) && other != Some(n) && kind
    };
    let verdicts: Vec<_> = {
        use rayon::prelude::*;
        located.par_iter().map(|p| judge(p)).collect()
    };
    let mut both = 0;
    for (p, v) in located.iter().zip(&verdicts) {
        let ok = right(p, v);
        both += usize::from(ok);
        println!(
            "{} at ({:.6}, {:.6}): {} | {}: lags {:?} | {:?} {}",
            p["type"].as_str().unwrap(),
            p["x"].as_f64().unwrap(),
            p["y"].as_f64().unwrap(),
            v[0].0,
            v[1].0,
            v[0].1,
            v[1].1,
            if ok { "right" } else { "WRONG" }
        );
    }
    println!(
        "{both} of {} located points judged right ({:.1}%)",
        located.len(),
        100.0 * both as f64 / located.len().max(1) as f64
    );
    Ok(())
}
