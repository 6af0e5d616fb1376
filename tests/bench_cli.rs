//! `cdlab bench` on two small samples: the report's structure, units, and figures that agree
//! with each other (per-contact cost from the per-step time, GPU work counts from the step's
//! structure); the GPU cases when a GPU is required.

mod common;
#[path = "gpu_support/mod.rs"]
mod gpu_support;

use common::cdlab;

/// The cases of the `bench.json` that `cdlab bench` wrote to `out`.
fn cases_in(out: &std::path::Path) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(out.join("bench.json")).unwrap();
    serde_json::from_str(&text).expect("an array of cases")
}

/// The row of `bench.md`'s machine table for round `round`, from its probe's figures in
/// `bench.json`, after checking that they can be figures of a machine: positive and
/// finite, and the round trip between threads given where the test runs on two cores or
/// more.
fn machine_row(round: u64, m: &serde_json::Value) -> String {
    let f = |k: &str| {
        let v = m[k].as_f64().unwrap_or_else(|| panic!("{k}: {m}"));
        assert!(v.is_finite() && v > 0.0, "{k}: {m}");
        v
    };
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let trip = m["round_trip_ns"].as_f64();
    assert_eq!(trip.is_some(), cores > 1, "{m}");
    assert!(trip.is_none_or(|t| t.is_finite() && t > 0.0), "{m}");
    let job = m["team_job_us"].as_f64();
    assert_eq!(job.is_some(), cores > 1, "{m}");
    assert!(job.is_none_or(|t| t.is_finite() && t > 0.0), "{m}");
    format!(
        "| {round} | {:.1} | {:.0} | {} | {:.1} | {} | {:.1} |",
        f("fill_gb_s"),
        f("load_ns"),
        trip.map_or_else(|| "-".to_string(), |t| format!("{t:.0}")),
        f("thread_start_us"),
        job.map_or_else(|| "-".to_string(), |t| format!("{t:.1}")),
        f("wake_us")
    )
}

#[test]
fn bench_writes_its_report_and_rejects_bad_sizes() {
    let out = std::env::temp_dir().join(format!("cdlab-bench-{}", std::process::id()));
    let run = cdlab;
    let gpu = gpu_support::require_gpu();
    let backends = if gpu { "cpu,gpu" } else { "cpu" };
    if !gpu {
        eprintln!(
            "SKIPPED (GPU cases): bench_writes_its_report_and_rejects_bad_sizes: \
             CDLAB_REQUIRE_GPU is not set, the CPU cases alone are checked"
        );
    }
    let (ok, text) = run(&[
        "bench",
        "--disks",
        "200,300",
        "--steps",
        "6",
        "--window",
        "3",
        "--warmup",
        "2",
        "--backend",
        backends,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let cases = cases_in(&out);
    assert_eq!(cases.len(), if gpu { 4 } else { 2 }, "{cases:?}");
    let md = std::fs::read_to_string(out.join("bench.md")).unwrap();
    // The table's header names every column with its unit.
    for head in [
        "| backend | method | disks | contacts | check every (it) | iterations/step | ms/step | ns/contact update |",
        "dispatches/step",
        "empty dispatches/step",
        "waits/window",
        "device traffic (MB/step)",
        "host peak (MiB)",
        "device (MiB)",
    ] {
        assert!(md.contains(head), "no {head:?} in {md}");
    }
    let f = |c: &serde_json::Value, k: &str| c[k].as_f64().unwrap_or_else(|| panic!("{k}: {c}"));
    for c in &cases {
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
        let row = machine_row(1, &c["machine"]);
        assert!(md.contains(&row), "no machine row {row:?} in {md}");
        // The markdown row shows the same figures, with the table's precision.
        let backend = c["backend"].as_str().unwrap();
        assert_eq!(f(c, "window"), 3.0, "{c}");
        let every = f(c, "check_every");
        let row = format!(
            "| {backend} | colored-gs | {disks} | {contacts} | {every} | {it:.1} | {ms:.2} | {ns:.2} | {:.1} |",
            f(c, "colors_per_step")
        );
        assert!(md.contains(&row), "no row {row:?} in {md}");
        let (d, sub, rb, fixed) = (
            f(c, "dispatches_per_step"),
            f(c, "submissions_per_step"),
            f(c, "readbacks_per_window"),
            f(c, "fixed_dispatches_per_step"),
        );
        if backend.starts_with("cpu") {
            // The CPU tests convergence every iteration by default (solver.check_every 0).
            assert_eq!(every, 1.0, "{c}");
            assert_eq!(
                (d, sub, rb, fixed, f(c, "device_mib"), f(c, "traffic_mb_per_step")),
                (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
                "{c}"
            );
        } else {
            // src/gpu/step.rs: 20 fixed dispatches before the solve and 3 after it, 1 for
            // the reductions, plus the coloring rounds; one per color per iteration
            // besides. More "fixed" dispatches than a few dozen would mean work that grows
            // with the iterations.
            assert_eq!(every, cdlab::solver::GPU_CHECK_EVERY as f64, "{c}");
            let colors = f(c, "colors_per_step");
            // At least one sweep dispatch per iteration (the small colors together), at
            // most one per color.
            assert!(d >= it + 24.0 && d <= (colors + 1.0) * it + 24.0 + 64.0, "{c}");
            assert!(
                (24.0..24.0 + 64.0).contains(&fixed),
                "fixed dispatches {fixed}: {c}"
            );
            // One submission per step and one wait per window, unless a window was run
            // again (each redo submits and waits once more).
            let redone = f(c, "redone_steps");
            assert_eq!(rb, 1.0 + redone / 2.0, "waits per window {rb}: {c}");
            assert_eq!(
                sub,
                1.0 + redone * 3.0 / 6.0 + redone / 6.0,
                "submissions per step {sub}: {c}"
            );
            assert!(f(c, "device_mib") > 0.0, "{c}");
            // Device times, where the adapter writes timestamps (lavapipe does): the solve
            // is part of the step, and the steps run one after the other on one queue
            // within the wall time measured around them.
            if let (Some(dev), Some(solve)) = (
                c["device_ms_per_step"].as_f64(),
                c["device_solve_ms_per_step"].as_f64(),
            ) {
                assert!(0.0 < solve && solve < dev && dev <= ms, "{c}");
                // The phases tile the step: their sum with the solve is the step's time,
                // to the rounding of the timestamps (one tick each, under a microsecond).
                let p = &c["device_phases_ms_per_step"];
                let parts: Vec<f64> = ["detection", "coloring", "deep_updates", "integration"]
                    .iter()
                    .map(|k| p[k].as_f64().unwrap_or(-1.0))
                    .collect();
                assert!(parts.iter().all(|&t| t >= 0.0), "{c}");
                let sum = solve + parts.iter().sum::<f64>();
                assert!(
                    (sum - dev).abs() <= 1e-3 * dev + 1e-3,
                    "phases {sum} ms against the step's {dev} ms: {c}"
                );
                // Detection and coloring each run a dozen dispatches or more.
                assert!(parts[0] > 0.0 && parts[1] > 0.0, "{c}");
            }
            // The sweeps alone move 204 bytes per contact and iteration (src/gpu/traffic.rs:
            // the record, two velocities read and written, impulses and convergence terms).
            let mb = f(c, "traffic_mb_per_step");
            assert!(
                mb >= 0.9 * 204e-6 * contacts * it,
                "device traffic {mb} MB/step: {c}"
            );
        }
    }
    for bad in [["--disks", "0"], ["--steps", "0"], ["--rounds", "0"]] {
        let (ok, text) = run(&["bench", bad[0], bad[1], "--out", out.to_str().unwrap()]);
        assert!(
            !ok && text.contains(bad[0]) && !text.contains("panicked"),
            "{text}"
        );
    }
    let _ = std::fs::remove_dir_all(&out);
}

/// `--rounds`: every case again per round, sizes in turn, and the ratio between sizes given
/// per round and as the median over the rounds, computed here again from `bench.json`.
#[test]
fn bench_rounds_give_each_ratio_within_a_round_and_its_median() {
    let out = std::env::temp_dir().join(format!("cdlab-bench-rounds-{}", std::process::id()));
    let (ok, text) = cdlab(&[
        "bench",
        "--disks",
        "200,300",
        "--steps",
        "3",
        "--window",
        "3",
        "--warmup",
        "1",
        "--backend",
        "cpu",
        "--rounds",
        "3",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let cases = cases_in(&out);
    let order: Vec<(u64, u64)> = cases
        .iter()
        .map(|c| (c["round"].as_u64().unwrap(), c["disks"].as_u64().unwrap()))
        .collect();
    assert_eq!(
        order,
        [(1, 200), (1, 300), (2, 200), (2, 300), (3, 200), (3, 300)]
    );
    let ms = |k: usize| cases[k]["ms_per_step"].as_f64().unwrap();
    let fixed = |k: usize| cases[k]["cpu_phases"]["fixed_ns_per_disk"].as_f64().unwrap();
    let mut step: Vec<f64> = (0..3).map(|r| ms(2 * r + 1) / ms(2 * r)).collect();
    let mut per_disk: Vec<f64> = (0..3).map(|r| fixed(2 * r + 1) / fixed(2 * r)).collect();
    step.sort_by(f64::total_cmp);
    per_disk.sort_by(f64::total_cmp);
    let md = std::fs::read_to_string(out.join("bench.md")).unwrap();
    let backend = cases[0]["backend"].as_str().unwrap();
    // The median of three is the middle one; the range runs from the smallest to the largest.
    let want = format!(
        "- {backend} colored-gs: 300 against 200 disks: time per step x{:.2} (x{:.2}-x{:.2}, 3 rounds); fixed part per disk x{:.2} (x{:.2}-x{:.2}, 3 rounds)",
        step[1], step[0], step[2], per_disk[1], per_disk[0], per_disk[2]
    );
    assert!(md.contains(&want), "no {want:?} in {md}");
    // Each round's ratio is against that round's first size, not the first round's.
    let third = format!("round 3: 200 -> 300 disks: time per step x{:.2}", ms(5) / ms(4));
    assert!(md.contains(&third), "no {third:?} in {md}");
    // Each round has its own probe of the machine, which both its cases carry and the
    // table shows in the round's row.
    for r in 0..3 {
        assert_eq!(
            cases[2 * r]["machine"],
            cases[2 * r + 1]["machine"],
            "round {}",
            r + 1
        );
        let row = machine_row(r as u64 + 1, &cases[2 * r]["machine"]);
        assert!(md.contains(&row), "no {row:?} in {md}");
    }
    let _ = std::fs::remove_dir_all(&out);
}
