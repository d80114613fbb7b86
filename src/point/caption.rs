//! The caption of `point --plot`: what was computed, how, and what to notice in each panel.

use super::laminar::dist;
use super::plot::{HEIGHT, PointPlot, WIDTH};
use crate::config::Config;
use crate::model::Mode;

/// "Stribeck friction (fs=0.25, fk=0.05, l1=1.42, l2=0.005), eta=1.2, R=0.6": the friction
/// law with its own coefficients only, then eta and R, and with `all` the other parameters.
pub(super) fn model_line(cfg: &Config, all: bool) -> String {
    let m = &cfg.model;
    let law = match m.friction {
        crate::config::FrictionLaw::Coulomb => format!("Coulomb friction lambda={}", m.lambda),
        crate::config::FrictionLaw::Stribeck => format!(
            "Stribeck friction fs={}, fk={}, l1={}, l2={}",
            m.fs, m.fk, m.l1, m.l2
        ),
    };
    let rest = if all {
        format!(
            ", r={}, delta={}, b1={}, mu={}",
            m.clearance, m.delta, m.b1, m.mu
        )
    } else {
        String::new()
    };
    format!("eta={}, R={}, {law}{rest}", m.eta, m.restitution)
}

/// "A, B and C".
fn and_list(v: &[String]) -> String {
    match v {
        [] => String::new(),
        [a] => a.clone(),
        [rest @ .., last] => format!("{} and {last}", rest.join(", ")),
    }
}

/// The caption of the JSON: what was computed, how, and what to notice.
pub fn caption(p: &PointPlot) -> String {
    let c = &p.cfg;
    let r = &p.report;
    let l = &p.laminar;
    let sh = &p.shown;
    let (class, modes) = (class_phrase(p), modes_phrase(p));
    let (episodes, cycle) = (episodes_phrase(p), cycle_phrase(p));
    format!(
        "One parameter point ({title}), integrated with {how}, from y0 = {y0:?} at phase 0 \
         of the forcing; {tr} transient periods discarded, then {sa} sampled periods (this \
         figure is always computed on the CPU in f64, whatever the configuration names). \
         Class: {class}. (a) z = y3 - y1 (position of m2 in the clearance) and \
         the slip velocity v = y2 - y4 over the last {n} forcing periods P = 2 pi / eta, \
         t / P from {from} to {to} after the transient; dashed: the stops z = +-{rr}; \
         triangles: the {imp} impacts ({ip} at +r, {im} at -r; the integrator's diagnostics \
         count {dimp} over these periods); {modes}; {rev} slip reversals. (b) Phase portrait \
         (z, dz/dt) over the same periods, dz/dt = y4 - y2 = -v; the stops as vertical dashed \
         lines; the line breaks at each impact, where the relative velocity jumps to -R times \
         its value (R = {rest}), and the triangle marks the state just before. (c) \
         Stroboscopic section (y1, y2) at phase 0 of the forcing, all {sa} sampled periods; \
         {cycle}. (d) y1 at the section against the period index k = 1..{sa}, with the returns \
         (vermillion) and nearly periodic episodes (shaded), and the histogram of episode \
         lengths: {rule}; lag {lag_rule}; tol = {tol:e}, s = {s:.3e}, threshold {thr:.3e}. \
         Found: {episodes}. Quantities are dimensionless (time tau = omega1 t, omega1 the \
         natural frequency of m1; eta = forcing frequency / omega1). Raster image, {w} x {h} \
         px, with an SVG twin.",
        title = model_line(c, true),
        how = crate::caption::computed_with(c, "cpu", &r.device),
        y0 = c.initial.y,
        tr = p.transient,
        sa = p.samples.len(),
        n = p.options.periods,
        from = sh.from,
        to = sh.to,
        rr = c.model.clearance,
        imp = sh.impacts_pos + sh.impacts_neg,
        ip = sh.impacts_pos,
        im = sh.impacts_neg,
        dimp = sh.impacts,
        rev = sh.reversals,
        rest = c.model.restitution,
        rule = l.rule,
        lag_rule = l.lag_rule,
        tol = l.tol,
        s = l.span,
        thr = l.threshold,
        w = WIDTH,
        h = HEIGHT,
    )
}

/// The class, with its evidence: the cycle's multiplier or the largest exponent.
fn class_phrase(p: &PointPlot) -> String {
    let r = &p.report;
    match (&r.period, &r.cycle) {
        (Some(n), Some(cy)) => format!(
            "period-{n} (Newton-confirmed cycle, leading Floquet multiplier modulus {:.3})",
            cy.leading_modulus()
        ),
        _ => format!(
            "{} (largest Lyapunov exponent {:.4} per unit time)",
            r.class,
            r.lyapunov_spectrum
                .as_ref()
                .and_then(|s| s.first().copied())
                .unwrap_or(f64::NAN)
        ),
    }
}

/// The stick and lock intervals in the time panels.
fn modes_phrase(p: &PointPlot) -> String {
    let mut modes = Vec::new();
    let n_stick = p.intervals.iter().filter(|i| i.mode == Mode::Stick).count();
    let n_lock = p.intervals.len() - n_stick;
    if n_stick > 0 {
        modes.push(format!("{n_stick} stick intervals (orange)"));
    }
    if n_lock > 0 {
        modes.push(format!("{n_lock} lock intervals at a stop (green)"));
    }
    if modes.is_empty() {
        "no stick or lock in these periods".to_string()
    } else {
        and_list(&modes)
    }
}

/// The nearly periodic episodes panel (d) found.
fn episodes_phrase(p: &PointPlot) -> String {
    let l = &p.laminar;
    let lengths: Vec<u32> = l.episodes.iter().map(|e| e.length).collect();
    match lengths.as_slice() {
        [] => "no episode: no sampled period returns within the threshold".to_string(),
        [one] => format!(
            "1 episode of {one} periods{}",
            if *one + l.lag == p.samples.len() as u32 {
                " (every sampled period returns: periodic to within the threshold)"
            } else {
                ""
            }
        ),
        _ => {
            let mut s = lengths.clone();
            s.sort_unstable();
            format!(
                "{} episodes of {} to {} periods (median {}), {} of them cut by the ends of the \
                 record; {:.1}% of the comparisons are returns: nearly periodic phases \
                 interrupted by bursts",
                s.len(),
                s[0],
                s[s.len() - 1],
                s[s.len() / 2],
                l.episodes.iter().filter(|e| e.censored).count(),
                100.0 * l.returns as f64 / l.comparisons.max(1) as f64
            )
        }
    }
}

/// The Newton-refined cycle drawn in the section, and how close the samples lie to it.
fn cycle_phrase(p: &PointPlot) -> String {
    let spread = p
        .samples
        .iter()
        .map(|y| {
            p.cycle_points
                .iter()
                .map(|q| dist(y, q))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max);
    if p.cycle_points.is_empty() {
        "no converged cycle".to_string()
    } else {
        let n = p.cycle_points.len();
        format!(
            "black {}: the {} of the Newton-refined cycle; every sampled section point lies \
             within {spread:.1e} of {}",
            if n == 1 { "ring" } else { "rings" },
            if n == 1 {
                "section point".to_string()
            } else {
                format!("{n} section points")
            },
            if n == 1 { "it" } else { "one of them" }
        )
    }
}
