//! The one imaging chain on one set of samples: calibrate, reconstruct with the rig's
//! geometry, grid, fill, fit the base plane, measure a feature, score against a true surface
//! over scan time, and write PLY + PNG + CSV + the progressive plot. `scanhil reconstruct` and
//! the loop's `scan` both call [`image_samples`], [`Imaging::score_progressive`] and
//! [`write_outputs`], so both write the same files and the same [`ImagingReport`] fields; each
//! puts the report into its own `report.json`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use scanhil_geometry::{GeometryModel, Scanner, ScannerSetup};
use scanhil_scene::truth::TrueScene;

use super::feature::{FeatureError, FeatureHeight, FeatureParams, feature_height};
use super::fill::{FillMethod, FillReport, fill_missing};
use super::grid::{GridError, GridMethod, GridSpec, HeightMap, grid_points};
use super::ply::{PlyEncoding, PlyError, write_ply_file};
use super::progressive::{
    ProgressiveComparison, ProgressivePoint, ProgressiveRun, progressive_errors,
};
use super::ransac::{PlaneFit, RansacError, RansacParams, fit_plane};
use super::reconstruct::{DEFAULT_MODEL, Reconstruction, ScanSample, reconstruct};
use crate::rig::Calibration;

/// What to make of the samples.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ImagingOptions {
    /// The reconstruction model.
    pub model: GeometryModel,
    /// The scanner's mechanical setup (the rig's).
    pub setup: ScannerSetup,
    /// The rig's corrections of angles and distances, applied before reconstruction.
    pub calibration: Calibration,
    /// Height map cell size, mm.
    pub pitch_mm: f64,
    /// How samples become cells.
    pub grid: GridMethod,
    /// How missing cells are filled.
    pub fill: FillMethod,
    /// Map heights above the RANSAC base plane instead of z_s.
    pub subtract_plane: bool,
    /// The base-plane fit (for `subtract_plane`; a feature measurement uses its own).
    pub ransac: RansacParams,
    /// Measure a feature's height with these settings.
    pub feature: Option<FeatureParams>,
    /// Checkpoints of the map's coverage and error against scan time (at least 1).
    pub progressive_steps: usize,
}

/// The most checkpoints [`ImagingOptions::progressive_steps`] may ask for: each is a
/// gridding pass over the points and a map of the whole grid.
pub const MAX_PROGRESSIVE_STEPS: usize = 1000;

impl Default for ImagingOptions {
    /// Eq. 1-3, the paper's setup without correction, 0.1 mm cells (about the 130 um spot),
    /// inverse-distance gridding, no fill, z_s mapped, no feature, 10 checkpoints.
    fn default() -> Self {
        ImagingOptions {
            model: DEFAULT_MODEL,
            setup: ScannerSetup::default(),
            calibration: Calibration::default(),
            pitch_mm: 0.1,
            grid: GridMethod::default(),
            fill: FillMethod::None,
            subtract_plane: false,
            ransac: RansacParams::default(),
            feature: None,
            progressive_steps: 10,
        }
    }
}

/// Everything made from the samples.
#[derive(Debug, Clone, PartialEq)]
pub struct Imaging {
    /// The points.
    pub reconstruction: Reconstruction,
    /// The height map (z_s, or height above the plane with `subtract_plane`).
    pub map: HeightMap,
    /// What the fill did.
    pub fill: FillReport,
    /// The subtracted base plane.
    pub plane: Option<PlaneFit>,
    /// The feature measurement, or why it failed (the other outputs stand either way).
    pub feature: Option<Result<FeatureHeight, FeatureError>>,
    /// The z_s map's coverage, and its error against the true surface when one is known,
    /// after each checkpoint of scan time ([`Imaging::score_progressive`]).
    pub progressive: Vec<ProgressivePoint>,
    /// The true scene scored against, if any.
    pub truth: Option<String>,
    /// The options used.
    pub options: ImagingOptions,
}

impl Imaging {
    /// Grids the z_s map (as the options say, whether or not the map here is
    /// plane-subtracted) after `progressive_steps` equal parts of `[0, scan_time_s]` and
    /// scores each against `truth` when given (coverage only without): see
    /// [`progressive_errors`] for the figures. The last checkpoint is the whole scan.
    pub fn score_progressive(&mut self, truth: Option<&TrueScene>, scan_time_s: f64) {
        let steps = self.options.progressive_steps;
        let checkpoints: Vec<f64> = (1..=steps)
            .map(|i| scan_time_s * i as f64 / steps as f64)
            .collect();
        self.progressive = progressive_errors(
            &self.reconstruction.cloud.points,
            self.map.spec,
            self.options.grid,
            self.options.fill,
            &checkpoints,
            |x, y| truth.and_then(|t| t.z_mm(x, y)),
        );
        self.truth = truth.map(|t| t.path.display().to_string());
    }

    /// The error of the whole scan against the truth (the last checkpoint), if scored.
    #[must_use]
    pub fn truth_error(&self) -> Option<ProgressivePoint> {
        self.truth.as_ref().and(self.progressive.last().copied())
    }
}

/// Why imaging failed.
#[derive(Debug, thiserror::Error)]
pub enum ImagingError {
    /// The scanner setup is unusable.
    #[error("scanner setup: {0}")]
    Setup(#[from] scanhil_geometry::SetupError),
    /// The options ask for something that cannot be made.
    #[error("imaging option `{field}`: {reason}")]
    Options {
        /// The option.
        field: &'static str,
        /// Why.
        reason: String,
    },
    /// No grid could be laid over the points.
    #[error("height map: {0}")]
    Grid(#[from] GridError),
    /// The base plane could not be fitted.
    #[error("base plane: {0}")]
    Plane(#[from] RansacError),
    /// The point cloud could not be written.
    #[error(transparent)]
    Ply(#[from] PlyError),
    /// The PNG could not be written.
    #[error(transparent)]
    Png(#[from] scanhil_report::ReportError),
    /// Another output could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// Calibrates, reconstructs, grids, fills and measures `samples`.
///
/// # Errors
/// [`ImagingError`]: an unusable setup or option, no point to lay a grid over, a base plane
/// that cannot be fitted for `subtract_plane`. A feature that cannot be measured is not an
/// error here: it is kept in [`Imaging::feature`].
pub fn image_samples(
    samples: &[ScanSample],
    options: &ImagingOptions,
) -> Result<Imaging, ImagingError> {
    let steps = options.progressive_steps;
    if !(1..=MAX_PROGRESSIVE_STEPS).contains(&steps) {
        return Err(ImagingError::Options {
            field: "progressive_steps",
            reason: format!("{steps} is not between 1 and {MAX_PROGRESSIVE_STEPS}"),
        });
    }
    let scanner = Scanner::new(options.setup, options.model)?;
    let calibrated: Vec<ScanSample> = samples
        .iter()
        .map(|&sample| options.calibration.apply(sample))
        .collect();
    let reconstruction = reconstruct(&calibrated, &scanner);
    let xyz: Vec<[f64; 3]> = reconstruction
        .cloud
        .points
        .iter()
        .map(|p| [p.x_mm, p.y_mm, p.z_mm])
        .collect();
    let feature = options.feature.map(|params| feature_height(&xyz, &params));
    let plane = match (&feature, options.subtract_plane) {
        (Some(Ok(f)), true) => Some(f.plane.clone()),
        (_, true) => Some(fit_plane(&xyz, &options.ransac)?),
        (_, false) => None,
    };
    let spec = GridSpec::covering(xyz.iter().map(|p| (p[0], p[1])), options.pitch_mm)?;
    let heights = xyz.iter().map(|&p| {
        let h = plane.as_ref().map_or(p[2], |f| f.plane.height_mm(p));
        (p[0], p[1], h)
    });
    let mut map = grid_points(heights, spec, options.grid);
    let fill = fill_missing(&mut map, options.fill);
    Ok(Imaging {
        reconstruction,
        map,
        fill,
        plane,
        feature,
        progressive: Vec::new(),
        truth: None,
        options: *options,
    })
}

/// The JSON report of an imaging run.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ImagingReport {
    /// The reconstruction model's name.
    pub model: String,
    /// Samples in.
    pub samples: usize,
    /// Points out.
    pub points: usize,
    /// Samples without a distance.
    pub missing_samples: usize,
    /// Samples with a non-finite value.
    pub non_finite_samples: usize,
    /// Missing distances by reason, as the recording gave them (see
    /// [`super::recording::Recording::missing_by_reason`]).
    pub missing_by_reason: BTreeMap<String, usize>,
    /// What the map holds: `z_mm` or `height_above_plane_mm`.
    pub map_quantity: String,
    /// The grid.
    pub grid: GridSpec,
    /// Cells measured, as a fraction of all cells.
    pub coverage_fraction: f64,
    /// The map's (min, max), mm.
    pub map_range_mm: Option<(f64, f64)>,
    /// The fill.
    pub fill: FillReport,
    /// The subtracted plane.
    pub plane: Option<PlaneFit>,
    /// The feature height.
    pub feature: Option<FeatureHeight>,
    /// Why the feature height could not be measured, when it could not.
    pub feature_error: Option<String>,
    /// The true scene scored against, if any.
    pub truth: Option<String>,
    /// The z_s map's error against the true surface over the whole scan, when one was given.
    pub truth_error: Option<ProgressivePoint>,
    /// Coverage (and error against the truth, when given) after each checkpoint of scan time.
    pub progressive: Vec<ProgressivePoint>,
    /// The options used.
    pub options: ImagingOptions,
    /// The files written, relative to the output folder.
    pub files: Vec<String>,
}

/// File names [`write_outputs`] uses inside its folder.
pub const OUTPUT_FILES: [&str; 4] = [
    "points.ply",
    "height_map.png",
    "height_map.csv",
    "progressive.svg",
];

/// The height map PNG is drawn at least this many pixels along its longer side (whole
/// pixels per cell, at most [`MAX_PIXELS_PER_CELL`]): a 0.1 mm grid over a 12 mm field is
/// 480 px, not 120.
pub const MIN_PNG_SIDE_PX: usize = 480;
/// The most pixels per height map cell.
pub const MAX_PIXELS_PER_CELL: usize = 8;

/// Writes `points.ply`, `height_map.png`, `height_map.csv` and `progressive.svg` into `dir`
/// (created if needed) and returns the report for the caller's `report.json`;
/// `missing_by_reason` is copied into it.
///
/// # Errors
/// The first file that cannot be written.
pub fn write_outputs(
    imaging: &Imaging,
    dir: &Path,
    encoding: PlyEncoding,
    missing_by_reason: &BTreeMap<String, usize>,
) -> Result<ImagingReport, ImagingError> {
    let io = |path: PathBuf| move |source| ImagingError::Io { path, source };
    std::fs::create_dir_all(dir).map_err(io(dir.to_owned()))?;
    let [ply, png, csv, svg] = OUTPUT_FILES.map(|f| dir.join(f));
    write_ply_file(&ply, &imaging.reconstruction.cloud, encoding)?;
    let longer_side = imaging.map.spec.nx.max(imaging.map.spec.ny).max(1);
    let pixels_per_cell = MIN_PNG_SIDE_PX
        .div_ceil(longer_side)
        .clamp(1, MAX_PIXELS_PER_CELL);
    let map_range_mm = imaging.map.write_png(&png, pixels_per_cell)?;
    let file = std::fs::File::create(&csv).map_err(io(csv.clone()))?;
    imaging
        .map
        .write_csv(std::io::BufWriter::new(file))
        .map_err(io(csv.clone()))?;
    let mut files: Vec<String> = OUTPUT_FILES[..3].iter().map(|f| f.to_string()).collect();
    if !imaging.progressive.is_empty() {
        let mut comparison = ProgressiveComparison::new(
            imaging.options.model,
            None,
            imaging.map.spec,
            imaging.options.grid,
            imaging.options.fill,
        );
        comparison.runs.push(ProgressiveRun {
            name: "this scan".into(),
            samples: samples_in(&imaging.reconstruction),
            missing_samples: imaging.reconstruction.missing_samples,
            points: imaging.progressive.clone(),
        });
        comparison.draw(&svg)?;
        files.push(OUTPUT_FILES[3].to_string());
    }
    let r = &imaging.reconstruction;
    let report = ImagingReport {
        model: r.cloud.model.name().to_string(),
        samples: samples_in(r),
        points: r.cloud.points.len(),
        missing_samples: r.missing_samples,
        non_finite_samples: r.non_finite_samples,
        missing_by_reason: missing_by_reason.clone(),
        map_quantity: if imaging.plane.is_some() {
            "height_above_plane_mm"
        } else {
            "z_mm"
        }
        .into(),
        grid: imaging.map.spec,
        coverage_fraction: imaging.map.coverage_fraction(),
        map_range_mm,
        fill: imaging.fill,
        plane: imaging.plane.clone(),
        feature: imaging.feature.clone().and_then(Result::ok),
        feature_error: imaging
            .feature
            .as_ref()
            .and_then(|f| f.as_ref().err().map(ToString::to_string)),
        truth: imaging.truth.clone(),
        truth_error: imaging.truth_error(),
        progressive: imaging.progressive.clone(),
        options: imaging.options,
        files,
    };
    Ok(report)
}

/// Samples that went into a reconstruction.
fn samples_in(r: &Reconstruction) -> usize {
    r.cloud.points.len() + r.missing_samples + r.non_finite_samples
}
