//! What a snapshot draws over its disks: the velocity field as arrows and the force network
//! as bars, with the key that reads them.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{Chart, LABEL, draw_err};
use crate::backend::ContactClass;
use crate::error::Result;
use crate::record::Snapshot;

/// Fill of the disks under arrows and bars: light, so the overlay stands out.
pub const DISK_BACKGROUND: RGBColor = RGBColor(222, 222, 222);
/// Color of the velocity arrows.
pub const ARROW: RGBColor = RGBColor(190, 20, 20);
/// Color of the bars of rolling (force-carrying, non-slipping) contacts.
pub const ROLLING: RGBColor = RGBColor(31, 119, 180);
/// Color of the bars of sliding contacts.
pub const SLIDING: RGBColor = RGBColor(214, 39, 40);

/// One line of a key: an optional color swatch and its text.
#[derive(Clone, Debug, PartialEq)]
pub struct KeyEntry {
    /// The swatch drawn before the text.
    pub swatch: Option<RGBColor>,
    /// The text.
    pub text: String,
}

impl KeyEntry {
    fn text(t: impl Into<String>) -> Self {
        KeyEntry {
            swatch: None,
            text: t.into(),
        }
    }
}

/// `v` with three significant digits, in plain notation from 0.001 to 10^5.
pub fn sig3(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 || !a.is_finite() {
        return format!("{v}");
    }
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.2e}");
    }
    let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
    format!("{v:.decimals$}")
}

/// A force per unit thickness (N/m) with a unit that keeps the number short.
pub fn format_force(f: f64) -> String {
    let a = f.abs();
    if a >= 1e6 {
        format!("{} MN/m", sig3(f / 1e6))
    } else if a >= 1e3 {
        format!("{} kN/m", sig3(f / 1e3))
    } else {
        format!("{} N/m", sig3(f))
    }
}

fn mean_radius(snap: &Snapshot) -> f64 {
    snap.disks.iter().map(|d| d.r).sum::<f64>() / snap.disks.len().max(1) as f64
}

/// Draws every disk's velocity as an arrow from its centre; the fastest disk's arrow is
/// three mean radii long, so arrows of neighbours rarely cross. Returns the key.
pub fn draw_velocities<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    snap: &Snapshot,
) -> Result<Vec<KeyEntry>> {
    let vmax = snap.disks.iter().map(|d| d.vx.hypot(d.vy)).fold(0.0, f64::max);
    if !(vmax > 0.0 && vmax.is_finite()) {
        return Ok(vec![KeyEntry::text("every disk at rest")]);
    }
    let len_max = 3.0 * mean_radius(snap);
    let per = len_max / vmax; // metres of arrow per m/s
    let arrows: Vec<((f64, f64), (f64, f64))> = snap
        .disks
        .iter()
        // Arrows under a hundredth of the longest are dots at any sensible size: skipped.
        .filter(|d| d.vx.hypot(d.vy) * per > 0.01 * len_max)
        .map(|d| ((d.x, d.y), (d.x + d.vx * per, d.y + d.vy * per)))
        .collect();
    chart
        .draw_series(
            arrows
                .iter()
                .map(|&(a, b)| PathElement::new(vec![a, b], ARROW.stroke_width(2))),
        )
        .map_err(draw_err)?;
    chart
        .draw_series(
            arrows
                .iter()
                .map(|&(a, b)| Polygon::new(arrow_head(a, b), ARROW.filled())),
        )
        .map_err(draw_err)?;
    Ok(vec![
        KeyEntry {
            swatch: Some(ARROW),
            text: "velocity".into(),
        },
        KeyEntry::text(format!("longest: {} m/s", sig3(vmax))),
        KeyEntry::text(format!("({len_max:.2} m long)")),
    ])
}

/// The triangle at the tip `b` of the arrow from `a`: a third of the arrow long.
fn arrow_head(a: (f64, f64), b: (f64, f64)) -> Vec<(f64, f64)> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (hx, hy) = (dx / 3.0, dy / 3.0);
    let base = (b.0 - hx, b.1 - hy);
    // Half-width of the head is half its length, perpendicular to the shaft.
    let (px, py) = (-hy * 0.5, hx * 0.5);
    vec![b, (base.0 + px, base.1 + py), (base.0 - px, base.1 - py)]
}

/// The four corners of a bar of width `w` from `a` to `b`.
fn bar(a: (f64, f64), b: (f64, f64), w: f64) -> Vec<(f64, f64)> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let l = dx.hypot(dy).max(f64::MIN_POSITIVE);
    let (px, py) = (-dy / l * w / 2.0, dx / l * w / 2.0);
    vec![
        (a.0 + px, a.1 + py),
        (b.0 + px, b.1 + py),
        (b.0 - px, b.1 - py),
        (a.0 - px, a.1 - py),
    ]
}

/// One bar of the force network.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bar {
    /// Centre of disk i (m).
    pub from: (f64, f64),
    /// Centre of disk j, or the contact point on the wall (m).
    pub to: (f64, f64),
    /// Normal force (N/m).
    pub f_n: f64,
    /// Rolling or sliding.
    pub class: ContactClass,
}

/// The bars of the force network, one per force-carrying contact. A disk-disk bar joins
/// the two centres; a disk-wall bar goes from the disk's centre to its contact point on the
/// wall (the normal points from the wall to the disk, so that point is `x_i - r_i n`).
pub fn force_bars(snap: &Snapshot) -> Vec<Bar> {
    let n = snap.disks.len();
    snap.contacts
        .iter()
        .filter_map(|c| {
            let class = ContactClass::from_u8(c.class)?;
            let carries = matches!(class, ContactClass::Rolling | ContactClass::Sliding) && c.f_n > 0.0;
            let di = snap.disks.get(c.i as usize).filter(|_| carries)?;
            let to = match snap.disks.get(c.j as usize) {
                Some(dj) => (dj.x, dj.y),
                None if c.j as usize >= n => (di.x - di.r * c.nx, di.y - di.r * c.ny),
                None => return None,
            };
            Some(Bar {
                from: (di.x, di.y),
                to,
                f_n: c.f_n,
                class,
            })
        })
        .collect()
}

/// Draws the force network: bars whose width is proportional to the normal force (the
/// largest force gets 0.8 mean radius), blue for rolling and red for sliding contacts, the
/// sliding ones on top since they are fewer. Zero-force contacts are not drawn. Returns the
/// key.
pub fn draw_forces<DB: DrawingBackend>(chart: &mut Chart<'_, DB>, snap: &Snapshot) -> Result<Vec<KeyEntry>> {
    let bars = force_bars(snap);
    let fmax = bars.iter().map(|b| b.f_n).fold(0.0, f64::max);
    if bars.is_empty() {
        return Ok(vec![KeyEntry::text("no force-carrying contact")]);
    }
    let w_max = 0.8 * mean_radius(snap);
    let mut counts = [0usize; 2];
    for (k, (class, color)) in [(ContactClass::Rolling, ROLLING), (ContactClass::Sliding, SLIDING)]
        .into_iter()
        .enumerate()
    {
        let these: Vec<&Bar> = bars.iter().filter(|b| b.class == class).collect();
        counts[k] = these.len();
        chart
            .draw_series(
                these
                    .iter()
                    .map(|b| Polygon::new(bar(b.from, b.to, w_max * b.f_n / fmax), color.filled())),
            )
            .map_err(draw_err)?;
    }
    let zero = snap
        .contacts
        .iter()
        .filter(|c| c.class == ContactClass::ZeroForce as u8)
        .count();
    Ok(vec![
        KeyEntry {
            swatch: Some(ROLLING),
            text: format!("rolling ({})", counts[0]),
        },
        KeyEntry {
            swatch: Some(SLIDING),
            text: format!("sliding ({})", counts[1]),
        },
        KeyEntry::text("width ∝ normal force"),
        KeyEntry::text(format!("widest: {}", format_force(fmax))),
        KeyEntry::text(format!("({w_max:.2} m wide)")),
        KeyEntry::text(format!("zero-force ({zero}):")),
        KeyEntry::text("not drawn"),
    ])
}

/// Draws a key in the panel at the right of a snapshot: one entry per line.
pub fn draw_key<DB: DrawingBackend>(panel: &DrawingArea<DB, Shift>, key: &[KeyEntry]) -> Result<()> {
    let line_h = 28;
    for (k, e) in key.iter().enumerate() {
        let y = 30 + k as i32 * line_h;
        let mut x = 12;
        if let Some(c) = e.swatch {
            panel
                .draw(&Rectangle::new([(x, y + 3), (x + 28, y + 14)], c.filled()))
                .map_err(draw_err)?;
            x += 36;
        }
        panel
            .draw(&Text::new(e.text.clone(), (x, y), LABEL))
            .map_err(draw_err)?;
    }
    Ok(())
}
