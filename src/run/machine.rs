//! What the machine gave at the time of a measurement (`cdlab bench`, once per round): the
//! memory's speed and latency, and what it costs threads to meet. On a shared machine these
//! move from day to day and within a day; the CPU step's cost and the thread team's gain
//! move with them (docs/benchmarks.md, "The machine's day").

use std::hint::black_box;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// Bytes written and chased by the memory probes: twice the 32 MB last-level cache of the
/// project's reference machine (docs/benchmarks.md), so that there they measure the memory.
/// Where the last-level cache is larger, part of the chase hits it.
const SPAN: usize = 64 << 20;

/// One cache line.
const LINE: usize = 64;

/// The probes' figures.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Machine {
    /// Writing 64 MiB, median of five (GB/s).
    pub fill_gb_s: f64,
    /// One load that depends on the last, in a random cycle over the cache lines of 64 MiB
    /// (ns): the memory's latency as a scattered access sees it.
    pub load_ns: f64,
    /// A value handed from one thread to another through a shared cache line and back
    /// (ns), both spinning; none with a single core available. The team's threads meet
    /// like this at each barrier.
    pub round_trip_ns: Option<f64>,
    /// Starting and joining a thread, median of 21 (us): what a team started once per
    /// step would pay each step.
    pub thread_start_us: f64,
    /// Handing a job to a resident team of two (the solver's, kept from step to step) and
    /// waiting for its end, each after a millisecond of the caller's own work, as a step's
    /// fixed part comes between two solves; median of 21 (us). None with a single core.
    pub team_job_us: Option<f64>,
    /// Waking a parked thread and being woken by it in return, mean of a hundred (us).
    pub wake_us: f64,
}

impl Machine {
    /// The figures on one line, each with its unit.
    pub fn line(&self) -> String {
        format!(
            "writing {:.1} GB/s, dependent load {:.0} ns, round trip between threads {}, thread start {:.1} us, job to the resident team {}, wake and back {:.1} us",
            self.fill_gb_s,
            self.load_ns,
            self.round_trip_ns
                .map_or_else(|| "- (one core)".to_string(), |t| format!("{t:.0} ns")),
            self.thread_start_us,
            self.team_job_us
                .map_or_else(|| "- (one core)".to_string(), |t| format!("{t:.1} us")),
            self.wake_us
        )
    }
}

/// Runs the probes (about half a second).
pub fn probe() -> Machine {
    let mut buf = vec![0u8; SPAN];
    Machine {
        fill_gb_s: fill(&mut buf),
        load_ns: chase(&mut buf),
        round_trip_ns: round_trip(),
        thread_start_us: thread_start(),
        team_job_us: team_job(),
        wake_us: wake(),
    }
}

/// The median of `v` (not empty).
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn fill(buf: &mut [u8]) -> f64 {
    // The first pass maps the pages; it is not timed.
    buf.fill(1);
    let rates = (2..7u8)
        .map(|k| {
            let t = Instant::now();
            buf.fill(k);
            black_box(&mut *buf);
            buf.len() as f64 / t.elapsed().as_secs_f64() / 1e9
        })
        .collect();
    median(rates)
}

fn chase(buf: &mut [u8]) -> f64 {
    let lines = buf.len() / LINE;
    // The lines in a shuffled order (from a fixed seed), each pointing to the next in that
    // order and the last to the first: one cycle through every line, in which each load's
    // address is the value the last one read, so that no prefetcher can run ahead.
    let mut order: Vec<u32> = (0..lines as u32).collect();
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    for k in (1..lines).rev() {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        order.swap(k, (x % k as u64) as usize);
    }
    let at = |l: u32| l as usize * LINE;
    for w in 0..lines {
        let (from, to) = (order[w], order[(w + 1) % lines]);
        buf[at(from)..at(from) + 8].copy_from_slice(&(at(to) as u64).to_ne_bytes());
    }
    let next = |p: usize| u64::from_ne_bytes(buf[p..p + 8].try_into().expect("eight bytes")) as usize;
    let mut p = at(order[0]);
    let t = Instant::now();
    for _ in 0..lines {
        p = next(black_box(p));
    }
    black_box(p);
    t.elapsed().as_secs_f64() * 1e9 / lines as f64
}

/// Spins until `flag` holds a value that `done` accepts, and gives it; it yields now and
/// then, so that a descheduled partner is not waited for through whole time slices.
fn spin_until(flag: &AtomicU64, done: impl Fn(u64) -> bool) -> u64 {
    let mut spins = 0u32;
    loop {
        let v = flag.load(Ordering::Acquire);
        if done(v) {
            return v;
        }
        spins = spins.wrapping_add(1);
        if spins.is_multiple_of(4096) {
            std::thread::yield_now();
        } else {
            std::hint::spin_loop();
        }
    }
}

/// Whether a single core is available: the probes between two threads then have nothing
/// to measure.
fn one_core() -> bool {
    std::thread::available_parallelism().map_or(1, |n| n.get()) < 2
}

fn round_trip() -> Option<f64> {
    if one_core() {
        return None;
    }
    // Odd values are the question, even ones the answer; the other thread stops at u64::MAX.
    let flag = AtomicU64::new(0);
    let ask = |k: u64| {
        flag.store(2 * k + 1, Ordering::Release);
        spin_until(&flag, |v| v == 2 * k + 2);
    };
    const TRIPS: u64 = 20_000;
    let mut trips = 0;
    let elapsed = std::thread::scope(|s| {
        s.spawn(|| {
            for k in 0.. {
                if spin_until(&flag, |v| v == 2 * k + 1 || v == u64::MAX) == u64::MAX {
                    return;
                }
                flag.store(2 * k + 2, Ordering::Release);
            }
        });
        // The first trips wake the partner; they are not timed.
        (0..100).for_each(ask);
        let t = Instant::now();
        for k in 100..100 + TRIPS {
            ask(k);
            trips += 1;
            if t.elapsed() > Duration::from_millis(50) {
                break;
            }
        }
        let e = t.elapsed();
        flag.store(u64::MAX, Ordering::Release);
        e
    });
    Some(elapsed.as_secs_f64() * 1e9 / trips as f64)
}

fn thread_start() -> f64 {
    let times = (0..21)
        .map(|_| {
            let t = Instant::now();
            std::thread::scope(|s| {
                s.spawn(|| black_box(1));
            });
            t.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    median(times)
}

fn team_job() -> Option<f64> {
    if one_core() {
        return None;
    }
    let team = crate::solver::resident::Resident::new(2);
    team.run(&|t| {
        black_box(t);
    });
    let times = (0..21)
        .map(|_| {
            let work = Instant::now();
            while work.elapsed() < Duration::from_millis(1) {
                std::hint::spin_loop();
            }
            let t = Instant::now();
            team.run(&|t| {
                black_box(t);
            });
            t.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    Some(median(times))
}

fn wake() -> f64 {
    const TRIPS: u64 = 100;
    let flag = AtomicU64::new(0);
    let main = std::thread::current();
    std::thread::scope(|s| {
        let partner = s.spawn(|| {
            for k in 0..TRIPS {
                while flag.load(Ordering::Acquire) != 2 * k + 1 {
                    std::thread::park();
                }
                flag.store(2 * k + 2, Ordering::Release);
                main.unpark();
            }
        });
        let partner = partner.thread().clone();
        let t = Instant::now();
        for k in 0..TRIPS {
            flag.store(2 * k + 1, Ordering::Release);
            partner.unpark();
            while flag.load(Ordering::Acquire) != 2 * k + 2 {
                std::thread::park();
            }
        }
        t.elapsed().as_secs_f64() * 1e6 / TRIPS as f64
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The chase visits every line once per cycle: a broken cycle (a shorter loop, or a
    /// line pointing outside the buffer) would make it a cache-resident loop or a panic.
    /// On a small buffer the cycle is checked directly.
    #[test]
    fn the_chase_is_one_cycle_through_every_line() {
        let mut buf = vec![0u8; 256 * LINE];
        chase(&mut buf);
        let next = |p: usize| u64::from_ne_bytes(buf[p..p + 8].try_into().unwrap()) as usize;
        let mut seen = vec![false; 256];
        let mut p = 0;
        for _ in 0..256 {
            assert_eq!(p % LINE, 0);
            assert!(!seen[p / LINE], "line {} visited twice", p / LINE);
            seen[p / LINE] = true;
            p = next(p);
        }
        assert_eq!(p, 0, "back to the start after every line");
    }

    #[test]
    fn the_median_is_the_middle_value() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![5.0, 1.0, 4.0, 2.0, 3.0]), 3.0);
    }
}
