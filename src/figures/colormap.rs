//! Color maps and the colorbar that explains them.
//!
//! Two maps: a sequential one for magnitudes (dark violet through teal to yellow, the
//! perceptually even "viridis" look, interpolated from nine anchors) and a diverging one for
//! signed fields (blue, near-white at 0, red), so that the sign of a rotation reads at a
//! glance and 0 is neutral.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{TICK, draw_err};
use crate::error::Result;

/// A piecewise-linear color map on [0, 1] through evenly spaced anchors.
#[derive(Clone, Copy, Debug)]
pub struct Colormap {
    anchors: &'static [(u8, u8, u8)],
}

/// Sequential map for magnitudes (0 dark violet, 1 yellow).
pub const SEQUENTIAL: Colormap = Colormap {
    anchors: &[
        (68, 1, 84),
        (71, 44, 122),
        (59, 82, 139),
        (44, 113, 142),
        (33, 145, 140),
        (39, 173, 129),
        (92, 200, 99),
        (170, 220, 50),
        (253, 231, 37),
    ],
};

/// Diverging map for signed values: 0 blue, 0.5 near-white, 1 red.
pub const DIVERGING: Colormap = Colormap {
    anchors: &[
        (33, 102, 172),
        (103, 169, 207),
        (247, 247, 247),
        (239, 138, 98),
        (178, 24, 43),
    ],
};

impl Colormap {
    /// The color at `t` (clamped to [0, 1]; NaN maps to the middle).
    pub fn at(&self, t: f64) -> RGBColor {
        let t = if t.is_nan() { 0.5 } else { t.clamp(0.0, 1.0) };
        let last = self.anchors.len() - 1;
        let s = t * last as f64;
        let k = (s.floor() as usize).min(last - 1);
        let f = s - k as f64;
        let (a, b) = (self.anchors[k], self.anchors[k + 1]);
        let mix = |x: u8, y: u8| (x as f64 + f * (y as f64 - x as f64)).round() as u8;
        RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
    }
}

/// A color map stretched over the values `[lo, hi]`.
#[derive(Clone, Copy, Debug)]
pub struct Scale {
    /// The map.
    pub map: Colormap,
    /// Value at the map's 0.
    pub lo: f64,
    /// Value at the map's 1.
    pub hi: f64,
}

impl Scale {
    /// A scale over `[lo, hi]`; an empty or invalid range is widened so that the map stays
    /// defined (every value then gets the middle color of a unit-wide range).
    pub fn new(map: Colormap, lo: f64, hi: f64) -> Scale {
        let (lo, hi) = if lo.is_finite() && hi.is_finite() && hi > lo {
            (lo, hi)
        } else {
            let c = if lo.is_finite() { lo } else { 0.0 };
            (c - 0.5, c + 0.5)
        };
        Scale { map, lo, hi }
    }

    /// A diverging scale centered on 0, over `[-limit, limit]`.
    pub fn symmetric(limit: f64) -> Scale {
        let l = if limit.is_finite() && limit > 0.0 {
            limit
        } else {
            1.0
        };
        Scale::new(DIVERGING, -l, l)
    }

    /// The color of `value` (values outside the range take the end colors).
    pub fn color(&self, value: f64) -> RGBColor {
        self.map.at((value - self.lo) / (self.hi - self.lo))
    }
}

/// Number of color steps of a colorbar: enough to look continuous, few enough to keep the
/// SVG small.
pub const COLORBAR_STEPS: usize = 128;

/// Draws a vertical colorbar filling `area`: the bar on the left, ticks and `label` on the
/// right. The bottom step has exactly the map's 0 color and the top step its 1 color, so
/// both extremes are visible.
pub fn draw_colorbar<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    scale: &Scale,
    label: &str,
) -> Result<()> {
    let mut chart = ChartBuilder::on(area)
        .margin_top(20)
        .margin_bottom(60)
        .margin_left(15)
        .margin_right(45)
        .set_label_area_size(LabelAreaPosition::Right, 80)
        .build_cartesian_2d(0.0..1.0, scale.lo..scale.hi)
        .map_err(draw_err)?
        .set_secondary_coord(0.0..1.0, scale.lo..scale.hi);
    let n = COLORBAR_STEPS;
    let dv = (scale.hi - scale.lo) / n as f64;
    chart
        .draw_series((0..n).map(|k| {
            let v0 = scale.lo + k as f64 * dv;
            let color = scale.map.at(k as f64 / (n - 1) as f64);
            Rectangle::new([(0.0, v0), (1.0, v0 + dv)], color.filled())
        }))
        .map_err(draw_err)?;
    chart
        .configure_secondary_axes()
        .y_desc(label)
        .label_style(TICK)
        .axis_desc_style(super::LABEL)
        .y_labels(6)
        .draw()
        .map_err(draw_err)?;
    Ok(())
}

/// Color of friction number `k` of `n`: the sequential map, stopping short of its pale
/// yellow end, which would vanish on white.
pub fn friction_color(k: usize, n: usize) -> RGBColor {
    SEQUENTIAL.at(if n > 1 {
        0.85 * k as f64 / (n - 1) as f64
    } else {
        0.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_and_middle_are_the_anchors() {
        assert_eq!(SEQUENTIAL.at(0.0), RGBColor(68, 1, 84));
        assert_eq!(SEQUENTIAL.at(1.0), RGBColor(253, 231, 37));
        // The diverging map's middle anchor is its color for 0 on a symmetric scale.
        assert_eq!(Scale::symmetric(2.0).color(0.0), RGBColor(247, 247, 247));
        assert_eq!(Scale::symmetric(2.0).color(-5.0), RGBColor(33, 102, 172));
    }

    #[test]
    fn empty_range_stays_defined() {
        let s = Scale::new(SEQUENTIAL, 3.0, 3.0);
        assert!(s.hi > s.lo);
        assert_eq!(s.color(3.0), SEQUENTIAL.at(0.5));
    }
}
