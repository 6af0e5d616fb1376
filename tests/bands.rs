//! Shear bands on synthetic displacement fields of known geometry, and on a tiny real run.

mod common;

use cdlab::analysis::bands::{
    BandOptions, StrainOptions, analyse_pair, analyse_run, local_shear, local_strain, mean_diameter, select,
};
use cdlab::record::{DiskRecord, RunRecord, Snapshot};
use common::{Rng, biaxial, cdlab, small_config};
use glam::{DMat2, DVec2};

/// A disordered, non-overlapping sample of about `nx * ny` disks: a jittered square lattice
/// of pitch 1 m, radii in [0.35, 0.45] m (mean diameter 0.8 m), centred on the origin.
fn sample(nx: usize, ny: usize, seed: u64) -> Vec<DiskRecord> {
    let mut rng = Rng(seed);
    let mut out = Vec::new();
    for a in 0..nx {
        for b in 0..ny {
            // Jitter up to 0.05 m keeps neighbours at least 0.9 m apart: no overlap.
            out.push(DiskRecord {
                x: a as f64 - 0.5 * nx as f64 + rng.range(-0.05, 0.05),
                y: b as f64 - 0.5 * ny as f64 + rng.range(-0.05, 0.05),
                r: rng.range(0.35, 0.45),
                ..Default::default()
            });
        }
    }
    out
}

/// The snapshot pair of `disks` displaced by `u(x)`, at strains 0.01 and 0.02.
fn pair(disks: &[DiskRecord], u: impl Fn(DVec2) -> DVec2) -> (Snapshot, Snapshot) {
    let a = Snapshot {
        time_s: 1.0,
        strain: 0.01,
        disks: disks.to_vec(),
        contacts: Vec::new(),
    };
    let mut b = a.clone();
    b.time_s = 2.0;
    b.strain = 0.02;
    for d in &mut b.disks {
        let v = u(DVec2::new(d.x, d.y));
        d.x += v.x;
        d.y += v.y;
        d.dx += v.x;
        d.dy += v.y;
    }
    (a, b)
}

/// Band direction at `deg` from the vertical (positive towards +x), and its normal.
fn frame(deg: f64) -> (DVec2, DVec2) {
    let th = deg.to_radians();
    (DVec2::new(th.sin(), th.cos()), DVec2::new(th.cos(), -th.sin()))
}

/// Simple shear `gamma` along a strip at `deg` from the vertical through `c`, of width
/// `width` m; the material on either side translates rigidly.
fn strip(deg: f64, width: f64, gamma: f64, c: DVec2) -> impl Fn(DVec2) -> DVec2 {
    let (t, n) = frame(deg);
    move |x| t * gamma * n.dot(x - c).clamp(-0.5 * width, 0.5 * width)
}

#[test]
fn a_localized_simple_shear_gives_its_angle_and_width() {
    let disks = sample(40, 100, 7);
    let d = mean_diameter(&disks).unwrap();
    for (deg, seed_shift) in [(30.0, 0.0), (55.0, 3.0), (-30.0, -4.0), (-55.0, 2.0)] {
        let width = 6.0 * d;
        let (a, b) = pair(&disks, strip(deg, width, 0.1, DVec2::new(seed_shift, 0.0)));
        let rep = analyse_pair(&a, &b, &BandOptions::default()).unwrap();
        // Imposed: one band at `deg`, 6 mean diameters wide; tolerances 3 deg and 25%.
        assert_eq!(rep.bands.len(), 1, "{deg} deg: {rep:#?}");
        let band = &rep.bands[0];
        assert!(
            (band.angle_deg - deg).abs() <= 3.0,
            "{deg} deg: found {}",
            band.angle_deg
        );
        assert!(
            (band.width_diameters - 6.0).abs() <= 0.25 * 6.0,
            "{deg} deg: width {} diameters, imposed 6",
            band.width_diameters
        );
        // Outside the strip the motion is rigid: background shear 0, contrast 1.
        assert!(
            band.background_shear.abs() < 1e-9 && band.contrast > 0.99,
            "{band:?}"
        );
    }
}

#[test]
fn conjugate_bands_are_both_reported() {
    let disks = sample(40, 100, 11);
    let d = mean_diameter(&disks).unwrap();
    let (u1, u2) = (
        strip(35.0, 6.0 * d, 0.1, DVec2::new(0.0, 15.0)),
        strip(-35.0, 6.0 * d, 0.1, DVec2::new(0.0, -15.0)),
    );
    let (a, b) = pair(&disks, |x| u1(x) + u2(x));
    let rep = analyse_pair(&a, &b, &BandOptions::default()).unwrap();
    let mut angles: Vec<f64> = rep.bands.iter().map(|b| b.angle_deg).collect();
    angles.sort_by(f64::total_cmp);
    // Imposed: +35 and -35 deg from the vertical, within 3 deg.
    assert_eq!(angles.len(), 2, "{rep:#?}");
    assert!(
        (angles[0] + 35.0).abs() <= 3.0 && (angles[1] - 35.0).abs() <= 3.0,
        "{angles:?}"
    );
}

/// The maximum shear strain of the Green-Lagrange tensor of `u = G x`, written out.
fn closed_form_shear(g: [[f64; 2]; 2]) -> f64 {
    let [[a, b], [c, d]] = g; // u_x = a x + b y, u_y = c x + d y
    let exx = a + 0.5 * (a * a + c * c);
    let eyy = d + 0.5 * (b * b + d * d);
    let exy = 0.5 * (b + c + a * b + c * d);
    ((exx - eyy).powi(2) + 4.0 * exy * exy).sqrt()
}

#[test]
fn a_homogeneous_field_gives_the_imposed_strain_everywhere_and_no_band() {
    let disks = sample(30, 60, 3);
    let g = [[0.012, 0.03], [-0.004, -0.02]];
    let m = DMat2::from_cols(DVec2::new(g[0][0], g[1][0]), DVec2::new(g[0][1], g[1][1]));
    let (a, b) = pair(&disks, |x| m * x + DVec2::new(0.3, -0.2));
    let expected = closed_form_shear(g);
    let expected_area = (1.0 + g[0][0]) * (1.0 + g[1][1]) - g[0][1] * g[1][0] - 1.0;
    let local = local_strain(&a, &b, &StrainOptions::default()).unwrap();
    // Only the 4 corner disks have fewer than 3 neighbours (lattice pitch 1 m, neighbours
    // within 0.4 m of the surface: the diagonal ones at 1.41 m are out).
    assert_eq!(local.iter().filter(|s| s.is_none()).count(), 4);
    for s in local.iter().flatten() {
        // An affine field is fitted exactly: closed form to round-off, residual 0.
        assert!((s.shear - expected).abs() < 1e-12, "{} vs {expected}", s.shear);
        assert!((s.volumetric - expected_area).abs() < 1e-12);
        assert!(s.d2min < 1e-24);
    }
    let rep = analyse_pair(&a, &b, &BandOptions::default()).unwrap();
    // Uniform field: contrast at round-off level, so no band on either side.
    assert!(rep.bands.is_empty(), "{rep:#?}");
    assert!(rep.rejected.iter().all(|b| b.contrast < 1e-9), "{rep:#?}");
    assert!((rep.shear_mean - expected).abs() < 1e-12);
}

#[test]
fn a_rigid_rotation_has_no_local_strain() {
    let disks = sample(20, 20, 5);
    // A finite rotation (0.3 rad) about an off-centre point: the small-strain tensor would
    // see 1 - cos 0.3 = 0.045 of contraction; the Green-Lagrange one must be 0.
    let (s, c) = 0.3f64.sin_cos();
    let rot = DMat2::from_cols(DVec2::new(c, s), DVec2::new(-s, c));
    let o = DVec2::new(3.0, -2.0);
    let (a, b) = pair(&disks, |x| rot * (x - o) + o - x);
    for v in local_strain(&a, &b, &StrainOptions::default())
        .unwrap()
        .iter()
        .flatten()
    {
        assert!(
            v.shear.abs() < 1e-12 && v.volumetric.abs() < 1e-12 && v.d2min < 1e-24,
            "{v:?}"
        );
    }
}

#[test]
fn bad_input_gives_messages_or_no_value_not_nan() {
    let disks = sample(10, 10, 9);
    let (a, mut b) = pair(&disks, |x| 0.01 * x);
    // A disk with a non-finite position has no value, its neighbours still do.
    b.disks[55].x = f64::NAN;
    let shear = local_shear(&a, &b).unwrap();
    assert!(shear[55].is_none());
    assert!(shear.iter().flatten().all(|v| v.is_finite()));
    assert!(shear.iter().filter(|v| v.is_some()).count() >= 95);
    // An isolated disk (no neighbour within half a mean diameter of its surface) has none.
    let mut lone = a.clone();
    lone.disks.push(DiskRecord {
        x: 100.0,
        y: 100.0,
        r: 0.4,
        ..Default::default()
    });
    let mut lone_b = lone.clone();
    lone_b.strain = 0.02;
    assert!(local_shear(&lone, &lone_b).unwrap()[100].is_none());
    // Different samples, no or one snapshot, reversed window: errors that say why.
    let mut other = b.clone();
    other.disks.pop();
    assert!(
        local_shear(&a, &other)
            .unwrap_err()
            .to_string()
            .contains("not the same sample")
    );
    let mut rec = RunRecord::default();
    for n in 0..2 {
        let e = analyse_run(&rec, None, None, &BandOptions::default()).unwrap_err();
        assert!(e.to_string().contains(&format!("holds {n} snapshot")), "{e}");
        rec.snapshots.push(a.clone());
    }
    rec.snapshots.push(b.clone());
    assert_eq!(select(&rec.snapshots, None, None).unwrap(), (1, 2));
    assert!(select(&rec.snapshots, Some(0.02), Some(0.01)).is_err());
    assert!(select(&rec.snapshots, Some(f64::NAN), None).is_err());
}

#[test]
fn a_tiny_run_reports_shear_bands_in_its_summary() {
    let dir = std::env::temp_dir().join(format!("cdlab-bands-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    // The quick configuration of the CLI tests: three snapshots over 0.6% strain.
    let cfg = small_config(&dir);
    let out = dir.join("run");
    let (ok, text) = biaxial(&cfg, &out, &[]);
    assert!(ok, "{text}");
    assert!(text.contains("shear bands"), "{text}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let sb = &summary["shear_bands"];
    assert!(sb.is_object(), "summary.json shear_bands: {sb}");
    for key in [
        "strain_from",
        "strain_to",
        "mean_diameter_m",
        "shear_mean",
        "null_strength_m",
    ] {
        assert!(sb[key].as_f64().is_some_and(f64::is_finite), "{key}: {sb}");
    }
    assert!(sb["strain_from"].as_f64() < sb["strain_to"].as_f64());
    for b in sb["bands"]
        .as_array()
        .unwrap()
        .iter()
        .chain(sb["rejected"].as_array().unwrap())
    {
        for key in [
            "angle_deg",
            "width_diameters",
            "contrast",
            "peak_shear",
            "background_shear",
        ] {
            assert!(b[key].as_f64().is_some_and(f64::is_finite), "{key}: {b}");
        }
    }
    // The command on the same run, over an explicit window, prints a table with units.
    let (ok, text) = cdlab(&["bands", out.to_str().unwrap(), "--from", "0", "--to", "0.006"]);
    assert!(
        ok && text.contains("angle (deg)") && text.contains("width (diameters)"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
