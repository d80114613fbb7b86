//! Output sets: all or nothing, one run's whole set under concurrency, interrupts, killed runs
//! and their locks, stale files, closed pipes, sets that replace another command's.

use std::path::Path;

mod common;
use common::*;

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

/// The id of a process that has ended (as a killed run's is).
fn gone_pid() -> u32 {
    let mut gone = std::process::Command::new("true").spawn().unwrap();
    let pid = gone.id();
    gone.wait().unwrap();
    pid
}

#[test]
fn a_commit_waits_for_the_directorys_lock_and_a_killed_holder_releases_it() {
    // The commit lock is the operating system's lock on the output directory (`flock`): a run
    // waits while another process holds it, and goes on as soon as that process ends, killed
    // or not; a `.rattle-commit.lock` file of an older build blocks nothing.
    let (d, cfg) = setup("dir-lock");
    std::fs::write(d.join(".rattle-commit.lock"), "1").unwrap();
    // `-o`: the lock is flock's own, not inherited by its command, so killing flock ends it.
    let mut holder = std::process::Command::new("flock")
        .arg("-o")
        .arg(&*d)
        .args(["sleep", "30"])
        .spawn()
        .expect("flock (util-linux) holds the directory's lock");
    std::thread::sleep(std::time::Duration::from_millis(300));
    let mut cmd = rattle();
    cmd.args(["map", "--backend", "cpu", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(d.join("w"))
        .stderr(std::process::Stdio::piped());
    let child = cmd.spawn().unwrap();
    // Held: after its computation the run waits, and says so, without committing.
    std::thread::sleep(std::time::Duration::from_secs(3));
    assert!(!d.join("w.json").exists(), "committed under another's lock");
    holder.kill().unwrap();
    holder.wait().unwrap();
    let t = std::time::Instant::now();
    let out = child.wait_with_output().unwrap();
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("waiting for another run"), "{err}");
    // Not a speed claim: a lock that outlived its holder would keep it waiting forever.
    assert!(t.elapsed() < std::time::Duration::from_secs(30));
    assert!(d.join("w.json").exists());
}

#[test]
fn two_processes_committing_to_one_folder_at_once_leave_both_sets_whole() {
    let (d, cfg) = setup("two-commits");
    for trial in 0..4 {
        let spawn = |p: &str| {
            rattle()
                .args(["map", "--backend", "cpu", "--config"])
                .arg(&cfg)
                .arg("--out")
                .arg(d.join(p))
                .stderr(std::process::Stdio::null())
                .spawn()
                .unwrap()
        };
        let (mut a, mut b) = (spawn("a"), spawn("b"));
        assert!(a.wait().unwrap().success() && b.wait().unwrap().success());
        for p in ["a", "b"] {
            let j = common::json(&d.join(format!("{p}.json")));
            for f in j["files"].as_array().unwrap() {
                assert!(
                    d.join(f.as_str().unwrap()).is_file(),
                    "trial {trial}: {f} missing"
                );
            }
        }
        let left: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .filter(|n| n.contains("partial"))
            .collect();
        assert!(left.is_empty(), "trial {trial}: {left:?}");
    }
}

#[test]
fn a_json_rattle_did_not_write_removes_nothing() {
    // Reliability round 5, H2: any PREFIX.json with a `files` list was trusted, and a new set
    // deleted the user's files it named. Only files a set of rattle's wrote, still as written
    // (size and CRC in its `file_sums`), are removed.
    let (d, cfg) = setup("foreign-json");
    std::fs::write(d.join("m.json"), r#"{"files":["m.csv","m-raw.csv"]}"#).unwrap();
    for f in ["m.csv", "m-raw.csv"] {
        std::fs::write(d.join(f), "the user's own").unwrap();
    }
    assert!(map(&cfg, &d.join("m"), &[]).status.success());
    for f in ["m.csv", "m-raw.csv"] {
        assert_eq!(
            std::fs::read_to_string(d.join(f)).unwrap(),
            "the user's own"
        );
    }
    // The same prefix, another command: the map's files go, except one edited since.
    std::fs::write(d.join("m-class.npy"), "edited").unwrap();
    ok(&mut bifurcation(&d.join("m"), 20));
    assert!(
        !d.join("m-lyapunov.npy").exists(),
        "the map's own file stays"
    );
    assert_eq!(
        std::fs::read_to_string(d.join("m-class.npy")).unwrap(),
        "edited"
    );
}

#[test]
fn a_prefix_that_would_write_over_another_sets_file_is_refused_before_computing() {
    // Reliability round 5, M5: `map --compare B --out fig`, then `map --out fig-compare`
    // overwrote fig's fig-compare.png silently.
    let (d, cfg) = setup("collide");
    let o = map(&cfg, &d.join("fig"), &["--compare", cfg.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let before = std::fs::read(d.join("fig-compare.png")).unwrap();
    let t = std::time::Instant::now();
    let o = map(&cfg, &d.join("fig-compare"), &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("fig.json"), "{}", stderr(&o));
    assert!(t.elapsed().as_secs_f64() < 5.0);
    assert_eq!(std::fs::read(d.join("fig-compare.png")).unwrap(), before);
    assert!(!d.join("fig-compare.json").exists());
    // Without the comparison, fig's set no longer has it: removed.
    assert!(map(&cfg, &d.join("fig"), &[]).status.success());
    assert!(!d.join("fig-compare.png").exists());
    // The other way round: fig-compare's own set first, then a comparison at fig.
    assert!(map(&cfg, &d.join("fig-compare"), &[]).status.success());
    let before = std::fs::read(d.join("fig-compare.png")).unwrap();
    let o = map(&cfg, &d.join("fig"), &["--compare", cfg.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("fig-compare.json"), "{}", stderr(&o));
    assert_eq!(std::fs::read(d.join("fig-compare.png")).unwrap(), before);
}

#[test]
fn a_directory_named_like_a_layer_is_refused_before_computing() {
    // Reliability round 5, L9: `mkdir x-class.npy` failed the map only after computing.
    let (d, cfg) = setup("layer-dir");
    std::fs::create_dir(d.join("x-class.npy")).unwrap();
    let t = std::time::Instant::now();
    let o = map(&cfg, &d.join("x"), &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("x-class.npy"), "{}", stderr(&o));
    assert!(t.elapsed().as_secs_f64() < 5.0);
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
    // Two deterministic maps (eta 1.26 and 1.3) write the same 32 files of prefix m. The
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
    assert_eq!(a.len(), 32);
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
        // The interrupt removed the run's temporary files (reliability round 5, L2).
        let partial: Vec<_> = std::fs::read_dir(&work)
            .unwrap()
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter(|n| n.ends_with(".partial"))
            .collect();
        assert!(partial.is_empty(), "interrupt {k}: left {partial:?}");
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

#[test]
fn boundaries_never_replace_a_set_written_at_their_prefix() {
    // A map written at x-boundaries, then `map --boundaries --out x`, whose boundaries are the
    // set x-boundaries: refused before computing (it deleted the first map's files), and every
    // file of the first map stays.
    let d = scratch("implied_prefix");
    let map = |out: &str, extra: &[&str]| {
        rattle()
            .args(["map", "--backend", "cpu", "--config"])
            .arg(common::config("r_lambda.toml"))
            .args(CHEAP_MAP)
            .args(extra)
            .arg("--out")
            .arg(d.join(out))
            .output()
            .unwrap()
    };
    let first = map("x-boundaries", &[]);
    assert!(first.status.success());
    let before: Vec<String> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(before.contains(&"x-boundaries-class.npy".to_string()));
    let second = map("x", &["--boundaries"]);
    let err = String::from_utf8_lossy(&second.stderr);
    assert_eq!(second.status.code(), Some(2), "{err}");
    assert!(
        err.contains("x-boundaries.json") && err.contains("another set"),
        "{err}"
    );
    let mut after: Vec<String> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    let mut before = before;
    before.sort();
    after.sort();
    assert_eq!(
        before, after,
        "files changed: nothing may be written or removed"
    );
    // Its own boundaries at the same prefix are replaced as any set is.
    assert!(map("y", &["--boundaries"]).status.success());
    assert!(map("y", &["--boundaries"]).status.success());
    // The boundaries are files of the map's set (committed with it, listed by its JSON), so a
    // map written at y without them removes them (they stayed beside the new map, round 6
    // M1); a map at x leaves the set at x-boundaries, a map's, alone.
    let listed = |json: &str| -> Vec<String> {
        let j = common::json(&d.join(json));
        j["files"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f.as_str().unwrap().to_string())
            .collect()
    };
    let ys = listed("y.json");
    for f in ["y-boundaries.png", "y-boundaries.csv", "y-boundaries.json"] {
        assert!(
            ys.contains(&f.to_string()),
            "{f} not in y.json's files: {ys:?}"
        );
        assert!(d.join(f).exists(), "{f}");
    }
    assert!(map("y", &[]).status.success());
    for f in ["y-boundaries.png", "y-boundaries.csv", "y-boundaries.json"] {
        assert!(
            !d.join(f).exists(),
            "{f} left beside a map written without boundaries"
        );
    }
    assert!(map("x", &[]).status.success());
    assert!(d.join("x-boundaries-class.npy").exists());
    assert!(d.join("x-boundaries.json").exists());
}
