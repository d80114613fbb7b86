//! Coarse-to-fine maps (`rattle map --refine K`): compute every K-th cell of the grid, then
//! refine only the blocks whose four corners differ in class, hold coexisting attractors, or
//! lie near a threshold (an exponent near the quasi-periodic band, a multiplier near the unit
//! circle), halving them level by level down to single cells; the cells inside a block whose
//! corners agree are filled with the corners' class and flagged as inferred.
//!
//! The risk is stated, not hidden: an island of another class smaller than the coarse spacing
//! that touches no corner of its block is missed. The agreement with the full computation is
//! measured (docs/maps.md, "Early termination").

use super::compute_cells;
use crate::class::Class;
use crate::config::Config;
use crate::decide::Summary;
use crate::engine::Engine;
use crate::engine::Timings;
use crate::progress::Progress;

/// A finished coarse-to-fine map: every cell's summary and attractor count, and 1 where the
/// cell was inferred from its block's corners.
pub struct Refined {
    pub cells: Vec<(Summary, u8)>,
    pub inferred: Vec<u8>,
    pub timings: Timings,
    /// Cells actually integrated.
    pub computed: usize,
}

/// Block corners [x0, x1] x [y0, y1] (inclusive grid indices).
#[derive(Clone, Copy, Debug)]
struct Block {
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
}

/// The coarse grid coordinates: 0, k, 2k, ... and the last index.
fn coarse(n: usize, k: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (0..n).step_by(k.max(1)).collect();
    if *v.last().unwrap_or(&0) != n - 1 {
        v.push(n - 1);
    }
    v
}

/// Default of `--refine-clear`: a chaotic corner is clear above 3 x `run.lyapunov_tol`.
pub const CLEAR_CHAOTIC: f64 = 3.0;

/// Whether a corner's class is clear of a threshold, so that a block of such corners may be
/// filled: chaotic with an exponent above `chaotic` x the quasi-periodic band's half-width
/// `tol`, a cycle well inside the unit circle, no impact. Quasi-periodic, unresolved and failed
/// corners always refine.
fn clear(s: &Summary, tol: f64, chaotic: f64) -> bool {
    match s.class {
        Class::Chaotic => s.lyapunov.value > chaotic * tol,
        Class::Periodic(_) => s.multiplier < 0.95,
        Class::NoImpact => true,
        _ => false,
    }
}

/// Computes the map of `cfg` coarse-to-fine with coarse spacing `k` (>= 2); a chaotic corner
/// is clear above `chaotic` x `run.lyapunov_tol` (`--refine-clear`).
pub fn compute_coarse(
    engine: &Engine,
    cfg: &Config,
    k: usize,
    chaotic: f64,
    starts: usize,
    progress: &dyn Progress,
) -> crate::Result<Refined> {
    let mut timings = Timings::default();
    let mut r = coarse_grid(
        (cfg.map.x_points as usize, cfg.map.y_points as usize),
        k,
        cfg.run.lyapunov_tol,
        chaotic,
        |todo| {
            let (s, t) = compute_cells(engine, cfg, todo.iter().copied(), starts, false, progress)?;
            timings.integration_s += t.integration_s;
            Ok::<_, crate::Error>(s)
        },
    )?;
    r.timings = timings;
    Ok(r)
}

impl Block {
    /// The block split at its midpoints along each side longer than one cell.
    fn split(&self) -> Vec<Block> {
        let (xm, ym) = ((self.x0 + self.x1) / 2, (self.y0 + self.y1) / 2);
        let xs = if self.x1 - self.x0 > 1 {
            vec![(self.x0, xm), (xm, self.x1)]
        } else {
            vec![(self.x0, self.x1)]
        };
        let ys = if self.y1 - self.y0 > 1 {
            vec![(self.y0, ym), (ym, self.y1)]
        } else {
            vec![(self.y0, self.y1)]
        };
        ys.iter()
            .flat_map(|&(y0, y1)| xs.iter().map(move |&(x0, x1)| Block { x0, x1, y0, y1 }))
            .collect()
    }
}

/// The refinement of an `nx` x `ny` grid (row-major) with coarse spacing `k`, where `compute`
/// integrates the listed cells (ascending, each once; its timings are the caller's). Kept apart
/// from the engine so that the rule can be tested on classes with a known boundary.
pub fn coarse_grid<E>(
    (nx, ny): (usize, usize),
    k: usize,
    tol: f64,
    chaotic: f64,
    mut compute: impl FnMut(&[usize]) -> Result<Vec<(Summary, u8)>, E>,
) -> Result<Refined, E> {
    let mut known: Vec<Option<(Summary, u8)>> = vec![None; nx * ny];
    let mut computed = 0usize;
    let (xs, ys) = (coarse(nx, k), coarse(ny, k));
    let mut todo: Vec<usize> = ys
        .iter()
        .flat_map(|&y| xs.iter().map(move |&x| y * nx + x))
        .collect();
    let mut blocks: Vec<Block> = ys
        .windows(2)
        .flat_map(|wy| {
            xs.windows(2).map(move |wx| Block {
                x0: wx[0],
                x1: wx[1],
                y0: wy[0],
                y1: wy[1],
            })
        })
        .collect();
    let mut inferred = vec![0u8; nx * ny];
    loop {
        todo.sort_unstable();
        todo.dedup();
        todo.retain(|&c| known[c].is_none());
        if !todo.is_empty() {
            let s = compute(&todo)?;
            computed += todo.len();
            for (&c, v) in todo.iter().zip(s) {
                known[c] = Some(v);
            }
        }
        todo.clear();
        let mut next = Vec::new();
        for b in blocks {
            let corner = |x: usize, y: usize| known[y * nx + x].expect("corner computed");
            let cs = [
                corner(b.x0, b.y0),
                corner(b.x1, b.y0),
                corner(b.x0, b.y1),
                corner(b.x1, b.y1),
            ];
            let uniform = cs
                .iter()
                .all(|c| c.0.class == cs[0].0.class && c.1 == 1 && clear(&c.0, tol, chaotic));
            if b.x1 - b.x0 <= 1 && b.y1 - b.y0 <= 1 {
                continue;
            }
            if uniform {
                for y in b.y0..=b.y1 {
                    for x in b.x0..=b.x1 {
                        let c = y * nx + x;
                        if known[c].is_none() {
                            // The class of the corners; no exponent or multiplier is claimed.
                            let mut s = cs[0].0;
                            s.lyapunov.value = f64::NAN;
                            s.multiplier = f64::NAN;
                            s.periods = 0;
                            s.settle = 0;
                            s.final_y = [f64::NAN; 4];
                            s.coexist = None;
                            s.looked = crate::decide::Look::None;
                            known[c] = Some((s, 1));
                            inferred[c] = 1;
                        }
                    }
                }
                continue;
            }
            // Split at the midpoints; the new corners are computed at the next level.
            for q in b.split() {
                todo.extend(
                    [(q.x0, q.y0), (q.x1, q.y0), (q.x0, q.y1), (q.x1, q.y1)]
                        .map(|(x, y)| y * nx + x),
                );
                next.push(q);
            }
        }
        if next.is_empty() {
            break;
        }
        blocks = next;
    }
    let cells = known
        .into_iter()
        .map(|c| c.expect("every cell computed or inferred"))
        .collect();
    Ok(Refined {
        cells,
        inferred,
        timings: Timings::default(),
        computed,
    })
}
