//! The loop runner behind `scanhil scan`: loads a scenario, opens the links (by default a pty
//! pair per node with `scanhil-emulator serve` on the other end), runs the loop in lockstep or
//! in real time, pairs distances with angles by the sensor's time, and writes the output
//! folder.
//!
//! # Layout
//! - [`scenario`]: the scenario file format and its loading.
//! - [`emulator_process`]: locating and starting `scanhil-emulator serve`.
//! - [`host_loop`]: the host's lockstep loop as a state machine without I/O.
//! - [`host_inbox`]: what the host does with each received frame (no I/O).
//! - [`loop_error`]: why a loop stopped early, for the pure loop, its links and its shells.
//! - [`mirror_link`]: the mirror node seen from the controller: exchanges, status, faults,
//!   watchdog.
//! - [`sensor_link`]: the ILD stream seen from the controller, with its raw recording.
//! - [`sample_log`]: a sensor's samples as they arrive on either link (counters unwrapped,
//!   arrivals bounding its clock).
//! - [`sensor_setup`]: configuring and reading back the sensor before a scan.
//! - [`bus_load`]: refusing a loop that cannot fit on a link's bit rate.
//! - [`budget`]: what a scan will hold and write (the height map's grid over the area it can
//!   cover, its recordings), checked before any link opens against what [`machine`] reads:
//!   the available memory and the output folder's free disk.
//! - [`chunked`]: what a run keeps per sample, in chunks freed as imaging passes them.
//! - [`lockstep`], [`realtime`]: the two loops.
//! - [`controller_timing`]: the host's real-time settings, wake-up probe and timing figures,
//!   and the report's verdicts on them (who missed each deadline, jitter against the probe).
//! - [`interrupt`]: Ctrl-C, SIGTERM and SIGHUP stop the loop like any early stop.
//! - [`plan`]: what a scan runs, worked out before its links open: controller, power check,
//!   [`lead_in`] before the recorded frame, predicted tracking error.
//! - [`pairing`]: distances with angles by the sensor's own time.
//! - [`tracking`]: reference against measured angles.
//! - [`replay_check`]: a scan against a recorded session (`--replay`): the report's `replay`
//!   section and what the verdict judges of it.
//! - [`verdict`]: whether the run did what it was asked (complete, stopped, failed), from its
//!   figures alone.
//! - [`output`]: report.json, PLY, height map, plots.
//! - [`output_failures`]: outputs that could not be written, listed instead of ending the
//!   scan.
//! - [`out_folder`]: the output folder, locked for one scan and cleared of an earlier one's
//!   files.
//! - [`progress`]: the progress bar (terminal only).
//! - [`power_guard`], [`power_backoff`]: the coil power check before a run (shrink, refuse)
//!   and the back-off when the node's power limit acts.
//! - [`conformance`]: checks of a mirror node and a sensor against the loop protocol;
//!   [`check_selection`]: which of them run (`--check`, `--skip`, `--destructive`).
//! - [`plant_link`]: [`crate::link::PlantLink`] over a real mirror link, for `scanhil identify`.

pub mod budget;
pub mod bus_load;
pub mod check_selection;
pub mod chunked;
pub mod conformance;
pub mod controller_timing;
pub mod emulator_process;
pub mod host_inbox;
pub mod host_loop;
pub mod interrupt;
pub mod lead_in;
pub mod link_faults;
pub mod lockstep;
pub mod loop_error;
pub mod machine;
pub mod mirror_link;
pub mod out_folder;
pub mod output;
pub mod output_failures;
pub mod pairing;
pub mod plan;
pub mod plant_link;
pub mod power_backoff;
pub mod power_guard;
pub mod progress;
pub mod realtime;
pub mod replay_check;
pub mod sample_log;
pub mod scenario;
pub mod sensor_link;
pub mod sensor_setup;
pub mod tracking;
pub mod verdict;

use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use anyhow::{Context, bail};
use scanhil_protocol::link::role::Role;
use scanhil_protocol::link::{CanCapture, CanLink, CaptureClock, LinkUri, PtyPair, VirtualClock};
use scanhil_protocol::socketcan::interface_state::{self, ExpectedBitrate};
use scanhil_protocol::validation::{Invalid, InvalidValue};

use emulator_process::{EmulatorProcess, locate_emulator};
use host_loop::{HostLoop, LoopRecord};
use lead_in::LeadIn;
use link_faults::LinkFaults;
use mirror_link::MirrorLink;
use output_failures::{OutputFailures, RecordingFailure, RecordingFile};
use pairing::{ArrivalBound, SensorClock};
use plan::ScanPlan;
use scenario::{NodeLink, Scenario, TimingMode};
use sensor_link::SensorLink;

/// How long the emulator gets to finish after the controller closed its links (on a bus
/// link it sees no hang-up, and is stopped after this).
const EMULATOR_GRACE: Duration = Duration::from_secs(2);

/// What `scanhil scan` was asked besides the scenario.
#[derive(Debug, Clone, Default)]
pub struct ScanOptions {
    /// The output folder.
    pub out_dir: PathBuf,
    /// The emulator binary, if not found the usual way.
    pub emulator: Option<PathBuf>,
    /// Overrides the scenario's mirror link.
    pub fsm: Option<NodeLink>,
    /// Overrides the scenario's sensor link.
    pub sensor: Option<NodeLink>,
    /// Overrides the scenario's timing mode.
    pub timing: Option<TimingMode>,
    /// Overrides the scenario's duration, s.
    pub duration_s: Option<f64>,
    /// Overrides the scenario's watchdog periods.
    pub watchdog_periods: Option<u32>,
    /// Overrides the scenario's lead-in with a fixed one, s.
    pub lead_in_s: Option<f64>,
    /// Do not start the emulator (the nodes are already on the links).
    pub no_emulator: bool,
    /// Fault overrides `KEY=VALUE` below the scenario's `faults`
    /// ([`link_faults::FaultsConfig::with_override`]), applied in order.
    pub faults: Vec<String>,
    /// Real time: busy-poll on both ends (only ever turns it on).
    pub busy_poll: bool,
    /// Overrides the scenario's host CPU.
    pub cpu: Option<usize>,
    /// Overrides the scenario's emulator CPU.
    pub emulator_cpu: Option<usize>,
    /// Overrides the scenario's `SCHED_FIFO` priority.
    pub sched_fifo_priority: Option<u8>,
    /// Overrides the scenario's wake-up probe duration, s.
    pub probe_s: Option<f64>,
    /// Overrides how long a started emulator may take to become ready, s.
    pub emulator_ready_s: Option<f64>,
    /// Stamps the recording with Unix times (only ever turns it on).
    pub record_epoch: bool,
    /// Overrides the scenario's recording interface name.
    pub record_iface: Option<String>,
    /// Leaves out the recordings (only ever turns them off).
    pub no_recordings: bool,
    /// Leaves out the figures (only ever turns them off).
    pub no_figures: bool,
    /// Serve this recorded session as the devices (`scanhil-emulator replay`) instead of
    /// emulating the scene.
    pub replay: Option<PathBuf>,
    /// With `replay`: a coil command that differs from the recording's fails the run.
    pub replay_must_match: bool,
}

impl ScanOptions {
    /// `scenario` with these overrides applied and checked as the file is
    /// ([`Scenario::check_values`]); an error in a value a flag gave names the flag, one in
    /// the file's own value the file and field.
    ///
    /// # Errors
    /// [`scenario::ScenarioError::Invalid`] naming the flag, or the file and field.
    pub fn apply_to(&self, scenario: &Scenario) -> Result<Scenario, scenario::ScenarioError> {
        let mut scenario = scenario.clone();
        if let Some(fsm) = &self.fsm {
            scenario.links.fsm = fsm.clone();
        }
        if let Some(sensor) = &self.sensor {
            scenario.links.sensor = sensor.clone();
        }
        if let Some(mode) = self.timing {
            scenario.timing.mode = mode;
        }
        if let Some(duration_s) = self.duration_s {
            scenario.duration_s = duration_s;
        }
        if let Some(periods) = self.watchdog_periods {
            scenario.timing.watchdog_periods = periods;
        }
        if let Some(duration_s) = self.lead_in_s {
            scenario.lead_in = LeadIn::Fixed { duration_s };
        }
        if self.no_emulator {
            scenario.links.spawn_emulator = false;
        }
        self.check_replay()?;
        for assignment in &self.faults {
            scenario.faults = scenario.faults.with_override(assignment).map_err(|error| {
                Invalid::new("fault", Invalid::new(error.field, error.reason).to_string())
                    .as_flag(&format!("--fault {assignment}"))
            })?;
        }
        let timing = &mut scenario.timing;
        timing.busy_poll |= self.busy_poll;
        timing.cpu = self.cpu.or(timing.cpu);
        timing.emulator_cpu = self.emulator_cpu.or(timing.emulator_cpu);
        timing.sched_fifo_priority = self.sched_fifo_priority.or(timing.sched_fifo_priority);
        timing.probe_s = self.probe_s.unwrap_or(timing.probe_s);
        timing.emulator_ready_s = self.emulator_ready_s.unwrap_or(timing.emulator_ready_s);
        scenario.recording.epoch |= self.record_epoch;
        if let Some(iface) = &self.record_iface {
            scenario.recording.iface.clone_from(iface);
        }
        scenario.outputs.recordings &= !self.no_recordings;
        scenario.outputs.figures &= !self.no_figures;
        scenario
            .check_values()
            .map_err(|invalid| match self.flag_of(&invalid.field) {
                Some(flag) => invalid.as_flag(flag),
                None => invalid.in_file(&scenario.path),
            })?;
        Ok(scenario)
    }

    /// `--replay` needs an emulator started here to serve the recording;
    /// `--replay-must-match` needs `--replay`.
    fn check_replay(&self) -> Result<(), InvalidValue> {
        let refused = match &self.replay {
            None if self.replay_must_match => Some(("--replay-must-match", "needs --replay DIR")),
            None => None,
            Some(_) if self.no_emulator => Some((
                "--replay",
                "serves the recording from an emulator this scan starts: not with --no-emulator",
            )),
            Some(_) => None,
        };
        match refused {
            Some((flag, reason)) => Err(Invalid::new("replay", reason).as_flag(flag)),
            None => Ok(()),
        }
    }

    /// The flag that set scenario field `field`, when it was given.
    fn flag_of(&self, field: &str) -> Option<&'static str> {
        let given = |given: bool, flag: &'static str| given.then_some(flag);
        match field {
            "duration_s" => given(self.duration_s.is_some(), "--duration-s"),
            "timing.watchdog_periods" => {
                given(self.watchdog_periods.is_some(), "--watchdog-periods")
            }
            "lead_in.duration_s" => given(self.lead_in_s.is_some(), "--lead-in-s"),
            "timing.mode" => [
                (self.timing.is_some(), "--timing"),
                (self.busy_poll, "--busy-poll"),
                (self.cpu.is_some(), "--cpu"),
                (self.emulator_cpu.is_some(), "--emulator-cpu"),
                (self.sched_fifo_priority.is_some(), "--sched-fifo-priority"),
            ]
            .into_iter()
            .find_map(|(given, flag)| given.then_some(flag)),
            "timing.cpu" => given(self.cpu.is_some(), "--cpu"),
            "timing.emulator_cpu" => given(self.emulator_cpu.is_some(), "--emulator-cpu"),
            "timing.sched_fifo_priority" => {
                given(self.sched_fifo_priority.is_some(), "--sched-fifo-priority")
            }
            "timing.probe_s" => given(self.probe_s.is_some(), "--probe-s"),
            "timing.emulator_ready_s" => {
                given(self.emulator_ready_s.is_some(), "--emulator-ready-s")
            }
            "recording.iface" => given(self.record_iface.is_some(), "--record-iface"),
            "scene" | "faults.sensor" => given(
                self.fsm.is_some() || self.sensor.is_some() || self.no_emulator,
                "--fsm/--sensor/--no-emulator",
            ),
            _ => None,
        }
    }
}

/// How the scan ended, for the exit status.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ScanEnd {
    /// Every period ran.
    Complete,
    /// The loop stopped early (link timeout, node fault, link failure); the message says why.
    Stopped(String),
}

impl ScanEnd {
    /// How the loop that made `record` ended.
    #[must_use]
    pub fn of(record: &host_loop::LoopRecord) -> ScanEnd {
        match &record.stopped_by {
            None => ScanEnd::Complete,
            Some(error) => ScanEnd::Stopped(error.to_string()),
        }
    }
}

/// What a scan came to: how its loop ended, its verdict, and the outputs that could not be
/// written.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanResult {
    /// How the loop ended.
    pub end: ScanEnd,
    /// Whether the run did what it was asked ([`verdict`]).
    pub verdict: verdict::Verdict,
    /// Output files that could not be written, with why (the others were written).
    pub failed_outputs: OutputFailures,
}

impl ScanResult {
    /// The exit status of `scanhil scan`: 0 complete, 3 stopped early or an output not
    /// written, 4 completed but not valid ([`verdict::Status::exit_code`]).
    #[must_use]
    pub fn exit_code(&self) -> u8 {
        if self.failed_outputs.is_empty() {
            self.verdict.status.exit_code()
        } else {
            verdict::Status::Stopped.exit_code()
        }
    }
}

/// Runs a scenario and writes its output folder; returns how it ended and which outputs
/// failed.
///
/// # Errors
/// Anything that keeps the run from starting (bad files, an unfit bus load, links that do
/// not open, no emulator binary) or from writing its outputs.
pub fn run_scan(scenario: &Scenario, options: &ScanOptions) -> anyhow::Result<ScanResult> {
    let mut scenario = options.apply_to(scenario)?;
    // What runs is reported: `--no-emulator` with a `pty` link still starts it.
    scenario.links.spawn_emulator = scenario
        .links
        .starts_emulator(scenario.rig.sensor.is_some());
    let plan = ScanPlan::new(&scenario)?;
    // What runs (and is reported) is the trajectory after the power check.
    scenario.trajectory = plan.trajectory.clone();
    let periods = plan.periods();
    let ScanPlan {
        mut controller,
        backoff,
        summary: plan_summary,
        grid_cells,
        ..
    } = plan;
    let lead_in_periods = plan_summary.lead_in.periods;
    let rig = &scenario.rig;
    let period_s = controller.period_s();
    let sensor_rate_hz = rig.sensor.map(|sensor| sensor.measuring_rate_hz);
    bus_load::check(&scenario, sensor_rate_hz.unwrap_or(0.0), period_s)?;
    if let Some(sensor) = &rig.sensor {
        sensor_setup::check_line(sensor, &scenario.links.sensor, &rig.path)?;
    }
    let sensor_cycles = sensor_rate_hz.map_or(0.0, |rate_hz| rate_hz * periods as f64 * period_s);
    let values_per_cycle = rig.sensor.map_or(0, |sensor| sensor.output().values.len());
    budget::OutputBytes::of_run(periods, sensor_cycles, values_per_cycle, grid_cells)
        .with_recordings(scenario.outputs.recordings)
        .check(machine::free_disk_bytes(&options.out_dir))
        .map_err(|invalid| {
            scenario::ScenarioError::from(match options.flag_of(&invalid.field) {
                Some(flag) => invalid.as_flag(flag),
                None => invalid.in_file(&scenario.path),
            })
        })?;
    // Held to the end of the scan: a second scan into this folder is refused meanwhile.
    let _folder = out_folder::OutputFolder::claim(&options.out_dir)?;

    // Real time: this thread runs the loop; it is set up, and the machine's wake-up latency
    // measured with the same settings, before the links open.
    let host_scheduling = (scenario.timing.mode == TimingMode::Realtime)
        .then(|| controller_timing::HostScheduling::set_up(&scenario.timing, period_s));
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the I/O runtime")?;
    let out_dir = options.out_dir.clone();
    let mut outcome = runtime.block_on(async {
        let started = std::time::Instant::now();
        let plan = LinkPlan {
            fsm: scenario.links.fsm.clone(),
            sensor: rig.sensor.map(|_| scenario.links.sensor.clone()),
            spawn_emulator: scenario.links.spawn_emulator,
            emulator: options.emulator.clone(),
            scene: scenario.scene.clone().unwrap_or_default(),
            seed: scenario.seed,
            sensor_faults: scenario.faults.sensor.clone(),
            timing: scenario.timing,
            period_s,
            duration_s: periods as f64 * period_s,
            record_dir: scenario.outputs.recordings.then(|| out_dir.clone()),
            recording: scenario.recording.clone(),
            bus_bitrate: rig.bus.map(|bus| bus.bitrate_bps.round() as u32),
            sensor_expectation: rig.sensor,
            replay: options.replay.clone(),
        };
        let mut links = open_links(&plan).await?;
        let progress = progress::Progress::new(periods, &scenario.name);
        let mut interrupt =
            interrupt::Interrupt::install().context("installing the signal handlers")?;
        // The sensor's samples bound its clock as they arrive, on whichever link it is; on the
        // ILD line each cycle's last byte arrives at least its transmit time after it was
        // measured.
        if let Some(sensor) = rig.sensor {
            let rate_hz = sensor.measuring_rate_hz;
            let bound = match scenario.timing.mode {
                TimingMode::Lockstep => ArrivalBound::steps(period_s, rate_hz),
                TimingMode::Realtime => ArrivalBound::wall_clock(rate_hz),
            };
            let values = sensor.output().values.len() as u32;
            let transmit_s = scanhil_protocol::ild::stream::cycle_transmit_s(values, sensor.baud);
            links
                .sensor
                .bound_clock_by_arrivals(bound.clone().after_transmit(transmit_s));
            links.mirror.distances_mut().bound_clock_by_arrivals(bound);
        }
        // Angle history only where sensor samples are paired with it: a mirror-only run's
        // record takes the same memory however long it runs.
        let empty_record = LoopRecord::new(period_s, periods)
            .with_lead_in(lead_in_periods)
            .keeping_angles(rig.sensor.is_some());
        // Declared frame faults act on the mirror's link in both timing modes.
        let repeats_steps = match LinkFaults::new(&scenario.faults, scenario.seed, period_s) {
            Some(faults) => {
                links.mirror.set_faults(faults);
                true
            }
            None => false,
        };
        let record = match scenario.timing.mode {
            TimingMode::Lockstep => {
                // Injected frame faults are survived by repeating a Step that got no answer.
                let tries = if repeats_steps {
                    scenario.timing.watchdog_periods
                } else {
                    1
                };
                let host = HostLoop::new(
                    &mut controller,
                    &scenario.trajectory,
                    empty_record,
                    links.mirror.take_inbox(),
                )
                .with_backoff(backoff)
                .with_tries_per_reading(tries);
                lockstep::run(
                    repeats_steps,
                    &mut links.mirror,
                    &mut links.sensor,
                    host,
                    &progress,
                    &mut interrupt,
                )
                .await
            }
            TimingMode::Realtime => {
                realtime::run(
                    &mut links.mirror,
                    &mut links.sensor,
                    &mut controller,
                    &scenario.trajectory,
                    empty_record,
                    &progress,
                    &mut interrupt,
                    host_scheduling.clone().unwrap_or_default(),
                )
                .await
            }
        };
        progress.finish();
        // The loop has stopped (coils at zero): from here a signal ends the process at once,
        // so no wrap-up step can leave a scan that ignores SIGTERM.
        interrupt.restore_default();
        let can_distances = links.mirror.distances_mut().take_samples();
        let can_arrivals = links.mirror.distances_mut().take_arrival_bound();
        let mirror_counters = links.mirror.counters();
        let node_events = links.mirror.events().to_vec();
        let frame_faults = links.mirror.fault_report();
        // Closing the mirror link (`C` on SLCAN) ends the emulator's run; the sensor stream
        // then drains. A failed close (the node is gone) leaves nothing open; a node that
        // stopped reading cannot take the `C`, so it is given up after a bounded wait.
        let _ = tokio::time::timeout(mirror_link::STOP_SEND_ALLOWANCE, links.mirror.close()).await;
        let mirror_link = Some(links.mirror.can_link_mut().report());
        // The recording's last lines: a write that fails here is listed with its file among
        // the failed outputs below (the recording file keeps why), like one that failed
        // mid-run, and every other output is still written.
        let _ = links.mirror.can_link_mut().flush_capture();
        drop(links.mirror);
        // A drain cut short (a recording that fails, a sensor that errs) costs only the
        // samples still in flight: the outputs are written all the same.
        if let Err(error) = links.sensor.drain(Duration::from_millis(200)).await {
            eprintln!("warning: draining the sensor link: {error}");
        }
        let mut failed_recordings = links.recording_failures;
        for recording in &links.recordings {
            if let Some(why) = recording.get() {
                failed_recordings.add(recording.name, why.to_owned());
            }
        }
        let emulator_summary = match links.emulator {
            Some(process) => Some(finish_emulator(process, links.emulator_lines).await?),
            None => None,
        };
        anyhow::Ok(output::RunData {
            record,
            can_distances,
            can_arrivals,
            mirror_counters,
            mirror_link,
            node_events,
            sensor_arrivals: links.sensor.take_arrival_bound(),
            sensor: links.sensor.take_samples(),
            sensor_setup: links.sensor_setup,
            plant: links.plant,
            emulator_summary,
            frame_faults,
            run_time_s: started.elapsed().as_secs_f64(),
            failed_recordings,
            replay: options
                .replay
                .clone()
                .map(|recording| replay_check::ReplayRun {
                    recording,
                    must_match: options.replay_must_match,
                }),
        })
    })?;
    // Distance frames on the mirror's link always carry the counter; the ILD line when the
    // rig's sensor sends it.
    let on_can = scenario.links.sensor == NodeLink::Uri("fsm".into());
    let declared = rig.sensor.and_then(|sensor| {
        declared_sensor_clock(
            sensor.measuring_rate_hz,
            sensor.sends_counter() || on_can,
            outcome.emulator_summary.as_ref(),
        )
    });
    output::write(
        &scenario,
        &plan_summary,
        &mut outcome,
        declared,
        &options.out_dir,
    )
}

/// What to connect to: the nodes' links, and how to start the emulator for emulated nodes.
#[derive(Debug, Clone)]
pub struct LinkPlan {
    /// The mirror node's link.
    pub fsm: NodeLink,
    /// The sensor's link; `None` when the run needs no sensor.
    pub sensor: Option<NodeLink>,
    /// Start `scanhil-emulator serve` (for pty links always; for URIs when asked).
    pub spawn_emulator: bool,
    /// The emulator binary, if not found the usual way.
    pub emulator: Option<PathBuf>,
    /// The scene the emulator serves.
    pub scene: PathBuf,
    /// The plant's seed.
    pub seed: u64,
    /// The sensor losing its peak (handed to an emulator started here).
    pub sensor_faults: scanhil_protocol::fault_injection::SensorFaults,
    /// Timing and watchdog.
    pub timing: scenario::TimingConfig,
    /// The control period, s.
    pub period_s: f64,
    /// Real time: how long the emulator runs, s.
    pub duration_s: f64,
    /// Record the links into this folder (`fsm.log`, `sensor.ild`).
    pub record_dir: Option<PathBuf>,
    /// How `fsm.log` is stamped and which interface it names.
    pub recording: scenario::RecordingConfig,
    /// The rig's bus bit rate, bit/s, checked against a SocketCAN interface's own (`None`:
    /// the rig states no bus).
    pub bus_bitrate: Option<u32>,
    /// The rig's sensor: configured and read back before the run, and an emulator started here
    /// must serve it at its rate (`None`: left as it is, not checked).
    pub sensor_expectation: Option<crate::rig::RigSensor>,
    /// An emulator started here replays this recorded session (`scanhil-emulator replay`)
    /// instead of serving the scene's plant.
    pub replay: Option<PathBuf>,
}

impl LinkPlan {
    /// The baud rate of an emulated sensor's line: the rig's, or the factory 691 200 when no
    /// sensor is expected.
    #[must_use]
    pub fn sensor_baud(&self) -> u32 {
        self.sensor_expectation
            .map_or(scanhil_protocol::ild::stream::FACTORY_BAUD, |sensor| {
                sensor.baud
            })
    }
}

/// The open links and the emulator process behind them.
#[derive(Debug)]
pub struct OpenLinks {
    /// The mirror node.
    pub mirror: MirrorLink,
    /// The sensor.
    pub sensor: SensorLink,
    /// The emulator, when started here.
    pub emulator: Option<EmulatorProcess>,
    /// The emulator's stdout lines after its ready line.
    pub emulator_lines: Option<mpsc::Receiver<String>>,
    /// What the sensor set-up did, when the plan asked for one.
    pub sensor_setup: Option<sensor_setup::SensorSetupReport>,
    /// What the emulated plant declares of itself (nothing for real devices).
    pub plant: verdict::PlantDeclares,
    /// The recordings being written (`record_dir`), each with its first write error.
    pub recordings: Vec<RecordingFailure>,
    /// The recordings that could not be created.
    pub recording_failures: OutputFailures,
}

/// Opens the links of `plan`, starting the emulator first when the plan says so.
///
/// # Errors
/// Links that do not open, an emulator that cannot be found, started, or that exits before
/// it is ready.
pub async fn open_links(plan: &LinkPlan) -> anyhow::Result<OpenLinks> {
    let timing = plan.timing;
    let mut emulator_args: Vec<String> = match &plan.replay {
        Some(dir) => vec!["replay".into(), dir.display().to_string()],
        None => vec!["serve".into()],
    };
    emulator_args.extend([
        "--scene".into(),
        plan.scene.display().to_string(),
        "--seed".into(),
        plan.seed.to_string(),
        "--watchdog-periods".into(),
        timing.watchdog_periods.to_string(),
        "--lockstep-answer-allowance-s".into(),
        timing.lockstep_answer_allowance_s.to_string(),
        "--timing".into(),
        timing.mode.name().into(),
        // Killed with this process whatever ends it (started from this thread, which lives
        // as long as the process: the kernel's signal follows the thread that forked).
        "--exit-with-parent".into(),
        std::process::id().to_string(),
    ]);
    if timing.mode == TimingMode::Realtime {
        emulator_args.extend(realtime::emulator_args(&timing, plan.duration_s));
    }
    if plan.sensor_faults.is_active() {
        emulator_args.push("--sensor-faults".into());
        emulator_args
            .push(serde_json::to_string(&plan.sensor_faults).context("writing the sensor faults")?);
    }
    let mut spawn = plan.spawn_emulator || plan.replay.is_some();
    let fsm_pty = match &plan.fsm {
        NodeLink::Pty => {
            spawn = true;
            let pair = PtyPair::open()?;
            emulator_args.extend([
                "--fsm".into(),
                format!("slcan:{}", pair.slave_path().display()),
            ]);
            Some(pair)
        }
        NodeLink::Uri(uri) => {
            emulator_args.extend(["--fsm".into(), uri.clone()]);
            None
        }
    };
    let mut sensor_pty = None;
    match &plan.sensor {
        None => {}
        Some(NodeLink::Pty) => {
            spawn = true;
            let pair = PtyPair::open()?;
            emulator_args.extend([
                "--sensor".into(),
                format!("ild:{}@{}", pair.slave_path().display(), plan.sensor_baud()),
            ]);
            sensor_pty = Some(pair);
        }
        Some(NodeLink::Uri(uri)) => emulator_args.extend(["--sensor".into(), uri.clone()]),
    }
    // What the plant declares of itself: an emulator's ready line does, a real node does not.
    let mut plant = verdict::PlantDeclares::default();
    let (emulator, emulator_lines) = if spawn {
        let binary = locate_emulator(plan.emulator.as_deref())?;
        let mut process = EmulatorProcess::start(&binary, &emulator_args)?;
        let lines = process.stdout_lines();
        let wait = timing.emulator_ready_wait();
        let ready = tokio::task::spawn_blocking(move || {
            let first = lines.recv_timeout(wait);
            (first, lines)
        })
        .await
        .context("waiting for the emulator")?;
        let (first, lines) = ready;
        let ready = first
            .ok()
            .and_then(|line| serde_json::from_str::<serde_json::Value>(&line).ok())
            .filter(|line| line["event"] == "ready");
        // Not ready: the process is stopped as it is dropped here.
        let Some(ready) = ready else {
            bail!(
                "{} did not become ready within {:.1} s (`timing.emulator_ready_s`, \
                 `--emulator-ready-s`; see its error above, if any)",
                process.path().display(),
                wait.as_secs_f64()
            );
        };
        let devices = EmulatedDevices::from_ready_line(&ready);
        devices.check(
            &plan.scene,
            plan.period_s,
            plan.sensor_expectation.map(|s| s.measuring_rate_hz),
        )?;
        plant.dynamics = Some(devices.dynamics);
        (Some(process), Some(lines))
    } else {
        (None, None)
    };
    // The sensor is set up before the mirror's channel opens (which starts a real-time
    // emulator's clock), and before recording starts.
    let mut sensor = match (sensor_pty, &plan.sensor) {
        (Some(pair), _) => SensorLink::on_pty(pair, plan.sensor_baud())?,
        (None, Some(NodeLink::Uri(uri))) if uri != "fsm" => SensorLink::open(&uri.parse()?)?,
        _ => SensorLink::Elsewhere,
    };
    let sensor_setup = sensor_setup::for_plan(&mut sensor, plan).await?;
    let mut fsm = match (fsm_pty, &plan.fsm) {
        (Some(pair), _) => CanLink::open_pty(pair, None, Role::Host).await?,
        (None, NodeLink::Uri(uri)) => CanLink::open(&uri.parse()?, Role::Host).await?,
        (None, NodeLink::Pty) => unreachable!("a pty link has its pair"),
    };
    check_rig_bus(&fsm, &plan.fsm, plan.bus_bitrate)?;
    // A link given by URI: say what it was found to be (an adapter's family and the bit rate
    // set or kept; an interface's notes, such as a vcan's missing bit rate).
    if matches!(plan.fsm, NodeLink::Uri(_)) {
        eprintln!("scanhil: {}", fsm.open_summary());
    }
    let clock = (timing.mode == TimingMode::Lockstep).then(VirtualClock::default);
    // A recording that cannot be created is listed as a failed output; the scan runs without
    // it.
    let mut recordings = Vec::new();
    let mut recording_failures = OutputFailures::default();
    if let Some(dir) = &plan.record_dir {
        // Virtual time zero is now, when the loop is about to start.
        let capture_clock = match (clock.clone(), plan.recording.epoch) {
            (None, _) => CaptureClock::Wall,
            (Some(clock), false) => CaptureClock::Virtual(clock),
            (Some(clock), true) => CaptureClock::since_now(clock),
        };
        let fsm_log = RecordingFile::create(dir, output::FSM_LOG);
        if let Some((log, failure)) = recording_failures.attempt(output::FSM_LOG, fsm_log) {
            fsm.set_capture(CanCapture::new(log, &plan.recording.iface, capture_clock));
            recordings.push(failure);
        }
        if matches!(sensor, SensorLink::Ild(_)) {
            let capture = RecordingFile::create(dir, output::SENSOR_CAPTURE);
            if let Some((file, failure)) =
                recording_failures.attempt(output::SENSOR_CAPTURE, capture)
            {
                sensor.record_to(file);
                recordings.push(failure);
            }
        }
        for (file, why) in recording_failures.iter() {
            eprintln!("warning: {file} cannot be recorded ({why}); the scan runs without it");
        }
    }
    let allowance = match timing.mode {
        TimingMode::Lockstep => Duration::from_secs_f64(timing.lockstep_answer_allowance_s),
        TimingMode::Realtime => Duration::from_secs_f64(plan.period_s),
    };
    let mirror = MirrorLink::new(
        fsm,
        clock,
        plan.period_s,
        allowance,
        timing.watchdog_periods,
    );
    Ok(OpenLinks {
        mirror,
        sensor,
        recordings,
        recording_failures,
        emulator,
        emulator_lines,
        sensor_setup,
        plant,
    })
}

/// A SocketCAN interface whose bit rate is known must run at the rig's `bus_bitrate` (the URI's
/// `@BITRATE`, when given, was checked as the link opened).
///
/// # Errors
/// The two rates and the commands that set the interface.
fn check_rig_bus(fsm: &CanLink, link: &NodeLink, bus_bitrate: Option<u32>) -> anyhow::Result<()> {
    let NodeLink::Uri(uri) = link else {
        return Ok(());
    };
    let Ok(LinkUri::SocketCan { iface, .. }) = uri.parse() else {
        return Ok(());
    };
    let actual = fsm
        .report()
        .socketcan
        .and_then(|report| report.interface)
        .and_then(|interface| interface.bitrate);
    if let (Some(actual), Some(bitrate)) = (actual, bus_bitrate) {
        let expected = ExpectedBitrate {
            bitrate,
            source: "the rig's bus.bitrate_bps",
        };
        interface_state::check_bitrate(&iface, actual, expected)
            .map_err(|detail| anyhow::anyhow!("cannot use {}: {detail}", fsm.name()))?;
    }
    Ok(())
}

/// Waits for the emulator to exit (killing it after a grace period) and returns its exit
/// status and summary line as JSON.
///
/// # Errors
/// The OS error of waiting.
pub async fn finish_emulator(
    process: EmulatorProcess,
    lines: Option<mpsc::Receiver<String>>,
) -> anyhow::Result<serde_json::Value> {
    let status = tokio::task::spawn_blocking(move || process.finish(EMULATOR_GRACE))
        .await
        .context("waiting for the emulator")??;
    let summary = lines
        .into_iter()
        .flat_map(|rx| rx.into_iter())
        .filter_map(|line| serde_json::from_str::<serde_json::Value>(&line).ok())
        .find(|value| value["event"] == "summary")
        .unwrap_or(serde_json::Value::Null);
    Ok(emulator_end_json(status, summary))
}

/// The emulator's end in report.json: `exit_status` (its code, `null` when a signal ended
/// it), `killed` (a signal ended it, whoever sent it), `signal` (its name), `killed_by_host`
/// (this run killed it after the grace period) and its `summary` line (`null` without one).
fn emulator_end_json(
    status: Option<std::process::ExitStatus>,
    summary: serde_json::Value,
) -> serde_json::Value {
    use std::os::unix::process::ExitStatusExt;
    let (exit_status, signal, killed_by_host) = match status {
        Some(status) => (status.code(), status.signal(), false),
        None => (None, Some(nix::libc::SIGKILL), true),
    };
    let signal_name = signal.map(|number| {
        nix::sys::signal::Signal::try_from(number)
            .map_or_else(|_| format!("signal {number}"), |s| s.as_str().to_owned())
    });
    serde_json::json!({
        "exit_status": exit_status,
        "killed": signal.is_some(),
        "signal": signal_name,
        "killed_by_host": killed_by_host,
        "summary": summary,
    })
}

/// What an emulator serves, as its ready line states it: the control period and the
/// sensor's measuring rate (`None`: no sensor).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmulatedDevices {
    /// The mirror node's control period, s.
    pub period_s: f64,
    /// The emulated sensor's measuring rate, Hz, if it serves one.
    pub sensor_measuring_rate_hz: Option<f64>,
    /// Whether the emulated mirror has dynamics (part `axes`): without them it never moves.
    pub dynamics: bool,
}

impl EmulatedDevices {
    /// The devices an emulator's ready line declares.
    #[must_use]
    pub fn from_ready_line(ready: &serde_json::Value) -> EmulatedDevices {
        EmulatedDevices {
            period_s: ready["period_s"].as_f64().unwrap_or(f64::NAN),
            sensor_measuring_rate_hz: ready["sensor_measuring_rate_hz"].as_f64(),
            dynamics: ready["active_parts"]
                .as_array()
                .is_some_and(|parts| parts.iter().any(|part| part == "axes")),
        }
    }

    /// Checks them against what the host expects (the rig's control period and sensor rate),
    /// as a real sensor's configuration is read back and checked.
    ///
    /// # Errors
    /// A mismatch, naming both values and `scene`.
    pub fn check(
        &self,
        scene: &Path,
        period_s: f64,
        sensor_rate_hz: Option<f64>,
    ) -> anyhow::Result<()> {
        let scene = scene.display();
        let same_period = (self.period_s - period_s).abs() <= 1e-12 * period_s;
        if !same_period {
            bail!(
                "the emulated mirror node of scene {scene} runs at {:.1} Hz, the rig expects \
                 {:.1} Hz",
                1.0 / self.period_s,
                1.0 / period_s
            );
        }
        match (sensor_rate_hz, self.sensor_measuring_rate_hz) {
            (Some(expected), Some(served)) if (expected - served).abs() > 1e-9 * expected => {
                bail!(
                    "the emulated sensor of scene {scene} measures at {served} Hz, the rig \
                     expects {expected} Hz"
                )
            }
            (Some(expected), None) => bail!(
                "the rig has a sensor at {expected} Hz but scene {scene} has no `sensor` part"
            ),
            _ => Ok(()),
        }
    }
}

/// The sensor's clock as the emulator declared it in its summary, when it served the sensor:
/// the loop time of its counter 0, and, when the cycles carry no counter, the counter of the
/// first cycle it sent (the host counts its cycles from 0 there, so each is placed as its own
/// counter would place it). A real sensor declares nothing: its clock is then estimated from
/// arrival times.
fn declared_sensor_clock(
    measuring_rate_hz: f64,
    sends_counter: bool,
    emulator: Option<&serde_json::Value>,
) -> Option<SensorClock> {
    let sensor = &emulator?["summary"]["sensor"];
    let counter_offset = if sends_counter {
        0
    } else {
        sensor["first_sent_counter"].as_u64()?
    };
    Some(SensorClock {
        counter_offset,
        ..SensorClock::new(measuring_rate_hz, sensor["counter_zero_s"].as_f64()?)
    })
}

/// Reads a child's stdout lines on a thread.
pub(crate) fn spawn_line_reader(
    pipe: impl std::io::Read + Send + 'static,
) -> mpsc::Receiver<String> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(pipe).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

/// The output folder a scenario writes to by default: `scan-out/<scenario name>`.
#[must_use]
pub fn default_out_dir(scenario: &Scenario) -> PathBuf {
    Path::new("scan-out").join(&scenario.name)
}
