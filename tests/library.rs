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
    let whole =
        run::start(&base, Some(scene.clone()), run::Existing::Refuse, &mut Silent, &Cancel::new()).expect("whole run");
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
    let stopped = run::start(&cut, Some(scene), run::Existing::Refuse, &mut stop_at_compression, &cancel);
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
