//! Real time: the emulator is the clock master, from the moment the host opens the channel.
//! The loop keeps time for a [`ClockedNode`]: the emulated mirror ([`MirrorNode`]), or a
//! recorded session ([`super::replay_node::ReplayNode`]) whose periods go out at their recorded
//! times.
//! Every period it steps the plant with the
//! newest coil command it has (a command that arrived late still counts for the next period),
//! sends Sync(k) and AngleReading(k), then the sensor's samples and, at the heartbeat rate, a
//! Status frame. The controller answers each reading with CoilCommand(k) before the next
//! period. The controller's Status frame in a state other than running (its end of the run,
//! after the zero command that answers the last reading) ends the run: the node answers with
//! Status(ready) as its last frame, holding the zero. Timer resolution in an OS is coarse, so the loop waits for each period start by
//! yielding to the I/O driver and re-reading the clock (received frames are handled meanwhile).
//!
//! With `--misbehave` the period's frames go through [`Misbehaving`] (a deliberately
//! non-conforming node): a late answer stalls the node's clock ([`LATE_ANSWER_ALLOWANCES`] of
//! its watchdog's allowance, the periods after it keeping the delay), a slow clock stretches
//! every period, and the watchdog or the node itself may be disarmed or die.
//!
//! With busy-polling ([`ServeConfig::realtime`]) the wait spins on non-blocking reads of the
//! link instead (no readiness, no yielding), for the shortest wake-up at each period start.
//!
//! Reported: the measured period (tick to tick) and each tick's lateness after its period start
//! as min / median / p99 / max, overruns (a tick that started more than one period late, so a
//! period was skipped), and stale periods (no fresh command since the previous tick: a missed
//! deadline), each listed with how late this node sent the reading it answers, so the host
//! can tell which side missed ([`MissedDeadline`]).
//!
//! No write blocks the clock: a period whose frames the line does not take within the send
//! allowance is dropped and counted; an earlier period's bytes go out first, within the same
//! allowance, and a period whose allowance they use up is not queued at all (so what waits
//! stays one period's worth). When the line has taken no byte for the watchdog's allowance
//! of wall time, the host has stopped reading (a slow host still takes some): the run ends as
//! the watchdog ends it (`ended_by: host_stopped_reading`).

use std::time::{Duration, Instant};

use scanhil_protocol::can::CanFrame;
use scanhil_protocol::link::LinkError;
use scanhil_protocol::loop_timing::{MissedDeadline, PeriodRecorder};
use scanhil_protocol::message::{Carried, CoilCommand, Message, MessageError, NodeId, NodeState};

use super::lockstep::{end_of_run, host_stopped_reading};
use super::lockstep_node::{
    NodeSend, angle_frame, fault_frame, last_frames, periods_per_heartbeat, status_frame,
};
use super::mirror_node::{MirrorNode, NodeOutput};
use super::misbehaviour::{LATE_ANSWER_ALLOWANCES, Misbehaving};
use super::wind_down::{end_on_link_error_with, wind_down, with_wind_down};
use super::{LoopReport, RunEnd, ServeConfig, ServeLinks, ServeOutcome};

/// How long one period's frames may take to go out before they are dropped.
const SEND_ALLOWANCE: Duration = Duration::from_millis(2);

/// The most missed deadlines listed one by one in the summary (the rest are only counted).
const MAX_LISTED_MISSES: usize = 1 << 20;

/// A node the real-time loop clocks: what it sends each period and what it makes of the host's
/// frames. No I/O and no clock: the loop keeps time and does the sending.
pub trait ClockedNode {
    /// The control period, s.
    fn period_s(&self) -> f64;
    /// The period it steps next.
    fn next_period(&self) -> u64;
    /// When period `k` starts after the clock's start.
    fn period_start(&self, k: u64) -> Duration;
    /// Steps period [`Self::next_period`]: what it sends, in order (its AngleReading among the
    /// frames), a heartbeat Status frame among them when `heartbeat` asks for one.
    ///
    /// # Errors
    /// A plant error, a frame that cannot be encoded, a recording that has no such period.
    fn tick(&mut self, heartbeat: bool) -> anyhow::Result<Vec<NodeSend>>;
    /// Periods stepped so far without a fresh command since the one before.
    fn stale_periods(&self) -> u64;
    /// The host's coil command.
    fn take_command(&mut self, command: &CoilCommand);
    /// A loop frame with a malformed payload came.
    fn malformed_frame(&mut self);
    /// The watchdog fired after `missed_periods`: coils zeroed; its last frames.
    ///
    /// # Errors
    /// A frame that cannot be encoded.
    fn watchdog_fired(&mut self, missed_periods: u32) -> Result<[CanFrame; 2], MessageError>;
    /// The link failed: coils zeroed; its last frames.
    ///
    /// # Errors
    /// A frame that cannot be encoded.
    fn link_failed(&mut self) -> Result<[CanFrame; 2], MessageError>;
    /// The host ended the run (after its zero command): the node's answer, its last frame.
    ///
    /// # Errors
    /// A frame that cannot be encoded.
    fn run_ended(&mut self) -> Result<CanFrame, MessageError>;
}

impl ClockedNode for MirrorNode {
    fn period_s(&self) -> f64 {
        self.plant().period_s()
    }

    fn next_period(&self) -> u64 {
        MirrorNode::next_period(self)
    }

    fn period_start(&self, k: u64) -> Duration {
        Duration::from_secs_f64(self.plant().period_s()).saturating_mul(k as u32)
    }

    /// Sync(k), the AngleReading, fault frames, the heartbeat; the sensor's samples after them.
    fn tick(&mut self, heartbeat: bool) -> anyhow::Result<Vec<NodeSend>> {
        let k = MirrorNode::next_period(self);
        let period_s = self.plant().period_s();
        let mut sends = vec![NodeSend::Frame(Carried::checked(Message::Sync {
            step: k as u32,
        })?)];
        let NodeOutput {
            step,
            started_faults,
        } = self.step()?;
        sends.push(NodeSend::Frame(angle_frame(&step)?));
        for (kind, detail) in started_faults {
            sends.push(NodeSend::Frame(fault_frame(kind, detail, k)?));
        }
        if heartbeat {
            sends.push(NodeSend::Frame(status_frame(self.state(), k, period_s)?));
        }
        sends.push(NodeSend::Samples(step.sensor_samples));
        Ok(sends)
    }

    fn stale_periods(&self) -> u64 {
        self.counters().stale_periods
    }

    fn take_command(&mut self, command: &CoilCommand) {
        self.on_command(command.seq, command.amps());
    }

    fn malformed_frame(&mut self) {
        self.on_malformed_frame();
    }

    fn watchdog_fired(&mut self, missed_periods: u32) -> Result<[CanFrame; 2], MessageError> {
        let fault = self.on_link_timeout(missed_periods);
        last_frames(self, fault)
    }

    fn link_failed(&mut self) -> Result<[CanFrame; 2], MessageError> {
        let fault = self.on_link_failure();
        last_frames(self, fault)
    }

    fn run_ended(&mut self) -> Result<CanFrame, MessageError> {
        self.on_end_of_run();
        status_frame(
            self.state(),
            MirrorNode::next_period(self),
            self.plant().period_s(),
        )?
        .frame()
    }
}

/// Runs the real-time loop until the duration ends, the controller hangs up or closes the SLCAN
/// channel, or the watchdog fires (no command for `watchdog_periods` periods once the first one
/// arrived). Before the clock starts the sensor answers the host's ILD commands as they come;
/// during the run, at each period's samples.
///
/// A link error once the clock runs ends the ticks as [`end_on_link_error_with`] says (a
/// failure: coils zeroed, the node's fault frame attempted, the reason in the report), the
/// timing so far kept.
///
/// # Errors
/// A link error before the clock starts, the host's hang-up included (`serve` ends the run on
/// it the same way), a plant error, or a frame that cannot be encoded.
pub async fn run(
    node: &mut impl ClockedNode,
    links: &mut ServeLinks,
    config: &ServeConfig,
) -> anyhow::Result<LoopReport> {
    let period = Duration::from_secs_f64(node.period_s());
    let mut misbehaving = config.misbehave.map(Misbehaving::new);
    // The node's clock: its own, unless it is made to run slow.
    let clock_factor = misbehaving.as_ref().map_or(1.0, Misbehaving::clock_factor);
    let arms_watchdog = misbehaving.as_ref().is_none_or(Misbehaving::arms_watchdog);
    let heartbeat_every = periods_per_heartbeat(node.period_s(), config.heartbeat_hz);
    let total_periods = config
        .duration_s
        .map(|d| (d / node.period_s()).round() as u64);
    let mut recorder = PeriodRecorder::new(period.as_secs_f64());
    let mut lateness = PeriodRecorder::new(period.as_secs_f64());
    let mut misses: Vec<MissedDeadline> = Vec::new();
    let mut misses_not_listed = 0u64;
    // How late the previous tick's reading went out after its period start (`None`: dropped).
    let mut previous_reading_late_s: Option<f64> = None;
    let busy_poll = config.realtime.busy_poll;
    let mut host = HostHeard::default();
    let silence_allowance = period.saturating_mul(config.watchdog_periods);
    let late_pause = silence_allowance.mul_f64(LATE_ANSWER_ALLOWANCES);
    let mut dropped_periods = 0u64;
    // Since when the line has taken no byte while frames waited (the host is not reading).
    let mut unsent_since: Option<Instant> = None;
    // The clock starts when the host has opened the channel (SLCAN `O`; SocketCAN is open).
    while !links.fsm.channel_open() {
        tokio::select! {
            received = links.fsm.recv_timeout(Duration::from_millis(10)) => received?,
            error = links.sensor.answer_commands() => return Err(error),
        };
    }
    // Moved on by a misbehaving node's stall, so the periods after it keep the delay.
    let mut start = Instant::now();
    let mut last_tick: Option<Instant> = None;
    let mut outcome = ServeOutcome::Finished;
    let mut ended_by = RunEnd::Duration;
    let mut error = None;
    // A link error that ended the ticks (the host's hang-up included).
    let mut link_error: Option<anyhow::Error> = None;
    'ticks: loop {
        let k = node.next_period();
        if total_periods.is_some_and(|n| k >= n) && host.last_command_period.is_some() {
            // The duration ran out: no more periods. A commanding host's end of the run (its
            // zero command, then its Status) is still taken, within the watchdog's allowance.
            let waited = tokio::time::timeout(silence_allowance, async {
                while !host.ended {
                    let frame = links.fsm.recv().await?;
                    host.on_frame(node, &frame, k);
                }
                Ok::<_, LinkError>(())
            })
            .await;
            if let Ok(Err(err)) = waited {
                link_error = Some(err.into());
            }
        }
        if host.ended {
            // The controller ended the run (after its zero command, which the node took
            // first): the node answers Status(ready) as its last frame, after what the
            // sensor's line still carries.
            let ready = node.run_ended()?;
            let ended = async {
                release_the_rest(links).await?;
                end_of_run(&ready, links).await
            };
            match ended.await {
                Ok(report) => (outcome, ended_by) = (report.outcome, report.ended_by),
                Err(err) => link_error = Some(err),
            }
            break 'ticks;
        }
        if link_error.is_some() || total_periods.is_some_and(|n| k >= n) {
            break;
        }
        let deadline = start + node.period_start(k).mul_f64(clock_factor);
        let served = serve_until(links, node, k, deadline, busy_poll, &mut host).await;
        if let Err(err) = served {
            link_error = Some(err.into());
            break 'ticks;
        }
        if host.ended {
            // The end came before the duration ran out: answered at the next tick's start.
            continue;
        }
        if let Some(misbehaving) = &misbehaving
            && misbehaving.dies(links.fsm.stats().slcan.malformed_lines)
        {
            anyhow::bail!(
                "--misbehave dies-on-garbage: dying on purpose at the first period after a garbage SLCAN line"
            );
        }
        let now = Instant::now();
        if let Some(previous) = last_tick {
            recorder.record((now - previous).as_secs_f64());
        }
        lateness.record(now.duration_since(deadline).as_secs_f64());
        if now.duration_since(deadline) > period {
            recorder.overrun();
            lateness.overrun();
        }
        last_tick = Some(now);
        // The watchdog: armed by the first command; fires after `watchdog_periods` ticks
        // without one, or when a reading has waited that many periods of wall time for its
        // answer.
        let silent_ticks = arms_watchdog
            && host
                .last_command_period
                .is_some_and(|last| k - last > u64::from(config.watchdog_periods));
        let silent_wall = arms_watchdog
            && host.last_command_period.is_some()
            && host
                .unanswered_since
                .is_some_and(|since| now.duration_since(since) > silence_allowance);
        let not_reading =
            unsent_since.is_some_and(|since| now.duration_since(since) > silence_allowance);
        if silent_ticks || silent_wall || not_reading {
            // A frozen host leaves the line full: the frames are queued (a send that times out
            // keeps what it has not written) and go out while `linger` drains the host.
            let frames = node.watchdog_fired(config.watchdog_periods)?;
            let (end, reason) = if not_reading {
                (
                    RunEnd::HostStoppedReading,
                    host_stopped_reading(links.fsm.name(), silence_allowance),
                )
            } else {
                (
                    RunEnd::Watchdog,
                    format!(
                        "link timeout: no coil command for {} periods",
                        config.watchdog_periods
                    ),
                )
            };
            let wound_down = wind_down(links, &frames, true).await;
            outcome = ServeOutcome::LinkTimeout;
            ended_by = end;
            error = Some(with_wind_down(reason, wound_down));
            break;
        }
        host.unanswered_since.get_or_insert(now);
        let stale_before = node.stale_periods();
        let mut sends = node.tick(k.is_multiple_of(heartbeat_every))?;
        if node.stale_periods() > stale_before && k > 0 {
            if misses.len() < MAX_LISTED_MISSES {
                misses.push(MissedDeadline {
                    period: k,
                    reading_late_s: previous_reading_late_s,
                });
            } else {
                misses_not_listed += 1;
            }
        }
        if let Some(misbehaving) = &mut misbehaving {
            let answer = misbehaving.answer(sends)?;
            sends = answer.sends;
            if answer.late {
                // The node's clock stalls; its own stall is not the host's silence.
                tokio::time::sleep(late_pause).await;
                start += late_pause;
                if host.unanswered_since.is_some() {
                    host.unanswered_since = Some(Instant::now());
                }
            }
        }
        // The clock master never waits for a slow host: what cannot go out within the send
        // allowance is dropped (and counted), as frames on a bus nobody reads are lost; an
        // earlier period's bytes go first, and while they wait this period's are not queued.
        let written_before = links.fsm.bytes_written();
        // The period's samples go onto the sensor's line now (outside the send allowance, so
        // each is counted once, sent or dropped, even when the allowance runs out before the
        // sensor's turn: they wait for the next tick); what has arrived by this tick goes out
        // with its frames.
        let mut frames = Vec::with_capacity(sends.len());
        for send in sends {
            match send {
                NodeSend::Frame(frame) => match frame.frame() {
                    Ok(frame) => frames.push(frame),
                    Err(err) => {
                        link_error = Some(err.into());
                        break 'ticks;
                    }
                },
                NodeSend::Samples(samples) => links.sensor.offer(&samples),
                NodeSend::Cycles(cycles) => {
                    if let Err(err) = links.sensor.write_cycles(&cycles) {
                        link_error = Some(err.into());
                        break 'ticks;
                    }
                }
            }
        }
        let now_s = k as f64 * node.period_s();
        let send = async {
            links.fsm.flush().await?;
            // The period's frames go out together: one write per link.
            for frame in &frames {
                links.fsm.queue(frame).await?;
            }
            links.sensor.emit(now_s, &mut links.fsm).await?;
            links.fsm.flush().await?;
            anyhow::Ok(())
        };
        let sent = match tokio::time::timeout(SEND_ALLOWANCE, send).await {
            Ok(Ok(())) => true,
            Ok(Err(err)) => {
                link_error = Some(err);
                break 'ticks;
            }
            Err(_) => false,
        };
        if sent {
            previous_reading_late_s = Some(deadline.elapsed().as_secs_f64());
        } else {
            dropped_periods += 1;
            previous_reading_late_s = None;
        }
        // A slow host still takes bytes; one that stopped reading takes none.
        if sent || links.fsm.bytes_written() != written_before {
            unsent_since = None;
        } else {
            unsent_since.get_or_insert(now);
        }
    }
    if link_error.is_none()
        && ended_by == RunEnd::Duration
        && let Err(err) = release_the_rest(links).await
    {
        link_error = Some(err);
    }
    if let Some(link_error) = link_error {
        let report = end_on_link_error_with(links, link_error, || node.link_failed()).await?;
        (outcome, ended_by, error) = (report.outcome, report.ended_by, report.error);
    }
    let stats = recorder.stats();
    let stale = node.stale_periods();
    let deadline_held =
        stats.is_some_and(|s| s.overruns == 0) && stale <= 1 && dropped_periods == 0;
    Ok(LoopReport {
        outcome,
        ended_by,
        timing: serde_json::json!({
            "period_jitter": stats,
            "tick_lateness": lateness.stats(),
            "stale_command_periods": stale,
            "missed_deadlines": misses,
            "missed_deadlines_not_listed": misses_not_listed,
            "periods_with_dropped_frames": dropped_periods,
            "deadline_held": deadline_held,
        }),
        error,
    })
}

/// The end of the run: what the sensor's line still carries goes out as far as the line
/// takes it within the send allowance (the rest is counted dropped, as any cycle the line
/// cannot take).
async fn release_the_rest(links: &mut ServeLinks) -> anyhow::Result<()> {
    let sent = async {
        links.sensor.release_all(&mut links.fsm).await?;
        links.sensor.flush(&mut links.fsm).await
    };
    match tokio::time::timeout(SEND_ALLOWANCE, sent).await {
        Ok(sent) => sent,
        Err(_elapsed) => Ok(()),
    }
}

/// Handles the host's frames until `deadline` (busy-polling: spinning on non-blocking reads;
/// else yielding to the runtime between reads), then whatever it has queued: a tick that
/// starts late (catch-up after a stall of this process) never waits, but its host's queued
/// commands must count before the watchdog looks (else a stall of the node alone would look
/// like a silent host).
async fn serve_until(
    links: &mut ServeLinks,
    node: &mut impl ClockedNode,
    k: u64,
    deadline: Instant,
    busy_poll: bool,
    host: &mut HostHeard,
) -> Result<(), LinkError> {
    while Instant::now() < deadline && !host.ended {
        if busy_poll {
            take_queued(links, node, k, host)?;
            std::hint::spin_loop();
        } else {
            let received = tokio::select! {
                frame = links.fsm.recv() => Some(frame),
                () = tokio::task::yield_now() => None,
            };
            if let Some(frame) = received {
                host.on_frame(node, &frame?, k);
            }
        }
    }
    take_queued(links, node, k, host)
}

/// Handles every frame the host has queued, without waiting (none after the end of the run).
fn take_queued(
    links: &mut ServeLinks,
    node: &mut impl ClockedNode,
    k: u64,
    host: &mut HostHeard,
) -> Result<(), LinkError> {
    while !host.ended {
        let Some(frame) = links.fsm.try_recv()? else {
            break;
        };
        host.on_frame(node, &frame, k);
    }
    Ok(())
}

/// What the node has heard from the host so far.
#[derive(Debug, Default)]
struct HostHeard {
    /// The period of the newest coil command (`None`: none yet; the watchdog is not armed).
    last_command_period: Option<u64>,
    /// When the oldest reading the host has not answered yet went out (wall clock): the
    /// host's silence is measured from there, so a node whose sends stretch under a full line
    /// (each tick then waits out the send allowance) still notices a frozen host.
    unanswered_since: Option<Instant>,
    /// The controller's Status frame in a state other than running ended the run.
    ended: bool,
}

impl HostHeard {
    /// Handles one frame from the host during period `k`: a coil command is applied (and
    /// marks the period the host was last heard; it also answers the oldest unanswered
    /// reading), the controller's Status frame in a state other than running ends the run,
    /// a malformed loop frame is counted, others are ignored.
    fn on_frame(&mut self, node: &mut impl ClockedNode, frame: &CanFrame, k: u64) {
        match Message::decode(frame) {
            Ok(Message::CoilCommand(command)) => {
                self.last_command_period = Some(k);
                self.unanswered_since = None;
                node.take_command(&command);
            }
            Ok(Message::Status(status))
                if status.node == NodeId::Controller && status.state != NodeState::Running =>
            {
                self.ended = true;
            }
            Ok(_) | Err(MessageError::UnknownId(_)) => {}
            Err(_) => node.malformed_frame(),
        }
    }
}
