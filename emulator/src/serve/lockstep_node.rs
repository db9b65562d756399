//! The mirror node's side of the lockstep exchange, free of I/O and clocks: a frame from the
//! controller in, what to send back out, in the order it goes out. The serve loop
//! ([`super::lockstep`]) and an in-process loop (the `scanhil-lab` crate) both run it, so a
//! seed gives the same frames whichever transport carries them.
//!
//! Per Step(k) the node answers AngleReading(k), the sensor's samples of that period, a fault
//! frame for each fault that started, and a Status frame every `1 / heartbeat_hz` seconds of
//! loop time. The controller's own Status frame in a state other than running ends the run:
//! the node answers Status(ready) as its last frame.

use scanhil_protocol::can::CanFrame;
use scanhil_protocol::message::{
    AngleReading, Carried, Fault, FaultKind, Message, MessageError, NodeId, NodeState, Status,
    U24_MAX,
};

use super::lockstep::LockstepAnswers;
use super::mirror_node::{MirrorNode, NodeOutput};
use super::replay_node::ReplayError;
use crate::plant::{PlantError, PlantStep};
use crate::sensor::IldSample;

/// One thing to send, in order: a frame on the mirror's link, or the sensor's samples of the
/// period (on the sensor's own port).
#[derive(Debug, Clone, PartialEq)]
pub enum NodeSend {
    /// A frame on the mirror's CAN link (a message the node made, or a recorded frame).
    Frame(Carried),
    /// The sensor's samples of the period just stepped.
    Samples(Vec<IldSample>),
    /// The sensor's output cycles of a recorded period (raw values), sent as they are
    /// ([`super::replay_node`]).
    Cycles(Vec<Vec<u32>>),
}

/// What a frame from the controller asks of the node.
#[derive(Debug, Clone, PartialEq)]
pub enum NodeReply {
    /// Not for the node (another id, a malformed payload: counted, or a status frame that
    /// does not end the run): nothing to send, the watchdog is not fed.
    Ignored,
    /// A coil command or a Step: the watchdog is fed; send these in order (none after a
    /// command).
    Send(Vec<NodeSend>),
    /// The controller ended the run: send this frame, the node's Status(ready), last.
    EndOfRun(Carried),
}

/// Why the node cannot answer.
#[derive(Debug, thiserror::Error)]
pub enum LockstepNodeError {
    /// The plant refused the command (non-finite).
    #[error(transparent)]
    Plant(#[from] PlantError),
    /// A frame could not be encoded.
    #[error("cannot encode a frame: {0}")]
    Encode(#[from] MessageError),
    /// The recording being replayed cannot answer.
    #[error(transparent)]
    Replay(#[from] ReplayError),
}

/// The mirror node answering the controller frame by frame in lockstep.
#[derive(Debug)]
pub struct LockstepNode<'a> {
    node: &'a mut MirrorNode,
    heartbeat_every: u64,
    /// The Step counter of the period just stepped and its angle reading, answered again
    /// when that Step comes again.
    last_reading: Option<(u32, Carried)>,
}

impl<'a> LockstepNode<'a> {
    /// Runs `node` in lockstep with a Status frame `heartbeat_hz` times per second of loop
    /// time.
    pub fn new(node: &'a mut MirrorNode, heartbeat_hz: f64) -> LockstepNode<'a> {
        let heartbeat_every = periods_per_heartbeat(node.plant().period_s(), heartbeat_hz);
        LockstepNode {
            node,
            heartbeat_every,
            last_reading: None,
        }
    }

    /// The node inside.
    #[must_use]
    pub fn node(&self) -> &MirrorNode {
        self.node
    }

    /// Handles one frame (or, in one process, one message) from the controller.
    ///
    /// # Errors
    /// [`LockstepNodeError`]: the plant refused a command, or a frame cannot be encoded.
    pub fn on_frame(&mut self, frame: impl Into<Carried>) -> Result<NodeReply, LockstepNodeError> {
        let message = match frame.into().message() {
            Ok(message) => message,
            Err(MessageError::UnknownId(_)) => return Ok(NodeReply::Ignored),
            Err(_) => {
                self.node.on_malformed_frame();
                return Ok(NodeReply::Ignored);
            }
        };
        match message {
            Message::CoilCommand(command) => {
                self.node.on_command(command.seq, command.amps());
                Ok(NodeReply::Send(Vec::new()))
            }
            Message::Step { step } => Ok(NodeReply::Send(self.step(step)?)),
            Message::Status(status)
                if status.node == NodeId::Controller && status.state != NodeState::Running =>
            {
                self.node.on_end_of_run();
                let k = self.node.next_period();
                let period_s = self.node.plant().period_s();
                Ok(NodeReply::EndOfRun(status_frame(
                    NodeState::Ready,
                    k,
                    period_s,
                )?))
            }
            _ => Ok(NodeReply::Ignored),
        }
    }

    /// Step(`step`): advances the plant one period and returns what goes out, in order: the
    /// angle reading, the sensor's samples, a fault frame for each fault that started, and a
    /// Status frame on heartbeat periods. A Step for the period just stepped (a duplicate, or
    /// the host asking again for a reading it did not get) is answered with the same angle
    /// reading alone, the plant not stepped, and counted; a Step for any other period than the
    /// next is counted and not answered.
    ///
    /// # Errors
    /// As [`Self::on_frame`].
    pub fn step(&mut self, step: u32) -> Result<Vec<NodeSend>, LockstepNodeError> {
        if let Some((last, reading)) = self.last_reading
            && last == step
        {
            self.node.on_repeated_step();
            return Ok(vec![NodeSend::Frame(reading)]);
        }
        if !self.node.check_step_counter(step) {
            // A stale or corrupted Step: stepping on it would shift every later period.
            return Ok(Vec::new());
        }
        let k = self.node.next_period();
        let NodeOutput {
            step: plant_step,
            started_faults,
        } = self.node.step()?;
        let reading = angle_frame(&plant_step)?;
        self.last_reading = Some((step, reading));
        let mut sends = Vec::with_capacity(3 + started_faults.len());
        sends.push(NodeSend::Frame(reading));
        sends.push(NodeSend::Samples(plant_step.sensor_samples));
        for (kind, detail) in started_faults {
            sends.push(NodeSend::Frame(fault_frame(kind, detail, k)?));
        }
        if k.is_multiple_of(self.heartbeat_every) {
            let period_s = self.node.plant().period_s();
            sends.push(NodeSend::Frame(status_frame(
                self.node.state(),
                k,
                period_s,
            )?));
        }
        Ok(sends)
    }

    /// The watchdog fired after `missed_periods`: the coil currents drop to zero; returns the
    /// LinkTimeout fault and the Status(fault) to send.
    ///
    /// # Errors
    /// A frame that cannot be encoded.
    pub fn on_link_timeout(&mut self, missed_periods: u32) -> Result<[CanFrame; 2], MessageError> {
        let fault = self.node.on_link_timeout(missed_periods);
        last_frames(self.node, fault)
    }
}

impl LockstepAnswers for LockstepNode<'_> {
    fn on_frame(&mut self, frame: &CanFrame) -> Result<NodeReply, LockstepNodeError> {
        LockstepNode::on_frame(self, frame)
    }

    fn on_link_timeout(&mut self, missed_periods: u32) -> Result<[CanFrame; 2], MessageError> {
        LockstepNode::on_link_timeout(self, missed_periods)
    }

    fn loop_time_s(&self) -> f64 {
        self.node.next_period() as f64 * self.node.plant().period_s()
    }
}

/// The node's last frames after a fault that ends the run (the watchdog, a link failure): the
/// fault frame and Status(fault), in its next period.
///
/// # Errors
/// [`MessageError`] if a frame cannot be encoded.
pub fn last_frames(
    node: &MirrorNode,
    (fault, detail): (FaultKind, i32),
) -> Result<[CanFrame; 2], MessageError> {
    let k = node.next_period();
    Ok([
        fault_frame(fault, detail, k)?.frame()?,
        status_frame(NodeState::Fault, k, node.plant().period_s())?.frame()?,
    ])
}

/// The AngleReading of a stepped period (sequence counter = period mod 2^16).
///
/// # Errors
/// [`MessageError`] if the message cannot be encoded (never for the mirror's angles).
pub fn angle_frame(step: &PlantStep) -> Result<Carried, MessageError> {
    let reading = AngleReading::from_rad(step.period_index as u16, step.measured_angles_rad);
    Carried::checked(Message::AngleReading(reading))
}

/// The mirror node's fault frame for a fault that started in period `k`.
///
/// # Errors
/// [`MessageError`] if the message cannot be encoded.
pub fn fault_frame(kind: FaultKind, detail: i32, k: u64) -> Result<Carried, MessageError> {
    Carried::checked(Message::Fault(Fault {
        node: NodeId::Fsm,
        kind,
        detail,
        step: k as u16,
    }))
}

/// The mirror node's status frame in period `k` (its node time is the loop time, in us).
///
/// # Errors
/// [`MessageError`] if the message cannot be encoded.
pub fn status_frame(state: NodeState, k: u64, period_s: f64) -> Result<Carried, MessageError> {
    let node_time_us = (k as f64 * period_s * 1e6).round() as u64;
    Carried::checked(Message::Status(Status {
        node: NodeId::Fsm,
        state,
        step: (k & u64::from(U24_MAX)) as u32,
        node_time_us: (node_time_us & u64::from(U24_MAX)) as u32,
    }))
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

#[cfg(test)]
mod tests {
    use super::super::mirror_node::tests::node;
    use super::*;

    /// The messages a reply sends, and how many sensor samples.
    fn sent(reply: NodeReply) -> (Vec<Message>, usize) {
        let NodeReply::Send(sends) = reply else {
            panic!("{reply:?}");
        };
        let mut messages = Vec::new();
        let mut samples = 0;
        for send in sends {
            match send {
                NodeSend::Frame(frame) => messages.push(frame.message().unwrap()),
                NodeSend::Samples(period) => samples += period.len(),
                NodeSend::Cycles(_) => panic!("no recorded cycles here"),
            }
        }
        (messages, samples)
    }

    #[test]
    fn a_step_is_answered_with_its_reading_its_samples_and_a_heartbeat_on_time() {
        let mut mirror = node();
        // 400 Hz at 20 kHz: a heartbeat every 50 periods.
        let mut node = LockstepNode::new(&mut mirror, 400.0);
        let step = |k: u32| Message::Step { step: k }.encode().unwrap();
        let status = |k: u32, node_time_us: u32| {
            Message::Status(Status {
                node: NodeId::Fsm,
                state: NodeState::Running,
                step: k,
                node_time_us,
            })
        };
        let reading = |seq: u16| {
            Message::AngleReading(AngleReading {
                seq,
                alpha_urad: 0,
                beta_urad: 0,
            })
        };
        assert_eq!(
            sent(node.on_frame(step(0)).unwrap()),
            (vec![reading(0), status(0, 0)], 1)
        );
        for k in 1..50 {
            assert_eq!(
                sent(node.on_frame(step(k)).unwrap()),
                (vec![reading(k as u16)], 1)
            );
        }
        assert_eq!(
            sent(node.on_frame(step(50)).unwrap()),
            (vec![reading(50), status(50, 2500)], 1)
        );
        // The same Step again: the same reading alone, nothing stepped.
        assert_eq!(
            sent(node.on_frame(step(50)).unwrap()),
            (vec![reading(50)], 0)
        );
        assert_eq!(node.node().next_period(), 51);
    }
}
