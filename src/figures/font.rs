//! The font of the figures' text.
//!
//! PNG text is rasterized by plotters with ab_glyph from font bytes registered here: DejaVu
//! Sans, embedded from the `dejavu` crate, so a figure renders the same on a machine without
//! any installed font (a fresh CI image) and nothing depends on fontconfig. SVG text names
//! the `sans-serif` family and is rasterized by the viewer; plotters still measures it with
//! this font to place labels.

use std::sync::OnceLock;

use plotters::style::FontStyle;

use crate::error::{Error, Result};

/// The family name every figure uses.
pub const FAMILY: &str = "sans-serif";

/// Registers the embedded font with plotters (once per process; later calls are free).
/// Fails only if the embedded bytes are not a font, which a test would catch first.
pub fn ensure() -> Result<()> {
    static REGISTERED: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            // Bold and italic requests fall back to the normal style in plotters, so one
            // face covers every label.
            plotters::style::register_font(FAMILY, FontStyle::Normal, dejavu::sans::regular())
                .map_err(|_| "the embedded DejaVu Sans is not a readable font".to_string())
        })
        .clone()
        .map_err(Error::Drawing)
}
