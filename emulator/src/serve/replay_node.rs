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
//!
//! In real time ([`ClockedNode`]) the node is the clock master as the emulated mirror is: period
//! k's recorded frames and cycles go out at its reading's recorded time after the first
//! reading's (a lockstep recording's stamps are k periods apart; a real-time or bench
//! recording's keep their jitter and stalls), whatever the controller commands; each command
//! is compared with the recorded one of the period its counter names.

use std::time::Duration;

use scanhil_protocol::can::CanFrame;
use scanhil_protocol::message::{
    AMPS_PER_COUNT, Carried, CoilCommand, FaultKind, Message, MessageError, NodeId, NodeState,
};
use scanhil_protocol::plant_units::ActuatorPair;

use super::lockstep::LockstepAnswers;
use super::lockstep_node::{LockstepNodeError, NodeReply, NodeSend, fault_frame, status_frame};
use super::realtime::ClockedNode;
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
    /// Real time: periods sent with no fresh command since the period before.
    pub stale_periods: u64,
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
    /// Real time: a command came since the last period went out.
    fresh_command: bool,
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
            fresh_command: false,
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

    /// A coil command, compared with the recorded one of the period its counter names (the
    /// period nearest the next one with that counter: in lockstep the next, in real time the
    /// next or one before when it came late).
    fn on_command(&mut self, command: CoilCommand) {
        let next = self.next_period as u64;
        let behind = (next as u16).wrapping_sub(command.seq) as i16;
        let period = next.saturating_add_signed(-i64::from(behind));
        let recorded = usize::try_from(period)
            .ok()
            .and_then(|period| self.recording.commands.get(period));
        self.comparison.compare(period, &command, recorded);
        self.held = command;
        self.fresh_command = true;
    }

    /// The node's answer to the controller's end of the run: the recorded one, or Status(ready)
    /// when none was recorded.
    fn end_of_run(&mut self) -> Result<Carried, MessageError> {
        if self.state != NodeState::Fault {
            self.state = NodeState::Ready;
        }
        match self.recording.end_of_run.first() {
            Some(frame) => Ok(Carried::Frame(*frame)),
            None => status_frame(NodeState::Ready, self.next_period as u64, self.period_s),
        }
    }

    /// Step(`step`): the recorded frames of the next period with its sensor cycles after the
    /// reading.
    fn step(&mut self, step: u32) -> Result<Vec<NodeSend>, ReplayError> {
        if self.last_step == Some(step) {
            self.counters.repeated_steps += 1;
            let period = &self.recording.periods[self.next_period - 1];
            return Ok(vec![NodeSend::Frame(period.frames[period.reading].into())]);
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
        let mut sends: Vec<NodeSend> = period
            .frames
            .iter()
            .map(|frame| NodeSend::Frame(frame.into()))
            .collect();
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
                Ok(NodeReply::EndOfRun(self.end_of_run()?))
            }
            _ => Ok(NodeReply::Ignored),
        }
    }

    fn on_link_timeout(&mut self, missed_periods: u32) -> Result<[CanFrame; 2], MessageError> {
        self.state = NodeState::Fault;
        let k = self.next_period as u64;
        let detail = i32::try_from(missed_periods).unwrap_or(i32::MAX);
        Ok([
            fault_frame(FaultKind::LinkTimeout, detail, k)?.frame()?,
            status_frame(NodeState::Fault, k, self.period_s)?.frame()?,
        ])
    }

    fn loop_time_s(&self) -> f64 {
        self.next_period as f64 * self.period_s
    }
}

impl ClockedNode for ReplayNode {
    fn period_s(&self) -> f64 {
        self.period_s
    }

    fn next_period(&self) -> u64 {
        self.next_period as u64
    }

    /// The reading's recorded time after the first one's; past the recording, a period on
    /// from its last.
    fn period_start(&self, k: u64) -> Duration {
        let periods = &self.recording.periods;
        let first_s = periods.first().map_or(0.0, |p| p.reading_s);
        let last = periods.len().saturating_sub(1);
        let (at, extra) = match usize::try_from(k) {
            Ok(k) if k <= last => (k, 0),
            _ => (last, k - last as u64),
        };
        let recorded_s = periods.get(at).map_or(0.0, |p| p.reading_s) - first_s;
        let start_s = recorded_s.max(0.0) + extra as f64 * self.period_s;
        Duration::try_from_secs_f64(start_s).unwrap_or(Duration::MAX)
    }

    /// The recorded frames of the period, its cycles after the reading; the heartbeats are
    /// the recorded ones.
    fn tick(&mut self, _heartbeat: bool) -> anyhow::Result<Vec<NodeSend>> {
        if !std::mem::take(&mut self.fresh_command) && self.next_period > 0 {
            self.counters.stale_periods += 1;
        }
        let step = (self.next_period as u64 & u64::from(u32::MAX)) as u32;
        Ok(self.step(step)?)
    }

    fn stale_periods(&self) -> u64 {
        self.counters.stale_periods
    }

    fn take_command(&mut self, command: &CoilCommand) {
        self.on_command(*command);
    }

    fn malformed_frame(&mut self) {
        self.counters.malformed_frames += 1;
    }

    fn watchdog_fired(&mut self, missed_periods: u32) -> Result<[CanFrame; 2], MessageError> {
        self.on_link_timeout(missed_periods)
    }

    fn link_failed(&mut self) -> Result<[CanFrame; 2], MessageError> {
        self.on_link_failure()
    }

    fn run_ended(&mut self) -> Result<CanFrame, MessageError> {
        self.end_of_run()?.frame()
    }
}

#[cfg(test)]
mod tests {
    use scanhil_protocol::message::{AngleReading, Fault, Status};

    use super::*;
    use crate::serve::recording::RecordedPeriod;

    const PERIOD_S: f64 = 1e-3;

    fn encode(message: Message) -> CanFrame {
        message.encode().unwrap()
    }

    fn reading(seq: u16) -> CanFrame {
        encode(Message::AngleReading(AngleReading {
            seq,
            alpha_urad: i32::from(seq),
            beta_urad: 0,
        }))
    }

    fn heartbeat(step: u32) -> CanFrame {
        encode(Message::Status(Status {
            node: NodeId::Fsm,
            state: NodeState::Running,
            step,
            node_time_us: 0,
        }))
    }

    fn command(seq: u16, a_ua: i32, b_ua: i32) -> CoilCommand {
        CoilCommand {
            seq,
            current_a_ua: a_ua,
            current_b_ua: b_ua,
        }
    }

    /// Three periods (a heartbeat before period 1's reading), commands 10k uA and -k uA, five
    /// sensor cycles.
    fn recording() -> Recording {
        Recording {
            periods: vec![
                RecordedPeriod {
                    frames: vec![reading(0)],
                    reading: 0,
                    reading_s: 10.001,
                },
                RecordedPeriod {
                    frames: vec![heartbeat(0), reading(1)],
                    reading: 1,
                    reading_s: 10.002,
                },
                RecordedPeriod {
                    frames: vec![reading(2)],
                    reading: 0,
                    reading_s: 10.0045,
                },
            ],
            commands: (0..3)
                .map(|k| command(k, 10 * i32::from(k), -i32::from(k)))
                .collect(),
            end_of_run: Vec::new(),
            cycles: (0..5).map(|i| vec![i]).collect(),
            clock: None,
        }
    }

    /// 1.5 cycles a period.
    fn node() -> ReplayNode {
        ReplayNode::new(recording(), PERIOD_S, 1500.0)
    }

    fn sends(reply: NodeReply) -> Vec<NodeSend> {
        match reply {
            NodeReply::Send(sends) => sends,
            other => panic!("{other:?}"),
        }
    }

    fn step(node: &mut ReplayNode, k: u32) -> Vec<NodeSend> {
        sends(node.on_frame(&encode(Message::Step { step: k })).unwrap())
    }

    fn cycles(values: &[u32]) -> NodeSend {
        NodeSend::Cycles(values.iter().map(|&v| vec![v]).collect())
    }

    #[test]
    fn each_step_gets_its_periods_frames_and_the_cycles_measured_by_its_end() {
        let mut node = node();
        assert_eq!(node.state(), NodeState::Ready);
        assert_eq!(node.loop_time_s(), 0.0);
        // Cycles measured before 1.5, 3.0 (the last period: all that is left).
        assert_eq!(
            step(&mut node, 0),
            [NodeSend::Frame(reading(0).into()), cycles(&[0, 1])]
        );
        assert_eq!(node.state(), NodeState::Running);
        assert_eq!(
            step(&mut node, 1),
            [
                NodeSend::Frame(heartbeat(0).into()),
                NodeSend::Frame(reading(1).into()),
                cycles(&[2])
            ]
        );
        assert_eq!(
            step(&mut node, 2),
            [NodeSend::Frame(reading(2).into()), cycles(&[3, 4])]
        );
        assert!((node.loop_time_s() - 3.0 * PERIOD_S).abs() < 1e-15);
        let counters = node.counters();
        assert_eq!(
            (
                counters.periods,
                counters.recorded_periods,
                counters.sensor_cycles
            ),
            (3, 3, 5)
        );
    }

    #[test]
    fn a_recording_with_fewer_cycles_than_the_rate_runs_out_of_them_gently() {
        let mut node = ReplayNode::new(recording(), PERIOD_S, 4000.0);
        assert_eq!(step(&mut node, 0)[1], cycles(&[0, 1, 2, 3]));
        assert_eq!(step(&mut node, 1)[2], cycles(&[4]));
        assert_eq!(step(&mut node, 2)[1], cycles(&[]));
    }

    #[test]
    fn the_last_period_takes_the_cycles_left_beyond_the_rate() {
        // One cycle a period for five cycles in three periods.
        let mut node = ReplayNode::new(recording(), PERIOD_S, 1000.0);
        assert_eq!(step(&mut node, 0)[1], cycles(&[0]));
        assert_eq!(step(&mut node, 1)[2], cycles(&[1]));
        assert_eq!(step(&mut node, 2)[1], cycles(&[2, 3, 4]));
    }

    #[test]
    fn a_repeated_step_gets_the_reading_alone_and_another_step_nothing() {
        let mut node = node();
        step(&mut node, 0);
        step(&mut node, 1);
        assert_eq!(step(&mut node, 1), [NodeSend::Frame(reading(1).into())]);
        assert_eq!(node.counters().repeated_steps, 1);
        assert!(step(&mut node, 0).is_empty());
        assert!(step(&mut node, 5).is_empty());
        assert_eq!(node.counters().out_of_order_steps, 2);
        assert_eq!(step(&mut node, 2)[0], NodeSend::Frame(reading(2).into()));
    }

    #[test]
    fn in_real_time_periods_start_at_their_recorded_times_and_go_on_a_period_apart() {
        let node = node();
        let start_ms = |k: u64| node.period_start(k).as_secs_f64() * 1e3;
        let starts: Vec<f64> = (0..7).map(start_ms).collect();
        for (start, expected) in starts.iter().zip([0.0, 1.0, 3.5, 4.5, 5.5, 6.5, 7.5]) {
            assert!((start - expected).abs() < 1e-9, "{starts:?}");
        }
        assert_eq!(ClockedNode::period_s(&node), PERIOD_S);
    }

    #[test]
    fn in_real_time_each_tick_sends_its_period_and_stale_periods_are_counted() {
        let mut node = node();
        assert_eq!(
            node.tick(true).unwrap(),
            [NodeSend::Frame(reading(0).into()), cycles(&[0, 1])]
        );
        assert_eq!(ClockedNode::next_period(&node), 1);
        // Period 0 has no command before it to miss.
        assert_eq!(node.stale_periods(), 0);
        // No command before period 1 went out: stale.
        assert_eq!(
            node.tick(false).unwrap()[1],
            NodeSend::Frame(reading(1).into())
        );
        assert_eq!(node.stale_periods(), 1);
        node.take_command(&command(2, 20, -2));
        node.tick(false).unwrap();
        assert_eq!(node.stale_periods(), 1);
        assert_eq!(ClockedNode::next_period(&node), 3);
        assert!(node.tick(false).is_err(), "past the recording");
        node.malformed_frame();
        assert_eq!(node.counters().malformed_frames, 1);
    }

    #[test]
    fn in_real_time_a_command_is_compared_with_the_period_its_counter_names() {
        let mut node = node();
        node.tick(false).unwrap();
        node.tick(false).unwrap();
        // Next is period 2: the command for period 1 came late, the one for 2 on time.
        node.take_command(&command(1, 10, -1));
        node.take_command(&command(2, 21, -2));
        let comparison = node.comparison();
        assert_eq!((comparison.compared, comparison.differing), (2, 1));
        assert_eq!(comparison.first_divergence.unwrap().period, 2);
        let ready = node.run_ended().unwrap();
        assert!(matches!(
            Message::decode(&ready).unwrap(),
            Message::Status(Status {
                state: NodeState::Ready,
                ..
            })
        ));
        assert_eq!(node.state(), NodeState::Ready);
        let [fault, status] = node.watchdog_fired(7).unwrap();
        assert!(matches!(
            Message::decode(&fault).unwrap(),
            Message::Fault(Fault {
                kind: FaultKind::LinkTimeout,
                ..
            })
        ));
        assert!(matches!(
            Message::decode(&status).unwrap(),
            Message::Status(Status {
                state: NodeState::Fault,
                ..
            })
        ));
        assert_eq!(node.link_failed().unwrap().len(), 2);
    }

    #[test]
    fn a_step_past_the_recording_is_refused() {
        let mut node = node();
        for k in 0..3 {
            step(&mut node, k);
        }
        let error = node
            .on_frame(&encode(Message::Step { step: 3 }))
            .unwrap_err()
            .to_string();
        assert_eq!(
            error,
            "the recording ends after period 2 (3 periods): Step 3 cannot be answered"
        );
    }

    #[test]
    fn commands_are_compared_with_the_recorded_ones_of_their_period() {
        let mut node = node();
        let on = |node: &mut ReplayNode, c: CoilCommand| {
            assert!(sends(node.on_frame(&encode(Message::CoilCommand(c))).unwrap()).is_empty());
        };
        on(&mut node, command(0, 0, 0));
        assert_eq!(node.held_command_a(), ActuatorPair::default());
        step(&mut node, 0);
        // Period 1 recorded 10 uA and -1 uA.
        on(&mut node, command(1, 242, -1));
        assert_eq!(node.held_command_a(), command(1, 242, -1).amps());
        step(&mut node, 1);
        on(&mut node, command(2, 20, -2_000_002));
        step(&mut node, 2);
        on(&mut node, command(3, 0, 0));
        let comparison = node.comparison();
        assert_eq!(
            (
                comparison.compared,
                comparison.differing,
                comparison.not_recorded
            ),
            (3, 2, 1)
        );
        let first = comparison.first_divergence.expect("period 1 differs");
        assert_eq!(first.period, 1);
        assert_eq!(first.difference_a, ActuatorPair { a: 232e-6, b: 0.0 });
        assert_eq!(first.recorded_a, command(1, 10, -1).amps());
        assert_eq!(first.received_a, command(1, 242, -1).amps());
        assert_eq!(
            comparison.largest_difference_a,
            ActuatorPair { a: 232e-6, b: 2.0 }
        );
    }

    #[test]
    fn a_combined_fd_frame_is_the_command_and_the_step() {
        let mut node = node();
        let frame = encode(Message::CommandStepFd {
            command: command(0, 5, 0),
            step: 0,
        });
        assert_eq!(
            sends(node.on_frame(&frame).unwrap())[0],
            NodeSend::Frame(reading(0).into())
        );
        assert_eq!(node.comparison().differing, 1);
        assert_eq!(node.comparison().first_divergence.unwrap().period, 0);
    }

    #[test]
    fn the_controllers_end_gets_the_recorded_answer_or_a_ready_status() {
        let end = encode(Message::Status(Status {
            node: NodeId::Controller,
            state: NodeState::Ready,
            step: 1,
            node_time_us: 0,
        }));
        let mut node = node();
        step(&mut node, 0);
        let NodeReply::EndOfRun(ready) = node.on_frame(&end).unwrap() else {
            panic!("the end of the run")
        };
        assert_eq!(ready, status_frame(NodeState::Ready, 1, PERIOD_S).unwrap());
        assert_eq!(node.state(), NodeState::Ready);
        let recorded = heartbeat(9);
        let mut node = ReplayNode::new(
            Recording {
                end_of_run: vec![recorded],
                ..recording()
            },
            PERIOD_S,
            0.0,
        );
        assert_eq!(
            node.on_frame(&end).unwrap(),
            NodeReply::EndOfRun(recorded.into())
        );
        // The controller's running status is no end.
        let running = encode(Message::Status(Status {
            node: NodeId::Controller,
            state: NodeState::Running,
            step: 0,
            node_time_us: 0,
        }));
        assert_eq!(node.on_frame(&running).unwrap(), NodeReply::Ignored);
    }

    #[test]
    fn the_watchdog_or_a_failed_link_zeroes_the_coils_and_sends_the_fault() {
        let mut node = node();
        node.on_frame(&encode(Message::CoilCommand(command(0, 500, 0))))
            .unwrap();
        step(&mut node, 0);
        assert_ne!(node.held_command_a(), ActuatorPair::default());
        let [fault, status] = node.on_link_timeout(7).unwrap();
        assert_eq!(
            Message::decode(&fault).unwrap(),
            Message::Fault(Fault {
                node: NodeId::Fsm,
                kind: FaultKind::LinkTimeout,
                detail: 7,
                step: 1,
            })
        );
        assert_eq!(
            status,
            status_frame(NodeState::Fault, 1, PERIOD_S)
                .unwrap()
                .frame()
                .unwrap()
        );
        assert_eq!(node.state(), NodeState::Fault);
        assert_eq!(node.held_command_a(), ActuatorPair::default());
        // A faulted node stays so through a step and the end of the run.
        step(&mut node, 1);
        assert_eq!(node.state(), NodeState::Fault);
        let [fault, _] = node.on_link_failure().unwrap();
        assert!(matches!(
            Message::decode(&fault).unwrap(),
            Message::Fault(Fault { detail: 0, .. })
        ));
        let end = encode(Message::Status(Status {
            node: NodeId::Controller,
            state: NodeState::Ready,
            step: 2,
            node_time_us: 0,
        }));
        node.on_frame(&end).unwrap();
        assert_eq!(node.state(), NodeState::Fault);
    }

    #[test]
    fn frames_not_for_the_node_are_ignored_and_malformed_ones_counted() {
        let mut node = node();
        let unknown =
            CanFrame::new(scanhil_protocol::can::CanId::standard(0x7FF).unwrap(), &[1]).unwrap();
        assert_eq!(node.on_frame(&unknown).unwrap(), NodeReply::Ignored);
        let short_step =
            CanFrame::new(scanhil_protocol::can::CanId::standard(0x021).unwrap(), &[1]).unwrap();
        assert_eq!(node.on_frame(&short_step).unwrap(), NodeReply::Ignored);
        assert_eq!(node.on_frame(&reading(0)).unwrap(), NodeReply::Ignored);
        assert_eq!(node.counters().malformed_frames, 1);
        assert_eq!(node.counters().periods, 0);
    }
}
