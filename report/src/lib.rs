#![warn(missing_docs)]
//! What scanhil writes for people to look at: line charts (work-precision diagrams, Bode
//! plots, error against scan time) as SVG or PNG, and height maps as PNG images.
//!
//! # Layout
//! - [`chart`]: [`Chart`] and [`Series`], drawn by [`draw_charts`] into one file, one panel per
//!   chart stacked vertically; the file's extension (`.svg` or `.png`) picks the backend.
//! - [`height_map`]: height maps for people: one or more panels of a grid of heights (with
//!   missing cells marked) in mm, on one colour scale with a colour bar, as a PNG.
//!
//! PNG text is rendered with the DejaVu Sans font bundled in `fonts/` (licence beside it), so
//! nothing depends on the fonts installed on the machine.

pub mod chart;
pub mod height_map;

pub use chart::{Axis, Chart, LogZero, Series, draw_charts};
pub use height_map::{MISSING_RGB, MapFigure, MapPanel, draw_height_maps};

use std::path::PathBuf;
use std::sync::Once;

use plotters::style::FontStyle;

/// The bundled font every chart and map draws its text with.
const FONT: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");

/// Registers the bundled font as "sans-serif" (once per process); both backends measure text
/// with it, so it is registered before any drawing.
pub(crate) fn register_font() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            // The font is compiled in and known to parse; a failure here is a build defect.
            plotters::style::register_font("sans-serif", style, FONT)
                .unwrap_or_else(|_| panic!("bundled DejaVuSans.ttf does not parse"));
        }
    });
}

/// Why a plot or image could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// The output file's extension is neither `.svg` nor `.png`.
    #[error("{path}: unknown plot format (use a .svg or .png file name)")]
    UnknownFormat {
        /// The file that was asked for.
        path: PathBuf,
    },
    /// There was nothing to draw, or a value could not be drawn on the chosen axis.
    #[error("{path}: {reason}")]
    BadData {
        /// The file that was asked for.
        path: PathBuf,
        /// What was wrong with the data.
        reason: String,
    },
    /// The drawing backend failed (usually an I/O error writing the file).
    #[error("{path}: drawing failed: {reason}")]
    Drawing {
        /// The file that was asked for.
        path: PathBuf,
        /// The backend's message.
        reason: String,
    },
    /// The PNG encoder failed.
    #[error("{path}: {source}")]
    Image {
        /// The file that was asked for.
        path: PathBuf,
        /// The encoder's error.
        source: image::ImageError,
    },
}
