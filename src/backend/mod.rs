//! The interface the loading protocol talks to. A backend holds a scene, advances it by
//! steps under a [`Loading`], and hands back only reduced quantities ([`Reductions`]);
//! full states and contact lists are downloaded on demand (snapshots, checkpoints).
//! The protocol never knows which backend runs.

pub mod cpu;
pub mod reduce;

use glam::DVec2;

use crate::contact::detect::ListOrigin;
use crate::engine::StepParams;
use crate::error::Result;
use crate::model::Scene;

pub use cpu::CpuBackend;
pub use reduce::{ContactClass, Reductions};

/// External loads recomputed by the backend at every step.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Loading {
    /// Confining stress carried by each deformable-wall strip (Pa); 0 disables the strips.
    pub sigma3: f64,
    /// Strip of each disk: -1 left strip (pushed towards +x), +1 right strip (pushed towards
    /// -x), 0 none. Empty when there are no strips.
    pub strip: Vec<i8>,
    /// Index of the top wall (the sample height is its distance to the bottom wall).
    pub top: usize,
    /// Index of the bottom wall.
    pub bottom: usize,
    /// Force (N/m) applied along its normal to every force-driven wall listed here, as
    /// `(wall, force)`; set by the protocol from the current sample width.
    pub wall_forces: Vec<(usize, f64)>,
}

impl Loading {
    /// Sets the force of every force-driven wall listed in `wall_forces`.
    pub fn apply_wall_forces(&self, scene: &mut Scene) {
        for &(w, f) in &self.wall_forces {
            if let crate::model::WallDrive::Force { force, .. } = &mut scene.walls[w].drive {
                *force = f;
            }
        }
    }

    /// Sets the strip forces of `scene` for the current height: each strip carries
    /// `sigma3 * H` (N/m), shared among its disks in proportion to their radius (so that
    /// large and small disks carry the same pressure over their diameter), applied at the
    /// centres, horizontally, towards the sample. While the strips are on they are the only
    /// forces on free disks: a free disk outside them (one that has left a strip) carries
    /// none. Without strips, forces are left alone.
    pub fn apply(&self, scene: &mut Scene) {
        let shares = self.strip_shares(scene);
        self.apply_shares(scene, &shares);
        self.clear_outside_strips(scene, &shares);
    }

    /// Zeroes the force of every free disk outside the strips while the strips are on
    /// (`shares` from [`Self::strip_shares`]): the part of [`Self::apply`] that a run of
    /// steps, which changes no disk's kind, needs once.
    pub(crate) fn clear_outside_strips(&self, scene: &mut Scene, shares: &[StripShare]) {
        if shares.is_empty() {
            return;
        }
        let d = &mut scene.disks;
        for (k, &s) in self.strip.iter().enumerate() {
            if s == 0 && d.kind[k] == crate::model::BodyKind::Free {
                d.force[k] = DVec2::ZERO;
            }
        }
    }

    /// Each strip disk's share of its strip's force, for [`Self::apply_shares`]: empty
    /// when the strips are off. It depends on the strips and the disks' radii only, so a
    /// run of steps that changes neither works it out once.
    pub(crate) fn strip_shares(&self, scene: &Scene) -> Vec<StripShare> {
        if self.strip.is_empty() || self.sigma3 == 0.0 {
            return Vec::new();
        }
        let d = &scene.disks;
        let mut sum_r = [0.0f64; 2];
        for (k, &s) in self.strip.iter().enumerate() {
            if s != 0 {
                sum_r[(s > 0) as usize] += d.radius[k];
            }
        }
        (self.strip.iter().enumerate())
            .filter(|(_, s)| **s != 0)
            .map(|(k, &s)| StripShare {
                disk: k as u32,
                sign: -(s as f64),
                sum_r: sum_r[(s > 0) as usize],
            })
            .collect()
    }

    /// The wall forces and the strip disks' forces for the current height, from `shares`
    /// ([`Self::strip_shares`] of the same disks). Unlike [`Self::apply`] it leaves the
    /// other disks' forces alone: a run of steps calls it at every step and
    /// [`Self::clear_outside_strips`] once (a pass over every disk each step cost about 2%
    /// of a 5000-disk compression step).
    pub(crate) fn apply_shares(&self, scene: &mut Scene, shares: &[StripShare]) {
        self.apply_wall_forces(scene);
        if shares.is_empty() {
            return;
        }
        let h = scene.walls[self.top].point.y - scene.walls[self.bottom].point.y;
        let total = self.sigma3 * h;
        let d = &mut scene.disks;
        for s in shares {
            let k = s.disk as usize;
            d.force[k] = DVec2::new(s.sign * total * d.radius[k] / s.sum_r, 0.0);
        }
    }
}

/// A strip disk's part of [`Loading::apply`]: its force is `sign * sigma3 * H * radius /
/// sum_r` along x, `radius` the disk's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct StripShare {
    disk: u32,
    /// +1 for the left strip (pushed towards +x), -1 for the right one.
    sign: f64,
    /// The sum of the radii of the disk's strip (m).
    sum_r: f64,
}

/// One contact as downloaded for a snapshot (forces in N/m).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ContactRecord {
    /// Disk i.
    pub i: u32,
    /// Partner: a disk index, or `n_disks + wall`.
    pub j: u32,
    /// Normal, from j to i.
    pub n: DVec2,
    /// Gap at the start of the step (m).
    pub gap: f64,
    /// Normal impulse (N s/m), kept exactly for warm starts after a resume.
    pub rn: f64,
    /// Tangential impulse (N s/m).
    pub rt: f64,
    /// Normal force `R_n / dt` (N/m).
    pub f_n: f64,
    /// Tangential force `R_t / dt` (N/m).
    pub f_t: f64,
    /// Class (force-carrying rolling or sliding, zero-force, open).
    pub class: ContactClass,
}

impl ContactRecord {
    /// The record of a solver contact after a step of length `dt`; `gap_tol` is the
    /// zero-force gap tolerance ([`reduce::zero_gap_tolerance`]).
    pub fn new(c: &crate::contact::Contact, dt: f64, gap_tol: f64) -> Self {
        ContactRecord {
            i: c.i,
            j: c.disk_j,
            n: c.n,
            gap: c.gap,
            rn: c.rn,
            rt: c.rt,
            f_n: c.rn / dt,
            f_t: c.rt / dt,
            class: reduce::classify(c, gap_tol),
        }
    }
}

/// A time stepper the protocol can drive.
pub trait Backend {
    /// Human-readable name (backend and adapter).
    fn name(&self) -> String;
    /// The time stepping parameters in force.
    fn params(&self) -> StepParams;
    /// Changes the time stepping parameters (validated). A new time step must come with
    /// the tolerances derived from it: set it with [`StepParams::set_dt`].
    fn set_params(&mut self, params: StepParams) -> Result<()>;
    /// Replaces the state (an upload on a device). Warm-start impulses are kept when the
    /// bodies are the same.
    fn set_scene(&mut self, scene: &Scene) -> Result<()>;
    /// Downloads the full state.
    fn scene(&mut self) -> Result<Scene>;
    /// Downloads the contacts of the last step.
    fn contacts(&mut self) -> Result<Vec<ContactRecord>>;
    /// Replaces the warm-start impulses by those of `contacts` (as downloaded by
    /// [`Backend::contacts`]): with the scene, this restores a checkpoint exactly.
    fn set_warm_start(&mut self, contacts: &[ContactRecord]) -> Result<()>;
    /// Where the CPU's kept pair list was built, when its next step keeps it
    /// ([`crate::engine::CpuEngine::pair_list_origin`]): a checkpoint holds it, so that a
    /// resumed run builds the same list and goes on bit for bit. `None` for backends
    /// without one.
    fn pair_list_origin(&mut self) -> Result<Option<ListOrigin>> {
        Ok(None)
    }
    /// Makes the next step build the kept pair list at `origin` (from a checkpoint);
    /// backends without one ignore it.
    fn start_pair_list_from(&mut self, origin: ListOrigin) -> Result<()> {
        let _ = origin;
        Ok(())
    }
    /// Advances `steps` steps, recomputing the loads each step, and returns the reductions
    /// (wall forces averaged over the steps; counts and energies of the last step).
    fn run(&mut self, steps: u32, loading: &Loading) -> Result<Reductions>;
    /// Which disks form the deformable-wall strips of the current state: -1 left, +1 right,
    /// 0 neither, as [`reduce::strip_members`] says of the scene (walls `bottom` and `top`
    /// bound the heights, `thickness` in m). A backend that holds the state elsewhere may
    /// find them there (the GPU's reads back a word per disk, not the scene); its answer
    /// may differ from the scene's only for a disk within its rounding of a strip's
    /// inner boundary.
    fn strip_members(&mut self, bottom: usize, top: usize, thickness: f64) -> Result<Vec<i8>> {
        Ok(reduce::strip_members(&self.scene()?, bottom, top, thickness))
    }
    /// Where the time went since the last call, in one line for the user (the GPU: windows
    /// run and run again, the host's recording and waiting, the device's own time), or
    /// `None` where there is nothing to say (the CPU path).
    fn activity(&mut self) -> Option<String> {
        None
    }
}

/// A boxed backend is a backend: the CLI picks CPU or GPU at run time.
impl<B: Backend + ?Sized> Backend for Box<B> {
    fn name(&self) -> String {
        (**self).name()
    }
    fn params(&self) -> StepParams {
        (**self).params()
    }
    fn set_params(&mut self, params: StepParams) -> Result<()> {
        (**self).set_params(params)
    }
    fn set_scene(&mut self, scene: &Scene) -> Result<()> {
        (**self).set_scene(scene)
    }
    fn scene(&mut self) -> Result<Scene> {
        (**self).scene()
    }
    fn contacts(&mut self) -> Result<Vec<ContactRecord>> {
        (**self).contacts()
    }
    fn set_warm_start(&mut self, contacts: &[ContactRecord]) -> Result<()> {
        (**self).set_warm_start(contacts)
    }
    fn pair_list_origin(&mut self) -> Result<Option<ListOrigin>> {
        (**self).pair_list_origin()
    }
    fn start_pair_list_from(&mut self, origin: ListOrigin) -> Result<()> {
        (**self).start_pair_list_from(origin)
    }
    fn run(&mut self, steps: u32, loading: &Loading) -> Result<Reductions> {
        (**self).run(steps, loading)
    }
    fn activity(&mut self) -> Option<String> {
        (**self).activity()
    }
    fn strip_members(&mut self, bottom: usize, top: usize, thickness: f64) -> Result<Vec<i8>> {
        (**self).strip_members(bottom, top, thickness)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{BodyKind, Wall};

    /// Twelve disks of three sizes: four in each strip, four outside (one of them fixed),
    /// between a bottom wall and a top wall 10 m above it, every force set to garbage.
    fn strips() -> (Scene, Loading) {
        let mut s = Scene::default();
        let mut strip = Vec::new();
        for k in 0..12 {
            let r = [0.3, 0.45, 0.7][k % 3];
            s.disks
                .push(DVec2::new(k as f64, 1.0 + 0.5 * k as f64), r, 2600.0)
                .unwrap();
            s.disks.force[k] = DVec2::new(1.0 + k as f64, -2.0);
            strip.push([-1i8, 0, 1][k % 3]);
        }
        s.disks.set_kind(4, BodyKind::Fixed);
        s.walls = vec![
            Wall::fixed(DVec2::ZERO, DVec2::Y),
            Wall::fixed(DVec2::new(0.0, 10.0), -DVec2::Y),
        ];
        let loading = Loading {
            sigma3: 8e6,
            strip,
            bottom: 0,
            top: 1,
            ..Default::default()
        };
        (s, loading)
    }

    #[test]
    fn a_run_of_steps_sets_the_forces_apply_sets() {
        let (mut once, l) = strips();
        l.apply(&mut once);
        // Each strip carries sigma3 H = 8e7 N/m shared by radius: the left strip's disks
        // (k = 0, 3, 6, 9; radius 0.3 each) carry a quarter of it towards +x.
        assert_eq!(once.disks.force[0], DVec2::new(2e7, 0.0));
        assert_eq!(once.disks.force[1], DVec2::ZERO, "a free disk outside the strips");
        assert_eq!(
            once.disks.force[4],
            DVec2::new(5.0, -2.0),
            "a fixed disk keeps its force"
        );
        let right: f64 = [2, 5, 8, 11].iter().map(|&k| once.disks.force[k].x).sum();
        assert!(
            (right + 8e7).abs() < 1e-6 * 8e7,
            "the right strip's total {right} N/m"
        );
        // Later steps of a run: the top wall has moved, the strips' forces are stale.
        let shares = l.strip_shares(&once);
        let mut run = once.clone();
        for s in [&mut once, &mut run] {
            s.walls[1].point.y = 9.37;
        }
        for k in [0, 2, 3, 5] {
            run.disks.force[k] = DVec2::splat(f64::NAN);
        }
        l.apply(&mut once);
        l.apply_shares(&mut run, &shares);
        for (k, (a, b)) in once.disks.force.iter().zip(&run.disks.force).enumerate() {
            assert_eq!(
                (a.x.to_bits(), a.y.to_bits()),
                (b.x.to_bits(), b.y.to_bits()),
                "disk {k}"
            );
        }
        assert_ne!(
            once.disks.force[0],
            DVec2::new(2e7, 0.0),
            "the height entered the force"
        );
    }

    #[test]
    fn without_strips_the_shares_are_empty_and_forces_stay() {
        let (mut s, mut l) = strips();
        l.sigma3 = 0.0;
        assert!(l.strip_shares(&s).is_empty());
        l.apply(&mut s);
        assert_eq!(s.disks.force[1], DVec2::new(2.0, -2.0));
    }
}
