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
        self.apply_wall_forces(scene);
        if self.strip.is_empty() || self.sigma3 == 0.0 {
            return;
        }
        let h = scene.walls[self.top].point.y - scene.walls[self.bottom].point.y;
        let total = self.sigma3 * h;
        let d = &mut scene.disks;
        let mut sum_r = [0.0f64; 2];
        for (k, &s) in self.strip.iter().enumerate() {
            if s != 0 {
                sum_r[(s > 0) as usize] += d.radius[k];
            }
        }
        for (k, &s) in self.strip.iter().enumerate() {
            if s != 0 {
                let side = (s > 0) as usize;
                d.force[k] = DVec2::new(-(s as f64) * total * d.radius[k] / sum_r[side], 0.0);
            } else if d.kind[k] == crate::model::BodyKind::Free {
                d.force[k] = DVec2::ZERO;
            }
        }
    }
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
