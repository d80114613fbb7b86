//! The independent judge of a map's classes: long runs of a sample of cells by the reference of
//! `rattle::reference::dry` (exact motion between events under Coulomb friction, Dormand-Prince
//! under Stribeck friction; no code of the integrator or of the classifier), written as the
//! fixture that tests/classes.rs scores the map's classes against.
//!
//! `cargo run --release --example judge -- CONFIG CLASS_NPY SAMPLE SEED OUT_CSV`
//!
//! `rejudge:FIXTURE.csv` as SAMPLE re-judges the rows of an earlier fixture whose verdict was
//! `chaotic`, `unclear` or a period above 1 (the rule below for chaos once returned at the first
//! chaotic window, 3000 periods in: a chaotic transient then passed for chaos; the rule for a
//! period once took a slowly converging cycle for one of twice its period) and keeps the other
//! rows as they are (period 1, quasi-periodic and impact-free verdicts are final when reached).
//!
//! CLASS_NPY is a map's `PREFIX-class.npy` over the config's [map] grid (`-` with `rejudge:`). SAMPLE `s30` draws 30
//! cells of each map class group (chaotic, periodic of period 1-4, periodic of period 5 or more,
//! quasi-periodic, unresolved; fewer where the map has fewer), `u100` 100 cells uniformly over
//! the grid, with a fixed-seed generator; `cells:FILE.csv` judges the cells (ix, iy) of an
//! earlier fixture again. Each cell is judged from the map's start state:
//! - a run of 2000 periods, then windows of 1300 sampled periods (up to 3 x 10^4 periods in all)
//!   until one decides a periodic, quasi-periodic or impact-free motion; chaos is the verdict of
//!   the last window only (a chaotic transient can end tens of thousands of periods in);
//! - periodic: the window's last 256 sections repeat with the smallest lag n <= 1024 to 1e-9 of
//!   max(1, range), and a neighbour 1e-8 away converges onto it (a negative exponent); a cycle
//!   that still converges slowly (its alternating part repeats at twice the lag sooner: the
//!   difference at a proper divisor of the lag still halves or more over the window) waits
//!   for a later window;
//! - chaotic: the two-trajectory exponent (a neighbour 1e-8 away in y1, renormalised every
//!   period) exceeds 0.002 per unit time over the window and over each of its halves;
//! - quasi-periodic: that exponent is within 0.0002 of zero (a slowly contracting cycle, with
//!   exponents of -0.0005 and below, waits), weighted Birkhoff averages of y1 over the window's
//!   two halves agree to 8 digits, and no lag <= 1024 repeats to 1e-6;
//! - no_impact: no impact in the window; failed: the reference could not follow the motion;
//! - anything else after 3 x 10^4 periods is `unclear` (left out of the score).

use rattle::config::Config;
use rattle::model::Params;
use rattle::reference::dry::{DryReference, RefState};
use std::io::Write;
use std::path::Path;

/// Scan points per period of the reference (its states agree with 8192 to 3e-14 over a period,
/// tests/stickslip.rs).
const SCAN: u32 = 1024;
const FIRST: u32 = 2000;
const WINDOW: u32 = 1300;
const TOTAL: u32 = 30_000;
/// The longest period judged: a window's last 256 sections compared at lags up to this (the
/// window of 1300 holds them).
const MAX_LAG: usize = 1024;

/// The fixed-seed generator of the sample: the same on every machine.
use rattle::stats::SplitMix as Mix;

fn group(code: i32) -> Option<&'static str> {
    match code {
        -4 => Some("chaotic"),
        1..=4 => Some("periodic"),
        5.. => Some("long_periodic"),
        -3 => Some("quasi_periodic"),
        -5 => Some("unresolved"),
        _ => None,
    }
}

/// Weighted Birkhoff average of `x` (the smooth bump weight), the judge's own.
fn birkhoff(x: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (mut num, mut den) = (0.0, 0.0);
    for (k, v) in x.iter().enumerate() {
        let t = (k as f64 + 0.5) / n;
        let w = (-1.0 / (t * (1.0 - t))).exp();
        num += w * v;
        den += w;
    }
    num / den
}

/// A verdict: (class, period, exponent over the window, over its first half, Birkhoff digits).
type Verdict = (String, u32, f64, f64, f64);

fn judge(p: &Params<f64>, zeno: f64, y0: [f64; 4]) -> Verdict {
    let failed = |e: rattle::reference::ReferenceError| -> Verdict {
        eprintln!("eta {} R {} fs {}: {e}", p.eta, p.restitution, p.fs);
        ("failed".into(), 0, f64::NAN, f64::NAN, f64::NAN)
    };
    let r = match DryReference::new(p, SCAN, zeno) {
        Ok(r) => r,
        Err(e) => return failed(e),
    };
    let mut st = r.start(y0);
    if let Err(e) = r.run(&mut st, FIRST, None) {
        return failed(e);
    }
    let mut done = FIRST;
    let mut last = ("unclear".to_string(), 0, f64::NAN, f64::NAN, f64::NAN);
    while done < TOTAL {
        match window(&r, &mut st) {
            Ok(v) => {
                // Chaos may be a transient: only the last window's says it lasts.
                if v.0 != "unclear" && v.0 != "chaotic" {
                    return v;
                }
                last = v;
            }
            Err(e) => return failed(e),
        }
        done += WINDOW;
    }
    last
}

/// The verdicts of `k` starts 1e-9 apart in y1 around `y0`, as `verdict:count` joined by `;`.
fn outcomes(p: &Params<f64>, zeno: f64, y0: [f64; 4], k: u32) -> String {
    let mut seen: Vec<(String, u32)> = Vec::new();
    for j in 1..=k {
        let mut y = y0;
        y[0] += f64::from(j) * 1e-9;
        let v = judge(p, zeno, y).0;
        match seen.iter_mut().find(|s| s.0 == v) {
            Some(s) => s.1 += 1,
            None => seen.push((v, 1)),
        }
    }
    seen.iter()
        .map(|(v, n)| format!("{v}:{n}"))
        .collect::<Vec<_>>()
        .join(";")
}

/// One window of WINDOW periods from `st` (which it advances), with its neighbour.
fn window(
    r: &DryReference,
    st: &mut RefState,
) -> Result<Verdict, rattle::reference::ReferenceError> {
    let d0 = 1e-8;
    let mut b = *st;
    b.y[0] += d0;
    let (mut logs, mut first) = (0.0, 0.0);
    let mut samples = Vec::with_capacity(WINDOW as usize);
    let mut impacts = 0usize;
    let mut log = Vec::new();
    for k in 0..WINDOW {
        log.clear();
        r.period_from(st, 0.0, Some(&mut log))?;
        impacts += log.iter().filter(|e| e.kind.starts_with("impact")).count();
        r.period_from(&mut b, 0.0, None)?;
        let d = (0..4)
            .map(|i| (st.y[i] - b.y[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        let l = (d / d0).ln();
        logs += l;
        if k < WINDOW / 2 {
            first += l;
        }
        // Renormalise; a neighbour that collapsed onto the state (a stick removes directions)
        // restarts 1e-8 away in y1.
        if d > 0.0 {
            for i in 0..4 {
                b.y[i] = st.y[i] + (b.y[i] - st.y[i]) * d0 / d;
            }
        } else {
            b.y = st.y;
            b.y[0] += d0;
        }
        b.mode = st.mode;
        samples.push(st.y);
    }
    let t = r.period();
    let lyap = logs / (f64::from(WINDOW) * t);
    let lyap1 = first / (f64::from(WINDOW / 2) * t);
    let lyap2 = (logs - first) / (f64::from(WINDOW / 2) * t);
    let x: Vec<f64> = samples.iter().map(|s| s[0]).collect();
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let (a, b) = (birkhoff(&x[..x.len() / 2]), birkhoff(&x[x.len() / 2..]));
    let digits = -((a - b).abs() / (hi - lo).max(1e-300)).max(1e-16).log10();
    if impacts == 0 {
        return Ok(("no_impact".into(), 0, lyap, lyap1, digits));
    }
    let len = samples.len();
    let lag = |tol: f64| {
        let tol = tol * (hi - lo).max(1.0);
        (1..=MAX_LAG.min(len - 256)).find(|&n| {
            (len - 256..len)
                .all(|k| (0..4).all(|c| (samples[k][c] - samples[k - n][c]).abs() <= tol))
        })
    };
    // The largest difference at lag `d` over the sections `k0..k0 + 256`.
    let spread = |d: usize, k0: usize| {
        (k0..k0 + 256)
            .flat_map(|k| (0..4).map(move |c| (k, c)))
            .map(|(k, c)| (samples[k][c] - samples[k - d][c]).abs())
            .fold(0.0f64, f64::max)
    };
    // A cycle of period d whose multiplier is near -1 (or a complex pair near the unit circle)
    // converges so slowly that its sections repeat to 1e-9 at a multiple of d sooner than at d:
    // while the difference at a proper divisor d still shrinks over the window (to half or less
    // from its first 256 sections to its last), the motion is converging onto period d, not
    // on a cycle of the longer period, and the verdict waits for a later window.
    let converging = |n: usize| {
        (1..n)
            .filter(|&d| n.is_multiple_of(d))
            .any(|d| spread(d, len - 256) < 0.5 * spread(d, n))
    };
    let class = if let Some(n) = lag(1e-9).filter(|_| lyap < 0.0) {
        if converging(n) {
            return Ok(("unclear".into(), 0, lyap, lyap1, digits));
        }
        return Ok((format!("period-{n}"), n as u32, lyap, lyap1, digits));
    } else if lyap > 0.002 && lyap1 > 0.002 && lyap2 > 0.002 {
        "chaotic"
    } else if lyap.abs() < 2e-4 && digits >= 8.0 && lag(1e-6).is_none() {
        "quasi_periodic"
    } else {
        "unclear"
    };
    Ok((class.into(), 0, lyap, lyap1, digits))
}

fn main() -> anyhow::Result<()> {
    let a: Vec<String> = std::env::args().collect();
    anyhow::ensure!(
        a.len() == 6,
        "usage: judge CONFIG CLASS_NPY SAMPLE SEED OUT_CSV"
    );
    let cfg = Config::load(Path::new(&a[1]), &[])?;
    let (nx, ny) = (cfg.map.x_points as usize, cfg.map.y_points as usize);
    // `-`: no class array (a `rejudge:` takes each row's group from the fixture).
    let classes: Vec<i32> = if a[2] == "-" {
        vec![0; nx * ny]
    } else {
        let bytes = std::fs::read(&a[2])?;
        npyz::NpyFile::new(&bytes[..])?.into_vec()?
    };
    anyhow::ensure!(
        classes.len() == nx * ny,
        "the class array is not the config's grid"
    );
    let xs = Config::map_axis(cfg.map.x_from, cfg.map.x_to, cfg.map.x_points);
    let ys = Config::map_axis(cfg.map.y_from, cfg.map.y_to, cfg.map.y_points);
    let zeno = cfg.settings().zeno_speed;
    let name = |c: usize| group(classes[c]).unwrap_or("other");
    let mut picked: Vec<(usize, &str)> = Vec::new();
    // Rows of an earlier fixture kept as they are (`rejudge:`), by cell.
    let mut kept: std::collections::HashMap<usize, String> = Default::default();
    let mut order: Vec<usize> = Vec::new();
    if let Some(file) = a[3].strip_prefix("rejudge:") {
        let mut r = csv::Reader::from_path(file)?;
        for row in r.records() {
            let row = row?;
            let c = row[1].parse::<usize>()? * nx + row[0].parse::<usize>()?;
            order.push(c);
            let rerun = &row[5] == "chaotic"
                || &row[5] == "unclear"
                || row[5].strip_prefix("period-").is_some_and(|n| n != "1");
            if rerun {
                let g: &str = match &row[4] {
                    "chaotic" => "chaotic",
                    "periodic" => "periodic",
                    "long_periodic" => "long_periodic",
                    "quasi_periodic" => "quasi_periodic",
                    "unresolved" => "unresolved",
                    "any" => "any",
                    _ => "other",
                };
                picked.push((c, g));
            } else {
                kept.insert(c, row.iter().collect::<Vec<_>>().join(","));
            }
        }
    } else if let Some(file) = a[3].strip_prefix("cells:") {
        let mut r = csv::Reader::from_path(file)?;
        for row in r.records() {
            let row = row?;
            let c = row[1].parse::<usize>()? * nx + row[0].parse::<usize>()?;
            picked.push((c, name(c)));
        }
    } else {
        let (how, count) = a[3].split_at(1);
        let count: usize = count.parse()?;
        let mut rng = Mix(a[4].parse()?);
        let groups: &[&str] = if how == "u" {
            &["any"]
        } else {
            &[
                "chaotic",
                "periodic",
                "long_periodic",
                "quasi_periodic",
                "unresolved",
            ]
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
            picked.extend(cells.into_iter().take(count).map(|c| (c, name(c))));
        }
    }
    // JUDGE_STARTS=K: each cell judged again from K starts 1e-9 apart in y1 (a column
    // `outcomes`: each verdict reached and how often). Where a chaotic transient ends on one of
    // several attractors, which one a start reaches is beyond any integrator's reach after a
    // few hundred periods: the verdicts from nearby starts say which outcomes a map may name.
    let spread: u32 = std::env::var("JUDGE_STARTS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    let rows: Vec<(usize, String)> = {
        use rayon::prelude::*;
        picked
            .par_iter()
            .map(|&(c, g)| {
                let (ix, iy) = (c % nx, c / nx);
                let mut p = cfg.params();
                cfg.map.x.set(&mut p, xs[ix]);
                cfg.map.y.set(&mut p, ys[iy]);
                let (class, period, l, l1, digits) = judge(&p, zeno, cfg.initial.y);
                let mut row = format!(
                    "{ix},{iy},{:.9},{:.9},{g},{class},{period},{l:.6},{l1:.6},{digits:.2}",
                    xs[ix], ys[iy]
                );
                if spread > 0 {
                    row.push(',');
                    row.push_str(&outcomes(&p, zeno, cfg.initial.y, spread));
                }
                (c, row)
            })
            .collect()
    };
    // A re-judged fixture keeps its rows' order.
    let rows: Vec<String> = if order.is_empty() {
        rows.into_iter().map(|r| r.1).collect()
    } else {
        let mut new: std::collections::HashMap<usize, String> = rows.into_iter().collect();
        order
            .iter()
            .map(|c| kept.remove(c).or_else(|| new.remove(c)).expect("every row"))
            .collect()
    };
    let mut f = std::fs::File::create(&a[5])?;
    writeln!(
        f,
        "ix,iy,x,y,map_group,judge,judge_period,lyapunov,lyapunov_first_half,birkhoff_digits{}",
        if spread > 0 { ",outcomes" } else { "" }
    )?;
    for r in rows {
        writeln!(f, "{r}")?;
    }
    Ok(())
}
