//! `cdlab fabric RUN [--at STRAIN] [-o DIR]`: the microstructure of a recorded run's
//! snapshot (`crate::measure::micro`, docs/micromechanics.md): fabric and force
//! anisotropies, the strong and weak networks, the Love-Weber stress against the boundary
//! stresses, the force-chain observables; with the rose diagram and the force PDF as
//! figures (PNG and SVG). An archived test can be analysed when it was archived with
//! `--keep-last-snapshot` (its last snapshot, with the area from its thinned series).

use std::path::PathBuf;

use super::render::nearest_snapshot;
use crate::error::{Error, Result};
use crate::figures::rose::{ForcePdfFigure, RoseFigure};
use crate::measure::micro::{Analysis, PDF_BINS, PDF_MAX, ROSE_BINS};
use crate::record::{MCAP_FILE, SeriesRow, Snapshot, read_run, read_series};

pub use crate::campaign::archive::{LAST_SNAPSHOT_FILE, keep_last_snapshot};

/// The snapshots and series of a run directory, or of an archived test holding its last
/// snapshot (with its thinned series).
fn snapshots_and_series(run: &std::path::Path) -> Result<(Vec<Snapshot>, Vec<SeriesRow>)> {
    let kept = run.join(LAST_SNAPSHOT_FILE);
    if run.is_dir() && !run.join(MCAP_FILE).exists() && kept.exists() {
        let bytes = std::fs::read(&kept).map_err(|e| Error::io(&kept, e))?;
        let snap = Snapshot::decode(&bytes)
            .map_err(|e| Error::io(&kept, std::io::Error::new(std::io::ErrorKind::InvalidData, e)))?;
        let (series, _) = read_series(run)?;
        return Ok((vec![snap], series));
    }
    let rec = read_run(run)?;
    Ok((rec.snapshots, rec.series))
}

/// Options of `cdlab fabric`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The run directory (or its run.mcap).
    pub run: PathBuf,
    /// Analyse the snapshot nearest this axial strain (default: the last snapshot).
    #[arg(long)]
    pub at: Option<f64>,
    /// Directory for the figures (rose.png/svg, force_pdf.png/svg); default: `fabric/` in
    /// the run directory.
    #[arg(short = 'o', long = "out")]
    pub out: Option<PathBuf>,
}

/// Runs `cdlab fabric`.
pub fn run(args: &Args) -> Result<()> {
    if let Some(at) = args.at.filter(|a| !a.is_finite() || *a < 0.0) {
        return Err(Error::invalid("--at", at, "an axial strain (>= 0)"));
    }
    let (snapshots, series) = snapshots_and_series(&args.run)?;
    if snapshots.is_empty() {
        return Err(Error::Other(format!(
            "{}: the record holds no snapshot to analyse",
            args.run.display()
        )));
    }
    let k = match args.at {
        Some(at) => nearest_snapshot(&snapshots, at).expect("snapshots exist"),
        None => snapshots.len() - 1,
    };
    let snap = &snapshots[k];
    // The sample's area and boundary stresses from the series row recorded at the
    // snapshot's step (the snapshot holds no walls); an archived test's thinned series
    // gives the nearest row it kept.
    let row = SeriesRow::nearest(&series, snap.time_s)
        .ok_or_else(|| Error::Other(format!("{}: the record holds no series row", args.run.display())))?;
    let area = row.height_m * row.width_m;
    if !(area > 0.0 && area.is_finite()) {
        return Err(Error::Other(format!(
            "{}: the series row at t = {:.3} s gives no sample area (height {} m, width {} m)",
            args.run.display(),
            row.time_s,
            row.height_m,
            row.width_m
        )));
    }
    let radius: Vec<f64> = snap.disks.iter().map(|d| d.r).collect();
    let contacts = snap.micro_contacts();
    let a = Analysis::of(&contacts, &radius, area);
    if a.sums.n_force == 0 {
        return Err(Error::Other(format!(
            "{}: the snapshot at strain {:.4} has no force-carrying contact",
            args.run.display(),
            snap.strain
        )));
    }
    print!("{}", report(&a, snap.strain, snap.time_s, row));
    let dir = match &args.out {
        Some(d) => d.clone(),
        None if args.run.is_dir() => args.run.join("fabric"),
        None => args.run.with_file_name("fabric"),
    };
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let title = format!("contact orientations at axial strain {:.4}", snap.strain);
    let rose = RoseFigure {
        all: &a.rose_all,
        strong: &a.rose_strong,
        title,
    };
    let [p1, p2] = crate::figures::save_both(&rose, &dir, "rose")?;
    let pdf = ForcePdfFigure {
        pdf: &a.pdf,
        title: format!("normal force distribution at axial strain {:.4}", snap.strain),
    };
    let [p3, p4] = crate::figures::save_both(&pdf, &dir, "force_pdf")?;
    for p in [p1, p2, p3, p4] {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// The printed report: every number with its unit.
fn report(a: &Analysis, strain: f64, time_s: f64, row: &crate::record::SeriesRow) -> String {
    let mut s = String::new();
    let mut line = |k: &str, v: String| s.push_str(&format!("  {k:<44} {v}\n"));
    line("snapshot", format!("axial strain {strain:.4}, t = {time_s:.3} s"));
    line(
        "force-carrying disk-disk contacts",
        format!("{} (mean normal force {:.4e} N/m)", a.sums.n_force, a.mean_f_n),
    );
    line(
        "fabric anisotropy a_c",
        format!(
            "{:.4} (principal direction {:.1} deg from x)",
            a.a_c, a.theta_c_deg
        ),
    );
    line("normal force anisotropy a_n", format!("{:.4}", a.a_n));
    line("tangential force anisotropy a_t", format!("{:.4}", a.a_t));
    line(
        "q/p: Love-Weber / (a_c + a_n + a_t)/2",
        format!("{:.4} / {:.4}", a.q_over_p, a.sff_q_over_p),
    );
    line(
        "Love-Weber sigma1 / sigma3",
        format!(
            "{:.3} MPa / {:.3} MPa over {:.1} m^2",
            a.sigma1_pa / 1e6,
            a.sigma3_pa / 1e6,
            a.area_m2
        ),
    );
    line(
        "boundary sigma1 (top wall) / sigma3 (strips)",
        format!("{:.3} MPa / {:.3} MPa", row.sigma1_pa / 1e6, row.sigma3_pa / 1e6),
    );
    line(
        "strong network (f_n > <f_n>)",
        format!(
            "{} contacts, {:.1}% of them, carrying {:.1}% of q",
            a.sums.n_strong,
            100.0 * a.strong_fraction,
            100.0 * a.strong_q_share
        ),
    );
    line(
        "weak network",
        format!(
            "{} contacts, carrying {:.1}% of q",
            a.sums.n_force - a.sums.n_strong,
            100.0 * (1.0 - a.strong_q_share)
        ),
    );
    line(
        "force-branch angle alpha, strong / weak",
        format!(
            "{:.2} deg / {:.2} deg (mean)",
            a.alpha_strong_mean_deg, a.alpha_weak_mean_deg
        ),
    );
    line(
        "disks in strong chains (>= 2 strong contacts)",
        format!(
            "{}, mean radius {:.4} m against {:.4} m for all disks ({:+.1}%)",
            a.chain_disks,
            a.chain_radius_mean_m,
            a.radius_mean_m,
            100.0 * (a.chain_radius_mean_m / a.radius_mean_m - 1.0)
        ),
    );
    line(
        "orientation homogeneity",
        format!(
            "largest deviation from the mean {:.1}% ({ROSE_BINS} bins of {:.0} deg)",
            100.0 * a.rose_max_deviation,
            180.0 / ROSE_BINS as f64
        ),
    );
    line(
        "force PDF",
        format!("{PDF_BINS} bins over f_n/<f_n> in [0, {PDF_MAX}) (-)"),
    );
    s
}
