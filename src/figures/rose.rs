//! Figures of a contact network's microstructure (`cdlab fabric`): the rose diagram of
//! contact orientations, overall and for the strong network, and the probability density
//! of the normal forces on a log-lin scale ([`crate::measure::micro`]).

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{Figure, LABEL, LINE_COLORS, TICK, draw_err, draw_legend};
use crate::error::{Error, Result};

/// Two polar histograms side by side: the orientation densities (1/rad over [0, pi)) of
/// all the force-carrying contacts and of the strong network, each bin drawn as a wedge
/// and mirrored through the centre (an orientation has no sign), with the isotropic
/// density 1/pi as a circle.
#[derive(Clone, Debug)]
pub struct RoseFigure<'a> {
    /// Densities of all the force-carrying contacts, bins of equal width over [0, pi).
    pub all: &'a [f64],
    /// Densities of the strong network, same bins.
    pub strong: &'a [f64],
    /// Title.
    pub title: String,
}

impl Figure for RoseFigure<'_> {
    type Output = ();

    fn size(&self) -> (u32, u32) {
        (1000, 560)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        if self.all.is_empty() || self.all.len() != self.strong.len() {
            return Err(Error::NothingToDraw(
                "rose diagram: no orientation histogram (no force-carrying contact)".into(),
            ));
        }
        let root = root.titled(&self.title, LABEL).map_err(draw_err)?;
        let panels = root.split_evenly((1, 2));
        let reach = self
            .all
            .iter()
            .chain(self.strong)
            .cloned()
            .fold(1.0 / std::f64::consts::PI, f64::max)
            * 1.1;
        for (k, (area, (h, name))) in panels
            .iter()
            .zip([
                (self.all, "all force-carrying contacts"),
                (self.strong, "strong network"),
            ])
            .enumerate()
        {
            let mut chart = ChartBuilder::on(area)
                .caption(name, LABEL)
                .margin(20)
                .build_cartesian_2d(-reach..reach, -reach..reach)
                .map_err(draw_err)?;
            let color = LINE_COLORS[k];
            let bins = h.len();
            let width = std::f64::consts::PI / bins as f64;
            for (b, &d) in h.iter().enumerate() {
                for half in [0.0, std::f64::consts::PI] {
                    let a0 = half + b as f64 * width;
                    let mut pts = vec![(0.0, 0.0)];
                    for s in 0..=8 {
                        let a = a0 + width * s as f64 / 8.0;
                        pts.push((d * a.cos(), d * a.sin()));
                    }
                    chart
                        .draw_series(std::iter::once(Polygon::new(pts.clone(), color.mix(0.55))))
                        .map_err(draw_err)?;
                    chart
                        .draw_series(std::iter::once(PathElement::new(pts, color.stroke_width(1))))
                        .map_err(draw_err)?;
                }
            }
            let iso = 1.0 / std::f64::consts::PI;
            chart
                .draw_series(std::iter::once(PathElement::new(
                    (0..=120)
                        .map(|s| {
                            let a = s as f64 / 120.0 * 2.0 * std::f64::consts::PI;
                            (iso * a.cos(), iso * a.sin())
                        })
                        .collect::<Vec<_>>(),
                    BLACK.stroke_width(1),
                )))
                .map_err(draw_err)?
                .label("isotropic 1/π rad⁻¹")
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(-reach, 0.0), (reach, 0.0)],
                    BLACK.mix(0.3),
                )))
                .map_err(draw_err)?;
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(0.0, -reach), (0.0, reach)],
                    BLACK.mix(0.3),
                )))
                .map_err(draw_err)?;
            draw_legend(
                chart.configure_series_labels(),
                SeriesLabelPosition::LowerRight,
                TICK,
            )?;
        }
        Ok(())
    }
}

/// The probability density of `f_n / <f_n>` on a logarithmic density axis (empty bins
/// left out).
#[derive(Clone, Debug)]
pub struct ForcePdfFigure<'a> {
    /// (bin centre, density) pairs.
    pub pdf: &'a [(f64, f64)],
    /// Title.
    pub title: String,
}

impl Figure for ForcePdfFigure<'_> {
    type Output = ();

    fn size(&self) -> (u32, u32) {
        super::curves::CURVE_SIZE
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        let pts: Vec<(f64, f64)> = self.pdf.iter().cloned().filter(|(_, p)| *p > 0.0).collect();
        if pts.is_empty() {
            return Err(Error::NothingToDraw(
                "force PDF: no force-carrying contact".into(),
            ));
        }
        let x1 = self.pdf.last().map_or(1.0, |(x, _)| *x) * 1.05;
        let lo = pts.iter().map(|p| p.1).fold(f64::INFINITY, f64::min) * 0.5;
        let hi = pts.iter().map(|p| p.1).fold(0.0, f64::max) * 2.0;
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, LABEL)
            .margin(15)
            .x_label_area_size(55)
            .y_label_area_size(85)
            .build_cartesian_2d(0.0..x1, (lo..hi).log_scale())
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .x_desc("normal force f_n / <f_n> (-)")
            .y_desc("probability density (-)")
            .label_style(TICK)
            .axis_desc_style(LABEL)
            .light_line_style(WHITE)
            .draw()
            .map_err(draw_err)?;
        let color = LINE_COLORS[0];
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
            .map_err(draw_err)?;
        chart
            .draw_series(pts.iter().map(|p| Circle::new(*p, 3, color.filled())))
            .map_err(draw_err)?;
        Ok(())
    }
}
