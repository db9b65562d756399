//! `scanhil-emulator step`: the open-loop response of the emulated mirror to a coil current
//! step on one sensing axis (a bench "bump test"), one row per control period.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;

use super::print_or_broken_pipe;
use serde::Serialize;

use scanhil_emulator::mirror::SensingAxis;
use scanhil_emulator::part_cost::{self, CostTiming, PartCosts};
use scanhil_emulator::plant::{Plant, PlantStep};
use scanhil_emulator::scene::{Part, Scene};
use scanhil_protocol::ild::IldValue;
use scanhil_protocol::plant_units::actuator_from_sensing;

/// Arguments of `scanhil-emulator step`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene file (JSON).
    #[arg(long)]
    scene: PathBuf,
    /// The sensing axis the step is applied on (`x` = beta, spot along x; `y` = alpha).
    #[arg(long, default_value = "alpha", value_parser = parse_axis)]
    axis: SensingAxis,
    /// The current step on that sensing axis, in A (rotated onto the coils).
    #[arg(long, default_value_t = 0.1, allow_negative_numbers = true)]
    amplitude: f64,
    /// How many control periods to run (at most 1 000 000: the whole response is held and
    /// printed).
    #[arg(long, default_value_t = 2000, allow_negative_numbers = true)]
    samples: u64,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

fn parse_axis(text: &str) -> Result<SensingAxis, String> {
    match text {
        "alpha" | "y" => Ok(SensingAxis::Alpha),
        "beta" | "x" => Ok(SensingAxis::Beta),
        other => Err(format!("unknown axis `{other}`: use alpha|beta (or y|x)")),
    }
}

/// The JSON report of a step run.
#[derive(Debug, Serialize)]
struct Report<'a> {
    scene: &'a str,
    active_parts: Vec<&'static str>,
    parts: PartCosts,
    integrator: Option<String>,
    period_s: f64,
    coil_resistance_ohm: f64,
    axis: &'static str,
    amplitude_a: f64,
    samples: Vec<PlantStep>,
}

/// The most periods `step` runs (it holds and prints every one).
const MAX_SAMPLES: u64 = 1_000_000;

/// Runs `scanhil-emulator step`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        (1..=MAX_SAMPLES).contains(&args.samples),
        "--samples {}: must be between 1 and {MAX_SAMPLES} (50 s at 20 kHz)",
        args.samples
    );
    anyhow::ensure!(
        args.amplitude.is_finite(),
        "--amplitude must be a finite current in A, got {}",
        args.amplitude
    );
    let scene = Scene::load(&args.scene)?;
    let mut plant = Plant::from_scene(&scene)
        .with_context(|| format!("cannot build the plant of {}", args.scene.display()))?;
    let parts = part_cost::measure(&scene, CostTiming::default())?;
    let command = actuator_from_sensing(args.axis.pair(args.amplitude));
    let samples = (0..args.samples)
        .map(|_| plant.step(command))
        .collect::<Result<Vec<_>, _>>()?;
    let report = Report {
        scene: &scene.name,
        active_parts: plant.active_parts().iter().map(|p| p.name()).collect(),
        parts,
        integrator: plant
            .integrator()
            .map(|(method, substeps)| format!("{method} x{substeps}")),
        period_s: plant.period_s(),
        coil_resistance_ohm: plant.coil_resistance_ohm(),
        axis: args.axis.name(),
        amplitude_a: args.amplitude,
        samples,
    };
    if args.json {
        scanhil_protocol::outln!("{}", serde_json::to_string_pretty(&report)?)?;
    } else {
        print_or_broken_pipe(print_table(&report, scene.has(Part::Axes)))?;
    }
    Ok(ExitCode::SUCCESS)
}

fn print_table(report: &Report<'_>, moves: bool) -> std::io::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "scene {}: step of {} A on {} | active parts: [{}] | integrator: {} | Ta = {} us | R = {:.4} ohm",
        report.scene,
        report.amplitude_a,
        report.axis,
        report.active_parts.join(", "),
        report
            .integrator
            .as_deref()
            .unwrap_or("none (nothing moves)"),
        report.period_s * 1e6,
        report.coil_resistance_ohm,
    )?;
    writeln!(
        out,
        "part costs, us per period (marginal, measured over {} periods): {} | whole plant {:.3} us",
        report.parts.periods_timed,
        report.parts.describe(),
        report.parts.plant_us_per_period
    )?;
    if !moves {
        writeln!(
            out,
            "note: part `axes` is not active, the mirror holds its initial angles"
        )?;
    }
    writeln!(
        out,
        "{:>7} {:>10} {:>9} {:>9} {:>12} {:>12} {:>12} {:>12}  {:<14} events",
        "k",
        "t_ms",
        "i_a_A",
        "i_b_A",
        "alpha_urad",
        "beta_urad",
        "true_a_urad",
        "true_b_urad",
        "ild"
    )?;
    for s in &report.samples {
        let events: Vec<String> = s
            .events
            .iter()
            .map(|e| {
                serde_json::to_value(e).map_or_else(
                    |_| "?".into(),
                    |v| v["event"].as_str().unwrap_or("?").to_string(),
                )
            })
            .collect();
        // The ILD values of this period: raw distances, or the error's name.
        let ild: Vec<String> = s
            .sensor_samples
            .iter()
            .map(|sample| match sample.value {
                IldValue::Distance(raw) => raw.to_string(),
                IldValue::Error(e) => e.name().to_string(),
            })
            .collect();
        let ild = if ild.is_empty() {
            "-".to_string()
        } else {
            ild.join(",")
        };
        writeln!(
            out,
            "{:>7} {:>10.4} {:>9.5} {:>9.5} {:>12.3} {:>12.3} {:>12.3} {:>12.3}  {:<14} {}{}",
            s.period_index,
            s.t_end_s * 1e3,
            s.applied_currents_a.a,
            s.applied_currents_a.b,
            s.measured_angles_rad.alpha * 1e6,
            s.measured_angles_rad.beta * 1e6,
            s.true_angles_rad.alpha * 1e6,
            s.true_angles_rad.beta * 1e6,
            ild,
            events.join(","),
            if s.faulted { " FAULT" } else { "" },
        )?;
    }
    Ok(())
}
