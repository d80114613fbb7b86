//! The captions of a map's set: what the class, exponent and multiplier images show, and how
//! two configurations' maps differ.

use super::files::MapReport;
use crate::class::Class;
use crate::config::Config;
use crate::render::percent;
use std::collections::BTreeMap;

/// How large the maps' raster images print (1100 px at 150 dpi).
pub const RASTER: &str = "18.6 cm wide at 150 dpi";

/// The map's title: the configured one, or the model with the two axes' parameters left out.
pub fn title(cfg: &Config) -> String {
    if !cfg.map.title.is_empty() {
        return cfg.map.title.clone();
    }
    let mut varied = vec![cfg.map.x.name(), cfg.map.y.name()];
    varied.extend(cfg.z_axis().map(|z| z.param.name()));
    crate::caption::model_title(cfg, &varied)
}

/// The caption of a map's JSON.
/// What the long look saw over a map (docs/classes.md): cells looked at to the end, cells
/// looked at for the first stage, and cells with a coexisting stable cycle carried from a
/// neighbour (of which chaotic).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct LookSeen {
    /// Cells that looked chaotic after the configured periods and got the whole look.
    pub looked: usize,
    /// Cells that looked chaotic among chaotic-looking neighbours: the look's first stage.
    pub first: usize,
    pub coexist: usize,
    pub coexist_chaotic: usize,
}

pub(super) fn caption(
    cfg: &Config,
    report: &MapReport,
    counts: &BTreeMap<String, usize>,
    rules: &BTreeMap<String, usize>,
    coexisting: usize,
    look: LookSeen,
) -> String {
    let r = &cfg.run;
    let backend = report.backend.as_deref().unwrap_or("unknown");
    let device = report
        .device
        .clone()
        .or_else(|| report.devices.as_ref().map(|d| d.join(", ")))
        .unwrap_or_default();
    let coex = if coexisting > 0 {
        format!(
            " {coexisting} cells reached different attractors from their initial states \
             (--starts) and are drawn as coexisting attractors; the other classes are those \
             of the first start."
        )
    } else {
        String::new()
    };
    let refined = report.refine.as_ref().map_or(String::new(), |f| {
        format!(
            " Coarse-to-fine (--refine {k}): {inf} of {all} cells ({pct}) were not integrated \
             but filled with the class shared by the corners of their block (PREFIX-inferred.npy; \
             corners chaotic with an exponent above {c} x {ltol}, periodic with |mu_1| < 0.95, or \
             without impact), and claim no exponent or multiplier; an island of another class \
             smaller than its block that touches no corner is missed.",
            k = f.spacing,
            inf = f.cells_inferred,
            all = f.cells_integrated + f.cells_inferred,
            pct = percent(f.cells_inferred, f.cells_integrated + f.cells_inferred),
            c = f.chaotic_clear,
            ltol = r.lyapunov_tol,
        )
    });
    let escaped = match rules.get("escaped") {
        Some(e) => format!(
            " A cell still chaotic-looking or undecided beside a neighbour on a stable \
                     cycle carried to it then ran {n} copies of its motion for up to {span} periods each \
                     (f64, on the host): in {e} cells copies landed on a stable cycle, which the \
                     cell names (rule escaped: its chaos was a transient; PREFIX-settle.npy: the \
                     periods run plus the copies' mean lifetime, PREFIX-settle_se.npy: its \
                     error).",
            n = crate::escape::COPIES,
            span = crate::escape::SPAN,
        ),
        None => String::new(),
    };
    let looked = if r.look > r.transient_periods + r.sample_periods {
        format!(
            " A cell still chaotic-looking then went on and left as soon as a window showed \
             another attractor: {c} cells (chaotic-looking beside a cell of another class, or \
             quasi-periodic-looking, which keep their class where no cycle is found) went on to \
             {l} periods in all, so chaotic there means chaotic for {l} periods; {f} cells \
             among chaotic-looking neighbours went on to {g} times the configured periods \
             (PREFIX-looked.npy; PREFIX-settle.npy: periods until on the attractor). {k} cells ({kc} of them \
             chaotic) have a stable cycle carried from a neighbour beside the attractor their \
             trajectory reached (PREFIX-coexist.npy: its period).",
            c = look.looked,
            f = look.first,
            g = crate::adaptive::LOOK_GROWTH,
            l = r.look,
            k = look.coexist,
            kc = look.coexist_chaotic,
        )
    } else {
        String::new()
    };
    format!(
        "Class map of the attractor reached at each of {grid}. Each cell starts from y0 = {start:?} and is integrated with {how}; {tr} transient periods, then \
         {sa} sampled periods. Classes (docs/classes.md): period-n only where Newton's method \
         converges to a cycle whose Floquet multipliers all lie inside the unit circle, tried at \
         the detector's period (tolerance {tol}) and at up to {cand} candidate periods <= {maxp} \
         that the last section values repeat with (relative tolerance {ctol}); chaotic only \
         where the largest Lyapunov exponent exceeds {z} standard errors (batch means over \
         {blocks} blocks); quasi-periodic only where the torus test passes (weighted Birkhoff \
         averages of y1 over the two halves of the window agree to {digits} digits) with an \
         exponent shown to be within {bound} of zero (|exponent| + {z} standard errors); aperiodic where no exponent was \
         computed. A cell still undecided gets doubling windows up to {hz} x the configured \
         periods (PREFIX-periods.npy) and is unresolved only then.{looked} A cell still \
         quasi-periodic or unresolved then runs {win} periods more on the host (f64) for a \
         recurrence at a lag <= {maxl} that Newton's method confirms as a stable cycle the \
         motion approaches.{escaped} Cells by deciding rule: \
         {rules}. Colours: one hue per period family (1, 2, 3, 4, 5-8, 9-16, 17-64, 65-1024) with \
         lightness steps inside a family; chaotic near-black, quasi-periodic light green. The \
         legend gives the share and the count of every class shown. Most frequent: \
         {top}.{coex}{refined} Raster image, 1100 x 800 px ({RASTER}).",
        grid = grid_phrase(cfg),
        start = cfg.initial.y,
        how = crate::caption::computed_with(cfg, backend, &device),
        tr = r.transient_periods,
        sa = r.sample_periods,
        tol = r.period_tol,
        bound = crate::classify::TORUS_BOUND,
        cand = crate::classify::MAX_CANDIDATES,
        maxp = crate::classify::MAX_TRIAL_PERIOD,
        win = crate::recurrence::WINDOW,
        maxl = crate::recurrence::MAX_LONG_PERIOD,
        ctol = crate::classify::CANDIDATE_TOL,
        z = crate::classify::CHAOS_MARGIN,
        blocks = crate::classify::BLOCKS,
        digits = crate::classify::TORUS_DIGITS,
        hz = r.horizon,
        rules = rules
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect::<Vec<_>>()
            .join(", "),
        top = crate::caption::top_classes(counts, 5),
    )
}

/// The grid and model of a map, for the captions of its images.
pub(super) fn grid_phrase(cfg: &Config) -> String {
    let m = &cfg.map;
    let plane = format!(
        "{nx} x {ny} cell centres: {x} from {x0} to {x1} (horizontal) and {y} from {y0} to {y1} \
         (vertical)",
        nx = m.x_points,
        ny = m.y_points,
        x = m.x,
        x0 = m.x_from,
        x1 = m.x_to,
        y = m.y,
        y0 = m.y_from,
        y1 = m.y_to,
    );
    match cfg.z_axis() {
        // A volume: one panel per slice, each a map of x and y.
        Some(z) => format!(
            "{} slices (panels, one per value of {} from {} to {}) of {plane}; {}",
            z.points,
            z.param,
            z.from,
            z.to,
            title(cfg)
        ),
        None => format!("{plane}; {}", title(cfg)),
    }
}

/// The caption of PREFIX-lyapunov.png; None where it is not drawn.
pub(super) fn lyapunov_caption(cfg: &Config, values: &[f64], clip: f64) -> Option<String> {
    let v: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    let tol = cfg.run.lyapunov_tol;
    let pos = v.iter().filter(|&&l| l > tol).count();
    let zero = v.iter().filter(|&&l| l.abs() <= tol).count();
    let (lo, hi) = v
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &l| {
            (a.min(l), b.max(l))
        });
    Some(format!(
        "Largest Lyapunov exponent per unit time at each of {grid}, from the same run as the \
         class map (one tangent vector through the RK4 stages and the saltation matrices of the \
         events; a cell whose cycle Newton confirmed carries ln|mu_1| / P). Diverging colours \
         centred on 0, clipped at the 99th percentile of |exponent| ({clip:.3}); grey: no \
         exponent (failed, or inferred by refinement). {n} cells with a value, from {lo:.3} to \
         {hi:.3}: {pos} above +{tol}, {zero} within +-{tol}, the rest below (the classes weigh \
         each exponent against its standard error, PREFIX-lyapunov_se.npy, not against this \
         band). Raster image, 1100 x 800 px ({RASTER}).",
        grid = grid_phrase(cfg),
        n = v.len(),
    ))
}

/// The caption of PREFIX-multiplier.png; None where it is not drawn.
pub(super) fn multiplier_caption(cfg: &Config, values: &[f64]) -> Option<String> {
    let v: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    let near = v.iter().filter(|&&m| m > 0.95).count();
    let hi = v.iter().copied().fold(0.0, f64::max);
    Some(format!(
        "Stability margin at each of {grid}: the modulus of the leading Floquet multiplier of \
         each cell's Newton-confirmed stable cycle (viridis, 0 to 1; 1 is where a cycle loses \
         stability), grey where no stable cycle was confirmed (aperiodic, no impact, failed, \
         inferred). {n} periodic cells, largest modulus {hi:.4}; {near} of them above 0.95, \
         slowly contracting cycles near a bifurcation whose transients a fixed number of \
         periods may not outlast. Raster image, 1100 x 800 px ({RASTER}).",
        grid = grid_phrase(cfg),
        n = v.len(),
    ))
}

/// The caption of PREFIX-settle.png: how long the cells took to settle, by the kind of
/// attractor they reached.
pub(super) fn settle_caption(cfg: &Config, f: &super::fields::Fields) -> Option<String> {
    let chaotic = Class::Chaotic.code();
    let (mut on, mut ch): (Vec<u32>, Vec<u32>) = (Vec::new(), Vec::new());
    let mut whole = 0;
    for (((&s, &c), &i), &l) in f
        .settle
        .iter()
        .zip(&f.class)
        .zip(&f.inferred)
        .zip(&f.looked)
    {
        if i != 0 {
            continue;
        }
        if c == chaotic {
            ch.push(s);
            whole += usize::from(l == 2);
        } else {
            on.push(s);
        }
    }
    if on.is_empty() && ch.is_empty() {
        return None;
    }
    on.sort_unstable();
    let q = |v: &[u32], p: usize| v.get((v.len().saturating_sub(1)) * p / 100).copied();
    let long = cfg.run.transient_periods + cfg.run.sample_periods;
    let late = on.iter().filter(|&&s| s >= long).count();
    Some(format!(
        "Periods until the motion was on its attractor at each of {grid} (log scale): for a \
         periodic, quasi-periodic or impact-free cell the periods before the window that showed \
         its attractor (an upper bound), for a chaotic cell the length of its look (chaos is \
         known to last that long, no longer); grey: inferred cells. {n} non-chaotic cells: \
         median {med}, 99th percentile {p99}, longest {max}; {late} of them settled only after \
         the configured {long} periods. {c} chaotic cells, {whole} of them chaotic through the \
         whole look ({look} periods; the others chaotic through the look's first stage, their \
         neighbours all chaotic-looking, or chaotic after the configured periods where the look \
         was off). Raster image, 1100 x 800 px ({RASTER}).",
        grid = grid_phrase(cfg),
        n = on.len(),
        med = q(&on, 50).map_or("-".into(), |v| v.to_string()),
        p99 = q(&on, 99).map_or("-".into(), |v| v.to_string()),
        max = on.last().map_or("-".into(), |v| v.to_string()),
        c = ch.len(),
        look = cfg.run.look,
    ))
}

/// The caption of PREFIX-compare.png.
pub fn compare_caption(cfg: &Config, other: &Config, a: &[Class], b: &[Class]) -> String {
    let n = a.len().max(1);
    let kind = |x: &Class, y: &Class| std::mem::discriminant(x) == std::mem::discriminant(y);
    let failed = a
        .iter()
        .zip(b)
        .filter(|(x, y)| **x == Class::Failed || **y == Class::Failed)
        .count();
    let period = a
        .iter()
        .zip(b)
        .filter(|(x, y)| x != y && kind(x, y) && **x != Class::Failed)
        .count();
    let motion = a
        .iter()
        .zip(b)
        .filter(|(x, y)| !kind(x, y) && **x != Class::Failed && **y != Class::Failed)
        .count();
    format!(
        "Where the class of the attractor changes between two configurations on the same grid: \
         {grid}, against the same model with {diff}. Each cell of both maps is computed as in \
         the class map (same initial state, method, periods and precision). Light grey: same \
         class; sky blue: another period ({period} cells, {pp}); vermillion: another type of \
         motion, e.g. periodic against chaotic or no impact ({motion} cells, {mp}); black: \
         failed in one of the two ({failed} cells). Okabe-Ito colours, told apart with \
         colour-vision deficiencies. Raster image, 1100 x 800 px ({RASTER}).",
        grid = grid_phrase(cfg),
        diff = model_diff(cfg, other).join(", "),
        pp = percent(period, n),
        mp = percent(motion, n),
    )
}

/// `key = a -> b` for every model value that differs between two configurations.
pub(super) fn model_diff(cfg: &Config, other: &Config) -> Vec<String> {
    let (ma, mb) = (
        serde_json::to_value(&cfg.model).unwrap_or_default(),
        serde_json::to_value(&other.model).unwrap_or_default(),
    );
    ma.as_object()
        .into_iter()
        .flatten()
        .filter(|(k, v)| mb.get(k.as_str()) != Some(v))
        .map(|(k, v)| format!("{k} = {v} -> {}", mb[k.as_str()]))
        .collect()
}
