//! The memory refusal's advice holds (round 7 L11): the largest map it names is one the same
//! check accepts, and explore, which cannot use shards, is not told to. Its own test binary:
//! the memory limit is set in this process's environment.

use rattle::config::Config;
use rattle::memory::check_map;

mod common;

/// "<= N cells" in a refusal: N.
fn named(message: &str) -> usize {
    message
        .split("<= ")
        .nth(1)
        .and_then(|r| r.split(" cells").next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no largest size named: {message}"))
}

#[test]
fn the_largest_map_a_refusal_names_is_accepted() {
    // SAFETY: the only test of this binary; nothing else reads the environment meanwhile.
    unsafe { std::env::set_var("RATTLE_MEMORY_LIMIT", "1073741824") };
    for (backend, overlap) in [("cpu", "1"), ("gpu", "1"), ("gpu", "4")] {
        let sets = [
            format!("method.backend={backend}"),
            format!("run.overlap={overlap}"),
        ];
        let cfg = Config::load(&common::config("r_lambda.toml"), &sets).unwrap();
        for starts in [1, 3] {
            let e = check_map(&cfg, 1 << 26, starts, None)
                .unwrap_err()
                .to_string();
            let n = named(&e);
            assert!(e.contains("shards"), "{e}");
            // Before: the layers' bytes alone, the block in flight left out ("<= 902777
            // cells", then 950 x 950 = 902,500 refused).
            assert!(
                check_map(&cfg, n, starts, None).is_ok(),
                "{backend} x{overlap}, {starts} starts: {n} named and refused: {e}"
            );
            assert!(check_map(&cfg, n + 1, starts, None).is_err(), "{n}");
        }
    }
    // Explore computes each view in one run: a refusal advises a coarser grid, not shards.
    let cfg = Config::load(
        &common::config("r_lambda.toml"),
        &[
            "map.x_points=8192".to_string(),
            "map.y_points=8192".to_string(),
        ],
    )
    .unwrap();
    let e = rattle::explore::EXPLORE
        .check(&cfg)
        .unwrap_err()
        .to_string();
    assert!(!e.contains("shards") && e.contains("explore"), "{e}");
}
