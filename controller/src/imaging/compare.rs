//! Two scans side by side: the paper's Fig. 6 (snapshots of each scan after the same
//! fractions of its frame, rows = scans, columns = fractions, one colour scale) and Fig. 10
//! (both scans' sections and the true surface on the same axes), made from the data a
//! `scanhil scan` or `scanhil reconstruct` output folder holds:
//!
//! - `report.json`: its `imaging` section ([`ImagingReport`]): grid, gridding, subtracted
//!   plane, frame;
//! - `points.ply`: the points with their times, gridded again for the snapshots;
//! - `profiles.csv`: the sections and the true heights.

use std::path::{Path, PathBuf};

use scanhil_report::ReportError;

use super::pipeline::{ImagingReport, POINTS_PLY, PROFILES_CSV, PROFILES_SVG, SNAPSHOTS_PNG};
use super::ply::{PlyError, read_point_cloud_file};
use super::profiles::{Profiles, ProfilesError, draw_profiles};
use super::progressive::ScanFrame;
use super::reconstruct::ScanPoint;
use super::snapshots::{SNAPSHOT_FRACTIONS, Snapshot, draw_snapshots, snapshots};

/// The run report in an output folder.
pub const REPORT_JSON: &str = "report.json";

/// What one output folder holds for a comparison.
#[derive(Debug, Clone)]
pub struct ScanFolder {
    /// The folder.
    pub dir: PathBuf,
    /// Its name in the figures.
    pub label: String,
    /// Its imaging report.
    pub report: ImagingReport,
    /// Its points.
    pub points: Vec<ScanPoint>,
    /// Its sections.
    pub profiles: Profiles,
}

/// Why two folders could not be compared.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// A file the comparison needs is not in the folder.
    #[error(
        "{}: no {file}: not an output folder of `scanhil scan` or `scanhil reconstruct` with imaging, or one written by an older scanhil",
        dir.display()
    )]
    Missing {
        /// The folder.
        dir: PathBuf,
        /// The file.
        file: &'static str,
    },
    /// `report.json` has no usable `imaging` section.
    #[error("{}: {reason}", path.display())]
    Report {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The point cloud could not be read.
    #[error("{}: {source}", path.display())]
    Ply {
        /// The file.
        path: PathBuf,
        /// The reader's error.
        source: PlyError,
    },
    /// The sections could not be read.
    #[error(transparent)]
    Profiles(#[from] ProfilesError),
    /// The two maps hold different quantities.
    #[error("{a} maps {qa}, {b} maps {qb}: the heights do not compare")]
    Quantities {
        /// The first folder.
        a: String,
        /// Its map quantity.
        qa: String,
        /// The second folder.
        b: String,
        /// Its map quantity.
        qb: String,
    },
    /// A figure could not be drawn.
    #[error(transparent)]
    Draw(#[from] ReportError),
    /// The output folder could not be made.
    #[error("{}: {source}", path.display())]
    Io {
        /// The folder.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
}

impl ScanFolder {
    /// Reads `dir`'s `report.json`, `points.ply` and `profiles.csv`, to be shown as `label`.
    ///
    /// # Errors
    /// [`CompareError`] naming the folder and the missing file, or the file that does not read.
    pub fn read(dir: &Path, label: &str) -> Result<ScanFolder, CompareError> {
        for file in [REPORT_JSON, POINTS_PLY, PROFILES_CSV] {
            if !dir.join(file).is_file() {
                return Err(CompareError::Missing {
                    dir: dir.to_owned(),
                    file,
                });
            }
        }
        let path = dir.join(REPORT_JSON);
        let report_error = |reason: String| CompareError::Report {
            path: path.clone(),
            reason,
        };
        let text = std::fs::read_to_string(&path).map_err(|e| report_error(e.to_string()))?;
        let json: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| report_error(e.to_string()))?;
        let imaging = json
            .get("imaging")
            .filter(|v| !v.is_null())
            .ok_or_else(|| {
                report_error("no `imaging` section (a scan without distances?)".into())
            })?;
        let report: ImagingReport = serde_json::from_value(imaging.clone())
            .map_err(|e| report_error(format!("imaging: {e}")))?;
        let ply = dir.join(POINTS_PLY);
        let points = read_point_cloud_file(&ply)
            .map_err(|source| CompareError::Ply {
                path: ply.clone(),
                source,
            })?
            .points;
        let profiles = Profiles::read_csv_file(&dir.join(PROFILES_CSV))?;
        Ok(ScanFolder {
            dir: dir.to_owned(),
            label: label.to_owned(),
            report,
            points,
            profiles,
        })
    }

    /// The snapshots after [`SNAPSHOT_FRACTIONS`] of the folder's frame, on its own grid.
    #[must_use]
    pub fn snapshots(&self) -> Vec<Snapshot> {
        let r = &self.report;
        let plane = (r.map_quantity == "height_above_plane_mm")
            .then_some(r.plane.as_ref().map(|f| &f.plane))
            .flatten();
        let frame = r
            .frame
            .unwrap_or_else(|| ScanFrame::spanning(self.points.iter().map(|p| p.t_s)));
        snapshots(
            &self.points,
            plane,
            r.grid,
            r.options.grid,
            frame,
            &SNAPSHOT_FRACTIONS,
        )
    }
}

/// Draws `scans` side by side into `out` (created if needed): `snapshots.png` (one row per
/// scan) and `profiles.svg`; returns the files written.
///
/// # Errors
/// Maps of different quantities (z_s against heights above a plane), or a figure that cannot
/// be written.
pub fn draw_comparison(scans: &[ScanFolder], out: &Path) -> Result<Vec<PathBuf>, CompareError> {
    if let [first, rest @ ..] = scans
        && let Some(other) = rest
            .iter()
            .find(|s| s.report.map_quantity != first.report.map_quantity)
    {
        return Err(CompareError::Quantities {
            a: first.dir.display().to_string(),
            qa: first.report.map_quantity.clone(),
            b: other.dir.display().to_string(),
            qb: other.report.map_quantity.clone(),
        });
    }
    let caption = scans
        .first()
        .map_or("height (mm)", |s| s.report.quantity_caption());
    std::fs::create_dir_all(out).map_err(|source| CompareError::Io {
        path: out.to_owned(),
        source,
    })?;
    let rows: Vec<(String, Vec<Snapshot>)> = scans
        .iter()
        .map(|s| (s.label.clone(), s.snapshots()))
        .collect();
    let names: Vec<&str> = scans.iter().map(|s| s.label.as_str()).collect();
    let snapshots_png = out.join(SNAPSHOTS_PNG);
    draw_snapshots(
        &snapshots_png,
        &format!(
            "{} after parts of each frame (no fill)",
            names.join(" against ")
        ),
        caption,
        &rows,
    )?;
    let profiles_svg = out.join(PROFILES_SVG);
    let profiles: Vec<(String, &Profiles)> = scans
        .iter()
        .map(|s| (s.label.clone(), &s.profiles))
        .collect();
    draw_profiles(&profiles_svg, caption, &profiles)?;
    Ok(vec![snapshots_png, profiles_svg])
}
