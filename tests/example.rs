//! The library example (`examples/run_test.rs`) runs, and what it prints is what the run
//! recorded: the same code, included here, so that the documented API cannot rot.

#[path = "../examples/run_test.rs"]
#[allow(dead_code)]
mod example;

/// A 300-disk test to 0.3% of axial strain under 1 MPa: the callback sees every row the
/// record holds and the three phases end in order, the record ends at the end strain, and
/// the peak stress lies above the confining stress (a compressed sample carries more
/// axially than laterally) and below five times it (docs/results.md: over the whole
/// 5000-disk campaign the peak stress ratio stays between 1.33 and 2.63; 300 disks scatter
/// more, a few tenths of a percent of strain build less).
#[test]
fn the_library_example_runs_a_test_and_reads_it_back() {
    let dir = std::env::temp_dir().join(format!("cdlab_example_{}", std::process::id()));
    let m = example::run_example(&dir).expect("the example runs");
    assert_eq!(
        m.rows_seen, m.rows_recorded,
        "every recorded row reaches the callback"
    );
    assert_eq!(m.phases_ended, ["compaction", "confinement", "compression"]);
    assert!(
        m.final_strain >= 0.003 && m.final_strain < 0.0031,
        "final strain {}",
        m.final_strain
    );
    assert!(
        m.sigma1_peak_mpa > 1.0 && m.sigma1_peak_mpa < 5.0,
        "peak sigma1 {} MPa",
        m.sigma1_peak_mpa
    );
    let _ = std::fs::remove_dir_all(&dir);
}
