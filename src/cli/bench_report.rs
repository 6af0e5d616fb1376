//! What `cdlab bench` prints and writes: one line per case, and `bench.md`'s table with
//! the cost per contact update against the first size of the same round, and over several
//! rounds the median of those ratios.

use crate::run::bench::{Case, CpuPhases};
use crate::run::machine::Machine;

/// A device time (ms), or "-" without timestamps.
fn ms(t: Option<f64>) -> String {
    t.map_or_else(|| "-".to_string(), |t| format!("{t:.2}"))
}

/// The device's time per phase outside the solve (ms), or "-" without timestamps.
fn phases(c: &Case) -> String {
    c.device_phases_ms_per_step.map_or_else(
        || "-".to_string(),
        |p| {
            format!(
                "{:.3} / {:.3} / {:.3} / {:.3}",
                p.detection, p.coloring, p.deep_updates, p.integration
            )
        },
    )
}

/// One case on one line, every figure with its unit.
pub fn line(c: &Case) -> String {
    format!(
        "{:<40} {} {:>6} disks {:>7} contacts check every {} it {:>7.1} it/step {:>9.2} ms/step {:>7.2} ns/update {:>6.1} colors {:>5.1} rounds/step {} redone {:>8.1} dispatches/step ({:.1} fixed, {:.1} empty) {:>5.2} submissions/step {:>5.2} waits/window of {} steps, host recording {:.2} ms/step on {} threads, sweep_all {}, device {} ms/step (solve {}) {:>8.1} MB/step device traffic host {:>7.1} MiB device {:>7.1} MiB",
        c.backend,
        c.method,
        c.disks,
        c.contacts,
        c.check_every,
        c.iterations_per_step,
        c.ms_per_step,
        c.ns_per_contact_update,
        c.colors_per_step,
        c.color_rounds_per_step,
        c.redone_steps,
        c.dispatches_per_step,
        c.fixed_dispatches_per_step,
        c.empty_dispatches_per_step,
        c.submissions_per_step,
        c.readbacks_per_window,
        c.window,
        c.host_record_ms_per_step,
        c.record_threads,
        c.sweep_all,
        ms(c.device_ms_per_step),
        ms(c.device_solve_ms_per_step),
        c.traffic_mb_per_step,
        c.host_peak_mib,
        c.device_mib
    )
}

/// `bench.md`: the cases as a table (solver tolerance `tol`, `warmup` and `steps` steps
/// per case), and how the cost scales with the size.
pub fn markdown(cases: &[Case], tol: f64, warmup: u32, steps: u32) -> String {
    let mut s = format!(
        "# cdlab bench\n\nConfined dense sample under shear (deposit closed by walls, top wall at 0.5 m/s, friction 0.3), tolerance {}, {} warm-up and {} measured steps per case.\n\n",
        tol, warmup, steps
    );
    s.push_str("| backend | method | disks | contacts | check every (it) | iterations/step | ms/step | ns/contact update | colors | coloring rounds/step | windows redone | dispatches/step | fixed dispatches/step | empty dispatches/step | submissions/step | waits/window | host recording (ms/step) | recording threads | device (ms/step) | device solve (ms/step) | device detection / coloring / deep updates / integration (ms/step) | device traffic (MB/step) | host peak (MiB) | device (MiB) | round |\n");
    s.push_str(
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for c in cases {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {:.1} | {:.2} | {:.2} | {:.1} | {:.1} | {} | {:.1} | {:.1} | {:.1} | {:.2} | {:.2} | {:.2} | {} | {} | {} | {} | {:.1} | {:.1} | {:.1} | {} |\n",
            c.backend, c.method, c.disks, c.contacts, c.check_every, c.iterations_per_step, c.ms_per_step, c.ns_per_contact_update, c.colors_per_step,
            c.color_rounds_per_step, c.redone_steps,
            c.dispatches_per_step, c.fixed_dispatches_per_step, c.empty_dispatches_per_step, c.submissions_per_step, c.readbacks_per_window, c.host_record_ms_per_step, c.record_threads, ms(c.device_ms_per_step), ms(c.device_solve_ms_per_step), phases(c), c.traffic_mb_per_step, c.host_peak_mib, c.device_mib, c.round
        ));
    }
    s.push_str("\nCost per contact update against the first size of the same round (linear scaling keeps it flat; the cost per step at 50k within 11x of 5k asks for the same):\n\n");
    for (c, first) in against_first(cases) {
        s.push_str(&format!(
            "- {}, round {}: {} -> {} disks: time per step x{:.2} for x{:.2} disks; ns per contact update x{:.2}\n",
            c.backend,
            c.round,
            first.disks,
            c.disks,
            c.ms_per_step / first.ms_per_step,
            c.disks as f64 / first.disks as f64,
            c.ns_per_contact_update / first.ns_per_contact_update
        ));
    }
    let cpu: Vec<(&Case, &CpuPhases)> = cases
        .iter()
        .filter_map(|c| c.cpu_phases.as_ref().map(|p| (c, p)))
        .collect();
    if !cpu.is_empty() {
        s.push_str("\nWhere a CPU step's time goes (ms/step); the fixed part is everything but the sweeps, per disk against the first size of the same round (a step that scales keeps it near x1):\n\n");
        s.push_str("| disks | method | detect | contacts | solver setup | sweeps | deep contacts | store | integrate | fixed | fixed per disk (ns) | fixed per disk against the first | round |\n");
        s.push_str("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
        for (c, p) in &cpu {
            let first = first_of(cases, c)
                .and_then(|f| f.cpu_phases.as_ref())
                .unwrap_or(p);
            s.push_str(&format!(
                "| {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.1} | x{:.2} | {} |\n",
                c.disks, c.method, p.detect_ms, p.contacts_ms, p.setup_ms, p.sweeps_ms, p.deep_ms, p.store_ms, p.integrate_ms, p.fixed_ms,
                p.fixed_ns_per_disk, p.fixed_ns_per_disk / first.fixed_ns_per_disk, c.round
            ));
        }
    }
    s.push_str(&over_rounds(cases));
    s.push_str("\nThe fixed dispatches per step are the dispatches with work left after one per color per solver iteration and one convergence test per check: the same figure at every size and iteration count means each iteration costs exactly one dispatch per color. Empty dispatches launch no workgroup: the blocks of iterations recorded past the solve's end and the colors recorded beyond those holding contacts (the margins the host records without waiting for the device). Waits/window: the blocking reads of the device per window of steps (one series row of a test).\n");
    s
}

/// `bench.md`'s table of the machine as each round's probe found it
/// ([`crate::run::machine`]).
pub fn machine_table(machines: &[Machine]) -> String {
    let mut s = String::from(
        "\nThe machine before each round: writing 64 MiB, a load that depends on the last over 64 MiB, a value handed between two threads and back, starting a thread, handing a job to the solver's resident team of two, waking a parked thread and being woken back (docs/benchmarks.md, \"The machine's day\"):\n\n| round | writing (GB/s) | dependent load (ns) | round trip between threads (ns) | thread start (us) | job to the resident team (us) | wake and back (us) |\n| --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for (k, m) in machines.iter().enumerate() {
        s.push_str(&format!(
            "| {} | {:.1} | {:.0} | {} | {:.1} | {} | {:.1} |\n",
            k + 1,
            m.fill_gb_s,
            m.load_ns,
            m.round_trip_ns
                .map_or_else(|| "-".to_string(), |t| format!("{t:.0}")),
            m.thread_start_us,
            m.team_job_us
                .map_or_else(|| "-".to_string(), |t| format!("{t:.1}")),
            m.wake_us
        ));
    }
    s
}

/// The cases measured alike (backend, method, convergence checks, GPU recording), which
/// differ by their size only.
fn alike(a: &Case, b: &Case) -> bool {
    (
        &a.backend,
        &a.method,
        a.check_every,
        a.record_threads,
        a.sweep_all,
    ) == (
        &b.backend,
        &b.method,
        b.check_every,
        b.record_threads,
        b.sweep_all,
    )
}

/// The first case of `c`'s round measured alike, the reference of its ratios; `c` itself
/// when it is that case.
fn first_of<'a>(cases: &'a [Case], c: &Case) -> Option<&'a Case> {
    cases.iter().find(|f| f.round == c.round && alike(f, c))
}

/// Each case of another size than its round's reference, with that reference.
fn against_first(cases: &[Case]) -> impl Iterator<Item = (&Case, &Case)> {
    cases.iter().filter_map(|c| {
        let first = first_of(cases, c)?;
        (first.disks != c.disks).then_some((c, first))
    })
}

/// The median of `v` (the mean of the middle two for an even count) and its range; `None`
/// when `v` is empty.
fn median_range(v: &[f64]) -> Option<(f64, f64, f64)> {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let median = match n {
        0 => return None,
        _ if n % 2 == 1 => v[n / 2],
        _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    };
    Some((median, v[0], v[n - 1]))
}

/// With several rounds, the ratios of each size to the first, per round, as a median and a
/// range: the time per step, and for the CPU the fixed part per disk.
fn over_rounds(cases: &[Case]) -> String {
    let rounds = cases.iter().map(|c| c.round).max().unwrap_or(1);
    if rounds < 2 {
        return String::new();
    }
    let mut s = format!(
        "\nOver {rounds} rounds: each ratio is taken within a round, against the first size measured alike; median (range):\n\n"
    );
    let mut seen: Vec<&Case> = Vec::new();
    for (c, _) in against_first(cases) {
        if seen.iter().any(|d| d.disks == c.disks && alike(d, c)) {
            continue;
        }
        seen.push(c);
        let pairs: Vec<(&Case, &Case)> = against_first(cases)
            .filter(|(d, _)| d.disks == c.disks && alike(d, c))
            .collect();
        let first = pairs[0].1.disks;
        let step: Vec<f64> = pairs.iter().map(|(d, f)| d.ms_per_step / f.ms_per_step).collect();
        let fixed: Vec<f64> = pairs
            .iter()
            .filter_map(|(d, f)| Some(d.cpu_phases?.fixed_ns_per_disk / f.cpu_phases?.fixed_ns_per_disk))
            .collect();
        let show = |v: &[f64]| {
            median_range(v).map_or_else(
                || "-".to_string(),
                |(m, lo, hi)| format!("x{m:.2} (x{lo:.2}-x{hi:.2}, {} rounds)", v.len()),
            )
        };
        s.push_str(&format!(
            "- {} {}: {} against {} disks: time per step {}; fixed part per disk {}\n",
            c.backend,
            c.method,
            c.disks,
            first,
            show(&step),
            show(&fixed)
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::median_range;

    #[test]
    fn the_median_is_the_middle_value_or_the_mean_of_the_middle_two() {
        assert_eq!(median_range(&[]), None);
        assert_eq!(median_range(&[3.0, 1.0, 2.0]), Some((2.0, 1.0, 3.0)));
        assert_eq!(median_range(&[4.0, 1.0, 2.0, 10.0]), Some((3.0, 1.0, 10.0)));
    }
}
