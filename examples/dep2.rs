fn main() {
    let n: usize = std::env::args().nth(1).unwrap().parse().unwrap();
    let radii = cdlab::sample::sample_radii(n, 0.5, 2.0, 1).unwrap();
    let pk = cdlab::sample::deposit(&radii, 21.44).unwrap();
    for (k, (c, r)) in pk.centers.iter().zip(&pk.radii).enumerate() {
        eprintln!("{k} {:.3} {:.3} {:.3}", c.x, c.y, r);
        println!("{},{},{}", c.x, c.y, r);
    }
}
