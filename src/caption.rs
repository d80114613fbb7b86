//! Phrases shared by the captions of every figure's JSON (diagrams, maps, basins, points).

use crate::config::Config;
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
