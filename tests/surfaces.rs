//! A volume's boundaries between slices and its surfaces (`rattle map --boundaries` on a
//! volume): the period-1 cycle's doubling located along eta on the edges between two slices
//! around Fig. 2's point, each point judged by the independent reference (exact motion between
//! events, its own Newton and multipliers: `rattle::reference::dry`), the doubling sheet one
//! connected mesh through Fig. 2's point, and the PLY read back by a parser of its own.

use rattle::config::Config;
use rattle::reference::dry::DryReference;
use std::collections::HashSet;
use std::path::Path;

mod common;
use common::{json, npy, ok, rattle, scratch};

/// Fig. 2's model (N = 256) on R 0.59-0.61 x lambda 0.018-0.022 (4 x 4 cells) at eta 1.355 and
/// 1.385: the period-1 cycle's doubling (eta 1.37059 at R 0.6, lambda 0.02) lies between the
/// slices.
fn volume(dir: &Path) -> std::path::PathBuf {
    let model = common::fig2_model();
    let path = dir.join("v.toml");
    std::fs::write(
        &path,
        format!(
            "{model}\n[map]\nx = \"R\"\nx_from = 0.595\nx_to = 0.605\nx_points = 4\n\
             y = \"lambda\"\ny_from = 0.019\ny_to = 0.021\ny_points = 4\n\
             z = \"eta\"\nz_from = 1.34\nz_to = 1.40\nz_points = 2\n"
        ),
    )
    .unwrap();
    path
}

/// A PLY file as its parser of its own reads it: the header's elements with their properties,
/// then each element's rows of numbers.
struct Ply {
    elements: Vec<(String, usize, Vec<String>)>,
    rows: Vec<Vec<Vec<f64>>>,
}

fn read_ply(text: &str) -> Ply {
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("ply"));
    assert_eq!(lines.next(), Some("format ascii 1.0"));
    let mut elements: Vec<(String, usize, Vec<String>)> = Vec::new();
    for line in lines.by_ref() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w[..] {
            ["end_header"] => break,
            ["comment", ..] => {}
            ["element", name, n] => elements.push((name.into(), n.parse().unwrap(), Vec::new())),
            ["property", "list", _, _, name] | ["property", _, name] => {
                elements.last_mut().unwrap().2.push(name.into());
            }
            _ => panic!("a header line PLY does not have: {line}"),
        }
    }
    let mut rows = Vec::new();
    for (_, n, _) in &elements {
        let r: Vec<Vec<f64>> = lines
            .by_ref()
            .take(*n)
            .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
            .collect();
        assert_eq!(r.len(), *n);
        rows.push(r);
    }
    assert_eq!(lines.next(), None, "lines after the last element");
    Ply { elements, rows }
}

#[test]
fn a_doubling_between_slices_is_located_judged_and_meshed_through_fig2s_point() {
    let d = scratch("surfaces");
    let cfg_path = volume(&d);
    let run = common::map(&cfg_path, &d.join("v"), &["--boundaries"]);
    assert!(run.status.success(), "{}", common::stderr(&run));
    let j = json(&d.join("v-boundaries.json"));
    let across = j["across"]["points"].as_array().unwrap();
    let doublings: Vec<&serde_json::Value> = across
        .iter()
        .filter(|p| p["type"] == "period_doubling" && p["located"] == true)
        .collect();
    eprintln!(
        "{} of {} points between the slices are doublings",
        doublings.len(),
        across.len()
    );
    assert!(doublings.len() >= 8, "{}", j["across"]);

    // Each judged by the reference at its own (R, lambda), by its own claim: its Newton from
    // the continued cell's final state, that cycle continued in 16 steps of eta to 1/64 of the
    // edge before the point stays stable (half the way where the point is nearer its cell); 1/64 past it, continued once more, it is unstable
    // through -1 (a real multiplier below -1) or, seen from the doubled side, has merged into
    // its half (its least period half the period).
    let cfg = Config::load(&cfg_path, &[]).unwrap();
    let zeno = cfg.settings().zeno_speed;
    let state: Vec<f64> = npy(&d.join("v-state.npy"));
    let zs = [1.355, 1.385];
    let edge = zs[1] - zs[0];
    for p in &doublings {
        let (x, y, z) = (
            p["x"].as_f64().unwrap(),
            p["y"].as_f64().unwrap(),
            p["z"].as_f64().unwrap(),
        );
        let n = p["period"].as_u64().unwrap() as u32;
        let from = p["from"].as_u64().unwrap() as usize;
        let start = zs[from / 16];
        let toward = (z - start).signum();
        let at = |eta: f64| {
            let mut q = cfg.params();
            cfg.map.x.set(&mut q, x);
            cfg.map.y.set(&mut q, y);
            rattle::model::Param::Eta.set(&mut q, eta);
            DryReference::new(&q, 1024, zeno).unwrap()
        };
        let mut last: [f64; 4] = state[4 * from..4 * from + 4].try_into().unwrap();
        // (Half the way from the cell where the point lies closer than that to it.)
        let before = z - toward * (edge / 64.0).min(0.5 * (z - start).abs());
        for k in 0..=16 {
            let eta = start + (before - start) * f64::from(k) / 16.0;
            let c = at(eta)
                .cycle(last, n)
                .filter(|c| c.stable() && c.period == n)
                .unwrap_or_else(|| {
                    panic!("the reference's period-{n} is not stable at {eta}: {p}")
                });
            last = c.point;
        }
        let past = at(z + toward * edge / 64.0)
            .cycle(last, n)
            .expect("the reference's cycle past the point");
        let lead = past.lead();
        eprintln!(
            "doubling of period-{n} at R {x:.5}, lambda {y:.5}: eta {z:.6}; past it period {} \
             with {lead:?}",
            past.period
        );
        let through = lead[1] == 0.0 && lead[0] < -1.0;
        let merged = n.is_multiple_of(2) && past.period == n / 2;
        assert!(through || merged, "{lead:?}, period {} at {p}", past.period);
    }

    // The sheet: one connected mesh of the period-1 cycle's doublings, through Fig. 2's point.
    let sheets: Vec<&serde_json::Value> = j["surfaces"]["sheets"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| s["type"] == "period_doubling" && s["class"] == "period-1")
        .collect();
    assert_eq!(sheets.len(), 1, "{}", j["surfaces"]);
    // Through each of the 3 x 3 cubes (the points between the slices and, where the lower
    // slice holds both classes, those within it).
    assert!(
        sheets[0]["triangles"].as_u64().unwrap() >= 9,
        "{}",
        sheets[0]
    );

    let ply = read_ply(&std::fs::read_to_string(d.join("v-surfaces.ply")).unwrap());
    let names = |e: usize| ply.elements[e].2.join(" ");
    assert_eq!(ply.elements[0].0, "vertex");
    assert_eq!(names(0), "x y z type period sheet");
    assert_eq!(ply.elements[1].0, "face");
    assert_eq!(names(1), "vertex_indices type period sheet");
    let (verts, faces) = (&ply.rows[0], &ply.rows[1]);
    let sheet = j["surfaces"]["sheets"]
        .as_array()
        .unwrap()
        .iter()
        .position(|s| s == sheets[0])
        .unwrap() as f64;
    let mut seen = HashSet::new();
    let mut nearest = f64::INFINITY;
    for f in faces {
        assert_eq!(f.len(), 7, "{f:?}");
        assert_eq!(f[0], 3.0);
        let idx: Vec<usize> = f[1..4].iter().map(|&v| v as usize).collect();
        assert!(idx.iter().all(|&i| i < verts.len()), "{f:?}");
        let mut key = idx.clone();
        key.sort_unstable();
        key.dedup();
        assert_eq!(key.len(), 3, "a degenerate face {f:?}");
        assert!(seen.insert(key), "a duplicate face {f:?}");
        let t: [[f64; 3]; 3] = std::array::from_fn(|k| {
            let v = &verts[idx[k]];
            [v[0], v[1], v[2]]
        });
        // No face of no area (in grid units: R cells 0.005, lambda 0.001, eta 0.03).
        let g = |p: [f64; 3]| [p[0] / 0.005, p[1] / 0.001, p[2] / 0.03];
        let (a, b, c) = (g(t[0]), g(t[1]), g(t[2]));
        let (u, v) = (
            [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
            [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
        );
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        assert!(n.iter().map(|x| x * x).sum::<f64>() > 1e-12, "{f:?}");
        // The face's properties are its vertices'.
        for &i in &idx {
            assert_eq!(verts[i][3..6], f[4..7], "{f:?}");
        }
        if f[6] == sheet {
            assert_eq!(
                (f[4], f[5]),
                (0.0, 1.0),
                "a period-1 doubling: type 0, period 1"
            );
            nearest = nearest.min(rattle::map::surfaces::distance([0.6, 0.02, 1.37059], t));
        }
    }
    eprintln!("the doubling sheet passes {nearest:.2e} from Fig. 2's point");
    assert!(nearest < 1e-3, "{nearest}");

    // `rattle boundaries PREFIX` on the volume written without them: the same points between
    // the slices and the same meshes.
    let run = common::map(&cfg_path, &d.join("w"), &[]);
    assert!(run.status.success(), "{}", common::stderr(&run));
    ok(rattle().arg("boundaries").arg(d.join("w")));
    let w = json(&d.join("w-boundaries.json"));
    assert_eq!(w["across"]["points"], j["across"]["points"]);
    assert_eq!(w["surfaces"], j["surfaces"]);
    assert_eq!(
        std::fs::read(d.join("w-surfaces.ply")).unwrap(),
        std::fs::read(d.join("v-surfaces.ply")).unwrap()
    );
}
