//! Curves of one run against axial strain: the stress-strain curve with the volumetric
//! strain, and the contact counts. Only the compression phase is drawn (axial strain is
//! defined from its start).

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{Figure, LABEL, LINE_COLORS, TICK, draw_err, draw_legend};
use crate::error::{Error, Result};
use crate::measure::derived::PEAK_WINDOW;
use crate::record::SeriesRow;

/// Figure size in pixels: a landscape page-width plot.
pub const CURVE_SIZE: (u32, u32) = (900, 600);

/// The rows of the compression phase with a finite axial strain.
fn compression(rows: &[SeriesRow]) -> Result<Vec<&SeriesRow>> {
    let c: Vec<&SeriesRow> = rows
        .iter()
        .filter(|r| r.phase == "compression" && r.strain_axial.is_finite())
        .collect();
    if c.is_empty() {
        return Err(Error::NothingToDraw(
            "the run has no series row of the compression phase: nothing to plot against axial strain".into(),
        ));
    }
    Ok(c)
}

/// Title of the axial-strain axis. The subscript is a character of its own: plotters draws
/// text as given, so `ε_z` showed its underscore.
pub const STRAIN_AXIS: &str = "axial strain ε₁ (-)";

/// The color of sigma_1 row by row, under its moving mean: the mean's color
/// ([`LINE_COLORS`]`[0]`) halfway to white.
pub const ROW_COLOR: RGBColor = RGBColor(143, 187, 217);

/// The share of the curves' range added below them in [`StressStrainFigure`], for its
/// legend.
const LEGEND_ROOM: f64 = 0.3;

/// The windows of the summary's peak over `rows` (in increasing strain): for each row, the
/// mean sigma_1 (MPa) of the rows within [`PEAK_WINDOW`] of strain from it, at the window's
/// centre, as [`crate::measure::derived::moving_peak`] takes them.
fn window_means(rows: &[&SeriesRow]) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(rows.len());
    let (mut end, mut sum) = (0, 0.0);
    for start in 0..rows.len() {
        while end < rows.len() && rows[end].strain_axial <= rows[start].strain_axial + PEAK_WINDOW {
            sum += rows[end].sigma1_pa;
            end += 1;
        }
        if end > start {
            let n = (end - start) as f64;
            out.push((
                0.5 * (rows[start].strain_axial + rows[end - 1].strain_axial),
                sum / n / 1e6,
            ));
        }
        sum -= rows[start].sigma1_pa;
    }
    out
}

/// A range that contains `values` with a margin of 5% of their spread (or +-1 around a
/// single value); `from_zero` makes it start at 0 when all values are non-negative.
pub(crate) fn padded_range(values: impl Iterator<Item = f64>, from_zero: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if from_zero && lo >= 0.0 {
        lo = 0.0;
    }
    let pad = if hi > lo {
        0.05 * (hi - lo)
    } else {
        lo.abs().max(1.0)
    };
    (if from_zero && lo == 0.0 { 0.0 } else { lo - pad }, hi + pad)
}

/// A chart of one quantity against axial strain, its mesh and axis titles drawn; no
/// caption when `caption` is empty. A `count` axis labels only its whole-number ticks, without
/// a decimal point ("1400", not "1400.0"; no label at 2.5 on a short range).
fn strain_chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    caption: &str,
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
    y_desc: &str,
    count: bool,
) -> Result<
    ChartContext<
        'a,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
> {
    let mut builder = ChartBuilder::on(area);
    if !caption.is_empty() {
        builder.caption(caption, LABEL);
    }
    let mut chart = builder
        .margin(15)
        .x_label_area_size(55)
        .y_label_area_size(85)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(draw_err)?;
    let whole = |v: &f64| {
        if (v - v.round()).abs() < 1e-9 {
            format!("{v:.0}")
        } else {
            String::new()
        }
    };
    let mut mesh = chart.configure_mesh();
    if count {
        mesh.y_label_formatter(&whole);
    }
    mesh.x_desc(STRAIN_AXIS)
        .y_desc(y_desc)
        .label_style(TICK)
        .axis_desc_style(LABEL)
        .light_line_style(WHITE)
        .draw()
        .map_err(draw_err)?;
    Ok(chart)
}

/// sigma_1 (MPa, left axis) and volumetric strain (right axis) against axial strain.
///
/// sigma_1 is drawn twice: row by row (light), and as its mean over [`PEAK_WINDOW`] of
/// axial strain (dark), the curve whose maximum is the summary's peak, which is marked.
/// Row by row, the first rows show the top wall's start: set moving at full speed from
/// rest, it can push sigma_1 above the peak for a few steps (a spike at strain of order
/// 1e-5). The mean smooths it as the peak does; the stress axis spans the rows rather
/// than starting at 0, so that the curve fills the plot.
#[derive(Clone, Debug)]
pub struct StressStrainFigure<'a> {
    /// The run's series (any phases; only compression rows are drawn).
    pub rows: &'a [SeriesRow],
    /// Title (e.g. the run's friction and confining stress).
    pub title: String,
}

impl Figure for StressStrainFigure<'_> {
    type Output = ();

    fn size(&self) -> (u32, u32) {
        CURVE_SIZE
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        let rows = compression(self.rows)?;
        let strain = |r: &&SeriesRow| r.strain_axial;
        let means = window_means(&rows);
        let (x0, x1) = padded_range(rows.iter().map(strain), true);
        // Room below both curves for the legend (four lines in the lower right), which
        // would otherwise hide them now that the stress axis does not start at 0.
        let room = |(lo, hi): (f64, f64)| (lo - LEGEND_ROOM * (hi - lo), hi);
        let (s0, s1) = room(padded_range(rows.iter().map(|r| r.sigma1_pa / 1e6), false));
        let (v0, v1) = room(padded_range(rows.iter().map(|r| r.volumetric_strain), false));
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, LABEL)
            .margin(15)
            .x_label_area_size(55)
            .y_label_area_size(75)
            .right_y_label_area_size(90)
            .build_cartesian_2d(x0..x1, s0..s1)
            .map_err(draw_err)?
            .set_secondary_coord(x0..x1, v0..v1);
        chart
            .configure_mesh()
            .x_desc(STRAIN_AXIS)
            .y_desc("axial stress σ₁ (MPa)")
            .label_style(TICK)
            .axis_desc_style(LABEL)
            .light_line_style(WHITE)
            .draw()
            .map_err(draw_err)?;
        chart
            .configure_secondary_axes()
            .y_desc("volumetric strain ΔV/V₀ (-, dilation +)")
            .label_style(TICK)
            .axis_desc_style(LABEL)
            .draw()
            .map_err(draw_err)?;
        let (c1, c2) = (LINE_COLORS[0], LINE_COLORS[1]);
        chart
            .draw_series(LineSeries::new(
                rows.iter().map(|r| (r.strain_axial, r.sigma1_pa / 1e6)),
                ROW_COLOR.stroke_width(1),
            ))
            .map_err(draw_err)?
            .label("σ₁ row by row (MPa, left axis)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 25, y)], ROW_COLOR.stroke_width(2)));
        chart
            .draw_series(LineSeries::new(means.iter().copied(), c1.stroke_width(2)))
            .map_err(draw_err)?
            .label("σ₁ mean over 0.002 strain (its top: the peak)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 25, y)], c1.stroke_width(2)));
        if let Some(&(at, peak)) = means.iter().reduce(|a, b| if b.1 > a.1 { b } else { a }) {
            chart
                .draw_series(std::iter::once(Circle::new((at, peak), 6, BLACK.stroke_width(2))))
                .map_err(draw_err)?
                .label(format!("peak {peak:.3} MPa at strain {at:.4}"))
                .legend(|(x, y)| Circle::new((x + 12, y), 5, BLACK.stroke_width(2)));
        }
        chart
            .draw_secondary_series(LineSeries::new(
                rows.iter().map(|r| (r.strain_axial, r.volumetric_strain)),
                c2.stroke_width(2),
            ))
            .map_err(draw_err)?
            .label("ΔV/V₀ (-, right axis)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 25, y)], c2.stroke_width(2)));
        draw_legend(
            chart.configure_series_labels(),
            SeriesLabelPosition::LowerRight,
            LABEL,
        )
    }
}

/// Rolling, sliding and zero-force contact counts against axial strain.
#[derive(Clone, Debug)]
pub struct ContactsFigure<'a> {
    /// The run's series (any phases; only compression rows are drawn).
    pub rows: &'a [SeriesRow],
    /// Title.
    pub title: String,
}

impl Figure for ContactsFigure<'_> {
    type Output = ();

    fn size(&self) -> (u32, u32) {
        CURVE_SIZE
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        let rows = compression(self.rows)?;
        type Count = fn(&SeriesRow) -> u64;
        let series: [(&str, Count, RGBColor); 3] = [
            ("rolling", |r| r.n_rolling, LINE_COLORS[0]),
            ("sliding", |r| r.n_sliding, LINE_COLORS[3]),
            ("zero-force", |r| r.n_zero_force, LINE_COLORS[2]),
        ];
        let (x0, x1) = padded_range(rows.iter().map(|r| r.strain_axial), true);
        let (y0, y1) = padded_range(
            rows.iter()
                .flat_map(|r| series.iter().map(move |s| s.1(r) as f64)),
            true,
        );
        let mut chart = strain_chart(root, &self.title, (x0, x1), (y0, y1), "contacts (count)", true)?;
        for (name, get, color) in series {
            chart
                .draw_series(LineSeries::new(
                    rows.iter().map(|r| (r.strain_axial, get(r) as f64)),
                    color.stroke_width(2),
                ))
                .map_err(draw_err)?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 25, y)], color.stroke_width(2)));
        }
        draw_legend(
            chart.configure_series_labels(),
            SeriesLabelPosition::MiddleRight,
            LABEL,
        )
    }
}

/// Several runs' curves against axial strain, for comparing tests (frictions, pressures,
/// settings): the stress ratio sigma_1 / sigma_3 above, so that tests at different
/// confining stresses share an axis, and the volumetric strain below. One color per run,
/// in the order given, from the sequential map.
#[derive(Clone, Debug)]
pub struct CompareFigure<'a> {
    /// Each run's legend label and series (any phases; only compression rows are drawn).
    pub runs: Vec<(String, &'a [SeriesRow])>,
    /// Title.
    pub title: String,
}

/// Size of the comparison figure with its narrowest key: two stacked panels and the key on
/// their right. The key widens with its labels ([`CompareFigure::key_width`]).
pub const COMPARE_SIZE: (u32, u32) = (1150, 900);

/// Narrowest width of the key's column (px): room for labels such as "μ = 12, dt = 0.0625 ms".
const KEY_WIDTH: u32 = 250;

/// Widest key column (px): a label longer than this is cut at the figure's edge.
const KEY_WIDTH_MAX: u32 = 1200;

/// Left of a key label in its column (px): the line sample before it.
const KEY_TEXT_X: i32 = 48;

impl CompareFigure<'_> {
    /// Width of the key's column: the longest label, measured in the key's font, with its
    /// line sample and a margin, from 250 to 1200 px. A fixed column cut long labels
    /// (directory names) at the figure's edge, where two runs' labels could no longer be
    /// told apart.
    pub fn key_width(&self) -> u32 {
        // Measuring needs the embedded font (registered once; a failure leaves the narrow key).
        let _ = super::font::ensure();
        let font = TICK.into_font();
        let widest = self
            .runs
            .iter()
            .filter_map(|(label, _)| font.box_size(label).ok())
            .map(|(w, _)| w)
            .max()
            .unwrap_or(0);
        (widest + KEY_TEXT_X as u32 + 20).clamp(KEY_WIDTH, KEY_WIDTH_MAX)
    }
}

/// One panel of [`CompareFigure`]: its area, value range, axis title and value of a row.
type Panel<'a, DB> = (
    &'a DrawingArea<DB, Shift>,
    (f64, f64),
    &'a str,
    fn(&SeriesRow) -> f64,
);

impl Figure for CompareFigure<'_> {
    type Output = ();

    fn size(&self) -> (u32, u32) {
        (COMPARE_SIZE.0 - KEY_WIDTH + self.key_width(), COMPARE_SIZE.1)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        let mut runs = Vec::with_capacity(self.runs.len());
        for (label, rows) in &self.runs {
            let rows = compression(rows).map_err(|e| Error::NothingToDraw(format!("{label}: {e}")))?;
            if rows.iter().any(|r| r.sigma3_pa.is_nan() || r.sigma3_pa <= 0.0) {
                return Err(Error::NothingToDraw(format!(
                    "{label}: a compression row without a positive confining stress: no stress ratio"
                )));
            }
            runs.push((label, rows));
        }
        if runs.is_empty() {
            return Err(Error::NothingToDraw("no run to compare".into()));
        }
        let all = || runs.iter().flat_map(|(_, rows)| rows.iter());
        let (x0, x1) = padded_range(all().map(|r| r.strain_axial), true);
        let (s0, s1) = padded_range(all().map(|r| r.sigma1_pa / r.sigma3_pa), false);
        let (v0, v1) = padded_range(all().map(|r| r.volumetric_strain), false);
        // A margin above the title: plotters places it 5 px from the top, where the accents
        // and the tops of its capitals were cut.
        let root = root
            .margin(12, 0, 0, 0)
            .titled(&self.title, LABEL)
            .map_err(draw_err)?;
        // The key has its own column: inside a panel it would hide curves, which fill both.
        let (w, h) = root.dim_in_pixel();
        let (plots, key) = root.split_horizontally(w.saturating_sub(self.key_width()));
        let (top, bottom) = plots.split_vertically(h / 2);
        let n = runs.len();
        let color = |k: usize| super::colormap::friction_color(k, n);
        let panels: [Panel<'_, DB>; 2] = [
            (&top, (s0, s1), "stress ratio σ₁/σ₃ (-)", |r| {
                r.sigma1_pa / r.sigma3_pa
            }),
            (
                &bottom,
                (v0, v1),
                "volumetric strain ΔV/V₀ (-, dilation +)",
                |r| r.volumetric_strain,
            ),
        ];
        for (area, (y0, y1), desc, get) in panels {
            let mut chart = strain_chart(area, "", (x0, x1), (y0, y1), desc, false)?;
            for (j, (_, rows)) in runs.iter().enumerate() {
                chart
                    .draw_series(LineSeries::new(
                        rows.iter().map(|r| (r.strain_axial, get(r))),
                        color(j).stroke_width(2),
                    ))
                    .map_err(draw_err)?;
            }
        }
        let row = 24;
        for (j, (label, _)) in runs.iter().enumerate() {
            let y = 30 + row * j as i32;
            key.draw(&PathElement::new(
                vec![(10, y), (40, y)],
                color(j).stroke_width(3),
            ))
            .map_err(draw_err)?;
            key.draw(&Text::new(
                label.as_str(),
                (KEY_TEXT_X, y - 8),
                TICK.into_font().color(&BLACK),
            ))
            .map_err(draw_err)?;
        }
        Ok(())
    }
}
