//! Micromechanical measures of a contact network: fabric and force anisotropies, the
//! strong and weak networks, the Love-Weber stress, the force distribution and the
//! force-chain observables of the paper's section 4.3. Definitions and references are in
//! `docs/micromechanics.md`.
//!
//! Everything here is a pure function of a contact set ([`MicroContact`]). The series
//! columns come from additive sums ([`MicroSums`]) that both backends compute at every row
//! (the GPU in `shaders/reduce.wgsl`, only the sums leave the device); the full analysis
//! of a snapshot ([`Analysis`]) adds the histograms and the per-disk observables.
//!
//! Conventions: the normal `n` points from body j to body i, the tangent is
//! `t = (n_y, -n_x)` ([`crate::contact::tangent`]), the force on i is `f_n n + f_t t`, and
//! stresses are compressive positive. Angles of orientations are taken modulo pi: a contact
//! has no sign.

use glam::DVec2;

/// Relative threshold below which a normal force counts as zero: a contact carries force
/// when `N > FORCE_THRESHOLD * mean(N)` over the contacts with `N > 0` (dimensionless).
/// The backends' reductions count force-carrying contacts by it too.
pub const FORCE_THRESHOLD: f64 = 1e-6;

/// Bins of the orientation histogram over [0, pi) kept in the sums: 18 bins of 10 degrees.
/// The fabric homogeneity ([`MicroSums::rose_max_deviation`]) is measured on these bins.
pub const ROSE_BINS: usize = 18;

/// Bins of the force PDF over `f_n / <f_n>` in [0, [`PDF_MAX`]).
pub const PDF_BINS: usize = 40;

/// Upper end of the force PDF's range in units of the mean normal force; larger forces
/// are counted in the last bin's normalisation (the density still integrates to 1 over
/// the range because they are put in the last bin).
pub const PDF_MAX: f64 = 6.0;

/// One contact as the measures see it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MicroContact {
    /// Disk i.
    pub i: u32,
    /// Partner disk, `None` for a wall.
    pub j: Option<u32>,
    /// Unit normal, from j to i.
    pub n: DVec2,
    /// Normal force on i (N/m, compressive positive).
    pub f_n: f64,
    /// Tangential force on i along `t = (n_y, -n_x)` (N/m).
    pub f_t: f64,
    /// Length of the branch vector `l = length * n` (m): centre to centre for two disks,
    /// centre to the wall for a wall contact.
    pub length: f64,
}

impl MicroContact {
    /// The contact's force on i (N/m).
    pub fn force(&self) -> DVec2 {
        self.f_n * self.n + self.f_t * crate::contact::tangent(self.n)
    }

    /// Orientation of the normal in [0, pi) (rad).
    pub fn orientation(&self) -> f64 {
        let a = self.n.y.atan2(self.n.x);
        let a = if a < 0.0 { a + std::f64::consts::PI } else { a };
        // atan2 returns pi for (-1, +0): fold it onto 0.
        if a >= std::f64::consts::PI { 0.0 } else { a }
    }
}

/// A symmetric 2x2 tensor `[[xx, xy], [xy, yy]]`.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sym2 {
    /// xx component.
    pub xx: f64,
    /// xy = yx component.
    pub xy: f64,
    /// yy component.
    pub yy: f64,
}

impl Sym2 {
    /// The symmetric part of `a b^T` times `w`.
    pub fn outer(a: DVec2, b: DVec2, w: f64) -> Sym2 {
        Sym2 {
            xx: w * a.x * b.x,
            xy: 0.5 * w * (a.x * b.y + a.y * b.x),
            yy: w * a.y * b.y,
        }
    }

    /// Adds `o` in place.
    pub fn add(&mut self, o: Sym2) {
        self.xx += o.xx;
        self.xy += o.xy;
        self.yy += o.yy;
    }

    /// `self - o`.
    pub fn minus(self, o: Sym2) -> Sym2 {
        Sym2 {
            xx: self.xx - o.xx,
            xy: self.xy - o.xy,
            yy: self.yy - o.yy,
        }
    }

    /// `self * s`.
    pub fn scale(self, s: f64) -> Sym2 {
        Sym2 {
            xx: self.xx * s,
            xy: self.xy * s,
            yy: self.yy * s,
        }
    }

    /// Trace.
    pub fn trace(&self) -> f64 {
        self.xx + self.yy
    }

    /// Half the difference of the principal values, `sqrt(((xx - yy) / 2)^2 + xy^2)`.
    pub fn half_spread(&self) -> f64 {
        (0.25 * (self.xx - self.yy).powi(2) + self.xy * self.xy).sqrt()
    }

    /// Principal values, larger first.
    pub fn principal(&self) -> (f64, f64) {
        let m = 0.5 * self.trace();
        let d = self.half_spread();
        (m + d, m - d)
    }

    /// Direction of the larger principal value in [0, pi) (rad); 0 for an isotropic tensor.
    pub fn direction(&self) -> f64 {
        let a = 0.5 * (2.0 * self.xy).atan2(self.xx - self.yy);
        if a < 0.0 { a + std::f64::consts::PI } else { a }
    }

    /// The deviatoric part's component along direction `theta`:
    /// `((xx - yy) / 2) cos 2 theta + xy sin 2 theta`; equal to [`Sym2::half_spread`] along
    /// the tensor's own principal direction.
    pub fn deviator_along(&self, theta: f64) -> f64 {
        0.5 * (self.xx - self.yy) * (2.0 * theta).cos() + self.xy * (2.0 * theta).sin()
    }
}

/// `2 (l1 - l2) / (l1 + l2)` of a tensor, 0 when its trace is not positive.
fn anisotropy(t: &Sym2) -> f64 {
    let tr = t.trace();
    if tr > 0.0 { 4.0 * t.half_spread() / tr } else { 0.0 }
}

/// Additive sums over a contact set from which the series columns follow. Both backends
/// compute them at every row; the GPU in single precision.
///
/// "Force-carrying" is the `n_force` column's criterion: `f_n > FORCE_THRESHOLD <f_n>`
/// over the contacts with `f_n > 0` (walls included in that mean). The fabric and the
/// force anisotropies are over the force-carrying disk-disk contacts; the sample's
/// Love-Weber stress over every force-carrying contact, walls included; the strong
/// network is the disk-disk contacts with `f_n` above the mean normal force of the
/// force-carrying disk-disk contacts (computed first: the sums take two passes).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MicroSums {
    /// Force-carrying disk-disk contacts.
    pub n_force: u32,
    /// Sum of `n n` over them.
    pub nn: Sym2,
    /// Sum of `f_n` over them (N/m).
    pub f_n: f64,
    /// Sum of `f_n n n` (N/m).
    pub fnn: Sym2,
    /// Sum of the symmetric part of `f_t t n` (N/m).
    pub ftn: Sym2,
    /// Sum of `f l` over every force-carrying contact, walls included (N): times `1 / A`
    /// the Love-Weber stress.
    pub stress: Sym2,
    /// Sum of `f l` over the force-carrying disk-disk contacts (N).
    pub stress_dd: Sym2,
    /// Strong contacts (disk-disk, `f_n > <f_n>`).
    pub n_strong: u32,
    /// Sum of `f l` over the strong contacts (N).
    pub stress_strong: Sym2,
    /// Force-carrying disk-disk contacts per orientation bin over [0, pi).
    pub rose: [u32; ROSE_BINS],
}

/// Bin of an orientation in [0, pi) among `bins`.
pub fn orientation_bin(theta: f64, bins: usize) -> usize {
    ((theta / std::f64::consts::PI * bins as f64).floor() as usize).min(bins - 1)
}

/// The force-carrying threshold of a contact set: `FORCE_THRESHOLD` times the mean of the
/// positive normal forces (0 when none).
pub fn force_threshold(contacts: &[MicroContact]) -> f64 {
    let (s, m) = contacts
        .iter()
        .filter(|c| c.f_n > 0.0)
        .fold((0.0, 0usize), |(s, m), c| (s + c.f_n, m + 1));
    FORCE_THRESHOLD * s / m.max(1) as f64
}

/// Mean normal force of the force-carrying disk-disk contacts (N/m; 0 when none).
pub fn mean_normal_force(contacts: &[MicroContact]) -> f64 {
    let thr = force_threshold(contacts);
    let (s, m) = contacts
        .iter()
        .filter(|c| c.j.is_some() && c.f_n > thr)
        .fold((0.0, 0usize), |(s, m), c| (s + c.f_n, m + 1));
    if m > 0 { s / m as f64 } else { 0.0 }
}

impl MicroSums {
    /// The sums over a contact set.
    pub fn of(contacts: &[MicroContact]) -> MicroSums {
        let thr = force_threshold(contacts);
        let strong = mean_normal_force(contacts);
        let mut s = MicroSums::default();
        for c in contacts.iter().filter(|c| c.f_n > thr) {
            let fl = Sym2::outer(c.force(), c.n, c.length);
            s.stress.add(fl);
            if c.j.is_none() {
                continue;
            }
            s.n_force += 1;
            s.nn.add(Sym2::outer(c.n, c.n, 1.0));
            s.f_n += c.f_n;
            s.fnn.add(Sym2::outer(c.n, c.n, c.f_n));
            s.ftn.add(Sym2::outer(crate::contact::tangent(c.n), c.n, c.f_t));
            s.stress_dd.add(fl);
            if c.f_n > strong {
                s.n_strong += 1;
                s.stress_strong.add(fl);
            }
            s.rose[orientation_bin(c.orientation(), ROSE_BINS)] += 1;
        }
        s
    }

    /// The fabric tensor `phi = <n n>` (trace 1; zero without contacts).
    pub fn fabric(&self) -> Sym2 {
        self.nn.scale(1.0 / (self.n_force.max(1) as f64))
    }

    /// Fabric anisotropy `a_c = 2 (phi_1 - phi_2)`.
    pub fn a_c(&self) -> f64 {
        anisotropy(&self.nn)
    }

    /// Principal direction of the fabric, `theta_c` in [0, pi) (rad).
    pub fn theta_c(&self) -> f64 {
        self.nn.direction()
    }

    /// Normal force anisotropy `a_n = 2 (chi^n_1 - chi^n_2) / (chi^n_1 + chi^n_2) - a_c`,
    /// with `chi^n = <f_n n n> / <f_n>`.
    pub fn a_n(&self) -> f64 {
        if self.n_force == 0 {
            return 0.0;
        }
        anisotropy(&self.fnn) - self.a_c()
    }

    /// Tangential force anisotropy
    /// `a_t = 2 (chi_1 - chi_2) / (chi^n_1 + chi^n_2) - (a_c + a_n)`, with
    /// `chi = chi^n + <f_t sym(t n)> / <f_n>` (the trace of the tangential part is 0).
    pub fn a_t(&self) -> f64 {
        if self.n_force == 0 {
            return 0.0;
        }
        let mut chi = self.fnn;
        chi.add(self.ftn);
        let tr = self.fnn.trace();
        let total = if tr > 0.0 {
            4.0 * chi.half_spread() / tr
        } else {
            0.0
        };
        total - anisotropy(&self.fnn)
    }

    /// Fraction of the force-carrying disk-disk contacts in the strong network.
    pub fn strong_fraction(&self) -> f64 {
        if self.n_force == 0 {
            0.0
        } else {
            self.n_strong as f64 / self.n_force as f64
        }
    }

    /// Share of the disk-disk network's deviatoric stress carried by the strong network:
    /// the strong network's deviator along the network's principal direction over the
    /// network's `q`. The weak network carries the rest (shares are additive because both
    /// are taken along the same direction); 0 when the network has no deviator.
    pub fn strong_q_share(&self) -> f64 {
        let q = self.stress_dd.half_spread();
        if q > 0.0 {
            self.stress_strong.deviator_along(self.stress_dd.direction()) / q
        } else {
            0.0
        }
    }

    /// The Love-Weber stress of a sample of area `area` (Pa; compressive positive): the
    /// symmetric part of `(1 / A) sum_c f^c l^c`.
    pub fn love_weber(&self, area: f64) -> Sym2 {
        self.stress.scale(1.0 / area)
    }

    /// Largest deviation of the orientation histogram from its mean, relative to the mean
    /// (dimensionless; the paper's fabric "homogeneity"), over [`ROSE_BINS`] bins; 0
    /// without contacts.
    pub fn rose_max_deviation(&self) -> f64 {
        let counts: Vec<f64> = self.rose.iter().map(|&c| c as f64).collect();
        max_deviation(&counts)
    }
}

/// Largest `|h_k - mean| / mean` of a histogram (0 for an empty one).
pub fn max_deviation(h: &[f64]) -> f64 {
    let mean = h.iter().sum::<f64>() / h.len().max(1) as f64;
    if mean <= 0.0 {
        return 0.0;
    }
    h.iter().map(|x| (x - mean).abs() / mean).fold(0.0, f64::max)
}

/// The microstructure of one state: what `cdlab fabric` prints and draws.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Analysis {
    /// The additive sums.
    pub sums: MicroSums,
    /// Sample area the stress is divided by (m^2).
    pub area_m2: f64,
    /// Fabric anisotropy.
    pub a_c: f64,
    /// Principal direction of the fabric (degrees in [0, 180)).
    pub theta_c_deg: f64,
    /// Normal force anisotropy.
    pub a_n: f64,
    /// Tangential force anisotropy.
    pub a_t: f64,
    /// Love-Weber stress (Pa).
    pub stress: Sym2,
    /// Its principal values (Pa), larger first.
    pub sigma1_pa: f64,
    /// See `sigma1_pa`.
    pub sigma3_pa: f64,
    /// `q / p = (sigma1 - sigma3) / (sigma1 + sigma3)` of the Love-Weber stress.
    pub q_over_p: f64,
    /// `(a_c + a_n + a_t) / 2`, the stress-force-fabric estimate of `q / p`.
    pub sff_q_over_p: f64,
    /// Mean normal force of the force-carrying disk-disk contacts (N/m).
    pub mean_f_n: f64,
    /// Strong-network fraction and share of q (see [`MicroSums`]).
    pub strong_fraction: f64,
    /// See `strong_fraction`.
    pub strong_q_share: f64,
    /// Probability density of `f_n / <f_n>` over the force-carrying disk-disk contacts:
    /// (bin centre, density); integrates to 1 over [0, PDF_MAX).
    pub pdf: Vec<(f64, f64)>,
    /// Orientation histogram of the force-carrying disk-disk contacts over [0, pi) as a
    /// probability density in 1/rad (integrates to 1 over [0, pi)).
    pub rose_all: Vec<f64>,
    /// The same for the strong network.
    pub rose_strong: Vec<f64>,
    /// Largest deviation of `rose_all` from its mean (fraction).
    pub rose_max_deviation: f64,
    /// Mean angle between a strong contact's force and its branch vector (degrees).
    pub alpha_strong_mean_deg: f64,
    /// The same over the weak contacts (degrees).
    pub alpha_weak_mean_deg: f64,
    /// Mean radius of the disks with two or more strong contacts (m), the disks that carry
    /// the strong chains.
    pub chain_radius_mean_m: f64,
    /// Mean radius of all the disks (m).
    pub radius_mean_m: f64,
    /// Disks with two or more strong contacts.
    pub chain_disks: usize,
}

/// The probability density of `f_n / <f_n>` over the force-carrying disk-disk contacts, in
/// [`PDF_BINS`] bins over [0, [`PDF_MAX`]): (bin centre, density), the densities summing to 1
/// times the bin width. Forces beyond the range go to the last bin, so the density is a
/// probability over every contact. Empty without a force-carrying contact.
pub fn force_pdf(contacts: &[MicroContact], bins: usize, max: f64) -> Vec<(f64, f64)> {
    let thr = force_threshold(contacts);
    let mean = mean_normal_force(contacts);
    let f: Vec<f64> = contacts
        .iter()
        .filter(|c| c.j.is_some() && c.f_n > thr)
        .map(|c| c.f_n / mean)
        .collect();
    if f.is_empty() || bins == 0 || max <= 0.0 {
        return Vec::new();
    }
    let w = max / bins as f64;
    let mut h = vec![0.0; bins];
    for x in &f {
        h[((x / w).floor() as usize).min(bins - 1)] += 1.0;
    }
    let norm = 1.0 / (f.len() as f64 * w);
    h.iter()
        .enumerate()
        .map(|(k, c)| ((k as f64 + 0.5) * w, c * norm))
        .collect()
}

/// Orientation densities (1/rad over [0, pi)) of the contacts `keep` selects, in `bins`.
fn rose(contacts: &[MicroContact], bins: usize, keep: impl Fn(&MicroContact) -> bool) -> Vec<f64> {
    let mut h = vec![0.0; bins];
    let mut m = 0usize;
    for c in contacts.iter().filter(|c| keep(c)) {
        h[orientation_bin(c.orientation(), bins)] += 1.0;
        m += 1;
    }
    if m > 0 {
        let norm = bins as f64 / (std::f64::consts::PI * m as f64);
        h.iter_mut().for_each(|x| *x *= norm);
    }
    h
}

/// Mean angle (degrees) between force and branch over the contacts `keep` selects; 0 when
/// none. For disks the branch is along the normal, so the angle is `atan(|f_t| / f_n)`.
fn alpha_mean(contacts: &[MicroContact], keep: impl Fn(&MicroContact) -> bool) -> f64 {
    let (s, m) = contacts
        .iter()
        .filter(|c| keep(c))
        .fold((0.0, 0usize), |(s, m), c| {
            (s + c.f_t.abs().atan2(c.f_n).to_degrees(), m + 1)
        });
    if m > 0 { s / m as f64 } else { 0.0 }
}

impl Analysis {
    /// The analysis of a contact set among disks of radii `radius`, the stress divided by
    /// the sample area `area` (m^2, > 0).
    pub fn of(contacts: &[MicroContact], radius: &[f64], area: f64) -> Analysis {
        let sums = MicroSums::of(contacts);
        let thr = force_threshold(contacts);
        let mean = mean_normal_force(contacts);
        let carrying = |c: &MicroContact| c.j.is_some() && c.f_n > thr;
        let strong = |c: &MicroContact| carrying(c) && c.f_n > mean;
        let stress = sums.love_weber(area);
        let (s1, s3) = stress.principal();
        let (a_c, a_n, a_t) = (sums.a_c(), sums.a_n(), sums.a_t());
        let mut strong_count = vec![0u32; radius.len()];
        for c in contacts.iter().filter(|c| strong(c)) {
            for k in [Some(c.i), c.j].into_iter().flatten() {
                if let Some(n) = strong_count.get_mut(k as usize) {
                    *n += 1;
                }
            }
        }
        let chain: Vec<f64> = radius
            .iter()
            .zip(&strong_count)
            .filter(|(_, n)| **n >= 2)
            .map(|(r, _)| *r)
            .collect();
        let mean_of = |v: &[f64]| {
            if v.is_empty() {
                0.0
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        Analysis {
            sums,
            area_m2: area,
            a_c,
            theta_c_deg: sums.theta_c().to_degrees(),
            a_n,
            a_t,
            stress,
            sigma1_pa: s1,
            sigma3_pa: s3,
            q_over_p: if s1 + s3 > 0.0 { (s1 - s3) / (s1 + s3) } else { 0.0 },
            sff_q_over_p: 0.5 * (a_c + a_n + a_t),
            mean_f_n: mean,
            strong_fraction: sums.strong_fraction(),
            strong_q_share: sums.strong_q_share(),
            pdf: force_pdf(contacts, PDF_BINS, PDF_MAX),
            rose_all: rose(contacts, ROSE_BINS, carrying),
            rose_strong: rose(contacts, ROSE_BINS, strong),
            rose_max_deviation: sums.rose_max_deviation(),
            alpha_strong_mean_deg: alpha_mean(contacts, strong),
            alpha_weak_mean_deg: alpha_mean(contacts, |c| carrying(c) && c.f_n <= mean),
            chain_radius_mean_m: mean_of(&chain),
            radius_mean_m: mean_of(radius),
            chain_disks: chain.len(),
        }
    }
}

/// The measures' view of a solver's contacts after a step of length `dt`, among `n_disks`
/// disks of radii `radius`: branch lengths from the contact's own geometry (`r_i + r_j +
/// gap`, or `r_i + gap` to a wall), so that `l = length n` is the centre-to-centre (or
/// centre-to-wall) vector the contact was detected with.
pub fn from_solver(contacts: &[crate::contact::Contact], radius: &[f64], dt: f64) -> Vec<MicroContact> {
    let nd = radius.len();
    contacts
        .iter()
        .map(|c| {
            let j = c.disk_j as usize;
            let disk = j < nd;
            MicroContact {
                i: c.i,
                j: disk.then_some(c.disk_j),
                n: c.n,
                f_n: c.rn / dt,
                f_t: c.rt / dt,
                length: radius[c.i as usize] + if disk { radius[j] } else { 0.0 } + c.gap,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn contact(theta: f64, f_n: f64, f_t: f64) -> MicroContact {
        MicroContact {
            i: 0,
            j: Some(1),
            n: DVec2::new(theta.cos(), theta.sin()),
            f_n,
            f_t,
            length: 1.0,
        }
    }

    #[test]
    fn principal_values_and_direction_of_a_rotated_tensor() {
        // diag(3, 1) rotated by 30 degrees: principal values 3 and 1, direction 30 deg.
        let a = PI / 6.0;
        let (c, s) = (a.cos(), a.sin());
        let t = Sym2 {
            xx: 3.0 * c * c + s * s,
            xy: 2.0 * c * s,
            yy: 3.0 * s * s + c * c,
        };
        let (l1, l2) = t.principal();
        assert!((l1 - 3.0).abs() < 1e-12 && (l2 - 1.0).abs() < 1e-12, "{l1} {l2}");
        assert!((t.direction() - a).abs() < 1e-12, "{}", t.direction());
        assert!((t.deviator_along(a) - 1.0).abs() < 1e-12);
        assert!(t.deviator_along(a + PI / 2.0) + 1.0 < 1e-12);
    }

    #[test]
    fn orientation_folds_onto_half_a_turn() {
        for (n, expected) in [
            (DVec2::new(1.0, 0.0), 0.0),
            (DVec2::new(-1.0, 0.0), 0.0),
            (DVec2::new(0.0, -1.0), PI / 2.0),
            (DVec2::new(-1.0, -1.0).normalize(), PI / 4.0),
        ] {
            let c = MicroContact {
                n,
                ..contact(0.0, 1.0, 0.0)
            };
            assert!(
                (c.orientation() - expected).abs() < 1e-12,
                "{n}: {}",
                c.orientation()
            );
        }
    }

    #[test]
    fn uniform_normal_forces_have_no_force_anisotropy() {
        // Any fabric with equal normal forces and no friction: chi^n is phi, so a_n = 0 and
        // a_t = 0, while a_c = 2 (phi_1 - phi_2) of the fabric: normals at 0 and 90 degrees
        // weighted 3 to 1 give phi = diag(3/4, 1/4), a_c = 1 along theta_c = 0.
        let set = [0.0, 0.0, 0.0, PI / 2.0].map(|t| contact(t, 5.0, 0.0));
        let s = MicroSums::of(&set);
        assert!((s.a_c() - 1.0).abs() < 1e-12, "a_c {}", s.a_c());
        assert!(s.a_n().abs() < 1e-12 && s.a_t().abs() < 1e-12);
        assert!(s.theta_c().abs() < 1e-12);
    }

    #[test]
    fn a_sliding_set_has_the_tangential_anisotropy_of_its_fourier_term() {
        // Uniform normals, f_n = 1 and f_t = -a sin 2 theta: the tangential part of chi is
        // <f_t sym(t n)> with sym(t n) = (sin 2t / 2, -cos 2t / 2; -cos 2t / 2, -sin 2t / 2)
        // for t = (n_y, -n_x), whose xx - yy = sin 2 theta; <f_t sin 2 theta> = -a / 2, so
        // chi = diag(1/2 - a/4, 1/2 + a/4) and a_t = 2 (a / 2) / 1 = a, with a_c = a_n = 0.
        let a = 0.3;
        let m = 3600;
        let set: Vec<MicroContact> = (0..m)
            .map(|k| {
                let t = (k as f64 + 0.5) * PI / m as f64;
                contact(t, 1.0, -a * (2.0 * t).sin())
            })
            .collect();
        let s = MicroSums::of(&set);
        assert!(s.a_c().abs() < 1e-9 && s.a_n().abs() < 1e-9);
        assert!((s.a_t() - a).abs() < 1e-9, "a_t {}", s.a_t());
    }

    #[test]
    fn strong_network_split_and_q_share() {
        // Two vertical contacts of force 3 and two horizontal of force 1: mean 2, so the
        // vertical pair is strong. The network's stress sum is diag(2, 6) (unit branches),
        // q = 2 along y; the strong pair's diag(0, 6) has deviator 3 along y and the weak
        // pair's diag(2, 0) has -1: shares 3/2 and -1/2.
        let set = [
            contact(PI / 2.0, 3.0, 0.0),
            contact(PI / 2.0, 3.0, 0.0),
            contact(0.0, 1.0, 0.0),
            contact(0.0, 1.0, 0.0),
        ];
        let s = MicroSums::of(&set);
        assert_eq!((s.n_force, s.n_strong), (4, 2));
        assert!((s.strong_fraction() - 0.5).abs() < 1e-15);
        assert!((s.strong_q_share() - 1.5).abs() < 1e-12, "{}", s.strong_q_share());
    }

    #[test]
    fn max_deviation_of_histograms() {
        assert_eq!(max_deviation(&[2.0, 2.0, 2.0]), 0.0);
        assert!((max_deviation(&[1.0, 2.0, 3.0]) - 0.5).abs() < 1e-15);
        assert_eq!(max_deviation(&[0.0, 0.0]), 0.0);
    }
}
