fn main() {
    let n: usize = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(300);
    let w = cdlab::sample::box_width_for(n, 0.5, 2.0, 2.5);
    let t = std::time::Instant::now();
    let pk = cdlab::sample::deposit_sample(n, 0.5, 2.0, w, 1).unwrap();
    eprintln!(
        "n {n} w {w:.2} h {:.2} phi {:.3} z {:.2} t {:.3}s",
        pk.height,
        cdlab::sample::packing_fraction(&pk, 0.1 * pk.height, 0.8 * pk.height),
        cdlab::sample::geometric_coordination(&pk, 1e-6),
        t.elapsed().as_secs_f64()
    );
    if std::env::args().nth(2).is_some() {
        for (c, r) in pk.centers.iter().zip(&pk.radii) {
            println!("{},{},{}", c.x, c.y, r);
        }
    }
}
