//! Captions of the accuracy study's charts, written from the numbers of the run.

use super::{OrderJson, POLISHED, ReferenceInfo, Row};
use crate::config::Config;

/// "a" when `lo` and `hi` print the same, else "a-b" (with `fmt` applied to both).
fn span(lo: f64, hi: f64, fmt: &dyn Fn(f64) -> String) -> String {
    let (a, b) = (fmt(lo), fmt(hi));
    if a == b { a } else { format!("{a} to {b}") }
}

/// Min and max of `vals`, if any.
fn min_max(vals: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    vals.fold(None, |acc, v| match acc {
        None => Some((v, v)),
        Some((a, b)) => Some((a.min(v), b.max(v))),
    })
}

/// Caption of the work-precision chart, with the numbers of this run.
pub(super) fn work_precision_caption(
    rows: &[Row],
    r: &ReferenceInfo,
    orders: &[OrderJson],
) -> String {
    let mut backends: Vec<&str> = rows
        .iter()
        .filter(|x| x.kind == "error")
        .map(|x| x.backend.as_str())
        .collect();
    backends.sort();
    backends.dedup();
    let order_of = |m: &str| {
        min_max(
            orders
                .iter()
                .filter(|o| o.method == m)
                .filter_map(|o| o.order),
        )
    };
    let f2 = |v: f64| format!("{v:.2}");
    let orders_text = ["located", "naive"]
        .iter()
        .filter_map(|m| order_of(m).map(|(a, b)| format!("{m} {}", span(a, b, &f2))))
        .collect::<Vec<_>>()
        .join(", ");
    let f32_floor = min_max(
        rows.iter()
            .filter(|x| x.kind == "error" && x.case == r.case && x.precision == "f32")
            .filter(|x| x.method == "located")
            .filter_map(|x| x.error),
    )
    .map_or(String::new(), |(lo, _)| {
        format!(" The smallest located f32 error is {lo:.1e}: the f32 round-off floor.")
    });
    let polish = min_max(
        rows.iter()
            .filter(|x| x.kind == "error" && x.case == r.case && x.method == POLISHED)
            .filter(|x| x.n == 256)
            .filter_map(|x| x.error),
    )
    .map_or(String::new(), |(lo, hi)| {
        format!(
            " Lines located+newton (own colours): the located f32 run's section point refined \
             by Newton's method in f64 at the same N, as rattle confirms every periodic point; \
             the cost includes the Newton iteration of one point on one thread. At N = 256 \
             its error is {}: f64's, not the f32 floor.",
            span(lo, hi, &|v| format!("{v:.1e}"))
        )
    });
    format!(
        "Work-precision chart at {case} ({class} attractor): max-norm error of the section \
         point (state at a multiple of the forcing period) after {t} transient periods from \
         y0 = 0, against a CPU f64 event-located RK4 reference at N = {n} steps per period \
         (which changes by {ch:.1e} when N doubles), versus seconds per parameter point \
         measured on a batch of {e} copies of the point. One marker per N = 16, 32, ..., 4096 \
         (cost grows with N), except the located f64 rows at N = {n}, which repeat the \
         reference's own N and measure only round-off (CSV only). Solid: event-located RK4 (impacts located inside the step); \
         dashed: naive RK4 (impacts applied at step ends), in the same colour for the same \
         precision (f32, f64) and backend ({backends}). Observed orders of convergence \
         (least-squares slope over the errors down to the noise floor, 1e-6 in f32 and 1e-12 in f64): \
         {orders_text}.{f32_floor}{polish}",
        case = r.case,
        class = r.class,
        t = r.transient_periods,
        n = r.n,
        ch = r.change_at_2n,
        e = r.ensemble,
        backends = backends.join(", "),
    )
}

/// Caption of the failure chart, with the numbers of this run.
pub(super) fn failure_caption(
    rows: &[Row],
    sweep: &str,
    r: &ReferenceInfo,
    cfg: &Config,
) -> String {
    let share = |m: &str| {
        min_max(
            rows.iter()
                .filter(|x| x.kind == "failure" && x.method == m)
                .filter_map(|x| x.class_mismatch)
                .map(|v| 100.0 * v),
        )
    };
    let pct = |v: f64| format!("{v:.0}%");
    let shares = ["located", "naive"]
        .iter()
        .filter_map(|m| share(m).map(|(a, b)| format!("{m} {}", span(a, b, &pct))))
        .collect::<Vec<_>>()
        .join(", ");
    let backend = rows
        .iter()
        .find(|x| x.kind == "failure")
        .map_or("", |x| x.backend.as_str());
    let s = &cfg.sweep;
    format!(
        "Share of the sweep points ({sweep}, {p} from {from} to {to}) whose class differs from \
         the reference (CPU, f64, event-located RK4, N = {n}), versus steps per forcing period \
         N, for both impact methods (solid: event-located, dashed: naive, same colour for the \
         same precision) on the {backend} backend; {t} transient and 100 sampled periods from y0 = {y0:?}. Dashed lines \
         in further colours: points with event-budget overflows or non-finite states, drawn \
         where not zero. The y axis is linear below 1% and logarithmic above, so that zero and \
         the small shares stay readable. Class differs, over all N: {shares}.",
        p = s.param,
        from = s.from,
        to = s.to,
        n = r.n,
        t = r.transient_periods,
        y0 = cfg.initial.y,
    )
}
