//! Phrases shared by the captions of every figure's JSON (diagrams, maps, basins, points).

use crate::config::{Config, FrictionLaw};
use std::collections::BTreeMap;

/// How a run was integrated, for captions: method, steps per period, precision, backend.
pub fn computed_with(cfg: &Config, backend: &str, device: &str) -> String {
    let m = &cfg.method;
    let method = match m.impacts {
        crate::method::ImpactMethod::Located => {
            "event-located RK4 (impacts located inside the step)"
        }
        crate::method::ImpactMethod::Naive => {
            "naive RK4 (impacts applied at step ends, first order)"
        }
    };
    let dev = if device.is_empty() {
        String::new()
    } else {
        format!(" ({device})")
    };
    format!(
        "{method} with N = {} steps per forcing period in {} arithmetic on the {backend} \
         backend{dev}",
        m.steps_per_period,
        m.precision.name()
    )
}

/// "period-1 41%, chaotic 30%, ...": the most frequent classes, at most `k`.
pub fn top_classes(counts: &BTreeMap<String, usize>, k: usize) -> String {
    let total: usize = counts.values().sum();
    let mut v: Vec<(&String, &usize)> = counts.iter().collect();
    v.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
    v.iter()
        .take(k)
        .map(|(name, n)| format!("{name} {:.1}%", 100.0 * **n as f64 / total.max(1) as f64))
        .collect::<Vec<_>>()
        .join(", ")
}

/// "Coulomb friction, eta=1.5, R=0.6, ...": the model's values except those named in `except`
/// (the axes of a map).
pub fn model_title(cfg: &Config, except: &[&str]) -> String {
    let m = &cfg.model;
    // The friction law's own parameters: lambda for Coulomb, fs, fk, l1, l2 for Stribeck.
    let friction: &[(&str, f64)] = match m.friction {
        FrictionLaw::Coulomb => &[("lambda", m.lambda)],
        FrictionLaw::Stribeck => &[("fs", m.fs), ("fk", m.fk), ("l1", m.l1), ("l2", m.l2)],
    };
    let mut fixed = Vec::new();
    let common = [
        ("r", m.clearance),
        ("delta", m.delta),
        ("b1", m.b1),
        ("mu", m.mu),
    ];
    let head = [("eta", m.eta), ("R", m.restitution)];
    for &(k, v) in head.iter().chain(friction).chain(&common) {
        if !except.contains(&k) {
            fixed.push(format!("{k}={v}"));
        }
    }
    format!("{:?} friction, {}", m.friction, fixed.join(", "))
}
