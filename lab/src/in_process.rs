//! A lockstep scenario run in one process. The host's [`HostLoop`] sends its messages; the
//! in-memory transport records each in the candump capture and hands it to the mirror node's
//! [`LockstepNode`] at once, which queues its answers for the host in the order the serve loop
//! would write them to the pty. The sensor's cycles go to the host's decoder
//! ([`IldSampleDecoder::push_cycle`]), their bytes made only for `sensor.ild`.
//!
//! Messages go across as they are ([`Carried::Message`]): a frame is encoded only for the
//! capture (or for injected frame faults, which act on bytes), and never decoded again. A
//! message is checked as encoding would check it; property tests hold that a message and a
//! cycle handed over read as their bytes decode, and `tests/bit_for_bit.rs` compares the run
//! with the pty run (which encodes and decodes everything) byte for byte.
//!
//! The recording matches a pty run frame for frame: the host records a received frame when it
//! takes it from the queue, stamped with the loop time it was waiting at, so the frames that
//! follow a period's angle reading (faults, status) are recorded after the next period's
//! commands, as over the pty. Where the host would wait in vain (nothing queued), the
//! transport answers with the watchdog's link timeout at once.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::time::Duration;

use anyhow::{Context, bail};
use scanhil_controller::run::chunked::Chunked;
use scanhil_controller::run::host_inbox::HostInbox;
use scanhil_controller::run::host_loop::{Heard, HostAction, HostLoop, LoopRecord};
use scanhil_controller::run::link_faults::LinkFaults;
use scanhil_controller::run::loop_error::LoopError;
use scanhil_controller::run::out_folder::OutputFolder;
use scanhil_controller::run::output::{self, RunData};
use scanhil_controller::run::output_failures::OutputFailures;
use scanhil_controller::run::pairing::SensorClock;
use scanhil_controller::run::plan::{PlanSummary, ScanPlan};
use scanhil_controller::run::scenario::{DEFAULT_RECORDING_IFACE, NodeLink, Scenario, TimingMode};
use scanhil_controller::run::sensor_link::{IldSampleDecoder, SampleLayout};
use scanhil_controller::run::sensor_setup::SensorSetupReport;
use scanhil_controller::run::verdict::{PlantDeclares, Verdict};
use scanhil_controller::run::{EmulatedDevices, ScanEnd};
use scanhil_emulator::part_cost::{self, CostTiming};
use scanhil_emulator::scene::Part;
use scanhil_emulator::sensor::IldSample;
use scanhil_emulator::sensor_faults::SensorFaultModel;
use scanhil_emulator::serve::lockstep_node::{LockstepNode, NodeReply, NodeSend};
use scanhil_emulator::serve::mirror_node::MirrorNode;
use scanhil_emulator::serve::sensor_commands::IldSettings;
use scanhil_emulator::serve::sensor_port::SensorClockTrack;
use scanhil_emulator::serve::{DEFAULT_HEARTBEAT_HZ, load_plant};
use scanhil_protocol::can::CanFrame;
use scanhil_protocol::ild::MeasuringRate;
use scanhil_protocol::ild::stream::encode_cycle_into;
use scanhil_protocol::link::{CanCapture, CaptureClock, VirtualClock};
use scanhil_protocol::message::Carried;
use scanhil_protocol::plant_units::SensingPair;

/// The in-memory link's name (in the host's errors).
pub const LINK_NAME: &str = "in-process:fsm";

/// What an in-process run produced: what the output writer needs, and how it ended.
#[derive(Debug)]
pub struct InProcessOutcome {
    /// The loop's record, the mirror link's counters and events, the sensor's samples, and
    /// the node's summary in place of the emulator's.
    pub run: RunData,
    /// The sensor's clock as the emulated sensor declared it (`None`: no sample was sent).
    pub sensor_clock: Option<SensorClock>,
    /// What ran: the scenario with the trajectory after the power check.
    pub scenario: Scenario,
    /// The plan's figures (lead-in, power check, predicted tracking error).
    pub plan: PlanSummary,
    /// How the run ended (as the output writer says, when it ran).
    pub end: ScanEnd,
    /// The run's verdict, once its output folder is written ([`Self::write`]).
    pub verdict: Option<Verdict>,
    /// The frames each side sent and received, counted by the transport (apart from the
    /// fault injector's own ledger).
    pub wire: WireCounts,
}

/// Frames counted where they leave and reach each side.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WireCounts {
    /// Frames the host sent through the injected faults.
    pub host_sent: u64,
    /// Frames of the run's stop (the zero command, the end of the run) the host sent past the
    /// injected faults, straight to the node.
    pub stop_frames: u64,
    /// Frames handed to the node through the injected faults (the stop's frames not counted).
    pub node_received: u64,
    /// Frames the node sent.
    pub node_sent: u64,
    /// Frames handed to the host.
    pub host_received: u64,
}

impl InProcessOutcome {
    /// Writes the output folder of `scanhil scan` (report, point cloud, height map, plots)
    /// into `out_dir`; returns how the run ended and keeps its verdict. The sensor samples
    /// and the angle record are consumed (as `scanhil scan` does: the frame is never held as
    /// samples and points at once); what else the run produced stays.
    ///
    /// # Errors
    /// A file that cannot be written (all of them named, after the others were written).
    pub fn write(&mut self, out_dir: &Path) -> anyhow::Result<ScanEnd> {
        let result = output::write(
            &self.scenario,
            &self.plan,
            &mut self.run,
            self.sensor_clock,
            out_dir,
        )?;
        anyhow::ensure!(
            result.failed_outputs.is_empty(),
            "{}: outputs not written: {}",
            out_dir.display(),
            result.failed_outputs
        );
        self.verdict = Some(result.verdict);
        Ok(result.end)
    }
}

/// Runs `scenario` (lockstep) in this process. With `out_dir`, records `fsm.log` and
/// `sensor.ild` there (unless the scenario's `outputs.recordings` leaves them out) and writes
/// the output folder as `scanhil scan --out` does.
///
/// # Errors
/// A scenario this loop cannot run (real time, a sensor on the mirror's CAN link, no scene),
/// files that do not load or cannot be written, a controller or scene that disagrees with the
/// rig (as `scanhil scan` refuses them), a plant error.
pub fn run(scenario: &Scenario, out_dir: Option<&Path>) -> anyhow::Result<InProcessOutcome> {
    run_plan(scenario, ScanPlan::new(scenario)?, out_dir)
}

/// [`run`] with a plan made beforehand: a test can swap the controller that runs for one the
/// plan (and so the predicted tracking) does not describe, as a controller implementation
/// that departs from its own model would.
///
/// # Errors
/// As [`run`].
pub fn run_plan(
    scenario: &Scenario,
    plan: ScanPlan,
    out_dir: Option<&Path>,
) -> anyhow::Result<InProcessOutcome> {
    run_probed(scenario, plan, out_dir, &mut |_, _| {})
}

/// [`run_plan`], calling `probe` with each reading as the loop takes it (period k, the
/// angles): a soak samples its memory there, a study or test reads the angles as they come.
/// The record keeps no angle history of its own unless sensor samples are paired with it, so
/// a run without a sensor takes the same memory however long it runs.
///
/// # Errors
/// As [`run`].
pub fn run_probed(
    scenario: &Scenario,
    plan: ScanPlan,
    out_dir: Option<&Path>,
    probe: &mut dyn FnMut(u64, SensingPair),
) -> anyhow::Result<InProcessOutcome> {
    if scenario.timing.mode != TimingMode::Lockstep {
        bail!(
            "{}: the in-process loop runs in lockstep only",
            scenario.path.display()
        );
    }
    let Some(scene_path) = &scenario.scene else {
        bail!(
            "{}: the in-process loop emulates the devices: the scenario needs a `scene`",
            scenario.path.display()
        );
    };
    let started = std::time::Instant::now();
    let periods = plan.periods();
    let ScanPlan {
        mut controller,
        trajectory,
        backoff,
        summary: plan_summary,
        ..
    } = plan;
    // What runs (and is reported) is the trajectory after the power check.
    let planned_scenario = Scenario {
        trajectory,
        ..scenario.clone()
    };
    let scenario = &planned_scenario;
    let (scene, plant) = load_plant(scene_path, Some(scenario.seed))?;
    let part_costs = part_cost::measure(&scene, CostTiming::default())?;
    let period_s = controller.period_s();
    let rig_sensor_hz = scenario.rig.sensor.map(|sensor| sensor.measuring_rate_hz);
    // A rig without a sensor runs the plant's sensor unread, as `scanhil scan` asks the
    // emulator for no sensor link.
    let serves_sensor = scene.has(Part::Sensor) && rig_sensor_hz.is_some();
    EmulatedDevices {
        period_s: plant.period_s(),
        sensor_measuring_rate_hz: scene
            .has(Part::Sensor)
            .then(|| scene.sensor.unwrap_or_default().measuring_rate_hz),
        dynamics: scene.has(Part::Axes),
    }
    .check(scene_path, period_s, rig_sensor_hz)?;
    let measuring_rate_hz = rig_sensor_hz.unwrap_or_default();
    if serves_sensor && scenario.links.sensor == NodeLink::Uri("fsm".into()) {
        bail!(
            "{}: the in-process loop carries the sensor on the ILD stream only, not as \
             Distance frames on the mirror's link",
            scenario.path.display()
        );
    }
    // Held to the end of the run, as `scanhil scan` holds its folder.
    let _folder = out_dir.map(OutputFolder::claim).transpose()?;
    let sensor_settings = match (serves_sensor, scenario.rig.sensor) {
        (true, Some(sensor)) => Some(
            IldSettings::new(
                MeasuringRate::from_hz(sensor.measuring_rate_hz)
                    .context("the rig's sensor rate (checked when it loaded)")?,
                sensor.range_span_mm,
                sensor.baud,
            )
            .with_extras(sensor.extra_values),
        ),
        _ => None,
    };
    let record_dir = out_dir.filter(|_| scenario.outputs.recordings);
    let mut transport = Transport::new(record_dir, sensor_settings, measuring_rate_hz)?;
    transport.faults = LinkFaults::new(&scenario.faults, scenario.seed, period_s);
    // Injected frame faults are survived as over a link: a reading that does not come gets
    // its Step sent again, up to the watchdog's periods.
    let tries = if transport.faults.is_some() {
        scenario.timing.watchdog_periods
    } else {
        1
    };
    let mut node = MirrorNode::new(plant);
    if scenario.faults.sensor.is_active() {
        node = node.with_sensor_faults(SensorFaultModel::new(
            scenario.faults.sensor.clone(),
            scene.seed,
            scene.sensor.unwrap_or_default().measuring_rate_hz,
        ));
    }
    let mut lockstep_node = LockstepNode::new(&mut node, DEFAULT_HEARTBEAT_HZ);
    let record = LoopRecord::new(period_s, periods)
        .with_lead_in(plan_summary.lead_in.periods)
        .keeping_angles(serves_sensor);
    let mut host = HostLoop::new(
        &mut controller,
        &scenario.trajectory,
        record,
        HostInbox::new(LINK_NAME),
    )
    .with_backoff(backoff)
    .with_tries_per_reading(tries);
    loop {
        match host.next_action() {
            HostAction::Done => break,
            HostAction::Send(frames) => {
                for sent in &frames {
                    transport.host_sends(sent.carried, sent.t_s, &mut lockstep_node)?;
                }
            }
            HostAction::SendStop(frames) => {
                for sent in &frames {
                    transport.host_sends_stop(sent.carried, sent.t_s, &mut lockstep_node)?;
                }
            }
            HostAction::AwaitReading { period, t_s } => match transport.host_receives(t_s)? {
                Some(frame) => {
                    if let Heard::Reading(k) = host.on_frame(frame, transport.arrival) {
                        probe(k, host.latest_reading());
                    }
                }
                None => match host.on_silence() {
                    Some(step) => {
                        transport.host_sends(step.carried, step.t_s, &mut lockstep_node)?
                    }
                    None => host.on_error(LoopError::LinkTimeout {
                        link: LINK_NAME.to_owned(),
                        period,
                        periods: scenario.timing.watchdog_periods,
                        waited: Duration::ZERO,
                    }),
                },
            },
            HostAction::AwaitNodeReady { t_s } => match transport.host_receives(t_s)? {
                Some(frame) => {
                    host.on_frame(frame, transport.arrival);
                }
                None => host.on_error(LoopError::LinkTimeout {
                    link: LINK_NAME.to_owned(),
                    period: host.record().periods_done,
                    periods: scenario.timing.watchdog_periods,
                    waited: Duration::ZERO,
                }),
            },
        }
    }
    let (record, mut inbox) = host.finish();
    let node_summary = serde_json::json!({
        "in_process": true,
        "summary": {
            "event": "summary",
            "outcome": "finished",
            "node": node.counters(),
            "final_state": node.state(),
            "held_coil_currents_a": node.held_command_a(),
            "sensor": transport.sensor.as_ref().map(|sensor| sensor.track),
            "sensor_faults": node.sensor_fault_counts(),
            "parts": part_costs,
            "timing": serde_json::Value::Null,
        },
    });
    // The declared clock: counter 0's instant, offset by the first cycle's counter when the
    // cycles carry no counter (the host counts them from there), as `scanhil scan` reads the
    // emulator's.
    let sends_counter = scenario
        .rig
        .sensor
        .is_some_and(|sensor| sensor.sends_counter());
    let sensor_clock = transport.sensor.as_ref().and_then(|sensor| {
        let counter_offset = if sends_counter {
            0
        } else {
            u64::from(sensor.track.first_sent_counter?)
        };
        Some(SensorClock {
            counter_offset,
            ..SensorClock::new(measuring_rate_hz, sensor.track.counter_zero_s?)
        })
    });
    let frame_faults = transport.faults.as_ref().map(LinkFaults::report);
    let wire = transport.wire;
    let sensor = transport.finish()?;
    let end = ScanEnd::of(&record);
    let mut outcome = InProcessOutcome {
        run: RunData {
            record,
            can_distances: inbox.distances_mut().take_samples(),
            can_arrivals: None,
            mirror_counters: inbox.counters(),
            mirror_link: None,
            node_events: inbox.events().to_vec(),
            sensor,
            sensor_arrivals: None,
            emulator_summary: Some(node_summary),
            frame_faults,
            run_time_s: started.elapsed().as_secs_f64(),
            failed_recordings: OutputFailures::default(),
            replay: None,
            plant: PlantDeclares {
                dynamics: Some(scene.has(Part::Axes)),
            },
            sensor_setup: serves_sensor.then(|| SensorSetupReport::Skipped {
                reason: "in process: the emulated sensor starts as the loop needs it; there is \
                         no ASCII line to configure it over"
                    .into(),
            }),
        },
        sensor_clock,
        scenario: scenario.clone(),
        plan: plan_summary,
        end,
        verdict: None,
        wire,
    };
    if let Some(dir) = out_dir {
        outcome.end = outcome.write(dir)?;
    }
    Ok(outcome)
}

/// The in-memory links between the host and the node, with their recordings.
struct Transport {
    /// The node's frames, in the order it sent them, until the host takes them.
    to_host: std::collections::VecDeque<Carried>,
    /// The node answered the end of the run: it takes no more frames.
    node_finished: bool,
    clock: VirtualClock,
    /// What frames and cycles are stamped as arriving at: in process there is no wall-clock
    /// arrival (loop time is virtual and the sensor declares its clock), so the run's start.
    arrival: tokio::time::Instant,
    capture: Option<CanCapture>,
    sensor: Option<MemorySensor>,
    /// Injected frame faults between the host and the node.
    faults: Option<LinkFaults>,
    wire: WireCounts,
}

/// The ILD stream in memory: the emulated sensor's side (its settings and clock) and the
/// host's decoding. No line paces it: in process the cycles go to the host's decoder at once
/// (arrivals play no part, the sensor declares its clock).
struct MemorySensor {
    settings: IldSettings,
    track: SensorClockTrack,
    capture: Option<BufWriter<File>>,
    /// A cycle's values (used again for every sample).
    values: Vec<u32>,
    /// A cycle's bytes for the capture (used again for every cycle).
    bytes: Vec<u8>,
    decoder: IldSampleDecoder,
}

impl MemorySensor {
    /// One output cycle of `values` goes to the host's decoder at `arrival`, handed over as
    /// values ([`IldSampleDecoder::push_cycle`]); its bytes are made only for the capture.
    fn emit(&mut self, values: &[u32], arrival: tokio::time::Instant) -> anyhow::Result<()> {
        if let Some(capture) = &mut self.capture {
            self.bytes.clear();
            encode_cycle_into(values, &mut self.bytes);
            capture
                .write_all(&self.bytes)
                .context("recording the ILD stream")?;
        }
        self.decoder.push_cycle(values, arrival);
        Ok(())
    }
}

impl Transport {
    /// The links, recorded into `record_dir` when given.
    fn new(
        record_dir: Option<&Path>,
        sensor_settings: Option<IldSettings>,
        measuring_rate_hz: f64,
    ) -> anyhow::Result<Transport> {
        let clock = VirtualClock::default();
        let capture = record_dir
            .map(|dir| {
                let path = dir.join(output::FSM_LOG);
                let file =
                    File::create(&path).with_context(|| format!("creating {}", path.display()))?;
                anyhow::Ok(CanCapture::new(
                    file,
                    DEFAULT_RECORDING_IFACE,
                    CaptureClock::Virtual(clock.clone()),
                ))
            })
            .transpose()?;
        let sensor = if let Some(settings) = sensor_settings {
            let capture = record_dir
                .map(|dir| {
                    let path = dir.join(output::SENSOR_CAPTURE);
                    File::create(&path)
                        .map(BufWriter::new)
                        .with_context(|| format!("creating {}", path.display()))
                })
                .transpose()?;
            let layout = SampleLayout::of(&settings.output_info())
                .context("the emulated sensor sends the distance")?;
            Some(MemorySensor {
                settings,
                track: SensorClockTrack::new(measuring_rate_hz),
                capture,
                values: Vec::new(),
                bytes: Vec::new(),
                decoder: IldSampleDecoder::new(layout),
            })
        } else {
            None
        };
        Ok(Transport {
            arrival: tokio::time::Instant::now(),
            to_host: std::collections::VecDeque::new(),
            node_finished: false,
            clock,
            capture,
            sensor,
            faults: None,
            wire: WireCounts::default(),
        })
    }

    /// The host sends `frame` at loop time `t_s`: past the injected faults, if any, each
    /// frame that reaches the node is recorded and handled by it.
    fn host_sends(
        &mut self,
        sent: Carried,
        t_s: f64,
        node: &mut LockstepNode<'_>,
    ) -> anyhow::Result<()> {
        self.wire.host_sent += 1;
        match &mut self.faults {
            None => self.node_receives(sent, t_s, node, true),
            Some(faults) => {
                let passed: Vec<CanFrame> = faults.outgoing(&sent.frame()?, t_s).collect();
                passed
                    .into_iter()
                    .try_for_each(|frame| self.node_receives(frame.into(), t_s, node, true))
            }
        }
    }

    /// The host sends a frame of the run's stop at loop time `t_s`: past the injected faults,
    /// straight to the node (counted apart, in [`WireCounts::stop_frames`]).
    fn host_sends_stop(
        &mut self,
        frame: Carried,
        t_s: f64,
        node: &mut LockstepNode<'_>,
    ) -> anyhow::Result<()> {
        self.wire.stop_frames += 1;
        self.node_receives(frame, t_s, node, false)
    }

    /// A frame reaches the node at loop time `t_s`: recorded, then handled by the node, whose
    /// answers are queued for the host (frames) or go out on the ILD stream (samples). A
    /// frame that came `through_faults` is counted in [`WireCounts::node_received`].
    fn node_receives(
        &mut self,
        frame: Carried,
        t_s: f64,
        node: &mut LockstepNode<'_>,
        through_faults: bool,
    ) -> anyhow::Result<()> {
        self.record(&frame, t_s)?;
        if self.node_finished {
            return Ok(());
        }
        self.wire.node_received += u64::from(through_faults);
        match node.on_frame(frame)? {
            NodeReply::Ignored => {}
            NodeReply::Send(sends) => {
                for send in sends {
                    match send {
                        NodeSend::Frame(frame) => {
                            self.wire.node_sent += 1;
                            self.to_host.push_back(frame);
                        }
                        NodeSend::Samples(samples) => self.emit_samples(&samples)?,
                        NodeSend::Cycles(cycles) => self.emit_cycles(&cycles)?,
                    }
                }
            }
            NodeReply::EndOfRun(ready) => {
                self.wire.node_sent += 1;
                self.to_host.push_back(ready);
                self.node_finished = true;
            }
        }
        Ok(())
    }

    /// The host takes the node's next frame at loop time `t_s` (recorded as the node sent
    /// it, before any injected fault); `None` when nothing more has reached the host.
    fn host_receives(&mut self, t_s: f64) -> anyhow::Result<Option<Carried>> {
        loop {
            if let Some(frame) = self.faults.as_mut().and_then(|f| f.next_incoming(t_s)) {
                self.wire.host_received += 1;
                return Ok(Some(frame.into()));
            }
            let Some(frame) = self.to_host.pop_front() else {
                return Ok(None);
            };
            self.record(&frame, t_s)?;
            match &mut self.faults {
                None => {
                    self.wire.host_received += 1;
                    return Ok(Some(frame));
                }
                Some(faults) => faults.incoming(&frame.frame()?, t_s),
            }
        }
    }

    /// The sensor's samples as the ILD stream sends them (a cycle of the values the settings
    /// select per sample), recorded and decoded on the host's side.
    fn emit_samples(&mut self, samples: &[IldSample]) -> anyhow::Result<()> {
        let Some(sensor) = &mut self.sensor else {
            return Ok(());
        };
        let mut values = std::mem::take(&mut sensor.values);
        for sample in samples {
            if !sensor.settings.cycle_into(sample, &mut values) {
                continue;
            }
            sensor.track.measured(sample);
            sensor.track.sent(sample.counter);
            sensor.emit(&values, self.arrival)?;
        }
        sensor.values = values;
        Ok(())
    }

    /// A recorded session's output cycles go out on the ILD stream as they are.
    fn emit_cycles(&mut self, cycles: &[Vec<u32>]) -> anyhow::Result<()> {
        if let Some(sensor) = &mut self.sensor {
            for values in cycles {
                sensor.emit(values, self.arrival)?;
            }
        }
        Ok(())
    }

    /// Records `frame` in the capture, if any, stamped with loop time `t_s`: the only place
    /// a message is encoded when no fault is injected.
    fn record(&mut self, frame: &Carried, t_s: f64) -> anyhow::Result<()> {
        if let Some(capture) = &mut self.capture {
            self.clock.set(Duration::from_secs_f64(t_s));
            capture
                .record(&frame.frame()?)
                .context("recording the mirror's link")?;
        }
        Ok(())
    }

    /// Flushes the recordings; returns the host's decoded sensor samples and counters.
    fn finish(
        mut self,
    ) -> anyhow::Result<(
        Chunked<scanhil_controller::run::sample_log::CountedSample>,
        scanhil_controller::run::sensor_link::SensorCounters,
    )> {
        if let Some(capture) = &mut self.capture {
            capture.flush().context("recording the mirror's link")?;
        }
        match self.sensor {
            None => Ok(Default::default()),
            Some(mut sensor) => {
                if let Some(capture) = &mut sensor.capture {
                    capture.flush().context("recording the ILD stream")?;
                }
                Ok(sensor.decoder.finish())
            }
        }
    }
}
