//! `scanhil scan SCENARIO`: runs a whole scan and writes its output folder.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use scanhil_controller::run::output::REPORT;
use scanhil_controller::run::scenario::{NodeLink, Scenario, ScenarioError, TimingMode};
use scanhil_controller::run::verdict::Status;
use scanhil_controller::run::{ScanEnd, ScanOptions, default_out_dir, run_scan};

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
    #[arg(long, allow_negative_numbers = true)]
    duration_s: Option<f64>,
    /// Missed periods before a link timeout, instead of the scenario's.
    #[arg(long, allow_negative_numbers = true)]
    watchdog_periods: Option<u32>,
    /// A fixed lead-in before the recorded frame instead of the scenario's, in seconds.
    #[arg(long, allow_negative_numbers = true)]
    lead_in_s: Option<f64>,
    /// Do not start the emulator: the nodes on --fsm / --sensor are already there (real
    /// hardware, or an emulator started by hand).
    #[arg(long)]
    no_emulator: bool,
    /// The `scanhil-emulator` binary (default: $SCANHIL_EMULATOR, else next to `scanhil`).
    #[arg(long)]
    emulator: Option<PathBuf>,
    /// Injects a fault, over the scenario's `faults`: `KEY=VALUE` with KEY a field below
    /// `faults` and VALUE JSON, such as `node_to_host.drop_rate=0.001`,
    /// `host_to_node.at=[{"period":500,"fault":"drop","message":"Step"}]` or
    /// `sensor.laser_off=[{"from_s":0.1,"to_s":0.2}]` (repeatable; checked as the file is).
    #[arg(long = "fault", value_name = "KEY=VALUE")]
    faults: Vec<String>,
    /// Real time: both ends spin on non-blocking reads instead of waiting on readiness.
    #[arg(long)]
    busy_poll: bool,
    /// Real time: pin the host's loop to this CPU, instead of the scenario's.
    #[arg(long, allow_negative_numbers = true)]
    cpu: Option<usize>,
    /// Real time: pin the emulator this scan starts to this CPU, instead of the scenario's.
    #[arg(long, allow_negative_numbers = true)]
    emulator_cpu: Option<usize>,
    /// Real time: both loops under SCHED_FIFO at this priority (1 to 99), memory locked.
    #[arg(long, allow_negative_numbers = true)]
    sched_fifo_priority: Option<u8>,
    /// Real time: each end's wake-up probe before the loop, in seconds, instead of the
    /// scenario's (0: none).
    #[arg(long, allow_negative_numbers = true)]
    probe_s: Option<f64>,
    /// How long the emulator this scan starts may take to become ready, in seconds, instead
    /// of the scenario's `timing.emulator_ready_s` (default 20; the probe comes on top).
    #[arg(long, allow_negative_numbers = true)]
    emulator_ready_s: Option<f64>,
    /// Lockstep: stamp `fsm.log` with Unix times (the loop's start on the wall clock plus the
    /// loop's time) instead of the loop's time from zero, as `log2asc` and `canplayer` expect.
    #[arg(long)]
    record_epoch: bool,
    /// The interface name each line of `fsm.log` carries instead of the scenario's (`fsm`),
    /// e.g. `can0`, so `canplayer -I fsm.log` replays it there.
    #[arg(long, value_name = "IFACE")]
    record_iface: Option<String>,
    /// Leave out the recordings (`fsm.log`, `sensor.ild`): for a run that only wants its
    /// report. The report lists them under `outputs.left_out`.
    #[arg(long)]
    no_recordings: bool,
    /// Leave out the figures (`tracking.svg`, `height_map.png`, `progressive.svg`,
    /// `snapshots.png`, `profiles.svg`); the CSV files, the point cloud and the report stay.
    #[arg(long)]
    no_figures: bool,
    /// Serve a recorded session (a scan's output folder or a bench capture: `fsm.log`,
    /// `sensor.ild`) as the devices, in lockstep, instead of emulating the scene; the report's
    /// `replay` section names the first period whose coil command differs from the recording's.
    #[arg(long, value_name = "DIR")]
    replay: Option<PathBuf>,
    /// With --replay: a coil command that differs from the recording's fails the run (exit 4).
    #[arg(long)]
    replay_must_match: bool,
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
        faults: args.faults,
        busy_poll: args.busy_poll,
        cpu: args.cpu,
        emulator_cpu: args.emulator_cpu,
        sched_fifo_priority: args.sched_fifo_priority,
        probe_s: args.probe_s,
        emulator_ready_s: args.emulator_ready_s,
        record_epoch: args.record_epoch,
        record_iface: args.record_iface,
        no_recordings: args.no_recordings,
        no_figures: args.no_figures,
        replay: args.replay,
        replay_must_match: args.replay_must_match,
    };
    // A scenario error names its file already; anything else gets the scan's name.
    let result = run_scan(&scenario, &options).map_err(|error| {
        if error.chain().any(|cause| cause.is::<ScenarioError>()) {
            error
        } else {
            error.context(format!("scan {}", args.scenario.display()))
        }
    })?;
    let report_path = out_dir.join(REPORT);
    if !result.failed_outputs.contains(REPORT) {
        let report: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(&report_path)
                .with_context(|| format!("reading back {}", report_path.display()))?,
        )?;
        scanhil_protocol::outln!("{}", summary_text(&report, &out_dir))?;
    }
    if let ScanEnd::Stopped(why) = &result.end {
        eprintln!("scanhil: scan stopped early: {why}");
    }
    if result.verdict.status == Status::Failed {
        eprintln!(
            "scanhil: the scan completed but its result is not valid: {}",
            result.verdict.reasons.join("; ")
        );
    }
    if !result.failed_outputs.is_empty() {
        eprintln!(
            "scanhil: outputs not written in {}: {}",
            out_dir.display(),
            result.failed_outputs
        );
    }
    Ok(ExitCode::from(result.exit_code()))
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
    let outcome = &report["outcome"];
    for note in outcome["notes"].as_array().into_iter().flatten() {
        text += &format!("note: {}\n", note.as_str().unwrap_or("?"));
    }
    if let Some(verdict) = outcome["verdict"].as_str().filter(|v| *v != "complete") {
        text += &format!(
            "verdict: {verdict}: {}\n",
            outcome["reasons"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(serde_json::Value::as_str)
                .collect::<Vec<_>>()
                .join("; ")
        );
    }
    if report["timing"]["mode"] == "realtime" {
        text += &realtime_summary(&report["timing"], &report["scenario"]["timing"]);
    }
    text + &format!("outputs in {}", out_dir.display())
}

/// Real time: the settings each end had, its loop jitter beside the wake-up probe, and who
/// missed deadlines by how much.
fn realtime_summary(timing: &serde_json::Value, asked: &serde_json::Value) -> String {
    let micros = |value: &serde_json::Value| {
        value
            .as_f64()
            .map_or_else(|| "-".to_owned(), |s| format!("{:.1} us", s * 1e6))
    };
    let three = |stats: &serde_json::Value| {
        format!(
            "median {}, p99 {}, max {}",
            micros(&stats["median_s"]),
            micros(&stats["p99_s"]),
            micros(&stats["max_s"])
        )
    };
    let settings = |in_effect: &serde_json::Value, cpu_asked: &serde_json::Value| {
        let mut parts = Vec::new();
        match (&in_effect["cpu"], cpu_asked.is_null()) {
            (serde_json::Value::Null, true) => {}
            (serde_json::Value::Null, false) => parts.push(format!("CPU {cpu_asked} not granted")),
            (cpu, _) => parts.push(format!("CPU {cpu}")),
        }
        match (
            &in_effect["sched_fifo_priority"],
            asked["sched_fifo_priority"].is_null(),
        ) {
            (serde_json::Value::Null, true) => parts.push("normal scheduler".to_owned()),
            (serde_json::Value::Null, false) => parts.push("SCHED_FIFO not granted".to_owned()),
            (priority, _) => parts.push(format!("SCHED_FIFO {priority}")),
        }
        if !asked["sched_fifo_priority"].is_null() {
            parts.push(if in_effect["memory_locked"] == true {
                "memory locked".to_owned()
            } else {
                "memory not locked".to_owned()
            });
        }
        parts.join(", ")
    };
    let mut text = format!(
        "real time: busy-poll {}; host {}",
        if asked["busy_poll"] == true {
            "on"
        } else {
            "off"
        },
        settings(
            &timing["controller"]["scheduling"]["in_effect"],
            &asked["cpu"]
        ),
    );
    let emulator = &timing["emulator"]["scheduling"]["in_effect"];
    if !emulator.is_null() {
        text += &format!("; emulator {}", settings(emulator, &asked["emulator_cpu"]));
    }
    text.push('\n');
    let jitter = &timing["jitter_against_probe"];
    if !jitter.is_null() {
        text += &format!(
            "wake-up probe (emulator): {}; loop tick lateness: {} (p99 {}x the probe's, target {}x)\n",
            three(&jitter["wakeup_probe"]),
            three(&jitter["loop_tick_lateness"]),
            jitter["p99_ratio"]
                .as_f64()
                .map_or_else(|| "-".to_owned(), |r| format!("{r:.2}")),
            jitter["target_p99_ratio"],
        );
    }
    let misses = &timing["deadline_misses"];
    if !misses.is_null() {
        let side = |name: &str, side: &serde_json::Value| {
            format!(
                "{name} {} (worst {}, p99 {})",
                side["count"],
                micros(&side["worst_s"]),
                micros(&side["p99_s"])
            )
        };
        text += &format!(
            "deadline: missed in {} periods: {}, {}, {}\n",
            misses["total"],
            side("node late", &misses["node"]),
            side("host late", &misses["host"]),
            side("link (transit at least)", &misses["link"]),
        );
    }
    text
}
