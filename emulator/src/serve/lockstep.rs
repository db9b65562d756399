//! Lockstep: the controller's Step(k) frame advances the plant exactly one period, so time is
//! virtual and a seed gives the same frames on every transport.
//!
//! Per period the controller sends CoilCommand(seq = k) then Step(k); the node answers as
//! [`super::lockstep_node`] says (AngleReading(k), the sensor's samples of that period, fault
//! frames for faults that started, and a Status frame on heartbeat periods). The watchdog is
//! armed by the first frame from the controller: when no frame arrives for `watchdog_periods`
//! wall-clock allowances, the node drops its coil currents to zero, sends a LinkTimeout
//! fault and a Status(fault), and the run ends. The run also ends when the controller hangs
//! up, or when it sends its own Status frame in a state other than running (the end of the
//! run on a bus): the node answers Status(ready) as its last frame.
//!
//! No write blocks the safety logic: a period's answers must be written within the
//! watchdog's whole allowance (`watchdog_periods` x the answer allowance). A host that stops
//! reading (its line full) ends the run as the watchdog does (coils zeroed, LinkTimeout fault
//! queued, `ended_by: host_stopped_reading`, exit 3), instead of leaving the node blocked in a
//! write with current on the coils. The node's last frames never wait either
//! ([`super::wind_down::send_last_frames`]).
//!
//! A link error ends this loop and comes back to `serve`, which ends the run on it
//! ([`super::wind_down`]): the host's hang-up finishes it; a failure (SocketCAN bus-off, an
//! OS error on a line, the sensor's line failing) zeroes the coils as the watchdog does,
//! attempts the node's fault frame and exits 3 with the reason in the summary.

use std::time::Duration;

use anyhow::bail;

use scanhil_protocol::can::CanFrame;
use scanhil_protocol::link::Watchdog;

use scanhil_protocol::message::MessageError;

use super::lockstep_node::{LockstepNode, LockstepNodeError, NodeReply, NodeSend};
use super::mirror_node::MirrorNode;
use super::misbehaviour::{Answer, LATE_ANSWER_ALLOWANCES, Misbehaving};
use super::wind_down::{linger, wind_down, with_wind_down};
use super::{LoopReport, RunEnd, ServeConfig, ServeLinks, ServeOutcome};

/// What answers the controller's frames in lockstep, free of I/O: the emulated mirror
/// ([`LockstepNode`]) or a recorded session ([`super::replay_node::ReplayNode`]).
pub trait LockstepAnswers {
    /// Handles one frame from the controller.
    ///
    /// # Errors
    /// The node cannot answer (a plant error, a frame that cannot be encoded, a recording that
    /// ends).
    fn on_frame(&mut self, frame: &CanFrame) -> Result<NodeReply, LockstepNodeError>;

    /// The watchdog fired after `missed_periods`: the coils drop to zero; returns the
    /// LinkTimeout fault and the Status(fault) to send.
    ///
    /// # Errors
    /// A frame that cannot be encoded.
    fn on_link_timeout(&mut self, missed_periods: u32) -> Result<[CanFrame; 2], MessageError>;

    /// The loop time at the end of the period just answered, s.
    fn loop_time_s(&self) -> f64;
}

/// Runs the lockstep loop with the emulated mirror `node` ([`LockstepNode`]), as
/// [`run_answers`] says.
///
/// # Errors
/// As [`run_answers`].
pub async fn run(
    node: &mut MirrorNode,
    links: &mut ServeLinks,
    config: &ServeConfig,
) -> anyhow::Result<LoopReport> {
    let mut node = LockstepNode::new(node, config.heartbeat_hz);
    run_answers(&mut node, links, config).await
}

/// Runs the lockstep loop until the controller hangs up, closes the SLCAN channel, ends the run
/// with its Status frame, or the watchdog fires. What the node answers is `node`'s; this loop
/// only receives, sends and keeps the watchdog. While waiting for frames, the sensor answers
/// the host's ILD commands. With `config.misbehave`, the node's answers go through
/// [`Misbehaving`] (a deliberately non-conforming node).
///
/// # Errors
/// A link error, the host's hang-up included (`serve` ends the run on it as
/// [`super::wind_down::end_on_link_error`] says), a plant error (non-finite command), a frame
/// that cannot be encoded, a recording that ends, or `--misbehave dies-on-garbage` dying.
pub async fn run_answers(
    node: &mut impl LockstepAnswers,
    links: &mut ServeLinks,
    config: &ServeConfig,
) -> anyhow::Result<LoopReport> {
    let allowance = Duration::from_secs_f64(config.lockstep_answer_allowance_s);
    // How long a period's answers may take to be written: the silence the node accepts.
    let write_allowance = allowance.saturating_mul(config.watchdog_periods);
    let mut watchdog: Option<Watchdog> = None;
    let mut misbehaving = config.misbehave.map(Misbehaving::new);
    let late_pause = allowance
        .saturating_mul(config.watchdog_periods)
        .mul_f64(LATE_ANSWER_ALLOWANCES);
    loop {
        let silence = watchdog.as_ref().map(Watchdog::remaining);
        // Biased, receive first: after a host stall both the queued frame and the expired
        // watchdog are ready at once, and a frame that has arrived must win (an unbiased
        // select would make the spurious timeout a coin flip).
        let received = tokio::select! {
            biased;
            frame = links.fsm.recv() => Some(frame),
            () = sleep_or_never(silence) => None,
            error = links.sensor.answer_commands() => return Err(error),
        };
        let frame = match received {
            None => {
                let frames = node.on_link_timeout(config.watchdog_periods)?;
                let wound_down = wind_down(links, &frames, true).await;
                let reason = format!(
                    "link timeout: no frame from the controller for {} periods of {:?}",
                    config.watchdog_periods, allowance
                );
                return Ok(LoopReport {
                    outcome: ServeOutcome::LinkTimeout,
                    ended_by: RunEnd::Watchdog,
                    timing: serde_json::Value::Null,
                    error: Some(with_wind_down(reason, wound_down)),
                });
            }
            Some(received) => received?,
        };
        if let Some(misbehaving) = &misbehaving
            && misbehaving.dies(links.fsm.stats().slcan.malformed_lines)
        {
            bail!(
                "--misbehave dies-on-garbage: dying on purpose at the first frame after a garbage SLCAN line"
            );
        }
        match node.on_frame(&frame)? {
            NodeReply::Ignored => {}
            NodeReply::Send(sends) => {
                if misbehaving.as_ref().is_none_or(Misbehaving::arms_watchdog) {
                    watchdog
                        .get_or_insert_with(|| {
                            Watchdog::new("controller", allowance, config.watchdog_periods)
                        })
                        .feed();
                }
                let answer = match &mut misbehaving {
                    Some(misbehaving) => misbehaving.answer(sends)?,
                    None => Answer { sends, late: false },
                };
                if answer.late {
                    tokio::time::sleep(late_pause).await;
                    // The node's own stall is not the host's silence.
                    if let Some(watchdog) = &mut watchdog {
                        watchdog.feed();
                    }
                }
                // The period's frames go out together (one write per link), within the
                // silence the node accepts: a host that stops reading never blocks the node.
                // The mirror's frames go first, so the host wakes once, for the reading it
                // waits on, and finds the sensor's cycles there when it looks (written first,
                // they woke it once more a period).
                // The sensor's line is written whole (lossless), so it is bounded here too;
                // `sensor_turn` says which line a timeout found unread.
                // The sensor's cycles go with the answer of the period their last byte arrives
                // in: by the end of the period just stepped.
                let until_s = node.loop_time_s();
                let sensor_turn = std::cell::Cell::new(false);
                let send = async {
                    for send in answer.sends {
                        match send {
                            NodeSend::Frame(frame) => links.fsm.queue(&frame.frame()?).await?,
                            NodeSend::Samples(samples) => {
                                links.sensor.offer(&samples);
                                links.sensor.release(until_s, &mut links.fsm).await?;
                            }
                            NodeSend::Cycles(cycles) => links.sensor.write_cycles(&cycles)?,
                        }
                    }
                    links.fsm.flush().await?;
                    sensor_turn.set(true);
                    links.sensor.flush(&mut links.fsm).await?;
                    anyhow::Ok(())
                };
                if let Ok(sent) = tokio::time::timeout(write_allowance, send).await {
                    sent?;
                } else {
                    let frames = node.on_link_timeout(config.watchdog_periods)?;
                    let unread = if sensor_turn.get() {
                        links.sensor.name()
                    } else {
                        links.fsm.name()
                    };
                    let reason = host_stopped_reading(unread, write_allowance);
                    let wound_down = wind_down(links, &frames, true).await;
                    return Ok(LoopReport {
                        outcome: ServeOutcome::LinkTimeout,
                        ended_by: RunEnd::HostStoppedReading,
                        timing: serde_json::Value::Null,
                        error: Some(with_wind_down(reason, wound_down)),
                    });
                }
            }
            NodeReply::EndOfRun(ready) => {
                // What the sensor's line still carries arrives after the last period: it goes
                // out before the end.
                links.sensor.release_all(&mut links.fsm).await?;
                if let Ok(flushed) =
                    tokio::time::timeout(write_allowance, links.sensor.flush(&mut links.fsm)).await
                {
                    flushed?;
                }
                return end_of_run(&ready.frame()?, links).await;
            }
        }
    }
}

/// The controller ended the run (its Status frame, in any state but running): the node answers
/// with its own Status(ready) as its last frame, so the controller knows it has every frame of
/// the last period, and finishes. This is how the run ends on a bus, where no hang-up comes;
/// on a serial line the node then waits for the hang-up, as closing the line first would drop
/// what the controller has not read yet.
pub(super) async fn end_of_run(
    ready: &CanFrame,
    links: &mut ServeLinks,
) -> anyhow::Result<LoopReport> {
    links.fsm.send(ready).await?;
    if links.fsm.is_slcan() {
        linger(links).await?;
    }
    Ok(LoopReport {
        outcome: ServeOutcome::Finished,
        ended_by: RunEnd::ControllerStatus,
        timing: serde_json::Value::Null,
        error: None,
    })
}

/// Sleeps for `duration`, or for ever when there is none (the watchdog is not armed yet).
async fn sleep_or_never(duration: Option<Duration>) {
    match duration {
        Some(duration) => tokio::time::sleep(duration).await,
        None => std::future::pending().await,
    }
}

/// The reason given when the host left the node's frames unread for `waited`.
#[must_use]
pub fn host_stopped_reading(line: &str, waited: Duration) -> String {
    format!(
        "the host stopped reading {line}: the node's frames could not be written for {waited:?}"
    )
}
