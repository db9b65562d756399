//! A recorded session as the lockstep node, free of I/O and clocks: the controller's Step(k)
//! is answered with the node's recorded frames of period k (its AngleReading, heartbeats,
//! faults, Distance frames) and the sensor's recorded output cycles of that period, whatever
//! the controller commands: the replay is open loop, the mirror moving as it moved when
//! recorded. Each coil command received is compared with the recorded one of its period
//! ([`CommandComparison`]), so a controller can be checked against a bench session.
//!
//! The sensor's recording carries no timing: cycle i (from 0) was measured at `i / rate`
//! after the first, so period k delivers the cycles measured before its end,
//! `i < (k + 1) x rate x period`, and the last recorded period whatever is left. The node
//! answers as [`super::lockstep_node::LockstepNode`] does otherwise: a repeated Step gets the
//! same AngleReading alone, a Step for any other period than the next is counted and not
//! answered, the controller's Status ends the run with the recorded answer (or a
//! Status(ready) when none was recorded). A Step past the recording's last period is an error
//! ([`ReplayError::Exhausted`]): there is nothing recorded to answer it with.

use scanhil_protocol::can::CanFrame;
use scanhil_protocol::message::{
    AMPS_PER_COUNT, CoilCommand, FaultKind, Message, MessageError, NodeId, NodeState,
};
use scanhil_protocol::plant_units::ActuatorPair;

use super::lockstep::LockstepAnswers;
use super::lockstep_node::{LockstepNodeError, NodeReply, NodeSend, fault_frame, status_frame};
use super::recording::Recording;

/// Coil current counts (uA) per ampere on the wire.
const COUNTS_PER_AMP: f64 = 1.0 / AMPS_PER_COUNT;

/// Why the replay cannot answer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReplayError {
    /// The controller asked for a period the recording does not hold.
    #[error(
        "the recording ends after period {last} ({periods} periods): Step {step} cannot be answered"
    )]
    Exhausted {
        /// The Step's period counter.
        step: u32,
        /// The recording's periods.
        periods: usize,
        /// Its last period.
        last: usize,
    },
}

/// The first period whose coil command differs from the recorded one.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Divergence {
    /// The period.
    pub period: u64,
    /// The recorded command, A per actuator axis.
    pub recorded_a: ActuatorPair,
    /// The command received, A.
    pub received_a: ActuatorPair,
    /// Received minus recorded, A.
    pub difference_a: ActuatorPair,
}

/// The controller's coil commands against the recorded ones, compared as they came on the wire
/// (1 uA steps): equal means the same bits.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct CommandComparison {
    /// Commands compared with a recorded one.
    pub compared: u64,
    /// Of those, commands that differ.
    pub differing: u64,
    /// Commands for periods the recording holds no command for.
    pub not_recorded: u64,
    /// The largest difference per axis, by magnitude, A.
    pub largest_difference_a: ActuatorPair,
    /// The first period that differs (`None`: none did).
    pub first_divergence: Option<Divergence>,
}

impl CommandComparison {
    /// Compares the command received for `period` with `recorded` (`None`: none recorded).
    pub fn compare(&mut self, period: u64, received: &CoilCommand, recorded: Option<&CoilCommand>) {
        let Some(recorded) = recorded else {
            self.not_recorded += 1;
            return;
        };
        self.compared += 1;
        if (received.current_a_ua, received.current_b_ua)
            == (recorded.current_a_ua, recorded.current_b_ua)
        {
            return;
        }
        self.differing += 1;
        // From the wire's whole microamperes: 232 uA reads 0.000232 A, not a float residue.
        let amps = |ua: i32| f64::from(ua) / COUNTS_PER_AMP;
        let difference_a = ActuatorPair {
            a: amps(received.current_a_ua - recorded.current_a_ua),
            b: amps(received.current_b_ua - recorded.current_b_ua),
        };
        let (received_a, recorded_a) = (received.amps(), recorded.amps());
        let largest = &mut self.largest_difference_a;
        largest.a = largest.a.max(difference_a.a.abs());
        largest.b = largest.b.max(difference_a.b.abs());
        self.first_divergence.get_or_insert(Divergence {
            period,
            recorded_a,
            received_a,
            difference_a,
        });
    }
}

/// Counters the replay reports at the end of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct ReplayCounters {
    /// Periods answered.
    pub periods: u64,
    /// The recording's periods.
    pub recorded_periods: u64,
    /// Sensor cycles sent.
    pub sensor_cycles: u64,
    /// Step frames for the period just answered: answered again with its reading alone.
    pub repeated_steps: u64,
    /// Step frames for another period than the next: not answered.
    pub out_of_order_steps: u64,
    /// Frames with a loop id and a malformed payload.
    pub malformed_frames: u64,
}

/// A recorded session answering the controller in lockstep.
#[derive(Debug)]
pub struct ReplayNode {
    recording: Recording,
    cycles_per_period: f64,
    period_s: f64,
    next_period: usize,
    next_cycle: usize,
    last_step: Option<u32>,
    state: NodeState,
    held: CoilCommand,
    comparison: CommandComparison,
    counters: ReplayCounters,
}

impl ReplayNode {
    /// Serves `recording` with control period `period_s`, its sensor measuring at
    /// `measuring_rate_hz` (0 when the recording's cycles are not served).
    #[must_use]
    pub fn new(recording: Recording, period_s: f64, measuring_rate_hz: f64) -> ReplayNode {
        let counters = ReplayCounters {
            recorded_periods: recording.periods.len() as u64,
            ..ReplayCounters::default()
        };
        ReplayNode {
            recording,
            cycles_per_period: measuring_rate_hz * period_s,
            period_s,
            next_period: 0,
            next_cycle: 0,
            last_step: None,
            state: NodeState::Ready,
            held: CoilCommand::default(),
            comparison: CommandComparison::default(),
            counters,
        }
    }

    /// The commands compared so far.
    #[must_use]
    pub fn comparison(&self) -> &CommandComparison {
        &self.comparison
    }

    /// Its counters so far.
    #[must_use]
    pub fn counters(&self) -> ReplayCounters {
        self.counters
    }

    /// The node's state: ready, running, or fault after the watchdog or a link failure.
    #[must_use]
    pub fn state(&self) -> NodeState {
        self.state
    }

    /// The coil currents last commanded (zero after a fault), A: what a node would hold.
    #[must_use]
    pub fn held_command_a(&self) -> ActuatorPair {
        if self.state == NodeState::Fault {
            ActuatorPair::default()
        } else {
            self.held.amps()
        }
    }

    /// The node's link failed: its last frames, as after the watchdog with no period missed.
    ///
    /// # Errors
    /// A frame that cannot be encoded.
    pub fn on_link_failure(&mut self) -> Result<[CanFrame; 2], MessageError> {
        self.on_link_timeout(0)
    }

    fn on_command(&mut self, command: CoilCommand) {
        let period = self.next_period;
        self.comparison
            .compare(period as u64, &command, self.recording.commands.get(period));
        self.held = command;
    }

    /// Step(`step`): the recorded frames of the next period with its sensor cycles after the
    /// reading.
    fn step(&mut self, step: u32) -> Result<Vec<NodeSend>, ReplayError> {
        if self.last_step == Some(step) {
            self.counters.repeated_steps += 1;
            let period = &self.recording.periods[self.next_period - 1];
            return Ok(vec![NodeSend::Frame(period.frames[period.reading])]);
        }
        if u64::from(step) != self.next_period as u64 & u64::from(u32::MAX) {
            self.counters.out_of_order_steps += 1;
            return Ok(Vec::new());
        }
        let periods = self.recording.periods.len();
        let Some(period) = self.recording.periods.get(self.next_period) else {
            return Err(ReplayError::Exhausted {
                step,
                periods,
                last: periods - 1,
            });
        };
        let end_cycle = if self.next_period + 1 == periods {
            self.recording.cycles.len()
        } else {
            let measured = ((self.next_period + 1) as f64 * self.cycles_per_period).ceil();
            (measured as usize).clamp(self.next_cycle, self.recording.cycles.len())
        };
        let cycles = self.recording.cycles[self.next_cycle..end_cycle].to_vec();
        let mut sends: Vec<NodeSend> = period.frames.iter().copied().map(NodeSend::Frame).collect();
        sends.insert(period.reading + 1, NodeSend::Cycles(cycles));
        self.counters.sensor_cycles += (end_cycle - self.next_cycle) as u64;
        self.next_cycle = end_cycle;
        self.next_period += 1;
        self.counters.periods += 1;
        self.last_step = Some(step);
        if self.state != NodeState::Fault {
            self.state = NodeState::Running;
        }
        Ok(sends)
    }
}

impl LockstepAnswers for ReplayNode {
    fn on_frame(&mut self, frame: &CanFrame) -> Result<NodeReply, LockstepNodeError> {
        let message = match Message::decode(frame) {
            Ok(message) => message,
            Err(MessageError::UnknownId(_)) => return Ok(NodeReply::Ignored),
            Err(_) => {
                self.counters.malformed_frames += 1;
                return Ok(NodeReply::Ignored);
            }
        };
        match message {
            Message::CoilCommand(command) => {
                self.on_command(command);
                Ok(NodeReply::Send(Vec::new()))
            }
            Message::CommandStepFd { command, step } => {
                self.on_command(command);
                Ok(NodeReply::Send(self.step(step)?))
            }
            Message::Step { step } => Ok(NodeReply::Send(self.step(step)?)),
            Message::Status(status)
                if status.node == NodeId::Controller && status.state != NodeState::Running =>
            {
                if self.state != NodeState::Fault {
                    self.state = NodeState::Ready;
                }
                let ready = match self.recording.end_of_run.first() {
                    Some(frame) => *frame,
                    None => status_frame(NodeState::Ready, self.next_period as u64, self.period_s)?,
                };
                Ok(NodeReply::EndOfRun(ready))
            }
            _ => Ok(NodeReply::Ignored),
        }
    }

    fn on_link_timeout(&mut self, missed_periods: u32) -> Result<[CanFrame; 2], MessageError> {
        self.state = NodeState::Fault;
        let k = self.next_period as u64;
        let detail = i32::try_from(missed_periods).unwrap_or(i32::MAX);
        Ok([
            fault_frame(FaultKind::LinkTimeout, detail, k)?,
            status_frame(NodeState::Fault, k, self.period_s)?,
        ])
    }

    fn loop_time_s(&self) -> f64 {
        self.next_period as f64 * self.period_s
    }
}
