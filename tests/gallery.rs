//! The gallery's figures are what their listed commands write today: the two `rattle point
//! --plot` figures of docs/commands.md are rewritten by their commands and compared byte for
//! byte, and every number the page quotes about them is read back from the JSON the command
//! writes (round 8 M2: the intermittent point's figure and numbers were of an older build).

mod common;
use common::{config, json, ok, rattle, scratch};

/// docs/commands.md's section on the point figures (from its heading to the next one).
fn section() -> String {
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/commands.md"),
    )
    .unwrap();
    let start = text.find("### A periodic point").expect("the section");
    let end = text[start..]
        .find("## Timings")
        .map_or(text.len(), |e| start + e);
    // One line, words separated by single spaces (the page wraps its lines).
    text[start..end]
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
}

/// The number right after `before` in `text` (the first match).
fn after(text: &str, before: &str) -> f64 {
    let at = text
        .find(before)
        .unwrap_or_else(|| panic!("{before:?} is not quoted"));
    let rest = &text[at + before.len()..];
    let n: String = rest
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.')
        .collect();
    n.trim_end_matches('.')
        .parse()
        .unwrap_or_else(|_| panic!("no number after {before:?}: {rest:.40}"))
}

/// Runs the figure's command to `out` in a scratch folder; its JSON, after comparing the PNG and
/// SVG with the gallery's.
fn figure(args: &[&str], doc: &str) -> serde_json::Value {
    let d = scratch(doc);
    let cfg = config("fig2.toml");
    ok(rattle()
        .args(["point", "--config"])
        .arg(&cfg)
        .args(args)
        .arg("--plot")
        .arg(d.join("f")));
    let docs = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs");
    for ext in ["png", "svg"] {
        let ours = std::fs::read(d.join(format!("f.{ext}"))).unwrap();
        let shown = std::fs::read(docs.join(format!("{doc}.{ext}"))).unwrap();
        assert!(
            ours == shown,
            "docs/{doc}.{ext} is not what its command writes today: redraw it"
        );
    }
    json(&d.join("f.json"))
}

#[test]
fn the_point_figures_and_their_numbers_are_their_commands() {
    let text = section();
    let (periodic, chaotic) = text.split_once("### An intermittent point").unwrap();
    let j = figure(&["--eta", "1.5"], "point-periodic");
    let mu = j["cycle"]["multipliers"][0].as_array().unwrap();
    let modulus = mu[0].as_f64().unwrap().hypot(mu[1].as_f64().unwrap());
    assert_eq!(
        after(periodic, "multiplier modulus "),
        (modulus * 1e3).round() / 1e3
    );
    let shown = &j["shown"];
    assert_eq!(
        after(periodic, "lock, "),
        shown["reversals"].as_f64().unwrap()
    );
    let impacts = after(
        periodic,
        "reports: period-1, leading Floquet multiplier modulus 0.812; ",
    );
    assert_eq!(impacts, shown["impacts"].as_f64().unwrap());
    assert_eq!(
        after(periodic, "periods shown ("),
        shown["impacts_pos"].as_f64().unwrap()
    );
    assert_eq!(
        after(periodic, "at +r, "),
        shown["impacts_neg"].as_f64().unwrap()
    );
    let eps = j["laminar"]["episodes"].as_array().unwrap();
    assert_eq!(eps.len(), 1);
    assert_eq!(
        after(periodic, "1 episode of "),
        eps[0]["length"].as_f64().unwrap()
    );

    let j = figure(
        &["--eta", "1.26", "--set", "run.sample_periods=2000"],
        "point-intermittent",
    );
    let shown = &j["shown"];
    let exponent = j["lyapunov_spectrum"][0].as_f64().unwrap();
    assert_eq!(
        after(chaotic, "largest Lyapunov exponent "),
        (exponent * 1e4).round() / 1e4
    );
    assert_eq!(
        after(chaotic, "per unit time; "),
        shown["impacts"].as_f64().unwrap()
    );
    assert_eq!(
        after(chaotic, "shown ("),
        shown["impacts_pos"].as_f64().unwrap()
    );
    assert_eq!(
        after(chaotic, "at +r, "),
        shown["impacts_neg"].as_f64().unwrap()
    );
    assert_eq!(
        after(chaotic, "or lock, "),
        shown["reversals"].as_f64().unwrap()
    );
    let l = &j["laminar"];
    assert_eq!(after(chaotic, "lag p = "), l["lag"].as_f64().unwrap());
    let eps = l["episodes"].as_array().unwrap();
    let lens: Vec<f64> = eps.iter().map(|e| e["length"].as_f64().unwrap()).collect();
    let n = eps.len() as f64;
    assert_eq!(after(chaotic, "most returns of any lag); "), n);
    assert_eq!(after(chaotic, "orbit: "), n);
    let longest = lens.iter().copied().fold(0.0, f64::max);
    assert_eq!(after(chaotic, "episodes of 1 to "), longest);
    let (returns, comparisons) = (
        l["returns"].as_f64().unwrap(),
        l["comparisons"].as_f64().unwrap(),
    );
    assert_eq!(after(chaotic, "periods in 2000 ("), returns);
    assert_eq!(after(chaotic, "returns in "), comparisons);
    let share = (1000.0 * returns / comparisons).round() / 10.0;
    assert_eq!(after(chaotic, "of the record; "), share);
    let count = |k: f64| lens.iter().filter(|&&x| x == k).count() as f64;
    assert_eq!(after(chaotic, "(peaks at 4 periods, "), count(4.0));
    assert_eq!(after(chaotic, "and at 10, "), count(10.0));
}
