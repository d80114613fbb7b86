//! Stable cycles carried between neighbouring points: each stable cycle a point found seeds
//! Newton's method at its neighbours' parameters (a map's four neighbouring cells, a sweep's
//! two neighbours in the swept parameter) wherever those did not land on a cycle; a cycle found
//! stable there seeds their neighbours in turn, a front, until no point gains a cycle. A point
//! then knows a stable cycle that exists at its own parameters even where its trajectory went
//! elsewhere (coexistence). It runs once every point is decided: a sweep's after its look
//! ([`crate::adaptive::look::coexist`]), a map's over its whole grid when its parts are joined
//! ([`crate::map::carry_over`]), so that shards and checkpoints carry as one run does.

use crate::class::Class;
use crate::cycles::{Cycle, Refine};
use crate::engine::Decider;
use crate::method::{Integrator, PointState, Settings};
use crate::model::{Mode, Params};

/// Which points of a run neighbour each other.
#[derive(Clone, Debug)]
pub struct Neighbours {
    /// The neighbours of each point within the run.
    pub of: Vec<Vec<usize>>,
    /// Whether every neighbour a point has in its grid or sweep is in the run (or is to be
    /// taken as if it were: [`Neighbours::known_only`]).
    pub complete: Vec<bool>,
}

impl Neighbours {
    /// `n` points with no neighbours known (a single point, a study's random draws).
    pub fn none(n: usize) -> Neighbours {
        Neighbours {
            of: vec![Vec::new(); n],
            complete: vec![false; n],
        }
    }

    /// These neighbours, with the known ones taken as all there are (a point none of whose
    /// known neighbours is of another class counts as among chaotic-looking ones).
    pub fn known_only(mut self) -> Neighbours {
        self.complete.iter_mut().for_each(|c| *c = true);
        self
    }

    /// `n` points along one swept parameter, in order.
    pub fn line(n: usize) -> Neighbours {
        Neighbours {
            of: (0..n)
                .map(|i| {
                    let mut v = Vec::with_capacity(2);
                    if i > 0 {
                        v.push(i - 1);
                    }
                    if i + 1 < n {
                        v.push(i + 1);
                    }
                    v
                })
                .collect(),
            complete: vec![true; n],
        }
    }

    /// The `cells` (row-major indices of an `nx` x `ny` grid) of a run, `k` points per cell
    /// (point `c * k + j` is start `j` of cell `cells[c]`): a point's neighbours are the same
    /// start of the four edge-neighbouring cells in the run.
    pub fn grid(cells: &[usize], (nx, ny): (usize, usize), k: usize) -> Neighbours {
        let at: std::collections::HashMap<usize, usize> =
            cells.iter().enumerate().map(|(c, &g)| (g, c)).collect();
        let k = k.max(1);
        let mut of = Vec::with_capacity(cells.len() * k);
        let mut complete = Vec::with_capacity(cells.len() * k);
        for &g in cells {
            // A volume's cells see their own slice only (`g / nx` counts the slices' rows).
            let (ix, iy) = (g % nx, (g / nx) % ny);
            let mut grid = Vec::with_capacity(4);
            if ix > 0 {
                grid.push(g - 1);
            }
            if ix + 1 < nx {
                grid.push(g + 1);
            }
            if iy > 0 {
                grid.push(g - nx);
            }
            if iy + 1 < ny {
                grid.push(g + nx);
            }
            let known: Vec<usize> = grid.iter().filter_map(|g| at.get(g).copied()).collect();
            for j in 0..k {
                of.push(known.iter().map(|c| c * k + j).collect());
                complete.push(known.len() == grid.len());
            }
        }
        Neighbours { of, complete }
    }
}

/// A stable cycle that a point's neighbours carried to its parameters ([`carry`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Carried {
    /// Its least period.
    pub period: u32,
    /// Its leading multiplier modulus.
    pub multiplier: f64,
}

/// Where a cycle starts Newton's method at a neighbour: (period, section point, mode).
pub type Seed = (u32, [f64; 4], Mode);

/// Classes whose points receive carried cycles: those that did not land on a cycle.
fn receives(c: Class) -> bool {
    matches!(
        c,
        Class::Chaotic | Class::QuasiPeriodic | Class::Unresolved | Class::Aperiodic
    )
}

/// Carries the stable cycles `seeds` (one per point that landed on one) to the neighbouring
/// points that did not (`classes`), as a front: each cycle seeds Newton's method at every
/// neighbour's parameters (`params(i)`), each neighbour tries each period once, and a cycle
/// found stable there seeds its own neighbours in the next round, until no point gains a
/// cycle. Returns each point's first carried stable cycle.
pub fn carry(
    decider: Decider,
    settings: &Settings,
    params: &(dyn Fn(usize) -> Params<f64> + Sync),
    classes: &[Class],
    seeds: &[Option<Seed>],
    nb: &Neighbours,
) -> Vec<Option<Cycle>> {
    let n = classes.len();
    let mut got: Vec<Option<Cycle>> = vec![None; n];
    let mut tried: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut seed: Vec<Option<Seed>> = seeds.to_vec();
    let mut front: Vec<usize> = (0..n).filter(|&i| seed[i].is_some()).collect();
    let mut rounds = 0;
    let (t0, mut trials) = (std::time::Instant::now(), 0);
    while !front.is_empty() {
        rounds += 1;
        let mut idx = Vec::new();
        let mut tasks = Vec::new();
        for &s in &front {
            let (period, y, mode) = seed[s].expect("a front point has a seed");
            for &t in &nb.of[s] {
                if !receives(classes[t]) || got[t].is_some() || tried[t].contains(&period) {
                    continue;
                }
                tried[t].push(period);
                let start = PointState {
                    y,
                    mode,
                    diag: Default::default(),
                };
                idx.push(t);
                tasks.push(Refine::new(
                    Integrator::<f64>::new(&params(t), settings),
                    &start,
                    period,
                ));
            }
        }
        let mut next = Vec::new();
        trials += tasks.len();
        for (t, task) in idx.into_iter().zip(decider.refine(settings, tasks)) {
            let c = task.cycle();
            if got[t].is_none() && c.is_stable() {
                seed[t] = Some((c.period, c.point, c.mode));
                got[t] = Some(c);
                next.push(t);
            }
        }
        front = next;
    }
    log::debug!(
        "carry: {} points gained a stable cycle in {rounds} rounds, {trials} trials, {:.3} s",
        got.iter().filter(|c| c.is_some()).count(),
        t0.elapsed().as_secs_f64()
    );
    got
}

/// The carried cycle `c` as recorded at a point of class `class`: none where the point landed
/// on that very cycle.
pub fn coexisting(c: Option<&Cycle>, class: Class) -> Option<Carried> {
    c.filter(|c| class != Class::Periodic(c.period))
        .map(|c| Carried {
            period: c.period,
            multiplier: c.leading_modulus(),
        })
}
