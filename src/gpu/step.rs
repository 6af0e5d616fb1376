//! Recording of one time step on the device, phase by phase (the order of
//! `CpuEngine::step`), and the run loop with its few readbacks:
//!
//! 1. submission A: clear, free velocities, grid, detection, compaction with warm start,
//!    incidence lists, warm-start gather, coloring (one dispatch per round, as many rounds
//!    as the last step needed plus a margin); then one readback of the status words
//!    (contact count, overflows, colors and their offsets, contacts left uncolored,
//!    largest overlap). On overflow, or when the rounds were too few, the capacities grow
//!    and A is recorded again (nothing in A changes the state).
//! 2. submissions B: `conv_every` iterations (one dispatch per color, or three for
//!    Jacobi) and a convergence reduction; one readback of two floats each.
//! 3. submission C: local updates of deep contacts (two dispatches), integration, wall
//!    impulses, saving the impulses for the warm start.
//!
//! At the end of a run, one more submission reduces counts, overlaps and energies.

use super::WG;
use super::backend::GpuBackend;
use super::buffers::float_slot::{
    CONV_D2, CONV_DV, CONV_R2, CONV_WORDS, MICRO_COUNTS, MICRO_SUMS, RED_CONNECTED, RED_CONNECTED_ENERGY,
    RED_FREE, RED_KINETIC, RED_MICRO, RED_MICRO_SUMS, RED_OVERLAP_COUNT, RED_OVERLAP_MAX, RED_OVERLAP_SUM,
    RED_ROLLING, RED_SLIDING, RED_STRIP_N_LEFT, RED_STRIP_N_RIGHT, RED_STRIP_X_LEFT, RED_STRIP_X_RIGHT,
    RED_TRANSLATIONAL, RED_ZERO_FORCE,
};
use super::buffers::{ARGS_STRIDE, SimParams, round_slot, status};
use super::pipeline::Kernel;
use super::traffic::{self, Counts};
use crate::backend::{Loading, Reductions};
use crate::error::{Error, Result};
use crate::solver::Method;

fn groups(n: u32) -> u32 {
    n.div_ceil(WG)
}

/// The dispatches of a recording, for their byte counts: each kernel with the items it
/// covers, `None` for an indirect dispatch over the contacts (counted on the device, known
/// to the host once it reads the status words back).
type Log = Vec<(Kernel, Option<u32>)>;

/// A compute pass with the shared bind groups set, a dispatch counter and a log of the
/// dispatches for their traffic ([`GpuBackend::charge`]).
struct Rec<'a> {
    pass: wgpu::ComputePass<'a>,
    b: &'a GpuBackend,
    dispatches: u64,
    log: Log,
}

impl<'a> Rec<'a> {
    fn new(enc: &'a mut wgpu::CommandEncoder, b: &'a GpuBackend) -> Self {
        let mut pass = enc
            .begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("cdlab step"),
                timestamp_writes: None,
            })
            .forget_lifetime();
        pass.set_bind_group(0, &b.bind.0, &[]);
        Rec {
            pass,
            b,
            dispatches: 0,
            log: Vec::new(),
        }
    }

    /// Dispatches `x` workgroups of `kernel` with argument slot `slot`, over `items` items
    /// (the count its per-item traffic is multiplied by, see [`super::traffic`]).
    fn go(&mut self, kernel: Kernel, slot: u32, x: u32, items: u32) {
        if x == 0 {
            return;
        }
        self.log.push((kernel, Some(items)));
        self.pass.set_pipeline(self.b.pipes.get(kernel));
        self.pass
            .set_bind_group(1, &self.b.bind.1, &[(slot as u64 * ARGS_STRIDE) as u32]);
        self.pass.dispatch_workgroups(x, 1, 1);
        self.dispatches += 1;
    }

    /// Dispatches `kernel` over the contacts (indirect: the count is on the GPU).
    fn go_contacts(&mut self, kernel: Kernel) {
        self.go_contacts_with(kernel, 0);
    }

    /// [`Rec::go_contacts`] with argument slot `slot`.
    fn go_contacts_with(&mut self, kernel: Kernel, slot: u32) {
        self.pass.set_pipeline(self.b.pipes.get(kernel));
        self.pass
            .set_bind_group(1, &self.b.bind.1, &[(slot as u64 * ARGS_STRIDE) as u32]);
        self.pass.dispatch_workgroups_indirect(&self.b.bufs.indirect, 0);
        self.dispatches += 1;
        self.log.push((kernel, None));
    }

    /// Ends the pass: the dispatches recorded and their log.
    fn finish(self) -> (u64, Log) {
        (self.dispatches, self.log)
    }
}

/// What one step did on the device.
struct StepInfo {
    iterations: u32,
    converged: bool,
    colors: u32,
}

impl GpuBackend {
    /// Runs `steps` steps under `loading` and returns the reductions.
    pub(super) fn run_steps(&mut self, steps: u32, loading: &Loading) -> Result<Reductions> {
        if *loading != self.loading {
            // The strip flags and the wall forces live in the disk and wall records:
            // download, re-tag, upload (once per change of loading, not per step).
            let mut scene = crate::backend::Backend::scene(self)?;
            self.loading = loading.clone();
            loading.apply_wall_forces(&mut scene);
            crate::backend::Backend::set_scene(self, &scene)?;
        }
        let nw = self.scene.walls.len();
        let zeros = vec![0u8; 8 * nw];
        if nw > 0 {
            self.gpu
                .queue
                .write_buffer(&self.bufs.floats, 4 * self.sim.f_wall as u64, &zeros);
        }
        self.gpu
            .queue
            .write_buffer(&self.bufs.floats, 4 * self.sim.f_deep as u64, &[0u8; 8]);
        if self.sim.deep_budget != self.deep_budget {
            self.sim.deep_budget = self.deep_budget;
            self.write_params();
        }
        let mut red = Reductions::default();
        let mut colors = 0u64;
        for _ in 0..steps {
            let info = self.step_once()?;
            red.steps += 1;
            red.iterations_sum += info.iterations as u64;
            red.iterations_max = red.iterations_max.max(info.iterations);
            red.capped_steps += !info.converged as u32;
            colors += info.colors as u64;
            self.scene.time += self.params.dt;
            self.scene.step += 1;
        }
        red.colors_mean = colors as f64 / red.steps.max(1) as f64;
        self.finish_reductions(red, loading)
    }

    /// Adds the bytes of the dispatches in `log` to the counters, for a step with `n`
    /// contacts (the items of the indirect dispatches).
    fn charge(&mut self, log: &Log, n: u32) {
        let walls = self.sim.n_walls as u64;
        for &(kernel, items) in log {
            let counts = Counts {
                items: items.unwrap_or(n) as u64,
                contacts: n as u64,
                walls,
            };
            let b = traffic::bytes(kernel, counts);
            self.counters.bytes_read += b.read;
            self.counters.bytes_written += b.written;
        }
    }

    /// Submits `enc`; validation errors of the recording (a dispatch beyond the adapter's
    /// limits, say) are reported by wgpu on the spot and end the run here.
    fn submit(&mut self, enc: wgpu::CommandEncoder) -> Result<()> {
        self.gpu.queue.submit([enc.finish()]);
        self.counters.submissions += 1;
        self.gpu.check("submitting the time step")
    }

    fn step_once(&mut self) -> Result<StepInfo> {
        let nd = self.sim.n_disks;
        let nb = self.sim.n_bodies;
        // Submission A, redone after a growth.
        let status = loop {
            let rounds = self.rounds_hint.clamp(1, self.cap.rounds);
            let mut enc = self.gpu.device.create_command_encoder(&Default::default());
            let mut d = 0;
            let mut log = Log::new();
            let clear = self.bufs.layout.clear_len;
            {
                let mut r = Rec::new(&mut enc, self);
                r.go(Kernel::ClearInts, 0, groups(clear), clear);
                r.go(Kernel::FreeVelocity, 0, groups(nb), nb);
                r.go(Kernel::GridBounds, 0, 1, nd);
                r.go(Kernel::GridCount, 0, groups(nd), nd);
                r.go(Kernel::Scan, 1, 1, self.sim.cap_cells);
                r.go(Kernel::GridScatter, 0, groups(nd), nd);
                r.go(Kernel::Detect, 0, groups(nd), nd);
                r.go(Kernel::Scan, 2, 1, nd);
                r.go(Kernel::ContactArgs, 0, 1, 1);
                let (k, l) = r.finish();
                d += k;
                log.extend(l);
            }
            let o = 4 * (self.sim.o_status as u64 + status::ARGS as u64);
            enc.copy_buffer_to_buffer(&self.bufs.ints, o, &self.bufs.indirect, 0, 12);
            {
                let mut r = Rec::new(&mut enc, self);
                r.go(Kernel::BuildContacts, 0, groups(nd), nd);
                r.go_contacts(Kernel::IncidenceCount);
                r.go(Kernel::Scan, 3, 1, nb);
                r.go_contacts(Kernel::IncidenceFill);
                r.go_contacts(Kernel::IncidenceRank);
                r.go(Kernel::Gather, 0, groups(nb), nb);
                r.go_contacts(Kernel::ColorSeed);
                for k in 1..=rounds {
                    r.go_contacts_with(Kernel::ColorRound, round_slot(self.cap, k));
                }
                r.go_contacts(Kernel::ColorCount);
                r.go(Kernel::ColorOffsets, round_slot(self.cap, rounds), 1, 1);
                r.go_contacts(Kernel::ColorScatter);
                let (k, l) = r.finish();
                d += k;
                log.extend(l);
            }
            self.counters.dispatches += d;
            self.submit(enc)?;
            let words = status::WORDS as u64 + self.cap.colors as u64 + 1;
            let ints = self.bufs.ints.clone();
            let bytes = self.download(&ints, 4 * self.sim.o_status as u64, 4 * words)?;
            let st: Vec<u32> = bytemuck::cast_slice(&bytes).to_vec();
            let mut cap = self.cap;
            let n = st[status::CONTACTS];
            // The kernels ran over the contacts that fit (WGSL `n_contacts`).
            self.charge(&log, n.min(cap.contacts));
            if n > cap.contacts {
                cap.contacts = n + n / 4 + 64;
            }
            if st[status::SLOTS_NEED] > cap.k_slots {
                cap.k_slots = st[status::SLOTS_NEED] + 4;
            }
            if st[status::COLORS] > cap.colors {
                cap.colors = 2 * st[status::COLORS];
            }
            // Too few rounds recorded: redo with twice as many (rare, the hint follows the
            // last step's count).
            let unfinished = n <= cap.contacts && st[status::LEFT] > 0;
            if unfinished {
                // Colors carry their round in 16 bits (color.wgsl); JPL needs about as many
                // rounds as the largest clique has contacts, far below that.
                if 2 * rounds > 0xffff {
                    return Err(self.gpu.failure(
                        &format!("step {}", self.scene.step),
                        format!(
                            "the coloring left {} contacts after {rounds} rounds",
                            st[status::LEFT]
                        ),
                    ));
                }
                self.rounds_hint = 2 * rounds;
                cap.rounds = cap.rounds.max(self.rounds_hint);
            }
            if cap == self.cap && !unfinished {
                break st;
            }
            if cap != self.cap {
                self.grow(cap)?;
            }
            self.counters.redone += 1;
        };
        let rounds = status[status::ROUNDS];
        // New contacts need a few rounds even when the last step needed none.
        self.rounds_hint = rounds + rounds / 4 + 4;
        let n = status[status::CONTACTS];
        let n_colors = status[status::COLORS];
        self.n_contacts = n;
        self.color_offsets = status[status::WORDS..status::WORDS + n_colors as usize + 1].to_vec();
        // The sweeps dispatch one range per color: ranges that do not tile 0..n mean the
        // coloring did not finish, and dispatching them would ask for billions of groups.
        let tiled = self.color_offsets.first() == Some(&0)
            && self.color_offsets.last() == Some(&n)
            && self.color_offsets.windows(2).all(|w| w[0] <= w[1]);
        if n > 0 && !tiled {
            return Err(self.gpu.failure(
                &format!("step {}", self.scene.step),
                format!(
                    "the GPU coloring left {n} contacts in inconsistent color ranges ({n_colors} colors, \
                     offsets {:?})",
                    self.color_offsets
                ),
            ));
        }
        let overlap = f32::from_bits(status[status::OVERLAP]) as f64;
        if overlap > self.params.overlap_limit {
            return Err(Error::Numerical {
                step: self.scene.step,
                message: format!(
                    "overlap {overlap:.3e} m exceeds the limit {:.3e} m. {}",
                    self.params.overlap_limit,
                    crate::engine::overlap_advice(self.params.solver.max_iter)
                ),
            });
        }
        let (iterations, converged) = self.iterate(n)?;
        // Submission C.
        let mut enc = self.gpu.device.create_command_encoder(&Default::default());
        {
            let mut r = Rec::new(&mut enc, self);
            let p = self.params.solver;
            if p.deep_updates() && n > 0 {
                // Local updates of deep contacts: the selection, then every sweep over the
                // colors in one workgroup, so that the phase costs two dispatches whatever
                // deep_sweeps and the colors (recorded every step: the count is on the device).
                r.go_contacts(Kernel::DeepMark);
                r.go(Kernel::DeepUpdates, 0, 1, 1);
            }
            r.go(Kernel::Integrate, 0, groups(nb), nb);
            let nw = self.sim.n_walls;
            r.go(Kernel::WallImpulse, 0, nw, nw);
            r.go(Kernel::SavePrev, 0, groups(n.max(nd + 1)), nd + 1);
            let (d, log) = r.finish();
            self.counters.dispatches += d;
            self.charge(&log, n);
        }
        self.submit(enc)?;
        self.counters.steps += 1;
        self.counters.iterations += iterations as u64;
        self.counters.color_rounds += rounds as u64;
        Ok(StepInfo {
            iterations,
            converged,
            colors: if self.params.solver.method == Method::Jacobi {
                0
            } else {
                // Seeded colors can leave a color empty: it costs no dispatch, and is not
                // counted, so that dispatches per iteration equal the colors reported.
                self.color_offsets.windows(2).filter(|w| w[1] > w[0]).count() as u32
            },
        })
    }

    /// The solver loop: `conv_every` iterations per submission, then the two convergence
    /// sums read back. Plain `Method::Gs` has no parallel form and runs colored on the GPU.
    fn iterate(&mut self, n: u32) -> Result<(u32, bool)> {
        if n == 0 {
            return Ok((0, true));
        }
        let p = self.params.solver;
        let jacobi = p.method == Method::Jacobi;
        let nb = self.sim.n_bodies;
        let mut done = 0u32;
        loop {
            let mut batch = self.conv_every.max(1).min(p.max_iter - done);
            // A batch runs at one relaxation: it ends where the relaxation changes.
            if done < p.gs_relax_after {
                batch = batch.min(p.gs_relax_after - done);
            }
            let relax = p.relax_at(done + 1);
            // Written at the start of every step too, so that no other upload of the
            // parameters can leave the buffer and the host copy apart.
            if !jacobi && (done == 0 || self.sim.gs_relax != relax as f32) {
                self.sim.gs_relax = relax as f32;
                let at = std::mem::offset_of!(SimParams, gs_relax) as u64;
                self.gpu
                    .queue
                    .write_buffer(&self.bufs.sim, at, bytemuck::bytes_of(&self.sim.gs_relax));
            }
            // The velocity test compares the batch's last iterate with the one before it
            // (the CPU tests every iteration; the same with check_every = 1).
            let velocity_test = !jacobi && p.velocity_tol > 0.0 && done + batch > p.gs_relax_after;
            let mut enc = self.gpu.device.create_command_encoder(&Default::default());
            {
                let mut r = Rec::new(&mut enc, self);
                for k in 0..batch {
                    if velocity_test && k + 1 == batch {
                        r.go(Kernel::SaveIterate, 0, groups(nb), nb);
                    }
                    if jacobi {
                        r.go(Kernel::JacobiSolve, 0, groups(n), n);
                        r.go(Kernel::JacobiCommit, 0, groups(n), n);
                        r.go(Kernel::Gather, 0, groups(nb), nb);
                    } else {
                        for (c, w) in self.color_offsets.windows(2).enumerate() {
                            let m = w[1] - w[0];
                            r.go(Kernel::SweepColor, 4 + c as u32, groups(m), m);
                        }
                    }
                }
                r.go(Kernel::ConvReduce, 0, 1, n);
                if velocity_test {
                    r.go(Kernel::VelocityChange, 0, 1, nb);
                }
                let (d, log) = r.finish();
                self.counters.dispatches += d;
                self.charge(&log, n);
            }
            self.submit(enc)?;
            done += batch;
            let floats = self.bufs.floats.clone();
            let bytes = self.download(&floats, 4 * self.sim.f_conv as u64, 4 * CONV_WORDS as u64)?;
            let s: &[f32] = bytemuck::cast_slice(&bytes);
            let (d2, r2, dv) = (s[CONV_D2] as f64, s[CONV_R2] as f64, s[CONV_DV] as f64);
            if !(d2.is_finite() && r2.is_finite()) {
                return Err(Error::Numerical {
                    step: self.scene.step,
                    message: format!("non-finite impulses in the GPU solver (sums {d2}, {r2})"),
                });
            }
            // As on the CPU, the change of a relaxed iteration is divided by its relaxation.
            let w = if jacobi { p.relax } else { relax };
            let residual = if d2 == 0.0 {
                0.0
            } else if r2 == 0.0 {
                f64::INFINITY
            } else {
                (d2 / r2).sqrt() / w
            };
            // The velocity change too, as the CPU's velocity test does.
            if residual <= p.tol || (velocity_test && dv / w <= p.velocity_tol) {
                return Ok((done, true));
            }
            if done >= p.max_iter {
                return Ok((done, false));
            }
        }
    }

    /// The end-of-run reductions: one dispatch, one readback of the float accumulators.
    fn finish_reductions(&mut self, mut red: Reductions, loading: &Loading) -> Result<Reductions> {
        let mut enc = self.gpu.device.create_command_encoder(&Default::default());
        {
            let mut r = Rec::new(&mut enc, self);
            r.go(Kernel::ReduceFinal, 0, 1, self.sim.n_disks);
            let (d, log) = r.finish();
            self.counters.dispatches += d;
            let n = self.n_contacts;
            self.charge(&log, n);
        }
        self.submit(enc)?;
        let floats = self.bufs.floats.clone();
        let keep = self.bufs.layout.floats_keep as u64;
        let bytes = self.download(&floats, 0, 4 * keep)?;
        let f: Vec<f32> = bytemuck::cast_slice(&bytes).to_vec();
        let nw = self.scene.walls.len();
        let walls_buf = self.bufs.walls.clone();
        if nw > 0 {
            let wb = self.download(&walls_buf, 0, 32 * nw as u64)?;
            let walls: &[super::buffers::GpuWall] = bytemuck::cast_slice(&wb);
            for (w, g) in walls.iter().enumerate() {
                self.scene.walls[w].point =
                    glam::DVec2::new(g.px as f64 + self.centre.x, g.py as f64 + self.centre.y);
            }
        }
        let dt = self.params.dt;
        let steps = red.steps.max(1) as f64;
        let fw = self.sim.f_wall as usize;
        red.wall_force = (0..nw)
            .map(|w| glam::DVec2::new(f[fw + 2 * w] as f64, f[fw + 2 * w + 1] as f64) / (steps * dt))
            .collect();
        red.wall_point = self.scene.walls.iter().map(|w| w.point).collect();
        red.time = self.scene.time;
        red.step = self.scene.step;
        red.candidates = self.n_contacts;
        let r = self.sim.f_red as usize;
        let u = |k: usize| f[r + k].to_bits();
        red.rolling = u(RED_ROLLING);
        red.sliding = u(RED_SLIDING);
        red.zero_force = u(RED_ZERO_FORCE);
        red.force_carrying = red.rolling + red.sliding;
        let (connected, free) = (u(RED_CONNECTED) as f64, u(RED_FREE) as f64);
        red.coordination = if connected > 0.0 {
            2.0 * red.force_carrying as f64 / connected
        } else {
            0.0
        };
        red.isolated_fraction = if free > 0.0 { 1.0 - connected / free } else { 0.0 };
        let n_ov = f[r + RED_OVERLAP_COUNT] as f64;
        red.overlap_mean = if n_ov > 0.0 {
            f[r + RED_OVERLAP_SUM] as f64 / n_ov
        } else {
            0.0
        };
        red.overlap_max = f[r + RED_OVERLAP_MAX] as f64;
        red.deep_sum = f[self.sim.f_deep as usize].to_bits() as u64;
        let cut = f[self.sim.f_deep as usize + 1].to_bits() as u64;
        if cut > 0 && self.counters.deep_sweeps_cut == 0 {
            // Once per backend, as the adapter warning of gpu::device::open.
            eprintln!(
                "warning: the software GPU adapter's loop limit cut the local updates of deep \
                 contacts short ({cut} sweeps left out over the last {} steps); fewer deep \
                 contacts (a smaller time step) or solver.deep_sweeps below {} avoid it",
                red.steps, self.params.solver.deep_sweeps
            );
        }
        self.counters.deep_sweeps_cut += cut;
        red.kinetic_energy = f[r + RED_KINETIC] as f64;
        red.translational_energy = f[r + RED_TRANSLATIONAL] as f64;
        red.connected_energy = f[r + RED_CONNECTED_ENERGY] as f64;
        red.micro = micro_sums(&f[r + RED_MICRO..r + RED_MICRO_SUMS + MICRO_SUMS], dt);
        let has = |s: i8| loading.strip.contains(&s);
        // The outer edges need the positions: one download at the output interval.
        if !loading.strip.is_empty() {
            let scene = crate::backend::Backend::scene(self)?;
            red.strip_edges = crate::backend::reduce::strip_outer_edges(&scene, loading);
        } else {
            red.strip_edges = [f64::NAN; 2];
        }
        red.strip_mean_x = [
            (-1i8, RED_STRIP_X_LEFT, RED_STRIP_N_LEFT),
            (1, RED_STRIP_X_RIGHT, RED_STRIP_N_RIGHT),
        ]
        .map(|(s, sx, sc)| {
            if has(s) && f[r + sc] > 0.0 {
                f[r + sx] as f64 / f[r + sc] as f64 + self.centre.x
            } else {
                f64::NAN
            }
        });
        Ok(red)
    }
}

/// The micromechanical sums as `reduce_final` leaves them (reduce.wgsl, `micro_sums`):
/// counts as u32 bits, sums of impulses turned into forces with `dt`.
fn micro_sums(m: &[f32], dt: f64) -> crate::measure::micro::MicroSums {
    use crate::measure::micro::{MicroSums, ROSE_BINS, Sym2};
    let sym = |k: usize, scale: f64| Sym2 {
        xx: m[k] as f64 * scale,
        xy: m[k + 1] as f64 * scale,
        yy: m[k + 2] as f64 * scale,
    };
    let per_dt = 1.0 / dt;
    let mut rose = [0u32; ROSE_BINS];
    for (b, r) in rose.iter_mut().enumerate() {
        *r = m[2 + b].to_bits();
    }
    // The sums follow the counts, in the order micro_sums writes them.
    let k = MICRO_COUNTS;
    MicroSums {
        n_force: m[0].to_bits(),
        nn: sym(k, 1.0),
        f_n: m[k + 3] as f64 * per_dt,
        fnn: sym(k + 4, per_dt),
        ftn: sym(k + 7, per_dt),
        stress: sym(k + 10, per_dt),
        stress_dd: sym(k + 13, per_dt),
        n_strong: m[1].to_bits(),
        stress_strong: sym(k + 16, per_dt),
        rose,
    }
}
