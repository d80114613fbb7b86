//! How far a point lies from each sheet of a volume's surfaces (`PREFIX-surfaces.ply`, written
//! by `rattle map --boundaries` on a volume): the least distance, in parameter values, from the
//! point to the sheet's triangles, for the sheets of one type code (0: period doubling, as the
//! PLY's comments list) and period, nearest first.
//!
//! `cargo run --release --example sheet_distance -- PLY X Y Z [TYPE PERIOD]`
//! e.g. `... -- atlas-surfaces.ply 0.6 0.02 1.37059 0 1`: Fig. 2's period doubling.

use std::collections::BTreeMap;

fn main() -> anyhow::Result<()> {
    let a: Vec<String> = std::env::args().collect();
    anyhow::ensure!(
        a.len() == 5 || a.len() == 7,
        "usage: sheet_distance PLY X Y Z [TYPE PERIOD]"
    );
    let text = std::fs::read_to_string(&a[1])?;
    let p: Vec<f64> = a[2..5]
        .iter()
        .map(|v| v.parse())
        .collect::<Result<_, _>>()?;
    let only: Option<(f64, f64)> = match a.len() {
        7 => Some((a[5].parse()?, a[6].parse()?)),
        _ => None,
    };
    let mut lines = text.lines();
    let mut counts = Vec::new();
    for line in lines.by_ref() {
        if let ["element", _, n] = line.split_whitespace().collect::<Vec<_>>()[..] {
            counts.push(n.parse::<usize>()?);
        }
        if line == "end_header" {
            break;
        }
    }
    anyhow::ensure!(counts.len() == 2, "not a surfaces PLY: {}", a[1]);
    let row = |l: &str| -> Vec<f64> {
        l.split_whitespace()
            .filter_map(|v| v.parse().ok())
            .collect()
    };
    let verts: Vec<Vec<f64>> = lines.by_ref().take(counts[0]).map(row).collect();
    let mut best: BTreeMap<u32, (f64, usize, f64, f64)> = BTreeMap::new();
    for f in lines.take(counts[1]).map(row) {
        let (ty, period, sheet) = (f[4], f[5], f[6] as u32);
        if only.is_some_and(|o| o != (ty, period)) {
            continue;
        }
        let t: Vec<[f64; 3]> = f[1..4]
            .iter()
            .map(|&i| {
                let v = &verts[i as usize];
                [v[0], v[1], v[2]]
            })
            .collect();
        let d = rattle::map::surfaces::distance([p[0], p[1], p[2]], [t[0], t[1], t[2]]);
        let e = best.entry(sheet).or_insert((f64::INFINITY, 0, ty, period));
        e.0 = e.0.min(d);
        e.1 += 1;
    }
    let mut rows: Vec<_> = best.into_iter().collect();
    rows.sort_by(|a, b| a.1.0.total_cmp(&b.1.0));
    println!("sheet,type,period,triangles,distance");
    for (sheet, (d, n, ty, period)) in rows {
        println!("{sheet},{ty},{period},{n},{d:.3e}");
    }
    Ok(())
}
