//! Volumes (`map.z`): every slice of every layer is the map of its z value byte for byte (CPU
//! f64 and lavapipe f32), a sharded + merged, a checkpointed and a memory-bounded volume equal
//! one run, and bad volumes are refused before anything is computed.

use std::path::Path;

mod common;
use common::{json, ok, rattle, refused, scratch};

/// A 9 x 7 R x lambda plane over 40 + 20 periods (tests/map.rs's small map).
fn plane() -> String {
    common::points::rl_map(64, 40, 20, 9, 7)
}

/// The plane with a z axis over eta: three slices across Fig. 2's chaotic band.
fn volume() -> String {
    format!(
        "{}z = \"eta\"\nz_from = 1.2\nz_to = 1.8\nz_points = 3\n",
        plane()
    )
}

/// The data of an NPY file (after its header) and its shape.
fn npy_data(path: &Path) -> (Vec<u8>, Vec<u64>) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let shape = npyz::NpyFile::new(&bytes[..]).unwrap().shape().to_vec();
    let start = match bytes[6] {
        1 => 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize,
        _ => 12 + u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
    };
    (bytes[start..].to_vec(), shape)
}

/// Runs the volume and the map of each of its z values with `args`, and compares every layer
/// slice by slice, byte for byte. Returns the volume's JSON.
fn slices_equal_maps(name: &str, args: &[&str]) -> serde_json::Value {
    let d = scratch(name);
    let (vol, pl) = (d.join("vol.toml"), d.join("plane.toml"));
    std::fs::write(&vol, volume()).unwrap();
    std::fs::write(&pl, plane()).unwrap();
    let run = |cfg: &Path, out: &Path, extra: &[String]| {
        ok(rattle()
            .arg("map")
            .args(args)
            .arg("--config")
            .arg(cfg)
            .arg("--out")
            .arg(out)
            .args(extra))
    };
    run(&vol, &d.join("v"), &[]);
    let j = json(&d.join("v.json"));
    let zs: Vec<f64> = j["axes"]["z_values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(zs.len(), 3);
    assert_eq!(j["axes"]["z"], "eta");
    assert_eq!(j["slices"].as_array().unwrap().len(), 3);
    let layers: Vec<String> = j["layers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["name"].as_str().unwrap().to_string())
        .collect();
    assert!(layers.len() >= 20, "{layers:?}");
    let mut classes = std::collections::BTreeSet::new();
    for (k, z) in zs.iter().enumerate() {
        let out = d.join(format!("m{k}"));
        run(&pl, &out, &["--set".into(), format!("model.eta={z}")]);
        for name in &layers {
            let (v, shape) = npy_data(&d.join(format!("v-{name}.npy")));
            let (m, mshape) = npy_data(&d.join(format!("m{k}-{name}.npy")));
            assert_eq!(shape[0], 3, "{name}: {shape:?}");
            assert_eq!(&shape[1..], &mshape[..], "{name}");
            let n = m.len();
            assert_eq!(v.len(), 3 * n, "{name}");
            assert!(
                v[k * n..(k + 1) * n] == m[..],
                "{name}: slice {k} (eta = {z}) differs from its map"
            );
        }
        let mj = json(&d.join(format!("m{k}.json")));
        assert_eq!(
            j["slices"][k]["class_counts"], mj["class_counts"],
            "slice {k}"
        );
        for c in mj["class_counts"].as_object().unwrap().keys() {
            classes.insert(c.clone());
        }
    }
    // Three slices across the band: the test compares more than one kind of cell.
    assert!(classes.len() >= 3, "{classes:?}");
    // The animations through z: one frame per slice, each the size of the first; a plane
    // has none.
    for gif in ["v.gif", "v-lyapunov.gif"] {
        let file = std::fs::File::open(d.join(gif)).unwrap_or_else(|e| panic!("{gif}: {e}"));
        let mut dec = gif::DecodeOptions::new().read_info(file).expect(gif);
        let (w, h) = (dec.width(), dec.height());
        let mut frames = 0;
        while let Some(f) = dec.read_next_frame().expect(gif) {
            assert_eq!((f.width, f.height), (w, h), "{gif}");
            frames += 1;
        }
        assert_eq!(frames, 3, "{gif}");
    }
    assert!(!d.join("m0.gif").exists() && !d.join("m0-lyapunov.gif").exists());
    j
}

#[test]
fn every_slice_is_its_map_byte_for_byte_on_the_cpu() {
    let j = slices_equal_maps("vol-cpu", &["--backend", "cpu", "--precision", "f64"]);
    assert_eq!(j["backend"], "cpu");
}

#[test]
fn every_slice_is_its_map_byte_for_byte_on_the_gpu() {
    // Fails, not skips, without an adapter when RATTLE_REQUIRE_GPU=1 (CI).
    if common::open_gpu().is_none() {
        return;
    }
    let j = slices_equal_maps("vol-gpu", &["--backend", "gpu", "--precision", "f32"]);
    assert_eq!(j["backend"], "gpu", "the volume fell back to the CPU");
}

#[test]
fn sharded_checkpointed_and_memory_bounded_volumes_equal_one_run() {
    let d = scratch("vol-shard");
    let cfg = d.join("vol.toml");
    std::fs::write(&cfg, volume()).unwrap();
    let map = |extra: &[&str], out: &str, limit: Option<&str>| {
        let mut c = rattle();
        c.args(["map", "--backend", "cpu", "--precision", "f64", "--config"])
            .arg(&cfg)
            .arg("--out")
            .arg(d.join(out))
            .args(extra);
        if let Some(l) = limit {
            c.env("RATTLE_MEMORY_LIMIT", l);
        }
        let o = c.output().unwrap();
        assert!(o.status.success(), "{}", common::stderr(&o));
        common::stderr(&o)
    };
    map(&[], "whole", None);
    // Four shards of 189 cells: each cuts a slice in two.
    for i in 0..4 {
        map(&["--shard", &format!("{i}/4")], "sh", None);
    }
    let parts: Vec<_> = (0..4)
        .map(|i| d.join(format!("sh.part-{i}-of-4.json")))
        .collect();
    ok(rattle()
        .arg("merge")
        .args(&parts)
        .arg("--out")
        .arg(d.join("merged")));
    map(&["--checkpoint", "4"], "ck", None);
    // A bound under the whole volume's estimate (about 1.8 MB) but over one slice's: the
    // volume runs in chunks of whole slices instead of being refused.
    let said = map(&[], "bounded", Some("1500000"));
    let bounded = json(&d.join("bounded.json"));
    let mem = &bounded["memory"];
    assert_eq!(mem["cells_at_once"], 63, "{mem} {said}");
    assert!(
        mem["estimated_peak_bytes"].as_f64().unwrap() <= 0.8 * 1.5e6,
        "{mem}"
    );
    assert!(said.contains("chunks"), "{said}");
    let whole = json(&d.join("whole.json"));
    assert_eq!(whole["memory"]["cells_at_once"], 189);
    for (field, _, _) in rattle::map::Fields::LAYERS {
        let a = std::fs::read(d.join(format!("whole-{field}.npy"))).unwrap();
        for other in ["merged", "ck", "bounded"] {
            let b = std::fs::read(d.join(format!("{other}-{field}.npy"))).unwrap();
            assert!(a == b, "{field}: {other} differs from the single run");
        }
    }
}

#[test]
fn bad_volumes_are_refused_before_computing() {
    let d = scratch("vol-bad");
    let cfg = d.join("vol.toml");
    std::fs::write(&cfg, volume()).unwrap();
    let out = d.join("out");
    let map = |sets: &[&str], extra: &[&str]| {
        let mut c = rattle();
        c.args(["map", "--backend", "cpu", "--config"])
            .arg(&cfg)
            .arg("--out")
            .arg(&out);
        for s in sets {
            c.args(["--set", s]);
        }
        c.args(extra);
        c
    };
    for (sets, keys) in [
        (&["map.z=R"][..], &["map.z", "map.x"][..]),
        (&["map.z=fs"], &["map.z", "map.y"]),
        (&["map.z_points=0"], &["map.z_points", "[1, 4096]"]),
        (&["map.z_points=5000"], &["map.z_points"]),
        (&["map.z_to=-1"], &["map.z_to", "(0, inf)"]),
        (&["map.z_to=1.2"], &["map.z_to", "non-zero width"]),
        (
            &["map.x_points=4096", "map.y_points=4096", "map.z_points=8"],
            &["map.z_points", "cells"],
        ),
    ] {
        refused(&mut map(sets, &[]), keys);
    }
    // A z key without map.z, and map.z without its range.
    let plane = d.join("plane.toml");
    std::fs::write(&plane, plane_text()).unwrap();
    let mut c = rattle();
    c.args(["map", "--backend", "cpu", "--config"])
        .arg(&plane)
        .args(["--set", "map.z_points=4", "--out"])
        .arg(&out);
    refused(&mut c, &["map.z_points", "map.z"]);
    let mut c = rattle();
    c.args(["map", "--backend", "cpu", "--config"])
        .arg(&plane)
        .args(["--set", "map.z=\"eta\"", "--out"])
        .arg(&out);
    refused(&mut c, &["map.z_from"]);
    // A value for the parameter z varies would be dropped unread.
    refused(&mut map(&[], &["--eta", "1.3"]), &["eta", "map.z"]);
    // Options that work on planes only, each with its reason.
    for (extra, key) in [
        (&["--refine", "4"][..], "refine"),
        (&["--compare", cfg.to_str().unwrap()], "compare"),
    ] {
        refused(&mut map(&[], extra), &[key, "volume"]);
    }
    // A volume over the bound even in chunks of rows.
    let mut c = map(&[], &[]);
    c.env("RATTLE_MEMORY_LIMIT", "20000");
    refused(&mut c, &["map.z_points", "shards"]);
    // Nothing was written by any refusal.
    let left: Vec<_> = std::fs::read_dir(&*d)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n.to_string_lossy().starts_with("out"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

fn plane_text() -> String {
    plane()
}

#[test]
fn a_volumes_boundaries_are_each_slices_own() {
    let d = scratch("vol-bounds");
    let (vol, pl) = (d.join("vol.toml"), d.join("plane.toml"));
    std::fs::write(&vol, volume()).unwrap();
    std::fs::write(&pl, plane()).unwrap();
    let run = |cfg: &Path, out: &str, extra: &[String]| {
        ok(rattle()
            .args([
                "map",
                "--backend",
                "cpu",
                "--precision",
                "f64",
                "--boundaries",
            ])
            .arg("--config")
            .arg(cfg)
            .arg("--out")
            .arg(d.join(out))
            .args(extra))
    };
    run(&vol, "v", &[]);
    let csv = std::fs::read_to_string(d.join("v-boundaries.csv")).unwrap();
    let mut lines = csv.lines();
    assert!(lines.next().unwrap().starts_with("eta,R,lambda,type,"));
    // The slices' points (on edges along x or y), then those between slices (along z).
    let all: Vec<&str> = lines.collect();
    let rows: Vec<&str> = all
        .iter()
        .filter_map(|r| r.strip_suffix(",x").or_else(|| r.strip_suffix(",y")))
        .collect();
    let between = all.iter().filter(|r| r.ends_with(",z")).count();
    assert_eq!(rows.len() + between, all.len());
    let j = json(&d.join("v-boundaries.json"));
    assert_eq!(j["z_param"], "eta");
    assert_eq!(j["points"].as_array().unwrap().len(), rows.len());
    assert_eq!(j["across"]["points"].as_array().unwrap().len(), between);
    assert!(between > 0, "no edge between slices holds a point");
    let zs: Vec<f64> = json(&d.join("v.json"))["axes"]["z_values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let mut located = 0;
    for (k, z) in zs.iter().enumerate() {
        run(
            &pl,
            &format!("m{k}"),
            &["--set".into(), format!("model.eta={z}")],
        );
        let own = std::fs::read_to_string(d.join(format!("m{k}-boundaries.csv"))).unwrap();
        let own: Vec<&str> = own.lines().skip(1).collect();
        let prefix = format!("{z},");
        let slice: Vec<&str> = rows
            .iter()
            .filter_map(|r| r.strip_prefix(prefix.as_str()))
            .collect();
        assert_eq!(slice, own, "slice {k} (eta = {z})");
        located += own.iter().filter(|r| r.contains(",true,")).count();
    }
    assert!(
        located > 0,
        "no change located on any slice: the test compares nothing"
    );
    // `rattle boundaries PREFIX` on the volume written without them: the same points.
    ok(rattle()
        .args(["map", "--backend", "cpu", "--precision", "f64", "--config"])
        .arg(&vol)
        .arg("--out")
        .arg(d.join("w")));
    let out = rattle()
        .arg("boundaries")
        .arg(d.join("w"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let again = std::fs::read_to_string(d.join("w-boundaries.csv")).unwrap();
    assert_eq!(again, csv);
    // The minutes after the map are told: each slice's line as it ends, in order, then the
    // phases between slices, with the counts the JSON holds.
    let log = String::from_utf8_lossy(&out.stderr);
    let mut at = 0;
    for (k, z) in zs.iter().enumerate() {
        let line = format!("boundaries: slice {} of {} (eta = {z}): ", k + 1, zs.len());
        let found = log[at..]
            .find(&line)
            .unwrap_or_else(|| panic!("no `{line}` in\n{log}"));
        at += found + line.len();
    }
    let across = format!(
        "boundaries between slices: {} edges between classes",
        j["across"]["edges"]
    );
    assert!(
        log[at..].contains(&across),
        "no `{across}` after the slices in\n{log}"
    );
    assert!(log[at..].contains(&format!("{} coexistences checked", j["across"]["claims"])));
}
