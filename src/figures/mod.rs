//! Figures of a run and of a campaign, as PNG or SVG (chosen by the file extension).
//!
//! - [`curves`]: sigma_1 and volumetric strain against axial strain, contact counts;
//! - [`envelope`]: the Mohr-Coulomb envelopes in the (p, q) plane and `mu_macro` against the
//!   contact friction, from a campaign [`Report`](crate::analysis::report::Report);
//! - [`snapshot`]: one snapshot drawn to scale: disks colored by displacement or rotation,
//!   the velocity field, the force network ([`network`] draws the arrows and the bars);
//! - [`colormap`]: the sequential and diverging color maps and the colorbar;
//! - [`font`]: the embedded font that PNG text needs.
//!
//! Every figure implements [`Figure`]: one drawing code for both backends, so the PNG and
//! the SVG of a figure show the same thing. Figures are drawn in memory and written whole
//! ([`crate::fsio::write_file`]), so an unwritable path is an [`Error::Io`] naming it.

pub mod colormap;
pub mod curves;
pub mod envelope;
pub mod font;
pub mod network;
pub mod rose;
pub mod snapshot;

use std::path::Path;

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::error::{Error, Result};

pub use curves::{CompareFigure, ContactsFigure, StressStrainFigure};
pub use envelope::{EnvelopeFigure, MuMacroFigure};
pub use snapshot::{Field, Frame, ShearField, SnapshotFigure};

/// The two output formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Raster, 8-bit RGB, text rendered with the embedded font.
    Png,
    /// Vector; text is left to the viewer's `sans-serif` font.
    Svg,
}

impl Format {
    /// The format named by the extension of `path` (`.png` or `.svg`, any case).
    pub fn from_path(path: &Path) -> Result<Format> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("png") => Ok(Format::Png),
            Some("svg") => Ok(Format::Svg),
            _ => Err(Error::invalid(
                "figure file",
                path.display(),
                "the extension must be .png or .svg",
            )),
        }
    }
}

/// A figure that can be drawn on any plotters backend.
pub trait Figure {
    /// What drawing tells the caller (the pixel frame of a snapshot, or nothing).
    type Output;

    /// Width and height in pixels (SVG user units).
    fn size(&self) -> (u32, u32);

    /// Draws the figure on `root`, which is already filled white.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<Self::Output>;
}

/// Turns a plotters error into ours. Plotters fails only on a font problem or a backend
/// write; both are worth a message rather than a panic.
pub(crate) fn draw_err<E: std::fmt::Display>(e: E) -> Error {
    Error::Drawing(format!("drawing a figure: {e}"))
}

/// Draws `fig` as an encoded PNG file's bytes.
pub fn render_png<F: Figure>(fig: &F) -> Result<(Vec<u8>, F::Output)> {
    font::ensure()?;
    let (w, h) = fig.size();
    let mut rgb = vec![0u8; w as usize * h as usize * 3];
    let out = {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let out = fig.draw(&root)?;
        root.present().map_err(draw_err)?;
        out
    };
    Ok((encode_png(&rgb, w, h)?, out))
}

/// Draws `fig` as SVG text.
pub fn render_svg<F: Figure>(fig: &F) -> Result<(String, F::Output)> {
    // The SVG backend measures text to place labels, which needs the font too.
    font::ensure()?;
    let mut svg = String::new();
    let out = {
        let root = SVGBackend::with_string(&mut svg, fig.size()).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let out = fig.draw(&root)?;
        root.present().map_err(draw_err)?;
        out
    };
    Ok((svg, out))
}

/// Draws `fig` into `path`, PNG or SVG after its extension.
pub fn save<F: Figure>(fig: &F, path: &Path) -> Result<F::Output> {
    let (bytes, out) = match Format::from_path(path)? {
        Format::Png => render_png(fig)?,
        Format::Svg => {
            let (s, out) = render_svg(fig)?;
            (s.into_bytes(), out)
        }
    };
    crate::fsio::write_file(path, &bytes)?;
    Ok(out)
}

/// Writes `fig` as `stem.png` and `stem.svg` in `dir`; returns the two paths.
pub fn save_both<F: Figure>(fig: &F, dir: &Path, stem: &str) -> Result<[std::path::PathBuf; 2]> {
    let png = dir.join(format!("{stem}.png"));
    let svg = dir.join(format!("{stem}.svg"));
    save(fig, &png)?;
    save(fig, &svg)?;
    Ok([png, svg])
}

fn encode_png(rgb: &[u8], w: u32, h: u32) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let err = |e: png::EncodingError| Error::Drawing(format!("encoding a PNG figure: {e}"));
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header().map_err(err)?;
    writer.write_image_data(rgb).map_err(err)?;
    writer.finish().map_err(err)?;
    Ok(out)
}

/// The chart of a snapshot figure (metres on both axes), on which [`snapshot`] draws the
/// disks and [`network`] the arrows and bars: kept here so those two need not import each
/// other.
pub(crate) type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Font of titles, axis descriptions and legends: one size everywhere keeps the figures
/// consistent side by side.
pub(crate) const LABEL: (&str, u32) = ("sans-serif", 18);
/// Font of tick labels.
pub(crate) const TICK: (&str, u32) = ("sans-serif", 14);

/// Draws a chart's legend at `position` in the figures' common style (white, slightly
/// transparent box with a black border).
pub(crate) fn draw_legend<'a, 'b, DB, CT>(
    mut labels: plotters::chart::SeriesLabelStyle<'a, 'b, DB, CT>,
    position: SeriesLabelPosition,
    font: (&'b str, u32),
) -> Result<()>
where
    DB: DrawingBackend + 'a,
    CT: plotters::coord::CoordTranslate,
{
    labels
        .position(position)
        .label_font(font)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(draw_err)
}

/// Line colors of the curves (colorblind-safe pairs: blue, orange, green, red, purple).
pub const LINE_COLORS: [RGBColor; 5] = [
    RGBColor(31, 119, 180),
    RGBColor(230, 97, 1),
    RGBColor(26, 152, 80),
    RGBColor(214, 39, 40),
    RGBColor(117, 74, 164),
];
