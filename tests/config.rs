//! Configuration: defaults, errors that name the key, overrides.

use rattle::config::Config;

#[test]
fn defaults_are_the_paper() {
    let c = Config::from_toml("", &[]).unwrap();
    let p = c.params();
    assert_eq!(
        (p.restitution, p.fs, p.fk, p.clearance),
        (0.6, 0.02, 0.02, 0.8)
    );
    assert_eq!((p.delta, p.b1, p.mu), (0.5, 0.1, 0.693));
}

#[test]
fn errors_name_the_key() {
    let e = Config::from_toml("[model]\nfoo = 1\n", &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("foo"), "{e}");
    let e = Config::from_toml("[model]\nR = 1.5\n", &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("model.R") && e.contains("[0, 1]"), "{e}");
    let e = Config::from_toml("[model]\nmu = 0.0\n", &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("model.mu") && e.contains("(0, inf)"), "{e}");
    let e = Config::from_toml("[model]\nb1 = nan\n", &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("model.b1"), "{e}");
    let e = Config::from_toml("", &["eta=-1".into()])
        .unwrap_err()
        .to_string();
    assert!(e.contains("model.eta"), "{e}");
    let e = Config::from_toml("[sweep]\nparam = \"R\"\nto = 2.0\n", &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("sweep.to") && e.contains("[0, 1]"), "{e}");
    for bad in ["0", "9"] {
        let e = Config::from_toml(&format!("[run]\noverlap = {bad}\n"), &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("run.overlap") && e.contains("[1, 8]"), "{e}");
    }
}

#[test]
fn overrides_apply() {
    let c = Config::from_toml(
        "[model]\nR = 0.6\n",
        &["R=0.62".into(), "run.sample_periods=64".into()],
    )
    .unwrap();
    assert_eq!(c.model.restitution, 0.62);
    assert_eq!(c.run.sample_periods, 64);
    let c = Config::from_toml("", &["friction=stribeck".into()]).unwrap();
    assert_eq!(c.params().fs, 0.25);
}
