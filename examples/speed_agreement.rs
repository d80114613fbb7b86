//! Speed against agreement of the sensitivity maps `configs/r_lambda.toml` (n x n cells),
//! `configs/eta_lambda.toml` (2n x n cells, Coulomb friction up to lambda = 0.1) and the
//! stick-slip map `configs/stribeck_eta_r.toml` (n x n/2 cells): brute force, early termination, and early
//! termination with coarse-to-fine refinement at three coarse spacings. Agreement = share of
//! cells whose class equals the brute-force map's. Writes OUT-MAP.csv, .png and .svg per map.
//!
//! `cargo run --release --example speed_agreement -- [n] [OUT] [cpu|gpu]`
//! (default 160, speed_agreement, cpu)

use rattle::class::Class;
use rattle::config::{Backend, Config};
use rattle::engine::Engine;
use rattle::map::{MapOptions, run};
use rattle::output::with_suffix;
use rattle::progress::Silent;
use rattle::render::{LinePlot, Scale, Series, line_plot_png, line_plot_svg};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let n: u32 = args.get(1).map_or(Ok(160), |s| s.parse())?;
    let out = args
        .get(2)
        .map_or("speed_agreement", String::as_str)
        .to_string();
    let backend = match args.get(3).map(String::as_str) {
        None | Some("cpu") => Backend::Cpu,
        Some("gpu") => Backend::Gpu,
        Some(b) => anyhow::bail!("backend must be cpu or gpu, not {b}"),
    };
    let dir = std::env::temp_dir().join(format!("rattle-speed-agreement-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let engine = Engine::open(backend)?;
    let device = engine.device();
    for (map, title, nx, ny) in [
        ("r_lambda", "Speed against agreement: R x lambda", n, n),
        (
            "eta_lambda",
            "Speed against agreement: eta x lambda",
            2 * n,
            n,
        ),
        (
            "stribeck_eta_r",
            "Speed against agreement: Stribeck, eta x R",
            n,
            n / 2,
        ),
    ] {
        let n = ny;
        let rows = measure(&engine, &dir, map, nx, n)?;
        let mut w = csv::Writer::from_path(format!("{out}-{map}.csv"))?;
        w.write_record([
            "method",
            "seconds",
            "agreement",
            "cells_equal",
            "cells",
            "device",
        ])?;
        for (name, secs, agree, same, cells) in &rows {
            w.write_record([
                name.to_string(),
                format!("{secs:.2}"),
                format!("{agree:.6}"),
                same.to_string(),
                cells.to_string(),
                device.clone(),
            ])?;
        }
        w.flush()?;
        let series: Vec<Series> = rows
            .iter()
            .enumerate()
            .map(|(i, (name, secs, agree, _, _))| Series {
                label: name.to_string(),
                points: vec![(*secs, 100.0 * agree)],
                color_index: i,
                dashed: false,
            })
            .collect();
        let title = format!("{title} ({nx} x {n} cells)");
        // The adapter's short name ("llvmpipe", "NVIDIA H100 ...") keeps the label on the chart.
        let short = device.split(" (").next().unwrap_or(&device);
        let x_label = format!("wall time (s), {short}");
        let plot = LinePlot {
            title: &title,
            x_label: &x_label,
            y_label: "cells with the brute-force class (%)",
            x_scale: Scale::Linear,
            y_scale: Scale::Linear,
            series: &series,
            width: 1100,
            height: 700,
        };
        let stem = PathBuf::from(format!("{out}-{map}"));
        line_plot_png(&stem.with_extension("png"), &plot)?;
        line_plot_svg(&stem.with_extension("svg"), &plot)?;
        let caption = caption(map, nx, n, &device, &rows);
        std::fs::write(
            stem.with_extension("json"),
            serde_json::to_string_pretty(&serde_json::json!({ "caption": caption }))?,
        )?;
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

/// The chart's caption: what was computed, how, and what to notice.
fn caption(map: &str, nx: u32, ny: u32, device: &str, rows: &[Row]) -> String {
    let parts: Vec<String> = rows
        .iter()
        .map(|(name, secs, agree, _, _)| format!("{name} {secs:.1} s, {:.2}%", 100.0 * agree))
        .collect();
    format!(
        "Speed against agreement for `configs/{map}.toml` at {nx} x {ny} cells (f32, {device}): \
         the wall time of each way to compute the map (brute force: every cell all its \
         periods; early termination: cells leave once Newton confirms their cycle; + refine K: \
         a coarse grid of spacing K, refined only where corners differ or lie near a \
         threshold) against the share of cells whose class equals the brute-force map's. \
         {}. One point per method and run (linear axes: the values span less than a decade); \
         the cells that differ sit on class boundaries and in chaotic bands (listed by class \
         pair when the example runs). Line chart, PNG 1100 x 700 px with an SVG twin.",
        parts.join("; ")
    )
}

/// One way to compute the map: (method, seconds, agreement, cells equal, cells).
type Row = (&'static str, f64, f64, usize, usize);

/// The rows of every way to compute the map.
fn measure(engine: &Engine, dir: &Path, map: &str, nx: u32, ny: u32) -> anyhow::Result<Vec<Row>> {
    let cases: [(&str, bool, Option<usize>); 5] = [
        ("brute force", false, None),
        ("early termination", true, None),
        ("early termination + refine 8", true, Some(8)),
        ("early termination + refine 4", true, Some(4)),
        ("early termination + refine 2", true, Some(2)),
    ];
    let mut rows = Vec::new();
    let mut reference: Option<Vec<i32>> = None;
    for (name, early, refine) in cases {
        let cfg = Config::load(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("configs/{map}.toml")),
            &[
                format!("map.x_points={nx}"),
                format!("map.y_points={ny}"),
                format!("run.early_stop={early}"),
            ],
        )?;
        let prefix = dir.join(format!("{map}-{}", name.replace([' ', '+'], "_")));
        let opts = MapOptions {
            starts: 1,
            refine,
            ..Default::default()
        };
        let t = Instant::now();
        run(engine, &cfg, &prefix, &opts, &Silent)?;
        let secs = t.elapsed().as_secs_f64();
        let class = read_i32(&with_suffix(&prefix, "class.npy"))?;
        let reference = reference.get_or_insert_with(|| class.clone());
        let same = class
            .iter()
            .zip(reference.iter())
            .filter(|(a, b)| a == b)
            .count();
        let agreement = same as f64 / class.len() as f64;
        println!(
            "{map} {name}: {secs:.2} s, classes equal at {same}/{} ({:.3}%)",
            class.len(),
            100.0 * agreement
        );
        // Which classes the differing cells have (brute force -> this method), most frequent first.
        let mut pairs = std::collections::BTreeMap::<(String, String), usize>::new();
        for (a, b) in reference.iter().zip(&class).filter(|(a, b)| a != b) {
            let key = (Class::from_code(*a).name(), Class::from_code(*b).name());
            *pairs.entry(key).or_default() += 1;
        }
        let mut pairs: Vec<_> = pairs.into_iter().collect();
        pairs.sort_by_key(|p| std::cmp::Reverse(p.1));
        for ((a, b), k) in pairs.iter().take(8) {
            println!("    {k:>5}  {a} -> {b}");
        }
        rows.push((name, secs, agreement, same, class.len()));
    }
    Ok(rows)
}

fn read_i32(path: &Path) -> anyhow::Result<Vec<i32>> {
    let bytes = std::fs::read(path)?;
    Ok(npyz::NpyFile::new(&bytes[..])?.into_vec::<i32>()?)
}
