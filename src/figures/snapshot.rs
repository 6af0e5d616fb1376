//! One snapshot drawn to scale (the paper's Figures 4, 7, 8 and 10).
//!
//! The plot keeps equal scales on x and y: the pixel size of the plot area is computed from
//! the sample's extent, and disks are filled polygons in data coordinates (plotters' circles
//! take integer pixel radii, which would distort the small disks of a large sample).

use std::str::FromStr;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::colormap::{SEQUENTIAL, Scale, draw_colorbar};
use super::{Chart, Figure, LABEL, TICK, draw_err, network};
use crate::error::{Error, Result};
use crate::record::Snapshot;

/// What a snapshot figure shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    /// Disks colored by the magnitude of their displacement since the start of compression.
    Displacement,
    /// Disks colored by their rotation (diverging map centered on 0).
    Rotation,
    /// The disks' velocities as arrows.
    Velocity,
    /// The force network: bars between the centres of contacting bodies.
    Forces,
    /// Disks colored by their local shear strain since the snapshot before, with the
    /// axes of the shear bands found in that field.
    Shear,
}

impl Field {
    /// Every field, in the order of the documentation.
    pub const ALL: [Field; 5] = [
        Field::Displacement,
        Field::Rotation,
        Field::Velocity,
        Field::Forces,
        Field::Shear,
    ];

    /// The name used on the command line and in file names.
    pub fn name(self) -> &'static str {
        match self {
            Field::Displacement => "displacement",
            Field::Rotation => "rotation",
            Field::Velocity => "velocity",
            Field::Forces => "forces",
            Field::Shear => "shear",
        }
    }
}

impl FromStr for Field {
    type Err = Error;
    fn from_str(s: &str) -> Result<Field> {
        Field::ALL.into_iter().find(|f| f.name() == s).ok_or_else(|| {
            Error::invalid(
                "--field",
                s,
                "one of displacement, rotation, velocity, forces, shear",
            )
        })
    }
}

/// How data coordinates (m) map to the pixels of a drawn snapshot figure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Pixel x of the data point x = 0.
    pub px0: f64,
    /// Pixel y of the data point y = 0 (pixel rows grow downwards).
    pub py0: f64,
    /// Pixels per metre along x.
    pub sx: f64,
    /// Pixels per metre along y (equal to `sx` up to rounding: the figure keeps the aspect).
    pub sy: f64,
}

impl Frame {
    /// The pixel (column, row) of the data point (x, y) in metres.
    pub fn to_pixel(&self, x: f64, y: f64) -> (f64, f64) {
        (self.px0 + self.sx * x, self.py0 - self.sy * y)
    }
}

/// What [`Field::Shear`] draws, computed from the snapshot and the one before it
/// (`crate::analysis::bands`).
#[derive(Clone, Debug, PartialEq)]
pub struct ShearField {
    /// Each disk's local shear strain over the interval (none where the fit was refused).
    pub values: Vec<Option<f64>>,
    /// Axial strain of the interval's first snapshot.
    pub strain_from: f64,
    /// The bands found in the field.
    pub bands: Vec<crate::analysis::bands::Band>,
}

impl ShearField {
    /// The local shear strain of `next` since `prev`, and the bands in it: what the
    /// summary's band analysis computes for a run's last two snapshots.
    pub fn between(prev: &Snapshot, next: &Snapshot) -> Result<ShearField> {
        use crate::analysis::bands::{BandOptions, analyse_strain, local_strain};
        let opts = BandOptions::default();
        let local = local_strain(prev, next, &opts.strain)?;
        let bands = analyse_strain(prev, next, &local, &opts)?.bands;
        let values = local.iter().map(|s| s.map(|s| s.shear)).collect();
        Ok(ShearField {
            values,
            strain_from: prev.strain,
            bands,
        })
    }
}

/// A snapshot figure: the sample at one instant with one [`Field`].
#[derive(Clone, Debug)]
pub struct SnapshotFigure<'a> {
    /// The snapshot to draw.
    pub snap: &'a Snapshot,
    /// The snapshot rotations are measured from (in practice the first one of the
    /// compression), when it has the same disks; otherwise rotations are the recorded totals.
    pub reference: Option<&'a Snapshot>,
    /// What to show.
    pub field: Field,
    /// Height of the plot area in pixels; the width follows from the sample's aspect.
    pub plot_height: u32,
    /// The local shear strain and bands, which [`Field::Shear`] needs.
    pub shear: Option<&'a ShearField>,
}

// Layout in pixels. Fixed sizes make the plot area, and so the equal aspect, exact.
const TITLE_H: u32 = 60;
const MARGIN: u32 = 15;
const LEFT: u32 = 70;
const BOTTOM: u32 = 55;
const PANEL_W: u32 = 190;

/// Data extent (m): x0, x1, y0, y1, padded so that no disk touches the frame.
fn extent(snap: &Snapshot) -> (f64, f64, f64, f64) {
    let mut e = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for d in &snap.disks {
        e = (
            e.0.min(d.x - d.r),
            e.1.max(d.x + d.r),
            e.2.min(d.y - d.r),
            e.3.max(d.y + d.r),
        );
    }
    let pad = 0.02 * (e.1 - e.0).max(e.3 - e.2);
    (e.0 - pad, e.1 + pad, e.2 - pad, e.3 + pad)
}

impl SnapshotFigure<'_> {
    /// Plot area width for the sample's aspect (at least 1 pixel).
    fn plot_width(&self) -> u32 {
        let (x0, x1, y0, y1) = extent(self.snap);
        ((self.plot_height as f64 * (x1 - x0) / (y1 - y0)).round() as u32).max(1)
    }

    /// The rotation of every disk (rad), relative to the reference when it has the same
    /// disks.
    fn rotations(&self) -> Vec<f64> {
        match self.rotation_reference() {
            Some(r) => self
                .snap
                .disks
                .iter()
                .zip(&r.disks)
                .map(|(d, d0)| d.theta - d0.theta)
                .collect(),
            None => self.snap.disks.iter().map(|d| d.theta).collect(),
        }
    }

    /// The reference of the rotations, if it fits this snapshot.
    fn rotation_reference(&self) -> Option<&Snapshot> {
        self.reference.filter(|r| r.disks.len() == self.snap.disks.len())
    }
}

/// The value at quantile `q` of `|v|` (0 for an empty list).
fn abs_quantile(v: &[f64], q: f64) -> f64 {
    let mut a: Vec<f64> = v.iter().map(|x| x.abs()).filter(|x| x.is_finite()).collect();
    if a.is_empty() {
        return 0.0;
    }
    a.sort_by(f64::total_cmp);
    a[((a.len() - 1) as f64 * q).round() as usize]
}

/// A disk outline as a polygon in data coordinates, with enough vertices that the edges
/// stay below a pixel or so at `px_per_m`.
pub(crate) fn disk_polygon(x: f64, y: f64, r: f64, px_per_m: f64) -> Vec<(f64, f64)> {
    let n = ((r * px_per_m).round() as usize).clamp(12, 48);
    (0..n)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            (x + r * a.cos(), y + r * a.sin())
        })
        .collect()
}

/// Color of the disk outlines.
pub const OUTLINE: RGBColor = RGBColor(110, 110, 110);

impl Figure for SnapshotFigure<'_> {
    type Output = Frame;

    fn size(&self) -> (u32, u32) {
        (
            LEFT + self.plot_width() + 2 * MARGIN + PANEL_W,
            TITLE_H + self.plot_height + 2 * MARGIN + BOTTOM,
        )
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<Frame> {
        let snap = self.snap;
        if snap.disks.is_empty() {
            return Err(Error::NothingToDraw(format!(
                "the snapshot at axial strain {:.4} holds no disk",
                snap.strain
            )));
        }
        let (w, _) = self.size();
        let (title, body) = root.split_vertically(TITLE_H);
        let (plot_area, panel) = body.split_horizontally(w - PANEL_W);
        let what = match (self.field, self.rotation_reference()) {
            (Field::Displacement, _) => "displacement since the start of compression".to_string(),
            (Field::Rotation, Some(r)) => format!("rotation since axial strain {:.5}", r.strain),
            (Field::Rotation, None) => "rotation since the start of the run".to_string(),
            (Field::Velocity, _) => "velocity field".to_string(),
            (Field::Forces, _) => "force network".to_string(),
            (Field::Shear, _) => match self.shear {
                Some(sh) => format!("local shear strain since axial strain {:.5}", sh.strain_from),
                None => {
                    return Err(Error::NothingToDraw(
                        "the shear field needs the local strain of an interval (a render of the run \
                         computes it from the snapshot before)"
                            .into(),
                    ));
                }
            },
        };
        // Two lines: a tall sample leaves a narrow figure.
        let lines = [
            what,
            format!(
                "axial strain {:.5}, t = {:.4} s, {} disks",
                snap.strain,
                snap.time_s,
                snap.disks.len()
            ),
        ];
        for (k, line) in lines.into_iter().enumerate() {
            title
                .draw(&Text::new(line, (MARGIN as i32, 10 + 24 * k as i32), LABEL))
                .map_err(draw_err)?;
        }

        // The x range is widened to the rounded plot width so both axes keep one scale.
        let (x0, _, y0, y1) = extent(snap);
        let x1 = x0 + (y1 - y0) * self.plot_width() as f64 / self.plot_height as f64;
        let mut chart = ChartBuilder::on(&plot_area)
            .margin(MARGIN)
            .x_label_area_size(BOTTOM)
            .y_label_area_size(LEFT)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x (m)")
            .y_desc("y (m)")
            .label_style(TICK)
            .axis_desc_style(LABEL)
            .draw()
            .map_err(draw_err)?;
        let frame = frame_of(&chart, (x0, x1, y0, y1));

        match self.field {
            Field::Displacement => {
                let mag: Vec<f64> = snap.disks.iter().map(|d| d.dx.hypot(d.dy)).collect();
                let hi = mag.iter().cloned().fold(0.0, f64::max);
                let scale = Scale::new(SEQUENTIAL, 0.0, hi);
                draw_disks(&mut chart, snap, frame.sx, |k| scale.color(mag[k]))?;
                draw_colorbar(&panel, &scale, "displacement magnitude (m)")?;
            }
            Field::Rotation => {
                let rot = self.rotations();
                // The 99th percentile sets the range: a few disks spinning freely at the
                // boundary would otherwise leave the whole sample near-white.
                let scale = Scale::symmetric(abs_quantile(&rot, 0.99));
                draw_disks(&mut chart, snap, frame.sx, |k| scale.color(rot[k]))?;
                draw_colorbar(&panel, &scale, "rotation (rad, counterclockwise +)")?;
            }
            Field::Velocity => {
                draw_disks(&mut chart, snap, frame.sx, |_| network::DISK_BACKGROUND)?;
                let key = network::draw_velocities(&mut chart, snap)?;
                network::draw_key(&panel, &key)?;
            }
            Field::Forces => {
                draw_disks(&mut chart, snap, frame.sx, |_| network::DISK_BACKGROUND)?;
                let key = network::draw_forces(&mut chart, snap)?;
                network::draw_key(&panel, &key)?;
            }
            Field::Shear => {
                let sh = self.shear.expect("checked with the title");
                let known: Vec<f64> = sh.values.iter().flatten().copied().collect();
                // As for rotations: a few rattlers' fits would otherwise set the range.
                let scale = Scale::new(SEQUENTIAL, 0.0, abs_quantile(&known, 0.99));
                draw_disks(&mut chart, snap, frame.sx, |k| {
                    match sh.values.get(k).copied().flatten() {
                        Some(v) => scale.color(v),
                        None => network::DISK_BACKGROUND,
                    }
                })?;
                draw_bands(&mut chart, &sh.bands, (x0, x1, y0, y1))?;
                draw_colorbar(&panel, &scale, "local shear strain (-)")?;
            }
        }
        Ok(frame)
    }
}

/// Each band's axis across the plot (a line through its centre at its angle from the axial
/// direction, clipped to the data range), labelled with its angle and width.
fn draw_bands<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    bands: &[crate::analysis::bands::Band],
    (x0, x1, y0, y1): (f64, f64, f64, f64),
) -> Result<()> {
    for b in bands {
        let a = b.angle_deg.to_radians();
        // Positive angles rise towards +x: the direction from the vertical.
        let dir = (a.sin(), a.cos());
        let Some((p, q)) = clip_line((b.centre_x_m, b.centre_y_m), dir, (x0, x1, y0, y1)) else {
            continue;
        };
        chart
            .draw_series(std::iter::once(PathElement::new(
                vec![p, q],
                BLACK.stroke_width(2),
            )))
            .map_err(draw_err)?;
        // The label near the upper end, where the line leaves the sample, on a white box held
        // wholly inside the plot: at the plot's edge it would run into the axis, and over
        // the disks it would be unreadable.
        let top = if p.1 > q.1 { p } else { q };
        let label = format!("{:+.0}°, {:.1} d", b.angle_deg, b.width_diameters);
        let area = chart.plotting_area();
        let style = TICK.into_text_style(area).color(&BLACK);
        let (pw, ph) = area.dim_in_pixel();
        let (tw, th) = area.estimate_text_size(&label, &style).map_err(draw_err)?;
        // Data units per pixel, and the box's padding (px).
        let (sx, sy) = ((x1 - x0) / pw.max(1) as f64, (y1 - y0) / ph.max(1) as f64);
        let pad = 4.0;
        let (w, h) = (tw as f64 * sx, th as f64 * sy);
        let x = (top.0 - 0.5 * w).clamp(x0 + 2.0 * pad * sx, (x1 - w - 2.0 * pad * sx).max(x0));
        let y = (top.1 - 2.0 * pad * sy).clamp((y0 + h + 2.0 * pad * sy).min(y1), y1 - 2.0 * pad * sy);
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(x - pad * sx, y + pad * sy), (x + w + pad * sx, y - h - pad * sy)],
                WHITE.mix(0.9).filled(),
            )))
            .map_err(draw_err)?;
        chart
            .draw_series(std::iter::once(Text::new(label, (x, y), style)))
            .map_err(draw_err)?;
    }
    Ok(())
}

/// The segment of the line through `c` along `dir` inside the box (x0, x1, y0, y1), or
/// none when the line misses it.
pub fn clip_line(
    c: (f64, f64),
    dir: (f64, f64),
    (x0, x1, y0, y1): (f64, f64, f64, f64),
) -> Option<((f64, f64), (f64, f64))> {
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for (p, d, a, b) in [(c.0, dir.0, x0, x1), (c.1, dir.1, y0, y1)] {
        if d.abs() < 1e-12 {
            if p < a || p > b {
                return None;
            }
            continue;
        }
        let (t0, t1) = ((a - p) / d, (b - p) / d);
        lo = lo.max(t0.min(t1));
        hi = hi.min(t0.max(t1));
    }
    (lo < hi).then(|| {
        let at = |t: f64| (c.0 + t * dir.0, c.1 + t * dir.1);
        (at(lo), at(hi))
    })
}

/// The pixel frame of a chart whose data range is (x0, x1, y0, y1).
fn frame_of<DB: DrawingBackend>(chart: &Chart<'_, DB>, (x0, x1, y0, y1): (f64, f64, f64, f64)) -> Frame {
    let (a, b) = (chart.backend_coord(&(x0, y0)), chart.backend_coord(&(x1, y1)));
    let sx = (b.0 - a.0) as f64 / (x1 - x0);
    let sy = (a.1 - b.1) as f64 / (y1 - y0);
    Frame {
        px0: a.0 as f64 - sx * x0,
        py0: a.1 as f64 + sy * y0,
        sx,
        sy,
    }
}

/// Fills every disk with `color(k)`; outlines them in grey when they are big enough on
/// screen for an outline not to hide the fill.
pub(crate) fn draw_disks<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    snap: &Snapshot,
    px_per_m: f64,
    color: impl Fn(usize) -> RGBColor,
) -> Result<()> {
    chart
        .draw_series(
            snap.disks
                .iter()
                .enumerate()
                .map(|(k, d)| Polygon::new(disk_polygon(d.x, d.y, d.r, px_per_m), color(k).filled())),
        )
        .map_err(draw_err)?;
    chart
        .draw_series(snap.disks.iter().filter(|d| d.r * px_per_m >= 4.0).map(|d| {
            let mut p = disk_polygon(d.x, d.y, d.r, px_per_m);
            p.push(p[0]);
            PathElement::new(p, OUTLINE.stroke_width(1))
        }))
        .map_err(draw_err)?;
    Ok(())
}
