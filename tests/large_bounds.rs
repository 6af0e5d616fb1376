//! The checker of `benches/large_bounds.sh` (`benches/large_bounds.py`) reads the summary a
//! real run writes, passes a test within the overlap bound, and fails on a test past it or
//! on a test that never finished.

mod common;

use common::{biaxial, outcome, small_config};
use std::path::{Path, PathBuf};
use std::process::Command;

/// `python3 benches/large_bounds.py DIRS...`: whether it passed, and what it printed.
fn check(dirs: &[&Path]) -> (bool, String) {
    let out = Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/large_bounds.py"))
        .args(dirs)
        .output()
        .expect("python3 runs (the CI installs it)");
    outcome(&out)
}

#[test]
fn the_bound_check_passes_a_run_within_it_and_fails_one_past_it() {
    let base: PathBuf = std::env::temp_dir().join(format!("cdlab-large-bounds-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&base);
    let cfg = small_config(&base);
    let run = base.join("within");
    let (ok, text) = biaxial(&cfg, &run, &["--no-figures"]);
    assert!(ok, "{text}");
    let summary = std::fs::read_to_string(run.join("summary.json")).unwrap();
    let mut value: serde_json::Value = serde_json::from_str(&summary).unwrap();
    let largest = value["overlap_max_rel"].as_f64().unwrap();
    // The small run stays far inside the bound (1% of r_min, docs/method.md).
    assert!(largest < 0.01, "largest overlap {largest} of r_min");

    let (ok, text) = check(&[&run]);
    assert!(ok, "{text}");
    assert!(text.contains("| within | 400 |"), "{text}");
    assert!(text.contains("every test within 1% of r_min"), "{text}");

    // The same summary with its largest overlap at 1.5% of r_min.
    let past = base.join("past");
    std::fs::create_dir_all(&past).unwrap();
    value["overlap_max_rel"] = serde_json::json!(0.015);
    std::fs::write(past.join("summary.json"), value.to_string()).unwrap();
    let (ok, text) = check(&[&run, &past]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("| past | 400 |") && text.contains("| 1.500 |"),
        "{text}"
    );
    assert!(text.contains("unfinished: ") && text.contains("past"), "{text}");

    // A test without a summary (stopped, or never run) fails the check too.
    let missing = base.join("missing");
    let (ok, text) = check(&[&run, &missing]);
    assert!(!ok, "{text}");
    assert!(text.contains("no finished test"), "{text}");
    let _ = std::fs::remove_dir_all(&base);
}
