//! Lockstep: the controller's Step(k) frame advances the plant exactly one period, so time is
//! virtual and a seed gives the same frames on every transport.
//!
//! Per period the controller sends CoilCommand(seq = k) then Step(k); the node answers
//! AngleReading(k), then fault frames for faults that started, the sensor's samples of that
//! period, and a Status frame every `1 / heartbeat_hz` seconds of loop time. The watchdog is
//! armed by the first frame from the controller: when no frame arrives for `watchdog_periods`
//! wall-clock allowances, the node drops its coil currents to zero, sends a LinkTimeout
//! fault and a Status(fault), and the run ends. The run also ends when the controller hangs
//! up, or when it sends its own Status frame in a state other than running (the end of the
//! run on a bus): the node answers Status(ready) as its last frame.

use std::time::Duration;

use scanhil_protocol::can::CanFrame;
use scanhil_protocol::link::Watchdog;
use scanhil_protocol::message::{
    AngleReading, Fault, FaultKind, Message, MessageError, NodeId, NodeState, Status, U24_MAX,
};

use super::mirror_node::{MirrorNode, NodeOutput};
use super::{LoopReport, RunEnd, ServeConfig, ServeLinks, ServeOutcome};

/// Runs the lockstep loop until the controller hangs up, closes the SLCAN channel, ends the run
/// with its Status frame, or the watchdog fires. While waiting for frames, the sensor answers
/// the host's ILD commands.
///
/// # Errors
/// A link error other than a hang-up, or a plant error (non-finite command).
pub async fn run(
    node: &mut MirrorNode,
    links: &mut ServeLinks,
    config: &ServeConfig,
) -> anyhow::Result<LoopReport> {
    let allowance = Duration::from_secs_f64(config.lockstep_answer_allowance_s);
    let mut watchdog: Option<Watchdog> = None;
    let heartbeat_every = periods_per_heartbeat(node.plant().period_s(), config.heartbeat_hz);
    loop {
        let silence = watchdog.as_ref().map(Watchdog::remaining);
        let received = tokio::select! {
            frame = links.fsm.recv() => Some(frame),
            () = sleep_or_never(silence) => None,
            error = links.sensor.answer_commands() => return Err(error),
        };
        let frame = match received {
            None => {
                let (fault, detail) = node.on_link_timeout(config.watchdog_periods);
                let k = node.next_period();
                links.fsm.send(&fault_frame(fault, detail, k)?).await?;
                links
                    .fsm
                    .send(&status_frame(NodeState::Fault, k, node.plant().period_s())?)
                    .await?;
                linger(links).await?;
                return Ok(LoopReport {
                    outcome: ServeOutcome::LinkTimeout,
                    ended_by: RunEnd::Watchdog,
                    timing: serde_json::Value::Null,
                    error: Some(format!(
                        "link timeout: no frame from the controller for {} periods of {:?}",
                        config.watchdog_periods, allowance
                    )),
                });
            }
            Some(Err(err)) => {
                return match RunEnd::from_link_error(&err) {
                    Some(ended_by) => Ok(LoopReport {
                        outcome: ServeOutcome::Finished,
                        ended_by,
                        timing: serde_json::Value::Null,
                        error: None,
                    }),
                    None => Err(err.into()),
                };
            }
            Some(Ok(frame)) => frame,
        };
        let message = match Message::decode(&frame) {
            Ok(message) => message,
            Err(MessageError::UnknownId(_)) => continue,
            Err(_) => {
                node.on_malformed_frame();
                continue;
            }
        };
        match message {
            Message::CoilCommand(command) => {
                watchdog
                    .get_or_insert_with(|| {
                        Watchdog::new("controller", allowance, config.watchdog_periods)
                    })
                    .feed();
                node.on_command(command.seq, command.amps());
            }
            Message::Step { step } => {
                watchdog
                    .get_or_insert_with(|| {
                        Watchdog::new("controller", allowance, config.watchdog_periods)
                    })
                    .feed();
                let k = node.next_period();
                node.check_step_counter(step);
                for output in node.step()? {
                    match output {
                        NodeOutput::Angles(step) => {
                            links.fsm.send(&angle_frame(&step)?).await?;
                            links
                                .sensor
                                .emit(&step.sensor_samples, &mut links.fsm)
                                .await?;
                        }
                        NodeOutput::Fault(kind, detail) => {
                            links.fsm.send(&fault_frame(kind, detail, k)?).await?;
                        }
                    }
                }
                if k.is_multiple_of(heartbeat_every) {
                    let status = status_frame(node.state(), k, node.plant().period_s())?;
                    links.fsm.send(&status).await?;
                }
            }
            Message::Status(status)
                if status.node == NodeId::Controller && status.state != NodeState::Running =>
            {
                return end_of_run(node, links).await;
            }
            _ => {}
        }
    }
}

/// The controller ended the run (its Status frame, in any state but running): the node answers
/// with its own Status(ready) as its last frame, so the controller knows it has every frame of
/// the last period, and finishes. This is how the run ends on a bus, where no hang-up comes;
/// on a serial line the node then waits for the hang-up, as closing the line first would drop
/// what the controller has not read yet.
async fn end_of_run(node: &MirrorNode, links: &mut ServeLinks) -> anyhow::Result<LoopReport> {
    let k = node.next_period();
    let ready = status_frame(NodeState::Ready, k, node.plant().period_s())?;
    links.fsm.send(&ready).await?;
    if links.fsm.slcan_bitrate().is_some() {
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

/// The AngleReading frame of a stepped period (sequence counter = period mod 2^16).
///
/// # Errors
/// [`MessageError`] if the message cannot be encoded (never for the mirror's angles).
pub fn angle_frame(step: &crate::plant::PlantStep) -> Result<CanFrame, MessageError> {
    let reading = AngleReading::from_rad(step.period_index as u16, step.measured_angles_rad);
    Message::AngleReading(reading).encode()
}

/// The mirror node's fault frame for a fault that started in period `k`.
///
/// # Errors
/// [`MessageError`] if the message cannot be encoded.
pub fn fault_frame(kind: FaultKind, detail: i32, k: u64) -> Result<CanFrame, MessageError> {
    Message::Fault(Fault {
        node: NodeId::Fsm,
        kind,
        detail,
        step: k as u16,
    })
    .encode()
}

/// The mirror node's status frame in period `k` (its node time is the loop time, in us).
///
/// # Errors
/// [`MessageError`] if the message cannot be encoded.
pub fn status_frame(state: NodeState, k: u64, period_s: f64) -> Result<CanFrame, MessageError> {
    let node_time_us = (k as f64 * period_s * 1e6).round() as u64;
    Message::Status(Status {
        node: NodeId::Fsm,
        state,
        step: (k & u64::from(U24_MAX)) as u32,
        node_time_us: (node_time_us & u64::from(U24_MAX)) as u32,
    })
    .encode()
}

/// How long the node keeps the link open after its last frames, so the host can read them
/// (closing a pty drops what the other end has not read yet).
pub const LINGER: Duration = Duration::from_secs(2);

/// Keeps the link open, ignoring what arrives, until the host hangs up, closes the channel, or
/// [`LINGER`] passes.
///
/// # Errors
/// A link error other than the hang-up.
pub async fn linger(links: &mut ServeLinks) -> anyhow::Result<()> {
    let deadline = tokio::time::Instant::now() + LINGER;
    loop {
        match tokio::time::timeout_at(deadline, links.fsm.recv()).await {
            Err(_) => return Ok(()),
            Ok(Err(error)) if RunEnd::from_link_error(&error).is_some() => return Ok(()),
            Ok(Err(error)) => return Err(error.into()),
            Ok(Ok(_)) => {}
        }
    }
}

/// Periods between two status frames (at least 1).
#[must_use]
pub fn periods_per_heartbeat(period_s: f64, heartbeat_hz: f64) -> u64 {
    let periods = (1.0 / (heartbeat_hz * period_s)).round();
    if periods.is_finite() && periods >= 1.0 {
        periods as u64
    } else {
        1
    }
}
