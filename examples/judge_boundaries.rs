//! The independent judge of a map's boundary points (`rattle map --boundaries`), by the exact
//! system's multipliers: for a fixed-seed sample of points, Newton's method on the stroboscopic
//! map of the reference of `rattle::reference::dry` (exact motion between events under Coulomb
//! friction; no code of the integrator, the classifier or rattle's Newton), with its Jacobian by
//! central differences and its multipliers from nalgebra, at 1/64 of a cell before and after
//! the point along its edge.
//!
//! `cargo run --release --example judge_boundaries -- CONFIG PREFIX COUNT SEED [TYPE]`
//! (TYPE: only the points of that type, e.g. `grazing`). A volume's points are judged in the
//! whole volume: its slices' along x or y, those between slices (`across`) along z; with
//! `JUDGE_EDGES=slices` or `JUDGE_EDGES=across` only those.
//!
//! A located point says: the cycle of period n (`period`) continued from the cell `from`
//! stops being stable here, of `type`. The judge continues its own cycle: Newton at the cell
//! from the cell's final state (the map's `state` layer: a start only), then 64 steps to 1/64
//! of a cell before the point (where its Newton fails, as it does where an impact of the cycle
//! crosses phase 0 and the stroboscopic map jumps, Newton from its own motion 60 cycles on, on a
//! stable cycle of period n whose section's positions lie within 1e-2 of the last one's). Right
//! where that cycle stays stable up to there, and after the point (Newton from it, the same way):
//! - `period_doubling`: the continued cycle is unstable through -1 (a real multiplier below
//!   -1), or, seen from the doubled side, it has merged into its half (its least period n/2),
//!   or no period-n cycle is found and Newton for period n/2 finds a stable one whose section's
//!   positions lie within 5e-2 of the last one's (the half, where Newton for the half traversed
//!   twice fails: its multiplier is near +1);
//! - `neimark_sacker`: unstable through a complex pair (modulus above 1);
//! - `fold`: no cycle of period n is found from the last one (none, or Newton lands on a cycle
//!   of another period), or it is unstable through +1;
//! - an `undetermined` end whose reason says the exact system's end is not resolved (a jump of
//!   the integrator's map, the search's solves run out): nothing more than the cycle stable up
//!   to there (its verdict says so);
//! - `grazing`, `stick_onset`, `stick_loss`, `undetermined` (located ends): no stable cycle of
//!   period n continues, and for `grazing` (`stick_loss`) the reference's cycle has an impact
//!   speed or a clearance at a reversal (a stick's length) that vanishes at the point: its zero,
//!   extrapolated from 1/64 and 1/512 of a cell before the point, within 1e-3 of a cell of it
//!   (`stick_onset` and `undetermined`: the end only);
//!
//! and the class after the point (the JSON's `change[1]`) is what the reference's motion
//! reaches 1/32 of a cell past it (or half the way to the edge's next point), run 3,156 periods
//! from the point's own cycle or from the far cell's final state: `period-m` where Newton
//! there finds a stable cycle of least period m, or the motion's last 256 periods repeat at
//! least lag m within 1e-6 (past a doubling the daughter's multiplier is near +1, where the
//! central differences' multipliers may not confirm it); `no_impact` where the last 256
//! periods hold no impact; any other class where the motion repeats at no lag up to 128 (a
//! check of "not periodic", weaker than the class's own claim); `unresolved` is never wrong.
//!
//! `coexistence` points: at the edge's midpoint the reference's Newton from the `from` cell's
//! final state finds a stable cycle of the cell's period, and the other cell's final state,
//! run there for 10^4 periods, is not on it. A side the reference cannot start (a section at
//! rest, where central differences cross the at-rest rule) is counted "cannot tell".
//! Prints one line per point and the counts by type.

use rattle::config::Config;
use rattle::reference::dry::DryReference;
use std::collections::BTreeMap;
use std::path::Path;

#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Debug)]
enum Verdict {
    Right,
    Wrong,
    CannotTell,
}

fn main() -> anyhow::Result<()> {
    let a: Vec<String> = std::env::args().collect();
    anyhow::ensure!(
        a.len() == 5 || a.len() == 6,
        "usage: judge_boundaries CONFIG PREFIX COUNT SEED [TYPE]"
    );
    let only = a.get(5).cloned();
    let cfg = Config::load(Path::new(&a[1]), &[])?;
    let prefix = &a[2];
    let count: usize = a[3].parse()?;
    let mut rng = rattle::stats::SplitMix(a[4].parse()?);
    let b: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(format!(
        "{prefix}-boundaries.json"
    ))?)?;
    let bytes = std::fs::read(format!("{prefix}-state.npy"))?;
    let state: Vec<f64> = npyz::NpyFile::new(&bytes[..])?.into_vec()?;
    let bytes = std::fs::read(format!("{prefix}-class.npy"))?;
    let class: Vec<i32> = npyz::NpyFile::new(&bytes[..])?.into_vec()?;
    let m = &cfg.map;
    let (nx, ny) = (m.x_points as usize, m.y_points as usize);
    let xs = Config::map_axis(m.x_from, m.x_to, m.x_points);
    let ys = Config::map_axis(m.y_from, m.y_to, m.y_points);
    // A volume's z values (its slices' points carry their slice's z; those between slices,
    // `across`, the z of their change).
    let z = cfg.z_axis();
    let zs = z.as_ref().map_or_else(|| vec![f64::NAN], |z| z.values());
    let coords = |c: usize| -> [f64; 3] { [xs[c % nx], ys[(c / nx) % ny], zs[c / (nx * ny)]] };
    let zeno = cfg.settings().zeno_speed;
    // Which points: JUDGE_EDGES=slices (within the slices), across (between them) or all.
    let edges = std::env::var("JUDGE_EDGES").unwrap_or_else(|_| "all".into());
    let empty = Vec::new();
    let listed = |v: &serde_json::Value| v.as_array().unwrap_or(&empty).clone();
    let (within, between) = (listed(&b["points"]), listed(&b["across"]["points"]));
    // Each point with its cells in the whole volume and the axis of its edge.
    let placed = |p: &serde_json::Value, across: bool| -> Pt {
        let mut cells = [0, 1].map(|k| p["cells"][k].as_u64().unwrap() as usize);
        if !across && let Some(z) = p["z"].as_f64() {
            let k = zs.iter().position(|&v| v == z).expect("a slice's z");
            cells = cells.map(|c| c + k * nx * ny);
        }
        // y before x: a grid one cell wide has y edges of one cell's step.
        let axis = match cells[1] - cells[0] {
            d if d == nx * ny => 2,
            d if d == nx => 1,
            _ => 0,
        };
        let z = p["z"].as_f64().unwrap_or(f64::NAN);
        let pos = [p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap(), z];
        Pt {
            json: p.clone(),
            cells,
            axis,
            pos,
            across,
        }
    };
    let mut all: Vec<Pt> = Vec::new();
    if edges != "across" {
        all.extend(within.iter().map(|p| placed(p, false)));
    }
    if edges != "slices" {
        all.extend(between.iter().map(|p| placed(p, true)));
    }
    // Located points and coexistence points are judged; the others say nothing to judge.
    let mut pool: Vec<&Pt> = all
        .iter()
        .filter(|q| q.json["located"] == true || q.json["type"] == "coexistence")
        .filter(|q| only.as_ref().is_none_or(|t| q.json["type"] == t.as_str()))
        .collect();
    // Fisher-Yates with the fixed generator, then the first `count`.
    for i in (1..pool.len()).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        pool.swap(i, j);
    }
    pool.truncate(count);
    let reference = |at: [f64; 3]| {
        let mut p = cfg.params();
        m.x.set(&mut p, at[0]);
        m.y.set(&mut p, at[1]);
        if let Some(z) = &z {
            z.param.set(&mut p, at[2]);
        }
        DryReference::new(&p, 1024, zeno).ok()
    };
    let cell_state = |c: usize| -> [f64; 4] { std::array::from_fn(|i| state[4 * c + i]) };
    let judge = |q: &Pt| -> (Verdict, String) {
        let (p, cells, axis, pos) = (&q.json, q.cells, q.axis, q.pos);
        let ty = p["type"].as_str().unwrap();
        if ty == "coexistence" {
            let Some(r) = reference(pos) else {
                return (Verdict::CannotTell, "no reference".into());
            };
            // The side whose class is a cycle and whose cycle the reference finds stable here.
            for k in 0..2 {
                let (c, o) = (cells[k], cells[1 - k]);
                if class[c] <= 0 {
                    continue;
                }
                let Some(cy) = r.cycle(cell_state(c), class[c] as u32) else {
                    continue;
                };
                if !cy.stable() || cy.period != class[c] as u32 {
                    continue;
                }
                let mut st = r.start(cell_state(o));
                let Ok(s) = r.run(&mut st, 10_000, None) else {
                    return (Verdict::CannotTell, "other side not followed".into());
                };
                let end = s[s.len() - 1];
                let scale = end.iter().fold(1.0f64, |a, v| a.max(v.abs()));
                let mut on = r.start(cy.point);
                let orbit = r.run(&mut on, cy.period, None).unwrap_or_default();
                let near = orbit
                    .iter()
                    .any(|q| (0..4).all(|i| (q[i] - end[i]).abs() < 1e-4 * scale));
                return if near {
                    (
                        Verdict::Wrong,
                        format!("other side ends on the period-{} cycle", cy.period),
                    )
                } else {
                    (
                        Verdict::Right,
                        format!("period-{} stable, other side apart", cy.period),
                    )
                };
            }
            return (
                Verdict::Wrong,
                "no stable cycle of either side's class".into(),
            );
        }
        let n = p["period"].as_u64().unwrap() as u32;
        // A slice's point names its cell in the slice: the same cell of the volume.
        let from = p["from"].as_u64().unwrap() as usize
            + (cells[0] - p["cells"][0].as_u64().unwrap() as usize);
        let other = if from == cells[0] { cells[1] } else { cells[0] };
        let (cf, co) = (coords(from)[axis], coords(other)[axis]);
        let delta = (co - cf) / 64.0;
        let along = |v: f64| {
            let mut at = pos;
            at[axis] = v;
            at
        };
        let at = |d: f64| reference(along(pos[axis] + d));
        let Some(ra) = at(delta) else {
            return (Verdict::CannotTell, "no reference".into());
        };
        // The reference's own continuation from the `from` cell's attractor: Newton at the
        // cell from its final state, then 64 steps to 1/64 of a cell before the point.
        let here = |v: f64| reference(along(v));
        let v_point = pos[axis];
        // 1/64 of a cell before the point, or half way from the cell where the point lies
        // closer to the cell's centre than that.
        let v_before = if (v_point - cf).abs() > delta.abs() {
            v_point - delta
        } else {
            0.5 * (v_point + cf)
        };
        let own = class[from] == n as i32;
        // The reference's period-n cycle at `r` from `x`: its Newton, or where that fails, its
        // Newton from its own motion 60 cycles on from `x` where that motion is on a stable
        // period-n cycle whose section's positions lie within 1e-2 of `x`'s. (Its stroboscopic
        // map jumps where an impact of the cycle crosses phase 0, as rattle's does: Newton
        // from the other side of the impact fails while the motion goes on.)
        let cycle_of = |r: &DryReference, x: [f64; 4]| {
            r.cycle(x, n).or_else(|| {
                let mut st = r.start(x);
                r.run(&mut st, 60 * n, None).ok()?;
                r.cycle(st.y, n).filter(|c| {
                    c.stable()
                        && c.period == n
                        && (c.point[0] - x[0]).abs().max((c.point[2] - x[2]).abs()) < 1e-2
                })
            })
        };
        // A point on a branch that followed an earlier change on the edge (a doubled cycle):
        // the reference's cycle from the point's section (a start only) 1/64 of a cell before
        // it; the cell's own cycle is continued from the cell.
        let (v0, start) = if own {
            (cf, cell_state(from))
        } else {
            let s: Vec<f64> = p["section"]
                .as_array()
                .map(|a| a.iter().filter_map(|v| v.as_f64()).collect())
                .unwrap_or_default();
            let Ok(s) = <[f64; 4]>::try_from(s) else {
                return (Verdict::CannotTell, "no section".into());
            };
            (v_before, s)
        };
        let Some(r0) = here(v0) else {
            return (Verdict::CannotTell, "no reference".into());
        };
        let Some(mut before) = r0.cycle(start, n) else {
            return (
                Verdict::CannotTell,
                "no cycle at the cell (reference)".into(),
            );
        };
        if !before.stable() || before.period != n {
            return (
                Verdict::CannotTell,
                format!(
                    "the cell's own cycle: period {} lead {:?}",
                    before.period,
                    before.lead()
                ),
            );
        }
        for k in (1..=STEPS).filter(|_| own) {
            let v = cf + (v_before - cf) * f64::from(k) / f64::from(STEPS);
            let Some(r) = here(v) else {
                return (Verdict::CannotTell, "no reference".into());
            };
            match cycle_of(&r, before.point) {
                Some(c) if c.stable() && c.period == n => before = c,
                Some(c) => {
                    return (
                        Verdict::Wrong,
                        format!(
                            "the reference's period-{n} cycle loses stability at {:.6} before \
                             the point (period {}, lead {:.4?})",
                            v,
                            c.period,
                            c.lead()
                        ),
                    );
                }
                None => {
                    return (
                        Verdict::Wrong,
                        format!("the reference's period-{n} cycle ends at {v:.6} before the point"),
                    );
                }
            }
        }
        let after = cycle_of(&ra, before.point);
        let desc = match &after {
            Some(c) => format!(
                "before lead {:.4?}, after period {} lead {:.4?}",
                before.lead(),
                c.period,
                c.lead()
            ),
            None => format!("before lead {:.4?}, after no cycle", before.lead()),
        };
        // Where no period-n cycle is found past the point: its half there (Newton for period
        // n/2 from the last cycle), stable and beside its orbit, or `None`.
        let half = (after.is_none() && n.is_multiple_of(2))
            .then(|| ra.cycle(before.point, n / 2))
            .flatten();
        let near_half = half.as_ref().is_some_and(|c| {
            c.stable()
                && c.period == n / 2
                && (c.point[0] - before.point[0])
                    .abs()
                    .max((c.point[2] - before.point[2]).abs())
                    < 5e-2
        });
        let desc = match &half {
            Some(c) => format!(
                "{desc}, its half period {} lead {:.4?} at {:.1e}",
                c.period,
                c.lead(),
                (c.point[0] - before.point[0])
                    .abs()
                    .max((c.point[2] - before.point[2]).abs())
            ),
            None => desc,
        };
        // A non-smooth end claims that a feature of the cycle vanishes at the point: the
        // reference's cycle 1/64 and 1/512 of a cell before it, the feature's zero extrapolated
        // from there (linearly for a clearance or a stick's length, in its square for an impact
        // speed) within 1e-3 of a cell of the point.
        let vanishes = |kinds: &[usize]| -> (bool, String) {
            let v_near = v_point - (v_point - v_before) / 8.0;
            let Some(r512) = here(v_near) else {
                return (false, "no reference 1/512 before".into());
            };
            let Some(near) = r512
                .cycle(before.point, n)
                .filter(|c| c.stable() && c.period == n)
            else {
                return (false, "no stable cycle 1/512 of a cell before".into());
            };
            let Some(r64) = here(v_before) else {
                return (false, "no reference".into());
            };
            let (f8, f64_) = (features(&r64, &before, n), features(&r512, &near, n));
            // A third distance, 1/4096 of a cell before, where the reference's cycle is
            // still stable there: what tells the stick length's law (below).
            let f4096 = here(v_point - (v_point - v_before) / 64.0).and_then(|r| {
                r.cycle(near.point, n)
                    .filter(|c| c.stable() && c.period == n)
                    .map(|c| features(&r, &c, n))
            });
            let cell = (co - cf).abs();
            let d1 = (v_point - v_before).abs();
            let d2 = d1 / 8.0;
            // The zero's distance before the point (negative: beyond it), in cells, from
            // the feature in the power that is linear in the distance at two distances.
            let zero =
                |(a, da): (f64, f64), (b, db): (f64, f64)| (db - b * (da - db) / (a - b)) / cell;
            let best = kinds
                .iter()
                .filter(|&&k| f8[k].is_finite() && f64_[k].is_finite() && f8[k] > 0.0)
                .map(|&k| {
                    // An impact speed vanishes like the square root of the distance, a
                    // clearance linearly. A stick phase's length does either: linearly where
                    // the friction force's excess crosses zero at the stick's start, like the
                    // square root where the stick vanishes at that excess's minimum (period-1
                    // stick losses of two maps: the length shrinks 0.354 = 8^-1/2 from 1/64 to
                    // 1/512 of a cell). Its law is the one whose line through the two nearer
                    // distances (1/512, 1/4096) meets the third (1/64) closer.
                    let square = match (k, f4096) {
                        (0, _) => true,
                        (2, Some(f3)) if f3[k].is_finite() => {
                            let d3 = d1 / 64.0;
                            let misfit = |pw: i32| {
                                let g = |f: f64| f.powi(pw);
                                let slope = (g(f64_[k]) - g(f3[k])) / (d2 - d3);
                                let at_d1 = g(f3[k]) + slope * (d1 - d3);
                                (at_d1 / g(f8[k]) - 1.0).abs()
                            };
                            misfit(2) < misfit(1)
                        }
                        _ => false,
                    };
                    let sq = |f: f64| if square { f * f } else { f };
                    (
                        k,
                        f64_[k] / f8[k],
                        zero((sq(f8[k]), d1), (sq(f64_[k]), d2)),
                        square,
                    )
                })
                .min_by(|x, y| x.2.abs().total_cmp(&y.2.abs()));
            match best {
                Some((k, ratio, d0, square)) => (
                    ratio < 0.5 && d0.abs() <= 1e-3,
                    format!(
                        "{} {:.3e} -> {:.3e} (ratio {ratio:.3}), zero {d0:+.2e} cell from the \
                         point ({})",
                        FEATURES[k],
                        f8[k],
                        f64_[k],
                        if square { "in its square" } else { "linear" }
                    ),
                ),
                None => (false, "no feature on the cycle".into()),
            }
        };
        let feature = match ty {
            "grazing" => Some(vanishes(&[0, 1])),
            "stick_loss" => Some(vanishes(&[2])),
            _ => None,
        };
        let desc = match &feature {
            Some((_, why)) => format!("{desc}; {why}"),
            None => desc,
        };
        // A fold claims the cycle ceases to exist at the point. Where Newton after it, from
        // 1/32 of a cell away, lands on a cycle of the same period that is not unstable
        // through +1 (another cycle, or the same one gone on), the reference's own cycle is
        // continued across the point in 64 steps: the claim holds where that branch ends
        // within 1/64 of a cell of the point (Newton fails, or jumps to another cycle, or
        // the cycle turns unstable through +1); it fails where the branch goes on.
        // Unstable through +1: the far side of a fold.
        let past_fold = |c: &rattle::reference::dry::RefCycle| {
            let l = c.lead();
            !c.stable() && l[1] == 0.0 && l[0] > 1.0
        };
        let branch_ends = || -> Option<f64> {
            let v_after = v_point + delta;
            let mut last = before.point;
            for k in 1..=STEPS {
                let v = v_before + (v_after - v_before) * f64::from(k) / f64::from(STEPS);
                let c = here(v).and_then(|r| r.cycle(last, n));
                let scale = last.iter().fold(1.0f64, |a, x| a.max(x.abs()));
                let gone = match &c {
                    None => true,
                    Some(c) => {
                        c.period != n
                            || (0..4).any(|i| (c.point[i] - last[i]).abs() > 0.1 * scale)
                            || past_fold(c)
                    }
                };
                if gone {
                    return Some(v);
                }
                last = c.map_or(last, |c| c.point);
            }
            None
        };
        let fold_end = if ty == "fold"
            && after
                .as_ref()
                .is_some_and(|c| c.period == n && !past_fold(c))
        {
            Some(branch_ends())
        } else {
            None
        };
        let desc = match fold_end {
            Some(Some(v)) => format!(
                "{desc}; the reference's branch continued across ends at {:+.2e} cell from the \
                 point",
                (v - v_point) / (co - cf)
            ),
            Some(None) => format!("{desc}; the reference's branch goes on across the point"),
            None => desc,
        };
        // An `undetermined` end whose reason leaves the exact system's end open (a jump of
        // the integrator's map, the search's solves run out) claims of the exact system only
        // that the cycle is stable up to the point: checked above.
        let open_end = ty == "undetermined"
            && p["reason"]
                .as_str()
                .is_some_and(|r| r.contains("is not resolved"));
        let desc = if open_end {
            format!("{desc}; its reason leaves the end open")
        } else {
            desc
        };
        let ok = feature.as_ref().is_none_or(|f| f.0)
            && match (ty, &after) {
                _ if open_end => true,
                // Through -1, or seen from the doubled side: merged into the half.
                ("period_doubling", Some(c)) => {
                    let l = c.lead();
                    c.period < n || (!c.stable() && l[1] == 0.0 && l[0] < -1.0)
                }
                ("neimark_sacker", Some(c)) => !c.stable() && c.lead()[1] != 0.0,
                ("fold", None) => true,
                // Newton from the last cycle lands on another cycle of another period: the
                // period-n cycle is gone.
                ("fold", Some(c)) if c.period != n => true,
                ("fold", Some(c)) => {
                    past_fold(c)
                        || fold_end
                            .is_some_and(|e| e.is_some_and(|v| (v - v_point).abs() <= delta.abs()))
                }
                // Seen from the doubled side: past the point no period-n cycle (the reference's
                // Newton for it fails where it would be the half traversed twice, its
                // multiplier near +1), and its half is there, stable, beside its orbit.
                ("period_doubling", None) => near_half,
                ("neimark_sacker", None) => false,
                (_, None) => true,
                (_, Some(c)) => !(c.stable() && c.period == n),
            };
        if !ok {
            return (Verdict::Wrong, desc);
        }
        // The class after the point (MODEL.md's full claim): what the motion reaches just
        // beyond it, 1/32 of a cell on (or half the way to the edge's next point), from the
        // point's own cycle and from the far cell's final state.
        let next = all
            .iter()
            .filter(|o| o.cells == q.cells && o.json["located"] == true)
            .map(|o| (o.pos[axis] - v_point) * (co - cf).signum())
            .filter(|&g| g > 0.0)
            .fold(f64::INFINITY, f64::min);
        let step = (delta.abs() / 2.0).min(0.5 * next) * (co - cf).signum();
        let claim = p["change"][1].as_str().unwrap_or("unresolved");
        let (right, why) = match here(v_point + step) {
            Some(r) => reaches(&r, claim, &[before.point, cell_state(other)]),
            None => (false, "no reference after".into()),
        };
        let desc = format!("{desc}; after {claim}: {why}");
        (
            if right {
                Verdict::Right
            } else {
                Verdict::Wrong
            },
            desc,
        )
    };
    let verdicts: Vec<_> = {
        use rayon::prelude::*;
        pool.par_iter().map(|p| judge(p)).collect()
    };
    let mut by_type: BTreeMap<(String, Verdict), usize> = BTreeMap::new();
    for (q, (v, why)) in pool.iter().zip(&verdicts) {
        let p = &q.json;
        let ty = p["type"].as_str().unwrap().to_string();
        *by_type.entry((ty.clone(), *v)).or_default() += 1;
        let z = if q.pos[2].is_nan() {
            String::new()
        } else {
            format!(
                ", {:.6}{}",
                q.pos[2],
                if q.across { " between slices" } else { "" }
            )
        };
        println!(
            "{ty} at ({:.6}, {:.6}{z}) {} | {}: {v:?}: {why}",
            q.pos[0],
            q.pos[1],
            p["classes"][0].as_str().unwrap(),
            p["classes"][1].as_str().unwrap(),
        );
    }
    for ((ty, v), k) in &by_type {
        println!("{ty}: {v:?} {k}");
    }
    let right = verdicts.iter().filter(|v| v.0 == Verdict::Right).count();
    let told = verdicts
        .iter()
        .filter(|v| v.0 != Verdict::CannotTell)
        .count();
    println!(
        "{right} of {told} points the judge could tell right ({:.1}%), {} cannot tell",
        100.0 * right as f64 / told.max(1) as f64,
        pool.len() - told
    );
    Ok(())
}

/// A point to judge: its JSON, its cells in the whole volume (a plane's own), the axis of its
/// edge (0: x, 1: y, 2: z), where it lies, and whether it is between slices.
struct Pt {
    json: serde_json::Value,
    cells: [usize; 2],
    axis: usize,
    pos: [f64; 3],
    across: bool,
}

/// The names of [`features`]'s values.
/// Steps of the reference's own continuation from the cell to the point.
const STEPS: u32 = 64;

const FEATURES: [&str; 3] = ["impact speed", "clearance", "stick length"];

/// The vanishing candidates of the reference's cycle `c` of period `n` over one cycle (after
/// one cycle from its point): the slowest impact's relative speed, the least clearance
/// r - |z| where the relative velocity passes zero (z' = y4 - y2: the clearance's minima), the
/// shortest stick or lock (in periods). Infinity where the cycle has none.
fn features(r: &DryReference, c: &rattle::reference::dry::RefCycle, n: u32) -> [f64; 3] {
    let mut log = Vec::new();
    let mut st = r.start(c.point);
    if r.run(&mut st, 2 * n, Some(&mut log)).is_err() {
        return [f64::NAN; 3];
    }
    let mut out = [f64::INFINITY; 3];
    let mut held_from: Option<f64> = None;
    use rattle::reference::dry::RefMode;
    for e in &log {
        let second = e.time >= f64::from(n);
        if second && e.kind.starts_with("impact") {
            out[0] = out[0].min(e.v_before.abs());
        }
        if second && e.kind == "reversal" {
            let z = e.y_before[2] - e.y_before[0];
            out[1] = out[1].min((r.clearance() - z.abs()).max(0.0));
        }
        let held = matches!(e.mode, RefMode::Stick | RefMode::Lock(_));
        match (held, held_from) {
            (true, None) => held_from = Some(e.time),
            (false, Some(t)) => {
                if second && t >= f64::from(n) {
                    out[2] = out[2].min(e.time - t);
                }
                held_from = None;
            }
            _ => {}
        }
    }
    out
}

/// Whether the reference's motion from one of `starts`, run 3,156 periods, reaches the class
/// named `claim` (see the module's comment), and what it reached.
fn reaches(r: &DryReference, claim: &str, starts: &[[f64; 4]]) -> (bool, String) {
    if claim == "unresolved" {
        return (true, "unresolved is never wrong".into());
    }
    let mut seen = Vec::new();
    for &y in starts {
        if y.iter().any(|v| !v.is_finite()) {
            continue;
        }
        let mut st = r.start(y);
        if r.run(&mut st, 2900, None).is_err() {
            continue;
        }
        let mut log = Vec::new();
        let Ok(s) = r.run(&mut st, 256, Some(&mut log)) else {
            continue;
        };
        let end = s[s.len() - 1];
        let scale = end.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        let lag = (1..=128).find(|&n| {
            (n..s.len()).all(|k| (0..4).all(|c| (s[k][c] - s[k - n][c]).abs() < 1e-6 * scale))
        });
        let impacts = log.iter().any(|e| e.kind.starts_with("impact"));
        let right = match claim.strip_prefix("period-") {
            Some(m) => {
                // Newton's stable cycle, or the motion itself on a cycle of least period m:
                // just past a doubling the daughter's multiplier is near +1, where the
                // multipliers by central differences cannot confirm what the motion shows.
                let m: u32 = m.parse().unwrap_or(0);
                lag == Some(m as usize)
                    || r.cycle(end, m).is_some_and(|c| c.stable() && c.period == m)
            }
            None if claim == "no_impact" => !impacts,
            None => lag.is_none(),
        };
        seen.push(match lag {
            Some(n) => format!("lag {n}"),
            None if !impacts => "no impact".into(),
            None => "no lag <= 128".into(),
        });
        if right {
            return (true, seen.join(", "));
        }
    }
    (false, format!("reached {}", seen.join(", ")))
}
