//! Concurrent runs on one campaign directory (issue 23, class 6). Deterministic: the other
//! process is this test process itself, holding a test's or a sample's lock through the
//! project's lock API, and a wait is for a line the sweep prints, never a sleep.

mod common;

use std::io::{BufRead, BufReader};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use cdlab::protocol::sample_file::{SampleLock, read_sample, write_atomic};
use cdlab::record::RunLock;
use common::cdlab;

/// A fresh directory holding a base configuration of small, short tests (300 disks to
/// strain 0.004) and `sweep.toml` over mu `mus` at 1 MPa, seed 1, into `campaign/`.
fn campaign(name: &str, mus: &str) -> (PathBuf, PathBuf) {
    let base = std::env::temp_dir().join(format!("cdlab-conc-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&base);
    std::fs::create_dir_all(&base).unwrap();
    std::fs::write(
        base.join("base.toml"),
        "[sample]\ndisks = 300\nseed = 1\n[solver]\ntol = 1e-3\n[test]\nstrip_thickness = \"3 m\"\n\
         strain_end = 0.004\n[output]\nseries_every = 10\nsnapshot_every = 0.0\n",
    )
    .unwrap();
    let sweep = base.join("sweep.toml");
    std::fs::write(
        &sweep,
        format!(
            "base = \"base.toml\"\nout = \"{}\"\nmu = [{mus}]\nsigma3 = [\"1 MPa\"]\nseeds = [1]\n",
            base.join("campaign").display()
        ),
    )
    .unwrap();
    (base, sweep)
}

fn test_dir(base: &Path, mu: &str) -> PathBuf {
    base.join("campaign").join(format!("seed1_mu{mu}_s1MPa"))
}

/// The campaign's seed-1 sample "in preparation by another process": this process holds its
/// lock. Returns the finished sample that process will write (made beforehand with the
/// campaign's settings, at the first path), the sample's place in the campaign, and the lock.
fn sample_in_preparation(base: &Path) -> (PathBuf, PathBuf, SampleLock) {
    let made = base.join("made.bin");
    let (ok, text) = cdlab(&[
        "prepare",
        "--config",
        base.join("base.toml").to_str().unwrap(),
        "-o",
        made.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let samples = base.join("campaign").join("samples");
    std::fs::create_dir_all(&samples).unwrap();
    let sample = samples.join("seed1.bin");
    let lock = SampleLock::acquire(&sample, || panic!("no one else holds it")).unwrap();
    (made, sample, lock)
}

/// A sweep finds one test's lock held (another process runs it) and the seed's sample being
/// prepared elsewhere: it reports the test as running elsewhere, not FAILED, waits for the
/// sample, reads the file written meanwhile instead of compacting again, runs the other test
/// and exits 0. Before: the held test was FAILED with exit 1, and the sample was compacted
/// again beside the other process's.
#[test]
fn a_sweep_leaves_running_tests_and_waits_for_a_sample_in_preparation() {
    let (base, sweep) = campaign("locks", "0.1, 0.5");
    let (made, sample, sample_lock) = sample_in_preparation(&base);
    let busy = test_dir(&base, "0.1");
    let run_lock = RunLock::acquire(&busy).unwrap();

    let mut child = Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args(["sweep", sweep.to_str().unwrap(), "--jobs", "1"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut seen = String::new();
    let mut line = String::new();
    while !line.contains("waiting for it") {
        line.clear();
        assert!(
            err.read_line(&mut line).unwrap() > 0,
            "the sweep ended without waiting for the sample: {seen}"
        );
        seen += &line;
    }
    // The other process finishes its sample: written whole, then its lock released.
    write_atomic(&sample, &std::fs::read(&made).unwrap()).unwrap();
    let inode = std::fs::metadata(&sample).unwrap().ino();
    drop(sample_lock);
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut err, &mut rest).unwrap();
    let status = child.wait().unwrap();
    let text = seen + &rest;
    assert!(status.success(), "{text}");
    assert!(!text.contains("FAILED"), "{text}");
    assert!(
        text.contains(&format!(
            "{}: running in another process, skipped",
            busy.display()
        )),
        "{text}"
    );
    assert!(text.contains("1 running in another process"), "{text}");
    assert!(test_dir(&base, "0.5").join("summary.json").exists(), "{text}");
    assert!(
        !busy.join("summary.json").exists(),
        "the held test was run: {text}"
    );
    // The file the other process wrote, not a second compaction written over it.
    assert_eq!(std::fs::metadata(&sample).unwrap().ino(), inode, "{text}");
    read_sample(&sample).unwrap();
    drop(run_lock);
    let _ = std::fs::remove_dir_all(&base);
}

/// Two sweeps started together on one directory share the work: both exit 0, neither
/// reports a failure, and every test of the grid is finished once both have ended.
#[test]
fn two_sweeps_at_once_both_succeed_and_finish_the_grid() {
    let (base, sweep) = campaign("twice", "0.1, 0.5");
    let start = || {
        Command::new(env!("CARGO_BIN_EXE_cdlab"))
            .args(["sweep", sweep.to_str().unwrap(), "--jobs", "1"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let (a, b) = (start(), start());
    for child in [a, b] {
        let out = child.wait_with_output().unwrap();
        let text = String::from_utf8_lossy(&out.stderr).into_owned() + &String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{text}");
        assert!(!text.contains("FAILED"), "{text}");
    }
    for mu in ["0.1", "0.5"] {
        assert!(
            test_dir(&base, mu).join("summary.json").exists(),
            "mu {mu} not finished"
        );
    }
    read_sample(&base.join("campaign/samples/seed1.bin")).unwrap();
    let _ = std::fs::remove_dir_all(&base);
}

/// `archive --with-unfinished` leaves a test whose lock another process holds (it is
/// running now), saying so; before, it read and archived the record being written.
#[test]
fn archive_skips_a_test_running_now() {
    let (base, _) = campaign("archive", "0.1");
    let dir = test_dir(&base, "0.1");
    std::fs::create_dir_all(&dir).unwrap();
    // An unfinished test: a record, no summary (its content is not read when skipped).
    std::fs::write(dir.join("run.mcap"), b"").unwrap();
    let to = base.join("archive");
    let args = [
        "archive",
        base.join("campaign").to_str().unwrap(),
        "--to",
        to.to_str().unwrap(),
        "--with-unfinished",
    ]
    .map(String::from);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let lock = RunLock::acquire(&dir).unwrap();
    let (ok, text) = cdlab(&args);
    assert!(ok, "{text}");
    assert!(
        text.contains("running now in another process, not archived")
            && text.contains("0 unfinished tests kept"),
        "{text}"
    );
    assert!(!to.join("seed1_mu0.1_s1MPa").exists(), "{text}");
    drop(lock);
    // Once the lock is free the test is looked at (and this empty record refused).
    let (_, text) = cdlab(&args);
    assert!(
        !text.contains("running now") && text.contains("not archived"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&base);
}

/// `--jobs 2` runs two tests at once, proved without a clock: the seed's sample is held
/// "in preparation" by this process, so a test that has started cannot end; both tests of
/// the grid must nevertheless print their start. A sweep that ran its tests one after the
/// other would print one start and wait; the watchdog (a failure guard, never a pass
/// condition) then ends it and the test fails on the missing second start.
#[test]
fn two_jobs_start_two_tests_at_once() {
    let (base, sweep) = campaign("jobs2", "0.1, 0.5");
    let (made, sample, sample_lock) = sample_in_preparation(&base);

    let mut child = Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args(["sweep", sweep.to_str().unwrap(), "--jobs", "2"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let pid = child.id();
    let (done_tx, done_rx) = std::sync::mpsc::channel::<()>();
    let watchdog = std::thread::spawn(move || {
        if done_rx.recv_timeout(std::time::Duration::from_secs(300)).is_err() {
            // SAFETY: kill(2) on the child's pid, which this test has not yet waited for.
            unsafe { libc::kill(pid as i32, libc::SIGKILL) };
        }
    });
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut seen = String::new();
    let mut line = String::new();
    while seen.matches("sweep: starting").count() < 2 {
        line.clear();
        assert!(
            err.read_line(&mut line).unwrap() > 0,
            "the sweep did not start its second test while the first waited: {seen}"
        );
        seen += &line;
    }
    // Both tests started and neither can have ended: the sample they need is still held.
    assert!(!test_dir(&base, "0.1").join("summary.json").exists(), "{seen}");
    assert!(!test_dir(&base, "0.5").join("summary.json").exists(), "{seen}");
    write_atomic(&sample, &std::fs::read(&made).unwrap()).unwrap();
    drop(sample_lock);
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut err, &mut rest).unwrap();
    let status = child.wait().unwrap();
    let _ = done_tx.send(());
    watchdog.join().unwrap();
    let text = seen + &rest;
    assert!(status.success(), "{text}");
    for mu in ["0.1", "0.5"] {
        assert!(test_dir(&base, mu).join("summary.json").exists(), "{mu}: {text}");
    }
    let _ = std::fs::remove_dir_all(&base);
}
