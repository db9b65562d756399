//! `scanhil-emulator serve`: the emulated mirror node and/or sensor node on real links.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use scanhil_protocol::fault_injection::SensorFaults;
use scanhil_protocol::ild::command::LineEnding;
use scanhil_protocol::link::slcan::device::EmulatedAdapter;

use scanhil_emulator::serve::misbehaviour::Misbehaviour;
use scanhil_emulator::serve::{DEFAULT_HEARTBEAT_HZ, DEFAULT_PROBE_S, ServeConfig, TimingMode};
use scanhil_protocol::scheduling::RealtimeOptions;

/// Serve the emulated mirror (`--fsm`) and/or sensor (`--sensor`) on real links.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene to emulate (fixtures/scenes/*.json).
    #[arg(long)]
    scene: PathBuf,
    /// The mirror node's link: `slcan:PATH`, `socketcan:IFACE`, or `slcan:pty` (create a pty
    /// pair and print its path for an outside client).
    #[arg(long)]
    fsm: Option<String>,
    /// On an SLCAN link, the adapter the device end behaves as: `scanhil` (CR/BEL answers, no
    /// transmit acks), `canable` (CANable 1.x/2.x firmware: answers nothing but `V`, free
    /// text), `silent` (answers nothing at all), `lawicel` (CR/BEL answers, `z`/`Z` acks) or
    /// `lawicel-timestamps` (the same with `Z1`: every frame carries its millisecond
    /// timestamp).
    #[arg(long, default_value = "scanhil")]
    slcan_adapter: EmulatedAdapter,
    /// The sensor node's link: `ild:PATH[@BAUD]` (the ILD 2300 stream), `ild:pty[@BAUD]` (a pty
    /// pair standing for a line at that baud, 691200 by default), or `fsm` (Distance frames on
    /// the mirror's CAN link).
    #[arg(long)]
    sensor: Option<String>,
    /// How the emulated ILD takes command lines: `any` (CR, LF or CR LF ends a line) or `lf`
    /// (only LF does, CR is ignored, as the ILD 1220/1420 firmwares require).
    #[arg(long, value_enum, default_value_t = IldLineEnd::Any)]
    ild_line_end: IldLineEnd,
    /// Lockstep (the controller's Step frames advance time) or realtime (this emulator is the
    /// clock master).
    #[arg(long, value_enum, default_value_t = TimingMode::Lockstep)]
    timing: TimingMode,
    /// Overrides the scene's seed.
    #[arg(long, allow_negative_numbers = true)]
    seed: Option<u64>,
    /// Missed periods before the watchdog zeroes the coil currents and reports a link timeout.
    #[arg(long, default_value_t = 200, allow_negative_numbers = true)]
    watchdog_periods: u32,
    /// In lockstep, the wall-clock allowance per missed period, in seconds.
    #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
    lockstep_answer_allowance_s: f64,
    /// Real time: stop after this many seconds (default: until the link closes).
    #[arg(long, allow_negative_numbers = true)]
    duration_s: Option<f64>,
    /// Status/heartbeat frames per second (of loop time).
    #[arg(long, default_value_t = DEFAULT_HEARTBEAT_HZ, allow_negative_numbers = true)]
    heartbeat_hz: f64,
    /// A conformance test aid: break this protocol rule on purpose (`slow-clock` in real time only; see
    /// docs/loop.md). Hidden from --help: no real use wants a broken node.
    #[arg(long, value_enum, hide = true)]
    misbehave: Option<Misbehaviour>,
    /// The sensor losing its peak, as a scenario's `faults.sensor` JSON (laser off, out of
    /// range, occlusion bursts); the samples carry the ILD's error values.
    #[arg(long, value_parser = parse_sensor_faults)]
    sensor_faults: Option<SensorFaults>,
    /// Real time: spin on non-blocking reads instead of waiting on readiness.
    #[arg(long)]
    busy_poll: bool,
    /// Real time: pin the loop's thread to this CPU.
    #[arg(long, allow_negative_numbers = true)]
    cpu: Option<usize>,
    /// Real time: run the loop under SCHED_FIFO at this priority (1 to 99), memory locked.
    #[arg(long, allow_negative_numbers = true)]
    sched_fifo_priority: Option<u8>,
    /// Real time: run the wake-up probe for this long before the loop, in seconds (0: none).
    #[arg(long, default_value_t = DEFAULT_PROBE_S, allow_negative_numbers = true)]
    probe_s: f64,
    /// End at once (SIGKILL, the kernel's parent-death signal) when the process with this id,
    /// this emulator's parent, ends: `scanhil` passes its own, so a host killed at any moment
    /// (its start-up probe included) leaves no emulator behind.
    #[arg(long, value_name = "PID")]
    exit_with_parent: Option<u32>,
}

/// `--ild-line-end`: what ends a command line at the emulated ILD.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum IldLineEnd {
    /// CR, LF or CR LF.
    Any,
    /// LF only (CR ignored).
    Lf,
}

/// Parses and checks `--sensor-faults` (the field named in the error).
fn parse_sensor_faults(text: &str) -> Result<SensorFaults, String> {
    let faults: SensorFaults = serde_json::from_str(text).map_err(|error| error.to_string())?;
    faults.check().map_err(|error| error.to_string())?;
    Ok(faults)
}

/// Runs the node(s) until the controller closes the link, the watchdog fires or the duration
/// ends. Prints a `ready` JSON line (with any pty paths it created) when listening, and a
/// `summary` JSON line at the end. Exit status 0 after a clean run, 3 after a link timeout or
/// a link failure (bus-off, an I/O error: [`scanhil_emulator::serve::ServeOutcome::exit_status`]).
///
/// # Errors
/// A scene that does not load, a link that does not open, or a plant error.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    args.exit_with_parent_if_asked()?;
    let outcome = scanhil_emulator::serve::serve(&args.config()).context("serve")?;
    Ok(ExitCode::from(outcome.exit_status()))
}

impl Args {
    /// With `--exit-with-parent PID`: asks the kernel to SIGKILL this process when its parent
    /// ends, then checks the parent is still `PID` (one that ended before the request was made
    /// has left this process to init, and the signal would never come).
    ///
    /// # Errors
    /// The request refused, or the parent already gone.
    pub fn exit_with_parent_if_asked(&self) -> anyhow::Result<()> {
        let Some(parent) = self.exit_with_parent else {
            return Ok(());
        };
        nix::sys::prctl::set_pdeathsig(nix::sys::signal::Signal::SIGKILL)
            .context("--exit-with-parent: setting the parent-death signal")?;
        let now = nix::unistd::getppid().as_raw();
        if u32::try_from(now).ok() != Some(parent) {
            anyhow::bail!(
                "--exit-with-parent {parent}: that process has ended (the parent is {now})"
            );
        }
        Ok(())
    }

    /// The serve configuration these arguments ask for (checked by `serve` once the scene
    /// gives the control period).
    pub fn config(self) -> ServeConfig {
        let realtime = RealtimeOptions {
            busy_poll: self.busy_poll,
            cpu: self.cpu,
            sched_fifo_priority: self.sched_fifo_priority,
        };
        // Every value is checked (ServeConfig::check) once the scene gives the control
        // period, before any link opens or the ready line is printed.
        ServeConfig {
            scene: self.scene,
            fsm: self.fsm,
            slcan_adapter: self.slcan_adapter,
            sensor: self.sensor,
            ild_line_ending: match self.ild_line_end {
                IldLineEnd::Any => LineEnding::CrOrLf,
                IldLineEnd::Lf => LineEnding::Lf,
            },
            timing: self.timing,
            seed: self.seed,
            watchdog_periods: self.watchdog_periods,
            lockstep_answer_allowance_s: self.lockstep_answer_allowance_s,
            duration_s: self.duration_s,
            heartbeat_hz: self.heartbeat_hz,
            misbehave: self.misbehave,
            sensor_faults: self.sensor_faults,
            realtime,
            probe_s: self.probe_s,
            replay: None,
        }
    }
}
