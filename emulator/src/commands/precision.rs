//! `scanhil-emulator precision`: the integrators' error against the exact solution and their
//! run time per simulated second, as a table, JSON, and a log-log work-precision plot.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;

use super::print_or_broken_pipe;
use serde::Serialize;

use scanhil_emulator::drive_model::{DriveModel, DriveParts};
use scanhil_emulator::integrator::Method;
use scanhil_emulator::precision::{ALPHA_DRIVE_HZ, BETA_DRIVE_HZ, StudyRow, StudySetup, run_study};
use scanhil_emulator::scene::{Part, Scene};
use scanhil_report::{Axis, Chart, LogZero, Series, draw_charts};

/// Arguments of `scanhil-emulator precision`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Study the dynamics of this scene's active parts (default: the paper's mirror with
    /// cross-talk and amplifiers, at 20 kHz).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Simulated time per run, in s.
    #[arg(long, default_value_t = 0.1, allow_negative_numbers = true)]
    duration_s: f64,
    /// The largest sub-step count tried (powers of two from 1).
    #[arg(long, default_value_t = 256, allow_negative_numbers = true)]
    max_substeps: u32,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Draw the work-precision diagram (error against run time, log-log) to this .svg/.png.
    #[arg(long)]
    plot: Option<PathBuf>,
}

/// The JSON report.
#[derive(Debug, Serialize)]
struct Report {
    plant: String,
    active_parts: Vec<&'static str>,
    period_s: f64,
    duration_s: f64,
    drive: String,
    reference: &'static str,
    rows: Vec<StudyRow>,
}

const DEFAULT_PARTS: [Part; 3] = [Part::Axes, Part::CrossTalk, Part::Amplifier];

/// Runs `scanhil-emulator precision`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        args.duration_s.is_finite() && args.duration_s > 0.0,
        "--duration-s must be finite and > 0, got {}",
        args.duration_s
    );
    anyhow::ensure!(args.max_substeps >= 1, "--max-substeps must be at least 1");
    let (name, scene) = match &args.scene {
        Some(path) => {
            let scene = Scene::load(path)?;
            (scene.name.clone(), scene)
        }
        None => {
            let text = format!(
                r#"{{"name": "paper drive", "parts": [{}]}}"#,
                DEFAULT_PARTS.map(|p| format!("\"{p}\"")).join(",")
            );
            let scene = Scene::from_json_str(&text, std::path::Path::new("<built-in>"))
                .context("built-in study scene")?;
            ("paper drive (built-in)".to_string(), scene)
        }
    };
    anyhow::ensure!(
        scene.has(Part::Axes),
        "scene {name} has no `axes` part: there are no dynamics to integrate"
    );
    let model = DriveModel::build(&DriveParts::of_scene(&scene));
    let substeps = std::iter::successors(Some(1u32), |n| n.checked_mul(2))
        .take_while(|n| *n <= args.max_substeps)
        .collect();
    let setup = StudySetup {
        model,
        mirror: scene.mirror.clone(),
        period_s: scene.period_s(),
        duration_s: args.duration_s,
        substeps,
    };
    let report = Report {
        plant: name,
        active_parts: scene
            .active_parts()
            .into_iter()
            .filter(|p| p.is_linear_drive())
            .map(Part::name)
            .collect(),
        period_s: setup.period_s,
        duration_s: args.duration_s,
        drive: format!(
            "full-range sines held per period: {ALPHA_DRIVE_HZ} Hz on alpha, {BETA_DRIVE_HZ} Hz on beta"
        ),
        reference: "exact_zoh, 1 sub-step per period",
        rows: run_study(&setup),
    };
    if let Some(path) = &args.plot {
        draw_charts(path, &[work_precision_chart(&report)])
            .with_context(|| format!("cannot draw {}", path.display()))?;
    }
    if args.json {
        scanhil_protocol::outln!("{}", serde_json::to_string_pretty(&report)?)?;
    } else {
        print_or_broken_pipe(print_table(&report))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// The log-log chart of run time against error, a series per method. An error of 0 (the
/// reference row) has no place on a log axis: it is drawn [`LogZero::BELOW`] times below the
/// smallest nonzero error, and the axis label says so.
fn work_precision_chart(report: &Report) -> Chart {
    let zero = LogZero::of(report.rows.iter().filter_map(|r| r.max_error_urad));
    let series = Method::ALL
        .iter()
        .map(|&method| Series {
            label: method.name().to_string(),
            points: report
                .rows
                .iter()
                .filter(|r| r.method == method)
                .filter_map(|r| {
                    let error = r.max_error_urad?;
                    let drawn = zero.map_or(error, |zero| zero.place(error));
                    Some((r.run_time_per_sim_s?, drawn))
                })
                .collect(),
            markers: true,
        })
        .collect();
    let zero_note = zero.map_or_else(String::new, |zero| zero.note("the reference"));
    Chart {
        title: format!(
            "Work-precision, {} (Ta = {} us, parts: {})",
            report.plant,
            report.period_s * 1e6,
            report.active_parts.join(", ")
        ),
        x_label: "run time per simulated second [s/s]".into(),
        y_label: format!("max angle error vs exact [urad]{zero_note}"),
        x_axis: Axis::Log,
        y_axis: Axis::Log,
        series,
    }
}

fn print_table(report: &Report) -> std::io::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "precision study: {} | active parts: [{}] | Ta = {} us | {} s simulated",
        report.plant,
        report.active_parts.join(", "),
        report.period_s * 1e6,
        report.duration_s
    )?;
    writeln!(
        out,
        "drive: {}; reference: {}",
        report.drive, report.reference
    )?;
    writeln!(
        out,
        "{:<15} {:>8} {:>11} {:>14} {:>14} {:>16}",
        "method", "substeps", "step_us", "max_err_urad", "rms_err_urad", "run_s_per_sim_s"
    )?;
    for r in &report.rows {
        let cell = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| format!("{v:.3e}"));
        writeln!(
            out,
            "{:<15} {:>8} {:>11.4} {:>14} {:>14} {:>16}{}",
            r.method.name(),
            r.substeps,
            r.step_s * 1e6,
            cell(r.max_error_urad),
            cell(r.rms_error_urad),
            cell(r.run_time_per_sim_s),
            r.refused
                .as_ref()
                .map_or_else(String::new, |why| format!("  REFUSED: {why}")),
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(method: Method, substeps: u32, error_urad: Option<f64>, run_s: f64) -> StudyRow {
        StudyRow {
            method,
            substeps,
            step_s: 5e-5 / f64::from(substeps),
            max_error_urad: error_urad,
            rms_error_urad: error_urad,
            run_time_per_sim_s: Some(run_s),
            refused: error_urad.is_none().then(|| "unstable".to_owned()),
        }
    }

    fn report(rows: Vec<StudyRow>) -> Report {
        Report {
            plant: "test".into(),
            active_parts: vec!["axes"],
            period_s: 5e-5,
            duration_s: 0.1,
            drive: String::new(),
            reference: "exact_zoh, 1 sub-step per period",
            rows,
        }
    }

    fn points(chart: &Chart, method: Method) -> Vec<(f64, f64)> {
        chart
            .series
            .iter()
            .find(|s| s.label == method.name())
            .map(|s| s.points.clone())
            .unwrap()
    }

    #[test]
    fn the_exact_reference_stays_on_the_log_plot_below_the_smallest_error() {
        let chart = work_precision_chart(&report(vec![
            row(Method::ExactZoh, 1, Some(0.0), 0.01),
            row(Method::ExactZoh, 2, Some(2e-3), 0.02),
            row(Method::Rk4, 1, None, 0.0),
            row(Method::Rk4, 2, Some(0.5), 0.03),
        ]));
        assert_eq!(
            points(&chart, Method::ExactZoh),
            [(0.01, 2e-4), (0.02, 2e-3)]
        );
        assert_eq!(points(&chart, Method::Rk4), [(0.03, 0.5)]);
        assert!(
            chart
                .y_label
                .ends_with("(0, the reference, drawn at 2.0e-4)"),
            "{}",
            chart.y_label
        );
        let nonzero = work_precision_chart(&report(vec![row(Method::Rk4, 2, Some(0.5), 0.03)]));
        assert_eq!(nonzero.y_label, "max angle error vs exact [urad]");
        let only_zero =
            work_precision_chart(&report(vec![row(Method::ExactZoh, 1, Some(0.0), 0.01)]));
        assert_eq!(points(&only_zero, Method::ExactZoh), [(0.01, 1.0)]);
    }
}
