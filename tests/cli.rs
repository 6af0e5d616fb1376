//! The command line end to end: a small biaxial run writes its record and summary, refuses
//! to overwrite, resumes a record cut short to the same result, and rejects bad input.

mod common;

use common::{biaxial, cdlab, small_config};
use std::path::{Path, PathBuf};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("cdlab-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn biaxial_run_records_resumes_and_refuses_to_overwrite() {
    let base = scratch("run");
    let cfg = small_config(&base);
    let out = base.join("full");
    let (ok, text) = biaxial(&cfg, &out, &[]);
    assert!(ok, "{text}");
    assert!(text.contains("peak sigma1") && text.contains("MPa"), "{text}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    for key in [
        "sigma1_peak_mpa",
        "strain_peak",
        "volumetric_strain_final",
        "wall_time_s",
        "phases",
    ] {
        assert!(summary.get(key).is_some(), "summary.json lacks {key}");
    }
    let rec = cdlab::record::read_run(&out).unwrap();
    assert!(rec.truncated.is_none());
    assert!(rec.series.iter().any(|r| r.phase == "compression"));
    assert!(rec.snapshots.len() >= 2, "{} snapshots", rec.snapshots.len());
    let csv = std::fs::read_to_string(out.join("series.csv")).unwrap();
    assert_eq!(csv.lines().count(), rec.series.len() + 1, "CSV rows and header");

    // An existing output directory is refused without --force, nothing overwritten.
    let before = std::fs::read(out.join("run.mcap")).unwrap();
    let (ok, text) = biaxial(&cfg, &out, &[]);
    assert!(!ok && text.contains("--force"), "{text}");
    assert_eq!(before, std::fs::read(out.join("run.mcap")).unwrap());
    // A finished run cannot be resumed.
    let (ok, text) = cdlab(&["biaxial", "--resume", out.to_str().unwrap(), "--quiet"]);
    assert!(!ok && text.contains("already complete"), "{text}");

    // A run killed midway: the record cut at 70% of its size. Resuming it reaches the same
    // summary as the uninterrupted run, bit for bit on the CPU path.
    let cut = base.join("cut");
    std::fs::create_dir_all(&cut).unwrap();
    std::fs::write(cut.join("run.mcap"), &before[..before.len() * 7 / 10]).unwrap();
    let partial = cdlab::record::read_run(&cut).unwrap();
    assert!(partial.truncated.is_some() && partial.last_checkpoint.is_some());
    let (ok, text) = cdlab(&["biaxial", "--resume", cut.to_str().unwrap(), "--quiet"]);
    assert!(ok, "{text}");
    let resumed: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cut.join("summary.json")).unwrap()).unwrap();
    common::assert_same_outcome(&out, &cut);
    // The wall time runs on over the parts: the rows kept from the first part hold their
    // wall time unchanged, the new ones continue from it, and the summary counts both
    // parts (a summary of the resumed part alone would fall short of the first part's).
    let after = cdlab::record::read_run(&cut).unwrap();
    let kept = partial.last_checkpoint.as_ref().unwrap().0;
    let first: Vec<f64> = partial
        .series
        .iter()
        .filter(|r| r.step <= kept)
        .map(|r| r.wall_s)
        .collect();
    let replayed: Vec<f64> = after.series.iter().take(first.len()).map(|r| r.wall_s).collect();
    assert_eq!(first, replayed);
    let walls: Vec<f64> = after.series.iter().map(|r| r.wall_s).collect();
    assert!(walls.iter().all(|w| w.is_finite() && *w >= 0.0), "{walls:?}");
    assert!(walls.windows(2).all(|w| w[0] <= w[1]), "{walls:?}");
    let first_part = *first.last().expect("rows before the checkpoint");
    let total = resumed["wall_time_s"].as_f64().unwrap();
    assert!(
        total >= first_part && first_part > 0.0,
        "{total} s against {first_part} s"
    );
    assert!(total >= *walls.last().unwrap());
    let _ = std::fs::remove_dir_all(&base);
}

/// A preparation shows its compaction's progress: each equilibrium check's kinetic ratio
/// against its threshold, the wall's force balance, and the time left (an estimate once
/// the ratio decays, always the bound of the phase's time cap), then the phase's end.
#[test]
fn a_preparation_shows_its_compaction_and_the_time_left() {
    let base = scratch("prepare_progress");
    let cfg = small_config(&base);
    let sample = base.join("sample.bin");
    let (ok, text) = common::cdlab_with_env(
        &[
            "prepare",
            "--config",
            cfg.to_str().unwrap(),
            "-o",
            sample.to_str().unwrap(),
        ],
        &[("CDLAB_PROGRESS_EVERY", "0")],
    );
    assert!(ok, "{text}");
    let checks: Vec<&str> = text
        .lines()
        .filter(|l| l.contains("kinetic ratio") && l.contains("(ends below 1e-7)"))
        .collect();
    assert!(checks.len() >= 2, "one line per check of 200 steps: {text}");
    assert!(checks.iter().all(|l| l.contains("wall force off by")), "{text}");
    // From the second check on, a rate of wall time per simulated second turns the phase's
    // time cap into a bound on the time left.
    assert!(
        checks[1..]
            .iter()
            .all(|l| l.contains("left") && l.contains("the 60 s cap")),
        "{text}"
    );
    assert!(text.contains("compaction ended at t ="), "{text}");
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn a_prepared_sample_is_reused_by_a_test() {
    let base = scratch("prepare");
    let cfg = small_config(&base);
    let sample = base.join("sample.bin");
    let (ok, text) = cdlab(&[
        "prepare",
        "--config",
        cfg.to_str().unwrap(),
        "-o",
        sample.to_str().unwrap(),
    ]);
    assert!(ok && text.contains("prepared sample written"), "{text}");
    // The final line gives the compacted sample's coordination beside its packing fraction.
    assert!(text.contains("coordination"), "{text}");
    let (ok, text) = cdlab(&[
        "prepare",
        "--config",
        cfg.to_str().unwrap(),
        "-o",
        sample.to_str().unwrap(),
    ]);
    assert!(
        !ok && text.contains("--force"),
        "an existing sample must not be replaced: {text}"
    );
    // The test's configuration asks for 1000 disks (the default), the sample holds 400: a
    // flag that contradicts the sample is refused, a configuration takes the sample's
    // settings, so the summary counts the disks actually simulated.
    let cfg1000 = base.join("default_disks.toml");
    let text1000 = std::fs::read_to_string(&cfg)
        .unwrap()
        .replace("disks = 400", "disks = 1000");
    std::fs::write(&cfg1000, text1000).unwrap();
    let out = base.join("test");
    for (flag, value) in [("--disks", "500"), ("--seed", "7")] {
        let (ok, text) = biaxial(
            &cfg1000,
            &out,
            &["--sample", sample.to_str().unwrap(), flag, value],
        );
        assert!(
            !ok && text.contains(&format!("{flag} {value} contradicts the sample")),
            "{text}"
        );
        assert!(!out.exists(), "a refused test must leave no output");
    }
    let (ok, text) = biaxial(
        &cfg1000,
        &out,
        &["--sample", sample.to_str().unwrap(), "--mu", "0.5"],
    );
    assert!(ok, "{text}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(
        summary["disks"], 400,
        "the sample's 400 disks, not the configuration's 1000"
    );
    let rec = cdlab::record::read_run(&out).unwrap();
    // Started at confinement: no compaction rows.
    assert!(rec.series.iter().all(|r| r.phase != "compaction"));
    assert!(rec.series.iter().any(|r| r.phase == "compression"));
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn bad_input_is_rejected_with_a_clear_message() {
    let base = scratch("bad");
    let out = base.join("o");
    let o = out.to_str().unwrap();
    for (args, expect) in [
        (vec!["biaxial", "--sigma3", "8 m", "--out", o], "--sigma3"),
        (vec!["biaxial", "--sigma3=-1MPa", "--out", o], "sigma3"),
        (vec!["biaxial", "--strain", "1.5", "--out", o], "strain_end"),
        (vec!["biaxial", "--disks", "10", "--out", o], "disks"),
        (vec!["biaxial", "--mu=-0.1", "--out", o], "mu"),
        (vec!["biaxial", "--backend", "tpu", "--out", o], "backend"),
        (vec!["biaxial", "--resume", "/nonexistent/run"], "nonexistent"),
        (vec!["fc2d", "/nonexistent.dat"], "nonexistent"),
        (vec!["fc2d", "/dev/null", "--tol", "0"], "--tol"),
        (vec!["overlaps", "/nonexistent/run"], "nonexistent"),
        (vec!["overlaps", "/nonexistent/run", "--at", "nan"], "--at"),
    ] {
        let (ok, text) = cdlab(&args);
        assert!(!ok, "{args:?} succeeded: {text}");
        assert!(
            text.contains(expect) && !text.contains("panicked"),
            "{args:?}: {text}"
        );
    }
    // A foreign file given to --resume.
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("run.mcap"), b"this is not a record").unwrap();
    let (ok, text) = cdlab(&["biaxial", "--resume", o]);
    assert!(
        !ok && text.contains("run.mcap") && !text.contains("panicked"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&base);
}

/// On a headless machine without XDG_RUNTIME_DIR, Mesa's Vulkan drivers (the software
/// adapter CI installs) printed "error: XDG_RUNTIME_DIR is invalid or not set" while the
/// adapters were listed; cdlab now sets a private value first. Without a Vulkan driver the
/// probe prints nothing either way, so this can only fail where the driver is installed.
#[test]
fn adapter_listing_prints_no_wayland_error_without_a_runtime_dir() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .arg("info")
        .env_remove("XDG_RUNTIME_DIR")
        .output()
        .expect("cdlab runs");
    let text = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{text}");
    assert!(!text.contains("XDG_RUNTIME_DIR"), "stderr: {text}");
}

/// Output into a pipe whose reader has gone (`cdlab config --print-default | head -1`)
/// ended in a panic ("failed printing to stdout: Broken pipe", exit code 101); cdlab now
/// ends quietly, as other Unix tools do: killed by SIGPIPE at its first write, nothing on
/// stderr. The pipe's read end is closed before cdlab starts, so its first write meets a
/// closed pipe whatever the timing (closing it after the spawn let a fast child write its
/// whole output into the pipe's buffer first and pass without meeting a closed pipe).
#[cfg(unix)]
#[test]
fn printing_into_a_closed_pipe_does_not_panic() {
    use std::os::fd::FromRawFd;
    use std::os::unix::process::ExitStatusExt;
    // With a reader, the command prints something: the closed pipe below is written to.
    let open = std::process::Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args(["config", "--print-default"])
        .output()
        .expect("cdlab runs");
    assert!(open.status.success() && !open.stdout.is_empty());

    let mut fds = [0i32; 2];
    // SAFETY: pipe() fills the two descriptors of a new pipe; both are owned below.
    assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0);
    // SAFETY: fds[0] and fds[1] are open descriptors that nothing else owns.
    let (reader, writer) = unsafe {
        (
            std::os::fd::OwnedFd::from_raw_fd(fds[0]),
            std::os::fd::OwnedFd::from_raw_fd(fds[1]),
        )
    };
    drop(reader);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args(["config", "--print-default"])
        .stdout(std::process::Stdio::from(writer))
        .stderr(std::process::Stdio::piped())
        .output()
        .expect("cdlab runs");
    let text = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.signal(),
        Some(libc::SIGPIPE),
        "expected an end by SIGPIPE, got {}; stderr: {text}",
        out.status
    );
    assert!(text.is_empty(), "stderr: {text}");
}

/// SIGTERM (what a scheduler sends at a job's time limit) stops a run at a checkpoint with
/// exit status 143 (128 + 15) and a closed record; `--resume` then ends the test as the
/// uninterrupted run does, bit for bit on the CPU path. While the run goes on, no other
/// process may resume or overwrite its directory.
#[cfg(unix)]
#[test]
fn a_signal_stops_a_run_at_a_checkpoint_that_resumes_to_the_same_end() {
    let base = scratch("signal");
    let cfg = small_config(&base);
    let full = base.join("full");
    let (ok, text) = biaxial(&cfg, &full, &[]);
    assert!(ok, "{text}");
    let total_rows = std::fs::read_to_string(full.join("series.csv"))
        .unwrap()
        .lines()
        .count();

    let out = base.join("stopped");
    // 20 rows in, the run is under way and far from its end.
    let result = common::signal_after_rows(
        &[
            "biaxial",
            "--config",
            cfg.to_str().unwrap(),
            "--quiet",
            "--out",
            out.to_str().unwrap(),
        ],
        &out.join("series.csv"),
        20,
        || {
            // A second process on the running test's directory is refused, nothing touched.
            let (ok, text) = cdlab(&["biaxial", "--resume", out.to_str().unwrap(), "--quiet"]);
            assert!(!ok && text.contains("in use by another cdlab process"), "{text}");
            let (ok, text) = biaxial(&cfg, &out, &["--force"]);
            assert!(!ok && text.contains("in use by another cdlab process"), "{text}");
        },
        libc::SIGTERM,
    );
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(143), "{stderr}");
    assert!(
        stderr.contains("stopped by SIGTERM at step") && stderr.contains("--resume"),
        "{stderr}"
    );
    assert!(
        !out.join("summary.json").exists(),
        "an unfinished run wrote a summary"
    );
    let rec = cdlab::record::read_run(&out).unwrap();
    assert!(rec.truncated.is_none(), "the record was left open");
    let (step, _) = rec.last_checkpoint.clone().expect("a checkpoint");
    assert_eq!(
        rec.series.last().unwrap().step,
        step,
        "the record ends at its checkpoint"
    );
    assert!(
        rec.series.len() + 1 < total_rows,
        "the signal came after the run's end"
    );

    let (ok, text) = cdlab(&["biaxial", "--resume", out.to_str().unwrap(), "--quiet"]);
    assert!(ok, "{text}");
    common::assert_same_outcome(&full, &out);
    let _ = std::fs::remove_dir_all(&base);
}

/// A run whose largest overlap passes docs/method.md's 1% of r_min says so once, when it
/// happens, not only in its summary hours later; a run that stays below it says nothing.
/// At dt = 1 ms (twice the paper's step) and without local updates of deep contacts, the
/// compaction of this small sample under 8 MPa at friction 3 passes 1%; at the defaults it
/// stays below.
#[test]
fn a_run_warns_once_when_its_overlaps_pass_the_bound() {
    let base = scratch("overlap");
    let cfg = small_config(&base);
    let coarse = base.join("coarse.toml");
    let text = std::fs::read_to_string(&cfg).unwrap();
    std::fs::write(
        &coarse,
        text.replace("[solver]\n", "[solver]\ndt = \"1 ms\"\ndeep_overlap = 0.0\n"),
    )
    .unwrap();
    for (config, name) in [(&coarse, "coarse"), (&cfg, "fine")] {
        let out = base.join(name);
        let (ok, text) = cdlab(&[
            "biaxial",
            "--config",
            config.to_str().unwrap(),
            "--mu",
            "3",
            "--sigma3",
            "8MPa",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(ok, "{text}");
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        let deepest = summary["overlap_max_rel"].as_f64().unwrap();
        let warnings = text
            .matches("warning: the largest overlap passed 1% of r_min")
            .count();
        assert_eq!(warnings, usize::from(deepest > 0.01), "{name}: {deepest}: {text}");
        // The warning says how fast the overlap grew: the steps since it was within 0.5%
        // (a fresh run starts with no overlap, so there is such a row).
        assert_eq!(
            text.matches("it was within 0.5% ").count(),
            warnings,
            "{name}: {text}"
        );
        assert_eq!(
            warnings,
            usize::from(name == "coarse"),
            "{name}: {deepest}: {text}"
        );
        // `cdlab overlaps` finds the deep pair from the snapshots' positions: one line per
        // snapshot (strains 0, 0.003 and 0.006, and the preparation's ends at 0), none
        // deeper than the solver's own largest overlap of the run (the series' maximum,
        // over every step, the snapshots' included), and at least one within a factor two
        // of it (the deepest contact lives more than a few steps).
        let (ok, text) = cdlab(&["overlaps", out.to_str().unwrap()]);
        assert!(ok, "{text}");
        let depths: Vec<f64> = text
            .lines()
            .filter(|l| l.starts_with("strain "))
            .filter_map(|l| l.split("overlap").nth(1))
            .map(|l| l.trim().split('%').next().unwrap().trim().parse::<f64>().unwrap() / 100.0)
            .collect();
        assert!(depths.len() >= 3, "{text}");
        let top = depths.iter().cloned().fold(0.0, f64::max);
        assert!(
            top <= deepest * 1.0005 && top > 0.5 * deepest,
            "{name}: {top} against {deepest}: {text}"
        );
        let (ok, at) = cdlab(&["overlaps", out.to_str().unwrap(), "--at", "0.006", "--top", "3"]);
        assert!(ok && at.matches("  disks ").count() == 3, "{at}");
        // Its deepest pair is the last snapshot's line.
        let last = text.lines().rfind(|l| l.starts_with("strain ")).unwrap();
        let pair = |l: &str| {
            l.split(" at ")
                .next()
                .unwrap()
                .split("disks")
                .nth(1)
                .unwrap()
                .trim()
                .to_string()
        };
        let first = at.lines().find(|l| l.starts_with("  disks ")).unwrap();
        assert_eq!(pair(first), pair(last), "{at}\n{text}");
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// Every phase ends with a snapshot (issue 36, item 13: a run to strain 0.005 had one
/// snapshot, at 0.00006): the compaction's and the confinement's last states at strain 0
/// and the final state at the end strain, though it is no multiple of `snapshot_every`,
/// each at the time of its phase's last row. So `bands` has two snapshots to compare, and
/// `render --at` names the strain it drew when no snapshot is at the one asked for, as
/// `fabric --at` and `overlaps --at` name the one they use.
#[test]
fn every_phase_ends_with_a_snapshot_and_the_commands_name_the_one_they_use() {
    let base = scratch("phase-snapshots");
    std::fs::create_dir_all(&base).unwrap();
    let cfg = base.join("c.toml");
    std::fs::write(
        &cfg,
        "[sample]\ndisks = 200\n[solver]\ntol = 1e-3\nbackend = \"cpu\"\n\
         [test]\nstrip_thickness = \"3 m\"\nstrain_end = 0.0025\n\
         [output]\nseries_every = 10\nsnapshot_every = 0.01\ncheckpoint_every = 500\n",
    )
    .unwrap();
    let out = base.join("run");
    let (ok, text) = biaxial(&cfg, &out, &["--no-figures"]);
    assert!(ok, "{text}");
    let rec = cdlab::record::read_run(&out).unwrap();
    let last_row = |phase: &str| rec.series.iter().rfind(|r| r.phase == phase).unwrap();
    let strains: Vec<f64> = rec.snapshots.iter().map(|s| s.strain).collect();
    assert_eq!(rec.snapshots.len(), 3, "{strains:?}");
    for (snap, phase) in rec
        .snapshots
        .iter()
        .zip(["compaction", "confinement", "compression"])
    {
        assert_eq!(snap.time_s, last_row(phase).time_s, "{phase}: {strains:?}");
        assert_eq!(snap.strain, last_row(phase).strain_axial, "{phase}");
    }
    assert!(strains[2] >= 0.0025, "{strains:?}");
    let (ok, text) = cdlab(&["bands", out.to_str().unwrap()]);
    assert!(ok, "{text}");
    let fig = base.join("f.png");
    let render = |at: &str| {
        cdlab(&[
            "render",
            out.to_str().unwrap(),
            "--at",
            at,
            "-o",
            fig.to_str().unwrap(),
        ])
    };
    let (ok, text) = render("0.005");
    assert!(ok, "{text}");
    let note = format!(
        "no snapshot at axial strain 0.005: drawing the nearest, at axial strain {:.5}",
        strains[2]
    );
    assert!(text.contains(&note), "{text}");
    let (ok, text) = render(&format!("{}", strains[2]));
    assert!(ok && !text.contains("no snapshot at"), "{text}");
    // The other commands that take --at say so too, with what they do with the nearest.
    let fab = base.join("fabric");
    for (cmd, doing, extra) in [
        ("fabric", "analysing", vec!["-o", fab.to_str().unwrap()]),
        ("overlaps", "listing", vec![]),
    ] {
        let mut args = vec![cmd, out.to_str().unwrap(), "--at", "0.5"];
        args.extend(extra);
        let (ok, text) = cdlab(&args);
        let note = format!(
            "no snapshot at axial strain 0.5: {doing} the nearest, at axial strain {:.5}",
            strains[2]
        );
        assert!(ok && text.contains(&note), "{cmd}: {text}");
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// `cdlab version` prints the build's information (issue 36, item 18: the version alone):
/// the git commit it was built from when built in a checkout ("-dirty" after it when its
/// sources had uncommitted changes), the wgpu version of
/// Cargo.lock, the target and the profile.
#[test]
fn version_prints_the_build_information() {
    let (ok, text) = cdlab(&["version"]);
    assert!(ok, "{text}");
    assert!(
        text.starts_with(&format!("cdlab {}\n", env!("CARGO_PKG_VERSION"))),
        "{text}"
    );
    let root = env!("CARGO_MANIFEST_DIR");
    let lock = std::fs::read_to_string(Path::new(root).join("Cargo.lock")).unwrap();
    let wgpu = lock
        .split("[[package]]")
        .find(|p| p.contains("\nname = \"wgpu\"\n"))
        .and_then(|p| p.split("version = \"").nth(1))
        .and_then(|v| v.split('"').next())
        .unwrap();
    assert!(text.contains(&format!("\nwgpu: {wgpu}\n")), "{text}");
    assert!(
        text.contains("\nprofile: release\n") || text.contains("\nprofile: debug\n"),
        "{text}"
    );
    assert!(
        text.contains(&format!("\ntarget: {}-", std::env::consts::ARCH)),
        "{text}"
    );
    let head = std::process::Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .current_dir(root)
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string());
    // A build from sources that differ from the commit says so (issue 36's follow-up: a
    // binary built with a merge not yet committed named the commit before it): the same
    // sources as build.rs looks at, as they are now, which is how the build saw them (a
    // change to them reruns the build script).
    let dirty = std::process::Command::new("git")
        .args(["--no-optional-locks", "status", "--porcelain", "--"])
        .args(["src", "shaders", "build.rs", "Cargo.toml", "Cargo.lock"])
        .current_dir(root)
        .output()
        .ok()
        .filter(|o| o.status.success())
        .is_some_and(|o| !o.stdout.trim_ascii().is_empty());
    match head {
        Some(h) if dirty => assert!(text.contains(&format!("\ngit commit: {h}-dirty ")), "{text}"),
        Some(h) => assert!(text.contains(&format!("\ngit commit: {h} ")), "{text}"),
        None => assert!(text.contains("\ngit commit: unknown"), "{text}"),
    }
}
