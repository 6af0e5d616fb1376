//! The driver of a biaxial test: compaction, confinement, compression, with series rows,
//! snapshots and checkpoints handed to an [`Observer`].
//!
//! The control flow never depends on an output setting. The compression advances in
//! windows of steps that end at every step where something happens to the physics or to
//! the run's course: a strip refresh (every `strip_refresh_every` steps), a quasi-static
//! check (every [`QUASI_STATIC_CHECK_EVERY`] steps) and the first step whose axial strain
//! reaches `strain_end`, and also at every row of the series. Rows only read the state, so
//! `output.series_every` (and the snapshot interval) change what is recorded, never the
//! steps computed or where the test stops; a row that spans several windows averages its
//! wall forces over all of them, as a single window would.

use glam::DVec2;

use super::checkpoint::{Checkpoint, encode};
use super::{Gauge, LabState, Observer, Phase, PhaseEnd, ProtocolParams, walls};
use crate::backend::reduce::strip_members;
use crate::backend::{Backend, Loading, Reductions};
use crate::error::{Error, Result};
use crate::measure::SeriesRow;
use crate::model::{NOT_GLUED, Scene, WallDrive};
use serde::{Deserialize, Serialize};

/// Compression steps between two checks that the compression is still quasi-static
/// (`equilibrium.runaway_kinetic_ratio`): fixed, so that where a run stops never depends on
/// the series interval. Ten steps is the default series interval, at which the check ran
/// before it was decoupled from the rows.
pub const QUASI_STATIC_CHECK_EVERY: u32 = 10;

/// What a row needs from the windows of steps since the last row besides the last one:
/// the sums over their steps of what a row averages.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RowSums {
    /// Steps summed.
    pub steps: u32,
    /// Wall force times steps, per wall (N/m).
    pub wall_force_steps: Vec<DVec2>,
    /// Solver iterations.
    pub iterations_sum: u64,
    /// Largest iteration count of a step.
    pub iterations_max: u32,
    /// Steps whose solver hit its cap.
    pub capped_steps: u32,
    /// Colors times steps.
    pub colors_steps: f64,
    /// Deep-contact updates.
    pub deep_sum: u64,
}

impl RowSums {
    /// Adds a window.
    fn add(mut self, red: &Reductions) -> Self {
        let n = red.steps as f64;
        if self.wall_force_steps.len() < red.wall_force.len() {
            self.wall_force_steps.resize(red.wall_force.len(), DVec2::ZERO);
        }
        for (a, f) in self.wall_force_steps.iter_mut().zip(&red.wall_force) {
            *a += *f * n;
        }
        self.steps += red.steps;
        self.iterations_sum += red.iterations_sum;
        self.iterations_max = self.iterations_max.max(red.iterations_max);
        self.capped_steps += red.capped_steps;
        self.colors_steps += red.colors_mean * n;
        self.deep_sum += red.deep_sum;
        self
    }
}

/// The reductions of the windows summed in `sums` followed by `last`, as one window: the
/// averages over all their steps, the rest from `last`. Without earlier windows, `last`
/// itself (the same bits as before rows could span windows).
fn merged(sums: Option<&RowSums>, last: &Reductions) -> Reductions {
    let Some(sums) = sums else {
        return last.clone();
    };
    let all = sums.clone().add(last);
    let steps = all.steps.max(1) as f64;
    Reductions {
        steps: all.steps,
        wall_force: all.wall_force_steps.iter().map(|f| *f / steps).collect(),
        iterations_sum: all.iterations_sum,
        iterations_max: all.iterations_max,
        capped_steps: all.capped_steps,
        colors_mean: all.colors_steps / steps,
        deep_sum: all.deep_sum,
        ..last.clone()
    }
}

/// A biaxial test in progress on a backend.
pub struct Lab<B: Backend> {
    /// The backend that steps the sample.
    pub backend: B,
    /// The protocol state.
    pub state: LabState,
    reference: Vec<DVec2>,
}

impl<B: Backend> Lab<B> {
    /// Starts at compaction from a freshly deposited scene (see
    /// [`super::prepare::deposit_scene`]), or at confinement from a compacted one.
    pub fn new(mut backend: B, params: ProtocolParams, scene: &Scene, compacted: bool) -> Result<Self> {
        params.validate()?;
        backend.set_scene(scene)?;
        let r_min = scene.disks.radius.iter().cloned().fold(f64::INFINITY, f64::min);
        let mean_mass = scene.disks.mass.iter().sum::<f64>() / scene.disks.len().max(1) as f64;
        let state = LabState::new(
            params,
            Loading {
                top: walls::TOP,
                bottom: walls::BOTTOM,
                ..Default::default()
            },
            Gauge {
                top: walls::TOP,
                bottom: walls::BOTTOM,
                r_min,
                mean_mass,
                disk_area: scene
                    .disks
                    .radius
                    .iter()
                    .map(|r| std::f64::consts::PI * r * r)
                    .sum(),
                ..Default::default()
            },
            scene.time,
        );
        let mut lab = Lab {
            backend,
            state,
            reference: Vec::new(),
        };
        if compacted {
            lab.enter_confinement()?;
        } else {
            let mut s = lab.backend.scene()?;
            s.material.mu_disk = lab.state.params.mu_compaction;
            s.material.mu_wall = lab.state.params.mu_compaction;
            lab.backend.set_scene(&s)?;
        }
        Ok(lab)
    }

    /// Continues from a checkpoint.
    pub fn resume(mut backend: B, ck: Checkpoint) -> Result<Self> {
        ck.state.params.validate()?;
        backend.set_scene(&ck.scene)?;
        backend.set_warm_start(&ck.warm)?;
        if let Some(o) = ck.origin {
            backend.start_pair_list_from(o)?;
        }
        Ok(Lab {
            backend,
            state: ck.state,
            reference: ck.reference,
        })
    }

    /// Runs every remaining phase. A stop requested by a signal ([`crate::interrupt`]) ends
    /// the run after the current window of steps with a checkpoint, as
    /// [`Error::Interrupted`].
    pub fn run(&mut self, obs: &mut dyn Observer) -> Result<()> {
        self.run_until(obs, &crate::interrupt::Cancel::with_signals())
    }

    /// [`Lab::run`], stopped by `cancel` instead of by the process's signals alone.
    pub fn run_until(&mut self, obs: &mut dyn Observer, cancel: &crate::interrupt::Cancel) -> Result<()> {
        while self.state.phase != Phase::Done {
            self.advance(obs)?;
            if let Some(signal) = cancel.requested()
                && self.state.phase != Phase::Done
            {
                // The phase cut short has its account too.
                if let Some(text) = self.backend.activity() {
                    obs.activity(self.state.phase, &text)?;
                }
                let step = self.checkpoint(obs)?;
                return Err(Error::Interrupted { signal, step });
            }
        }
        Ok(())
    }

    /// Runs one window of steps of the current phase and handles its outcome (a series row,
    /// maybe a phase change, a snapshot, a checkpoint). In compression the window ends at
    /// the next row, strip refresh, quasi-static check or the end strain, whichever comes
    /// first (see the module documentation).
    pub fn advance(&mut self, obs: &mut dyn Observer) -> Result<()> {
        let p = self.state.params.clone();
        self.refresh_strips()?;
        let steps = match self.state.phase {
            Phase::Compression => self.compression_window()?,
            _ => p.equilibrium.window,
        };
        let red = self.backend.run(steps, &self.state.loading)?;
        self.state.since_checkpoint = self.state.since_checkpoint.saturating_add(steps);
        self.state.since_strips = self.state.since_strips.saturating_add(steps);
        match self.state.phase {
            Phase::Compaction => {
                let h = self.state.gauge.height(&red);
                let applied = p.sigma_c * h;
                let pushed = red.wall_force[walls::RIGHT].x;
                let mut row = self.row(&red, 0.0, 0.0);
                row.width_m = red.wall_point[walls::RIGHT].x - red.wall_point[walls::LEFT].x;
                row.sigma1_pa = red.wall_force[walls::TOP].y / row.width_m;
                let row = row.with_micro(&red.micro);
                obs.series(&row)?;
                self.state.loading.wall_forces = vec![(walls::RIGHT, applied)];
                if self.settle(&red, p.sigma_c, applied, pushed, [h, row.width_m], obs)? {
                    self.snapshot(0.0, obs)?;
                    self.enter_confinement()?;
                }
            }
            Phase::Confinement => {
                let w = self.state.gauge.width(&red);
                let applied = p.sigma3 * w;
                let row = self.row(&red, p.sigma3, 0.0);
                obs.series(&row)?;
                let pushed = red.wall_force[walls::TOP].y;
                self.state.loading.wall_forces = vec![(walls::TOP, applied)];
                let shape = [self.state.gauge.height(&red), w];
                if self.settle(&red, p.sigma3, applied, pushed, shape, obs)? {
                    // The state the compression starts from: axial strain 0.
                    self.snapshot(0.0, obs)?;
                    self.enter_compression(&red)?;
                }
            }
            Phase::Compression => {
                let s = &mut self.state;
                s.since_series = s.since_series.saturating_add(steps);
                s.since_guard = s.since_guard.saturating_add(steps);
                let whole = merged(s.row_sums.as_ref(), &red);
                let row = self.row(&whole, p.sigma3, p.axial_velocity);
                self.state.strain = Some(row.strain_axial);
                let reached = row.strain_axial >= p.strain_end;
                // A block of the derived results ends at each quasi-static check and at the
                // end: the windows always end there, whatever the series interval.
                let guard = if self.state.since_guard >= QUASI_STATIC_CHECK_EVERY || reached {
                    let block = merged(self.state.block_sums.take().as_ref(), &red);
                    let block = self.row(&block, p.sigma3, p.axial_velocity);
                    if let Some(d) = &mut self.state.derived {
                        d.push(&block);
                    }
                    if self.state.since_guard >= QUASI_STATIC_CHECK_EVERY {
                        self.state.since_guard = 0;
                        self.check_quasi_static(&red, &block)
                    } else {
                        Ok(())
                    }
                } else {
                    self.state.block_sums = Some(self.state.block_sums.take().unwrap_or_default().add(&red));
                    Ok(())
                };
                // The last row of a run, however it ends, is always written.
                if self.state.since_series >= p.series_every || reached || guard.is_err() {
                    obs.series(&row)?;
                    self.state.since_series = 0;
                    self.state.row_sums = None;
                    guard?;
                    // The final state always has its snapshot, whatever the interval.
                    let periodic = p.snapshot_every > 0.0 && row.strain_axial >= self.state.next_snapshot;
                    if periodic || reached {
                        self.snapshot(row.strain_axial, obs)?;
                    }
                    if periodic {
                        while self.state.next_snapshot <= row.strain_axial {
                            self.state.next_snapshot += p.snapshot_every;
                        }
                    }
                } else {
                    self.state.row_sums = Some(self.state.row_sums.take().unwrap_or_default().add(&red));
                }
                if reached {
                    let kinetic = self.kinetic_ratio(&red, p.sigma3);
                    self.end_phase(&red, true, 0.0, kinetic, obs)?;
                    self.state.phase = Phase::Done;
                }
            }
            Phase::Done => {}
        }
        if self.state.since_checkpoint >= p.checkpoint_every || self.state.phase == Phase::Done {
            self.checkpoint(obs)?;
        }
        Ok(())
    }

    /// The steps of the next compression window: up to the next row, strip refresh or
    /// quasi-static check, and short of the step predicted to reach the end strain (the
    /// top wall moves `axial_velocity * dt` per step), so that the windows then go one step
    /// at a time and the test stops at the first step that reaches it.
    fn compression_window(&mut self) -> Result<u32> {
        let s = &self.state;
        let p = &s.params;
        let mut w = p.series_every.saturating_sub(s.since_series);
        w = w.min(QUASI_STATIC_CHECK_EVERY.saturating_sub(s.since_guard));
        if p.strip_refresh_every > 0 && !s.loading.strip.is_empty() {
            w = w.min(p.strip_refresh_every.saturating_sub(s.since_strips));
        }
        let strain = match s.strain {
            Some(e) => e,
            None => {
                let scene = self.backend.scene()?;
                let h = scene.walls[walls::TOP].point.y - scene.walls[walls::BOTTOM].point.y;
                (self.state.gauge.h0 - h) / self.state.gauge.h0
            }
        };
        let p = &self.state.params;
        let per_step = p.axial_velocity * p.step.dt / self.state.gauge.h0;
        let left = ((p.strain_end - strain) / per_step).ceil();
        // NaN (a degenerate gauge) leaves the other bounds in charge.
        if left.is_finite() {
            let short = if left > 1.0 { left - 1.0 } else { 1.0 };
            w = w.min(short.min(u32::MAX as f64) as u32);
        }
        Ok(w.max(1))
    }

    /// Hands the current state to `obs` as a snapshot at axial strain `strain`.
    fn snapshot(&mut self, strain: f64, obs: &mut dyn Observer) -> Result<()> {
        let scene = self.backend.scene()?;
        let contacts = self.backend.contacts()?;
        obs.snapshot(strain, &scene, &contacts, &self.reference)
    }

    /// Recomputes which disks form the strips once `strip_refresh_every` steps have passed
    /// since the last time, so that the strips stay along the sides as the sample deforms.
    fn refresh_strips(&mut self) -> Result<()> {
        let every = self.state.params.strip_refresh_every;
        if every == 0 || self.state.loading.strip.is_empty() || self.state.since_strips < every {
            return Ok(());
        }
        // A disk that leaves a strip loses its share of the confinement with the next step
        // (the backends zero the forces of free disks outside the strips); one that kept
        // it would go on pushing into the sample for good.
        let t = self.state.params.strip_thickness;
        self.state.loading.strip = self.backend.strip_members(walls::BOTTOM, walls::TOP, t)?;
        self.state.since_strips = 0;
        Ok(())
    }

    /// The kinetic ratio of the equilibrium criteria: the connected disks' kinetic energy
    /// over `sigma` times the disk area ([`super::Equilibrium::kinetic_ratio`]).
    fn kinetic_ratio(&self, red: &Reductions, sigma: f64) -> f64 {
        red.connected_energy / (sigma * self.state.gauge.disk_area)
    }

    /// Stops a compression that has left the quasi-static regime, after its row is
    /// recorded. With strips fixed as sets of disks, samples at contact friction 0.01 lost
    /// their confinement (the strips sank into the sample) and ran on to negative widths
    /// and kinetic energies of 1e11 J/m until an overlap limit ended them, with rows that
    /// looked like results; the strips now follow the sides
    /// ([`crate::backend::reduce::strip_members`]) and this guard stays as a net.
    /// The ratio is the row's `K / (sigma3 h w)`, as the summary's `kinetic_ratio_max`;
    /// a sample without a positive area fails it.
    fn check_quasi_static(&self, red: &Reductions, row: &SeriesRow) -> Result<()> {
        let p = &self.state.params;
        let kinetic = row.kinetic_ratio();
        let limit = p.equilibrium.runaway_kinetic_ratio;
        if kinetic <= limit {
            return Ok(());
        }
        Err(Error::Numerical {
            step: red.step,
            message: format!(
                "the compression is no longer quasi-static at axial strain {:.4}: kinetic \
                 ratio {kinetic:.3e} (limit equilibrium.runaway_kinetic_ratio = {limit:e}), \
                 sigma1 {:.3} MPa against sigma3 {:.3} MPa, sample {:.2} m wide and {:.2} m \
                 high. The sample has probably lost its confinement: check that \
                 test.strip_refresh_every is not 0 (fixed strips sink into samples of low \
                 friction) and that the strips are several disks thick",
                row.strain_axial,
                row.sigma1_pa / 1e6,
                p.sigma3 / 1e6,
                row.width_m,
                row.height_m
            ),
        })
    }

    fn row(&self, red: &Reductions, sigma3: f64, v: f64) -> SeriesRow {
        self.state.gauge.row(red, self.state.phase.name(), sigma3, v)
    }

    /// Checks the equilibrium criteria after a window, given the sample's height and width
    /// (m); ends the phase when they hold or when the phase has lasted `max_time`.
    fn settle(
        &mut self,
        red: &Reductions,
        sigma: f64,
        applied: f64,
        pushed: f64,
        [height, width]: [f64; 2],
        obs: &mut dyn Observer,
    ) -> Result<bool> {
        let eq = self.state.params.equilibrium;
        let imbalance = (pushed - applied).abs() / applied;
        let kinetic = self.kinetic_ratio(red, sigma);
        let threshold = match self.state.phase {
            Phase::Compaction => eq.compaction_kinetic_ratio,
            _ => eq.kinetic_ratio,
        };
        let shape = &mut self.state.shape;
        shape.push([red.time, height, width]);
        if shape.len() > 2 * super::CREEP_WINDOWS {
            shape.remove(0);
        }
        let creep = super::creep_rate(shape);
        obs.settling(&super::Settling {
            phase: self.state.phase,
            time_s: red.time,
            phase_time_s: red.time - self.state.phase_start,
            kinetic_ratio: kinetic,
            kinetic_threshold: threshold,
            imbalance,
            imbalance_limit: eq.force_imbalance,
            creep,
            creep_limit: eq.creep_rate,
            max_time_s: eq.max_time,
        })?;
        let still = creep.is_some_and(|c| c < eq.creep_rate);
        let settled = (kinetic < threshold || still) && imbalance < eq.force_imbalance;
        let timeout = red.time - self.state.phase_start >= eq.max_time;
        if settled || timeout {
            self.end_phase(red, settled, imbalance, kinetic, obs)?;
            return Ok(true);
        }
        Ok(false)
    }

    fn end_phase(
        &mut self,
        red: &Reductions,
        settled: bool,
        imbalance: f64,
        kinetic: f64,
        obs: &mut dyn Observer,
    ) -> Result<()> {
        let end = PhaseEnd {
            phase: self.state.phase,
            time_s: red.time,
            step: red.step,
            settled,
            kinetic_ratio: kinetic,
            force_imbalance: imbalance,
            creep_rate: super::creep_rate(&self.state.shape),
        };
        self.state.shape.clear();
        obs.phase_end(&end)?;
        if let Some(text) = self.backend.activity() {
            obs.activity(end.phase, &text)?;
        }
        self.state.ends.push(end);
        self.state.phase_start = red.time;
        Ok(())
    }

    /// Removes the side walls, forms the strips and the bumpy walls, sets friction and the
    /// force-driven top wall.
    fn enter_confinement(&mut self) -> Result<()> {
        let p = self.state.params.clone();
        let mut s = self.backend.scene()?;
        s.walls[walls::LEFT].active = false;
        s.walls[walls::RIGHT].active = false;
        s.walls[walls::RIGHT].drive = WallDrive::Kinematic;
        s.walls[walls::RIGHT].vel = DVec2::ZERO;
        s.material.mu_disk = p.mu;
        s.material.mu_wall = p.mu_wall;
        s.material.e_n = p.e_n;
        s.material.e_t = p.e_t;
        let n = s.disks.len();
        let r_min = self.state.gauge.r_min;
        // Bumpy walls: the first layer of disks touching the top and the bottom wall.
        let touch = 0.01 * r_min;
        for k in 0..n {
            let (x, r) = (s.disks.pos[k], s.disks.radius[k]);
            for w in [walls::BOTTOM, walls::TOP] {
                if s.disks.glued_to[k] == NOT_GLUED && s.walls[w].distance(x) - r <= touch {
                    s.disks.glue(k, w);
                }
            }
        }
        // Counted after gluing, over every glued disk: a prepared sample arrives with its
        // bumpy walls already glued.
        let top_mass: f64 = (0..n)
            .filter(|&k| s.disks.glued_to[k] == walls::TOP as u32)
            .map(|k| s.disks.mass[k])
            .sum();
        if top_mass == 0.0 || !s.disks.glued_to.contains(&(walls::BOTTOM as u32)) {
            return Err(Error::Other(
                "no disk touches the top or bottom wall after compaction: the sample is not confined".into(),
            ));
        }
        // Strips: free disks whose centre lies within the strip thickness of the sample's
        // outer edge on either side.
        let x_l = (0..n)
            .map(|k| s.disks.pos[k].x - s.disks.radius[k])
            .fold(f64::INFINITY, f64::min);
        let x_r = (0..n)
            .map(|k| s.disks.pos[k].x + s.disks.radius[k])
            .fold(f64::NEG_INFINITY, f64::max);
        let t = p.strip_thickness;
        if x_r - x_l <= 2.0 * t + 2.0 * p.r_max {
            return Err(Error::invalid(
                "test.strip_thickness",
                t,
                &format!(
                    "two strips must leave a core between them: the sample is {:.2} m wide",
                    x_r - x_l
                ),
            ));
        }
        let strip = strip_members(&s, walls::BOTTOM, walls::TOP, t);
        self.state.since_strips = 0;
        let g = &mut self.state.gauge;
        g.w_ref = x_r - x_l;
        let height = s.walls[walls::TOP].point.y - s.walls[walls::BOTTOM].point.y;
        let applied = p.sigma3 * g.w_ref;
        s.walls[walls::TOP].drive = WallDrive::Force {
            mass: top_mass,
            force: applied,
        };
        s.walls[walls::TOP].vel = DVec2::ZERO;
        s.walls[walls::BOTTOM].vel = DVec2::ZERO;
        self.state.loading = Loading {
            sigma3: p.sigma3,
            strip,
            top: walls::TOP,
            bottom: walls::BOTTOM,
            wall_forces: vec![(walls::TOP, applied)],
        };
        debug_assert!(height > 0.0);
        self.backend.set_scene(&s)?;
        self.state.phase = Phase::Confinement;
        self.state.phase_start = s.time;
        Ok(())
    }

    /// Switches the top wall to displacement control and records the reference state.
    fn enter_compression(&mut self, red: &Reductions) -> Result<()> {
        let p = &self.state.params;
        let mut s = self.backend.scene()?;
        s.walls[walls::TOP].drive = WallDrive::Kinematic;
        s.walls[walls::TOP].vel = DVec2::new(0.0, -p.axial_velocity);
        let g = &mut self.state.gauge;
        g.h0 = g.height(red);
        g.w0 = g.width(red);
        self.reference = s.disks.pos.clone();
        self.state.loading.wall_forces.clear();
        self.backend.set_scene(&s)?;
        self.state.phase = Phase::Compression;
        self.state.phase_start = s.time;
        // The end of the confinement gave the snapshot at strain 0.
        self.state.next_snapshot = p.snapshot_every;
        self.state.since_series = 0;
        self.state.since_guard = 0;
        self.state.row_sums = None;
        self.state.block_sums = None;
        self.state.derived = Some(crate::measure::derived::DerivedCurve::new(p.sigma3));
        self.state.strain = Some(0.0);
        Ok(())
    }

    /// Records a checkpoint and returns its step.
    fn checkpoint(&mut self, obs: &mut dyn Observer) -> Result<u64> {
        let scene = self.backend.scene()?;
        let warm = self.backend.contacts()?;
        // Reset before encoding: a resumed run counts to its next checkpoint as the
        // uninterrupted run does.
        self.state.since_checkpoint = 0;
        let origin = self.backend.pair_list_origin()?;
        let bytes = encode(&self.state, &scene, &self.reference, &warm, origin.as_ref());
        obs.checkpoint(scene.step, &bytes)?;
        Ok(scene.step)
    }
}
