//! The library API of `cdlab::run` on its own, without the command line: a caller's
//! `Cancel` token stops a test at a checkpoint from inside its progress callback (no signal
//! involved), `run::resume` ends it exactly as an uninterrupted run, and the faults a caller
//! acts on come back as `Error::Run` with their `RunFault`.

mod record_support;

use cdlab::error::RunFault;
use cdlab::interrupt::{CANCELLED, Cancel};
use cdlab::run::{self, Event, Silent};
use cdlab::{Error, Result};
use record_support::{compacted, config, outcome, scratch};
use std::path::Path;

/// The fault of an `Error::Run`, or the error itself when it is another.
fn fault<T: std::fmt::Debug>(r: Result<T>) -> RunFault {
    match r {
        Err(Error::Run { fault, .. }) => fault,
        other => panic!("expected Error::Run, got {other:?}"),
    }
}

/// Cancelled at its first compression row, the test returns `Interrupted` with
/// `CANCELLED` and the step of a checkpoint past the preparation; resumed, it ends with the
/// summary, rows and final state of the same test run without a stop (bit for bit, the CPU
/// path being deterministic). Then: resuming the complete run is `Complete`, starting into
/// its directory without `replace` is `Occupied`, resuming a directory that is none is
/// `NoRun`, and `run::open` reads back the summary `resume` returned.
#[test]
fn a_cancelled_test_resumes_to_the_uninterrupted_result() {
    let root = scratch("library");
    let mut base = config(10);
    let scene = compacted(&base);

    base.output.dir = root.join("whole");
    let whole = run::start(
        &base,
        Some(scene.clone()),
        run::Existing::Refuse,
        &mut Silent,
        &Cancel::new(),
    )
    .expect("whole run");
    assert_eq!((whole.resumed_from, whole.summary_only), (None, false));

    let mut cut = base.clone();
    cut.output.dir = root.join("cut");
    let cancel = Cancel::new();
    let (token, mut rows) = (cancel.clone(), 0);
    let mut stop_at_compression = |e: &Event| {
        if let Event::Row { row, .. } = e {
            rows += 1;
            if row.phase == "compression" {
                token.cancel();
            }
        }
    };
    let stopped = run::start(
        &cut,
        Some(scene),
        run::Existing::Refuse,
        &mut stop_at_compression,
        &cancel,
    );
    let step = match stopped {
        Err(Error::Interrupted { signal, step }) => {
            assert_eq!(signal, CANCELLED);
            step
        }
        other => panic!("expected Interrupted, got {other:?}"),
    };
    assert!(
        step > 0 && rows > 0,
        "checkpoint at step {step} after {rows} rows"
    );
    assert!(
        !cut.output.dir.join("summary.json").exists(),
        "a stopped run has no summary"
    );

    let resumed = run::resume(&cut.output.dir, None, &mut Silent, &Cancel::new()).expect("resume");
    assert_eq!(resumed.resumed_from, Some(step));
    assert_eq!(outcome(&cut.output.dir), outcome(&base.output.dir));

    let again = run::resume(&cut.output.dir, None, &mut Silent, &Cancel::new());
    assert_eq!(fault(again), RunFault::Complete);
    let occupied = run::start(&cut, None, run::Existing::Refuse, &mut Silent, &Cancel::new());
    assert_eq!(fault(occupied), RunFault::Occupied);
    let none = run::resume(&root.join("nothing here"), None, &mut Silent, &Cancel::new());
    assert_eq!(fault(none), RunFault::NoRun);

    let opened = run::open(&cut.output.dir).expect("open");
    let summary = opened.summary.expect("a finished run has its summary");
    assert_eq!(summary.sigma1_peak_mpa, resumed.summary.sigma1_peak_mpa);
    assert_eq!(opened.record.series.len(), outcome(&cut.output.dir).rows.len());
    let _ = std::fs::remove_dir_all(&root);
}

/// The small test every case of [`every_configuration_key_changes_what_a_run_does`] starts
/// from: 120 disks, a compaction that ends at its time cap, a confinement that settles on
/// its kinetic ratio and balance after 200 of its 300 allowed steps' worth, a compression to
/// strain 0.002 (about 270 steps), a row every 5 steps, snapshots and checkpoints.
const KEY_TEST_BASE: &str = "[sample]\ndisks = 120\nseed = 3\n[solver]\nbackend = \"cpu\"\n\
    [test]\nstrip_thickness = \"2 m\"\nstrain_end = 0.002\n\
    [equilibrium]\nmax_time = \"0.3 s\"\nhold_steps = 50\n\
    [output]\nseries_every = 5\nsnapshot_every = 0.001\ncheckpoint_every = 100\n";

/// Each configuration key with two values that must make a run differ, and the other keys
/// it needs set for its effect to show (a relaxation only acts from the iteration its
/// `*_after` key names, a method's own setting only under that method, ...). Values are
/// TOML. The key's effect is one the run itself shows: its rows, phase ends, snapshots,
/// checkpoints, backend, directory or error.
const KEY_CASES: &[(&str, &[&str], &str, &str)] = &[
    ("sample.disks", &[], "120", "130"),
    ("sample.r_min", &[], "\"0.5 m\"", "\"0.45 m\""),
    ("sample.r_max", &[], "\"2 m\"", "\"1.8 m\""),
    ("sample.density", &[], "\"2600 kg/m3\"", "\"2000 kg/m3\""),
    ("sample.seed", &[], "3", "4"),
    ("sample.aspect_ratio", &[], "2.5", "2.0"),
    ("solver.dt", &[], "\"0.5 ms\"", "\"0.4 ms\""),
    ("solver.theta", &[], "1.0", "0.8"),
    ("solver.tol", &[], "3e-4", "1e-2"),
    ("solver.max_iter", &[], "1000", "3"),
    ("solver.method", &[], "\"colored-gs\"", "\"gs\""),
    (
        "solver.jacobi_relax",
        &["solver.method = \"jacobi\""],
        "0.5",
        "0.9",
    ),
    ("solver.gs_relax", &["solver.gs_relax_after = 0"], "0.5", "0.9"),
    ("solver.gs_relax_after", &[], "100", "0"),
    (
        "solver.velocity_tol",
        &["solver.gs_relax_after = 0"],
        "1e-5",
        "1e-2",
    ),
    ("solver.open_skip_gap", &[], "1e-3", "0.0"),
    ("solver.deep_overlap", &[], "0.0", "1e-6"),
    ("solver.deep_sweeps", &["solver.deep_overlap = 1e-6"], "50", "1"),
    (
        "solver.anderson_depth",
        &["solver.method = \"anderson-gs\""],
        "5",
        "1",
    ),
    ("solver.alert_distance", &[], "0.1", "0.3"),
    // The key the GPU once ignored (issue 35): on the CPU a step then ends only on a
    // multiple of it, so the iteration counts of the rows change.
    ("solver.check_every", &[], "0", "7"),
    (
        "solver.overlap_limit",
        &["solver.deep_overlap = 0.0"],
        "0.05",
        "1e-4",
    ),
    (
        "solver.backend",
        &["equilibrium.max_time = \"0.01 s\"", "test.strain_end = 0.0002"],
        "\"cpu\"",
        "\"gpu\"",
    ),
    ("compaction.sigma_c", &[], "\"8 MPa\"", "\"4 MPa\""),
    ("compaction.friction", &[], "0.0", "0.3"),
    ("test.mu", &[], "0.3", "0.1"),
    ("test.wall_mu", &[], "0.3", "0.0"),
    ("test.sigma3", &[], "\"8 MPa\"", "\"4 MPa\""),
    ("test.strip_thickness", &[], "\"2 m\"", "\"3 m\""),
    ("test.strip_refresh_every", &[], "100", "0"),
    ("test.axial_velocity", &[], "\"0.5 m/s\"", "\"0.3 m/s\""),
    ("test.strain_end", &[], "0.002", "0.0015"),
    ("test.e_n", &[], "0.0", "0.5"),
    ("test.e_t", &[], "0.0", "0.5"),
    ("equilibrium.kinetic_ratio", &[], "1e-8", "1e-3"),
    ("equilibrium.compaction_kinetic_ratio", &[], "1e-7", "1e-3"),
    ("equilibrium.runaway_kinetic_ratio", &[], "1e-2", "1e-12"),
    ("equilibrium.creep_rate", &[], "1e-5", "10.0"),
    ("equilibrium.force_imbalance", &[], "0.01", "1e-6"),
    ("equilibrium.hold_steps", &[], "50", "60"),
    ("equilibrium.max_time", &[], "\"0.3 s\"", "\"0.25 s\""),
    ("output.dir", &[], "\"a\"", "\"b\""),
    ("output.series_every", &[], "5", "7"),
    ("output.snapshot_every", &[], "0.001", "0.0005"),
    ("output.checkpoint_every", &[], "100", "150"),
];

/// Keys that change how fast a run goes but, by design, nothing it computes: each with
/// two values whose runs must be identical (the colored Gauss-Seidel team gives the
/// sequential sweep's results bit for bit whatever its size: docs/method.md).
const SPEED_ONLY_KEYS: &[(&str, &str, &str)] = &[("solver.threads", "1", "2")];

/// What a run did, as far as a configuration can change it: its directory, backend, rows
/// (wall times left out), phase ends, snapshots, last checkpoint and error.
fn fingerprint(config: &cdlab::Config) -> String {
    let mut seen = Vec::new();
    let mut progress = |e: &Event| match e {
        Event::Running { backend, dir } => seen.push(format!("running {backend} in {}", dir.display())),
        Event::Row { row, .. } => {
            let mut v = serde_json::to_value(row).unwrap();
            v.as_object_mut().unwrap().remove("wall_s");
            seen.push(v.to_string());
        }
        Event::PhaseEnd(end) => seen.push(serde_json::to_string(end).unwrap()),
        _ => {}
    };
    let result = run::start(
        config,
        None,
        run::Existing::Replace,
        &mut progress,
        &Cancel::new(),
    );
    match result {
        Ok(o) => {
            let rec = run::open(&o.dir).expect("a finished run opens").record;
            // The reader keeps only the last checkpoint; the record holds them all.
            let bytes = std::fs::read(o.dir.join(cdlab::record::MCAP_FILE)).unwrap();
            let checkpoints = mcap::MessageStream::new(&bytes)
                .unwrap()
                .filter(|m| m.as_ref().unwrap().channel.topic == cdlab::record::TOPIC_CHECKPOINT)
                .count();
            seen.push(format!(
                "{} snapshots at {:?}, {checkpoints} checkpoints, the last at step {:?}",
                rec.snapshots.len(),
                rec.snapshots.iter().map(|s| s.strain).collect::<Vec<_>>(),
                rec.last_checkpoint.map(|c| c.0)
            ));
        }
        Err(e) => seen.push(format!("error: {e}")),
    }
    seen.join("\n")
}

/// `KEY_TEST_BASE` with `settings` (`section.key = value`, TOML) applied, into `dir`.
fn key_config(settings: &[String], dir: &Path) -> cdlab::Config {
    let mut table: toml::Table = KEY_TEST_BASE.parse().unwrap();
    let mut has_dir = false;
    for s in settings {
        let (key, value) = s.split_once(" = ").unwrap();
        let (section, name) = key.split_once('.').unwrap();
        let value: toml::Table = format!("v = {value}").parse().unwrap();
        let section = table
            .entry(section)
            .or_insert_with(|| toml::Value::Table(Default::default()));
        section
            .as_table_mut()
            .unwrap()
            .insert(name.into(), value["v"].clone());
        has_dir |= key == "output.dir";
    }
    let mut config = cdlab::Config::from_toml_str(&table.to_string()).unwrap();
    config.output.dir = if has_dir {
        dir.join(&config.output.dir)
    } else {
        dir.join("run")
    };
    config
}

/// Every key of the configuration changes what a run does, or is listed as changing only
/// its speed (and then changes nothing it computes). A key parsed, validated and
/// documented but read by no code (as `solver.check_every` once was on the GPU) fails
/// here, and so does a new key added without a case.
#[test]
fn every_configuration_key_changes_what_a_run_does() {
    let value = serde_json::to_value(cdlab::Config::default()).unwrap();
    let mut keys: Vec<String> = value
        .as_object()
        .unwrap()
        .iter()
        .flat_map(|(s, t)| t.as_object().unwrap().keys().map(move |k| format!("{s}.{k}")))
        .collect();
    // Keys unset by default are not serialised: the default file shows them commented out.
    keys.extend(["solver.deep_overlap".to_string(), "test.wall_mu".to_string()]);
    keys.sort();
    let mut covered: Vec<String> = KEY_CASES
        .iter()
        .map(|c| c.0.to_string())
        .chain(SPEED_ONLY_KEYS.iter().map(|c| c.0.to_string()))
        .collect();
    covered.sort();
    assert_eq!(keys, covered, "each configuration key needs a case here");

    let root = scratch("keys");
    let mut inert = Vec::new();
    for (key, context, a, b) in KEY_CASES {
        let settings = |v: &str| {
            let mut s: Vec<String> = context.iter().map(|c| c.to_string()).collect();
            s.push(format!("{key} = {v}"));
            s
        };
        let (fa, fb) = (
            fingerprint(&key_config(&settings(a), &root)),
            fingerprint(&key_config(&settings(b), &root)),
        );
        if fa == fb {
            inert.push(format!("{key}: {a} and {b} ran alike"));
        }
    }
    assert!(inert.is_empty(), "keys without an effect:\n{}", inert.join("\n"));
    for (key, a, b) in SPEED_ONLY_KEYS {
        let (fa, fb) = (
            fingerprint(&key_config(&[format!("{key} = {a}")], &root)),
            fingerprint(&key_config(&[format!("{key} = {b}")], &root)),
        );
        // The run names its team ("cpu (2 threads; ...)"), and computes the same.
        let (head_a, rest_a) = fa.split_once('\n').unwrap();
        let (head_b, rest_b) = fb.split_once('\n').unwrap();
        assert_ne!(
            head_a, head_b,
            "{key} = {a} or {b}: the run names the same backend"
        );
        let first_difference = rest_a.lines().zip(rest_b.lines()).find(|(x, y)| x != y);
        assert!(
            rest_a == rest_b,
            "{key} = {a} or {b} changed what the run computed: {first_difference:?}"
        );
    }
    let _ = std::fs::remove_dir_all(&root);
}
