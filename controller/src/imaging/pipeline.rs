//! The whole imaging chain on one set of samples: reconstruct, grid, fill, fit the base
//! plane, measure a feature, and write PLY + PNG + CSV + JSON. `scanhil reconstruct` and the
//! loop's `scan` both call [`image_samples`] and [`write_outputs`].

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use scanhil_geometry::{GeometryModel, Scanner, ScannerSetup};

use super::feature::{FeatureError, FeatureHeight, FeatureParams, feature_height};
use super::fill::{FillMethod, FillReport, fill_missing};
use super::grid::{GridError, GridMethod, GridSpec, HeightMap, grid_points};
use super::ply::{PlyEncoding, PlyError, write_ply_file};
use super::progressive::{ProgressivePoint, ScanScene, progressive_errors};
use super::ransac::{PlaneFit, RansacError, RansacParams, fit_plane};
use super::reconstruct::{DEFAULT_MODEL, Reconstruction, ScanSample, reconstruct};

/// What to make of the samples.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ImagingOptions {
    /// The reconstruction model.
    pub model: GeometryModel,
    /// The scanner's mechanical setup.
    pub setup: ScannerSetup,
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
}

impl Default for ImagingOptions {
    /// Eq. 1-3, the paper's setup, 0.1 mm cells (about the 130 um spot), inverse-distance
    /// gridding, no fill, z_s mapped, no feature.
    fn default() -> Self {
        ImagingOptions {
            model: DEFAULT_MODEL,
            setup: ScannerSetup::default(),
            pitch_mm: 0.1,
            grid: GridMethod::default(),
            fill: FillMethod::None,
            subtract_plane: false,
            ransac: RansacParams::default(),
            feature: None,
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
    /// The feature measurement.
    pub feature: Option<FeatureHeight>,
    /// The z_s map's error against a known surface, after [`Imaging::score_against`].
    pub truth_error: Option<ProgressivePoint>,
    /// The options used.
    pub options: ImagingOptions,
}

impl Imaging {
    /// Scores the z_s height map (gridded and filled as the options say, whether or not the
    /// map here is plane-subtracted) against the true surface of `scene`, over all the
    /// points: see [`progressive_errors`] for the figures.
    pub fn score_against(&mut self, scene: &impl ScanScene) {
        let points = &self.reconstruction.cloud.points;
        let t_end_s = points.iter().map(|p| p.t_s).fold(0.0, f64::max);
        self.truth_error = progressive_errors(
            points,
            self.map.spec,
            self.options.grid,
            self.options.fill,
            &[t_end_s],
            |x, y| scene.true_z_mm(x, y),
        )
        .pop();
    }
}

/// Why imaging failed.
#[derive(Debug, thiserror::Error)]
pub enum ImagingError {
    /// The scanner setup is unusable.
    #[error("scanner setup: {0}")]
    Setup(#[from] scanhil_geometry::SetupError),
    /// No grid could be laid over the points.
    #[error("height map: {0}")]
    Grid(#[from] GridError),
    /// The base plane could not be fitted.
    #[error("base plane: {0}")]
    Plane(#[from] RansacError),
    /// The feature could not be measured.
    #[error("feature: {0}")]
    Feature(#[from] FeatureError),
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

/// Reconstructs, grids, fills and measures `samples`.
pub fn image_samples(
    samples: &[ScanSample],
    options: &ImagingOptions,
) -> Result<Imaging, ImagingError> {
    let scanner = Scanner::new(options.setup, options.model)?;
    let reconstruction = reconstruct(samples, &scanner);
    let xyz: Vec<[f64; 3]> = reconstruction
        .cloud
        .points
        .iter()
        .map(|p| [p.x_mm, p.y_mm, p.z_mm])
        .collect();
    let feature = options
        .feature
        .map(|params| feature_height(&xyz, &params))
        .transpose()?;
    let plane = match (&feature, options.subtract_plane) {
        (Some(f), true) => Some(f.plane.clone()),
        (None, true) => Some(fit_plane(&xyz, &options.ransac)?),
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
        truth_error: None,
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
    /// The z_s map's error against the true surface, when one was given.
    pub truth_error: Option<ProgressivePoint>,
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
    "report.json",
];

/// Writes `points.ply`, `height_map.png`, `height_map.csv` and `report.json` into `dir`
/// (created if needed) and returns the report; `missing_by_reason` is copied into it.
pub fn write_outputs(
    imaging: &Imaging,
    dir: &Path,
    encoding: PlyEncoding,
    missing_by_reason: &BTreeMap<String, usize>,
) -> Result<ImagingReport, ImagingError> {
    let io = |path: PathBuf| move |source| ImagingError::Io { path, source };
    std::fs::create_dir_all(dir).map_err(io(dir.to_owned()))?;
    let [ply, png, csv, json] = OUTPUT_FILES.map(|f| dir.join(f));
    write_ply_file(&ply, &imaging.reconstruction.cloud, encoding)?;
    let map_range_mm = imaging.map.write_png(&png, 1)?;
    let file = std::fs::File::create(&csv).map_err(io(csv.clone()))?;
    imaging
        .map
        .write_csv(std::io::BufWriter::new(file))
        .map_err(io(csv.clone()))?;
    let r = &imaging.reconstruction;
    let report = ImagingReport {
        model: r.cloud.model.name().to_string(),
        samples: r.cloud.points.len() + r.missing_samples + r.non_finite_samples,
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
        feature: imaging.feature.clone(),
        truth_error: imaging.truth_error,
        options: imaging.options,
        files: OUTPUT_FILES.iter().map(|f| f.to_string()).collect(),
    };
    let text = serde_json::to_string_pretty(&report).unwrap_or_default();
    std::fs::write(&json, text + "\n").map_err(io(json.clone()))?;
    Ok(report)
}
