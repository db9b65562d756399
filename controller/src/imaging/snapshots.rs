//! The paper's Fig. 6: the height map a scan has built after fractions of its frame (by
//! default 10, 25, 50 and 100 % of the time), drawn side by side on one grid and one colour
//! scale, one row per scan.
//!
//! A snapshot holds every point whose time is at most `frame.start_s + fraction *
//! frame.length_s`, gridded with the scan's own grid and method; heights are the scan's map
//! quantity (z_s, or the height above the subtracted base plane). Snapshots show measured
//! cells only: no fill, missing cells marked.

use std::path::Path;

use scanhil_report::{MapFigure, ReportError, draw_height_maps};

use super::grid::{GridMethod, GridSpec, HeightMap};
use super::point::Point3;
use super::progressive::{ScanFrame, progressive_maps_with};
use super::ransac::Plane;
use super::reconstruct::ScanPoint;

/// The fractions of the frame [`super::pipeline::write_outputs`] draws.
pub const SNAPSHOT_FRACTIONS: [f64; 4] = [0.1, 0.25, 0.5, 1.0];

/// The map after one fraction of the frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    /// The fraction of the frame, in (0, 1].
    pub fraction: f64,
    /// Time since the frame's start, s.
    pub t_s: f64,
    /// The map of the points up to then.
    pub map: HeightMap,
}

/// A snapshot's figures, for the report.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SnapshotCoverage {
    /// The fraction of the frame.
    pub fraction: f64,
    /// Time since the frame's start, s.
    pub t_s: f64,
    /// The fraction of cells measured by then.
    pub coverage_fraction: f64,
}

impl Snapshot {
    /// Its figures for the report.
    #[must_use]
    pub fn coverage(&self) -> SnapshotCoverage {
        SnapshotCoverage {
            fraction: self.fraction,
            t_s: self.t_s,
            coverage_fraction: self.map.coverage_fraction(),
        }
    }
}

/// The maps after each of `fractions` (ascending) of `frame`, of the points' heights above
/// `plane` when given (z_s otherwise), on `spec` with `grid`: see [`progressive_maps_with`]
/// (points in time order are read in place).
#[must_use]
pub fn snapshots(
    points: &[ScanPoint],
    plane: Option<&Plane>,
    spec: GridSpec,
    grid: GridMethod,
    frame: ScanFrame,
    fractions: &[f64],
) -> Vec<Snapshot> {
    let height_mm = |p: &ScanPoint| plane.map_or(p.z_mm, |plane| plane.height_mm(p.xyz_mm()));
    let checkpoints: Vec<f64> = fractions.iter().map(|&f| frame.time_at(f)).collect();
    progressive_maps_with(points, spec, grid, &checkpoints, height_mm)
        .into_iter()
        .zip(fractions)
        .map(|((t_s, map), &fraction)| Snapshot {
            fraction,
            t_s: t_s - frame.start_s,
            map,
        })
        .collect()
}

/// Draws one row of snapshots per `(label, snapshots)`, one column per fraction, on one
/// colour scale, as a PNG titled `title` whose colour bar is captioned `quantity`; returns
/// the height range the colours span.
///
/// # Errors
/// The PNG cannot be drawn (no snapshot, or the file cannot be written).
pub fn draw_snapshots(
    path: &Path,
    title: &str,
    quantity: &str,
    rows: &[(String, Vec<Snapshot>)],
) -> Result<Option<(f64, f64)>, ReportError> {
    let figure = MapFigure {
        title: title.into(),
        quantity: quantity.into(),
        rows: rows
            .iter()
            .map(|(label, row)| {
                row.iter()
                    .map(|s| {
                        let prefix = if label.is_empty() {
                            String::new()
                        } else {
                            format!("{label} ")
                        };
                        s.map.panel(format!(
                            "{prefix}{:.0} %, {:.3} s: {:.0} % of cells",
                            100.0 * s.fraction,
                            s.t_s,
                            100.0 * s.map.coverage_fraction()
                        ))
                    })
                    .collect()
            })
            .collect(),
    };
    draw_height_maps(path, &figure)
}
