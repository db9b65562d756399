//! Serving the emulated nodes on real links: the mirror node (coil commands in, angle
//! readings out) and the sensor node (distances out), in lockstep or in real time.
//!
//! # Layout
//! - [`mirror_node`]: the mirror node as a protocol state machine around the plant (no I/O).
//! - [`sensor_port`]: where the sensor's samples go (the ILD stream, or CAN Distance frames).
//! - [`sensor_commands`]: the emulated ILD 2300's settings and its answers to the host's ASCII
//!   commands (no I/O).
//! - [`ild_line`]: the ILD's RS422 line pacing the output cycles at its baud (no I/O).
//! - [`lockstep_node`]: the node's answers to the controller's frames in lockstep (no I/O).
//! - [`lockstep`]: the controller's Step frame advances the plant one period.
//! - [`realtime`]: this emulator is the clock master on the wall clock.
//! - [`wind_down`]: how either loop ends: the node's last frames, the linger, and the end on
//!   a link error (coils zeroed, last frames, reason).
//! - [`misbehaviour`]: deliberately non-conforming nodes for conformance tests.
//! - [`recording`]: a recorded session (`fsm.log`, `sensor.ild`) read into periods (no I/O
//!   but reading the folder).
//! - [`replay_node`]: the recorded session answering the controller in lockstep or clocked in
//!   real time at its recorded times, its commands compared with the recorded ones (no I/O).
//!
//! The process speaks on stdout in JSON lines: `{"event":"ready",...}` once the links are
//! open (with the paths of any pty it created), and `{"event":"summary",...}` at the end.

pub mod ild_line;
pub mod lockstep;
pub mod lockstep_node;
pub mod mirror_node;
pub mod misbehaviour;
pub mod realtime;
pub mod recording;
pub mod replay_node;
pub mod sensor_commands;
pub mod sensor_port;
pub mod wind_down;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, bail};
use scanhil_protocol::link::role::Role;
use scanhil_protocol::link::slcan::device::EmulatedAdapter;
use scanhil_protocol::link::{CanLink, LinkError, LinkUri, PtyPair};
use scanhil_protocol::loop_limits;
use scanhil_protocol::scheduling::{self, RealtimeOptions};
use scanhil_protocol::validation::Invalid;

use crate::plant::Plant;
use crate::scene::Scene;
use crate::sensor_faults::SensorFaultModel;
use mirror_node::MirrorNode;
use recording::{RecordedClock, Recording};
use replay_node::ReplayNode;
use scanhil_protocol::fault_injection::SensorFaults;
use scanhil_protocol::ild::command::LineEnding;
use sensor_port::SensorPort;

/// Status frames per second of loop time unless `serve` is told otherwise.
pub const DEFAULT_HEARTBEAT_HZ: f64 = 10.0;

/// Real time: how long the wake-up probe runs before the loop unless told otherwise, s.
pub const DEFAULT_PROBE_S: f64 = 0.5;

/// Who advances time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TimingMode {
    /// The controller's Step frame advances the plant one period (virtual time).
    Lockstep,
    /// The emulator is the clock master on the wall clock.
    Realtime,
}

/// Everything `serve` needs.
#[derive(Debug, Clone)]
pub struct ServeConfig {
    /// The scene file.
    pub scene: PathBuf,
    /// The mirror node's link URI (`slcan:pty` creates a pty pair).
    pub fsm: Option<String>,
    /// On an SLCAN link: the adapter the device end plays.
    pub slcan_adapter: EmulatedAdapter,
    /// The sensor node's link URI (`ild:pty[@BAUD]` creates a pty pair; `fsm` = the mirror's
    /// link).
    pub sensor: Option<String>,
    /// What ends a command line at the emulated ILD.
    pub ild_line_ending: LineEnding,
    /// Lockstep or real time.
    pub timing: TimingMode,
    /// Overrides the scene's seed.
    pub seed: Option<u64>,
    /// Missed periods before the watchdog fires.
    pub watchdog_periods: u32,
    /// Lockstep: wall-clock allowance per missed period, s.
    pub lockstep_answer_allowance_s: f64,
    /// Real time: how long to run, s (default: until the link closes).
    pub duration_s: Option<f64>,
    /// Status frames per second of loop time.
    pub heartbeat_hz: f64,
    /// A protocol rule to break on purpose (a conformance test aid).
    pub misbehave: Option<misbehaviour::Misbehaviour>,
    /// The sensor losing its peak (`None`: never).
    pub sensor_faults: Option<SensorFaults>,
    /// Real time: busy-polling, CPU pinning and `SCHED_FIFO` for the loop's thread.
    pub realtime: RealtimeOptions,
    /// Real time: how long the wake-up probe runs before the ready line, s (0: not at all).
    pub probe_s: f64,
    /// Serve this recorded session's folder instead of emulating the scene's plant
    /// ([`replay_node`]); the scene gives the control period and the sensor's settings.
    pub replay: Option<PathBuf>,
}

impl ServeConfig {
    /// Checks every timing value against the limits the host holds a run to
    /// ([`loop_limits`]), for a plant whose control period is `period_s`: the watchdog, the
    /// answer allowance, the real-time duration, the heartbeat (at most one per period), the
    /// probe and the real-time options. The error names the value's flag
    /// ([`Invalid::as_own_flag`]).
    ///
    /// # Errors
    /// The first value out of its range.
    pub fn check(&self, period_s: f64) -> Result<(), Invalid> {
        loop_limits::ANSWER_ALLOWANCE_S.check(
            "lockstep_answer_allowance_s",
            self.lockstep_answer_allowance_s,
        )?;
        let allowance_s = match self.timing {
            TimingMode::Lockstep => self.lockstep_answer_allowance_s,
            TimingMode::Realtime => period_s,
        };
        loop_limits::check_watchdog("watchdog_periods", self.watchdog_periods, allowance_s)?;
        loop_limits::DURATION_S.check_some("duration_s", self.duration_s)?;
        loop_limits::heartbeat_hz(1.0 / period_s).check("heartbeat_hz", self.heartbeat_hz)?;
        loop_limits::PROBE_S.check("probe_s", self.probe_s)?;
        scheduling::check(&self.realtime).map_err(|(field, reason)| Invalid::new(field, reason))?;
        if self.timing == TimingMode::Lockstep && self.realtime != RealtimeOptions::default() {
            return Err(Invalid::new(
                "timing",
                "--busy-poll, --cpu and --sched-fifo-priority apply to --timing realtime only",
            ));
        }
        if let Some(rule) = self.misbehave
            && self.timing == TimingMode::Lockstep
            && !rule.in_lockstep()
        {
            return Err(Invalid::new(
                "misbehave",
                "slow-clock needs --timing realtime (a lockstep node has no clock of its own)",
            ));
        }
        if self.replay.is_some() {
            let refused = match (&self.misbehave, &self.sensor_faults) {
                (Some(_), _) => Some(("misbehave", "no non-conforming node")),
                (_, Some(_)) => Some((
                    "sensor_faults",
                    "no sensor faults (it serves what was recorded)",
                )),
                _ => None,
            };
            if let Some((field, what)) = refused {
                return Err(Invalid::new(field, format!("a replay takes {what}")));
            }
        }
        Ok(())
    }
}

/// How a serve run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ServeOutcome {
    /// The controller closed the link or the duration ended.
    Finished,
    /// The watchdog fired: currents were zeroed and a LinkTimeout fault sent.
    LinkTimeout,
    /// A link failed (bus-off, an OS error on the line, the sensor's line failing): currents
    /// were zeroed and the node's fault frame attempted where the link could still send.
    LinkFailed,
}

impl ServeOutcome {
    /// The process's exit status: 0 after a clean run, 3 after a link timeout or failure.
    #[must_use]
    pub fn exit_status(self) -> u8 {
        match self {
            ServeOutcome::Finished => 0,
            ServeOutcome::LinkTimeout | ServeOutcome::LinkFailed => 3,
        }
    }
}

/// What ended a serve run (the summary's `ended_by`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RunEnd {
    /// The host closed the SLCAN channel (`C`): the end of its session, as a hang-up.
    HostClosedChannel,
    /// The host closed the line (or a bus link went away).
    HangUp,
    /// The controller's Status frame ended the run (after its zero command).
    ControllerStatus,
    /// Real time: the requested duration ran out.
    Duration,
    /// The watchdog fired.
    Watchdog,
    /// The host stopped reading the mirror's link: the node's frames could not be written
    /// within the watchdog's allowance (coils zeroed, as for the watchdog).
    HostStoppedReading,
    /// SocketCAN: the CAN controller went bus-off ([`LinkError::BusOff`]; coils zeroed).
    BusOff,
    /// Any other link failure: an OS error on a line, a peer breaking the link's protocol, the
    /// sensor's line failing (coils zeroed).
    LinkFailed,
}

impl RunEnd {
    /// How a link error ends the run: `Some` for the host's hang-up or its closing of the
    /// channel, `None` for a real failure.
    #[must_use]
    pub fn from_link_error(error: &LinkError) -> Option<RunEnd> {
        match error {
            LinkError::HangUp { .. } => Some(RunEnd::HangUp),
            LinkError::ChannelClosed { .. } => Some(RunEnd::HostClosedChannel),
            _ => None,
        }
    }

    /// How any link error ends the run: the host's hang-up or closing of the channel as
    /// [`RunEnd::from_link_error`] says, else [`RunEnd::BusOff`] or [`RunEnd::LinkFailed`].
    #[must_use]
    pub fn of_link_error(error: &LinkError) -> RunEnd {
        RunEnd::from_link_error(error).unwrap_or(match error {
            LinkError::BusOff { .. } => RunEnd::BusOff,
            _ => RunEnd::LinkFailed,
        })
    }

    /// The outcome of a run that ended so.
    #[must_use]
    pub fn outcome(self) -> ServeOutcome {
        match self {
            RunEnd::HostClosedChannel
            | RunEnd::HangUp
            | RunEnd::ControllerStatus
            | RunEnd::Duration => ServeOutcome::Finished,
            RunEnd::Watchdog | RunEnd::HostStoppedReading => ServeOutcome::LinkTimeout,
            RunEnd::BusOff | RunEnd::LinkFailed => ServeOutcome::LinkFailed,
        }
    }
}

/// The open links of a serve run.
#[derive(Debug)]
pub struct ServeLinks {
    /// The mirror node's CAN link (device end).
    pub fsm: CanLink,
    /// Where the sensor's samples go.
    pub sensor: SensorPort,
}

/// Loads the scene, opens the links, prints the ready line, runs, prints the summary.
///
/// A link error ends the run as [`wind_down::end_on_link_error`] says: the host's hang-up
/// finishes it, a failure (bus-off, an I/O error) zeroes the coils, attempts the node's fault
/// frame and ends with [`ServeOutcome::LinkFailed`] and the reason in the summary.
///
/// # Errors
/// A scene or plant that cannot be built, a value out of its range
/// ([`ServeConfig::check`]), a link that does not open, a plant error.
pub fn serve(config: &ServeConfig) -> anyhow::Result<ServeOutcome> {
    let (scene, plant) = load_plant(&config.scene, config.seed)?;
    config
        .check(plant.period_s())
        .map_err(Invalid::as_own_flag)?;
    // A recording that cannot be served is refused before any link opens.
    let recording = config.replay.as_deref().map(Recording::read).transpose()?;
    // What each part costs, measured before any link opens (the plant that runs is not
    // touched); a replay runs no part.
    let part_costs = match recording {
        None => Some(
            crate::part_cost::measure(&scene, crate::part_cost::CostTiming::default())
                .with_context(|| format!("timing the parts of {}", config.scene.display()))?,
        ),
        Some(_) => None,
    };
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the I/O runtime")?;
    // Real time: the loop's thread is set up, and the machine's wake-up latency measured with
    // the same settings, before the ready line (the clock starts after it).
    let scheduling_report = (config.timing == TimingMode::Realtime).then(|| {
        let in_effect = scheduling::apply(&config.realtime);
        for warning in &in_effect.warnings {
            eprintln!("scanhil-emulator: {warning}");
        }
        let probe = scheduling::wakeup_probe(
            Duration::from_secs_f64(plant.period_s()),
            Duration::from_secs_f64(config.probe_s),
        );
        serde_json::json!({
            "in_effect": in_effect,
            "wakeup_probe": match probe {
                Ok(stats) => serde_json::json!(stats),
                Err(errno) => serde_json::json!({ "error": format!("wake-up probe failed: {errno}") }),
            },
        })
    });
    runtime.block_on(async {
        let mut ready = serde_json::json!({
            "event": "ready",
            "scene": scene.name,
            "timing": config.timing,
            "period_s": plant.period_s(),
            "sensor_measuring_rate_hz": scene
                .has(crate::scene::Part::Sensor)
                .then(|| scene.sensor.unwrap_or_default().measuring_rate_hz),
            "active_parts": plant.active_parts(),
            "misbehave": config.misbehave,
            "replay": config.replay,
        });
        let Some(fsm_uri) = config.fsm.as_deref() else {
            bail!("--fsm is required: the mirror node clocks the sensor in both timing modes");
        };
        let fsm = open_fsm(fsm_uri, config.slcan_adapter).await?;
        ready["fsm"] = fsm.name().into();
        if fsm.is_slcan() {
            ready["slcan_adapter"] = config.slcan_adapter.name().into();
        }
        let (sensor, sensor_name) =
            SensorPort::open(config.sensor.as_deref(), &scene, config.ild_line_ending)?;
        // Lockstep loses no sensor cycle (the host gives time); real time streams as a real
        // sensor does, dropping what the line cannot take.
        let sensor = match config.timing {
            TimingMode::Lockstep => sensor.lossless(),
            TimingMode::Realtime => sensor,
        };
        ready["sensor"] = sensor_name.into();
        println_flushed(&ready)?;
        let mut links = ServeLinks { fsm, sensor };
        let rate_hz = scene.sensor.unwrap_or_default().measuring_rate_hz;
        let (mut report, mut summary, declared_clock) = match recording {
            Some(recording) => {
                replay(recording, plant.period_s(), rate_hz, &mut links, config).await?
            }
            None => {
                let (report, summary) = emulate(plant, &scene, &mut links, config).await?;
                (report, summary, None)
            }
        };
        if let (Some(scheduling), Some(timing)) = (scheduling_report, report.timing.as_object_mut())
        {
            timing.insert("scheduling".into(), scheduling);
        }
        let mut sensor = serde_json::json!(links.sensor.summary());
        if let (Some(clock), Some(sensor)) = (declared_clock, sensor.as_object_mut()) {
            // A replay declares the clock the recording's host used.
            sensor.insert("counter_zero_s".into(), clock.counter_zero_s.into());
            sensor.insert("first_sent_counter".into(), clock.first_counter.into());
        }
        summary.extend([
            ("event".to_owned(), "summary".into()),
            ("outcome".to_owned(), serde_json::json!(report.outcome)),
            ("ended_by".to_owned(), serde_json::json!(report.ended_by)),
            ("link".to_owned(), link_summary(&links.fsm)),
            ("sensor".to_owned(), sensor),
            ("parts".to_owned(), serde_json::json!(part_costs)),
            ("timing".to_owned(), std::mem::take(&mut report.timing)),
            ("error".to_owned(), serde_json::json!(report.error)),
        ]);
        println_flushed(&serde_json::Value::Object(summary))?;
        if let Some(error) = &report.error {
            eprintln!("scanhil-emulator: {error}; coil currents zeroed");
        }
        Ok(report.outcome)
    })
}

/// The summary's fields a node adds (its counters, final state, held currents).
type NodeSummary = serde_json::Map<String, serde_json::Value>;

/// Serves the scene's emulated plant in the timing mode asked.
async fn emulate(
    plant: Plant,
    scene: &Scene,
    links: &mut ServeLinks,
    config: &ServeConfig,
) -> anyhow::Result<(LoopReport, NodeSummary)> {
    let mut node = MirrorNode::new(plant);
    if let Some(faults) = &config.sensor_faults {
        let rate_hz = scene.sensor.unwrap_or_default().measuring_rate_hz;
        node = node.with_sensor_faults(SensorFaultModel::new(faults.clone(), scene.seed, rate_hz));
    }
    let served = match config.timing {
        TimingMode::Lockstep => lockstep::run(&mut node, links, config).await,
        TimingMode::Realtime => realtime::run(&mut node, links, config).await,
    };
    let report = match served {
        Ok(report) => report,
        Err(error) => wind_down::end_on_link_error(&mut node, links, error).await?,
    };
    let summary = NodeSummary::from_iter([
        ("node".to_owned(), serde_json::json!(node.counters())),
        ("final_state".to_owned(), serde_json::json!(node.state())),
        (
            "held_coil_currents_a".to_owned(),
            serde_json::json!(node.held_command_a()),
        ),
        (
            "sensor_faults".to_owned(),
            serde_json::json!(node.sensor_fault_counts()),
        ),
    ]);
    Ok((report, summary))
}

/// Serves a recorded session ([`ReplayNode`]) in the timing mode asked; its summary holds the comparison
/// of the controller's commands with the recorded ones (`replay`). Returns the sensor clock to
/// declare too: the recording host's, when its report gave it.
async fn replay(
    recording: Recording,
    period_s: f64,
    measuring_rate_hz: f64,
    links: &mut ServeLinks,
    config: &ServeConfig,
) -> anyhow::Result<(LoopReport, NodeSummary, Option<RecordedClock>)> {
    let clock = recording.clock;
    let mut node = ReplayNode::new(recording, period_s, measuring_rate_hz);
    let served = match config.timing {
        TimingMode::Lockstep => lockstep::run_answers(&mut node, links, config).await,
        TimingMode::Realtime => realtime::run(&mut node, links, config).await,
    };
    let report = match served {
        Ok(report) => report,
        Err(error) => {
            wind_down::end_on_link_error_with(links, error, || node.on_link_failure()).await?
        }
    };
    let summary = NodeSummary::from_iter([
        ("node".to_owned(), serde_json::json!(node.counters())),
        ("final_state".to_owned(), serde_json::json!(node.state())),
        (
            "held_coil_currents_a".to_owned(),
            serde_json::json!(node.held_command_a()),
        ),
        ("replay".to_owned(), serde_json::json!(node.comparison())),
    ]);
    Ok((report, summary, clock))
}

/// Loads the scene at `path`, `seed` (if given) overriding its own, and builds its plant, as
/// `serve` does.
///
/// # Errors
/// A scene that does not load, a plant that cannot be built.
pub fn load_plant(path: &Path, seed: Option<u64>) -> anyhow::Result<(Scene, Plant)> {
    let mut scene = Scene::load(path)?;
    if let Some(seed) = seed {
        scene.seed = seed;
    }
    let plant = Plant::from_scene(&scene)
        .with_context(|| format!("building the plant of {}", path.display()))?;
    Ok((scene, plant))
}

/// What a timing loop reports back.
#[derive(Debug, Clone)]
pub struct LoopReport {
    /// How it ended.
    pub outcome: ServeOutcome,
    /// What ended it.
    pub ended_by: RunEnd,
    /// Real time: the emulator's period statistics (JSON), lockstep: null.
    pub timing: serde_json::Value,
    /// A link or protocol error that ended the run, if any.
    pub error: Option<String>,
}

/// Opens the mirror node's link; on SLCAN the device end plays `adapter`, and the host's `C`
/// ends the run ([`RunEnd::HostClosedChannel`]).
async fn open_fsm(uri: &str, adapter: EmulatedAdapter) -> anyhow::Result<CanLink> {
    let mut link = if uri == "slcan:pty" {
        CanLink::open_pty(PtyPair::open()?, None, Role::Device).await?
    } else {
        let parsed: LinkUri = uri.parse()?;
        CanLink::open(&parsed, Role::Device).await?
    };
    link.play_slcan_adapter(adapter);
    link.end_run_on_close();
    Ok(link)
}

fn link_summary(link: &CanLink) -> serde_json::Value {
    let stats = link.stats();
    serde_json::json!({
        "frames_sent": stats.frames_sent,
        "frames_received": stats.frames_received,
        "slcan_malformed_lines": stats.slcan.malformed_lines,
        "slcan_refused_frames": stats.slcan.refused_frames,
        "slcan_dropped_while_closed": stats.slcan.dropped_while_closed,
        "bus_error_frames": stats.bus_error_frames,
    })
}

fn println_flushed(value: &serde_json::Value) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(out, "{value}").context("writing to stdout")?;
    out.flush().context("writing to stdout")
}
