//! `cdlab bench` on two small samples: the report's structure, units, and figures that agree
//! with each other (per-contact cost from the per-step time, GPU work counts from the step's
//! structure); the GPU cases when a GPU is required.

mod common;
#[path = "gpu_support/mod.rs"]
mod gpu_support;

use common::cdlab;

#[test]
fn bench_writes_its_report_and_rejects_bad_sizes() {
    let out = std::env::temp_dir().join(format!("cdlab-bench-{}", std::process::id()));
    let run = cdlab;
    let gpu = gpu_support::require_gpu();
    let backends = if gpu { "cpu,gpu" } else { "cpu" };
    let (ok, text) = run(&[
        "bench",
        "--disks",
        "200,300",
        "--steps",
        "3",
        "--warmup",
        "2",
        "--backend",
        backends,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let cases: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("bench.json")).unwrap()).unwrap();
    let cases = cases.as_array().expect("an array of cases");
    assert_eq!(cases.len(), if gpu { 4 } else { 2 }, "{cases:?}");
    let md = std::fs::read_to_string(out.join("bench.md")).unwrap();
    // The table's header names every column with its unit.
    for head in [
        "| backend | disks | contacts | iterations/step | ms/step | ns/contact update |",
        "dispatches/step",
        "readbacks/step",
        "device traffic (MB/step)",
        "host peak (MiB)",
        "device (MiB)",
    ] {
        assert!(md.contains(head), "no {head:?} in {md}");
    }
    let f = |c: &serde_json::Value, k: &str| c[k].as_f64().unwrap_or_else(|| panic!("{k}: {c}"));
    for c in cases {
        let disks = c["disks"].as_u64().unwrap();
        assert!(disks == 200 || disks == 300, "{c}");
        let contacts = f(c, "contacts");
        let (it, ms, ns) = (
            f(c, "iterations_per_step"),
            f(c, "ms_per_step"),
            f(c, "ns_per_contact_update"),
        );
        // A dense confined sample: more contacts than disks, at least one iteration.
        assert!(contacts > disks as f64 && it >= 1.0 && ms > 0.0, "{c}");
        // The per-contact figure is the per-step time over contacts x iterations:
        // ns = ms * 1e6 / (contacts * iterations).
        let expected = ms * 1e6 / (contacts * it);
        assert!(
            (ns - expected).abs() <= 1e-9 * expected,
            "ns per contact update {ns}, from ms/step {expected}: {c}"
        );
        assert!(f(c, "host_peak_mib") > 1.0, "{c}");
        // The markdown row shows the same figures, with the table's precision.
        let backend = c["backend"].as_str().unwrap();
        let row = format!(
            "| {backend} | {disks} | {contacts} | {it:.1} | {ms:.2} | {ns:.2} | {:.1} |",
            f(c, "colors_per_step")
        );
        assert!(md.contains(&row), "no row {row:?} in {md}");
        let (d, sub, rb, fixed) = (
            f(c, "dispatches_per_step"),
            f(c, "submissions_per_step"),
            f(c, "readbacks_per_step"),
            f(c, "fixed_dispatches_per_step"),
        );
        if backend.starts_with("cpu") {
            assert_eq!(
                (d, sub, rb, fixed, f(c, "device_mib"), f(c, "traffic_mb_per_step")),
                (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
                "{c}"
            );
        } else {
            // src/gpu/step.rs: 19 fixed dispatches in submission A and 3 in C, plus the
            // coloring rounds; one per color per iteration besides. More "fixed" dispatches
            // than a few dozen would mean work that grows with the iterations.
            let colors = f(c, "colors_per_step");
            assert!(d >= colors * it + 22.0, "{c}");
            assert!(
                (22.0..22.0 + 64.0).contains(&fixed),
                "fixed dispatches {fixed}: {c}"
            );
            // A status readback per step, and convergence read per batch of iterations, not
            // per iteration.
            assert!(rb > 1.0 && rb <= 2.0 + it / 4.0, "readbacks {rb}: {c}");
            assert!(sub >= rb, "{c}");
            assert!(f(c, "device_mib") > 0.0, "{c}");
            // The sweeps alone move 204 bytes per contact and iteration (src/gpu/traffic.rs:
            // the record, two velocities read and written, impulses and convergence terms).
            let mb = f(c, "traffic_mb_per_step");
            assert!(
                mb >= 0.9 * 204e-6 * contacts * it,
                "device traffic {mb} MB/step: {c}"
            );
        }
    }
    for bad in [["--disks", "0"], ["--steps", "0"]] {
        let (ok, text) = run(&["bench", bad[0], bad[1], "--out", out.to_str().unwrap()]);
        assert!(
            !ok && text.contains(bad[0]) && !text.contains("panicked"),
            "{text}"
        );
    }
    let _ = std::fs::remove_dir_all(&out);
}
