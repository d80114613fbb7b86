//! Map parts and checkpoints: run identity, impossible or forged contents, shard counts, the
//! comparison's grid, inputs that are not regular files.

use std::path::{Path, PathBuf};

mod common;
use common::*;

fn merge(parts: &[PathBuf], out: &Path) -> std::process::Output {
    rattle()
        .arg("merge")
        .args(parts)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
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
    // Named by its key and both values (reliability round 5, L8: "a different config").
    assert!(
        stderr(&o).contains("`method.steps_per_period` = 128 (this run: 64)"),
        "{}",
        stderr(&o)
    );
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
fn parts_that_differ_only_in_their_streams_merge_into_the_same_numbers() {
    // Reliability round 5, L8: parts computed with other `run.overlap` (the same numbers) were
    // refused as another run's. A 2 x 6 map on the CPU in f64, its shards with 1 and 3 streams.
    let (d, cfg) = setup("overlap-merge");
    let text = std::fs::read_to_string(&cfg)
        .unwrap()
        .replace("x_points = 1", "x_points = 2")
        .replace("y_points = 3", "y_points = 6");
    std::fs::write(&cfg, text).unwrap();
    let shard = |p: &str, i: usize, k: &str| {
        let o = map(
            &cfg,
            &d.join(p),
            &[
                "--shard",
                &format!("{i}/2"),
                "--set",
                &format!("run.overlap={k}"),
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        d.join(format!("{p}.part-{i}-of-2.json"))
    };
    let one = [shard("a", 0, "1"), shard("a", 1, "1")];
    let mixed = [shard("b", 0, "3"), shard("b", 1, "1")];
    let o = merge(&one, &d.join("one"));
    assert!(o.status.success(), "{}", stderr(&o));
    let o = merge(&mixed, &d.join("mixed"));
    assert!(o.status.success(), "{}", stderr(&o));
    for layer in ["class", "lyapunov", "period", "settle"] {
        assert_eq!(
            std::fs::read(d.join(format!("one-{layer}.npy"))).unwrap(),
            std::fs::read(d.join(format!("mixed-{layer}.npy"))).unwrap(),
            "{layer}"
        );
    }
}
