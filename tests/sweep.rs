//! A tiny campaign end to end: 2 frictions x 2 pressures on small samples, run as two
//! shards, skipped when rerun, then analysed by `cdlab report`.

mod common;

use common::cdlab;
use std::path::PathBuf;

/// A fresh directory `cdlab-NAME-PID` under the temp dir holding a base configuration of
/// small, short tests (300 disks to strain 0.004) and `sweep.toml` over `grid` (the
/// sweep file's `mu` and `sigma3` lines), whose tests go to `campaign/`. Returns the
/// directory and the sweep file.
fn tiny_campaign(name: &str, grid: &str) -> (PathBuf, PathBuf) {
    let base = std::env::temp_dir().join(format!("cdlab-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&base);
    std::fs::create_dir_all(&base).unwrap();
    std::fs::write(
        base.join("base.toml"),
        "[sample]\ndisks = 300\n[solver]\ntol = 1e-3\n[test]\nstrip_thickness = \"3 m\"\nstrain_end = 0.004\n\
         [output]\nseries_every = 10\nsnapshot_every = 0.0\n",
    )
    .unwrap();
    let sweep = base.join("sweep.toml");
    std::fs::write(
        &sweep,
        format!(
            "base = \"base.toml\"\nout = \"{}\"\n{grid}",
            base.join("campaign").display()
        ),
    )
    .unwrap();
    (base, sweep)
}

#[test]
fn tiny_sweep_runs_in_shards_skips_finished_tests_and_reports() {
    let (base, sweep) = tiny_campaign("sweep", "mu = [0.1, 0.5]\nsigma3 = [\"1 MPa\", \"4 MPa\"]\n");
    let s = sweep.to_str().unwrap();
    for shard in ["0/2", "1/2"] {
        let (ok, text) = cdlab(&["sweep", s, "--shard", shard, "--jobs", "2"]);
        assert!(ok, "shard {shard}: {text}");
        assert!(text.contains("2 in this shard"), "{text}");
        // That two jobs run two tests at once is proved without a clock in
        // tests/concurrency.rs, `two_jobs_start_two_tests_at_once`.
        assert_eq!(text.matches("sweep: starting").count(), 2, "{text}");
        if shard == "0/2" {
            // The grid's tests 0 and 2 are finished: a sweep of the whole grid takes them
            // first (they are only skipped), so its counts include them from the start.
            let (ok, text) = cdlab(&["sweep", s, "--jobs", "1", "--dry-run"]);
            assert!(ok, "{text}");
            assert!(
                text.contains("[2/4, campaign 0.00 h]")
                    && text.contains("seed1_mu0.5_s1MPa: already finished, would be skipped")
                    && text.contains("[3/4, campaign 0.00 h]"),
                "{text}"
            );
            let second = text.find("[2/4").unwrap();
            let third = text.find("[3/4").unwrap();
            assert!(text[second..third].contains("seed1_mu0.5_s1MPa"), "{text}");
            assert!(text[third..].contains("seed1_mu0.1_s4MPa: would start"), "{text}");
            // The report on the campaign so far names the other shard's tests as not run.
            let campaign = base.join("campaign");
            let (ok, text) = cdlab(&["report", campaign.to_str().unwrap()]);
            assert!(ok && text.contains("2 tests, 2 frictions"), "{text}");
            assert!(
                text.contains("not run: 2 tests listed in")
                    && text.contains("found nowhere: seed1_mu0.1_s4MPa, seed1_mu0.5_s4MPa\n"),
                "{text}"
            );
        }
    }
    let (ok, text) = cdlab(&["sweep", s]);
    assert!(
        ok && text.matches("already finished, skipped").count() == 4,
        "{text}"
    );
    let campaign = base.join("campaign");
    let (ok, text) = cdlab(&["report", campaign.to_str().unwrap()]);
    assert!(ok && text.contains("4 tests, 2 frictions"), "{text}");
    assert!(!text.contains("not run"), "{text}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(campaign.join("report.json")).unwrap()).unwrap();
    let rows = report["frictions"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    for r in rows {
        // Two pressures per friction, a positive macroscopic friction (sigma1 > sigma3).
        assert_eq!(r["tests"], 2);
        assert!(r["mu_macro"].as_f64().unwrap() > 0.0, "{r}");
    }
    // The per-test table: a header and one row per test, whose peak is the summary's.
    let csv = std::fs::read_to_string(campaign.join("tests.csv")).unwrap();
    assert_eq!(csv.lines().count(), 5, "{csv}");
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(campaign.join("seed1_mu0.5_s4MPa/summary.json")).unwrap(),
    )
    .unwrap();
    let line = csv.lines().find(|l| l.contains("seed1_mu0.5_s4MPa")).unwrap();
    let peak: f64 = line.split(',').nth(3).unwrap().parse().unwrap();
    assert_eq!(peak, summary["sigma1_peak_mpa"].as_f64().unwrap(), "{line}");
    // An empty grid and a bad shard are rejected.
    std::fs::write(&sweep, "out = \"x\"\nmu = []\n").unwrap();
    let (ok, text) = cdlab(&["sweep", s]);
    assert!(!ok && text.contains("empty"), "{text}");
    let (ok, text) = cdlab(&["sweep", s, "--shard", "2/2"]);
    assert!(!ok && text.contains("--shard"), "{text}");
    let _ = std::fs::remove_dir_all(&base);
}

/// A test killed before its first checkpoint leaves a record with nothing to resume: the
/// next sweep starts it again instead of failing it.
#[test]
fn a_test_killed_before_its_first_checkpoint_starts_again() {
    let (base, sweep) = tiny_campaign("sweep-restart", "mu = [0.3]\nsigma3 = [\"2 MPa\"]\n");
    let out = base.join("campaign");
    // What a run killed in its first step leaves: a record holding only its configuration.
    let dir = out.join("seed1_mu0.3_s2MPa");
    drop(cdlab::record::Recorder::create(&dir, &cdlab::config::Config::default()).unwrap());
    assert!(dir.join("run.mcap").exists());
    let (ok, text) = cdlab(&["sweep", sweep.to_str().unwrap()]);
    assert!(ok, "{text}");
    assert!(text.contains("restarting"), "{text}");
    assert!(dir.join("summary.json").exists(), "{text}");
    let _ = std::fs::remove_dir_all(&base);
}

/// A samples directory left by a campaign with other sample settings is refused by name,
/// not used in place of this campaign's sample.
#[test]
fn a_sample_prepared_with_other_settings_is_refused() {
    let (base, sweep) = tiny_campaign("sweep-foreign", "mu = [0.3]\nsigma3 = [\"2 MPa\"]\n");
    let samples = base.join("campaign").join("samples");
    std::fs::create_dir_all(&samples).unwrap();
    let foreign = samples.join("seed1.bin");
    let (ok, text) = cdlab(&[
        "prepare",
        "--config",
        base.join("base.toml").to_str().unwrap(),
        "--disks",
        "200",
        "-o",
        foreign.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let (ok, text) = cdlab(&["sweep", sweep.to_str().unwrap()]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("seed1.bin was prepared with other settings")
            && text.contains("sample.disks: 300 here, 200 in the sample"),
        "{text}"
    );
    assert!(!base.join("campaign/seed1_mu0.3_s2MPa/summary.json").exists());
    let _ = std::fs::remove_dir_all(&base);
}

/// `[[dt_by_friction]]` gives the high-friction tests their own time step, and a test found
/// with another step than the sweep asks (the sweep file changed under a campaign) is refused
/// by name instead of skipped into the report, while the other tests carry on.
#[test]
fn time_steps_by_friction_are_recorded_and_checked_on_rerun() {
    let grid = "mu = [0.1, 0.5]\nsigma3 = [\"2 MPa\"]\n";
    let (base, sweep) = tiny_campaign(
        "sweep-dt",
        &format!("{grid}[[dt_by_friction]]\nmu_from = 0.5\ndt = \"0.25 ms\"\n"),
    );
    let s = sweep.to_str().unwrap();
    // The test at the smaller step (more steps) comes first, ahead of the grid's order; the
    // dry run lists the tests in that order whatever --jobs says.
    let (ok, text) = cdlab(&["sweep", s, "--jobs", "2", "--dry-run"]);
    let at = |name: &str| text.find(&format!("{name}: would start"));
    assert!(ok && at("seed1_mu0.5_s2MPa") < at("seed1_mu0.1_s2MPa"), "{text}");
    assert!(at("seed1_mu0.1_s2MPa").is_some(), "{text}");
    let (ok, text) = cdlab(&["sweep", s, "--jobs", "2", "--log-every", "0"]);
    assert!(ok, "{text}");
    // In a log (stderr is a pipe here) each running test prints progress lines named by
    // its directory; --log-every 0 prints one per recorded row.
    for name in ["seed1_mu0.1_s2MPa", "seed1_mu0.5_s2MPa"] {
        assert!(
            text.contains(&format!("{name}: [")) && text.contains("strain 0.00"),
            "{text}"
        );
    }
    assert!(text.contains("campaign 0.0"), "{text}");
    let out = base.join("campaign");
    let dt = |name: &str| cdlab::record::read_config(out.join(name)).unwrap().solver.dt.si();
    // Expected: the built-in 0.5 ms below friction 0.5, the entry's 0.25 ms from it.
    assert_eq!(dt("seed1_mu0.1_s2MPa"), 5e-4);
    assert_eq!(dt("seed1_mu0.5_s2MPa"), 2.5e-4);
    // Both tests share one sample, prepared at the base step whichever test came first.
    assert_eq!(std::fs::read_dir(out.join("samples")).unwrap().count(), 1);

    let text_before = std::fs::read_to_string(&sweep).unwrap();
    std::fs::write(&sweep, text_before.replace("0.25 ms", "0.1 ms")).unwrap();
    let (ok, text) = cdlab(&["sweep", s]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("seed1_mu0.5_s2MPa holds a test of other settings")
            && text.contains("solver.dt: 0.0001 s here, 0.00025 s in the test"),
        "{text}"
    );
    assert!(text.contains("already finished, skipped"), "{text}");

    // The base changed from 300 to 200 disks (issue 36, item 5): the finished tests are
    // not of this campaign any more, and the sweep says so by key instead of skipping them
    // (the report then mixed both sizes without a word); the dry run too.
    std::fs::write(&sweep, &text_before).unwrap();
    let base_toml = base.join("base.toml");
    let config = std::fs::read_to_string(&base_toml).unwrap();
    std::fs::write(&base_toml, config.replace("disks = 300", "disks = 200")).unwrap();
    for dry in [true, false] {
        let args: &[&str] = if dry {
            &["sweep", s, "--dry-run"]
        } else {
            &["sweep", s]
        };
        let (ok, text) = cdlab(args);
        assert!(!ok, "{text}");
        assert!(
            text.contains("seed1_mu0.1_s2MPa holds a test of other settings")
                && text.contains("sample.disks: 200 here, 300 in the test"),
            "{text}"
        );
        assert!(!text.contains("already finished"), "{text}");
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// `cdlab archive` keeps a campaign without its records: the report of the archive gives
/// the same figures as the report of the runs, and a new output directory seeded with the
/// archive skips the archived tests, runs only the new point, and refuses an archived test
/// whose settings differ from the sweep's, by name.
#[test]
fn an_archived_campaign_reports_and_resumes_without_its_records() {
    let (base, sweep) = tiny_campaign("sweep-archive", "mu = [0.3]\nsigma3 = [\"1 MPa\", \"4 MPa\"]\n");
    let s = sweep.to_str().unwrap();
    let (ok, text) = cdlab(&["sweep", s, "--jobs", "2"]);
    assert!(ok, "{text}");
    let campaign = base.join("campaign");
    let archive = base.join("archive");
    let (a, c) = (archive.to_str().unwrap(), campaign.to_str().unwrap());
    let (ok, text) = cdlab(&["archive", c, "--to", a, "--series-rows", "5"]);
    assert!(ok && text.contains("2 tests archived, 0 already there"), "{text}");
    for name in ["seed1_mu0.3_s1MPa", "seed1_mu0.3_s4MPa"] {
        let dir = archive.join(name);
        assert!(!dir.join("run.mcap").exists());
        let series = std::fs::read_to_string(dir.join("series_thinned.csv")).unwrap();
        // A header and about 5 of the test's rows (6 with the last row).
        let rows = series.lines().count() - 1;
        assert!((5..=6).contains(&rows), "{rows} rows:\n{series}");
        assert_eq!(
            cdlab::record::read_config(&dir).unwrap(),
            cdlab::record::read_config(campaign.join(name)).unwrap()
        );
    }
    // The campaign's list of tests goes with the archive.
    assert_eq!(
        cdlab::campaign::read_grid(&archive).unwrap(),
        ["seed1_mu0.3_s1MPa", "seed1_mu0.3_s4MPa"]
    );
    // Archiving again finds the same tests in place.
    let (ok, text) = cdlab(&["archive", c, "--to", a]);
    assert!(ok && text.contains("0 tests archived, 2 already there"), "{text}");

    let mu_macro = |dir: &std::path::Path| {
        let (ok, text) = cdlab(&["report", dir.to_str().unwrap()]);
        assert!(ok, "{text}");
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
        r["frictions"][0]["mu_macro"].as_f64().unwrap()
    };
    assert_eq!(mu_macro(&archive), mu_macro(&campaign));

    // A fresh output directory seeded with the archive, one pressure added to the grid.
    let seeded = base.join("seeded");
    std::fs::create_dir_all(&seeded).unwrap();
    for name in ["seed1_mu0.3_s1MPa", "seed1_mu0.3_s4MPa"] {
        let to = seeded.join(name);
        std::fs::create_dir_all(&to).unwrap();
        for f in std::fs::read_dir(archive.join(name)).unwrap().flatten() {
            std::fs::copy(f.path(), to.join(f.file_name())).unwrap();
        }
    }
    let text = std::fs::read_to_string(&sweep)
        .unwrap()
        .replace(c, seeded.to_str().unwrap())
        .replace("\"4 MPa\"]", "\"4 MPa\", \"2 MPa\"]");
    std::fs::write(&sweep, text).unwrap();
    // A dry run says what would happen and runs nothing.
    let (ok, text) = cdlab(&["sweep", s, "--dry-run"]);
    assert!(ok, "{text}");
    assert_eq!(
        text.matches("already finished, would be skipped").count(),
        2,
        "{text}"
    );
    assert_eq!(text.matches("would start").count(), 1, "{text}");
    assert!(
        text.contains("dry run, nothing was run; 3 tests checked"),
        "{text}"
    );
    assert!(!seeded.join("seed1_mu0.3_s2MPa").exists() && !seeded.join("samples").exists());
    let (ok, text) = cdlab(&["sweep", s]);
    assert!(ok, "{text}");
    assert_eq!(text.matches("already finished, skipped").count(), 2, "{text}");
    assert_eq!(text.matches("sweep: starting").count(), 1, "{text}");
    assert!(
        text.contains("starting") && text.contains("seed1_mu0.3_s2MPa"),
        "{text}"
    );

    // An archived test of another friction than its directory says is refused by name
    // (its configuration written with a checksum of its own: one changed on disk is
    // damaged, `tests/faults.rs`, `an_archived_configuration_is_checked_and_named`).
    let config = seeded.join("seed1_mu0.3_s4MPa/config.toml");
    let toml = std::fs::read_to_string(&config).unwrap();
    let body = toml.split_once('\n').unwrap().1;
    assert!(body.contains("mu = 0.3"), "{toml}");
    std::fs::write(
        &config,
        cdlab::config::with_checksum(&body.replace("mu = 0.3", "mu = 0.4")),
    )
    .unwrap();
    let (ok, text) = cdlab(&["sweep", s, "--dry-run"]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("seed1_mu0.3_s4MPa holds a test of other settings") && text.contains("test.mu"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&base);
}

/// `cdlab summarize` writes a finished test's summary again from its record. On the summary
/// the run itself wrote it changes nothing: the run's end and the command compute the same
/// summary from the same rows, phase ends and snapshots. On a summary in an older form
/// (stress drops from row to row, no bin) it restores the current one byte for byte. The
/// archive of the old summary then takes the new one and says so; an archived test (no
/// record) is named as not summarized.
#[test]
fn summaries_are_written_again_from_records_and_the_archive_follows() {
    let (base, sweep) = tiny_campaign("summarize", "mu = [0.3]\nsigma3 = [\"1 MPa\"]\n");
    let (ok, text) = cdlab(&["sweep", sweep.to_str().unwrap()]);
    assert!(ok, "{text}");
    let campaign = base.join("campaign");
    let c = campaign.to_str().unwrap();
    let summary = campaign.join("seed1_mu0.3_s1MPa/summary.json");
    let current = std::fs::read_to_string(&summary).unwrap();
    let (ok, text) = cdlab(&["summarize", c]);
    assert!(
        ok && text.contains("0 summaries rewritten, 1 unchanged, 0 not summarized"),
        "{text}"
    );
    assert_eq!(std::fs::read_to_string(&summary).unwrap(), current);

    // The older form: events by rows, one of them made up, no bin, and no checksum (older
    // than that too).
    let mut old: serde_json::Value = serde_json::from_str(&current).unwrap();
    let o = old.as_object_mut().unwrap();
    assert!(o.remove("stress_drop_bin_strain").is_some(), "{current}");
    assert!(o.remove("checksum").is_some(), "{current}");
    o.insert(
        "stress_drops".into(),
        serde_json::json!([{"strain_start": 0.001, "strain_end": 0.0011, "drop_pa": 6e4, "volumetric_change": -1e-5}]),
    );
    std::fs::write(&summary, serde_json::to_string_pretty(&old).unwrap()).unwrap();
    let archive = base.join("archive");
    let a = archive.to_str().unwrap();
    let (ok, text) = cdlab(&["archive", c, "--to", a]);
    assert!(ok && text.contains("1 tests archived"), "{text}");

    let (ok, text) = cdlab(&["summarize", c, "--dry-run"]);
    assert!(
        ok && text.contains("would change: stress_drop_bin_strain, stress_drops"),
        "{text}"
    );
    assert!(text.contains("1 summaries would be rewritten"), "{text}");
    assert_ne!(std::fs::read_to_string(&summary).unwrap(), current);
    let (ok, text) = cdlab(&["summarize", c]);
    assert!(
        ok && text.contains("rewritten: stress_drop_bin_strain, stress_drops"),
        "{text}"
    );
    assert_eq!(std::fs::read_to_string(&summary).unwrap(), current);

    let (ok, text) = cdlab(&["archive", c, "--to", a]);
    assert!(
        ok && text.contains("0 tests archived, 1 already there (1 with their summaries updated)"),
        "{text}"
    );
    assert_eq!(
        std::fs::read_to_string(archive.join("seed1_mu0.3_s1MPa/summary.json")).unwrap(),
        current
    );
    // An archive holds no records to summarize from.
    let (ok, text) = cdlab(&["summarize", a]);
    assert!(!ok && text.contains("no record (run.mcap)"), "{text}");
    let _ = std::fs::remove_dir_all(&base);
}

/// The 5000-disk campaign kept in `assets/results/campaign5000/` (docs/results.md, "The
/// 5000-disk campaign") is what `assets/campaign5000.toml` asks for: copied into an output directory,
/// every archived test is checked against the sweep file's settings and would be skipped, so
/// the campaign resumes from it on any machine. The archive reads back in the report.
#[test]
fn the_shipped_5000_disk_archive_resumes_under_the_shipped_sweep_file() {
    let assets = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    let archive = assets.join("results/campaign5000");
    let all: Vec<_> = std::fs::read_dir(&archive)
        .unwrap()
        .flatten()
        .filter(|e| e.path().is_dir())
        .map(|e| e.file_name())
        .collect();
    let finished = |n: &std::ffi::OsString| archive.join(n).join("summary.json").exists();
    let names: Vec<_> = all.iter().filter(|n| finished(n)).cloned().collect();
    // The others are slim records of unfinished tests (`archive --with-unfinished`).
    let unfinished = all.len() - names.len();
    assert!(!names.is_empty(), "no archived test in {}", archive.display());
    for n in all.iter().filter(|n| !finished(n)) {
        let rec = cdlab::record::read_run(archive.join(n)).unwrap();
        assert!(rec.last_checkpoint.is_some() && rec.snapshots.is_empty(), "{n:?}");
    }
    let base = std::env::temp_dir().join(format!("cdlab-shipped-archive-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&base);
    let out = base.join("out");
    for name in &all {
        let to = out.join(name);
        std::fs::create_dir_all(&to).unwrap();
        for f in std::fs::read_dir(archive.join(name)).unwrap().flatten() {
            std::fs::copy(f.path(), to.join(f.file_name())).unwrap();
        }
    }
    let sweep = std::fs::read_to_string(assets.join("campaign5000.toml")).unwrap();
    let ours = sweep
        .replace(
            "base = \"campaign5000_base.toml\"",
            &format!("base = \"{}\"", assets.join("campaign5000_base.toml").display()),
        )
        .replace(
            "out = \"out/campaign5000\"",
            &format!("out = \"{}\"", out.display()),
        );
    assert_ne!(ours, sweep, "the shipped sweep file's base and out lines changed");
    let file = base.join("campaign5000.toml");
    std::fs::write(&file, ours).unwrap();
    let (ok, text) = cdlab(&["sweep", file.to_str().unwrap(), "--dry-run"]);
    assert!(ok, "{text}");
    assert_eq!(
        text.matches("already finished, would be skipped").count(),
        names.len(),
        "{text}"
    );
    assert_eq!(
        text.matches("would resume from its last checkpoint").count(),
        unfinished,
        "{text}"
    );
    // The rest of the paper's 65 tests would start.
    assert_eq!(
        text.matches("would start").count(),
        65 - names.len() - unfinished,
        "{text}"
    );
    let (ok, text) = cdlab(&[
        "report",
        archive.to_str().unwrap(),
        "--out",
        base.join("report").to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    assert!(text.contains(&format!("{} tests", names.len())), "{text}");
    let _ = std::fs::remove_dir_all(&base);
}

/// `cdlab archive --with-unfinished` keeps a test killed midway as a slim record (no
/// snapshots, its checkpoint kept): a sweep seeded with it resumes the test and ends it with
/// the summary of the uninterrupted test, bit for bit (CPU path). Without the flag the test
/// is named as not archived.
#[test]
fn an_unfinished_test_is_archived_to_resume_and_ends_as_if_uninterrupted() {
    let (base, sweep) = tiny_campaign("sweep-unfinished", "mu = [0.3]\nsigma3 = [\"2 MPa\"]\n");
    // Checkpoints every 200 steps and snapshots every 0.001 of strain, so that a cut record
    // holds both.
    let config = base.join("base.toml");
    let toml = std::fs::read_to_string(&config)
        .unwrap()
        .replace("snapshot_every = 0.0", "snapshot_every = 0.001");
    std::fs::write(&config, format!("{toml}checkpoint_every = 200\n")).unwrap();
    let s = sweep.to_str().unwrap();
    let (ok, text) = cdlab(&["sweep", s]);
    assert!(ok, "{text}");
    let name = "seed1_mu0.3_s2MPa";
    let full = base.join("campaign").join(name);
    let whole = std::fs::read(full.join("run.mcap")).unwrap();
    // What a killed test leaves: its record cut at 70% (past its confinement checkpoint).
    let killed = base.join("killed");
    std::fs::create_dir_all(killed.join(name)).unwrap();
    std::fs::write(killed.join(name).join("run.mcap"), &whole[..whole.len() * 7 / 10]).unwrap();
    let partial = cdlab::record::read_run(killed.join(name)).unwrap();
    let (step, _) = partial
        .last_checkpoint
        .clone()
        .expect("a checkpoint before the cut");
    assert!(!partial.snapshots.is_empty());

    let archive = base.join("archive");
    let (k, a) = (killed.to_str().unwrap(), archive.to_str().unwrap());
    // Unfinished tests are kept on demand only.
    let (ok, text) = cdlab(&["archive", k, "--to", a]);
    assert!(!ok && text.contains("no finished test"), "{text}");
    let (ok, text) = cdlab(&["archive", k, "--to", a, "--with-unfinished"]);
    assert!(ok, "{text}");
    assert!(
        text.contains(&format!("unfinished, kept to resume from step {step}"))
            && text.contains("1 unfinished tests kept to resume"),
        "{text}"
    );
    let slim = cdlab::record::read_run(archive.join(name)).unwrap();
    assert!(slim.truncated.is_none());
    // The snapshots before the checkpoint are kept: without them the resumed test ended
    // without its shear bands (issue 36's follow-up).
    let time = cdlab::protocol::checkpoint::decode(&partial.last_checkpoint.as_ref().unwrap().1)
        .unwrap()
        .scene
        .time;
    let strains = |r: &cdlab::record::RunRecord, t: f64| -> Vec<f64> {
        r.snapshots
            .iter()
            .filter(|s| s.time_s <= t)
            .map(|s| s.strain)
            .collect()
    };
    assert!(!strains(&partial, time).is_empty());
    assert_eq!(strains(&slim, f64::INFINITY), strains(&partial, time));
    assert_eq!(slim.last_checkpoint, partial.last_checkpoint);
    assert_eq!(
        slim.series.len(),
        partial.series.iter().filter(|r| r.step <= step).count()
    );
    assert!(!archive.join(name).join("series.csv").exists());
    // Another test of the same name is not archived over it.
    let other = base.join("other").join(name);
    let mut rec = cdlab::record::Recorder::create(&other, &cdlab::config::Config::default()).unwrap();
    let (step_other, bytes) = partial.last_checkpoint.clone().unwrap();
    rec.checkpoint(step_other, 0.0, &bytes).unwrap();
    rec.finish().unwrap();
    let (ok, text) = cdlab(&[
        "archive",
        base.join("other").to_str().unwrap(),
        "--to",
        a,
        "--with-unfinished",
    ]);
    assert!(ok && text.contains("already holds another test"), "{text}");
    assert_eq!(
        cdlab::record::read_run(archive.join(name)).unwrap().config_json,
        slim.config_json
    );

    // A fresh output directory seeded with the slim record: the sweep resumes it.
    let seeded = base.join("seeded");
    std::fs::create_dir_all(seeded.join(name)).unwrap();
    std::fs::copy(
        archive.join(name).join("run.mcap"),
        seeded.join(name).join("run.mcap"),
    )
    .unwrap();
    let text = std::fs::read_to_string(&sweep)
        .unwrap()
        .replace(base.join("campaign").to_str().unwrap(), seeded.to_str().unwrap());
    std::fs::write(&sweep, text).unwrap();
    let (ok, text) = cdlab(&["sweep", s, "--dry-run"]);
    assert!(
        ok && text.contains("would resume from its last checkpoint"),
        "{text}"
    );
    let (ok, text) = cdlab(&["sweep", s]);
    assert!(ok && text.contains("resuming"), "{text}");
    common::assert_same_outcome(&full, &seeded.join(name));
    let bands = |d: &std::path::Path| {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("summary.json")).unwrap()).unwrap();
        v["shear_bands"].clone()
    };
    assert_eq!(bands(&seeded.join(name)), bands(&full));
    // Archived again once finished, the test keeps its summary and drops the slim record.
    let (ok, text) = cdlab(&["archive", seeded.to_str().unwrap(), "--to", a]);
    assert!(ok && text.contains("1 tests archived"), "{text}");
    assert!(archive.join(name).join("summary.json").exists());
    assert!(!archive.join(name).join("run.mcap").exists());
    let _ = std::fs::remove_dir_all(&base);
}

/// Ctrl-C (SIGINT) stops a sweep: the running test at a checkpoint, the queue left alone,
/// exit status 130 (128 + 2) and a message that says so; the same command then resumes the
/// stopped test and runs the rest. While the test runs, a second sweep leaves it alone.
#[cfg(unix)]
#[test]
fn a_signal_stops_a_sweep_that_the_same_command_resumes() {
    let (base, sweep) = tiny_campaign("sweep-signal", "mu = [0.3]\nsigma3 = [\"1 MPa\", \"2 MPa\"]\n");
    let s = sweep.to_str().unwrap();
    // The grid's first test (1 MPa) runs first; 20 rows into its series it is under way.
    let first = base.join("campaign/seed1_mu0.3_s1MPa");
    let result = common::signal_after_rows(
        &["sweep", s, "--jobs", "1", "--log-every", "0"],
        &first.join("series.csv"),
        20,
        || {
            // A second sweep over the running test (shard 0 of 2 holds it alone) leaves it
            // alone, says why, and does not count it as failed.
            let (ok, text) = cdlab(&["sweep", s, "--shard", "0/2"]);
            assert!(
                ok && text.contains("running in another process, skipped"),
                "{text}"
            );
            let (ok, text) = cdlab(&["sweep", s, "--dry-run"]);
            assert!(ok, "{text}");
            assert!(
                text.contains("seed1_mu0.3_s1MPa: would resume from its last checkpoint (running now in another process)")
                    || text.contains("seed1_mu0.3_s1MPa: would restart (its record holds no checkpoint yet) (running now in another process)"),
                "{text}"
            );
            assert!(text.contains("seed1_mu0.3_s2MPa: would start\n"), "{text}");
        },
        libc::SIGINT,
    );
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(130), "{stderr}");
    assert!(
        stderr.contains("stopped at its checkpoint of step")
            && stderr.contains("1 not started")
            && stderr.contains("the same command resumes"),
        "{stderr}"
    );
    assert!(!first.join("summary.json").exists(), "{stderr}");
    assert!(!base.join("campaign/seed1_mu0.3_s2MPa").exists(), "{stderr}");

    let (ok, text) = cdlab(&["sweep", s, "--jobs", "1"]);
    assert!(ok, "{text}");
    assert!(text.contains("resuming"), "{text}");
    assert!(text.contains("all 2 tests of this shard finished"), "{text}");
    let _ = std::fs::remove_dir_all(&base);
}

/// An archive is never written over, into or around the tests it archives (issue 36, item
/// 1: `archive CAMP --to CAMP --with-unfinished` replaced a running test's full record,
/// snapshots and all, with its slim copy). The destination is refused when it is the
/// source, lies inside it (even where it does not exist yet) or contains it, through a
/// link too, with both paths named; the record stays as it was and nothing is created. Apart
/// from its source the same test archives.
#[cfg(unix)]
#[test]
fn an_archive_that_overlaps_its_sources_is_refused() {
    use cdlab::protocol::{LabState, checkpoint};
    let base = std::env::temp_dir().join(format!("cdlab-archive-overlap-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&base);
    let campaign = base.join("campaign");
    let test = campaign.join("seed1_mu0.3_s2MPa");
    // An unfinished test: a snapshot and a checkpoint, no summary.
    let mut scene = cdlab::model::Scene::default();
    for k in 0..4 {
        scene
            .disks
            .push(glam::DVec2::new(3.0 * k as f64, 0.0), 1.0, 1.0)
            .unwrap();
    }
    let state = LabState::new(
        cdlab::Config::with_disks(4).protocol(),
        Default::default(),
        Default::default(),
        0.0,
    );
    let mut rec = cdlab::record::Recorder::create(&test, &cdlab::config::Config::default()).unwrap();
    rec.snapshot(&cdlab::run::snapshot(0.001, &scene, &[], &[]))
        .unwrap();
    rec.checkpoint(100, 0.0, &checkpoint::encode(&state, &scene, &[], &[], None))
        .unwrap();
    rec.finish().unwrap();
    let record = test.join("run.mcap");
    let before = std::fs::read(&record).unwrap();
    let link = base.join("link");
    std::os::unix::fs::symlink(&campaign, &link).unwrap();
    let inside = campaign.join("archive");
    let deeper = campaign.join("new").join("deeper");
    for (from, to, how) in [
        (&campaign, &campaign, "is the source"),
        (&test, &campaign, "contains the source"),
        (&campaign, &inside, "lies inside the source"),
        (&campaign, &deeper, "lies inside the source"),
        (&link, &campaign, "is the source"),
    ] {
        let (f, t) = (from.to_str().unwrap(), to.to_str().unwrap());
        for extra in [&["--with-unfinished"][..], &[][..]] {
            let mut args = vec!["archive", f, "--to", t];
            args.extend_from_slice(extra);
            let (ok, text) = cdlab(&args);
            assert_eq!(std::fs::read(&record).unwrap(), before, "{args:?}: {text}");
            assert!(
                !ok && text.contains(&format!("cannot archive {f} into {t}")) && text.contains(how),
                "{args:?}: {text}"
            );
        }
    }
    assert!(!inside.exists() && !campaign.join("new").exists());
    assert_eq!(
        std::fs::read_dir(&campaign).unwrap().count(),
        1,
        "something was created beside the test"
    );
    let apart = base.join("archive");
    let (ok, text) = cdlab(&[
        "archive",
        campaign.to_str().unwrap(),
        "--to",
        apart.to_str().unwrap(),
        "--with-unfinished",
    ]);
    assert!(ok && text.contains("kept to resume from step 100"), "{text}");
    assert_eq!(cdlab::record::read_run(&test).unwrap().snapshots.len(), 1);
    let _ = std::fs::remove_dir_all(&base);
}

/// A sweep whose output cannot be written (stdout and stderr on /dev/full, where every
/// write fails with ENOSPC) runs every test to its end and exits 0 (issue 36, item 9: the
/// first failed progress line panicked, exit 101 from a worker thread, and the tests left
/// never started). Progress lines are asked for at every row (`--log-every 0`). Then the
/// same with stdout and stderr pipes that their reader closed.
#[cfg(target_os = "linux")]
#[test]
fn a_sweep_whose_output_hits_a_full_disk_runs_every_test() {
    let (base, sweep) = tiny_campaign("sweep-full", "mu = [0.3]\nsigma3 = [\"1 MPa\", \"2 MPa\"]\n");
    let full = || std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args([
            "sweep",
            sweep.to_str().unwrap(),
            "--jobs",
            "1",
            "--log-every",
            "0",
        ])
        .stdout(full())
        .stderr(full())
        .status()
        .expect("cdlab runs");
    assert_eq!(status.code(), Some(0));
    for name in ["seed1_mu0.3_s1MPa", "seed1_mu0.3_s2MPa"] {
        let summary = base.join("campaign").join(name).join("summary.json");
        assert!(summary.exists(), "{} was not finished", summary.display());
    }
    let _ = std::fs::remove_dir_all(&base);

    // Pipes closed by their reader (`cdlab sweep FILE 2>&1 | head -2`): SIGPIPE ended the
    // sweep (exit code 141) and the tests left never started.
    let (base, sweep) = tiny_campaign("sweep-pipe", "mu = [0.3]\nsigma3 = [\"1 MPa\", \"2 MPa\"]\n");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args([
            "sweep",
            sweep.to_str().unwrap(),
            "--jobs",
            "1",
            "--log-every",
            "0",
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("cdlab runs");
    drop(child.stdout.take());
    drop(child.stderr.take());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(0), "{status}");
    for name in ["seed1_mu0.3_s1MPa", "seed1_mu0.3_s2MPa"] {
        let summary = base.join("campaign").join(name).join("summary.json");
        assert!(summary.exists(), "{} was not finished", summary.display());
    }
    let _ = std::fs::remove_dir_all(&base);
}
