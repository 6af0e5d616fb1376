//! The driver of a biaxial test: compaction, confinement, compression, with series rows,
//! snapshots and checkpoints handed to an [`Observer`].

use glam::DVec2;

use super::checkpoint::{Checkpoint, encode};
use super::{LabState, Observer, Phase, PhaseEnd, ProtocolParams, walls};
use crate::backend::reduce::strip_members;
use crate::backend::{Backend, Loading, Reductions};
use crate::error::{Error, Result};
use crate::measure::{Gauge, SeriesRow};
use crate::model::{NOT_GLUED, Scene, WallDrive};

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
        let state = LabState {
            phase: Phase::Compaction,
            loading: Loading {
                top: walls::TOP,
                bottom: walls::BOTTOM,
                ..Default::default()
            },
            gauge: Gauge {
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
            phase_start: scene.time,
            next_snapshot: 0.0,
            since_checkpoint: 0,
            ends: Vec::new(),
            since_strips: 0,
            params,
        };
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
        while self.state.phase != Phase::Done {
            self.advance(obs)?;
            if let Some(signal) = crate::interrupt::requested()
                && self.state.phase != Phase::Done
            {
                let step = self.checkpoint(obs)?;
                return Err(Error::Interrupted { signal, step });
            }
        }
        Ok(())
    }

    /// Runs one window of steps of the current phase and handles its outcome (a series row,
    /// maybe a phase change, a snapshot, a checkpoint).
    pub fn advance(&mut self, obs: &mut dyn Observer) -> Result<()> {
        let p = self.state.params.clone();
        let steps = match self.state.phase {
            Phase::Compression => p.series_every,
            _ => p.equilibrium.window,
        };
        self.refresh_strips()?;
        let red = self.backend.run(steps, &self.state.loading)?;
        self.state.since_checkpoint += steps;
        self.state.since_strips += steps;
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
                if self.settle(&red, p.sigma_c, applied, pushed, obs)? {
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
                if self.settle(&red, p.sigma3, applied, pushed, obs)? {
                    self.enter_compression(&red)?;
                }
            }
            Phase::Compression => {
                let row = self.row(&red, p.sigma3, p.axial_velocity);
                obs.series(&row)?;
                self.check_quasi_static(&red, &row)?;
                if p.snapshot_every > 0.0 && row.strain_axial >= self.state.next_snapshot {
                    let scene = self.backend.scene()?;
                    let contacts = self.backend.contacts()?;
                    obs.snapshot(row.strain_axial, &scene, &contacts, &self.reference)?;
                    while self.state.next_snapshot <= row.strain_axial {
                        self.state.next_snapshot += p.snapshot_every;
                    }
                }
                if row.strain_axial >= p.strain_end {
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
        let s = self.backend.scene()?;
        let t = self.state.params.strip_thickness;
        self.state.loading.strip = strip_members(&s, walls::BOTTOM, walls::TOP, t);
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

    /// Checks the equilibrium criteria after a window; ends the phase when they hold or
    /// when the phase has lasted `max_time`.
    fn settle(
        &mut self,
        red: &Reductions,
        sigma: f64,
        applied: f64,
        pushed: f64,
        obs: &mut dyn Observer,
    ) -> Result<bool> {
        let eq = self.state.params.equilibrium;
        let imbalance = (pushed - applied).abs() / applied;
        let kinetic = self.kinetic_ratio(red, sigma);
        let threshold = match self.state.phase {
            Phase::Compaction => eq.compaction_kinetic_ratio,
            _ => eq.kinetic_ratio,
        };
        let settled = kinetic < threshold && imbalance < eq.force_imbalance;
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
        };
        obs.phase_end(&end)?;
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
        self.state.next_snapshot = 0.0;
        Ok(())
    }

    /// Records a checkpoint and returns its step.
    fn checkpoint(&mut self, obs: &mut dyn Observer) -> Result<u64> {
        let scene = self.backend.scene()?;
        let warm = self.backend.contacts()?;
        let bytes = encode(&self.state, &scene, &self.reference, &warm);
        obs.checkpoint(scene.step, &bytes)?;
        self.state.since_checkpoint = 0;
        Ok(scene.step)
    }
}
