//! Grain size distribution and geometric deposition (docs/validation.md, "Sample").

use cdlab::sample::{
    self, d_by_area, d10_d60, deposit_sample, geometric_coordination, max_overlap, packing_fraction,
};

#[test]
fn grain_sizes_match_the_papers_d10_and_d60_by_area() {
    // Paper (docs/protocol.md, "Grain sizes"): D10 = 1.3 m, D60 = 2.8 m, uniformity coefficient 2.15, for radii
    // uniform by area in [0.5, 2] m. The analytic distribution gives them exactly.
    assert!((d_by_area(0.1, 0.5, 2.0) - 1.3).abs() < 1e-12);
    assert!((d_by_area(0.6, 0.5, 2.0) - 2.8).abs() < 1e-12);
    let r = sample::sample_radii(20_000, 0.5, 2.0, 42).unwrap();
    let (d10, d60) = d10_d60(&r);
    // Sampling error of an area quantile: the area CDF is linear, F = (r - 0.5)/1.5, and
    // area-weighted draws are effectively ~5000 independent (weights range 1 to 16), so the
    // standard error of the 10% quantile is about 1.5 * 2 * sqrt(0.1 * 0.9 / 5000) = 0.013 m.
    // Four standard errors: 0.05 m.
    assert!((d10 - 1.3).abs() < 0.05, "D10 = {d10} m");
    assert!((d60 - 2.8).abs() < 0.05, "D60 = {d60} m");
    assert!((d60 / d10 - 2.15).abs() < 0.1, "Cu = {}", d60 / d10);
    assert!(r.iter().all(|&x| (0.5..=2.0).contains(&x)));
}

#[test]
fn sampling_is_deterministic_per_seed() {
    let a = sample::sample_radii(100, 0.5, 2.0, 7).unwrap();
    let b = sample::sample_radii(100, 0.5, 2.0, 7).unwrap();
    let c = sample::sample_radii(100, 0.5, 2.0, 8).unwrap();
    assert_eq!(a, b);
    assert_ne!(a, c);
    let p = deposit_sample(200, 0.5, 2.0, 25.0, 7).unwrap();
    let q = deposit_sample(200, 0.5, 2.0, 25.0, 7).unwrap();
    assert_eq!(p, q);
}

#[test]
fn deposition_is_dense_supported_and_free_of_overlaps() {
    let n = 600;
    let w = sample::box_width_for(n, 0.5, 2.0, 2.5);
    let pk = deposit_sample(n, 0.5, 2.0, w, 3).unwrap();
    // No overlaps (geometric placement): at most round-off.
    let ov = max_overlap(&pk);
    assert!(ov < 1e-9, "max overlap {ov} m");
    // Inside the box.
    for (c, &r) in pk.centers.iter().zip(&pk.radii) {
        assert!(c.x >= r * (1.0 - 1e-9) && c.x <= w - r * (1.0 - 1e-9) && c.y >= r * (1.0 - 1e-9));
    }
    // Every disk is supported: it touches the floor, or two of (disks, side walls). A support
    // may stand higher than the disk's centre: a disk slides along a larger one into the
    // corner it makes with the floor or with a neighbour.
    let tol = 1e-7;
    for (k, (c, &r)) in pk.centers.iter().zip(&pk.radii).enumerate() {
        if c.y - r <= tol {
            continue;
        }
        let mut supports = pk
            .centers
            .iter()
            .zip(&pk.radii)
            .enumerate()
            .filter(|&(j, (cj, &rj))| j < k && (*cj - *c).length() - r - rj <= tol)
            .count();
        supports += (c.x - r <= tol) as usize + (w - c.x - r <= tol) as usize;
        assert!(
            supports >= 2 || (supports == 1 && (c.x - r <= tol || w - c.x - r <= tol)),
            "disk {k} at {c} rests on {supports} supports"
        );
    }
    // Packing fraction of the band 10%-80% of the height, wall zones included: the paper
    // reports about 0.84 for its deposit; the side walls loosen small samples more
    // (docs/protocol.md, "Deposition").
    let phi = packing_fraction(&pk, 0.1 * pk.height, 0.8 * pk.height);
    assert!((0.80..=0.87).contains(&phi), "packing fraction {phi}");
    // Mean coordination (disk-disk touching pairs): a sequential deposit has each disk on two
    // supports, so about 4 (paper: about 4); edges and the free surface lower it.
    let z = geometric_coordination(&pk, 1e-6);
    assert!((3.0..=4.5).contains(&z), "coordination {z}");
    println!(
        "deposit of {n}: phi = {phi:.3}, z = {z:.2}, aspect = {:.2}",
        pk.height / w
    );
}

#[test]
fn bad_sample_parameters_are_rejected() {
    assert!(
        sample::sample_radii(10, -1.0, 2.0, 1)
            .unwrap_err()
            .to_string()
            .contains("r_min")
    );
    assert!(
        sample::sample_radii(10, 1.0, 0.5, 1)
            .unwrap_err()
            .to_string()
            .contains("r_max")
    );
    assert!(sample::sample_radii(0, 0.5, 2.0, 1).is_err());
    assert!(sample::sample_radii(10, f64::NAN, 2.0, 1).is_err());
    assert!(
        deposit_sample(10, 0.5, 2.0, 3.0, 1)
            .unwrap_err()
            .to_string()
            .contains("width")
    );
}
