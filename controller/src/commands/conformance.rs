//! `scanhil conformance --fsm LINK [--sensor LINK]`: checks a mirror node and a sensor, real
//! or emulated, against the loop protocol; prints a pass/fail table (and for each failed check
//! what to look at on the bench), optionally JUnit XML. `--check`/`--skip` select checks; on a
//! real link the destructive ones run only with `--destructive`. `--timing realtime` checks a
//! node that runs on its own clock (no Step frames).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use scanhil_controller::run::check_selection::Selection;
use scanhil_controller::run::conformance::{
    CheckResult, Outcome, ended_early, junit_xml, run_checks, table,
};
use scanhil_controller::run::interrupt::Interrupt;
use scanhil_controller::run::scenario::{NodeLink, TimingConfig, TimingMode};
use scanhil_controller::run::{LinkPlan, finish_emulator, open_links};
use scanhil_protocol::loop_limits;
use scanhil_protocol::validation::Invalid;

/// How long a real-time emulated node started here may run, s: the checks take seconds and
/// end its run (the zero command and the host's end, or its own watchdog).
const EMULATED_NODE_MAX_S: f64 = 600.0;

/// Check a mirror node (and a sensor) against the loop protocol.

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The mirror node: `slcan:PATH[@BITRATE]`, `socketcan:IFACE`, or `pty` (start the
    /// emulator on a pty pair; needs --scene).
    #[arg(long)]
    fsm: String,
    /// The sensor: `ild:PATH[@BAUD]`, `pty` (emulated), or `fsm` (Distance frames on the
    /// mirror's link).
    #[arg(long)]
    sensor: Option<String>,
    /// The scene an emulated node serves.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// The control rate the device runs at, in Hz (at most 200 kHz, the loop's limit).
    #[arg(long, default_value_t = 20_000.0, allow_negative_numbers = true)]
    rate_hz: f64,
    /// How the node is clocked: `lockstep` (the host's Step frames advance it) or `realtime`
    /// (it runs on its own clock at --rate-hz and sends a reading every period).
    #[arg(long, value_enum, default_value_t = TimingMode::Lockstep)]
    timing: TimingMode,
    /// Missed answers before a link timeout (also what the device is expected to use). In
    /// real time each is one period: the node's silence may last this many periods.
    #[arg(long, default_value_t = 50, allow_negative_numbers = true)]
    watchdog_periods: u32,
    /// Lockstep: wall-clock allowance per answer, in seconds [default: 0.01]. In real time
    /// the allowance is one period.
    #[arg(long, allow_negative_numbers = true)]
    answer_allowance_s: Option<f64>,
    /// Write the results as JUnit XML here.
    #[arg(long)]
    junit: Option<PathBuf>,
    /// Run only this check (repeatable; all when none is given).
    #[arg(long = "check", value_name = "NAME")]
    checks: Vec<String>,
    /// Do not run this check (repeatable).
    #[arg(long = "skip", value_name = "NAME")]
    skips: Vec<String>,
    /// On a real link, also run the checks that can harm the bench: `over_current_fault`
    /// (8 A into the coils) and `survives_garbage_slcan_lines` (garbage lines to the adapter).
    /// The emulator `--fsm pty` starts always gets them.
    #[arg(long)]
    destructive: bool,
    /// The `scanhil-emulator` binary (default: $SCANHIL_EMULATOR, else next to `scanhil`).
    #[arg(long)]
    emulator: Option<PathBuf>,
}

/// Runs the checks; exit status 0 when every check that ran passed (and one did), 1
/// otherwise.
///
/// # Errors
/// Values out of range or check names unknown (before any link opens); links that do not
/// open; an emulated node without a scene; the JUnit file not writable.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    // Without the flag, a scenario's default.
    let answer_allowance_s = args
        .answer_allowance_s
        .unwrap_or(TimingConfig::default().lockstep_answer_allowance_s);
    loop_limits::CONTROL_RATE_HZ
        .check("rate_hz", args.rate_hz)
        .and_then(|()| {
            loop_limits::ANSWER_ALLOWANCE_S.check("answer_allowance_s", answer_allowance_s)
        })
        .and_then(|()| match (args.timing, args.answer_allowance_s) {
            (TimingMode::Realtime, Some(_)) => Err(Invalid::new(
                "answer_allowance_s",
                "applies to --timing lockstep only (in real time the allowance is one period)",
            )),
            _ => Ok(()),
        })
        .and_then(|()| {
            let allowance_s = match args.timing {
                TimingMode::Lockstep => answer_allowance_s,
                TimingMode::Realtime => 1.0 / args.rate_hz,
            };
            loop_limits::check_watchdog("watchdog_periods", args.watchdog_periods, allowance_s)
        })
        .map_err(Invalid::as_own_flag)?;
    let fsm = NodeLink::parse(&args.fsm);
    let selection = Selection {
        only: args.checks,
        skip: args.skips,
        destructive: args.destructive,
        emulated: fsm == NodeLink::Pty,
        timing: args.timing,
    };
    selection.check().map_err(Invalid::as_own_flag)?;
    let sensor = args.sensor.as_deref().map(NodeLink::parse);
    let emulated = fsm == NodeLink::Pty || sensor == Some(NodeLink::Pty);
    let scene = match (&args.scene, emulated) {
        (Some(scene), _) => scene.clone(),
        (None, true) => anyhow::bail!("an emulated node (`pty`) needs --scene"),
        (None, false) => PathBuf::new(),
    };
    let plan = LinkPlan {
        fsm,
        sensor,
        spawn_emulator: false,
        emulator: args.emulator,
        scene,
        seed: 0,
        sensor_faults: Default::default(),
        timing: TimingConfig {
            mode: args.timing,
            watchdog_periods: args.watchdog_periods,
            lockstep_answer_allowance_s: answer_allowance_s,
            ..TimingConfig::default()
        },
        period_s: 1.0 / args.rate_hz,
        // A real-time node started here runs at most this long; the checks end it sooner.
        duration_s: EMULATED_NODE_MAX_S,
        record_dir: None,
        recording: Default::default(),
        bus_bitrate: None,
        sensor_expectation: None,
        replay: None,
    };
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the I/O runtime")?;
    let junit = args.junit.clone();
    // The JUnit file is written whole after every result, so a run cut short keeps its rows.
    let write_junit = |results: &[CheckResult]| -> anyhow::Result<()> {
        match &junit {
            Some(path) => scanhil_protocol::whole_file::write_file(path, junit_xml(results))
                .with_context(|| format!("writing {}", path.display())),
            None => Ok(()),
        }
    };
    let mut junit_error = None;
    let mut results = Vec::new();
    runtime.block_on(async {
        let mut links = open_links(&plan).await?;
        let mut interrupt =
            Interrupt::install().context("installing the signal handlers")?;
        let sensor = plan.sensor.is_some().then_some(&mut links.sensor);
        let mut on_result = |so_far: &[CheckResult]| {
            if let Err(error) = write_junit(so_far) {
                junit_error.get_or_insert(error);
            }
        };
        let signal = tokio::select! {
            () = run_checks(&mut links.mirror, sensor, &selection, &mut results, &mut on_result) => None,
            signal = interrupt.recv() => Some(signal),
        };
        if let Some(signal) = signal {
            // Cut short mid-check: the node is given its zero command and its session ended.
            let period = links.mirror.counters().angle_readings;
            let _ = links.mirror.end_session(period).await;
            results.push(ended_early(signal));
            on_result(&results);
        }
        interrupt.restore_default();
        // `C` on SLCAN, so a real adapter is not left open; a node already gone is fine.
        let _ = links.mirror.close().await;
        drop(links.mirror);
        if let Some(process) = links.emulator {
            finish_emulator(process, links.emulator_lines).await?;
        }
        anyhow::Ok(())
    })?;
    scanhil_protocol::outln!("{}", table(&results))?;
    if let Some(error) = junit_error {
        return Err(error);
    }
    // A run in which no check ran (all skipped, or none applied to these links) did nothing.
    let ran = results.iter().any(|r| r.outcome != Outcome::Skipped);
    Ok(if ran && !results.iter().any(|r| r.failed()) {
        ExitCode::SUCCESS
    } else {
        if !ran {
            eprintln!("scanhil conformance: no check ran on these links");
        }
        ExitCode::FAILURE
    })
}
