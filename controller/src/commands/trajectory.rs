//! `scanhil trajectory`: the figures a trajectory's definition gives (frame rate, line
//! spacing), as JSON, and optionally a plot of one frame's path.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use scanhil_controller::trajectory::{SensingAxis, Trajectory};
use scanhil_protocol::plant_units::FULL_RANGE_DEG;
use scanhil_report::{Axis, Chart, Series, draw_charts};

/// Arguments of `scanhil trajectory`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A Lissajous scan: ALPHA_HZ,BETA_HZ (the paper's is 52,27; a leading `-` is a
    /// number's, never a flag's: `-52,27` reaches the trajectory's own check).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        conflicts_with_all = ["raster", "file"]
    )]
    lissajous: Option<Vec<f64>>,
    /// Phase of beta against alpha for --lissajous, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    phase_deg: f64,
    /// A raster scan: SLOW_HZ,FAST_HZ (the paper's is 2,34).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        conflicts_with = "file"
    )]
    raster: Option<Vec<f64>>,
    /// The axis carrying the slow triangle for --raster.
    #[arg(long, value_enum, default_value = "beta")]
    slow_axis: SensingAxis,
    /// A trajectory JSON file (as in a scenario's "trajectory").
    #[arg(long)]
    file: Option<PathBuf>,
    /// Scan range X_MM,Y_MM (x along beta, y along alpha) for spacings in mm, e.g. 11.5,18.5.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    range_mm: Option<Vec<f64>>,
    /// Plot the path of one frame (or 1 s) as beta (x) against alpha (y) in degrees.
    #[arg(long)]
    plot: Option<PathBuf>,
}

/// Runs `scanhil trajectory`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    for (flag, values) in [
        ("--lissajous", &args.lissajous),
        ("--raster", &args.raster),
        ("--range-mm", &args.range_mm),
    ] {
        if let Some(v) = values {
            anyhow::ensure!(
                v.len() == 2,
                "{flag} takes two comma-separated numbers, got {v:?}"
            );
        }
    }
    let full = FULL_RANGE_DEG.to_radians();
    let trajectory = match (&args.lissajous, &args.raster, &args.file) {
        (Some(f), _, _) => Trajectory::Lissajous {
            alpha_hz: f[0],
            beta_hz: f[1],
            alpha_amplitude_rad: full,
            beta_amplitude_rad: full,
            relative_phase_rad: args.phase_deg.to_radians(),
        },
        (_, Some(f), _) => Trajectory::Raster {
            slow_hz: f[0],
            fast_hz: f[1],
            slow_axis: args.slow_axis,
            alpha_amplitude_rad: full,
            beta_amplitude_rad: full,
            fast_max_harmonic: None,
        },
        (_, _, Some(path)) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            serde_json::from_str(&text)
                .with_context(|| format!("parsing the trajectory in {}", path.display()))?
        }
        _ => anyhow::bail!(
            "give one of --lissajous ALPHA_HZ,BETA_HZ, --raster SLOW_HZ,FAST_HZ or --file FILE"
        ),
    };
    // The file's checks (no control rate here, so no Nyquist limit), naming where the value
    // came from.
    trajectory.check(f64::INFINITY).map_err(|(field, reason)| {
        let source = match (&args.lissajous, &args.raster, &args.file) {
            (Some(_), _, _) => "--lissajous".to_owned(),
            (_, Some(_), _) => "--raster".to_owned(),
            (_, _, Some(path)) => format!("{}: field `{field}`", path.display()),
            _ => field.to_owned(),
        };
        anyhow::anyhow!("{source}: {reason}")
    })?;
    if let Some(range) = &args.range_mm {
        for value in range {
            anyhow::ensure!(
                value.is_finite() && *value > 0.0,
                "--range-mm: {value} mm must be positive and finite"
            );
        }
    }
    let range = args.range_mm.as_ref().map(|r| (r[0], r[1]));
    let figures = trajectory.figures(range);
    scanhil_protocol::outln!(
        "{}",
        serde_json::to_string_pretty(
            &serde_json::json!({ "trajectory": trajectory, "figures": figures })
        )?
    )?;
    if let Some(path) = &args.plot {
        let duration = figures.frame_time_s.unwrap_or(1.0).min(10.0);
        let n = 20_000;
        let points = (0..=n)
            .map(|i| trajectory.reference_rad(duration * f64::from(i) / f64::from(n)))
            .map(|r| (r.beta.to_degrees(), r.alpha.to_degrees()))
            .collect();
        let chart = Chart {
            title: format!("{} path over {duration} s", figures.kind),
            x_label: "beta (spot along x) [deg]".into(),
            y_label: "alpha (spot along y) [deg]".into(),
            x_axis: Axis::Linear,
            y_axis: Axis::Linear,
            series: vec![Series {
                label: "reference".into(),
                points,
                markers: false,
            }],
        };
        draw_charts(path, &[chart]).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}
