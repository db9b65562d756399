//! The one imaging chain on one set of samples: calibrate, reconstruct with the rig's
//! geometry, grid, fill, fit the base plane, measure a feature, score against a true surface
//! over scan time, and write PLY, the height map (PNG for people, CSV), the progressive plot,
//! the snapshots (Fig. 6) and the profiles (Fig. 10). `scanhil reconstruct` and
//! the loop's `scan` both call [`image_samples`], [`Imaging::score_progressive`] and
//! [`write_outputs`], so both write the same files and the same [`ImagingReport`] fields; each
//! puts the report into its own `report.json`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use scanhil_geometry::{GeometryModel, Scanner, ScannerSetup};
use scanhil_protocol::whole_file;
use scanhil_scene::truth::TrueScene;

use super::feature::{FeatureError, FeatureHeight, FeatureParams, feature_height};
use super::fill::{FillMethod, FillReport, fill_missing};
use super::grid::{GridError, GridMethod, GridSpec, HeightMap, grid_points};
use super::ply::{PlyEncoding, PlyError, write_ply_file};
use super::point::Point3;
use super::profiles::{ProfileCentre, draw_profiles, sections};
use super::progressive::{
    ProgressiveComparison, ProgressivePoint, ProgressiveRun, ScanFrame, progressive_errors,
};
use super::ransac::{PlaneFit, RansacError, RansacParams, fit_plane};
use super::reconstruct::{DEFAULT_MODEL, Reconstruction, ScanSample, reconstruct_each};
use super::snapshots::{SNAPSHOT_FRACTIONS, SnapshotCoverage, draw_snapshots, snapshots};
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
    /// The true scene scored against, if any (the profiles' true surface too).
    pub truth: Option<TrueScene>,
    /// The scan's frame: the time base of the checkpoints and snapshots (set by
    /// [`Imaging::score_progressive`]; without it the points' time span).
    pub frame: Option<ScanFrame>,
    /// The options used.
    pub options: ImagingOptions,
}

impl Imaging {
    /// Grids the z_s map (as the options say, whether or not the map here is
    /// plane-subtracted) after `progressive_steps` equal parts of `frame` and scores each
    /// against `truth` when given (coverage only without): see [`progressive_errors`] for the
    /// figures. The last checkpoint is the whole frame; checkpoint times are counted from the
    /// frame's start. The whole-image figures are of the preview a person sees: missing cells
    /// filled as the options say, or from the nearest measured cell when they say none (a
    /// Lissajous frame's early overview against a raster's first lines, the paper's Fig. 6).
    /// Keeps `frame` (the snapshots' time base) and `truth` (the profiles' true surface) for
    /// [`write_outputs`].
    pub fn score_progressive(&mut self, truth: Option<&TrueScene>, frame: ScanFrame) {
        let steps = self.options.progressive_steps;
        let checkpoints: Vec<f64> = (1..=steps)
            .map(|i| frame.time_at(i as f64 / steps as f64))
            .collect();
        self.progressive = progressive_errors(
            &self.reconstruction.cloud.points,
            self.map.spec,
            self.options.grid,
            match self.options.fill {
                FillMethod::None => FillMethod::Nearest,
                fill => fill,
            },
            &checkpoints,
            |x, y| truth.and_then(|t| t.z_mm(x, y)),
        );
        for point in &mut self.progressive {
            point.t_s -= frame.start_s;
        }
        self.frame = Some(frame);
        self.truth = truth.cloned();
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

/// Calibrates, reconstructs, grids, fills and measures `samples`: [`reconstruct_samples`],
/// then [`image_points`].
///
/// # Errors
/// [`ImagingError`]: an unusable setup or option, no point to lay a grid over, a base plane
/// that cannot be fitted for `subtract_plane`. A feature that cannot be measured is not an
/// error here: it is kept in [`Imaging::feature`].
pub fn image_samples(
    samples: &[ScanSample],
    options: &ImagingOptions,
) -> Result<Imaging, ImagingError> {
    image_points(
        reconstruct_samples(samples.iter().copied(), options)?,
        options,
    )
}

/// Calibrates and reconstructs samples as they come, with the options' setup, model and
/// calibration (a scan's frame, paired as it is read, is never held as samples).
///
/// # Errors
/// [`ImagingError`]: an unusable setup or option.
pub fn reconstruct_samples(
    samples: impl IntoIterator<Item = ScanSample>,
    options: &ImagingOptions,
) -> Result<Reconstruction, ImagingError> {
    check_options(options)?;
    let scanner = Scanner::new(options.setup, options.model)?;
    Ok(reconstruct_each(
        samples
            .into_iter()
            .map(|sample| options.calibration.apply(sample)),
        &scanner,
    ))
}

/// The options no imaging can use.
fn check_options(options: &ImagingOptions) -> Result<(), ImagingError> {
    let steps = options.progressive_steps;
    if !(1..=MAX_PROGRESSIVE_STEPS).contains(&steps) {
        return Err(ImagingError::Options {
            field: "progressive_steps",
            reason: format!("{steps} is not between 1 and {MAX_PROGRESSIVE_STEPS}"),
        });
    }
    if let Some(feature) = &options.feature {
        feature
            .check()
            .map_err(|(field, reason)| ImagingError::Options {
                field: "feature",
                reason: format!("{field}: {reason}"),
            })?;
    }
    if options.subtract_plane {
        options.ransac.check()?;
    }
    Ok(())
}

/// Grids, fills and measures reconstructed points, read in place: no copy of the frame's
/// points is made, so the imaging's working memory is the grid's and the feature's, not
/// another frame.
///
/// # Errors
/// [`ImagingError`]: an unusable option, no point to lay a grid over, a base plane that
/// cannot be fitted for `subtract_plane`. A feature that cannot be measured is not an error
/// here: it is kept in [`Imaging::feature`].
pub fn image_points(
    reconstruction: Reconstruction,
    options: &ImagingOptions,
) -> Result<Imaging, ImagingError> {
    check_options(options)?;
    let points = &reconstruction.cloud.points;
    let feature = options
        .feature
        .map(|params| feature_height(points, &params));
    let plane = match (&feature, options.subtract_plane) {
        (Some(Ok(f)), true) => Some(f.plane.clone()),
        (_, true) => Some(fit_plane(points, &options.ransac)?),
        (_, false) => None,
    };
    let spec = GridSpec::covering(points.iter().map(|p| (p.x_mm, p.y_mm)), options.pitch_mm)?;
    let heights = points.iter().map(|p| {
        let h = plane
            .as_ref()
            .map_or(p.z_mm, |f| f.plane.height_mm(p.xyz_mm()));
        (p.x_mm, p.y_mm, h)
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
        frame: None,
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
    /// The frame the checkpoints and snapshots count from.
    #[serde(default)]
    pub frame: Option<ScanFrame>,
    /// Coverage of each snapshot in `snapshots.png`.
    #[serde(default)]
    pub snapshots: Vec<SnapshotCoverage>,
    /// Where the sections in `profiles.svg` and `profiles.csv` cross.
    #[serde(default)]
    pub profile_centre: Option<ProfileCentre>,
    /// The options used.
    pub options: ImagingOptions,
    /// The files written, relative to the output folder.
    pub files: Vec<String>,
    /// The files that could not be written, with why (each failed alone: the others were
    /// written).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub failed_files: BTreeMap<String, String>,
}

/// The point cloud (with each point's time: the snapshots are made again from it).
pub const POINTS_PLY: &str = "points.ply";
/// The height map for people: axes and colour bar in mm, missing cells marked.
pub const HEIGHT_MAP_PNG: &str = "height_map.png";
/// The height map's cells.
pub const HEIGHT_MAP_CSV: &str = "height_map.csv";
/// Coverage and error against scan time.
pub const PROGRESSIVE_SVG: &str = "progressive.svg";
/// The map after 10, 25, 50 and 100 % of the frame (Fig. 6).
pub const SNAPSHOTS_PNG: &str = "snapshots.png";
/// The sections along x and y through the feature (Fig. 10).
pub const PROFILES_SVG: &str = "profiles.svg";
/// The sections' cells and true heights.
pub const PROFILES_CSV: &str = "profiles.csv";

/// Every file [`write_outputs`] writes.
pub const IMAGING_OUTPUTS: [&str; 7] = [
    POINTS_PLY,
    HEIGHT_MAP_PNG,
    HEIGHT_MAP_CSV,
    PROGRESSIVE_SVG,
    SNAPSHOTS_PNG,
    PROFILES_SVG,
    PROFILES_CSV,
];

impl ImagingReport {
    /// What the map's heights are, for a caption: `z_s (mm)` or `height above the base
    /// plane (mm)`.
    #[must_use]
    pub fn quantity_caption(&self) -> &'static str {
        quantity_caption(&self.map_quantity)
    }
}

/// The caption of a map quantity (`z_mm` or `height_above_plane_mm`).
fn quantity_caption(map_quantity: &str) -> &'static str {
    if map_quantity == "height_above_plane_mm" {
        "height above the base plane (mm)"
    } else {
        "z_s (mm)"
    }
}

/// Whether [`write_outputs`] draws the pictures (`height_map.png`, `progressive.svg`,
/// `snapshots.png`, `profiles.svg`); the report's figures are computed either way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Figures {
    /// Drawn.
    Drawn,
    /// Left out (the report's `map_range_mm`, the picture's colour range, is then `null`).
    LeftOut,
}

/// Writes into `dir` (created if needed) `points.ply`, `height_map.png`, `height_map.csv`,
/// `progressive.svg` (when scored), `snapshots.png` and `profiles.svg`/`profiles.csv` (the
/// pictures only when `figures` says so), and returns the report for the caller's
/// `report.json`; `missing_by_reason` is copied into it.
/// The snapshots count from [`Imaging::frame`]; the profiles cross at the feature's centre
/// (the map's centre without a feature) and carry the true surface when [`Imaging::truth`]
/// is known. A file that cannot be written does not stop the others: it is listed in
/// [`ImagingReport::failed_files`] with why.
///
/// # Errors
/// The folder cannot be created.
pub fn write_outputs(
    imaging: &Imaging,
    dir: &Path,
    encoding: PlyEncoding,
    missing_by_reason: &BTreeMap<String, usize>,
    figures: Figures,
) -> Result<ImagingReport, ImagingError> {
    let drawn = figures == Figures::Drawn;
    std::fs::create_dir_all(dir).map_err(|source| ImagingError::Io {
        path: dir.to_owned(),
        source,
    })?;
    let r = &imaging.reconstruction;
    let model = r.cloud.model.name();
    let mut written = Written::default();
    written.attempt(
        POINTS_PLY,
        whole(dir, POINTS_PLY, |path| {
            write_ply_file(path, &r.cloud, encoding)
        }),
    );
    let map_quantity = if imaging.plane.is_some() {
        "height_above_plane_mm"
    } else {
        "z_mm"
    };
    let caption = quantity_caption(map_quantity);
    let map_range_mm = drawn.then(|| {
        whole(dir, HEIGHT_MAP_PNG, |path| {
            imaging.map.draw_png(
                path,
                &format!(
                    "height map ({model} model, {})",
                    match imaging.options.fill {
                        FillMethod::None => "not filled",
                        FillMethod::Nearest => "filled: nearest",
                        FillMethod::Diffusion => "filled: diffusion",
                    }
                ),
                caption,
            )
        })
    });
    let map_range_mm = map_range_mm
        .and_then(|drawn| written.attempt(HEIGHT_MAP_PNG, drawn))
        .flatten();
    written.attempt(
        HEIGHT_MAP_CSV,
        write_csv_file(dir, HEIGHT_MAP_CSV, |out| imaging.map.write_csv(out)),
    );
    if drawn && !imaging.progressive.is_empty() {
        let mut comparison = ProgressiveComparison::new(
            imaging.options.model,
            None,
            imaging.map.spec,
            imaging.options.grid,
            imaging.options.fill,
        );
        comparison.runs.push(ProgressiveRun {
            name: "this scan".into(),
            samples: samples_in(r),
            missing_samples: r.missing_samples,
            points: imaging.progressive.clone(),
        });
        written.attempt(
            PROGRESSIVE_SVG,
            whole(dir, PROGRESSIVE_SVG, |path| comparison.draw(path)),
        );
    }
    let frame = imaging
        .frame
        .unwrap_or_else(|| ScanFrame::spanning(r.cloud.points.iter().map(|p| p.t_s)));
    let plane = imaging.plane.as_ref().map(|f| &f.plane);
    let snapshots = snapshots(
        &r.cloud.points,
        plane,
        imaging.map.spec,
        imaging.options.grid,
        frame,
        &SNAPSHOT_FRACTIONS,
    );
    if drawn {
        let picture = whole(dir, SNAPSHOTS_PNG, |path| {
            draw_snapshots(
                path,
                &format!(
                    "the map after parts of the {:.3} s frame (no fill)",
                    frame.length_s
                ),
                caption,
                &[(String::new(), snapshots.clone())],
            )
        });
        written.attempt(SNAPSHOTS_PNG, picture);
    }
    let spec = imaging.map.spec;
    let profile_centre = match &imaging.feature {
        Some(Ok(f)) => ProfileCentre {
            x_mm: f.centre_mm[0],
            y_mm: f.centre_mm[1],
            from: "feature_points".into(),
        },
        _ => ProfileCentre {
            x_mm: spec.x_min_mm + 0.5 * spec.nx as f64 * spec.pitch_mm,
            y_mm: spec.y_min_mm + 0.5 * spec.ny as f64 * spec.pitch_mm,
            from: "map_centre".into(),
        },
    };
    let profiles = sections(
        &imaging.map,
        (profile_centre.x_mm, profile_centre.y_mm),
        |x, y| {
            let z = imaging.truth.as_ref()?.z_mm(x, y)?;
            Some(plane.map_or(z, |plane| plane.height_mm([x, y, z])))
        },
    );
    if drawn {
        let picture = whole(dir, PROFILES_SVG, |path| {
            draw_profiles(path, caption, &[("this scan".to_string(), &profiles)])
        });
        written.attempt(PROFILES_SVG, picture);
    }
    written.attempt(
        PROFILES_CSV,
        write_csv_file(dir, PROFILES_CSV, |out| profiles.write_csv(out)),
    );
    let report = ImagingReport {
        model: model.to_string(),
        samples: samples_in(r),
        points: r.cloud.points.len(),
        missing_samples: r.missing_samples,
        non_finite_samples: r.non_finite_samples,
        missing_by_reason: missing_by_reason.clone(),
        map_quantity: map_quantity.into(),
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
        truth: imaging.truth.as_ref().map(|t| t.path.display().to_string()),
        truth_error: imaging.truth_error(),
        progressive: imaging.progressive.clone(),
        frame: Some(frame),
        snapshots: snapshots.iter().map(|s| s.coverage()).collect(),
        profile_centre: Some(profile_centre),
        options: imaging.options,
        files: written.files,
        failed_files: written.failed,
    };
    Ok(report)
}

/// The files [`write_outputs`] wrote and those it could not.
#[derive(Default)]
struct Written {
    files: Vec<String>,
    failed: BTreeMap<String, String>,
}

impl Written {
    /// `result` of writing `file`: its value, or `None` with the error listed.
    fn attempt<T>(&mut self, file: &str, result: Result<T, ImagingError>) -> Option<T> {
        match result {
            Ok(value) => {
                self.files.push(file.to_owned());
                Some(value)
            }
            Err(error) => {
                let why = scanhil_protocol::error_text::chain_text(&error);
                self.failed.insert(file.to_owned(), why);
                None
            }
        }
    }
}

/// Writes `file` in `dir` whole or not at all ([`whole_file`]): `write` writes the (temporary)
/// path it is given.
fn whole<T, E: Into<ImagingError>>(
    dir: &Path,
    file: &str,
    write: impl FnOnce(&Path) -> Result<T, E>,
) -> Result<T, ImagingError> {
    let path = dir.join(file);
    whole_file::write_whole(
        &path,
        |partial| write(partial).map_err(Into::into),
        |source| ImagingError::Io {
            path: path.clone(),
            source,
        },
    )
}

/// Writes CSV `file` in `dir` whole with `write` (buffered), naming the file in an error.
fn write_csv_file(
    dir: &Path,
    file: &str,
    write: impl FnOnce(std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), ImagingError> {
    whole(dir, file, |path| {
        std::fs::File::create(path)
            .and_then(|file| write(std::io::BufWriter::new(file)))
            .map_err(|source| ImagingError::Io {
                path: path.to_owned(),
                source,
            })
    })
}

/// Samples that went into a reconstruction.
fn samples_in(r: &Reconstruction) -> usize {
    r.cloud.points.len() + r.missing_samples + r.non_finite_samples
}
