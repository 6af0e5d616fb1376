//! The CPU reference time stepper (Moreau-Jean theta scheme), phase by phase:
//! free velocities, cell grid and contact detection with warm start, coloring, sweeps,
//! integration. Every phase has a twin kernel in `shaders/`.

use glam::{DVec2, DVec3};

use crate::contact::Contact;
use crate::contact::detect::{ListOrigin, Neighbours};
use crate::error::{Error, Result, check_non_negative, check_positive, check_range};
use crate::model::{BodyKind, NOT_GLUED, Scene, WallDrive};
use crate::solver::captured::Captured;
use crate::solver::{Method, SolveStats, SolverParams, sweep};

/// Parameters of the time stepping.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StepParams {
    /// Time step (s).
    pub dt: f64,
    /// Theta of the scheme, in [0.5, 1].
    pub theta: f64,
    /// Alert distance (m): pairs closer than this become candidate contacts.
    pub alert: f64,
    /// Largest overlap tolerated (m) before the run stops with a diagnostic.
    pub overlap_limit: f64,
    /// The contact solver.
    pub solver: SolverParams,
}

impl StepParams {
    /// Sets the time step and derives again the solver's tolerances that are velocities
    /// made from it: the configuration gives [`SolverParams::velocity_tol`] and
    /// [`SolverParams::open_skip`] as lengths per step (fractions of `r_min`) and divides
    /// them by `dt`, so a new `dt` keeps the lengths and changes the velocities. Assigning
    /// `dt` alone would keep velocities meant for the old step.
    pub fn set_dt(&mut self, dt: f64) {
        let scale = self.dt / dt;
        if scale.is_finite() {
            self.solver.velocity_tol *= scale;
            self.solver.open_skip *= scale;
        }
        self.dt = dt;
    }

    /// Rejects dt <= 0, theta outside [0.5, 1], negative distances and bad solver settings.
    pub fn validate(&self) -> Result<()> {
        check_positive("solver.dt", self.dt)?;
        crate::protocol::limits::check_time_step("solver.dt", self.dt)?;
        check_range("solver.theta", self.theta, 0.5, 1.0)?;
        check_non_negative("solver.alert", self.alert)?;
        check_positive("solver.overlap_limit", self.overlap_limit)?;
        self.solver.validate()
    }
}

/// What one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepStats {
    /// The solver's iterations, convergence and colors.
    pub solve: SolveStats,
    /// Candidate contacts (within the alert distance).
    pub contacts: usize,
    /// Largest overlap at the start of the step (m, >= 0).
    pub max_overlap: f64,
    /// Wall time of the sweeps alone (s), for the cost per contact update.
    pub solve_seconds: f64,
    /// Wall time of the whole step (s).
    pub step_seconds: f64,
}

/// Wall time of a CPU step's phases (s), summed over the steps counted (`steps`): what
/// `cdlab bench` reports as the fixed part of a step (everything but `sweeps`) and how it
/// grows with the sample (docs/benchmarks.md, "Sample size").
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct PhaseTimes {
    /// Steps counted.
    pub steps: u64,
    /// Contact detection: the kept pair list (rebuilt on the grid when stale) and the
    /// contact records, with their start-of-step values (relative velocities, law offsets,
    /// warm start), filled in as each record is made.
    pub detect: f64,
    /// The bodies' start-of-step and free velocities, and the overlap check.
    pub contacts: f64,
    /// The solver's setup: rows, parking, coloring, color order, vector packing.
    pub setup: f64,
    /// The solver's iterations (a whole solve for methods other than Gauss-Seidel).
    pub sweeps: f64,
    /// Deep contacts: finding them and their local updates.
    pub deep: f64,
    /// The impulses written back to the contacts.
    pub store: f64,
    /// Finite-velocity check, integration, warm-start list and wall impulses.
    pub integrate: f64,
}

impl PhaseTimes {
    /// Everything but the sweeps (s).
    pub fn fixed(&self) -> f64 {
        self.detect + self.contacts + self.setup + self.deep + self.store + self.integrate
    }

    /// The times since `earlier` (a copy taken from the same engine).
    pub fn since(&self, earlier: &PhaseTimes) -> PhaseTimes {
        PhaseTimes {
            steps: self.steps - earlier.steps,
            detect: self.detect - earlier.detect,
            contacts: self.contacts - earlier.contacts,
            setup: self.setup - earlier.setup,
            sweeps: self.sweeps - earlier.sweeps,
            deep: self.deep - earlier.deep,
            store: self.store - earlier.store,
            integrate: self.integrate - earlier.integrate,
        }
    }
}

/// The CPU backend's stepper. It owns the contact list between steps (warm start) and the
/// scratch buffers, so a step allocates nothing once sizes settle.
#[derive(Clone, Debug)]
pub struct CpuEngine {
    /// Time stepping parameters.
    pub params: StepParams,
    contacts: Vec<Contact>,
    /// Warm-start impulses given by [`Self::set_warm_start`] for the next step, by key;
    /// otherwise the kept list carries each contact's impulses from step to step.
    warm: Option<Vec<(u64, f64, f64)>>,
    neighbours: Neighbours,
    gv_minus: Vec<DVec3>,
    gv0: Vec<DVec3>,
    gv: Vec<DVec3>,
    work: sweep::Workspace,
    wall_impulse: Vec<DVec2>,
    /// The contact problem of the last step, kept when capture is on ([`Self::capture`]).
    captured: Option<Box<Captured>>,
    /// Where the steps' time went, summed since the engine was made.
    times: PhaseTimes,
}

impl CpuEngine {
    /// A stepper with validated parameters.
    pub fn new(params: StepParams) -> Result<Self> {
        params.validate()?;
        Ok(CpuEngine {
            params,
            contacts: Vec::new(),
            warm: None,
            neighbours: Neighbours::default(),
            gv_minus: Vec::new(),
            gv0: Vec::new(),
            gv: Vec::new(),
            work: sweep::Workspace::default(),
            wall_impulse: Vec::new(),
            captured: None,
            times: PhaseTimes::default(),
        })
    }

    /// The contacts of the last step, with their impulses: in key order ([`Contact::key`]),
    /// or for colored Gauss-Seidel by color ([`Self::color_ranges`]) and then key.
    pub fn contacts(&self) -> &[Contact] {
        &self.contacts
    }

    /// Color ranges of the last step's swept rows (`ranges[c]..ranges[c+1]`), empty unless
    /// colored. The rows are the contacts in their order, less the open candidates left
    /// out of the sweeps ([`crate::solver::SolverParams::open_skip`]).
    pub fn color_ranges(&self) -> &[u32] {
        &self.work.coloring().ranges
    }

    /// Indices of the swept rows sorted by color (the order of the colored sweeps) when the
    /// solver colored them itself; empty when they came colored from the kept list (the
    /// engine's own steps), or unless colored.
    pub fn color_order(&self) -> &[u32] {
        &self.work.coloring().order
    }

    /// True when the last color range of the last step was a serial group (the contacts
    /// of force-driven walls, see [`crate::solver::color::color`]).
    pub fn last_range_is_serial(&self) -> bool {
        self.work.coloring().serial_last
    }

    /// Replaces the warm-start impulses by `(key, R_n, R_t)` triples (see [`Contact::key`]).
    pub fn set_warm_start(&mut self, impulses: impl Iterator<Item = (u64, f64, f64)>) {
        let mut warm: Vec<_> = impulses.filter(|e| e.1 > 0.0).collect();
        warm.sort_unstable_by_key(|e| e.0);
        self.warm = Some(warm);
    }

    /// Where the steps' time went, summed over every step of this engine.
    pub fn phase_times(&self) -> PhaseTimes {
        self.times
    }

    /// Where the kept pair list (and its coloring) was built, if the next step keeps it:
    /// with the scene and the contacts' impulses, what a checkpoint needs for a resumed
    /// run to go on bit for bit as this one ([`Neighbours::origin`]).
    pub fn pair_list_origin(&self, scene: &Scene) -> Option<ListOrigin> {
        let p = &self.params;
        self.neighbours
            .origin(scene, p.alert, skin(p), p.solver.method == Method::ColoredGs)
    }

    /// Makes the next step build the kept pair list at `origin` (from a checkpoint).
    pub fn start_pair_list_from(&mut self, origin: ListOrigin) {
        self.neighbours.start_from(origin);
    }

    /// Forgets the warm-start impulses (e.g. after the scene was edited by hand).
    pub fn reset_warm_start(&mut self) {
        self.warm = Some(Vec::new());
    }

    /// Keeps (or stops keeping) a copy of each step's contact problem as the solver
    /// receives it, for solver studies ([`Captured`]); off by default, as it copies every
    /// contact each step.
    pub fn capture(&mut self, on: bool) {
        self.captured = on.then(Box::default);
    }

    /// The contact problem of the last step, when capture is on and a step ran.
    pub fn captured(&self) -> Option<&Captured> {
        self.captured.as_deref().filter(|c| !c.gv0.is_empty())
    }

    /// Advances `scene` by one step.
    pub fn step(&mut self, scene: &mut Scene) -> Result<StepStats> {
        let p = self.params;
        let (dt, theta) = (p.dt, p.theta);
        let t0 = std::time::Instant::now();
        follow_walls(scene);
        let t_contacts = std::time::Instant::now();
        self.velocities(scene);
        let t_detect = std::time::Instant::now();
        let colored = p.solver.method == Method::ColoredGs;
        let warm = self.warm.take();
        self.gv.clone_from(&self.gv0);
        let mut prepare = Prepare {
            gv: &mut self.gv,
            e_n: scene.material.e_n,
            e_t: scene.material.e_t,
            dt,
            theta,
            worst: None,
            deepest: 0.0,
        };
        self.neighbours
            .detect_kept(
                scene,
                p.alert,
                skin(&p),
                colored,
                warm.as_deref(),
                &mut self.contacts,
                &self.gv_minus,
                |k, c, vi, vj| prepare.contact(k, c, vi, vj),
            )
            .map_err(|e| at_step(e, scene.step))?;
        let worst = prepare.worst;
        let max_overlap = self.check_overlap(worst, scene)?;
        if let Some(c) = self.captured.as_deref_mut() {
            c.contacts.clone_from(&self.contacts);
            c.gv0.clone_from(&self.gv0);
            c.gv.clone_from(&self.gv);
        }
        let t_solve = std::time::Instant::now();
        let given = colored.then(|| sweep::Colors {
            ranges: self.neighbours.contact_ranges(),
            serial_last: self.neighbours.serial_last(),
        });
        if matches!(p.solver.method, Method::Gs | Method::ColoredGs) {
            // The figures the records were made from, so that the table and the rows agree.
            self.work
                .give_bodies(self.neighbours.disk_figures(), scene.walls.len());
        }
        let solve = sweep::solve(
            &p.solver,
            &mut self.contacts,
            &self.gv0,
            &mut self.gv,
            &mut self.work,
            given,
        );
        let t_integrate = std::time::Instant::now();
        let solve_seconds = (t_integrate - t_solve).as_secs_f64();
        self.check_finite(scene)?;
        self.integrate(scene, dt, theta);
        self.remember_impulses(scene.disks.len(), scene.walls.len());
        scene.time += dt;
        scene.step += 1;
        let w = self.work.times();
        let t = &mut self.times;
        t.steps += 1;
        t.detect += (t_solve - t_detect).as_secs_f64();
        t.contacts += (t_detect - t_contacts).as_secs_f64();
        t.setup += w.setup;
        t.deep += w.deep;
        t.store += w.store;
        t.sweeps += solve_seconds - w.setup - w.deep - w.store;
        t.integrate += t_integrate.elapsed().as_secs_f64();
        Ok(StepStats {
            solve,
            contacts: self.contacts.len(),
            max_overlap,
            solve_seconds,
            step_seconds: t0.elapsed().as_secs_f64(),
        })
    }

    /// The largest overlap (m), given the index of the most overlapping contact, or an
    /// error when it exceeds the limit.
    fn check_overlap(&self, worst: Option<usize>, scene: &Scene) -> Result<f64> {
        let Some(w) = worst.map(|k| &self.contacts[k]) else {
            return Ok(0.0);
        };
        if -w.gap > self.params.overlap_limit {
            return Err(Error::Numerical {
                step: scene.step,
                message: format!(
                    "overlap {:.3e} m between disk {} and {} exceeds the limit {:.3e} m. {}",
                    -w.gap,
                    w.i,
                    body_name(scene, w.disk_j as usize),
                    self.params.overlap_limit,
                    overlap_advice(self.params.solver.max_iter)
                ),
            });
        }
        Ok(-w.gap)
    }

    /// Fills `gv_minus` (start-of-step velocities), `gv0` (free velocities) for every body.
    fn velocities(&mut self, scene: &Scene) {
        let d = &scene.disks;
        let dt = self.params.dt;
        self.gv_minus.clear();
        self.gv0.clear();
        for k in 0..d.len() {
            let v = DVec3::new(d.vel[k].x, d.vel[k].y, d.spin[k]);
            self.gv_minus.push(v);
            let free = if d.kind[k] == BodyKind::Free {
                let acc = d.force[k] * d.inv_mass[k] + scene.gravity;
                v + dt * DVec3::new(acc.x, acc.y, d.torque[k] * d.inv_inertia[k])
            } else {
                v
            };
            self.gv0.push(free);
        }
        for w in &scene.walls {
            self.gv_minus.push(w.vel.extend(0.0));
            let free = match w.drive {
                WallDrive::Kinematic => w.vel,
                WallDrive::Force { mass, force } => w.vel + w.normal * (dt * force / mass),
            };
            self.gv0.push(free.extend(0.0));
        }
    }

    fn check_finite(&self, scene: &Scene) -> Result<()> {
        if let Some(k) = self.gv.iter().position(|v| !v.is_finite()) {
            let culprit = self
                .contacts
                .iter()
                .find(|c| c.i as usize == k || c.j as usize == k);
            return Err(Error::Numerical {
                step: scene.step,
                message: format!(
                    "non-finite velocity {} of {}{}",
                    self.gv[k],
                    body_name(scene, k),
                    culprit.map_or(String::new(), |c| format!(
                        " (contact between disk {} and {}, R_n {:e}, R_t {:e})",
                        c.i,
                        body_name(scene, c.disk_j as usize),
                        c.rn,
                        c.rt
                    ))
                ),
            });
        }
        Ok(())
    }

    fn integrate(&mut self, scene: &mut Scene, dt: f64, theta: f64) {
        let nd = scene.disks.len();
        let d = &mut scene.disks;
        for k in 0..nd {
            let (vm, vp) = (self.gv_minus[k], self.gv[k]);
            match d.kind[k] {
                BodyKind::Fixed => {}
                BodyKind::Kinematic if d.glued_to[k] != NOT_GLUED => {
                    // Glued disks move exactly as their wall does (a force-driven wall's
                    // velocity changes during the step), so they never drift from it.
                    let w = nd + d.glued_to[k] as usize;
                    let (wm, wp) = (self.gv_minus[w], self.gv[w]);
                    d.pos[k] += dt * ((1.0 - theta) * wm + theta * wp).truncate();
                    d.vel[k] = wp.truncate();
                }
                BodyKind::Kinematic => {
                    d.pos[k] += dt * vm.truncate();
                    d.theta[k] += dt * vm.z;
                }
                BodyKind::Free => {
                    let v = (1.0 - theta) * vm + theta * vp;
                    d.pos[k] += dt * v.truncate();
                    d.theta[k] += dt * v.z;
                    d.vel[k] = vp.truncate();
                    d.spin[k] = vp.z;
                }
            }
        }
        for (w, wall) in scene.walls.iter_mut().enumerate() {
            let (vm, vp) = (self.gv_minus[nd + w].truncate(), self.gv[nd + w].truncate());
            wall.point += dt * ((1.0 - theta) * vm + theta * vp);
            wall.vel = vp;
        }
    }

    /// Keeps the impulses of the step in the kept list for the next one's warm start and
    /// sums the impulses on each wall.
    fn remember_impulses(&mut self, nd: usize, n_walls: usize) {
        self.wall_impulse.clear();
        self.wall_impulse.resize(n_walls, DVec2::ZERO);
        let walls = &mut self.wall_impulse;
        self.neighbours.keep_impulses(&self.contacts, |c| {
            let j = c.j as usize;
            if j >= nd {
                let t = crate::contact::tangent(c.n);
                walls[j - nd] -= c.rn * c.n + c.rt * t;
            }
        });
    }

    /// Total impulse exerted on each wall by the contacts of the last step (N s/m),
    /// including the contacts of the disks glued to it. Divide by dt for the force.
    pub fn wall_impulses(&self) -> &[DVec2] {
        &self.wall_impulse
    }
}

/// What a step does to each contact as detection makes it: start-of-step velocities, law
/// offsets and warm start, leaving in `gv` the free velocities plus the warm-start
/// impulses; and it finds the contact with the largest overlap.
struct Prepare<'a> {
    gv: &'a mut [DVec3],
    e_n: f64,
    e_t: f64,
    dt: f64,
    theta: f64,
    worst: Option<usize>,
    deepest: f64,
}

impl Prepare<'_> {
    #[inline]
    fn contact(&mut self, k: usize, c: &mut Contact, vi: DVec3, vj: DVec3) {
        if c.gap < self.deepest {
            self.deepest = c.gap;
            self.worst = Some(k);
        }
        let (un, ut) = c.relative_velocity_of(vi, vj);
        c.un0 = un;
        c.ut0 = ut;
        c.bias_n = normal_bias(c.gap, un, self.theta, self.dt, self.e_n);
        c.bias_t = self.e_t * ut;
        // Detection gave each contact the impulses its pair kept from the last step.
        if c.rn > 0.0 {
            c.rt = c.rt.clamp(-c.mu * c.rn, c.mu * c.rn);
            c.apply(self.gv, c.rn, c.rt);
        }
    }
}

/// The margin of the kept pair list (m): twice the alert distance, so that the list is
/// rebuilt after a disk has moved one alert distance, every few hundred steps at the
/// test's velocities.
fn skin(p: &StepParams) -> f64 {
    2.0 * p.alert
}

/// Glued disks take their wall's velocity and stop spinning before the step.
fn follow_walls(scene: &mut Scene) {
    let d = &mut scene.disks;
    for k in 0..d.len() {
        let g = d.glued_to[k];
        if g != NOT_GLUED {
            d.vel[k] = scene.walls[g as usize].vel;
            d.spin[k] = 0.0;
        }
    }
}

fn at_step(e: Error, step: u64) -> Error {
    match e {
        Error::Numerical { message, .. } => Error::Numerical { step, message },
        other => other,
    }
}

/// What to do about an overlap above the limit. Overlaps are never pushed apart
/// (docs/method.md, "Overlaps"), so they grow from steps that end unconverged; at high
/// contact friction these are mostly the steps that reach the iteration cap
/// (docs/results.md, "Overlaps at high friction").
pub fn overlap_advice(max_iter: u32) -> String {
    format!(
        "Overlaps persist once made and grow from steps that end unconverged, mostly those \
         that reach the iteration cap (solver.max_iter = {max_iter}; high contact friction \
         needs thousands of iterations per step): raise it, or tighten the solver \
         tolerance, or reduce the time step or the loading rate"
    )
}

/// "disk 12" or "wall 3" for a generalized body index.
pub fn body_name(scene: &Scene, k: usize) -> String {
    let nd = scene.disks.len();
    if k < nd {
        format!("disk {k}")
    } else {
        format!("wall {}", k - nd)
    }
}

/// The offset `bias_n` of a contact's normal law for a step, from its gap and its
/// start-of-step normal velocity `un` (WGSL twin: `normal_bias` in shaders/common.wgsl,
/// compared by tests/gpu_kernels.rs).
///
/// An open gap (`gap > 0`) may close during the step but not beyond: the shift is
/// `max(0, (gap + (1 - theta) dt un) / (theta dt))`. A gap the start velocity alone would
/// already close gets no negative shift (that would push the disks apart and inject
/// energy). A closed gap gets the Newton restitution offset `e_n min(un, 0)`.
#[inline]
pub fn normal_bias(gap: f64, un: f64, theta: f64, dt: f64, e_n: f64) -> f64 {
    if gap > 0.0 {
        ((gap + (1.0 - theta) * dt * un) / (theta * dt)).max(0.0)
    } else {
        e_n * un.min(0.0)
    }
}
