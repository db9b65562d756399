//! `scanhil reconstruct`: a recording of samples to a point cloud, a height map and a report.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use scanhil_controller::imaging::feature::{FeatureParams, FeatureSelection, Region};
use scanhil_controller::imaging::fill::FillMethod;
use scanhil_controller::imaging::grid::{GridError, GridMethod};
use scanhil_controller::imaging::pipeline::{
    Figures, ImagingError, ImagingOptions, image_samples, write_outputs,
};
use scanhil_controller::imaging::ply::PlyEncoding;
use scanhil_controller::imaging::progressive::ScanFrame;
use scanhil_controller::imaging::ransac::RansacParams;
use scanhil_controller::imaging::recording::read_recording;
use scanhil_controller::rig::Rig;
use scanhil_geometry::GeometryModel;
use scanhil_protocol::ild::MeasuringRange;
use scanhil_scene::truth::TrueScene;

/// Arguments of `scanhil reconstruct`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The recording: CSV (header t_s,d_alpha_rad,d_beta_rad,z_meas_mm|ild_raw) or JSON lines.
    input: PathBuf,
    /// Folder for points.ply, height_map.png/.csv, progressive.svg, snapshots.png,
    /// profiles.svg/.csv and report.json.
    #[arg(long, default_value = "reconstruction")]
    out_dir: PathBuf,
    /// Reconstruction model: the paper's eq. 1-3 or the exact reflection.
    #[arg(long, value_enum, default_value_t = Model::SmallAngle)]
    model: Model,
    /// PLY data encoding.
    #[arg(long, value_enum, default_value_t = Encoding::Binary)]
    ply: Encoding,
    /// Height map cell size, mm.
    #[arg(long, default_value_t = 0.1, allow_negative_numbers = true)]
    pitch_mm: f64,
    /// Gridding: per-cell mean, or inverse-distance weighting within --radius-pitches.
    #[arg(long, value_enum, default_value_t = Gridding::InverseDistance)]
    grid: Gridding,
    /// Inverse-distance search radius, in cell pitches.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    radius_pitches: f64,
    /// How to fill cells no sample reached.
    #[arg(long, value_enum, default_value_t = Fill::None)]
    fill: Fill,
    /// Map heights above the RANSAC base plane instead of z_s.
    #[arg(long)]
    subtract_plane: bool,
    /// Measure the height of a feature above the base plane.
    #[arg(long)]
    feature_height: bool,
    /// Feature points: higher than this above the plane, mm.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    min_height_mm: f64,
    /// Feature points: farther than this from any lower point, mm.
    #[arg(long, default_value_t = 0.3, allow_negative_numbers = true)]
    edge_margin_mm: f64,
    /// Feature points: those inside this rectangle (x_min,x_max,y_min,y_max in mm) instead.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        requires = "feature_height"
    )]
    feature_rect: Option<Vec<f64>>,
    /// Fit the base plane only to points inside this rectangle (x_min,x_max,y_min,y_max).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        requires = "feature_height"
    )]
    plane_rect: Option<Vec<f64>>,
    /// RANSAC inlier distance, mm.
    #[arg(long, default_value_t = 0.3, allow_negative_numbers = true)]
    ransac_threshold_mm: f64,
    /// RANSAC seed.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    seed: u64,
    /// Score the z_s map against the surface of this scene file (ground truth), after each
    /// of --progressive-steps parts of the scan.
    #[arg(long)]
    truth_scene: Option<PathBuf>,
    /// Checkpoints of coverage and error against scan time (1 to 1000).
    #[arg(long, default_value_t = 10, allow_negative_numbers = true)]
    progressive_steps: usize,
    /// The rig description: scanner setup, calibration and sensor range (default: the
    /// paper's setup, no correction, the ILD 2300-100's range).
    #[arg(long)]
    rig: Option<PathBuf>,
    /// Start of the sensor's measuring range (for ild_raw), mm; overrides the rig's.
    #[arg(long, allow_negative_numbers = true)]
    range_start_mm: Option<f64>,
    /// Span of the sensor's measuring range (for ild_raw), mm; overrides the rig's.
    #[arg(long, allow_negative_numbers = true)]
    range_span_mm: Option<f64>,
}

/// The widest inverse-distance search radius, in cell pitches.
const MAX_RADIUS_PITCHES: f64 = 20.0;

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Model {
    SmallAngle,
    ExactReflection,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Encoding {
    Binary,
    Ascii,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Gridding {
    CellMean,
    InverseDistance,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Fill {
    None,
    Nearest,
    Diffusion,
}

/// The rectangle `x_min,x_max,y_min,y_max` given to `flag`, checked.
fn rect(flag: &str, v: &[f64]) -> anyhow::Result<Region> {
    if v.len() != 4 {
        anyhow::bail!(
            "{flag}: {} numbers given; a rectangle is 4, x_min,x_max,y_min,y_max in mm",
            v.len()
        );
    }
    let region = Region::Rect {
        x_min_mm: v[0],
        x_max_mm: v[1],
        y_min_mm: v[2],
        y_max_mm: v[3],
    };
    region
        .check()
        .map_err(|reason| anyhow::anyhow!("{flag} {v:?}: {reason}"))?;
    Ok(region)
}

/// The command-line flag that sets a field of [`FeatureParams::check`]'s answer.
fn feature_flag(field: &str) -> &str {
    match field {
        "selection.min_height_mm" => "--min-height-mm",
        "selection.edge_margin_mm" => "--edge-margin-mm",
        "ransac" => "--ransac-threshold-mm",
        other => other,
    }
}

/// Runs `scanhil reconstruct`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if !(args.radius_pitches.is_finite()
        && args.radius_pitches > 0.0
        && args.radius_pitches <= MAX_RADIUS_PITCHES)
    {
        anyhow::bail!(
            "--radius-pitches {}: must be positive and at most {MAX_RADIUS_PITCHES} (each cell \
             searches that far around it)",
            args.radius_pitches
        );
    }
    let rig = args.rig.as_deref().map(Rig::load).transpose()?;
    let rig_range = rig
        .as_ref()
        .and_then(|rig| rig.sensor)
        .map_or(MeasuringRange::ILD2300_100, |sensor| sensor.range());
    let range = MeasuringRange {
        start_mm: args.range_start_mm.unwrap_or(rig_range.start_mm),
        span_mm: args.range_span_mm.unwrap_or(rig_range.span_mm),
    };
    if !(range.start_mm.is_finite() && range.span_mm.is_finite() && range.span_mm > 0.0) {
        anyhow::bail!(
            "--range-start-mm {} / --range-span-mm {}: the range must be finite with a \
             positive span",
            range.start_mm,
            range.span_mm
        );
    }
    let truth = args
        .truth_scene
        .as_deref()
        .map(TrueScene::from_scene_file)
        .transpose()?;
    let recording = read_recording(&args.input, &range)?;
    let ransac = RansacParams {
        inlier_threshold_mm: args.ransac_threshold_mm,
        seed: args.seed,
        ..RansacParams::default()
    };
    let feature = if args.feature_height {
        let params = FeatureParams {
            plane_region: match &args.plane_rect {
                Some(v) => rect("--plane-rect", v)?,
                None => Region::All,
            },
            selection: match &args.feature_rect {
                Some(v) => FeatureSelection::Inside {
                    region: rect("--feature-rect", v)?,
                },
                None => FeatureSelection::AboveThreshold {
                    min_height_mm: args.min_height_mm,
                    edge_margin_mm: args.edge_margin_mm,
                },
            },
            ransac,
        };
        params
            .check()
            .map_err(|(field, reason)| anyhow::anyhow!("{}: {reason}", feature_flag(field)))?;
        Some(params)
    } else {
        None
    };
    if args.subtract_plane {
        ransac.check().context("--ransac-threshold-mm")?;
    }
    let options = ImagingOptions {
        model: match args.model {
            Model::SmallAngle => GeometryModel::SmallAngle,
            Model::ExactReflection => GeometryModel::ExactReflection,
        },
        pitch_mm: args.pitch_mm,
        grid: match args.grid {
            Gridding::CellMean => GridMethod::CellMean,
            Gridding::InverseDistance => GridMethod::InverseDistance {
                radius_pitches: args.radius_pitches,
                power: 2.0,
            },
        },
        fill: match args.fill {
            Fill::None => FillMethod::None,
            Fill::Nearest => FillMethod::Nearest,
            Fill::Diffusion => FillMethod::Diffusion,
        },
        subtract_plane: args.subtract_plane,
        ransac,
        feature,
        progressive_steps: args.progressive_steps,
        ..ImagingOptions::default()
    };
    let options = match &rig {
        Some(rig) => ImagingOptions {
            setup: rig.scanner.setup,
            calibration: rig.scanner.calibration,
            ..options
        },
        None => options,
    };
    // A pitch too fine for the points' area is the flag's fault: named, before any grid is
    // allocated (the grid's size is checked before its cells are).
    let mut imaging = image_samples(&recording.samples, &options).map_err(|error| match error {
        ImagingError::Grid(grid @ GridError::TooLarge { .. }) => {
            anyhow::anyhow!("--pitch-mm {}: {grid}", args.pitch_mm)
        }
        other => anyhow::Error::new(other).context(format!("imaging {}", args.input.display())),
    })?;
    let frame = ScanFrame::spanning(recording.samples.iter().map(|s| s.t_s));
    imaging.score_progressive(truth.as_ref(), frame);
    let encoding = match args.ply {
        Encoding::Binary => PlyEncoding::BinaryLittleEndian,
        Encoding::Ascii => PlyEncoding::Ascii,
    };
    let report = write_outputs(
        &imaging,
        &args.out_dir,
        encoding,
        &recording.missing_by_reason,
        Figures::Drawn,
    )?;
    let json = args.out_dir.join("report.json");
    let report_json = serde_json::json!({
        "input": args.input.display().to_string(),
        "rig": rig.as_ref().map(Rig::to_json),
        "imaging": &report,
    });
    scanhil_protocol::whole_file::write_file(
        &json,
        serde_json::to_string_pretty(&report_json).context("formatting report.json")? + "\n",
    )
    .with_context(|| format!("writing {}", json.display()))?;
    scanhil_protocol::outln!(
        "{}: {} samples, {} points ({} missing), model {}, {}x{} cells of {} mm, coverage {:.3}",
        args.input.display(),
        report.samples,
        report.points,
        report.missing_samples,
        report.model,
        report.grid.nx,
        report.grid.ny,
        report.grid.pitch_mm,
        report.coverage_fraction
    )?;
    if let Some(f) = &report.feature {
        scanhil_protocol::outln!(
            "feature height {:.4} mm, std {:.4} mm over {} points (plane: {} inliers, tilt {:.3} deg)",
            f.height_mm,
            f.std_mm,
            f.points,
            f.plane.inliers,
            f.plane.plane.tilt_rad().to_degrees()
        )?;
    }
    if let Some(e) = &report.truth_error {
        let mm = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.4}"));
        scanhil_protocol::outln!(
            "against the true surface: measured cells RMS {} mm, median |error| {} mm, max {} mm",
            mm(e.covered_rms_mm),
            mm(e.covered_median_abs_mm),
            mm(e.covered_max_mm)
        )?;
    }
    scanhil_protocol::outln!("wrote {}", args.out_dir.display())?;
    for (file, why) in &report.failed_files {
        eprintln!("error: {file} not written: {why}");
    }
    if !report.failed_files.is_empty() {
        return Ok(ExitCode::FAILURE);
    }
    if let Some(error) = &report.feature_error {
        eprintln!("error: feature height: {error}");
        return Ok(ExitCode::FAILURE);
    }
    Ok(ExitCode::SUCCESS)
}
