//! The CPU reference backend: a [`CpuEngine`] and the scene it steps.

use super::reduce::Accumulator;
use super::{Backend, ContactRecord, Loading, Reductions};
use crate::contact::detect::ListOrigin;
use crate::engine::{CpuEngine, StepParams};
use crate::error::Result;
use crate::model::Scene;

/// The CPU backend (f64, bit-reproducible).
#[derive(Clone, Debug)]
pub struct CpuBackend {
    engine: CpuEngine,
    scene: Scene,
}

impl CpuBackend {
    /// A backend holding `scene`, stepping with `params`.
    pub fn new(scene: Scene, params: StepParams) -> Result<Self> {
        scene.validate()?;
        Ok(CpuBackend {
            engine: CpuEngine::new(params)?,
            scene,
        })
    }

    /// The scene, without copying it.
    pub fn scene_ref(&self) -> &Scene {
        &self.scene
    }

    /// The engine (contacts of the last step, color ranges).
    pub fn engine(&self) -> &CpuEngine {
        &self.engine
    }

    /// The engine, to change what it keeps (e.g. [`CpuEngine::capture`]).
    pub fn engine_mut(&mut self) -> &mut CpuEngine {
        &mut self.engine
    }
}

impl Backend for CpuBackend {
    fn name(&self) -> String {
        // The sweeps run on the solver's team (rayon serves only Jacobi), and the team
        // engages from `parallel_min` contacts on.
        let solver = &self.engine.params.solver;
        let threads = match solver.team_size() {
            1 => "1 thread".to_string(),
            n => format!("team of {n} threads from {} contacts", solver.parallel_min),
        };
        if solver.method == crate::solver::Method::ColoredGs {
            format!("cpu ({threads}; {})", crate::solver::sweep::colored_lanes())
        } else {
            format!("cpu ({threads})")
        }
    }

    fn params(&self) -> StepParams {
        self.engine.params
    }

    fn set_params(&mut self, params: StepParams) -> Result<()> {
        params.validate()?;
        self.engine.params = params;
        Ok(())
    }

    fn set_scene(&mut self, scene: &Scene) -> Result<()> {
        scene.validate()?;
        if scene.disks.len() != self.scene.disks.len() || scene.walls.len() != self.scene.walls.len() {
            self.engine.reset_warm_start();
        }
        self.scene = scene.clone();
        Ok(())
    }

    fn scene(&mut self) -> Result<Scene> {
        Ok(self.scene.clone())
    }

    fn strip_members(&mut self, bottom: usize, top: usize, thickness: f64) -> Result<Vec<i8>> {
        Ok(super::reduce::strip_members(&self.scene, bottom, top, thickness))
    }

    fn contacts(&mut self) -> Result<Vec<ContactRecord>> {
        let dt = self.engine.params.dt;
        let gap_tol = super::reduce::zero_gap_tolerance(&self.scene);
        Ok(self
            .engine
            .contacts()
            .iter()
            .map(|c| ContactRecord::new(c, dt, gap_tol))
            .collect())
    }

    fn set_warm_start(&mut self, contacts: &[ContactRecord]) -> Result<()> {
        self.engine.set_warm_start(
            contacts
                .iter()
                .map(|c| (((c.i as u64) << 32) | c.j as u64, c.rn, c.rt)),
        );
        Ok(())
    }

    fn pair_list_origin(&mut self) -> Result<Option<ListOrigin>> {
        Ok(self.engine.pair_list_origin(&self.scene))
    }

    fn start_pair_list_from(&mut self, origin: ListOrigin) -> Result<()> {
        self.engine.start_pair_list_from(origin);
        Ok(())
    }

    fn run(&mut self, steps: u32, loading: &Loading) -> Result<Reductions> {
        let mut acc = Accumulator::new(&self.scene);
        // A step changes neither the disks' radii nor their kinds, so the strips' shares
        // hold for the whole run, and the forces cleared at its first step stay zero.
        let shares = loading.strip_shares(&self.scene);
        for step in 0..steps {
            loading.apply_shares(&mut self.scene, &shares);
            if step == 0 {
                loading.clear_outside_strips(&mut self.scene, &shares);
            }
            let stats = self.engine.step(&mut self.scene)?;
            acc.add_step(&stats, self.engine.wall_impulses());
        }
        Ok(acc.finish(
            &self.scene,
            self.engine.contacts(),
            self.engine.params.dt,
            loading,
        ))
    }
}
