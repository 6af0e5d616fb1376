//! The stress run of docs/reliability.md: a small biaxial test killed at chosen writes of
//! its record (the process aborts there, as `kill -9` would stop it, with that write torn
//! in half), its resume killed again inside the copy of the record it makes, then resumed
//! to the end, must end bit for bit as the uninterrupted run. The kills land on writes
//! counted by the record's fault hooks, never at a time, so each case is reproducible.
//!
//! The killed processes are this test binary run again on the ignored test `child`, which
//! reads its orders from `CDLAB_STRESS_CHILD`.

mod record_support;

use std::path::{Path, PathBuf};

use cdlab::record::atomic::fault::{self, Plan};
use cdlab::record::{MCAP_FILE, read_run};
use record_support::*;

const ORDERS: &str = "CDLAB_STRESS_CHILD";

/// Runs this binary's `child` test with `orders`; whether it ended normally, and its output.
fn run_child(orders: &str) -> (bool, String) {
    let out = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "child",
            "--ignored",
            "--nocapture",
            "--test-threads",
            "1",
        ])
        .env(ORDERS, orders)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

/// `fresh K DIR SAMPLE` or `resume K DIR`: aborts the process at the K-th fault point of
/// a new run from the sample, or of a resume.
#[test]
#[ignore = "entry point of the processes that kills_at_chosen_writes_resume_to_the_same_end kills"]
fn child() {
    let Ok(orders) = std::env::var(ORDERS) else {
        return;
    };
    let words: Vec<&str> = orders.split('\t').collect();
    let k: u64 = words[1].parse().unwrap();
    let dir = PathBuf::from(words[2]);
    let done = match words[0] {
        "fresh" => {
            let scene = load(Path::new(words[3]));
            fault::set(Plan::Abort(k));
            fresh(&config(10), &dir, &scene)
        }
        _ => {
            fault::set(Plan::Abort(k));
            resume(&dir)
        }
    };
    println!("child ended without its kill: {done:?}");
}

fn checkpoint_step(dir: &Path) -> Option<u64> {
    read_run(dir).ok()?.last_checkpoint.map(|c| c.0)
}

#[test]
fn kills_at_chosen_writes_resume_to_the_same_end() {
    let base = scratch("stress");
    let cfg = config(10);
    let scene = compacted(&cfg);
    let sample = base.join("sample.bin");
    save(&sample, &cfg, &scene);
    let reference = base.join("reference");
    fault::set(Plan::DiskFull(u64::MAX));
    fresh(&cfg, &reference, &scene).unwrap();
    let points = fault::count();
    fault::set(Plan::None);
    let want = outcome(&reference);

    let mut s = 0x5eed_0003u64;
    let mut ks: Vec<u64> = vec![1, 2, 3, 4, 6, points - 3, points - 1];
    ks.extend((0..9).map(|_| {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        1 + s % points
    }));
    let mut ended = 0;
    for (i, &k) in ks.iter().enumerate() {
        let dir = base.join(format!("k{k}"));
        let _ = std::fs::remove_dir_all(&dir);
        let orders = format!("fresh\t{k}\t{}\t{}", dir.display(), sample.display());
        let (finished, text) = run_child(&orders);
        // The rows carry the wall clock, so the count of writes varies by a few.
        assert!(!finished || k + 8 > points, "k = {k}: not killed: {text}");
        let kept = checkpoint_step(&dir);
        let mut done = finished;
        // Killed again inside the resume's copy of the record (its first writes) or later.
        if kept.is_some() && !finished {
            let k2 = 1 + (i as u64 * 5) % 9;
            let (finished, text) = run_child(&format!("resume\t{k2}\t{}", dir.display()));
            let after = checkpoint_step(&dir);
            assert!(
                after >= kept,
                "k = {k}, k2 = {k2}: the killed resume lost the checkpoint ({kept:?} -> {after:?}): {text}"
            );
            done = finished;
        }
        let last = if done { Ok(()) } else { resume(&dir) };
        match last {
            Ok(()) => {
                assert_eq!(outcome(&dir), want, "k = {k}");
                ended += 1;
            }
            Err(e) => {
                // Only a run killed before its first checkpoint has nothing to resume.
                assert_eq!(kept, None, "k = {k}: {e}");
                assert!(e.to_string().contains(MCAP_FILE), "k = {k}: {e}");
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
    assert!(ended >= 10, "{ended} of {} ended as the reference", ks.len());
    let _ = std::fs::remove_dir_all(&base);
}
