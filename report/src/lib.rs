#![warn(missing_docs)]
//! What scanhil writes for people to look at: line charts (work-precision diagrams, Bode
//! plots, error against scan time) as SVG or PNG, and height maps as PNG images.
//!
//! # Layout
//! - [`chart`]: [`Chart`] and [`Series`], drawn by [`draw_charts`] into one file, one panel per
//!   chart stacked vertically; the file's extension (`.svg` or `.png`) picks the backend.
//! - [`height_map`]: a grid of heights (with missing cells) written as a false-colour PNG.
//!
//! PNG text is rendered with the DejaVu Sans font bundled in `fonts/` (licence beside it), so
//! nothing depends on the fonts installed on the machine.

pub mod chart;
pub mod height_map;

pub use chart::{Axis, Chart, Series, draw_charts};
pub use height_map::{HeightMapImage, write_height_map_png};

use std::path::PathBuf;

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
