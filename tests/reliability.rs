//! No silently wrong map: run identity of parts and checkpoints, impossible part contents,
//! memory bounds, outputs that belong together.

use std::path::{Path, PathBuf};

mod common;
use common::{npy, ok, rattle, scratch};

/// 1 x 3 cells at eta = 1.33, R = 0.59: the middle cell has two attractors (see tests/map.rs).
const COEXIST: &str = "[model]\neta = 1.33\n[method]\nsteps_per_period = 64\n[run]\n\
    transient_periods = 300\nsample_periods = 50\n[map]\nx = \"R\"\nx_from = 0.58\n\
    x_to = 0.60\nx_points = 1\ny = \"lambda\"\ny_from = 0.085\ny_to = 0.115\ny_points = 3\n";

fn setup(name: &str) -> (common::Scratch, PathBuf) {
    let d = scratch(name);
    let cfg = d.join("c.toml");
    std::fs::write(&cfg, COEXIST).unwrap();
    (d, cfg)
}

fn map(cfg: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    rattle()
        .args(["map", "--backend", "cpu", "--precision", "f64", "--config"])
        .arg(cfg)
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

fn merge(parts: &[PathBuf], out: &Path) -> std::process::Output {
    rattle()
        .arg("merge")
        .args(parts)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs `cmd`, which must be refused before computing: exit 2 with every key in the message.
fn refused(cmd: &mut std::process::Command, keys: &[&str]) {
    let out = cmd.output().unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{cmd:?}: {err}");
    assert!(keys.iter().all(|k| err.contains(k)), "{cmd:?}: {err}");
}

#[test]
fn checkpoints_of_another_run_are_recomputed_not_reused() {
    let (d, cfg) = setup("ident-ckpt");
    let p = d.join("m");
    // Parts of a --starts 1 run under the names a 3-shard checkpoint uses.
    for i in 0..3 {
        let o = map(&cfg, &p, &["--starts", "1", "--shard", &format!("{i}/3")]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let o = map(&cfg, &p, &["--starts", "2", "--checkpoint", "3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("already done"), "{}", stderr(&o));
    let fresh = map(&cfg, &d.join("fresh"), &["--starts", "2"]);
    assert!(fresh.status.success());
    assert_eq!(npy::<u8>(&d.join("m-attractors.npy")), vec![1, 2, 1]);
    assert_eq!(
        std::fs::read(d.join("m-attractors.npy")).unwrap(),
        std::fs::read(d.join("fresh-attractors.npy")).unwrap()
    );
    // The same run resumed does reuse its parts.
    for i in 0..2 {
        ok(rattle()
            .args(["map", "--backend", "cpu", "--precision", "f64", "--config"])
            .arg(&cfg)
            .args(["--starts", "2", "--shard", &format!("{i}/3"), "--out"])
            .arg(d.join("r")));
    }
    let o = map(&cfg, &d.join("r"), &["--starts", "2", "--checkpoint", "3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        stderr(&o).matches("already done").count(),
        2,
        "{}",
        stderr(&o)
    );
}

#[test]
fn merge_refuses_parts_of_different_runs() {
    let (d, cfg) = setup("ident-merge");
    let p = d.join("m");
    let parts: Vec<PathBuf> = (0..3)
        .map(|i| {
            let starts = if i == 2 { "2" } else { "1" };
            let o = map(
                &cfg,
                &p,
                &["--starts", starts, "--shard", &format!("{i}/3")],
            );
            assert!(o.status.success(), "{}", stderr(&o));
            d.join(format!("m.part-{i}-of-3.json"))
        })
        .collect();
    let o = merge(&parts, &d.join("merged"));
    assert!(!o.status.success());
    assert!(stderr(&o).contains("m.part-2-of-3.json"), "{}", stderr(&o));
    assert!(stderr(&o).contains("starts"), "{}", stderr(&o));
    assert!(!d.join("merged-class.npy").exists());
    // Different N (or any other key) is another run too.
    let o = map(
        &cfg,
        &p,
        &["--set", "method.steps_per_period=128", "--shard", "2/3"],
    );
    assert!(o.status.success());
    let o = merge(&parts, &d.join("merged"));
    assert!(!o.status.success());
    assert!(stderr(&o).contains("config"), "{}", stderr(&o));
    // So is another precision.
    let o = rattle()
        .args(["map", "--backend", "cpu", "--precision", "f32", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(&p)
        .args(["--shard", "2/3"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let o = merge(&parts, &d.join("merged"));
    assert!(!o.status.success());
    assert!(stderr(&o).contains("m.part-2-of-3.json"), "{}", stderr(&o));
    assert!(!d.join("merged-class.npy").exists());
}

#[test]
fn impossible_part_contents_are_refused_with_the_file_name() {
    let (d, cfg) = setup("ident-edit");
    let p = d.join("m");
    for i in 0..3 {
        let o = map(&cfg, &p, &["--shard", &format!("{i}/3")]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let part = d.join("m.part-1-of-3.json");
    let original: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&part).unwrap()).unwrap();
    type Edit = fn(&mut serde_json::Value);
    let edits: [(&str, Edit); 4] = [
        ("class -99", |j| j["fields"]["class"][0] = (-99).into()),
        ("nonfinite next to a valid class", |j| {
            j["fields"]["nonfinite"][0] = 1.into()
        }),
        ("wrong array length", |j| {
            j["fields"]["impacts"]
                .as_array_mut()
                .unwrap()
                .push(3.into())
        }),
        ("attractors above starts", |j| {
            j["fields"]["attractors"][0] = 5.into()
        }),
    ];
    for (what, edit) in edits {
        let mut j = original.clone();
        edit(&mut j);
        std::fs::write(&part, serde_json::to_string(&j).unwrap()).unwrap();
        let parts: Vec<PathBuf> = (0..3)
            .map(|i| d.join(format!("m.part-{i}-of-3.json")))
            .collect();
        let o = merge(&parts, &d.join("merged"));
        assert!(!o.status.success(), "{what}: accepted");
        assert!(
            stderr(&o).contains("m.part-1-of-3.json"),
            "{what}: {}",
            stderr(&o)
        );
    }
}

#[test]
fn work_beyond_the_machine_memory_is_refused_before_computing() {
    let d = scratch("memory");
    // 1e7 points x 2 samples at N = 8: cheap to compute, but its per-point results, plot and
    // report need several GiB; with the available memory lowered to 1 GiB it must be refused
    // at once, naming the keys, and write nothing.
    let t = std::time::Instant::now();
    let o = rattle()
        .env("RATTLE_MEMORY_LIMIT", "1073741824")
        .args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(common::config("fig2.toml"))
        .args([
            "--set",
            "sweep.points=10000000",
            "--set",
            "run.sample_periods=2",
        ])
        .args([
            "--set",
            "run.transient_periods=0",
            "--set",
            "method.steps_per_period=8",
        ])
        .arg("--out")
        .arg(d.join("b"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("sweep.points") && e.contains("GiB"), "{e}");
    assert!(
        t.elapsed().as_secs_f64() < 20.0,
        "refused only after computing"
    );
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0);
    // A map whose fields do not fit is refused the same way.
    let o = rattle()
        .env("RATTLE_MEMORY_LIMIT", "1073741824")
        .args(["map", "--backend", "cpu", "--config"])
        .arg(common::config("r_lambda.toml"))
        .args(["--set", "map.x_points=8192", "--set", "map.y_points=8192"])
        .arg("--out")
        .arg(d.join("m"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("map.x_points x map.y_points"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0);
}

/// Peak resident memory (bytes, `VmHWM`) of a run that must succeed, read from /proc while it
/// runs: the high-water mark only grows, so the last reading before the exit holds the peak
/// unless it came in the run's last milliseconds (the peaks here come before the outputs are
/// written).
fn peak_resident(cmd: &mut std::process::Command) -> u64 {
    use std::process::Stdio;
    let mut child = cmd
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let status = format!("/proc/{}/status", child.id());
    let mut peak = 0;
    loop {
        if let Ok(s) = std::fs::read_to_string(&status) {
            let kb = s
                .lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok());
            peak = peak.max(kb.unwrap_or(0) * 1024);
        }
        if let Some(st) = child.try_wait().unwrap() {
            assert!(st.success(), "{cmd:?}");
            return peak;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
}

#[test]
fn the_memory_estimates_bound_the_growth_of_the_peak() {
    // The guard's estimates per map cell and per bifurcation point must bound what the peak
    // resident memory grows by per cell or point (the fixed part is the program and its
    // buffers); measured between two sizes, CPU, a cheap run.
    let d = scratch("peak");
    let cheap = [
        "--set",
        "run.transient_periods=2",
        "--set",
        "run.sample_periods=4",
        "--set",
        "method.steps_per_period=8",
    ];
    let map_peak = |n: usize, starts: &str| {
        peak_resident(
            rattle()
                .args(["map", "--backend", "cpu", "--starts", starts, "--config"])
                .arg(common::config("r_lambda.toml"))
                .args(cheap)
                .args(["--set", &format!("map.x_points={n}")])
                .args(["--set", &format!("map.y_points={n}")])
                .arg("--out")
                .arg(d.join(format!("m{n}-{starts}"))),
        )
    };
    for starts in [1usize, 2] {
        let (small, large) = (256usize, 640usize);
        let (a, b) = (
            map_peak(small, &starts.to_string()),
            map_peak(large, &starts.to_string()),
        );
        let per_cell = (b.saturating_sub(a)) as f64 / (large * large - small * small) as f64;
        let bound = rattle::memory::map_bytes_per_cell(starts) as f64;
        eprintln!("map, {starts} start(s): {per_cell:.0} B per cell, estimate {bound}");
        assert!(per_cell <= bound, "{per_cell} B per cell against {bound}");
    }
    let sweep_peak = |points: u32| {
        peak_resident(
            rattle()
                .args(["bifurcation", "--backend", "cpu", "--config"])
                .arg(common::config("fig2.toml"))
                .args(["--set", &format!("sweep.points={points}")])
                .args([
                    "--set",
                    "run.sample_periods=2",
                    "--set",
                    "run.transient_periods=0",
                ])
                .args(["--set", "method.steps_per_period=8", "--out"])
                .arg(d.join(format!("b{points}"))),
        )
    };
    let (a, b) = (sweep_peak(50_000), sweep_peak(250_000));
    let per_point = (b.saturating_sub(a)) as f64 / 200_000.0;
    let bound = rattle::memory::bifurcation_bytes_per_point(2) as f64;
    eprintln!("bifurcation: {per_point:.0} B per point, estimate {bound}");
    assert!(
        per_point <= bound,
        "{per_point} B per point against {bound}"
    );
}

#[test]
fn more_checkpoints_or_shards_than_cells_are_refused() {
    let (d, cfg) = setup("ckpt-count");
    for extra in [
        &["--checkpoint", "100000000"][..],
        &["--checkpoint", "4"][..],
        &["--shard", "0/4294967296"][..],
        &["--shard", "0/4", "--checkpoint", "2"][..],
    ] {
        let o = map(&cfg, &d.join("m"), extra);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("cells") || stderr(&o).contains("--shard"),
            "{extra:?}: {}",
            stderr(&o)
        );
    }
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1, "only the config");
}

fn bifurcation(out: &Path, points: u32) -> std::process::Command {
    let mut c = rattle();
    c.args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(common::config("fig2.toml"))
        .args(["--set", &format!("sweep.points={points}")])
        .args([
            "--set",
            "run.transient_periods=5",
            "--set",
            "run.sample_periods=4",
        ])
        .args(["--set", "method.steps_per_period=16"])
        .arg("--out")
        .arg(out);
    c
}

#[test]
fn concurrent_runs_on_one_prefix_leave_one_runs_whole_set() {
    let d = scratch("concurrent");
    let b = d.join("b");
    for trial in 0..6 {
        let mut x = bifurcation(&b, 300).spawn().unwrap();
        let mut y = bifurcation(&b, 301).spawn().unwrap();
        assert!(x.wait().unwrap().success() && y.wait().unwrap().success());
        let j = common::json(&d.join("b.json"));
        let points = j["config"]["sweep"]["points"].as_u64().unwrap();
        let rows = std::fs::read_to_string(d.join("b.csv"))
            .unwrap()
            .lines()
            .count()
            - 1;
        assert_eq!(
            rows as u64,
            points * 4,
            "trial {trial}: CSV of another run than the JSON"
        );
        let left: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .filter(|n| !n.starts_with("b.") || n.contains("partial"))
            .collect();
        assert!(left.is_empty(), "trial {trial}: left {left:?}");
    }
}

#[test]
fn an_unwritable_destination_fails_first_and_leaves_nothing() {
    let d = scratch("dest");
    // A destination that is a directory: nothing is computed or written.
    std::fs::create_dir(d.join("b.json")).unwrap();
    let o = bifurcation(&d.join("b"), 50).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("b.json"), "{}", stderr(&o));
    let names: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec!["b.json"], "left {names:?}");
    // A missing directory is reported before the computation, with its path.
    let t = std::time::Instant::now();
    let o = rattle()
        .args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(common::config("fig2.toml"))
        .arg("--out")
        .arg(d.join("nodir/b"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("nodir"), "{}", stderr(&o));
    assert!(
        t.elapsed().as_secs_f64() < 5.0,
        "refused only after computing"
    );
    let o = rattle()
        .args(["accuracy", "--backend", "cpu", "--config"])
        .arg(common::config("fig2.toml"))
        .arg("--out")
        .arg(d.join("nodir/acc"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("nodir"), "{}", stderr(&o));
    // A prefix that names a directory would write hidden files.
    let o = bifurcation(Path::new(&format!("{}/", d.display())), 5)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!d.join(".csv").exists());
}

/// Stribeck friction with a huge quadratic term: every cell's state overflows (CPU, f32 and
/// f64 alike).
const OVERFLOW: &str = "[model]\nfriction = \"stribeck\"\neta = 1.33\n[method]\n\
    steps_per_period = 64\n[run]\ntransient_periods = 300\nsample_periods = 50\n[map]\n\
    x = \"l2\"\nx_from = 1e3\nx_to = 1e6\nx_points = 3\ny = \"fs\"\ny_from = 0.2\n\
    y_to = 0.3\ny_points = 1\n";

#[test]
fn a_map_without_exponents_removes_the_stale_exponent_image() {
    let (d, cfg) = setup("stale");
    let o = map(&cfg, &d.join("m"), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("m-lyapunov.png").exists());
    // Same prefix, a map in which every cell fails: no exponent to draw.
    std::fs::write(&cfg, OVERFLOW).unwrap();
    let o = map(&cfg, &d.join("m"), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let class: Vec<i32> = npy(&d.join("m-class.npy"));
    assert!(class.iter().all(|&c| c == -2), "{class:?}");
    assert!(
        !d.join("m-lyapunov.png").exists(),
        "stale exponent image left"
    );
    assert!(stderr(&o).contains("lyapunov"), "{}", stderr(&o));
}

fn point(args: &[&str]) -> std::process::Output {
    rattle()
        .args(["point", "--backend", "cpu", "--config"])
        .arg(common::config("fig2.toml"))
        .args([
            "--set",
            "run.transient_periods=10",
            "--set",
            "run.sample_periods=5",
        ])
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn inputs_are_checked_before_anything_runs() {
    let fails = |o: &std::process::Output, key: &str| {
        assert_eq!(o.status.code(), Some(2), "{}", stderr(o));
        assert!(stderr(o).contains(key), "must name {key}: {}", stderr(o));
    };
    // A value with a newline would smuggle a second key.
    fails(&point(&["--set", "r=0.9\nR=0.1"]), "newline");
    // NaN on the command line is a number out of range, not a string.
    let o = point(&["--eta", "nan"]);
    fails(&o, "model.eta");
    assert!(!stderr(&o).contains("string"), "{}", stderr(&o));
    // A clearance f32 rounds to zero is refused in f32, accepted in f64.
    fails(
        &point(&["--set", "r=1e-300", "--precision", "f32"]),
        "model.r",
    );
    let c = "[model]\nr = 1e-300\n[method]\nprecision = \"f64\"\n";
    rattle::config::Config::from_toml(c, &[]).unwrap();
    // The config's own values are checked even when the command line overrides them.
    let d = scratch("tpu");
    std::fs::write(d.join("c.toml"), "[method]\nbackend = \"tpu\"\n").unwrap();
    let o = rattle()
        .args(["point", "--backend", "cpu", "--config"])
        .arg(d.join("c.toml"))
        .output()
        .unwrap();
    fails(&o, "tpu");
    // A sweep of zero width fails before computing, not in the plot.
    let o = rattle()
        .args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(common::config("fig2.toml"))
        .args(["--set", "sweep.from=1.5", "--set", "sweep.to=1.5", "--out"])
        .arg(d.join("b"))
        .output()
        .unwrap();
    fails(&o, "sweep.to");
    assert!(!d.join("b.json").exists());
    // Keys of the other friction law are reported as ignored.
    let o = point(&["--set", "fs=0.3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("model.fs is ignored"), "{}", stderr(&o));
    // point does not use [map]: a map-only mistake does not stop it; map refuses it.
    std::fs::write(d.join("m.toml"), "[map]\nx_points = 0\n").unwrap();
    let run = |sub: &str| {
        let mut c = rattle();
        c.args([sub, "--backend", "cpu", "--config"])
            .arg(d.join("m.toml"));
        c.args([
            "--set",
            "run.transient_periods=5",
            "--set",
            "run.sample_periods=2",
        ]);
        c.arg("--out").arg(d.join("mm"));
        if sub == "point" {
            c = rattle();
            c.args(["point", "--backend", "cpu", "--config"])
                .arg(d.join("m.toml"));
            c.args([
                "--set",
                "run.transient_periods=5",
                "--set",
                "run.sample_periods=2",
            ]);
        }
        c.output().unwrap()
    };
    assert!(run("point").status.success());
    // Nor does bifurcation, which uses [sweep].
    let o = run("bifurcation");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("mm.json").exists());
    fails(&run("map"), "map.x_points");
}

#[test]
fn bifurcation_with_failed_points_writes_them_as_failed() {
    let d = scratch("failed-bif");
    ok(rattle()
        .args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(common::config("fig3.toml"))
        .args([
            "--set",
            "sweep.param=l2",
            "--set",
            "sweep.from=1e3",
            "--set",
            "sweep.to=1e6",
        ])
        .args([
            "--set",
            "sweep.points=5",
            "--set",
            "run.transient_periods=50",
        ])
        .args(["--set", "run.sample_periods=10", "--out"])
        .arg(d.join("b")));
    let j = common::json(&d.join("b.json"));
    let pts = j["points"].as_array().unwrap();
    let failed = pts.iter().filter(|p| p["class"] == "failed").count();
    assert!(failed >= 4, "{}", j["class_counts"]);
    for p in pts {
        assert_eq!(
            p["class"] == "failed",
            p["diagnostics"]["nonfinite"] == true,
            "{p}"
        );
    }
}

#[test]
fn the_paper_figure_needs_no_checkout() {
    let d = scratch("paper");
    let o = rattle()
        .current_dir(&d)
        .args([
            "figure",
            "paper",
            "--points",
            "3",
            "--backend",
            "cpu",
            "--out",
            "p.png",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("p.png").exists());
}

#[test]
fn an_adapter_name_that_matches_nothing_is_an_error_not_a_panic() {
    for args in [
        &["adapters"][..],
        &["point", "--backend", "gpu", "--config"][..],
    ] {
        let mut c = rattle();
        c.env("WGPU_ADAPTER_NAME", "nonexistent-adapter-xyz")
            .args(args);
        if args[0] == "point" {
            c.arg(common::config("fig2.toml"));
        }
        let o = c.output().unwrap();
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains("matches no adapter") && e.contains("available"),
            "{e}"
        );
        assert!(!e.contains("panicked"), "{e}");
    }
}

#[test]
fn a_closed_pipe_ends_the_output_quietly() {
    // The reader is gone before the first line is written (as after `| head -1`): the writes
    // fail with a broken pipe, and rattle ends with status 0 and no panic.
    let mut child = rattle()
        .args(["point", "--backend", "cpu", "--config"])
        .arg(common::config("fig2.toml"))
        .args([
            "--set",
            "run.transient_periods=10",
            "--set",
            "run.sample_periods=4",
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?}: {err}", out.status);
    assert!(
        !err.contains("panicked") && !err.contains("Broken pipe"),
        "{err}"
    );
}

#[test]
fn clearances_that_f32_cannot_resolve_are_refused_with_the_key() {
    // In f32 the largest exponent at Fig. 2's eta = 1.5 drifts at r = 1e-11 and is NaN from
    // 1e-12 (f64 unaffected): below 1e-9 f32 is refused, wherever r is set, before anything
    // runs; f64 accepts the same values.
    let d = scratch("clearance");
    let cases: [(&[&str], &str); 3] = [
        (&["point", "--set", "r=1e-12"], "model.r"),
        (
            &[
                "map",
                "--set",
                "map.x=\"r\"",
                "--set",
                "map.x_from=1e-16",
                "--set",
                "map.x_to=1e-14",
                "--set",
                "map.x_points=2",
                "--set",
                "map.y_points=2",
            ],
            "map.x_from",
        ),
        (
            &[
                "bifurcation",
                "--set",
                "sweep.param=\"r\"",
                "--set",
                "sweep.from=1e-12",
                "--set",
                "sweep.to=0.5",
                "--set",
                "sweep.points=3",
            ],
            "sweep.from",
        ),
    ];
    for (args, key) in cases {
        let mut cmd = rattle();
        cmd.args(args)
            .args(["--backend", "cpu", "--precision", "f32", "--config"])
            .arg(common::config("fig2.toml"));
        if args[0] != "point" {
            cmd.arg("--out").arg(d.join("x"));
        }
        refused(&mut cmd, &[key, "1e-9"]);
    }
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0);
    let out = rattle()
        .args([
            "point",
            "--set",
            "r=1e-12",
            "--backend",
            "cpu",
            "--precision",
            "f64",
            "--json",
        ])
        .args(["--set", "run.tangent=\"largest\"", "--config"])
        .arg(common::config("fig2.toml"))
        .args(["--eta", "1.5"])
        .output()
        .unwrap();
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(j["class"], "period-1", "{}", stderr(&out));
    assert!(
        j["lyapunov"]
            .as_f64()
            .is_some_and(|l| (l + 0.0295).abs() < 1e-3)
    );
}

#[test]
fn validate_refuses_zero_state_points() {
    let out = rattle()
        .args(["validate", "--state-points", "0", "--config"])
        .arg(common::config("fig2.toml"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("--state-points"), "{}", stderr(&out));
}

#[test]
fn all_adapters_with_the_cpu_backend_is_refused() {
    // `--adapters all` runs on GPUs; with the CPU backend asked for it used to run on the GPU
    // anyway and write a JSON whose backend and config disagree.
    let (d, cfg) = setup("adapters-cpu");
    let out = map(&cfg, &d.join("m"), &["--adapters", "all"]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(
        err.contains("--adapters") && err.contains("`all`") && err.contains("cpu"),
        "{err}"
    );
    assert!(!d.join("m.json").exists());
}

/// The id of a process that has ended (as a killed run's is).
fn gone_pid() -> u32 {
    let mut gone = std::process::Command::new("true").spawn().unwrap();
    let pid = gone.id();
    gone.wait().unwrap();
    pid
}

#[test]
fn a_lock_left_by_a_killed_run_is_taken_over_at_once() {
    // A run killed during its commit leaves `.rattle-commit.lock` holding its process id: the
    // next run sees that the process is gone and takes the lock over instead of waiting 60 s
    // without a word.
    let (d, cfg) = setup("stale-lock");
    let pid = gone_pid();
    let lock = d.join(".rattle-commit.lock");
    std::fs::write(&lock, pid.to_string()).unwrap();
    let t = std::time::Instant::now();
    let out = map(&cfg, &d.join("m"), &[]);
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(!err.contains("waiting"), "{err}");
    // Not a speed claim: the old behaviour waited for the lock's 60 s age limit.
    assert!(t.elapsed() < std::time::Duration::from_secs(30));
    assert!(d.join("m.json").exists() && !lock.exists());
}

#[test]
fn a_directory_in_the_way_of_a_stale_file_fails_before_any_commit() {
    // A map without exponents removes the stale exponent images of the prefix; a directory
    // there used to fail that removal after all the new files were committed.
    let (d, cfg) = setup("stale-dir");
    std::fs::create_dir(d.join("m-multiplier.png")).unwrap();
    let out = map(&cfg, &d.join("m"), &["--set", "run.tangent=\"none\""]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("m-multiplier.png"),
        "{}",
        stderr(&out)
    );
    let left: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n != "c.toml" && n != "m-multiplier.png")
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn partial_files_of_killed_runs_are_removed_by_the_next_commit() {
    // A run killed before its commit leaves `FINAL.PID-N.partial` files; the next run that
    // commits the same files removes those whose process is gone, and no others.
    let (d, cfg) = setup("orphans");
    let pid = gone_pid();
    let orphan = d.join(format!("m.json.{pid}-3.partial"));
    let other = d.join(format!("x.json.{pid}-3.partial"));
    let live = d.join(format!("m.json.{}-0.partial", std::process::id()));
    for f in [&orphan, &other, &live] {
        std::fs::write(f, "partial").unwrap();
    }
    let out = map(&cfg, &d.join("m"), &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(!orphan.exists(), "an orphan of the committed set stays");
    assert!(other.exists(), "a file of another prefix was removed");
    assert!(
        live.exists(),
        "the partial file of a live process was removed"
    );
}

#[test]
fn every_command_that_holds_one_result_per_point_goes_through_the_memory_guard() {
    // With 3 GB available: the issue's 3e6-point sweep (measured at 1,829 B per point, estimated
    // 2,208) is refused, as are a bench and an accuracy ensemble of unbounded size, each before
    // computing, naming what sets the size.
    let cases: [(&[&str], &str); 3] = [
        (
            &[
                "bifurcation",
                "--set",
                "sweep.points=3000000",
                "--set",
                "run.sample_periods=2",
                "--set",
                "run.transient_periods=0",
                "--set",
                "method.steps_per_period=8",
            ],
            "sweep.points",
        ),
        (&["bench", "--points", "99999999999"], "--points"),
        (&["accuracy", "--ensemble", "100000000"], "--ensemble"),
    ];
    let d = scratch("guard");
    for (args, key) in cases {
        let t = std::time::Instant::now();
        refused(
            rattle()
                .env("RATTLE_MEMORY_LIMIT", "3000000000")
                .args(args)
                .args(["--backend", "cpu", "--config"])
                .arg(common::config("fig2.toml"))
                .current_dir(&d),
            &[key, "available"],
        );
        // Refused before computing (not a speed claim: any computation of these takes minutes).
        assert!(t.elapsed() < std::time::Duration::from_secs(20), "{args:?}");
    }
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0);
}

#[test]
fn a_start_outside_the_stops_of_a_swept_clearance_is_refused() {
    // `point` refuses a start with |y3 - y1| > r; a sweep or a map over r starts every value
    // from the same state, so it must lie inside the smallest r swept.
    let d = scratch("start-r");
    let start = "initial.y=[0.0, 0.0, 0.5, 0.0]";
    let cases: [(&[&str], &str); 2] = [
        (
            &[
                "bifurcation",
                "--set",
                "sweep.param=\"r\"",
                "--set",
                "sweep.from=0.1",
                "--set",
                "sweep.to=0.8",
            ],
            "sweep.from",
        ),
        (
            &[
                "map",
                "--set",
                "map.x=\"r\"",
                "--set",
                "map.x_from=0.9",
                "--set",
                "map.x_to=0.2",
            ],
            "map.x_to",
        ),
    ];
    for (args, key) in cases {
        refused(
            rattle()
                .args(args)
                .args(["--set", start, "--backend", "cpu", "--config"])
                .arg(common::config("fig2.toml"))
                .arg("--out")
                .arg(d.join("x")),
            &["initial.y", key],
        );
    }
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0);
}

/// The files of an output set in `dir` (no `.partial` files, no lock), name -> bytes; the
/// JSON's run-specific timings are left out.
fn output_set(dir: &Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .filter_map(|p| {
            let name = p.file_name()?.to_str()?.to_string();
            if name.ends_with(".partial") || name.starts_with('.') {
                return None;
            }
            let bytes = std::fs::read(&p).ok()?;
            let bytes = if name.ends_with(".json") {
                let j: serde_json::Value = serde_json::from_slice(&bytes).ok()?;
                j["config"].to_string().into_bytes()
            } else {
                bytes
            };
            Some((name, bytes))
        })
        .collect()
}

#[test]
fn an_interrupted_run_leaves_one_runs_whole_set() {
    // Two deterministic maps (eta 1.26 and 1.3) write the same 21 files of prefix m. The
    // second is interrupted (SIGINT) at many moments over its run, writes and commit included,
    // each time over the first's set: the files on disk are always all of one run's set,
    // never a mix, whatever the moment.
    let d = scratch("sigint");
    let run = |dir: &Path, eta: &str| {
        let mut c = rattle();
        c.args(["map", "--backend", "cpu", "--precision", "f64", "--config"])
            .arg(common::config("r_lambda.toml"))
            .args(["--eta", eta])
            .args([
                "--set",
                "run.transient_periods=0",
                "--set",
                "run.sample_periods=4",
            ])
            .args(["--set", "method.steps_per_period=8"])
            .args(["--set", "map.x_points=256", "--set", "map.y_points=256"])
            .arg("--out")
            .arg(dir.join("m"));
        c
    };
    let sets: Vec<_> = ["1.26", "1.3"]
        .iter()
        .map(|eta| {
            let dir = d.join(format!("ref-{eta}"));
            std::fs::create_dir(&dir).unwrap();
            let t = std::time::Instant::now();
            ok(&mut run(&dir, eta));
            (output_set(&dir), t.elapsed())
        })
        .collect();
    let (a, b) = (&sets[0].0, &sets[1].0);
    assert_eq!(a.len(), 25);
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    let full = sets[1].1;
    let work = d.join("work");
    std::fs::create_dir(&work).unwrap();
    let (mut whole_a, mut whole_b) = (0, 0);
    // Delays: at once, then densely over the end of the run (the writes and the commit), then
    // after its end.
    let delays: Vec<f64> = std::iter::once(0.0)
        .chain((0..16).map(|k| 0.7 + 0.025 * f64::from(k)))
        .chain(std::iter::once(2.0))
        .collect();
    for (k, &delay) in delays.iter().enumerate() {
        // Start from the first run's set.
        for (name, _) in a.iter() {
            std::fs::copy(d.join("ref-1.26").join(name), work.join(name)).unwrap();
        }
        let mut child = run(&work, "1.3");
        let mut child = child
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(full.mul_f64(delay));
        let _ = std::process::Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status();
        child.wait().unwrap();
        let now = output_set(&work);
        if now == *a {
            whole_a += 1;
        } else if now == *b {
            whole_b += 1;
        } else {
            let mixed: Vec<_> = now
                .iter()
                .filter(|(n, v)| a.get(*n) == Some(v))
                .map(|(n, _)| n)
                .collect();
            panic!(
                "interrupt {k}: a mixed set ({} of {} files from the first run: {mixed:?})",
                mixed.len(),
                now.len()
            );
        }
    }
    eprintln!("interrupted runs: {whole_a} left the first set, {whole_b} the second");
    // The first interrupt comes before anything is written, the last after the end.
    assert!(whole_a > 0 && whole_b > 0, "{whole_a} {whole_b}");
}

#[test]
fn a_bad_memory_limit_is_an_error_not_ignored() {
    let d = scratch("bad-limit");
    for v in ["4GB", "0", "-1"] {
        refused(
            rattle()
                .env("RATTLE_MEMORY_LIMIT", v)
                .args(["bifurcation", "--backend", "cpu", "--config"])
                .arg(common::config("fig2.toml"))
                .arg("--out")
                .arg(d.join("x")),
            &["RATTLE_MEMORY_LIMIT"],
        );
    }
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0);
}

/// Issue item: a map without exponents (`run.tangent = "none"`) still confirms cycles through
/// Newton, and the map with exponents decides no cell differently from it.
#[test]
fn a_map_without_exponents_confirms_the_cycles_the_default_map_finds() {
    let d = scratch("tangent_none");
    let short = [
        "--set",
        "run.transient_periods=20",
        "--set",
        "run.sample_periods=16",
        "--set",
        "method.steps_per_period=64",
        "--set",
        "map.x_points=8",
        "--set",
        "map.y_points=8",
    ];
    let run = |out: &str, extra: &[&str]| {
        ok(rattle()
            .args(["map", "--backend", "cpu", "--config"])
            .arg(common::config("r_lambda.toml"))
            .args(short)
            .args(extra)
            .arg("--out")
            .arg(d.join(out)));
        let class: Vec<i32> = npy(&d.join(format!("{out}-class.npy")));
        class
    };
    let none = run("none", &["--set", "run.tangent=\"none\""]);
    let full = run("full", &[]);
    let cycles = |c: &[i32]| c.iter().filter(|&&k| k >= 1).count();
    // Six cells settle on a cycle within these 36 periods (Newton at their periods).
    assert!(cycles(&none) >= 5, "{none:?}");
    assert!(cycles(&full) >= 5, "{full:?}");
    for (i, (&a, &b)) in none.iter().zip(&full).enumerate() {
        if b >= 1 {
            assert_eq!(
                a, b,
                "cell {i}: period {b} with exponents, class {a} without"
            );
        }
    }
}

/// Low items: every message names the key or flag at fault, in a form a person reads.
#[test]
fn messages_name_the_key_at_fault_in_readable_form() {
    let d = scratch("messages");
    let fig2 = common::config("fig2.toml");
    let cmd = |args: &[&str]| {
        let mut c = rattle();
        c.args(args).current_dir(&d);
        c
    };
    let point = |extra: &[&str]| {
        let mut c = cmd(&["point", "--backend", "cpu", "--config"]);
        c.arg(&fig2).args(extra);
        c
    };
    // A huge number in exponent form, not 309 digits.
    let o = point(&["--set", "eta=1e308"]).output().unwrap();
    assert!(stderr(&o).contains("1e308") && !stderr(&o).contains("00000000"));
    refused(&mut point(&["--set", "eta=1e308"]), &["model.eta"]);
    // A flag and a --set of the same key: neither is dropped unread.
    refused(
        &mut point(&["--eta", "1.2", "--set", "eta=0"]),
        &["--eta", "model.eta"],
    );
    // A level the friction law ignores is checked like the one it reads.
    refused(&mut point(&["--set", "fs=-1"]), &["model.fs"]);
    // A map range of zero width names its keys.
    let mut c = cmd(&["map", "--backend", "cpu", "--config"]);
    c.arg(common::config("r_lambda.toml")).args([
        "--set",
        "map.x_from=0.6",
        "--set",
        "map.x_to=0.6",
    ]);
    refused(&mut c, &["map.x_to", "map.x_from"]);
    // The error chain says each cause once.
    let o = cmd(&["point", "--config"])
        .arg(d.join("none.toml"))
        .output();
    let e = stderr(&o.unwrap());
    assert_eq!(e.matches("os error 2").count(), 1, "{e}");
    // A file in the way of the output directory is named as such.
    std::fs::write(d.join("file"), "").unwrap();
    let mut c = cmd(&["bifurcation", "--backend", "cpu", "--config"]);
    c.arg(&fig2).arg("--out").arg(d.join("file/m"));
    refused(&mut c, &["file is in the way"]);
    // The paper figure: its flag, and a PNG under a PNG name only.
    refused(
        &mut cmd(&["figure", "paper", "--points", "0"]),
        &["--points"],
    );
    refused(&mut cmd(&["figure", "paper", "--out", "x.jpg"]), &[".png"]);
    assert!(!d.join("x.jpg").exists());
}

/// A sweep in which every point fails says so, and writes nothing.
#[test]
fn a_sweep_where_every_point_fails_is_an_error_that_says_so() {
    let d = scratch("all_failed");
    let cfg = d.join("c.toml");
    std::fs::write(
        &cfg,
        "[model]\nfriction = \"stribeck\"\nb1 = 1e6\n[method]\nsteps_per_period = 64\n\
         [run]\ntransient_periods = 30\nsample_periods = 10\n[sweep]\npoints = 20\n",
    )
    .unwrap();
    let mut c = rattle();
    c.args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(d.join("b"));
    refused(&mut c, &["every one of the 20 points failed"]);
    assert!(!d.join("b.json").exists() && !d.join("b.csv").exists());
}

/// A map of 4 x 4 cells over 2 + 2 periods: cheap enough to run where only the checks matter.
const CHEAP_MAP: [&str; 8] = [
    "--set",
    "map.x_points=4",
    "--set",
    "map.y_points=4",
    "--set",
    "run.transient_periods=2",
    "--set",
    "run.sample_periods=2",
];

#[test]
fn a_value_for_a_parameter_the_command_varies_is_refused() {
    // Issue M2 of the reliability round: the flag's value was dropped without a word (the
    // study or map used its own values; the JSON's config said the flag's).
    let d = scratch("varied_flags");
    let out = d.join("x");
    let cheap = CHEAP_MAP;
    let cases: Vec<(Vec<&str>, &[&str])> = vec![
        (
            vec!["map", "--config", "configs/r_lambda.toml", "--R", "0.55"],
            &["--R", "map.x"],
        ),
        (
            vec!["map", "--config", "configs/eta_lambda.toml", "--eta", "1.3"],
            &["--eta", "map.x"],
        ),
        (
            vec![
                "map",
                "--config",
                "configs/eta_lambda.toml",
                "--set",
                "lambda=0.03",
            ],
            &["lambda=0.03", "map.y"],
        ),
        (
            vec![
                "map",
                "--config",
                "configs/r_lambda.toml",
                "--set",
                "fk=0.03",
            ],
            &["fk=0.03", "map.y"],
        ),
        (
            vec![
                "bifurcation",
                "--config",
                "configs/fig2.toml",
                "--eta",
                "1.3",
            ],
            &["--eta", "sweep.param"],
        ),
        (
            vec![
                "sensitivity",
                "--config",
                "configs/fig2.toml",
                "--lambda",
                "0.05",
                "--uncertain",
                "lambda=0.02+-0.005",
            ],
            &["--lambda", "--uncertain"],
        ),
    ];
    for (args, keys) in cases {
        let mut c = rattle();
        c.current_dir(env!("CARGO_MANIFEST_DIR"))
            .args(&args)
            .args(cheap)
            .arg("--backend")
            .arg("cpu")
            .arg("--out")
            .arg(&out);
        refused(&mut c, keys);
        assert!(
            std::fs::read_dir(&d).unwrap().next().is_none(),
            "{args:?} wrote files"
        );
    }
    // A flag for a parameter the command keeps fixed is still taken.
    let mut c = rattle();
    c.current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["map", "--config", "configs/r_lambda.toml", "--eta", "1.3"])
        .args(cheap)
        .args(["--backend", "cpu", "--out"])
        .arg(&out);
    ok(&mut c);
}

#[test]
fn compare_checks_the_grid_only_and_before_computing() {
    // Issue M4-M6 of the reliability round: --compare refused a config whose [map] differed
    // only in title or risk, refused a different grid only after the main map was computed,
    // and was ignored with --shard.
    let d = scratch("compare_grid");
    let cheap = [CHEAP_MAP.as_slice(), &["--backend", "cpu"]].concat();
    // The R = 0.62 config with one [map] line replaced.
    let other = |from: &str, to: &str| {
        let p = d.join(format!("o{}.toml", to.len()));
        let base = std::fs::read_to_string(common::config("eta_lambda_r062.toml")).unwrap();
        assert!(base.contains(from));
        std::fs::write(&p, base.replace(from, to)).unwrap();
        p
    };
    // `map` of eta_lambda.toml with `args`, compared with `other`, written to `out`.
    let compare = |args: &[&str], other: &Path, out: &str| {
        let mut c = rattle();
        c.args(["map", "--config"])
            .arg(common::config("eta_lambda.toml"))
            .args(args)
            .arg("--compare")
            .arg(other)
            .arg("--out")
            .arg(d.join(out));
        c
    };
    // Only the title differs: compared.
    let titled = other("[map]\n", "[map]\ntitle = \"another title\"\n");
    ok(&mut compare(&cheap, &titled, "t"));
    assert!(d.join("t-compare.png").exists());
    // Another grid: refused before computing (a 2000 x 2000 main map would take minutes).
    let coarse = other("x_from = 1.0", "x_from = 1.1");
    let big = [
        "--set",
        "map.x_points=2000",
        "--set",
        "map.y_points=2000",
        "--backend",
        "cpu",
    ];
    let t = std::time::Instant::now();
    refused(
        &mut compare(&big, &coarse, "g"),
        &["--compare", "map.x_from"],
    );
    assert!(t.elapsed().as_secs_f64() < 5.0, "{:?}", t.elapsed());
    // With a shard: refused, not ignored.
    let sharded = [cheap.as_slice(), &["--shard", "0/2"]].concat();
    refused(
        &mut compare(&sharded, &titled, "s"),
        &["--compare", "--shard"],
    );
}

#[test]
fn bench_sizes_are_refused_by_the_option_at_fault() {
    // Issue M8 of the reliability round: `--points 1 --periods 4294967295` blamed --points and
    // advised "points <= 0". The bench holds 2 samples per point (half the periods with
    // --lyapunov), and its periods have an upper bound of their own.
    for (args, keys) in [
        (
            vec!["--points", "1", "--periods", "4294967295"],
            &["--periods", "1000000"][..],
        ),
        (
            vec!["--points", "1", "--periods", "2"],
            &["--periods", "3"][..],
        ),
        (vec!["--points", "0"], &["--points", ">= 1"][..]),
    ] {
        let mut c = rattle();
        c.current_dir(env!("CARGO_MANIFEST_DIR"))
            .args(["bench", "--config", "configs/fig2.toml", "--backend", "cpu"])
            .args(&args);
        refused(&mut c, keys);
        let mut c = rattle();
        c.current_dir(env!("CARGO_MANIFEST_DIR"))
            .args(["bench", "--ladder", "--config", "configs/fig2.toml"])
            .args(&args);
        refused(&mut c, keys);
    }
}

#[test]
fn negative_values_are_read_as_values_and_refused_by_their_option() {
    // Issue L1 of the reliability round: `--risk -0.01,0.005` gave "unexpected argument '-0'"
    // (the value read as a flag) and named no option; likewise the other numeric options.
    let d = scratch("negative_values");
    let map = |opt: &str, v: &str, keys: &[&str]| {
        let mut c = rattle();
        c.args(["map", "--config"])
            .arg(common::config("r_lambda.toml"))
            .args(CHEAP_MAP)
            .args(["--backend", "cpu", opt, v, "--out"])
            .arg(d.join("m"));
        refused(&mut c, keys);
    };
    map("--risk", "-0.01,0.005", &["risk", "> 0"]);
    map("--refine", "-1", &["--refine", "-1"]);
    map("--starts", "-1", &["--starts", "-1"]);
    map("--shard", "-1/2", &["--shard", "-1/2"]);
    map("--checkpoint", "-2", &["--checkpoint", "-2"]);
    for opt in ["--samples", "--seed"] {
        let mut c = rattle();
        c.args(["sensitivity", "--config"])
            .arg(common::config("fig2.toml"))
            .args(["--uncertain", "R=0.6+-0.02", opt, "-1", "--out"])
            .arg(d.join("s"));
        refused(&mut c, &[opt, "-1"]);
    }
    assert!(std::fs::read_dir(&d).unwrap().next().is_none());
}

#[test]
fn a_key_set_twice_is_refused() {
    // Issue L5 of the reliability round: the last --set of a key won silently.
    for sets in [
        ["model.eta=1.3", "eta=1.4"],
        ["R=0.5", "R=0.6"],
        ["run.sample_periods=10", "run.sample_periods=20"],
    ] {
        let mut c = rattle();
        c.args(["point", "--backend", "cpu", "--config"])
            .arg(common::config("fig2.toml"))
            .args(["--set", sets[0], "--set", sets[1]]);
        refused(&mut c, &["--set", sets[0], sets[1]]);
    }
}

#[test]
fn a_paper_figure_of_one_value_is_refused_before_computing() {
    // Issue L9 of the reliability round: `figure paper --points 1` computed the four panels and
    // then failed with an internal plot message; a diagram over eta needs two values at least.
    let d = scratch("paper_one");
    let mut c = rattle();
    c.args(["figure", "paper", "--points", "1", "--out"])
        .arg(d.join("p.png"));
    let t = std::time::Instant::now();
    refused(&mut c, &["--points", "2..=10000000"]);
    assert!(t.elapsed().as_secs_f64() < 2.0);
    assert!(std::fs::read_dir(&d).unwrap().next().is_none());
}

#[test]
fn errors_in_secondary_configs_name_the_file_before_computing() {
    // Issue L7 of the reliability round: a bad `--compare` config or a bad file of
    // `figure paper --configs` was reported without its file name (and the paper figure
    // computed the panels before it).
    let d = scratch("secondary_configs");
    let bad = d.join("bad.toml");
    let base = std::fs::read_to_string(common::config("r_lambda.toml")).unwrap();
    assert!(base.contains("\neta = 1.26"));
    std::fs::write(&bad, base.replacen("\neta = 1.26", "\neta = -1", 1)).unwrap();
    let mut c = rattle();
    c.args(["map", "--config"])
        .arg(common::config("r_lambda.toml"))
        .args(CHEAP_MAP)
        .args(["--backend", "cpu", "--compare"])
        .arg(&bad)
        .arg("--out")
        .arg(d.join("m"));
    refused(&mut c, &["--compare", "bad.toml", "model.eta"]);
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
    // The paper figure's four files: the last one bad, refused before the first is computed.
    let dir = d.join("configs");
    std::fs::create_dir(&dir).unwrap();
    for name in ["fig2", "fig3", "fig4a", "fig4b"] {
        let text = std::fs::read_to_string(common::config(&format!("{name}.toml"))).unwrap();
        let text = if name == "fig4b" {
            assert!(text.contains("\nR = 0.62"));
            text.replacen("\nR = 0.62", "\nR = 5", 1)
        } else {
            text
        };
        std::fs::write(dir.join(format!("{name}.toml")), text).unwrap();
    }
    let t = std::time::Instant::now();
    let mut c = rattle();
    c.args([
        "figure",
        "paper",
        "--backend",
        "cpu",
        "--points",
        "3000",
        "--configs",
    ])
    .arg(&dir)
    .arg("--out")
    .arg(d.join("p.png"));
    refused(&mut c, &["fig4b.toml", "model.R"]);
    assert!(t.elapsed().as_secs_f64() < 5.0, "{:?}", t.elapsed());
    assert!(!d.join("p.png").exists());
}

#[test]
fn forged_parts_are_refused_and_the_parts_version_is_kept() {
    // Issue L2 of the reliability round: parts whose config was edited to an impossible one
    // (R = 5) or relabelled (8 x 8 cells as 4 x 16) merged, and parts of 0.1.0 gave a merged
    // JSON that said the merging binary's version.
    let d = scratch("forged_parts");
    let cfg = common::config("r_lambda.toml");
    let parts: Vec<PathBuf> = (0..2)
        .map(|i| {
            let mut c = rattle();
            c.args(["map", "--backend", "cpu", "--config"])
                .arg(&cfg)
                .args(CHEAP_MAP)
                .args(["--shard", &format!("{i}/2"), "--out"])
                .arg(d.join("m"));
            ok(&mut c);
            d.join(format!("m.part-{i}-of-2.json"))
        })
        .collect();
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let originals: Vec<serde_json::Value> = parts.iter().map(|p| read(p)).collect();
    let write = |edit: &dyn Fn(&mut serde_json::Value)| {
        for (p, o) in parts.iter().zip(&originals) {
            let mut j = o.clone();
            edit(&mut j);
            std::fs::write(p, serde_json::to_string(&j).unwrap()).unwrap();
        }
    };
    // The same edits resealed by the library, as a part that says what it holds would be.
    let reseal = |edit: &dyn Fn(&mut serde_json::Value)| {
        for (p, o) in parts.iter().zip(&originals) {
            let mut j = o.clone();
            edit(&mut j);
            let part: rattle::map::Part = serde_json::from_value(j).unwrap();
            rattle::map::write_part(p, &part).unwrap();
        }
    };
    let merged = d.join("merged");
    let refused_merge = |keys: &[&str]| {
        let mut c = rattle();
        c.arg("merge").args(&parts).arg("--out").arg(&merged);
        refused(&mut c, keys);
        assert!(!d.join("merged.json").exists());
    };
    let impossible = |j: &mut serde_json::Value| j["config"]["model"]["R"] = 5.0.into();
    let relabelled = |j: &mut serde_json::Value| {
        j["config"]["map"]["x_points"] = 2.into();
        j["config"]["map"]["y_points"] = 8.into();
    };
    write(&impossible);
    refused_merge(&["m.part-0-of-2.json", "model.R"]);
    reseal(&impossible);
    refused_merge(&["m.part-0-of-2.json", "model.R"]);
    write(&relabelled);
    refused_merge(&["m.part-0-of-2.json", "checksum"]);
    // Resealed parts of another version merge, and the map says which version computed it.
    reseal(&|j| j["version"] = "0.1.0".into());
    let mut c = rattle();
    c.arg("merge").args(&parts).arg("--out").arg(&merged);
    ok(&mut c);
    let j = common::json(&d.join("merged.json"));
    assert_eq!(j["version"], "0.1.0", "{j}");
    assert_eq!(j["merged_by"], env!("CARGO_PKG_VERSION"), "{j}");
}

/// Runs `cmd` and kills it if it has not ended within `secs`; the output, or None if killed.
fn within(cmd: &mut std::process::Command, secs: f64) -> Option<std::process::Output> {
    use std::process::Stdio;
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t = std::time::Instant::now();
    while t.elapsed().as_secs_f64() < secs {
        if child.try_wait().unwrap().is_some() {
            return Some(child.wait_with_output().unwrap());
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    None
}

#[test]
fn a_fifo_is_refused_as_a_config_and_replaced_as_a_checkpoint_part() {
    // Issue L3 of the reliability round: a FIFO as --config, or in the place of a checkpoint
    // part, blocked forever (nobody writes to it).
    let d = scratch("fifo");
    let fifo = |name: &str| {
        let p = d.join(name);
        let st = std::process::Command::new("mkfifo")
            .arg(&p)
            .status()
            .unwrap();
        assert!(st.success());
        p
    };
    let c = fifo("c.toml");
    let mut cmd = rattle();
    cmd.args(["point", "--backend", "cpu", "--config"]).arg(&c);
    let o = within(&mut cmd, 20.0).expect("point --config FIFO blocked");
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("c.toml") && stderr(&o).contains("regular file"));
    // --compare reads its config the same way.
    let mut cmd = rattle();
    cmd.args(["map", "--backend", "cpu", "--config"])
        .arg(common::config("r_lambda.toml"))
        .args(CHEAP_MAP)
        .arg("--compare")
        .arg(&c)
        .arg("--out")
        .arg(d.join("x"));
    let o = within(&mut cmd, 20.0).expect("map --compare FIFO blocked");
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("regular file"), "{}", stderr(&o));
    // A checkpoint whose part 1 is a FIFO: recomputed and replaced, as an unreadable part is.
    fifo("m.part-1-of-2.json");
    let mut cmd = rattle();
    cmd.args(["map", "--backend", "cpu", "--config"])
        .arg(common::config("r_lambda.toml"))
        .args(CHEAP_MAP)
        .args(["--checkpoint", "2", "--out"])
        .arg(d.join("m"));
    let o = within(&mut cmd, 60.0).expect("a FIFO checkpoint part blocked");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("m.json").is_file());
    let part = d.join("m.part-1-of-2.json");
    assert!(std::fs::symlink_metadata(&part).map_or(true, |m| m.is_file()));
    // merge names it: it is not a part.
    let mut cmd = rattle();
    cmd.args(["map", "--backend", "cpu", "--config"])
        .arg(common::config("r_lambda.toml"))
        .args(CHEAP_MAP)
        .args(["--shard", "0/2", "--out"])
        .arg(d.join("s"));
    ok(&mut cmd);
    let part = fifo("s.part-1-of-2.json");
    let mut cmd = rattle();
    cmd.arg("merge")
        .arg(d.join("s.part-0-of-2.json"))
        .arg(&part)
        .arg("--out")
        .arg(d.join("merged"));
    let o = within(&mut cmd, 20.0).expect("merge of a FIFO blocked");
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("s.part-1-of-2.json"), "{}", stderr(&o));
    assert!(stderr(&o).contains("regular file"), "{}", stderr(&o));
}

#[test]
fn a_new_set_removes_the_files_of_the_set_it_replaces() {
    // Issue L4 of the reliability round: files another command wrote under the same prefix
    // stayed beside the new set (a bifurcation's x.csv beside a map's x.json).
    let d = scratch("other_sets");
    let x = d.join("x");
    let names = || -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    std::fs::write(d.join("x-notes.txt"), "the user's own file").unwrap();
    let cheap = [
        "--set",
        "run.transient_periods=2",
        "--set",
        "run.sample_periods=4",
        "--set",
        "method.steps_per_period=64",
    ];
    let mut c = rattle();
    c.args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(common::config("fig2.toml"))
        .args(cheap)
        .args(["--set", "sweep.points=8", "--out"])
        .arg(&x);
    ok(&mut c);
    assert_eq!(names(), ["x-notes.txt", "x.csv", "x.json", "x.png"]);
    let mut c = rattle();
    c.args(["map", "--backend", "cpu", "--config"])
        .arg(common::config("r_lambda.toml"))
        .args(CHEAP_MAP)
        .arg("--out")
        .arg(&x);
    ok(&mut c);
    let map_set = names();
    assert!(!map_set.contains(&"x.csv".to_string()), "{map_set:?}");
    assert!(map_set.contains(&"x-class.npy".to_string()), "{map_set:?}");
    let mut c = rattle();
    c.args(["point", "--config"])
        .arg(common::config("fig2.toml"))
        .args(["--periods", "2", "--plot"])
        .arg(&x);
    ok(&mut c);
    assert_eq!(names(), ["x-notes.txt", "x.json", "x.png", "x.svg"]);
    // A map with --compare, then one without: the comparison of the first does not stay.
    let map = |compare: bool| {
        let mut c = rattle();
        c.args(["map", "--backend", "cpu", "--config"])
            .arg(common::config("eta_lambda.toml"))
            .args(CHEAP_MAP);
        if compare {
            c.arg("--compare")
                .arg(common::config("eta_lambda_r062.toml"));
        }
        ok(c.arg("--out").arg(&x));
        names()
    };
    assert!(map(true).contains(&"x-compare.png".to_string()));
    assert!(!map(false).contains(&"x-compare.png".to_string()));
    assert!(!names().contains(&"x.svg".to_string()));
}
