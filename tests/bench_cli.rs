//! `cdlab bench` on a small sample: the report is written and holds sensible figures.

mod common;

use common::cdlab;

#[test]
fn bench_writes_its_report_and_rejects_bad_sizes() {
    let out = std::env::temp_dir().join(format!("cdlab-bench-{}", std::process::id()));
    let run = cdlab;
    let (ok, text) = run(&[
        "bench",
        "--disks",
        "300",
        "--steps",
        "3",
        "--warmup",
        "2",
        "--backend",
        "cpu",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let cases: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("bench.json")).unwrap()).unwrap();
    let c = &cases[0];
    assert_eq!(c["disks"], 300);
    assert!(
        c["ms_per_step"].as_f64().unwrap() > 0.0 && c["contacts"].as_u64().unwrap() > 0,
        "{c}"
    );
    assert!(
        std::fs::read_to_string(out.join("bench.md"))
            .unwrap()
            .contains("| cpu")
    );
    for bad in [["--disks", "0"], ["--steps", "0"]] {
        let (ok, text) = run(&["bench", bad[0], bad[1], "--out", out.to_str().unwrap()]);
        assert!(
            !ok && text.contains(bad[0]) && !text.contains("panicked"),
            "{text}"
        );
    }
    let _ = std::fs::remove_dir_all(&out);
}
