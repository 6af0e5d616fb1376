//! Scene builders shared by the integration tests.
#![allow(dead_code)]

use cdlab::engine::{CpuEngine, StepParams};
use cdlab::model::{Material, Scene, Wall};
use cdlab::solver::{Method, SolverParams};
use glam::DVec2;

/// Density of the paper's grains (kg/m^3).
pub const RHO: f64 = 2600.0;

/// Step parameters with a tight tolerance, so closed-form checks see round-off, not the
/// solver's stopping error.
pub fn tight(method: Method) -> StepParams {
    StepParams {
        dt: 5e-4,
        theta: 0.5,
        alert: 0.01,
        overlap_limit: 0.05,
        solver: SolverParams {
            method,
            tol: 1e-12,
            max_iter: 20_000,
            jacobi: cdlab::solver::JacobiSettings { relax: 0.5 },
            parallel: true,
            parallel_min: cdlab::solver::default_parallel_min(),
            threads: 0,
            gauss_seidel: cdlab::solver::GaussSeidelSettings {
                relax: cdlab::solver::default_gs_relax(),
                relax_after: cdlab::solver::default_gs_relax_after(),
            },
            velocity_tol: 0.0,
            open_skip: 0.0,
            deep_gap: 0.0,
            deep_sweeps: 0,
            anderson: cdlab::solver::AndersonSettings {
                depth: cdlab::solver::default_anderson_depth(),
            },
            check_every: 0,
        },
    }
}

/// The built-in step parameters (those of the default configuration, as a run gets them),
/// with `method`: the closed forms' twins at the settings users run.
pub fn builtin(method: Method) -> StepParams {
    let mut p = cdlab::Config::with_disks(1).protocol().step;
    p.solver.method = method;
    p
}

/// An engine with `tight` parameters.
pub fn engine(method: Method) -> CpuEngine {
    CpuEngine::new(tight(method)).expect("valid parameters")
}

/// An empty scene with the given friction between disks and with walls.
pub fn scene(mu: f64) -> Scene {
    Scene {
        material: Material {
            mu_disk: mu,
            mu_wall: mu,
            e_n: 0.0,
            e_t: 0.0,
        },
        ..Default::default()
    }
}

/// A floor at y = 0 (inward normal +y).
pub fn floor() -> Wall {
    Wall::fixed(DVec2::ZERO, DVec2::Y)
}

/// A column of `n` disks of radius `r` on the floor under gravity `g` (m/s^2), the two
/// lowest overlapping by 1% of `r`, the others touching (the deep-contact tests).
pub fn sunk_column(n: usize, r: f64, g: f64) -> Scene {
    let mut s = scene(0.3);
    s.gravity = DVec2::new(0.0, -g);
    s.walls.push(floor());
    for k in 0..n {
        let y = r + 2.0 * r * k as f64 - if k == 0 { 0.0 } else { 0.01 * r };
        s.disks.push(DVec2::new(0.0, y), r, RHO).unwrap();
    }
    s
}

/// A column of `n` touching disks of radius `r` standing on the floor, friction 0.3, with
/// gravity `g` (m/s^2, downwards) and, when `top_force` is given, a force-driven top wall
/// of mass 1e4 kg/m touching the highest disk and pushing down with that force (N/m): a
/// statically determinate chain (the statics tests).
pub fn column(n: usize, r: f64, g: f64, top_force: Option<f64>) -> Scene {
    let mut s = scene(0.3);
    s.gravity = DVec2::new(0.0, -g);
    s.walls.push(floor());
    if let Some(force) = top_force {
        s.walls.push(Wall {
            drive: cdlab::model::WallDrive::Force { mass: 1.0e4, force },
            ..Wall::fixed(DVec2::new(0.0, 2.0 * r * n as f64), -DVec2::Y)
        });
    }
    for k in 0..n {
        s.disks
            .push(DVec2::new(0.0, r + 2.0 * r * k as f64), r, RHO)
            .expect("valid disk");
    }
    s
}

/// A small deterministic generator (SplitMix64) so tests need no external crate.
pub struct Rng(pub u64);

impl Rng {
    /// Next value uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
}

/// A loose random cloud of `nx * ny` disks on a jittered lattice (no overlaps), radii in
/// [0.5, 1] m, random velocities up to `speed` m/s and spins up to `speed` rad/s.
pub fn cloud(nx: usize, ny: usize, speed: f64, seed: u64) -> Scene {
    let mut rng = Rng(seed);
    let mut s = scene(0.3);
    let pitch = 2.2;
    for a in 0..nx {
        for b in 0..ny {
            let r = rng.range(0.5, 1.0);
            let jitter = (pitch / 2.0 - r).max(0.0);
            let x = a as f64 * pitch + rng.range(-jitter, jitter);
            let y = b as f64 * pitch + rng.range(-jitter, jitter);
            let k = s.disks.push(DVec2::new(x, y), r, RHO).expect("valid disk");
            s.disks.vel[k] = DVec2::new(rng.range(-speed, speed), rng.range(-speed, speed));
            s.disks.spin[k] = rng.range(-speed, speed);
        }
    }
    s
}

/// Adds four fixed walls around the box [x0, x1] x [y0, y1].
pub fn add_box(s: &mut Scene, x0: f64, x1: f64, y0: f64, y1: f64) {
    s.walls.push(Wall::fixed(DVec2::new(0.0, y0), DVec2::Y));
    s.walls.push(Wall::fixed(DVec2::new(0.0, y1), -DVec2::Y));
    s.walls.push(Wall::fixed(DVec2::new(x0, 0.0), DVec2::X));
    s.walls.push(Wall::fixed(DVec2::new(x1, 0.0), -DVec2::X));
}

/// Total linear momentum of the free disks (kg m/s per m).
pub fn momentum(s: &Scene) -> DVec2 {
    let d = &s.disks;
    (0..d.len()).map(|k| d.mass[k] * d.vel[k]).sum()
}

/// Total angular momentum about the origin (kg m^2/s per m): orbital plus spin.
pub fn angular_momentum(s: &Scene) -> f64 {
    let d = &s.disks;
    (0..d.len())
        .map(|k| {
            let m = d.mass[k];
            let r = d.radius[k];
            m * d.pos[k].perp_dot(d.vel[k]) + 0.5 * m * r * r * d.spin[k]
        })
        .sum()
}

/// Runs the `cdlab` binary; returns success and stdout + stderr.
pub fn cdlab(args: &[&str]) -> (bool, String) {
    cdlab_with_env(args, &[])
}

/// [`cdlab`] with environment variables set for the command.
pub fn cdlab_with_env(args: &[&str], env: &[(&str, &str)]) -> (bool, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args(args)
        .envs(env.iter().copied())
        .output()
        .expect("cdlab runs");
    outcome(&out)
}

/// `cdlab biaxial --config CONFIG [EXTRA...] --out OUT --quiet`.
pub fn biaxial(config: &std::path::Path, out: &std::path::Path, extra: &[&str]) -> (bool, String) {
    let mut args = vec!["biaxial", "--config", config.to_str().unwrap()];
    args.extend_from_slice(extra);
    args.extend(["--out", out.to_str().unwrap(), "--quiet"]);
    cdlab(&args)
}

/// Whether a finished command succeeded, and its stdout followed by its stderr.
pub fn outcome(out: &std::process::Output) -> (bool, String) {
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

/// A small, quick configuration: 400 disks, thin strips, 0.6% strain, frequent checkpoints.
pub fn small_config(dir: &std::path::Path) -> std::path::PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let p = dir.join("small.toml");
    std::fs::write(
        &p,
        "[sample]\ndisks = 400\n[solver]\ntol = 1e-3\nbackend = \"cpu\"\n\
         [test]\nstrip_thickness = \"3 m\"\nstrain_end = 0.006\n\
         [output]\nseries_every = 10\nsnapshot_every = 0.003\ncheckpoint_every = 500\n",
    )
    .unwrap();
    p
}

/// Asserts that the runs in directories `a` and `b` ended with the same outcome, bit for
/// bit: peak, final strains and step count of their `summary.json` (what a resumed run must
/// share with the uninterrupted one on the CPU path).
pub fn assert_same_outcome(a: &std::path::Path, b: &std::path::Path) {
    let read = |d: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join("summary.json")).unwrap()).unwrap()
    };
    let (a, b) = (read(a), read(b));
    for key in [
        "sigma1_peak_mpa",
        "strain_peak",
        "volumetric_strain_final",
        "strain_final",
        "steps",
    ] {
        assert_eq!(a[key], b[key], "{key}");
    }
}

/// Runs `cdlab ARGS`; once the CSV file `series` holds `rows` lines (the run is then under
/// way, its signal handler installed) stops it (SIGSTOP), calls `meanwhile`, sends it
/// `signal` and lets it go on (SIGCONT), then returns what it printed and how it ended.
///
/// No step of the run can pass between the rows appearing and the signal, however long
/// `meanwhile` takes and however fast or loaded the machine: the process is frozen, and the
/// signal is handled when it wakes. The only timing left is the 300 s guard, which fails the
/// test if the rows never come.
#[cfg(unix)]
pub fn signal_after_rows(
    args: &[&str],
    series: &std::path::Path,
    rows: usize,
    meanwhile: impl FnOnce(),
    signal: i32,
) -> std::process::Output {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("cdlab runs");
    let pid = child.id() as i32;
    let lines = || std::fs::read_to_string(series).map_or(0, |s| s.lines().count());
    let t0 = std::time::Instant::now();
    while lines() < rows {
        assert!(
            t0.elapsed().as_secs() < 300,
            "{} holds no {rows} rows after 300 s",
            series.display()
        );
        if let Some(status) = child.try_wait().expect("cdlab can be waited for") {
            panic!(
                "cdlab ended ({status}) before {} held {rows} rows",
                series.display()
            );
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    // SAFETY: kill() with a valid pid and signal number has no memory effects here.
    assert_eq!(unsafe { libc::kill(pid, libc::SIGSTOP) }, 0);
    // A stopped child is not "exited": waitpid(WNOHANG) without WUNTRACED reports nothing.
    assert!(
        child.try_wait().expect("cdlab can be waited for").is_none(),
        "cdlab ended before it could be stopped"
    );
    meanwhile();
    // SAFETY: as above.
    assert_eq!(unsafe { libc::kill(pid, signal) }, 0);
    // SAFETY: as above.
    assert_eq!(unsafe { libc::kill(pid, libc::SIGCONT) }, 0);
    child.wait_with_output().expect("cdlab ends")
}
