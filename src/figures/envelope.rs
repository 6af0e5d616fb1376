//! Campaign figures from a [`Report`]: the Mohr-Coulomb envelopes in the (p, q) plane, one
//! color per contact friction, and the macroscopic friction against the contact friction
//! with the fitted `a - b exp(-c mu)` curves.

use plotters::coord::Shift;
use plotters::prelude::*;

// The campaign's colors are the color map's ([`friction_color`]); the curves use them
// too, from `colormap`, so this file and `curves` need not import each other.
pub use super::colormap::friction_color;
use super::curves::CURVE_SIZE;
use super::{Figure, LABEL, LINE_COLORS, TICK, draw_err, draw_legend};
use crate::analysis::fit::Saturation;
use crate::analysis::report::Report;
use crate::error::{Error, Result};

/// Marker radius of the data points (px).
const MARKER: i32 = 5;

fn check(report: &Report) -> Result<()> {
    if report.frictions.is_empty() {
        return Err(Error::NothingToDraw(
            "the report holds no friction: nothing to plot".into(),
        ));
    }
    Ok(())
}

/// q against p (MPa): peak points (filled) and residual points (open) of every friction,
/// with the least-squares lines through the origin `q = p sin(phi)` (solid: peak, dashed:
/// residual).
#[derive(Clone, Debug)]
pub struct EnvelopeFigure<'a> {
    /// The campaign report.
    pub report: &'a Report,
}

impl Figure for EnvelopeFigure<'_> {
    type Output = ();

    fn size(&self) -> (u32, u32) {
        (CURVE_SIZE.0 + 200, CURVE_SIZE.1 + 100)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        check(self.report)?;
        let rows = &self.report.frictions;
        let all = rows
            .iter()
            .flat_map(|r| r.peak_pq_mpa.iter().chain(&r.residual_pq_mpa));
        let (pmax, qmax) = all.fold((0.0f64, 0.0f64), |(p, q), a| (p.max(a[0]), q.max(a[1])));
        let (pmax, qmax) = (1.05 * pmax.max(1e-9), 1.1 * qmax.max(1e-9));
        let mut chart = ChartBuilder::on(root)
            .caption("Mohr-Coulomb envelopes: peak and residual", LABEL)
            .margin(15)
            .x_label_area_size(55)
            .y_label_area_size(75)
            .build_cartesian_2d(0.0..pmax, 0.0..qmax)
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .x_desc("mean stress p = (σ₁ + σ₃)/2 (MPa)")
            .y_desc("deviatoric stress q = (σ₁ - σ₃)/2 (MPa)")
            .label_style(TICK)
            .axis_desc_style(LABEL)
            .light_line_style(WHITE)
            .draw()
            .map_err(draw_err)?;
        let n = rows.len();
        for (k, r) in rows.iter().enumerate() {
            let color = friction_color(k, n);
            let line = |slope: f64| vec![(0.0, 0.0), (pmax, slope * pmax)];
            if r.peak_fit.slope.is_finite() {
                chart
                    .draw_series(LineSeries::new(line(r.peak_fit.slope), color.stroke_width(2)))
                    .map_err(draw_err)?
                    .label(format!(
                        "μ = {}: μ_macro {:.3}, residual {:.3}",
                        r.mu, r.mu_macro, r.mu_macro_res
                    ))
                    .legend(move |(x, y)| Circle::new((x + 12, y), MARKER, color.filled()));
            }
            if r.residual_fit.slope.is_finite() {
                chart
                    .draw_series(DashedLineSeries::new(
                        line(r.residual_fit.slope),
                        8,
                        6,
                        color.stroke_width(2),
                    ))
                    .map_err(draw_err)?;
            }
            chart
                .draw_series(
                    r.peak_pq_mpa
                        .iter()
                        .map(|a| Circle::new((a[0], a[1]), MARKER, color.filled())),
                )
                .map_err(draw_err)?;
            chart
                .draw_series(
                    r.residual_pq_mpa
                        .iter()
                        .map(|a| Circle::new((a[0], a[1]), MARKER, color.stroke_width(2))),
                )
                .map_err(draw_err)?;
        }
        // Two entries explain the marker and line styles shared by every friction.
        let grey = RGBColor(90, 90, 90);
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(draw_err)?
            .label("peak: filled, fit solid")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 25, y)], grey.stroke_width(2)));
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(draw_err)?
            .label("residual: open, fit dashed")
            .legend(move |(x, y)| Circle::new((x + 12, y), MARKER, grey.stroke_width(2)));
        draw_legend(
            chart.configure_series_labels(),
            SeriesLabelPosition::UpperLeft,
            TICK,
        )
    }
}

/// `mu_macro` (peak) and `mu_macro_res` against the contact friction on a logarithmic axis,
/// with standard-error bars and the fitted saturation curves.
#[derive(Clone, Debug)]
pub struct MuMacroFigure<'a> {
    /// The campaign report.
    pub report: &'a Report,
}

/// Points of a saturation curve on `n` log-spaced frictions over [lo, hi].
fn saturation_curve(f: &Saturation, lo: f64, hi: f64, n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|k| {
            let mu = lo * (hi / lo).powf(k as f64 / (n - 1) as f64);
            (mu, f.a - f.b * (-f.c * mu).exp())
        })
        .collect()
}

impl Figure for MuMacroFigure<'_> {
    type Output = ();

    fn size(&self) -> (u32, u32) {
        CURVE_SIZE
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        check(self.report)?;
        let rows: Vec<_> = self.report.frictions.iter().filter(|r| r.mu > 0.0).collect();
        if rows.is_empty() {
            return Err(Error::NothingToDraw(
                "every friction of the report is 0, which a logarithmic axis cannot show".into(),
            ));
        }
        // The paper's range, 0.01 to 12, widened by a factor 1.4 so its end points sit
        // inside the frame, and further if the campaign went beyond it.
        let lo = rows.iter().map(|r| r.mu).fold(0.01, f64::min) / 1.4;
        let hi = rows.iter().map(|r| r.mu).fold(12.0, f64::max) * 1.4;
        let ys = rows.iter().flat_map(|r| {
            [
                r.mu_macro + r.mu_macro_se.max(0.0),
                r.mu_macro_res + r.mu_macro_res_se.max(0.0),
            ]
        });
        let fits = [self.report.mu_macro_fit, self.report.mu_macro_res_fit];
        let ymax = ys
            .chain(fits.iter().flatten().map(|f| f.a))
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
        let ymax = 1.15 * ymax.max(1e-9);
        let mut chart = ChartBuilder::on(root)
            .caption("Macroscopic friction against contact friction", LABEL)
            .margin(15)
            .x_label_area_size(55)
            .y_label_area_size(75)
            .build_cartesian_2d((lo..hi).log_scale(), 0.0..ymax)
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .x_desc("contact friction μ (-)")
            .y_desc("macroscopic friction tan φ (-)")
            .label_style(TICK)
            .axis_desc_style(LABEL)
            .light_line_style(WHITE)
            .draw()
            .map_err(draw_err)?;
        type Pick = fn(&crate::analysis::report::FrictionRow) -> (f64, f64);
        let sets: [(&str, Pick, Option<Saturation>, RGBColor, bool); 2] = [
            (
                "peak μ_macro",
                |r| (r.mu_macro, r.mu_macro_se),
                fits[0],
                LINE_COLORS[0],
                true,
            ),
            (
                "residual μ_macro_res",
                |r| (r.mu_macro_res, r.mu_macro_res_se),
                fits[1],
                LINE_COLORS[1],
                false,
            ),
        ];
        for (name, pick, fit, color, filled) in sets {
            let pts: Vec<(f64, f64, f64)> = rows
                .iter()
                .map(|r| (r.mu, pick(r).0, pick(r).1))
                .filter(|p| p.1.is_finite())
                .collect();
            let style = if filled {
                color.filled()
            } else {
                color.stroke_width(2)
            };
            chart
                .draw_series(
                    pts.iter()
                        .filter(|p| p.2.is_finite() && p.2 > 0.0)
                        .map(|&(x, y, se)| {
                            PathElement::new(vec![(x, y - se), (x, y + se)], color.stroke_width(1))
                        }),
                )
                .map_err(draw_err)?;
            chart
                .draw_series(pts.iter().map(|&(x, y, _)| Circle::new((x, y), MARKER, style)))
                .map_err(draw_err)?
                .label(format!("{name} (bars: standard error)"))
                .legend(move |(x, y)| Circle::new((x + 12, y), MARKER, style));
            if let Some(f) = fit {
                chart
                    .draw_series(LineSeries::new(
                        saturation_curve(&f, lo, hi, 200),
                        color.stroke_width(2),
                    ))
                    .map_err(draw_err)?
                    .label(format!("{:.3} - {:.3} exp(-{:.3} μ)", f.a, f.b, f.c))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 25, y)], color.stroke_width(2)));
            }
        }
        draw_legend(
            chart.configure_series_labels(),
            SeriesLabelPosition::LowerRight,
            LABEL,
        )
    }
}
