//! Fault injection on the records of a small biaxial test (docs/reliability.md): a full
//! disk at any write, bit flips and cuts at random places of a record, and the output
//! intervals, none of which may change a run's result or leave it without a usable record.

mod common;
mod record_support;

use std::path::Path;
use std::sync::{Mutex, MutexGuard, OnceLock};

use cdlab::config::Config;
use cdlab::model::Scene;
use cdlab::record::atomic::fault::{self, Plan};
use cdlab::record::{MCAP_FILE, read_run};
use record_support::*;

/// The fault hooks are global to the process: the tests that write records take turns.
static FAULTS: Mutex<()> = Mutex::new(());

/// A test's turn with the hooks; no plan is left behind however the test ends.
struct Turn(#[allow(dead_code)] MutexGuard<'static, ()>);

impl Drop for Turn {
    fn drop(&mut self) {
        fault::set(Plan::None);
    }
}

fn turn() -> Turn {
    let guard = FAULTS.lock().unwrap_or_else(|e| e.into_inner());
    fault::set(Plan::None);
    Turn(guard)
}

/// The compacted sample, made once for all tests of this file.
fn sample() -> &'static Scene {
    static SCENE: OnceLock<Scene> = OnceLock::new();
    SCENE.get_or_init(|| compacted(&config(10)))
}

/// A deterministic generator (xorshift64) for the fault positions.
struct Rng(u64);

impl Rng {
    fn below(&mut self, n: u64) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0 % n.max(1)
    }
}

/// Output settings change what is recorded, never the physics: runs with a row every
/// step, every 10 and every 1000 steps end at the same step, the first one whose axial
/// strain reaches the end strain, with the same final state bit for bit, and all record
/// that last row. Nor do they change the derived results (issue 36: the peak was 14.940,
/// 14.867 and 14.737 MPa at rows every 10, 100 and 1000 steps): the same bits at 10 and
/// 1000 (the same windows of steps), within rounding at 1 (windows of one step summed).
#[test]
fn series_interval_does_not_change_the_physics() {
    let _turn = turn();
    let base = scratch("series-every");
    let mut ends = Vec::new();
    let mut derived = Vec::new();
    for every in [1u32, 10, 1000] {
        let cfg = config(every);
        let dir = base.join(format!("every{every}"));
        fresh(&cfg, &dir, sample()).unwrap();
        let rec = read_run(&dir).unwrap();
        let (step, bytes) = rec.last_checkpoint.clone().unwrap();
        let ck = cdlab::protocol::checkpoint::decode(&bytes).unwrap();
        assert_eq!(ck.state.phase, cdlab::protocol::Phase::Done);
        let last = rec.series.last().unwrap();
        assert_eq!(last.step, step, "series_every {every}: the final row is written");
        assert!(last.strain_axial >= 0.003, "{}", last.strain_axial);
        if every == 1 {
            // A row at every step: the one before the last is still short of the end.
            let before = &rec.series[rec.series.len() - 2];
            assert_eq!(before.step + 1, step);
            assert!(before.strain_axial < 0.003, "{}", before.strain_axial);
        } else if every == 1000 {
            let compression = rec.series.iter().filter(|r| r.phase == "compression").count();
            assert!(
                compression <= 3,
                "{compression} compression rows at 1000 steps a row"
            );
        }
        ends.push((step, format!("{:?}", ck.scene), format!("{:?}", ck.warm)));
        let text = std::fs::read_to_string(dir.join("summary.json")).unwrap();
        let summary: cdlab::measure::summary::Summary = serde_json::from_str(&text).unwrap();
        let from = summary.derived_from.clone().expect("derived_from");
        assert_eq!((from.source.as_str(), from.every_steps), ("steps", 10), "{every}");
        assert!(
            summary.sigma1_peak_mpa > summary.sigma3_mpa,
            "{every}: {summary:?}"
        );
        derived.push(summary);
    }
    for k in 1..ends.len() {
        assert_eq!(ends[0].0, ends[k].0, "final steps");
        assert!(ends[0].1 == ends[k].1, "final scenes differ");
        assert!(ends[0].2 == ends[k].2, "final contact impulses differ");
    }
    let key = |s: &cdlab::measure::summary::Summary| {
        (
            s.sigma1_peak_mpa.to_bits(),
            s.strain_peak.to_bits(),
            s.kinetic_ratio_max.to_bits(),
            format!("{:?} {:?}", s.stress_drops, s.sigma1_residual_mpa),
        )
    };
    assert_eq!(key(&derived[1]), key(&derived[2]), "rows every 10 and 1000 steps");
    let (a, b) = (&derived[0], &derived[1]);
    assert!(
        (a.sigma1_peak_mpa - b.sigma1_peak_mpa).abs() < 1e-9 * b.sigma1_peak_mpa,
        "peak {} MPa at a row a step, {} MPa at a row every 10",
        a.sigma1_peak_mpa,
        b.sigma1_peak_mpa
    );
    assert!((a.strain_peak - b.strain_peak).abs() < 1e-12);
    assert_eq!(a.stress_drops.len(), b.stress_drops.len());
    let _ = std::fs::remove_dir_all(&base);
}

/// The uninterrupted run into `dir` and the number of fault points it passes.
fn reference(dir: &Path, cfg: &Config) -> (Outcome, u64) {
    fault::set(Plan::DiskFull(u64::MAX));
    fresh(cfg, dir, sample()).unwrap();
    let points = fault::count();
    fault::set(Plan::None);
    (outcome(dir), points)
}

/// The step of the last intact checkpoint of the record in `dir`, if any.
fn checkpoint_step(dir: &Path) -> Option<u64> {
    read_run(dir).ok()?.last_checkpoint.map(|c| c.0)
}

/// The disk fills up at the n-th write of a run (that write half done, every later one
/// failing with ENOSPC), for n spread over the whole run; then the disk fills up again at
/// the m-th write of the resume (inside its copy of the record, or later). The record keeps
/// its checkpoint through both (the resume used to truncate it first), and a last resume
/// ends exactly as the uninterrupted run. Only a run that failed before its first
/// checkpoint has nothing to resume, and then the resume says so naming the file.
#[test]
fn a_full_disk_at_any_write_loses_no_checkpoint_and_resumes_to_the_same_end() {
    let _turn = turn();
    let base = scratch("enospc");
    let cfg = config(10);
    let (want, points) = reference(&base.join("reference"), &cfg);
    assert!(points > 50, "{points} fault points");
    let mut rng = Rng(0x5eed_0001);
    let mut ns: Vec<u64> = vec![1, 2, 3, 5, 8, points - 2, points - 1, points];
    ns.extend((0..10).map(|_| 1 + rng.below(points)));
    let mut resumed = 0;
    for (i, &n) in ns.iter().enumerate() {
        let dir = base.join(format!("n{n}"));
        fault::set(Plan::DiskFull(n));
        let run = fresh(&cfg, &dir, sample());
        fault::set(Plan::None);
        // The rows carry the wall clock, so the number of writes varies by a few between
        // runs; a fault at the last renames leaves no write to fail.
        let Err(err) = run else {
            assert!(n + 8 > points, "n = {n} of {points}: the run ignored a full disk");
            assert_eq!(outcome(&dir), want, "n = {n}");
            resumed += 1;
            continue;
        };
        assert!(err.to_string().contains("os error 28"), "n = {n}: {err}");
        let kept = checkpoint_step(&dir);
        let mut done = false;
        // The resume itself meets a full disk, at a write of its copy or later.
        if kept.is_some() {
            fault::set(Plan::DiskFull(1 + (i as u64 * 7) % 40));
            // A resume with few writes left to do (a summary) may finish before it.
            done = resume(&dir).is_ok();
            fault::set(Plan::None);
            let after = checkpoint_step(&dir);
            assert!(
                after >= kept,
                "n = {n}: the failed resume lost its checkpoint: {kept:?} -> {after:?}"
            );
        }
        match if done { Ok(()) } else { resume(&dir) } {
            Ok(()) => {
                resumed += 1;
                assert_eq!(outcome(&dir), want, "n = {n}");
            }
            Err(e) => {
                assert_eq!(kept, None, "n = {n}: a checkpoint was there: {e}");
                let text = e.to_string();
                assert!(text.contains(MCAP_FILE), "n = {n}: {text}");
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
    // The first few writes come before the first checkpoint; the others must all resume.
    assert!(resumed >= 10, "{resumed} of {} ended as the reference", ns.len());
    let _ = std::fs::remove_dir_all(&base);
}

/// `cdlab biaxial --resume DIR --quiet` on the command line.
fn resume_cli(dir: &Path) -> (bool, String) {
    common::cdlab(&["biaxial", "--resume", dir.to_str().unwrap(), "--quiet"])
}

/// A record damaged at random places, a flipped bit or the file cut short: the resume
/// either ends exactly as the undamaged run, having said that it fell back to an earlier
/// checkpoint when the damage hid a later one, or refuses naming the file. It never ends
/// with other results.
#[test]
fn bit_flips_and_cuts_resume_to_the_same_end_or_are_refused() {
    let base = scratch("flips");
    let cfg = config(10);
    let want = {
        let _turn = turn();
        let (want, _) = reference(&base.join("reference"), &cfg);
        want
    };
    let bytes = std::fs::read(base.join("reference").join(MCAP_FILE)).unwrap();
    let n = bytes.len() as u64;
    let mut rng = Rng(0x5eed_0002);
    let (mut same, mut fell_back, mut refused) = (0, 0, 0);
    for k in 0..50 {
        let dir = base.join(format!("case{k}"));
        std::fs::create_dir_all(&dir).unwrap();
        let mut damaged = bytes.clone();
        let at = rng.below(n) as usize;
        let what = if k % 4 == 3 {
            damaged.truncate(at);
            format!("cut at byte {at} of {n}")
        } else {
            damaged[at] ^= 1 << rng.below(8);
            format!("bit flipped in byte {at} of {n}")
        };
        let file = dir.join(MCAP_FILE);
        std::fs::write(&file, &damaged).unwrap();
        let read = read_run(&dir);
        let (ok, text) = resume_cli(&dir);
        if ok {
            assert_eq!(outcome(&dir), want, "{what}: {text}");
            same += 1;
            if read.is_ok_and(|r| r.damaged.is_some()) {
                fell_back += 1;
                assert!(
                    text.contains("falling back") && text.contains(file.to_str().unwrap()),
                    "{what}: the fall-back is not said: {text}"
                );
            }
        } else {
            refused += 1;
            assert!(text.contains(file.to_str().unwrap()), "{what}: {text}");
            assert!(!dir.join("summary.json").exists(), "{what}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
    // Damage lands mostly in the body of the record, after its first checkpoint.
    assert!(same >= 35, "{same} ended as the reference, {refused} refused");
    assert!(fell_back >= 5, "{fell_back} fell back");
    let _ = std::fs::remove_dir_all(&base);
}

/// A finished test's results never outlive their record, and are rebuilt from it: a lost,
/// empty or damaged `summary.json` beside a complete record is written again by `cdlab
/// summarize` and by `biaxial --resume`, equal to the first; a forced run over the test,
/// killed early, leaves no old summary behind; and an old summary put back beside the new
/// record is not counted by the report, being another record's.
#[test]
fn stale_or_lost_summaries_are_removed_refused_or_rebuilt() {
    use cdlab::campaign::collect;
    let base = scratch("stale");
    let cfg = config(10);
    let run = base.join("run");
    let want = {
        let _turn = turn();
        fresh(&cfg, &run, sample()).unwrap();
        outcome(&run)
    };
    let summary = run.join("summary.json");
    let old = std::fs::read(&summary).unwrap();
    assert_eq!(collect(std::slice::from_ref(&run)).0.len(), 1);

    // Lost, then empty, then damaged: rebuilt each time, equal to the first.
    std::fs::remove_file(&summary).unwrap();
    let done = cdlab::cli::summarize::summarize(&run, false).unwrap();
    assert!(
        matches!(done, cdlab::cli::summarize::Outcome::Rewritten(_)),
        "{done:?}"
    );
    assert_eq!(outcome(&run), want);
    std::fs::write(&summary, b"").unwrap();
    {
        let _turn = turn();
        resume(&run).unwrap();
    }
    assert_eq!(outcome(&run), want);
    std::fs::write(&summary, &old[..old.len() / 2]).unwrap();
    let (ok, text) = resume_cli(&run);
    assert!(ok && text.contains("written again"), "{text}");
    assert_eq!(outcome(&run), want);
    // A sound summary: the run is complete, nothing to do.
    let (ok, text) = resume_cli(&run);
    assert!(!ok && text.contains("already complete"), "{text}");

    // A forced run over it, killed once its new record is on disk. A stale temporary
    // record that is a link to another file is removed, not written through (issue 36,
    // item 2: the forced run truncated and overwrote the link's target).
    let victim = base.join("victim.bin");
    std::fs::write(&victim, b"not cdlab's").unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(&victim, run.join("run.mcap.tmp")).unwrap();
    let toml = base.join("run.toml");
    std::fs::write(&toml, cfg.to_toml_string().unwrap()).unwrap();
    let old_id = cdlab::record::read_run_id(&run).unwrap();
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args(["biaxial", "--config", toml.to_str().unwrap(), "--out"])
        .arg(&run)
        .args(["--force", "--quiet"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    loop {
        let replaced = cdlab::record::read_run_id(&run).is_ok_and(|id| id != old_id);
        if replaced {
            break;
        }
        assert!(child.try_wait().unwrap().is_none(), "the forced run ended first");
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(std::fs::read(&victim).unwrap(), b"not cdlab's");
    assert!(!summary.exists() && !run.join("summary.txt").exists());
    let (points, missing) = collect(std::slice::from_ref(&run));
    assert!(points.is_empty() && missing.len() == 1, "{missing:?}");
    // The old summary put back: another record's, not counted.
    std::fs::write(&summary, &old).unwrap();
    let (points, missing) = collect(std::slice::from_ref(&run));
    assert!(points.is_empty(), "a stale summary was counted");
    assert!(missing[0].1.contains("another record"), "{missing:?}");
    let _ = std::fs::remove_dir_all(&base);
}

/// Every temporary file is created new, never through what holds its name (issue 36,
/// item 2): stale `run.mcap.tmp` and `series.csv.tmp` links, one to a file and one
/// dangling, and a stale `NAME.PID.tmp` link of an atomic write are removed, their targets
/// untouched (the record's were truncated and overwritten, the dangling one created), and
/// the new files are regular files under their real names.
#[cfg(unix)]
#[test]
fn temporary_files_are_created_new_never_through_a_link() {
    use cdlab::record::atomic;
    use std::os::unix::fs::symlink;
    let _turn = turn();
    let base = scratch("tmp-links");
    let run = base.join("run");
    std::fs::create_dir_all(&run).unwrap();
    let victim = base.join("victim.bin");
    std::fs::write(&victim, b"not cdlab's").unwrap();
    let nowhere = base.join("nowhere.bin");
    symlink(&victim, run.join("run.mcap.tmp")).unwrap();
    symlink(&nowhere, run.join("series.csv.tmp")).unwrap();
    let mut rec = cdlab::record::Recorder::create(&run, &config(10)).unwrap();
    rec.checkpoint(1, 0.0, b"state").unwrap();
    rec.finish().unwrap();
    let summary = run.join("summary.json");
    symlink(&victim, atomic::process_tmp_path(&summary)).unwrap();
    atomic::write_file(&summary, b"{}").unwrap();
    assert_eq!(std::fs::read(&victim).unwrap(), b"not cdlab's");
    assert!(
        nowhere.symlink_metadata().is_err(),
        "the dangling link's target was created"
    );
    for name in [MCAP_FILE, "series.csv", "summary.json"] {
        let meta = run.join(name).symlink_metadata().unwrap();
        assert!(meta.file_type().is_file(), "{name}: {meta:?}");
    }
    assert!(read_run(&run).unwrap().last_checkpoint.is_some());
    let left: Vec<_> = std::fs::read_dir(&run)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
    let _ = std::fs::remove_dir_all(&base);
}

/// The record read back at the end of a run for its summary cannot be read (an I/O error
/// at that read, the last one of the run; issue 36, item 6): the run fails naming the
/// record, writes no summary (one made without the record lacked its `record_id` and
/// shear bands and blamed missing snapshots), the test does not count as finished, and
/// `--resume` writes the summary the uninterrupted run writes instead of saying the run is
/// complete.
#[test]
fn a_failed_read_of_the_record_at_the_end_fails_the_run_and_the_resume_ends_it() {
    let _turn = turn();
    let base = scratch("reopen");
    let cfg = config(10);
    let (want, _) = reference(&base.join("reference"), &cfg);
    fault::set(Plan::ReadFails(u64::MAX));
    fresh(&cfg, &base.join("count"), sample()).unwrap();
    let reads = fault::count();
    assert!(reads >= 1, "the run reads its record back {reads} times");
    let run = base.join("run");
    fault::set(Plan::ReadFails(reads));
    let err = fresh(&cfg, &run, sample()).expect_err("the run ignored the failed read");
    fault::set(Plan::None);
    let file = run.join(MCAP_FILE);
    let text = err.to_string();
    assert!(text.contains(file.to_str().unwrap()), "{text}");
    assert!(text.contains("resuming the run writes it"), "{text}");
    assert_eq!(err.remedy(), Some(cdlab::error::Remedy::Resume(run.clone())));
    for name in ["summary.json", "summary.txt"] {
        assert!(!run.join(name).exists(), "{name} written without the record");
    }
    let (points, missing) = cdlab::campaign::collect(std::slice::from_ref(&run));
    assert!(points.is_empty() && missing.len() == 1, "{missing:?}");
    let (ok, text) = resume_cli(&run);
    assert!(ok && text.contains("written again"), "{text}");
    assert_eq!(outcome(&run), want);
    let _ = std::fs::remove_dir_all(&base);
}

/// The temporary files a kill leaves behind (`NAME.PID.tmp` of a whole-file write whose
/// process has ended) are removed where the next writer works (issue 36, item 12: they
/// stayed forever and went into archives): by a forced run in its run directory, and by
/// `cdlab archive` in the archive and each archived test, even one already there, where
/// nothing is written. A live process's temporary file is kept.
#[cfg(unix)]
#[test]
fn stale_temporaries_of_killed_writes_are_cleaned_and_never_archived() {
    let base = scratch("stale-tmps");
    let cfg = config(10);
    let run = base.join("run");
    {
        let _turn = turn();
        fresh(&cfg, &run, sample()).unwrap();
    }
    let dead = {
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        child.wait().unwrap();
        pid
    };
    let plant = |dir: &Path, names: &[&str]| {
        for n in names {
            std::fs::write(dir.join(format!("{n}.{dead}.tmp")), b"torn").unwrap();
        }
    };
    let tmps = |dir: &Path| -> Vec<String> {
        let mut found = Vec::new();
        let mut stack = vec![dir.to_path_buf()];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).unwrap().flatten() {
                if e.file_type().unwrap().is_dir() {
                    stack.push(e.path());
                } else if e.file_name().to_string_lossy().ends_with(".tmp") {
                    found.push(e.path().display().to_string());
                }
            }
        }
        found
    };
    plant(&run, &["summary.json", "stress_strain.png"]);
    let live = run.join("summary.txt.1.tmp");
    std::fs::write(&live, b"another process's write").unwrap();
    let arch = base.join("arch");
    let archive = || {
        let (ok, text) = common::cdlab(&["archive", run.to_str().unwrap(), "--to", arch.to_str().unwrap()]);
        assert!(ok, "{text}");
    };
    archive();
    assert_eq!(tmps(&arch), Vec::<String>::new());
    // A killed archive's leftovers, then the same test archived again: nothing to write.
    plant(&arch, &["grid.txt"]);
    plant(&arch.join("run"), &["summary.json", "series_thinned.csv"]);
    archive();
    assert_eq!(tmps(&arch), Vec::<String>::new());
    // A forced run over the test.
    let toml = base.join("run.toml");
    std::fs::write(&toml, cfg.to_toml_string().unwrap()).unwrap();
    let (ok, text) = common::cdlab(&[
        "biaxial",
        "--config",
        toml.to_str().unwrap(),
        "--out",
        run.to_str().unwrap(),
        "--force",
        "--quiet",
    ]);
    assert!(ok, "{text}");
    assert_eq!(tmps(&run), vec![live.display().to_string()]);
    let _ = std::fs::remove_dir_all(&base);
}

/// A summary changed after it was written (one digit of the peak stress, as a flipped bit
/// would) is refused wherever it is read, naming the file (issue 36, item 7: 2.95 read as
/// 3.95 MPa moved mu_macro from 0.196 to 0.347, and the archive copied it on): by the
/// report, by `cdlab archive`, by `run::open` and by every parse of a [`Summary`] (the
/// Python package's). A summary without a checksum (written before summaries had one) is
/// read as before, and `cdlab summarize` rebuilds the damaged one.
///
/// [`Summary`]: cdlab::measure::summary::Summary
#[test]
fn a_summary_changed_after_writing_is_refused_naming_it() {
    use cdlab::campaign::{archive::archive_finished, collect};
    let base = scratch("checksum");
    let cfg = config(10);
    let run = base.join("run");
    {
        let _turn = turn();
        fresh(&cfg, &run, sample()).unwrap();
    }
    let file = run.join("summary.json");
    let good = std::fs::read_to_string(&file).unwrap();
    assert!(good.contains("\"checksum\": \"crc32:"), "{good}");
    let key = "\"sigma1_peak_mpa\": ";
    let at = good.find(key).unwrap() + key.len();
    let digit = if &good[at..at + 1] == "1" { "2" } else { "1" };
    let flipped = format!("{}{digit}{}", &good[..at], &good[at + 1..]);
    std::fs::write(&file, &flipped).unwrap();
    let named = |text: String| {
        assert!(
            text.contains(file.to_str().unwrap()) && text.contains("checksum"),
            "{text}"
        );
    };
    let (points, missing) = collect(std::slice::from_ref(&run));
    assert!(points.is_empty(), "a damaged summary was counted");
    named(missing[0].1.clone());
    named(cdlab::run::open(&run).unwrap_err().to_string());
    let arch = base.join("arch");
    named(
        archive_finished(&run, &arch.join("run"), 10, false)
            .err()
            .expect("archived a damaged summary")
            .to_string(),
    );
    assert!(!arch.join("run").join("summary.json").exists());
    // The commands on the test's own directory say why it is not a finished test (they
    // said only "no finished test (summary.json) below [DIR]").
    for args in [
        vec!["report", run.to_str().unwrap()],
        vec!["archive", run.to_str().unwrap(), "--to", arch.to_str().unwrap()],
    ] {
        let (ok, text) = common::cdlab(&args);
        assert!(!ok, "{args:?}: {text}");
        named(text);
    }
    assert!(!arch.join("run").join("summary.json").exists());
    let parsed = serde_json::from_str::<cdlab::measure::summary::Summary>(&flipped);
    assert!(parsed.unwrap_err().to_string().contains("checksum"));
    assert!(serde_json::from_str::<cdlab::measure::summary::Summary>(&good).is_ok());

    // Without its checksum it reads as a summary of before: counted.
    let mut old: serde_json::Value = serde_json::from_str(&good).unwrap();
    old.as_object_mut().unwrap().remove("checksum");
    std::fs::write(&file, old.to_string()).unwrap();
    assert_eq!(collect(std::slice::from_ref(&run)).0.len(), 1);

    std::fs::write(&file, &flipped).unwrap();
    let done = cdlab::cli::summarize::summarize(&run, false).unwrap();
    assert!(
        matches!(&done, cdlab::cli::summarize::Outcome::Rewritten(k) if k[0].contains("checksum")),
        "{done:?}"
    );
    assert_eq!(collect(std::slice::from_ref(&run)).0.len(), 1);
    let _ = std::fs::remove_dir_all(&base);
}

/// A summary that names another record than the one beside it (a stale summary: archives
/// merged after a test was archived unfinished, finished and archived again) is unfinished
/// to the sweep as it is to the report (issue 36, item 4: the sweep skipped it forever):
/// the sweep resumes the test, which writes its summary again from the complete record.
/// And `cdlab summarize` takes the test's lock: while another process holds it (a forced
/// rerun replacing the record), it refuses rather than write the old record's summary.
#[test]
fn a_stale_summary_is_unfinished_to_the_sweep_and_summarize_waits_for_the_lock() {
    use cdlab::campaign::{Point, State, check_point, collect, point_config};
    let base = scratch("stale-sweep");
    let cfg = config(10);
    let run = base.join("run");
    {
        let _turn = turn();
        fresh(&cfg, &run, sample()).unwrap();
    }
    let p = Point {
        mu: cfg.test.mu,
        sigma3: cfg.test.sigma3.si(),
        seed: cfg.sample.seed,
        dt: cfg.solver.dt.si(),
        dir: run.clone(),
    };
    let ours = point_config(&cfg, &p);
    assert_eq!(check_point(&ours, &p).unwrap(), State::Finished);
    // Another record's summary, whole: its checksum is right for its content.
    let file = run.join("summary.json");
    let mut stale: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    stale["record_id"] = serde_json::Value::from("0".repeat(32));
    stale["checksum"] = serde_json::Value::from(cdlab::measure::summary::checksum(&stale));
    std::fs::write(&file, serde_json::to_string_pretty(&stale).unwrap()).unwrap();
    let (points, missing) = collect(std::slice::from_ref(&run));
    assert!(
        points.is_empty() && missing[0].1.contains("another record"),
        "{missing:?}"
    );
    assert_eq!(check_point(&ours, &p).unwrap(), State::Resumable);

    // Held by another process: summarize refuses and writes nothing.
    let lock = cdlab::record::RunLock::acquire(&run).unwrap();
    let before = std::fs::read(&file).unwrap();
    let e = cdlab::cli::summarize::summarize(&run, false).unwrap_err();
    assert!(matches!(e, cdlab::Error::InUse { .. }), "{e}");
    assert_eq!(std::fs::read(&file).unwrap(), before);
    drop(lock);

    // What the sweep then does with it: the resume writes the record's own summary.
    {
        let _turn = turn();
        resume(&run).unwrap();
    }
    assert_eq!(check_point(&ours, &p).unwrap(), State::Finished);
    assert_eq!(collect(std::slice::from_ref(&run)).0.len(), 1);
    let _ = std::fs::remove_dir_all(&base);
}

/// A forced run over a finished test whose CSV rename fails (issue 36, item 12) leaves no
/// old `series.csv` beside the new record: the old one is removed before the record is
/// replaced. The error names the CSV.
#[test]
fn a_failed_csv_rename_leaves_no_old_rows_beside_the_new_record() {
    let _turn = turn();
    let base = scratch("csv-rename");
    let cfg = config(10);
    let run = base.join("run");
    fresh(&cfg, &run, sample()).unwrap();
    let csv = run.join("series.csv");
    std::fs::write(&csv, "the old run's rows\n").unwrap();
    let old_id = cdlab::record::read_run_id(&run).unwrap();
    // The run's renames: its record, then its CSV.
    fault::set(Plan::RenameFails(2));
    let e = fresh(&cfg, &run, sample()).expect_err("the failed rename was ignored");
    fault::set(Plan::None);
    assert!(e.to_string().contains(csv.to_str().unwrap()), "{e}");
    assert_ne!(
        cdlab::record::read_run_id(&run).unwrap(),
        old_id,
        "the record was not replaced"
    );
    let left = std::fs::read_to_string(&csv).unwrap_or_default();
    assert!(!left.contains("the old run's rows"), "the old series.csv stayed");
    let _ = std::fs::remove_dir_all(&base);
}

/// A directory sync that fails after the summary's rename (issue 36, item 12) does not
/// fail a test that is complete: the run succeeds (a warning says the file may not survive
/// a power cut) and the test counts as finished; before, it exited 1 beside a summary that
/// marked it finished.
#[test]
fn a_failed_directory_sync_after_the_summary_does_not_fail_the_run() {
    let _turn = turn();
    let base = scratch("dir-sync");
    let cfg = config(10);
    fault::set(Plan::DirSyncFails(u64::MAX));
    fresh(&cfg, &base.join("count"), sample()).unwrap();
    let syncs = fault::count();
    let run = base.join("run");
    // The last one follows the rename of summary.json.
    fault::set(Plan::DirSyncFails(syncs));
    let done = fresh(&cfg, &run, sample());
    fault::set(Plan::None);
    done.unwrap();
    assert_eq!(cdlab::campaign::collect(std::slice::from_ref(&run)).0.len(), 1);
    // A sync that must precede what follows (the removal of an old summary) still fails.
    fault::set(Plan::DirSyncFails(1));
    let e = cdlab::run::clear_results(&run).expect_err("the failed sync was ignored");
    fault::set(Plan::None);
    assert!(e.to_string().contains(run.to_str().unwrap()), "{e}");
    let _ = std::fs::remove_dir_all(&base);
}

/// `--out` on a symbolic link that loops is refused with what it is (issue 36, item 12:
/// the message was "File exists").
#[cfg(unix)]
#[test]
fn an_output_directory_that_is_a_looping_link_is_named() {
    let base = scratch("out-loop");
    let looped = base.join("loop");
    std::os::unix::fs::symlink(&looped, &looped).unwrap();
    let toml = base.join("run.toml");
    std::fs::write(&toml, config(10).to_toml_string().unwrap()).unwrap();
    let (ok, text) = common::cdlab(&[
        "biaxial",
        "--config",
        toml.to_str().unwrap(),
        "--out",
        looped.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(!ok, "{text}");
    assert!(
        text.contains(looped.to_str().unwrap()) && text.contains("symbolic link that loops"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&base);
}

/// A run directory says what was run (issue 36, item 15): the configuration as TOML beside
/// the record, equal to the record's; the seed and the end strain in `summary.json` and
/// `summary.txt`; and `cdlab config --of DIR` prints the configuration from the record.
#[test]
fn a_run_directory_says_what_was_run() {
    let base = scratch("what-ran");
    let cfg = config(10);
    let run = base.join("run");
    {
        let _turn = turn();
        fresh(&cfg, &run, sample()).unwrap();
    }
    let recorded = cdlab::record::read_config(&run).unwrap();
    let beside = Config::load(run.join("config.toml")).unwrap();
    assert_eq!(beside, recorded);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["seed"].as_u64(), Some(cfg.sample.seed));
    assert_eq!(summary["strain_end"].as_f64(), Some(cfg.test.strain_end));
    let table = std::fs::read_to_string(run.join("summary.txt")).unwrap();
    assert!(
        table.contains("sample seed") && table.contains("end axial strain"),
        "{table}"
    );
    let (ok, text) = common::cdlab(&["config", "--of", run.to_str().unwrap()]);
    assert!(ok, "{text}");
    assert_eq!(Config::from_toml_str(&text).unwrap(), recorded);
    let _ = std::fs::remove_dir_all(&base);
}

/// A run whose progress or closing lines cannot be shown still runs to its end, exit code 0
/// (docs/reliability.md, "Progress never stops a run or a sweep"): stdout and stderr pipes
/// closed by their reader before the first line (`cdlab biaxial ... 2>&1 | head -3` killed
/// the run with SIGPIPE, exit code 141), and stdout on a full disk (the run finished, then
/// exited 1 with nothing on stderr). A command that exists to print (`version`, `report`,
/// `config --of`) fails on a full stdout, and says so on stderr.
#[cfg(unix)]
#[test]
fn output_that_cannot_be_written_never_stops_a_run_and_is_named() {
    use std::process::{Command, Stdio};
    let base = scratch("closed-output");
    let toml = base.join("run.toml");
    std::fs::write(&toml, config(10).to_toml_string().unwrap()).unwrap();
    let biaxial = |out: &Path| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_cdlab"));
        c.args(["biaxial", "--config", toml.to_str().unwrap(), "--no-figures"])
            .arg("--out")
            .arg(out);
        c
    };
    let full = || std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();

    let closed = base.join("closed");
    let mut child = biaxial(&closed)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Both read ends closed before the run writes anything.
    drop(child.stdout.take());
    drop(child.stderr.take());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(0), "{status}");
    assert!(closed.join("summary.json").exists());

    let on_full = base.join("full");
    let out = biaxial(&on_full).stdout(full()).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(on_full.join("summary.json").exists());
    assert!(err.contains("could not write to stdout"), "{err}");

    for args in [
        vec!["version"],
        vec!["report", on_full.to_str().unwrap()],
        vec!["config", "--of", on_full.to_str().unwrap()],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_cdlab"))
            .args(&args)
            .stdout(full())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("stdout") && err.contains("No space left on device"),
            "{args:?}: {err}"
        );
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// `cdlab archive` writes a test's thinned series from its record, whose chunks are
/// checked, never from the `series.csv` beside it: a CSV cut through a row, one with
/// flipped digits and a missing one each give the archive the intact test's series (they
/// were copied on as they were, or the archive had no series).
#[test]
fn the_archived_series_comes_from_the_record() {
    use cdlab::campaign::archive::{archive_finished, thin_csv};
    let base = scratch("archive-series");
    let run = base.join("run");
    {
        let _turn = turn();
        fresh(&config(10), &run, sample()).unwrap();
    }
    let csv = run.join("series.csv");
    let intact = std::fs::read_to_string(&csv).unwrap();
    let expected = thin_csv(&intact, 40);
    let flipped: String = intact
        .lines()
        .enumerate()
        .map(|(k, l)| match k % 5 {
            3 => format!("{}\n", l.replacen('3', "4", 1)),
            _ => format!("{l}\n"),
        })
        .collect();
    assert_ne!(flipped, intact);
    for (name, damaged) in [
        ("cut", Some(intact[..intact.len() / 2 + 3].to_string())),
        ("flipped", Some(flipped)),
        ("missing", None),
    ] {
        match damaged {
            Some(text) => std::fs::write(&csv, text).unwrap(),
            None => std::fs::remove_file(&csv).unwrap(),
        }
        let dest = base.join(name).join("run");
        archive_finished(&run, &dest, 40, false).unwrap();
        let kept = std::fs::read_to_string(dest.join("series_thinned.csv")).unwrap();
        assert!(
            kept == expected,
            "{name}: the archive's series is not the record's"
        );
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// An archived test's `config.toml` is its only configuration, and carries a checksum that
/// every reader checks (issue 36's follow-up: a digit changed from 150 to 250 disks was
/// taken by the sweep as the test's settings, and the report counted the test). Changed,
/// cut or missing, it is an error naming the file, to `cdlab config --of`, the report and
/// the sweep's check; a missing one said "run.mcap: No such file", a cut one "invalid
/// parameter `sample.r_min` = 0" without a file. A file without the checksum line (older
/// archives) is read as before, its errors naming it too.
#[test]
fn an_archived_configuration_is_checked_and_named() {
    use cdlab::campaign::{Point, archive::archive_finished, check_point, collect, point_config};
    let base = scratch("archive-config");
    let cfg = config(10);
    let run = base.join("run");
    {
        let _turn = turn();
        fresh(&cfg, &run, sample()).unwrap();
    }
    let arch = base.join("arch").join("run");
    archive_finished(&run, &arch, 40, false).unwrap();
    let file = arch.join("config.toml");
    let good = std::fs::read_to_string(&file).unwrap();
    assert!(good.starts_with("# checksum: crc32:"), "{good}");
    let p = Point {
        mu: cfg.test.mu,
        sigma3: cfg.test.sigma3.si(),
        seed: cfg.sample.seed,
        dt: cfg.solver.dt.si(),
        dir: arch.clone(),
    };
    let ours = point_config(&cfg, &p);
    assert!(check_point(&ours, &p).is_ok());
    assert_eq!(collect(std::slice::from_ref(&arch)).0.len(), 1);
    let body = good.split_once('\n').unwrap().1.to_string();
    assert!(body.contains("disks = 200"), "{body}");
    for (name, text, why) in [
        (
            "changed",
            Some(good.replace("disks = 200", "disks = 300")),
            "damaged",
        ),
        ("cut", Some(good[..good.len() / 2].to_string()), "damaged"),
        ("missing", None, "missing"),
        (
            "old, invalid",
            Some(body.replace("disks = 200", "disks = 1")),
            "sample.disks",
        ),
    ] {
        match &text {
            Some(t) => std::fs::write(&file, t).unwrap(),
            None => std::fs::remove_file(&file).unwrap(),
        }
        let named = |e: String| {
            assert!(
                e.contains(file.to_str().unwrap()) && e.contains(why) && !e.contains("run.mcap"),
                "{name}: {e}"
            );
        };
        named(cdlab::record::read_config(&arch).unwrap_err().to_string());
        named(check_point(&ours, &p).unwrap_err().to_string());
        let (points, missing) = collect(std::slice::from_ref(&arch));
        assert!(points.is_empty(), "{name}: counted");
        named(missing[0].1.clone());
        let (ok, text) = common::cdlab(&["config", "--of", arch.to_str().unwrap()]);
        assert!(!ok, "{name}: {text}");
        named(text);
    }
    // A syntax error in a file with a valid checksum: the line is the file's, the
    // checksum line counted.
    assert!(body.starts_with("[sample]\ndisks = 200\n"), "{body}");
    std::fs::write(
        &file,
        cdlab::config::with_checksum(&body.replacen("disks = 200", "disks = = 200", 1)),
    )
    .unwrap();
    let e = cdlab::record::read_config(&arch).unwrap_err().to_string();
    assert!(e.contains(&format!("{}: line 3:", file.display())), "{e}");
    // Written before archives had the checksum line: read unchecked.
    std::fs::write(&file, &body).unwrap();
    assert!(check_point(&ours, &p).is_ok());
    assert_eq!(collect(std::slice::from_ref(&arch)).0.len(), 1);
    let _ = std::fs::remove_dir_all(&base);
}
