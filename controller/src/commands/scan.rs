//! `scanhil scan SCENARIO`: runs a whole scan and writes its output folder.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use scanhil_controller::run::output::REPORT;
use scanhil_controller::run::scenario::{NodeLink, Scenario, TimingMode};
use scanhil_controller::run::{ScanEnd, ScanOptions, default_out_dir, run_scan};

/// Exit status of a scan that stopped early (link timeout, node fault, link failure, a
/// recording that could not be written) or whose outputs could not all be written; the
/// outputs it could write are written.
const EXIT_STOPPED: u8 = 3;

/// Run a scan scenario (fixtures/scenarios/*.json) and write its output folder.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scenario file.
    scenario: PathBuf,
    /// The output folder (default: `scan-out/<scenario name>`).
    #[arg(long)]
    out: Option<PathBuf>,
    /// The mirror node's link instead of the scenario's: `pty` (emulated), `slcan:PATH[@BITRATE]`
    /// or `socketcan:IFACE[@BITRATE]`.
    #[arg(long)]
    fsm: Option<String>,
    /// The sensor's link instead of the scenario's: `pty` (emulated), `ild:PATH[@BAUD]`, or
    /// `fsm` (Distance frames on the mirror's CAN link).
    #[arg(long)]
    sensor: Option<String>,
    /// Lockstep or real time instead of the scenario's.
    #[arg(long, value_enum)]
    timing: Option<TimingArg>,
    /// Scan duration instead of the scenario's, in seconds.
    #[arg(long)]
    duration_s: Option<f64>,
    /// Missed periods before a link timeout, instead of the scenario's.
    #[arg(long)]
    watchdog_periods: Option<u32>,
    /// A fixed lead-in before the recorded frame instead of the scenario's, in seconds.
    #[arg(long)]
    lead_in_s: Option<f64>,
    /// Do not start the emulator: the nodes on --fsm / --sensor are already there (real
    /// hardware, or an emulator started by hand).
    #[arg(long)]
    no_emulator: bool,
    /// The `scanhil-emulator` binary (default: $SCANHIL_EMULATOR, else next to `scanhil`).
    #[arg(long)]
    emulator: Option<PathBuf>,
}

/// The timing modes on the command line.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum TimingArg {
    Lockstep,
    Realtime,
}

/// Runs the scan; prints where the outputs went and the headline figures.
///
/// # Errors
/// A scenario, controller or scene that does not load; a loop that cannot fit its bus; links
/// that do not open; outputs that cannot be written.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let scenario = Scenario::load(&args.scenario)?;
    let out_dir = args.out.unwrap_or_else(|| default_out_dir(&scenario));
    let options = ScanOptions {
        out_dir: out_dir.clone(),
        emulator: args.emulator,
        fsm: args.fsm.as_deref().map(NodeLink::parse),
        sensor: args.sensor.as_deref().map(NodeLink::parse),
        timing: args.timing.map(|t| match t {
            TimingArg::Lockstep => TimingMode::Lockstep,
            TimingArg::Realtime => TimingMode::Realtime,
        }),
        duration_s: args.duration_s,
        watchdog_periods: args.watchdog_periods,
        lead_in_s: args.lead_in_s,
        no_emulator: args.no_emulator,
    };
    let result = run_scan(&scenario, &options)
        .with_context(|| format!("scan {}", args.scenario.display()))?;
    let report_path = out_dir.join(REPORT);
    if !result.failed_outputs.contains(REPORT) {
        let report: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(&report_path)
                .with_context(|| format!("reading back {}", report_path.display()))?,
        )?;
        println!("{}", summary_text(&report, &out_dir));
    }
    let mut code = ExitCode::SUCCESS;
    if let ScanEnd::Stopped(why) = &result.end {
        eprintln!("scanhil: scan stopped early: {why}");
        code = ExitCode::from(EXIT_STOPPED);
    }
    if !result.failed_outputs.is_empty() {
        eprintln!(
            "scanhil: outputs not written in {}: {}",
            out_dir.display(),
            result.failed_outputs
        );
        code = ExitCode::from(EXIT_STOPPED);
    }
    Ok(code)
}

fn summary_text(report: &serde_json::Value, out_dir: &std::path::Path) -> String {
    let tracking = &report["tracking_error"]["frame"];
    let predicted = &report["predicted_tracking_error"];
    let imaging = &report["imaging"];
    let feature = &imaging["feature"];
    let percent = |value: &serde_json::Value| {
        value
            .as_f64()
            .map_or_else(|| "-".to_owned(), |v| format!("{:.2} %", 100.0 * v))
    };
    let mut text = format!(
        "scan {}: {} of {} periods ({:.3} s lead-in, frame from {:.3} s for {:.3} s), {} points\n\
         tracking error over the frame (rms / peak): alpha {} (predicted {}), beta {} \
         (predicted {})\n",
        report["scenario"]["name"].as_str().unwrap_or("?"),
        report["periods"]["done"],
        report["periods"]["planned"],
        report["frame"]["lead_in"]["duration_s"]
            .as_f64()
            .unwrap_or(0.0),
        report["frame"]["start_s"].as_f64().unwrap_or(0.0),
        report["frame"]["duration_s"].as_f64().unwrap_or(0.0),
        imaging["points"].as_u64().unwrap_or(0),
        percent(&tracking["alpha"]["rms_relative"]),
        percent(&predicted["alpha_rms_relative"]),
        percent(&tracking["beta"]["rms_relative"]),
        percent(&predicted["beta_rms_relative"]),
    );
    if let Some(height) = feature["height_mm"].as_f64() {
        text += &format!(
            "feature height: {height:.4} mm (std {:.4} mm, {} points)\n",
            feature["std_mm"].as_f64().unwrap_or(f64::NAN),
            feature["points"]
        );
    } else if let Some(error) = imaging["feature_error"].as_str() {
        text += &format!("feature height: not measured ({error})\n");
    }
    text + &format!("outputs in {}", out_dir.display())
}
