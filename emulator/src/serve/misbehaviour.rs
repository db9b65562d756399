//! Deliberately non-conforming mirror nodes, a conformance test aid: `scanhil-emulator serve
//! --misbehave RULE` breaks one rule of the loop protocol, so `scanhil conformance` can be
//! shown to fail the check for that rule (`tests/loop/conformance.rs`), in lockstep and in
//! real time.
//!
//! [`Misbehaving`] is a pure wrapper around the node's answers: it rewrites or drops frames of
//! each answer (a lockstep answer, or a real-time period's frames), and tells the serve loop
//! ([`super::lockstep`], [`super::realtime`]) when to answer late, whether to arm its
//! watchdog, when to die and how fast its clock runs. Everything else the node does is
//! unchanged. In real time a late answer is a stall of the node's clock: the period's frames go
//! out late and the periods after it keep the delay (no catch-up burst).

use scanhil_protocol::message::{AngleReading, Carried, Message, MessageError};

use super::lockstep_node::NodeSend;

/// The answer (counting from 0) a misbehaving node breaks its rule at: late, or the first
/// one whose counter skips.
pub const MISBEHAVE_FROM_ANSWER: u64 = 1_000;
/// Factor on the angles of the `out-of-range` node (angles reported in the wrong unit).
pub const OUT_OF_RANGE_FACTOR: f64 = 100.0;
/// How late the `late-answers` node answers, as a multiple of its watchdog's whole allowance
/// (the answer deadline the host is expected to use).
pub const LATE_ANSWER_ALLOWANCES: f64 = 1.5;
/// The length of the `slow-clock` node's periods, as a multiple of the declared period: its
/// clock runs 5 % slow (a real node's crystal is off by parts per million).
pub const SLOW_CLOCK_FACTOR: f64 = 1.05;

/// The rule a deliberately non-conforming node breaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Misbehaviour {
    /// Answers Step [`MISBEHAVE_FROM_ANSWER`] only after [`LATE_ANSWER_ALLOWANCES`] times its
    /// watchdog's allowance.
    LateAnswers,
    /// From answer [`MISBEHAVE_FROM_ANSWER`] on, AngleReading counters run one ahead (one
    /// counter value skipped).
    SequenceGaps,
    /// Reports angles [`OUT_OF_RANGE_FACTOR`] times too large (a unit error): beyond the
    /// mirror's range as soon as it is driven, near zero while it rests.
    OutOfRange,
    /// Reports the first angles it measured for ever (a frozen angle sensor).
    FrozenAngles,
    /// Never sends the fault frames of its answers (over-current, power limit); the faults
    /// themselves still happen.
    NoFaultFrame,
    /// Never sends its heartbeat Status frames.
    NoStatusFrame,
    /// Never arms its watchdog: keeps the coils driven when the host falls silent.
    NoWatchdog,
    /// Exits at the first frame after a garbage SLCAN line.
    DiesOnGarbage,
    /// Real time only: its periods are [`SLOW_CLOCK_FACTOR`] times the declared one (a node
    /// configured for another rate, or a clock off by far more than any crystal).
    SlowClock,
}

impl Misbehaviour {
    /// Whether the rule can be broken in lockstep: a lockstep node has no clock of its own to
    /// run slow.
    #[must_use]
    pub fn in_lockstep(self) -> bool {
        self != Misbehaviour::SlowClock
    }
}

/// One answer after the misbehaviour: what to send, and whether to send it late.
#[derive(Debug, Clone, PartialEq)]
pub struct Answer {
    /// The frames and samples to send, in order.
    pub sends: Vec<NodeSend>,
    /// Send them only after [`LATE_ANSWER_ALLOWANCES`] times the watchdog's allowance.
    pub late: bool,
}

/// A node breaking `rule`, answer by answer (no I/O, no clock).
#[derive(Debug, Clone)]
pub struct Misbehaving {
    rule: Misbehaviour,
    answers: u64,
    frozen: Option<AngleReading>,
}

impl Misbehaving {
    /// A node that breaks `rule`.
    #[must_use]
    pub fn new(rule: Misbehaviour) -> Misbehaving {
        Misbehaving {
            rule,
            answers: 0,
            frozen: None,
        }
    }

    /// Whether the node arms its watchdog.
    #[must_use]
    pub fn arms_watchdog(&self) -> bool {
        self.rule != Misbehaviour::NoWatchdog
    }

    /// The length of the node's real-time periods, as a multiple of the declared one.
    #[must_use]
    pub fn clock_factor(&self) -> f64 {
        if self.rule == Misbehaviour::SlowClock {
            SLOW_CLOCK_FACTOR
        } else {
            1.0
        }
    }

    /// Whether the node dies now, having counted `malformed_lines` garbage SLCAN lines.
    #[must_use]
    pub fn dies(&self, malformed_lines: u64) -> bool {
        self.rule == Misbehaviour::DiesOnGarbage && malformed_lines > 0
    }

    /// Rewrites one answer of the node (its sends after one controller frame).
    ///
    /// # Errors
    /// A rewritten frame that cannot be encoded.
    pub fn answer(&mut self, sends: Vec<NodeSend>) -> Result<Answer, MessageError> {
        let mut late = false;
        let mut out = Vec::with_capacity(sends.len());
        for send in sends {
            let NodeSend::Frame(frame) = send else {
                out.push(send);
                continue;
            };
            match frame.message() {
                Ok(Message::AngleReading(reading)) => {
                    late |= self.rule == Misbehaviour::LateAnswers
                        && self.answers == MISBEHAVE_FROM_ANSWER;
                    let reading = self.reading(reading);
                    self.answers += 1;
                    out.push(NodeSend::Frame(Carried::checked(Message::AngleReading(
                        reading,
                    ))?));
                }
                Ok(Message::Fault(_)) if self.rule == Misbehaviour::NoFaultFrame => {}
                Ok(Message::Status(_)) if self.rule == Misbehaviour::NoStatusFrame => {}
                _ => out.push(NodeSend::Frame(frame)),
            }
        }
        Ok(Answer { sends: out, late })
    }

    /// The angle reading this node sends instead of `reading`.
    fn reading(&mut self, reading: AngleReading) -> AngleReading {
        match self.rule {
            Misbehaviour::SequenceGaps if self.answers >= MISBEHAVE_FROM_ANSWER => AngleReading {
                seq: reading.seq.wrapping_add(1),
                ..reading
            },
            Misbehaviour::OutOfRange => {
                let mut angles = reading.rad();
                angles.alpha *= OUT_OF_RANGE_FACTOR;
                angles.beta *= OUT_OF_RANGE_FACTOR;
                AngleReading::from_rad(reading.seq, angles)
            }
            Misbehaviour::FrozenAngles => {
                let first = *self.frozen.get_or_insert(reading);
                AngleReading {
                    seq: reading.seq,
                    ..first
                }
            }
            _ => reading,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanhil_protocol::message::{Fault, FaultKind, NodeId, NodeState, Status};

    fn reading(seq: u16, alpha_urad: i32) -> NodeSend {
        NodeSend::Frame(
            Carried::checked(Message::AngleReading(AngleReading {
                seq,
                alpha_urad,
                beta_urad: -alpha_urad,
            }))
            .unwrap(),
        )
    }

    fn decoded(answer: &Answer) -> Vec<Message> {
        answer
            .sends
            .iter()
            .filter_map(|send| match send {
                NodeSend::Frame(frame) => Some(frame.message().unwrap()),
                NodeSend::Samples(_) | NodeSend::Cycles(_) => None,
            })
            .collect()
    }

    fn run(rule: Misbehaviour, answers: u64) -> Vec<Answer> {
        let mut node = Misbehaving::new(rule);
        (0..answers)
            .map(|k| {
                node.answer(vec![reading(k as u16, 100 + k as i32)])
                    .unwrap()
            })
            .collect()
    }

    #[test]
    fn late_answers_are_late_once_and_unchanged() {
        let answers = run(Misbehaviour::LateAnswers, MISBEHAVE_FROM_ANSWER + 2);
        let late: Vec<usize> = (0..answers.len()).filter(|&k| answers[k].late).collect();
        assert_eq!(late, [MISBEHAVE_FROM_ANSWER as usize]);
        assert_eq!(answers[5].sends, vec![reading(5, 105)]);
    }

    #[test]
    fn sequence_gaps_skip_one_counter_from_the_given_answer_on() {
        let answers = run(Misbehaviour::SequenceGaps, MISBEHAVE_FROM_ANSWER + 2);
        let seq = |k: u64| match decoded(&answers[k as usize])[0] {
            Message::AngleReading(r) => r.seq,
            ref other => panic!("{other:?}"),
        };
        assert_eq!(seq(MISBEHAVE_FROM_ANSWER - 1), 999);
        assert_eq!(seq(MISBEHAVE_FROM_ANSWER), 1001);
        assert_eq!(seq(MISBEHAVE_FROM_ANSWER + 1), 1002);
    }

    #[test]
    fn out_of_range_and_frozen_angles_rewrite_the_angles_only() {
        let scaled = run(Misbehaviour::OutOfRange, 3);
        assert_eq!(decoded(&scaled[2]), [decode(&reading(2, 10200))]);
        let frozen = run(Misbehaviour::FrozenAngles, 3);
        assert_eq!(decoded(&frozen[2]), [decode(&reading(2, 100))]);
    }

    fn decode(send: &NodeSend) -> Message {
        match send {
            NodeSend::Frame(frame) => frame.message().unwrap(),
            NodeSend::Samples(_) | NodeSend::Cycles(_) => unreachable!("a frame"),
        }
    }

    #[test]
    fn fault_and_status_frames_are_dropped_by_their_rules_only() {
        let fault = NodeSend::Frame(
            Carried::checked(Message::Fault(Fault {
                node: NodeId::Fsm,
                kind: FaultKind::OverCurrent,
                detail: 8_000_000,
                step: 3,
            }))
            .unwrap(),
        );
        let status = NodeSend::Frame(
            Carried::checked(Message::Status(Status {
                node: NodeId::Fsm,
                state: NodeState::Running,
                step: 3,
                node_time_us: 150,
            }))
            .unwrap(),
        );
        let answer = vec![reading(3, 0), fault.clone(), status.clone()];
        let kept = |rule| Misbehaving::new(rule).answer(answer.clone()).unwrap().sends;
        assert_eq!(
            kept(Misbehaviour::NoFaultFrame),
            [reading(3, 0), status.clone()]
        );
        assert_eq!(kept(Misbehaviour::NoStatusFrame), [reading(3, 0), fault]);
        assert_eq!(kept(Misbehaviour::NoWatchdog), answer);
    }

    #[test]
    fn only_their_rules_disarm_the_watchdog_die_or_run_slow() {
        let silent = Misbehaving::new(Misbehaviour::NoWatchdog);
        assert!(!silent.arms_watchdog() && !silent.dies(5));
        assert_eq!(silent.clock_factor(), 1.0);
        let fragile = Misbehaving::new(Misbehaviour::DiesOnGarbage);
        assert!(fragile.arms_watchdog() && !fragile.dies(0) && fragile.dies(1));
        let slow = Misbehaving::new(Misbehaviour::SlowClock);
        assert!(slow.arms_watchdog() && !slow.dies(1));
        assert_eq!(slow.clock_factor(), SLOW_CLOCK_FACTOR);
        assert!(!Misbehaviour::SlowClock.in_lockstep() && Misbehaviour::LateAnswers.in_lockstep());
    }
}
