//! Micromechanical measures (`cdlab::measure::micro`, docs/micromechanics.md) on contact
//! sets with closed-form answers, the Love-Weber stress of a box of disks in equilibrium
//! against its walls, the force PDF's normalisation, and the summary's fabric keys through
//! a run's record, `cdlab summarize`, `cdlab archive` and `cdlab fabric`.

mod common;

use cdlab::measure::micro::{Analysis, MicroContact, MicroSums, force_pdf};
use cdlab::model::{Wall, WallDrive};
use cdlab::solver::Method;
use common::*;
use glam::DVec2;
use std::f64::consts::PI;

/// The contacts of a lattice of disks of radius 1/2 at unit spacing along the lattice
/// vectors `a` and `b` (unit length), rotated by `rot`: every pair of neighbours at
/// distance 1, each contact once, normal force `f_n(n)` and no friction.
fn lattice(a: DVec2, b: DVec2, rot: f64, m: i32, f_n: impl Fn(DVec2) -> f64) -> Vec<MicroContact> {
    let r = DVec2::from_angle(rot);
    let mut pos = Vec::new();
    for i in 0..m {
        for j in 0..m {
            pos.push(r.rotate(i as f64 * a + j as f64 * b));
        }
    }
    let mut out = Vec::new();
    for (i, p) in pos.iter().enumerate() {
        for (j, q) in pos.iter().enumerate().skip(i + 1) {
            let l = *p - *q;
            if (l.length() - 1.0).abs() < 1e-9 {
                let n = l.normalize();
                out.push(MicroContact {
                    i: i as u32,
                    j: Some(j as u32),
                    n,
                    f_n: f_n(n),
                    f_t: 0.0,
                    length: l.length(),
                });
            }
        }
    }
    out
}

#[test]
fn square_lattice_fabric_is_isotropic_with_four_fold_orientations() {
    // Contacts along 0 and 90 degrees in equal numbers (m (m - 1) each): phi = I / 2
    // exactly (eigenvalues 1/2 and 1/2), so a_c = 0, whatever the lattice's rotation;
    // the orientation histogram is not uniform (two of 18 bins hold everything), which
    // the second-order measure cannot see: it has 4-fold symmetry.
    for rot in [0.0, 0.3, 1.0] {
        let set = lattice(DVec2::X, DVec2::Y, rot, 8, |_| 1.0);
        assert_eq!(set.len(), 2 * 8 * 7);
        let s = MicroSums::of(&set);
        let phi = s.fabric();
        let (l1, l2) = phi.principal();
        assert!((l1 - 0.5).abs() < 1e-12 && (l2 - 0.5).abs() < 1e-12, "{l1} {l2}");
        assert!(s.a_c().abs() < 1e-12, "a_c {}", s.a_c());
        assert!(s.a_n().abs() < 1e-12 && s.a_t().abs() < 1e-12);
        // 18 bins, 2 full: those hold 9 times the mean, the others 0.
        assert!(
            (s.rose_max_deviation() - 8.0).abs() < 1e-12,
            "{}",
            s.rose_max_deviation()
        );
    }
    // Vertical forces three times the horizontal ones: chi^n = diag(1, 3) / 4 times the
    // mean, so a_n = 2 (3 - 1) / (3 + 1) = 1 with a_c = 0, along y.
    let set = lattice(DVec2::X, DVec2::Y, 0.0, 8, |n| {
        if n.y.abs() > 0.5 { 3.0 } else { 1.0 }
    });
    let s = MicroSums::of(&set);
    assert!((s.a_n() - 1.0).abs() < 1e-12, "a_n {}", s.a_n());
    assert!((s.fnn.direction() - PI / 2.0).abs() < 1e-12);
    // Strong network: the vertical contacts (force 3 > mean 2), half of them.
    assert!((s.strong_fraction() - 0.5).abs() < 1e-15);
}

#[test]
fn hexagonal_lattice_fabric_is_half_the_identity() {
    // Three directions 60 degrees apart in equal numbers: sum of n n over them is 3/2 I,
    // so phi = I / 2 and a_c = 0, for any rotation; the orientations fill 3 bins of 18.
    let b = DVec2::new(0.5, 3f64.sqrt() / 2.0);
    for rot in [0.05, 0.2, 0.7] {
        let set = lattice(DVec2::X, b, rot, 9, |_| 1.0);
        // Along a and b: 9 x 8 each; along b - a: 8 x 8.
        assert_eq!(set.len(), 2 * 72 + 64);
        // Unequal counts per direction (72, 72, 64) on a finite patch: phi deviates from
        // I / 2 by the deficit, so take the interior's exact answer from equal counts.
        let mut by_dir: [Vec<MicroContact>; 3] = Default::default();
        for c in &set {
            let a = c.orientation() - rot.rem_euclid(PI);
            let k = ((a.rem_euclid(PI) / (PI / 3.0)).round() as usize) % 3;
            by_dir[k].push(*c);
        }
        let equal: Vec<MicroContact> = by_dir.iter().flat_map(|d| d[..64].iter().copied()).collect();
        let s = MicroSums::of(&equal);
        let phi = s.fabric();
        assert!(
            (phi.xx - 0.5).abs() < 1e-12 && phi.xy.abs() < 1e-12 && (phi.yy - 0.5).abs() < 1e-12,
            "{phi:?}"
        );
        assert!(s.a_c() < 1e-12, "a_c {}", s.a_c());
        assert_eq!(s.rose.iter().filter(|&&c| c > 0).count(), 3);
    }
}

#[test]
fn uniformly_spread_normals_have_no_fabric_anisotropy() {
    // N independent uniform orientations: <cos 2 theta> and <sin 2 theta> have standard
    // deviation 1 / sqrt(2N), a_c = 2 |<exp(2 i theta)>| is Rayleigh-distributed with scale
    // 1 / sqrt(N), and exceeds 5 / sqrt(N) with probability exp(-12.5) = 4e-6. The set is
    // seeded, so the test is deterministic; the bound says why it holds.
    let n = 20_000;
    let mut rng = Rng(7);
    let set: Vec<MicroContact> = (0..n)
        .map(|k| {
            let t = rng.range(0.0, 2.0 * PI);
            MicroContact {
                i: k,
                j: Some(k + 1),
                n: DVec2::from_angle(t),
                f_n: rng.range(0.1, 2.0),
                f_t: rng.range(-0.1, 0.1),
                length: 1.0,
            }
        })
        .collect();
    let s = MicroSums::of(&set);
    let bound = 5.0 / (n as f64).sqrt();
    assert!(s.a_c() < bound, "a_c {} bound {bound}", s.a_c());
    // Forces independent of the orientation: a_n and a_t are as small, up to the spread of
    // the forces (a few times the same bound).
    assert!(
        s.a_n().abs() < 3.0 * bound && s.a_t().abs() < 3.0 * bound,
        "{} {}",
        s.a_n(),
        s.a_t()
    );
    // 18 bins of about 1111 contacts: the counts scatter by about 3% (1 / sqrt(1111)).
    assert!(s.rose_max_deviation() < 0.15, "{}", s.rose_max_deviation());
}

#[test]
fn constructed_anisotropic_set_has_its_exact_anisotropy_and_direction() {
    // Directions theta_0 + k pi / 4 with counts 3, 2, 1, 2: sum of exp(2 i (theta -
    // theta_0)) is 3 - 1 + 2 i - 2 i = 2 over 8 contacts, so
    // a_c = 2 |<exp(2 i theta)>| = 1/2 along theta_c = theta_0 (the Fourier density
    // (1 + a_c cos 2 (theta - theta_c)) / pi has <cos 2 (theta - theta_c)> = a_c / 2).
    let theta0 = 20f64.to_radians();
    let mut set = Vec::new();
    for (k, count) in [3, 2, 1, 2].into_iter().enumerate() {
        for _ in 0..count {
            set.push(MicroContact {
                i: 0,
                j: Some(1),
                n: DVec2::from_angle(theta0 + k as f64 * PI / 4.0),
                f_n: 1.0,
                f_t: 0.0,
                length: 1.0,
            });
        }
    }
    let s = MicroSums::of(&set);
    assert!((s.a_c() - 0.5).abs() < 1e-12, "a_c {}", s.a_c());
    assert!(
        (s.theta_c() - theta0).abs() < 1e-12,
        "theta_c {}",
        s.theta_c().to_degrees()
    );
    // Uniform forces: the whole deviator is the fabric's, and the stress-force-fabric
    // estimate (a_c + a_n + a_t) / 2 is exactly q / p of the Love-Weber stress (equal
    // branch lengths).
    let a = Analysis::of(&set, &[0.5, 0.5], 1.0);
    assert!((a.q_over_p - 0.25).abs() < 1e-12 && (a.sff_q_over_p - 0.25).abs() < 1e-12);
}

#[test]
fn force_pdf_integrates_to_one() {
    // An exponential-like set of normal forces, some beyond the histogram's range (they
    // are counted in its last bin): the density times the bin width sums to 1, and its
    // first moment is near <f / <f>> = 1 (binning error of half a bin at most, plus the
    // clipped tail).
    let mut rng = Rng(11);
    let set: Vec<MicroContact> = (0..5000)
        .map(|k| MicroContact {
            i: k,
            j: Some(k + 1),
            n: DVec2::from_angle(rng.range(0.0, PI)),
            f_n: -(1.0 - rng.uniform()).ln() * 1e6,
            f_t: 0.0,
            length: 1.0,
        })
        .collect();
    for bins in [10, 40, 97] {
        let pdf = force_pdf(&set, bins, 6.0);
        let w = 6.0 / bins as f64;
        let total: f64 = pdf.iter().map(|(_, p)| p * w).sum();
        assert!((total - 1.0).abs() < 1e-12, "{bins} bins: {total}");
        let mean: f64 = pdf.iter().map(|(x, p)| x * p * w).sum();
        assert!((mean - 1.0).abs() < 0.5 * w + 0.02, "{bins} bins: mean {mean}");
    }
    assert!(force_pdf(&[], 10, 6.0).is_empty());
}

#[test]
fn love_weber_stress_of_a_box_in_equilibrium_equals_the_wall_stresses() {
    // A random cloud of 36 disks (no gravity) between a fixed left and bottom wall and a
    // force-driven right and top wall pushing with sigma_x h and sigma_y w, the forces
    // updated every step from the box's size. Once settled, sum_c f l over every contact
    // (walls included, branch to the wall) equals F_right w e_x e_x + F_top h e_y e_y up to
    // the disks' residual momentum change (the identity holds exactly in static
    // equilibrium): sigma_LW = (F_right / h, F_top / w) over A = w h.
    let (sx, sy) = (1.0e5, 1.25e5);
    let mut s = cloud(6, 6, 0.0, 3);
    s.material.mu_disk = 0.5;
    s.material.mu_wall = 0.0;
    let (x0, y0, x1, y1) = (-1.2, -1.2, 12.2, 12.2);
    s.walls.push(Wall::fixed(DVec2::new(0.0, y0), DVec2::Y));
    s.walls.push(Wall::fixed(DVec2::new(x0, 0.0), DVec2::X));
    let mass: f64 = s.disks.mass.iter().sum::<f64>() / 6.0;
    for (p, n) in [(DVec2::new(0.0, y1), -DVec2::Y), (DVec2::new(x1, 0.0), -DVec2::X)] {
        s.walls.push(Wall {
            drive: WallDrive::Force { mass, force: 0.0 },
            ..Wall::fixed(p, n)
        });
    }
    let mut params = tight(Method::Gs);
    params.solver.tol = 1e-10;
    params.dt = 1e-3;
    let mut e = cdlab::engine::CpuEngine::new(params).unwrap();
    let size = |s: &cdlab::model::Scene| {
        (
            s.walls[3].point.x - s.walls[1].point.x,
            s.walls[2].point.y - s.walls[0].point.y,
        )
    };
    let mut steps = 0;
    loop {
        let (w, h) = size(&s);
        for (k, f) in [(2, sy * w), (3, sx * h)] {
            if let WallDrive::Force { force, .. } = &mut s.walls[k].drive {
                *force = f;
            }
        }
        e.step(&mut s).unwrap();
        steps += 1;
        let speed = s.disks.vel.iter().map(|v| v.length()).fold(0.0, f64::max);
        if (steps > 200 && speed < 1e-7) || steps >= 6_000 {
            break;
        }
    }
    let speed = s.disks.vel.iter().map(|v| v.length()).fold(0.0, f64::max);
    assert!(speed < 1e-7, "not settled after {steps} steps: {speed} m/s");
    let (w, h) = size(&s);
    let dt = e.params.dt;
    let contacts = cdlab::measure::micro::from_solver(e.contacts(), &s.disks.radius, dt);
    let sums = MicroSums::of(&contacts);
    let lw = sums.love_weber(w * h);
    let imp = e.wall_impulses();
    let (f_right, f_top) = (imp[3].x / dt, imp[2].y / dt);
    // The walls carry the applied forces (the force-driven walls are at rest).
    assert!(
        (f_right / h - sx).abs() < 1e-4 * sx,
        "right wall {} Pa",
        f_right / h
    );
    assert!((f_top / w - sy).abs() < 1e-4 * sy, "top wall {} Pa", f_top / w);
    // Exactly (an algebraic identity over the contact forces, equilibrium or not):
    // sum_c f l = F_right w e_x e_x + F_top h e_y e_y + sum_p (x_p - x_0) F_p, where F_p is
    // the net contact force on disk p and x_0 the corner of the fixed walls. The last term
    // is the solver's residual (zero in exact equilibrium): it sets the tolerance of the
    // comparison with the wall stresses, and must itself be small.
    let corner = DVec2::new(s.walls[1].point.x, s.walls[0].point.y);
    let mut net = vec![DVec2::ZERO; s.disks.len()];
    for c in &contacts {
        net[c.i as usize] += c.force();
        if let Some(j) = c.j {
            net[j as usize] -= c.force();
        }
    }
    let (mut rx, mut ry) = (0.0, 0.0);
    for (p, f) in s.disks.pos.iter().zip(&net) {
        rx += (p.x - corner.x) * f.x;
        ry += (p.y - corner.y) * f.y;
    }
    let (rx, ry) = (rx / (w * h), ry / (w * h));
    for (got, want, residual, name) in [(lw.xx, f_right / h, rx, "xx"), (lw.yy, f_top / w, ry, "yy")] {
        assert!(
            (got - want - residual).abs() < 1e-8 * want,
            "sigma_{name}: Love-Weber {got} Pa, wall {want} Pa, residual {residual} Pa"
        );
        assert!(
            residual.abs() < 1e-3 * want,
            "sigma_{name}: residual {residual} Pa"
        );
        assert!((got - want).abs() <= residual.abs() * (1.0 + 1e-6) + 1e-8 * want);
    }
    // sigma_xy is not compared: with a few point forces on each wall, the moments of the
    // side walls' forces about the box need not cancel (only the sample's torque balance
    // holds), so the boundary's own xy stress is not zero on a sample this small.
}

fn scratch(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("cdlab-micro-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn fabric_keys_round_trip_through_record_summarize_archive_and_fabric() {
    let base = scratch("run");
    let cfg = small_config(&base);
    let out = base.join("t1");
    let (ok, text) = biaxial(&cfg, &out, &[]);
    assert!(ok, "{text}");
    let read = |p: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let summary = read(&out.join("summary.json"));
    let fabric = summary["fabric"].clone();
    for stage in ["after_compaction", "after_confinement", "peak", "end"] {
        for key in [
            "a_c",
            "a_n",
            "a_t",
            "theta_c_deg",
            "lw_sigma1_mpa",
            "strong_fraction",
        ] {
            let v = fabric[stage][key].as_f64();
            assert!(
                v.is_some_and(f64::is_finite),
                "fabric.{stage}.{key} = {:?}",
                fabric[stage][key]
            );
        }
    }
    let hom = fabric["homogeneity_after_compaction_pct"].as_f64().unwrap();
    assert!(hom > 0.0 && hom < 100.0, "homogeneity {hom}%");
    assert_eq!(fabric["homogeneity_bins"], 18);
    // The record's rows hold the same columns: the summary written again from the record
    // is the same.
    let rec = cdlab::record::read_run(&out).unwrap();
    let last = rec.series.last().unwrap();
    assert_eq!(fabric["end"]["a_c"].as_f64().unwrap(), last.a_c);
    assert_eq!(
        fabric["end"]["lw_sigma1_mpa"].as_f64().unwrap(),
        last.lw_sigma1_pa / 1e6
    );
    // In compression the Love-Weber stress over h w is of the order of the boundary
    // stresses (the strips push at the disks' centres, inside the width, and the glued
    // layers' centres are inside the height: a loose check only).
    assert!(
        last.lw_sigma1_pa > 0.5 * last.sigma1_pa && last.lw_sigma1_pa < 1.5 * last.sigma1_pa,
        "{} against {} Pa",
        last.lw_sigma1_pa,
        last.sigma1_pa
    );
    let (ok, text) = cdlab(&["summarize", out.to_str().unwrap()]);
    assert!(ok, "{text}");
    assert_eq!(read(&out.join("summary.json"))["fabric"], fabric, "{text}");
    // Archived: the summary keeps the keys, the thinned series the columns.
    let arch = base.join("archive");
    let (ok, text) = cdlab(&["archive", out.to_str().unwrap(), "--to", arch.to_str().unwrap()]);
    assert!(ok, "{text}");
    assert_eq!(read(&arch.join("t1").join("summary.json"))["fabric"], fabric);
    let thinned = std::fs::read_to_string(arch.join("t1").join(cdlab::record::THINNED_SERIES_FILE)).unwrap();
    let rows = cdlab::record::parse_csv(&thinned).unwrap();
    assert_eq!(rows.last().unwrap(), last);
    // `cdlab fabric` on the run: the measures with their units, and the figures.
    let figs = base.join("figs");
    let (ok, text) = cdlab(&[
        "fabric",
        out.to_str().unwrap(),
        "--at",
        "0.003",
        "-o",
        figs.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    for needle in ["a_c", "a_n", "a_t", "MPa", "strong network", "deg"] {
        assert!(text.contains(needle), "`{needle}` not in:\n{text}");
    }
    for f in ["rose.png", "rose.svg", "force_pdf.png", "force_pdf.svg"] {
        let p = figs.join(f);
        assert!(
            p.metadata().map(|m| m.len() > 100).unwrap_or(false),
            "{} missing",
            p.display()
        );
    }
    // An archived test without its snapshot cannot be analysed, and says why; archived with
    // --keep-last-snapshot it can, with the same numbers as the run's last snapshot.
    let (ok, text) = cdlab(&["fabric", arch.join("t1").to_str().unwrap()]);
    assert!(!ok && text.contains("archived test"), "{text}");
    let arch2 = base.join("archive2");
    let (ok, text) = cdlab(&[
        "archive",
        out.to_str().unwrap(),
        "--to",
        arch2.to_str().unwrap(),
        "--keep-last-snapshot",
    ]);
    assert!(ok, "{text}");
    let (ok, from_archive) = cdlab(&[
        "fabric",
        arch2.join("t1").to_str().unwrap(),
        "-o",
        figs.to_str().unwrap(),
    ]);
    assert!(ok, "{from_archive}");
    let (ok, from_run) = cdlab(&["fabric", out.to_str().unwrap(), "-o", figs.to_str().unwrap()]);
    assert!(ok, "{from_run}");
    let measures = |t: &str| {
        t.lines()
            .filter(|l| l.contains("anisotropy"))
            .map(String::from)
            .collect::<Vec<_>>()
    };
    assert_eq!(measures(&from_archive), measures(&from_run));
    assert_eq!(measures(&from_run).len(), 3, "{from_run}");
    let _ = std::fs::remove_dir_all(&base);
}
