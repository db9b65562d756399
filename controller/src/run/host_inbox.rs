//! What the host does with each frame it receives on the mirror's link, free of I/O and
//! clocks: angle readings are handed back to the loop, the nodes' status and fault frames are
//! kept as events, Distance frames (a sensor sharing the mirror's link) are kept, and
//! malformed and foreign frames are counted. A node's LinkTimeout fault ends the run.

use scanhil_protocol::message::{Carried, FaultKind, Message, MessageError, NodeId, NodeState};
use scanhil_protocol::plant_units::{FULL_RANGE_DEG, SensingPair};

use super::loop_error::LoopError;
use super::sample_log::SampleLog;

/// A status or fault frame the node sent, with the loop time it was received at. Every fault
/// is one; of the status frames, those that say something: a node's first, every change of
/// state, and every one not `running` (a node's heartbeats while it runs are counted in
/// [`MirrorLinkCounters::status_frames`], not kept one by one: the record stays flat in a
/// long run).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct NodeEvent {
    /// Loop time at reception, s.
    pub t_s: f64,
    /// The node that sent it.
    pub node: NodeId,
    /// The state, for a status frame.
    pub status: Option<NodeState>,
    /// The fault, for a fault frame.
    pub fault: Option<FaultKind>,
    /// The step counter the node stamped on it (24 bits in a status, 16 in a fault).
    pub step: u32,
}

/// Counters of the mirror link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct MirrorLinkCounters {
    /// Angle readings received.
    pub angle_readings: u64,
    /// Angle readings ahead of the one waited for (sequence counter skipped values, mod 2^16).
    pub angle_sequence_gaps: u64,
    /// Angle readings of an earlier period than the one waited for (a duplicate, a delayed or
    /// reordered frame, an answer to a repeated Step): counted, not used.
    pub late_readings: u64,
    /// Awaited angle readings with an angle no mirror reaches ([`plausible_angles`]: beyond
    /// its range with margin, or not finite), taken as corrupted and asked for again (only
    /// while Steps are repeated, see `HostLoop::with_tries_per_reading`).
    pub implausible_readings: u64,
    /// Frames with a loop id and a malformed payload.
    pub malformed_frames: u64,
    /// Frames with ids that are not loop messages (other traffic).
    pub foreign_frames: u64,
    /// SocketCAN: the bus's error frames (error-passive, no ACK, ...; a bus-off also ends
    /// the run). Filled by the link, not the inbox.
    pub bus_error_frames: u64,
    /// Status frames from the nodes, heartbeats included.
    pub status_frames: u64,
}

/// Margin on the mirror's range beyond which an angle reading is not plausible.
pub const ANGLE_RANGE_MARGIN: f64 = 1.2;

/// The largest plausible angle magnitude of a reading, rad: the mirror's range
/// ([`FULL_RANGE_DEG`]) times [`ANGLE_RANGE_MARGIN`].
#[must_use]
pub fn plausible_angle_limit_rad() -> f64 {
    FULL_RANGE_DEG.to_radians() * ANGLE_RANGE_MARGIN
}

/// Whether both angles are finite and within [`plausible_angle_limit_rad`].
#[must_use]
pub fn plausible_angles(angles: SensingPair) -> bool {
    let limit_rad = plausible_angle_limit_rad();
    [angles.alpha, angles.beta]
        .iter()
        .all(|angle| angle.is_finite() && angle.abs() <= limit_rad)
}

/// The received frames of one mirror link, filed.
#[derive(Debug, Clone)]
pub struct HostInbox {
    link: String,
    events: Vec<NodeEvent>,
    /// Each node's state in its latest status frame.
    node_states: Vec<(NodeId, NodeState)>,
    /// Distance frames (a sensor on CAN).
    distances: SampleLog,
    counters: MirrorLinkCounters,
}

impl HostInbox {
    /// An empty inbox for the link named `link` (the name goes into its errors).
    #[must_use]
    pub fn new(link: &str) -> HostInbox {
        HostInbox {
            link: link.to_owned(),
            events: Vec::new(),
            node_states: Vec::new(),
            distances: SampleLog::new(),
            counters: MirrorLinkCounters::default(),
        }
    }

    /// The link's name.
    #[must_use]
    pub fn link(&self) -> &str {
        &self.link
    }

    /// Files a frame (or, in one process, a message) received at loop time `t_s` (wall-clock `arrived`, kept with Distance
    /// frames); returns an angle reading's sequence counter and angles. Angle readings are
    /// not counted here: [`Self::count_reading`] does, where the loop takes one.
    ///
    /// # Errors
    /// [`LoopError::NodeFault`] when a node reports its own link timeout (the run ends).
    pub fn classify(
        &mut self,
        frame: &Carried,
        t_s: f64,
        arrived: tokio::time::Instant,
    ) -> Result<Option<(u16, SensingPair)>, LoopError> {
        let message = match frame.message() {
            Ok(message) => message,
            Err(MessageError::UnknownId(_)) => {
                self.counters.foreign_frames += 1;
                return Ok(None);
            }
            Err(_) => {
                self.counters.malformed_frames += 1;
                return Ok(None);
            }
        };
        match message {
            Message::AngleReading(reading) => return Ok(Some((reading.seq, reading.rad()))),
            Message::Distance(distance) => {
                self.distances
                    .add(Some(distance.counter), distance.value, arrived);
            }
            Message::AnglesDistanceFd { angles, distance } => {
                self.distances
                    .add(Some(distance.counter), distance.value, arrived);
                return Ok(Some((angles.seq, angles.rad())));
            }
            Message::Status(status) if status.node != NodeId::Controller => {
                self.counters.status_frames += 1;
                if self.state_changes(status.node, status.state)
                    || status.state != NodeState::Running
                {
                    self.events.push(NodeEvent {
                        t_s,
                        node: status.node,
                        status: Some(status.state),
                        fault: None,
                        step: status.step,
                    });
                }
            }
            Message::Fault(fault) if fault.node != NodeId::Controller => {
                self.events.push(NodeEvent {
                    t_s,
                    node: fault.node,
                    status: None,
                    fault: Some(fault.kind),
                    step: u32::from(fault.step),
                });
                if fault.kind == FaultKind::LinkTimeout {
                    return Err(LoopError::NodeFault {
                        link: self.link.clone(),
                        node: fault.node,
                        kind: fault.kind,
                        step: fault.step,
                    });
                }
            }
            _ => {}
        }
        Ok(None)
    }

    /// Counts an angle reading with sequence counter `seq` taken while period `expected` was
    /// awaited; returns how far ahead of it the reading is (mod 2^16; 0: the one awaited;
    /// up to 2^15 - 1 ahead is counted as a sequence gap, further as a late reading).
    pub fn count_reading(&mut self, seq: u16, expected: u64) -> u16 {
        self.counters.angle_readings += 1;
        let offset = seq.wrapping_sub(expected as u16);
        match offset {
            0 => {}
            ahead if ahead < 0x8000 => self.counters.angle_sequence_gaps += 1,
            _ => self.counters.late_readings += 1,
        }
        offset
    }

    /// Records `node`'s state; whether it differs from the one it reported last (or is its
    /// first).
    fn state_changes(&mut self, node: NodeId, state: NodeState) -> bool {
        match self
            .node_states
            .iter_mut()
            .find(|(known, _)| *known == node)
        {
            Some((_, last)) => std::mem::replace(last, state) != state,
            None => {
                self.node_states.push((node, state));
                true
            }
        }
    }

    /// Real time: the period of a reading with counter `seq` taken while period `expected`
    /// is awaited, or `None` for a reading the loop must pass over (counted):
    /// - the awaited one, or one up to `max_ahead` periods ahead (the readings between went
    ///   missing: a sequence gap): `Some(period)`;
    /// - one behind it (a duplicate, or a frame delayed past the next): a late reading;
    /// - further ahead than `max_ahead` (the node's watchdog would have stopped it long before:
    ///   a corrupted counter): implausible.
    ///
    /// Angles are not judged here: real time cannot ask for a reading again, and a mirror
    /// really driven beyond its range (a corrupted command, the power limit) must still be
    /// seen and controlled back, not ignored.
    pub fn place_reading(&mut self, seq: u16, expected: u64, max_ahead: u64) -> Option<u64> {
        let offset = seq.wrapping_sub(expected as u16);
        if offset < 0x8000 && u64::from(offset) > max_ahead {
            self.counters.angle_readings += 1;
            self.count_implausible();
            return None;
        }
        let offset = self.count_reading(seq, expected);
        (offset < 0x8000).then(|| expected + u64::from(offset))
    }

    /// Counts an awaited reading taken as corrupted ([`plausible_angles`]).
    pub fn count_implausible(&mut self) {
        self.counters.implausible_readings += 1;
    }

    /// Whether the newest event is the mirror node's Status(ready) (its last frame of a run).
    #[must_use]
    pub fn node_ready_last(&self) -> bool {
        self.events.last().is_some_and(|event| {
            event.node == NodeId::Fsm && event.status == Some(NodeState::Ready)
        })
    }

    /// The node events so far: faults and the status frames that say something ([`NodeEvent`]).
    #[must_use]
    pub fn events(&self) -> &[NodeEvent] {
        &self.events
    }

    /// The Distance frames received (a sensor on CAN), for the loop to bound the sensor's
    /// clock by their arrivals and to take the samples at the end.
    pub fn distances_mut(&mut self) -> &mut SampleLog {
        &mut self.distances
    }

    /// The counters so far.
    #[must_use]
    pub fn counters(&self) -> MirrorLinkCounters {
        self.counters
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn real_time_readings_are_placed_passed_over_when_late_or_implausible() {
        let mut inbox = HostInbox::new("test");
        let expected = 70_000; // counters wrap at 2^16
        let seq = |period: u64| period as u16;
        assert_eq!(
            inbox.place_reading(seq(expected), expected, 200),
            Some(expected)
        );
        // Three readings went missing: taken as the one three periods on.
        assert_eq!(
            inbox.place_reading(seq(expected + 3), expected, 200),
            Some(expected + 3)
        );
        // A duplicate or a delayed reading: passed over, never taken as 2^16 periods on.
        assert_eq!(inbox.place_reading(seq(expected - 1), expected, 200), None);
        // A counter far beyond what the node's watchdog allows: corrupted.
        assert_eq!(
            inbox.place_reading(seq(expected + 4096), expected, 200),
            None
        );
        let counters = inbox.counters();
        assert_eq!(counters.angle_readings, 4);
        assert_eq!(counters.angle_sequence_gaps, 1);
        assert_eq!(counters.late_readings, 1);
        assert_eq!(counters.implausible_readings, 1);
    }
}
