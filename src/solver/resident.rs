//! A team of threads that outlives the step: started once, given one job per solve, and
//! waiting between jobs by spinning for a while before it sleeps.
//!
//! Starting a thread costs 40-90 us on the reference machine, and waking a sleeping one
//! 35-55 us (docs/benchmarks.md, "The machine's day"): 3-7% of a 5000-disk compression
//! step if paid once per step. Between two solves the calling thread runs the step's
//! fixed part alone, well under a millisecond at 5000 disks, so a member that keeps
//! watching for that long starts the next job within a fraction of a microsecond.
//!
//! The members yield the processor while they watch (after a short pure spin), so that a
//! machine with more runnable threads than cores keeps its time for them, and sleep once
//! [`IDLE_WATCH`] has passed without a job.

use std::cell::UnsafeCell;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::thread::{JoinHandle, Thread};
use std::time::{Duration, Instant};

/// How long a member watches for the next job before it sleeps: longer than the fixed part
/// of a 5000-disk step on the reference machine (0.4-1.2 ms), so that the team is awake
/// when the next solve starts.
const IDLE_WATCH: Duration = Duration::from_millis(3);

/// How long a waiting thread spins before it yields between checks: a member's share of
/// a job ends within microseconds of the others'.
const PURE_SPIN: Duration = Duration::from_micros(50);

/// A job as the members see it: the caller's closure, its lifetime erased. [`Resident::run`]
/// returns only after every member has finished with it, so it never outlives the borrow.
type Job = *const (dyn Fn(usize) + Sync);

struct Shared {
    /// Members counting the caller.
    n: usize,
    /// The current job, written by the caller before `epoch` moves on.
    job: UnsafeCell<Option<Job>>,
    /// The thread waiting for the job's end, written with `job`.
    caller: UnsafeCell<Option<Thread>>,
    /// Bumped once per job (Release after `job` is written).
    epoch: AtomicUsize,
    /// Members other than the caller that have not finished the current job.
    pending: AtomicUsize,
    exit: AtomicBool,
    /// A member's share of the job panicked.
    panicked: AtomicBool,
}

// SAFETY: `job` and `caller` are written by the caller only while no member reads them (no
// job pending) and published by the Release increment of `epoch`; members read them after
// an Acquire load that saw the new epoch, and the job is `Sync`.
unsafe impl Sync for Shared {}
unsafe impl Send for Shared {}

/// Waits until `ready` holds: a pure spin for `spin`, then spinning with a yield between
/// checks until `watch` has passed, then sleeping (woken by `unpark`; a wake-up token left
/// by an earlier wake only costs one more check). Returns at once when `ready` holds. The
/// clock is read once every 64 checks. The team's members wait for jobs with it, and
/// the barrier between colors (`watch` equal to `spin`: no yielding) in [`super::team`].
pub(super) fn wait_until(spin: Duration, watch: Duration, ready: impl Fn() -> bool) {
    let start = Instant::now();
    let mut spins = 0u32;
    while !ready() {
        spins = spins.wrapping_add(1);
        if !spins.is_multiple_of(64) {
            std::hint::spin_loop();
            continue;
        }
        let waited = start.elapsed();
        if waited < spin {
            std::hint::spin_loop();
        } else if waited < watch {
            std::thread::yield_now();
        } else {
            std::thread::park();
        }
    }
}

/// A team of `n - 1` threads beside the caller's, kept from solve to solve.
pub(crate) struct Resident {
    shared: Arc<Shared>,
    members: Vec<JoinHandle<()>>,
    /// The process that started the members: a child made by `fork` (Python's
    /// multiprocessing, say) inherits the team's memory but not its threads.
    pid: u32,
    /// One caller at a time: two threads handing jobs at once would overwrite each
    /// other's, so the team may move between threads but not be shared (not `Sync`).
    _one_caller: std::marker::PhantomData<std::cell::Cell<()>>,
}

impl Resident {
    /// Starts `n - 1` members (`n` at least 2).
    pub(crate) fn new(n: usize) -> Resident {
        assert!(n >= 2, "a team of one needs no members");
        let shared = Arc::new(Shared {
            n,
            job: UnsafeCell::new(None),
            caller: UnsafeCell::new(None),
            epoch: AtomicUsize::new(0),
            pending: AtomicUsize::new(0),
            exit: AtomicBool::new(false),
            panicked: AtomicBool::new(false),
        });
        let members = (1..n)
            .map(|t| {
                let shared = Arc::clone(&shared);
                std::thread::Builder::new()
                    .name(format!("cdlab-team-{t}"))
                    .spawn(move || member(&shared, t))
                    .expect("start a team thread")
            })
            .collect();
        Resident {
            shared,
            members,
            pid: std::process::id(),
            _one_caller: std::marker::PhantomData,
        }
    }

    /// Members counting the caller.
    pub(super) fn size(&self) -> usize {
        self.shared.n
    }

    /// The members' threads, in member order from 1 (the caller is member 0), for those
    /// that wake them.
    pub(super) fn threads(&self) -> impl Iterator<Item = &Thread> {
        self.members.iter().map(|h| h.thread())
    }

    /// Runs `f(t)` for every member `t` in `0..size()`, `f(0)` on the calling thread, and
    /// returns when all have returned. A panic in a member's share panics here.
    pub(crate) fn run(&self, f: &(dyn Fn(usize) + Sync)) {
        let s = &*self.shared;
        // SAFETY: only the lifetime is erased; this function returns only after every
        // member has finished with the job (`pending` back to 0), even when `f(0)` panics
        // (the guard below waits).
        let job: Job = unsafe { std::mem::transmute::<&(dyn Fn(usize) + Sync), Job>(f) };
        // SAFETY: no job is pending (the last `run` waited for its end), so no member reads
        // these cells until the epoch moves on.
        unsafe {
            *s.job.get() = Some(job);
            *s.caller.get() = Some(std::thread::current());
        }
        s.pending.store(s.n - 1, Ordering::Relaxed);
        s.epoch.fetch_add(1, Ordering::Release);
        for h in &self.members {
            // A member that is watching only loses a token it will not need.
            h.thread().unpark();
        }
        struct WaitAll<'a>(&'a Shared);
        impl Drop for WaitAll<'_> {
            fn drop(&mut self) {
                let s = self.0;
                wait_until(PURE_SPIN, IDLE_WATCH, || s.pending.load(Ordering::Acquire) == 0);
            }
        }
        {
            let _wait = WaitAll(s);
            f(0);
        }
        if s.panicked.swap(false, Ordering::Relaxed) {
            panic!("a member of the solver's thread team panicked");
        }
    }
}

/// A member's life: watch for a job, run its share, report, until told to exit.
fn member(s: &Shared, t: usize) {
    let mut seen = 0;
    loop {
        wait_until(PURE_SPIN, IDLE_WATCH, || {
            s.exit.load(Ordering::Acquire) || s.epoch.load(Ordering::Acquire) != seen
        });
        if s.exit.load(Ordering::Acquire) {
            return;
        }
        seen = s.epoch.load(Ordering::Acquire);
        // SAFETY: published before the epoch this member saw (Acquire above); the caller
        // keeps the job alive until `pending` reaches 0.
        let (job, caller) = unsafe { ((*s.job.get()).expect("a job"), (*s.caller.get()).clone()) };
        // SAFETY: as above.
        let f = unsafe { &*job };
        if catch_unwind(AssertUnwindSafe(|| f(t))).is_err() {
            s.panicked.store(true, Ordering::Relaxed);
        }
        if s.pending.fetch_sub(1, Ordering::AcqRel) == 1
            && let Some(c) = caller
        {
            c.unpark();
        }
    }
}

impl Drop for Resident {
    fn drop(&mut self) {
        if self.pid != std::process::id() {
            // A forked copy: its members live in the parent only, there is nobody to join.
            std::mem::forget(std::mem::take(&mut self.members));
            return;
        }
        self.shared.exit.store(true, Ordering::Release);
        for h in self.members.drain(..) {
            h.thread().unpark();
            // A member only ends by returning; a panic in a job was caught.
            let _ = h.join();
        }
    }
}

/// A place in a workspace for a [`Resident`] team, started on first use. A copy of the
/// workspace starts its own team when it needs one, rather than sharing this one.
#[derive(Default)]
pub(super) struct Slot(Option<Resident>);

impl Slot {
    /// The team of `n` members (`n` at least 2), started or restarted to that size, and
    /// started again in a process forked from the one that started it.
    pub(super) fn get(&mut self, n: usize) -> &Resident {
        let pid = std::process::id();
        if self.0.as_ref().is_none_or(|r| r.size() != n || r.pid != pid) {
            // The old team's threads are joined before the new one's start.
            self.0 = None;
            self.0 = Some(Resident::new(n));
        }
        self.0.as_ref().expect("just started")
    }
}

impl Clone for Slot {
    fn clone(&self) -> Self {
        Slot(None)
    }
}

impl std::fmt::Debug for Slot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.0 {
            Some(r) => write!(f, "Slot({} members)", r.size()),
            None => write!(f, "Slot(none)"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_member_runs_each_job_once_and_the_caller_is_member_zero() {
        let team = Resident::new(3);
        let caller = std::thread::current().id();
        for round in 0..200 {
            let hits: Vec<AtomicUsize> = (0..3).map(|_| AtomicUsize::new(0)).collect();
            let on_caller = AtomicBool::new(false);
            team.run(&|t| {
                hits[t].fetch_add(1, Ordering::Relaxed);
                if t == 0 {
                    on_caller.store(std::thread::current().id() == caller, Ordering::Relaxed);
                }
            });
            let counts: Vec<usize> = hits.iter().map(|h| h.load(Ordering::Relaxed)).collect();
            assert_eq!(counts, vec![1, 1, 1], "round {round}");
            assert!(on_caller.load(Ordering::Relaxed));
            if round == 100 {
                // Let the members fall asleep, so the next job must wake them.
                std::thread::sleep(IDLE_WATCH * 3);
            }
        }
    }

    #[test]
    fn a_job_sees_what_the_caller_wrote_and_the_caller_sees_the_members_writes() {
        let team = Resident::new(2);
        let mut data = vec![0u64; 1000];
        for round in 1..50u64 {
            let ptr = data.as_mut_ptr() as usize;
            team.run(&|t| {
                // Member t owns the elements of its parity.
                for (k, _) in (0..1000).enumerate().filter(|(k, _)| k % 2 == t) {
                    // SAFETY: disjoint elements per member; `run` waits for both.
                    unsafe { *(ptr as *mut u64).add(k) += round };
                }
            });
            let want: u64 = (1..=round).sum();
            assert!(data.iter().all(|&x| x == want), "round {round}");
        }
    }

    #[test]
    fn a_members_panic_reaches_the_caller_and_the_team_still_works() {
        let team = Resident::new(2);
        let r = catch_unwind(AssertUnwindSafe(|| {
            team.run(&|t| {
                if t == 1 {
                    panic!("member one fails");
                }
            })
        }));
        assert!(r.is_err());
        let n = AtomicUsize::new(0);
        team.run(&|_| {
            n.fetch_add(1, Ordering::Relaxed);
        });
        assert_eq!(n.load(Ordering::Relaxed), 2);
    }

    /// A process forked while a team is running (Python's multiprocessing forks) has the
    /// team's memory but none of its threads: its first solve must start a team of its own,
    /// not wait forever for members that are not there.
    #[cfg(unix)]
    #[test]
    fn a_forked_process_starts_its_own_team() {
        let mut slot = Slot::default();
        let n = AtomicUsize::new(0);
        slot.get(2).run(&|_| {
            n.fetch_add(1, Ordering::Relaxed);
        });
        // SAFETY: the child only runs a job on a fresh team and leaves with _exit.
        let child = unsafe { libc::fork() };
        assert!(child >= 0, "fork failed");
        if child == 0 {
            let m = AtomicUsize::new(0);
            slot.get(2).run(&|_| {
                m.fetch_add(1, Ordering::Relaxed);
            });
            // SAFETY: leaves the child at once, running nothing of the parent's.
            unsafe { libc::_exit(if m.load(Ordering::Relaxed) == 2 { 0 } else { 1 }) };
        }
        let mut status = 0;
        let start = Instant::now();
        let finished = loop {
            // SAFETY: waits for our own child without blocking.
            let r = unsafe { libc::waitpid(child, &mut status, libc::WNOHANG) };
            if r == child {
                break true;
            }
            if start.elapsed() > Duration::from_secs(30) {
                // SAFETY: our own child, hung.
                unsafe { libc::kill(child, libc::SIGKILL) };
                unsafe { libc::waitpid(child, &mut status, 0) };
                break false;
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        assert!(finished, "the forked process's solve hung");
        assert!(
            libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0,
            "status {status}"
        );
        // The parent's team still works.
        slot.get(2).run(&|_| {
            n.fetch_add(1, Ordering::Relaxed);
        });
        assert_eq!(n.load(Ordering::Relaxed), 4);
    }

    #[test]
    fn a_copied_slot_starts_its_own_team() {
        let mut a = Slot::default();
        assert_eq!(a.get(2).size(), 2);
        let mut b = a.clone();
        assert!(format!("{b:?}").contains("none"));
        assert_eq!(b.get(3).size(), 3);
        assert_eq!(a.get(2).size(), 2);
    }
}
