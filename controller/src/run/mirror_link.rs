//! The controller's view of the mirror node: one exchange per period (coil command out, angle
//! reading back), the node's status and fault frames collected on the way, the watchdog, and
//! the Distance frames of a sensor that shares the mirror's CAN link.

use std::time::Duration;

use scanhil_protocol::can::CanFrame;
use scanhil_protocol::ild::IldValue;
use scanhil_protocol::link::{CanLink, LinkError, VirtualClock};
use scanhil_protocol::message::{
    CoilCommand, FaultKind, Message, MessageError, NodeId, NodeState, Status, U24_MAX,
};
use scanhil_protocol::plant_units::{ActuatorPair, SensingPair};

/// Why the loop stopped early.
#[derive(Debug, thiserror::Error)]
pub enum LoopError {
    /// No answer within the watchdog's allowance.
    #[error(
        "link timeout on {link}: no angle reading for period {period} within {waited:?} ({periods} periods' allowance)"
    )]
    LinkTimeout {
        /// The link.
        link: String,
        /// The period waited for.
        period: u64,
        /// The watchdog's periods.
        periods: u32,
        /// The wall-clock time waited.
        waited: Duration,
    },
    /// A node reported a fault that ends the run (its own link timeout).
    #[error("{link}: the {node:?} node reported {kind:?} at step {step} (mod 2^16)")]
    NodeFault {
        /// The link.
        link: String,
        /// The node.
        node: NodeId,
        /// The fault.
        kind: FaultKind,
        /// Its step counter.
        step: u16,
    },
    /// A message could not be encoded.
    #[error("cannot encode a frame: {0}")]
    Encode(String),
    /// The transport failed (hang-up: the emulator or adapter went away).
    #[error(transparent)]
    Link(#[from] LinkError),
}

/// A status or fault frame the node sent, with the loop time it was received at.
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
    /// Angle readings whose sequence counter was not the one waited for (skipped or stale).
    pub angle_sequence_gaps: u64,
    /// Frames with a loop id and a malformed payload.
    pub malformed_frames: u64,
    /// Frames with ids that are not loop messages (other traffic).
    pub foreign_frames: u64,
}

/// The controller's end of the mirror node's link.
#[derive(Debug)]
pub struct MirrorLink {
    port: CanLink,
    clock: Option<VirtualClock>,
    period_s: f64,
    answer_allowance: Duration,
    watchdog_periods: u32,
    events: Vec<NodeEvent>,
    distances: Vec<(u32, IldValue, tokio::time::Instant)>,
    counters: MirrorLinkCounters,
}

impl MirrorLink {
    /// Wraps an open host-side link. The watchdog allows `watchdog_periods` missed answers
    /// of `answer_allowance` wall-clock time each. With `clock`, the link's capture is stamped
    /// with loop time (lockstep), which this sets before every frame.
    #[must_use]
    pub fn new(
        port: CanLink,
        clock: Option<VirtualClock>,
        period_s: f64,
        answer_allowance: Duration,
        watchdog_periods: u32,
    ) -> MirrorLink {
        MirrorLink {
            port,
            clock,
            period_s,
            answer_allowance,
            watchdog_periods: watchdog_periods.max(1),
            events: Vec::new(),
            distances: Vec::new(),
            counters: MirrorLinkCounters::default(),
        }
    }

    /// Lockstep period `k`: sends CoilCommand(k) and Step(k), waits for AngleReading(k).
    ///
    /// # Errors
    /// [`LoopError`]: the watchdog fired, the node faulted with a link timeout, the link failed.
    pub async fn exchange_lockstep(
        &mut self,
        k: u64,
        command_a: ActuatorPair,
    ) -> Result<SensingPair, LoopError> {
        let t_send = k as f64 * self.period_s;
        let command = Message::CoilCommand(CoilCommand::from_amps(k as u16, command_a));
        self.send(&command, t_send).await?;
        self.send(&Message::Step { step: k as u32 }, t_send).await?;
        self.await_reading(k, (k + 1) as f64 * self.period_s).await
    }

    /// Lockstep, after the last period: tells the node the run is over (the controller's
    /// Status(ready) at loop time `periods_done * period`) and collects what the node sent after
    /// the last reading (the sensor's samples of the last period), up to the node's own
    /// Status(ready), its last frame. On a bus the node sees no hang-up: this is how it learns
    /// to finish. A node that hangs up instead, or does not answer within the watchdog's
    /// allowance (a device without this exchange), ends it too: the scan itself is complete.
    ///
    /// # Errors
    /// Link errors other than the hang-up.
    pub async fn end_lockstep(&mut self, periods_done: u64) -> Result<(), LoopError> {
        let t_s = periods_done as f64 * self.period_s;
        let status = Message::Status(Status {
            node: NodeId::Controller,
            state: NodeState::Ready,
            step: (periods_done & u64::from(U24_MAX)) as u32,
            node_time_us: ((t_s * 1e6).round() as u64 & u64::from(U24_MAX)) as u32,
        });
        self.send(&status, t_s).await?;
        let deadline = tokio::time::Instant::now() + self.total_allowance();
        loop {
            let frame = match tokio::time::timeout_at(deadline, self.recv(t_s)).await {
                Err(_) | Ok(Err(LinkError::HangUp { .. })) => return Ok(()),
                Ok(frame) => frame?,
            };
            let events = self.events.len();
            self.classify(&frame, t_s)?;
            let node_ready = self.events.len() > events
                && self.events.last().is_some_and(|event| {
                    event.node == NodeId::Fsm && event.status == Some(NodeState::Ready)
                });
            if node_ready {
                return Ok(());
            }
        }
    }

    /// Real time: waits for the next AngleReading the clock master sends; returns its period
    /// (unwrapped against `expected`) and angles.
    ///
    /// # Errors
    /// [`LoopError`] as for [`Self::exchange_lockstep`].
    pub async fn next_reading(&mut self, expected: u64) -> Result<(u64, SensingPair), LoopError> {
        let t_s = (expected + 1) as f64 * self.period_s;
        let allowance = self.total_allowance();
        let deadline = tokio::time::Instant::now() + allowance;
        loop {
            let frame = tokio::time::timeout_at(deadline, self.recv(t_s))
                .await
                .map_err(|_| self.timeout(expected, allowance))??;
            if let Some((seq, angles)) = self.classify(&frame, t_s)? {
                self.counters.angle_readings += 1;
                let offset = seq.wrapping_sub(expected as u16);
                if offset != 0 {
                    self.counters.angle_sequence_gaps += 1;
                }
                return Ok((expected + u64::from(offset), angles));
            }
        }
    }

    /// Real time: answers period `k` with its coil command.
    ///
    /// # Errors
    /// Link errors.
    pub async fn send_command(&mut self, k: u64, command_a: ActuatorPair) -> Result<(), LoopError> {
        let command = Message::CoilCommand(CoilCommand::from_amps(k as u16, command_a));
        self.send(&command, (k + 1) as f64 * self.period_s).await?;
        Ok(())
    }

    /// Sends malformed input for period `k`: a Step and a CoilCommand with short payloads.
    /// Returns what was sent.
    ///
    /// # Errors
    /// Link errors.
    pub async fn send_malformed(&mut self, k: u64) -> Result<String, LoopError> {
        use scanhil_protocol::can::CanId;
        use scanhil_protocol::message::ids as id;
        let t_s = k as f64 * self.period_s;
        let mut sent = Vec::new();
        for (raw_id, name) in [(id::STEP, "Step"), (id::COIL_COMMAND, "CoilCommand")] {
            let frame = CanId::standard(raw_id)
                .and_then(|can_id| CanFrame::new(can_id, &[0xFF, 0xFF]).ok())
                .expect("a 2-byte classical frame with an 11-bit id");
            self.at(t_s);
            self.port.send(&frame).await?;
            sent.push(format!("{name} with 2 data bytes"));
        }
        Ok(sent.join(", "))
    }

    /// Stays silent and waits for the node's LinkTimeout fault (twice the watchdog's
    /// allowance at most). Returns what was seen.
    ///
    /// # Errors
    /// [`LoopError::LinkTimeout`] when no such fault came; link errors.
    pub async fn await_link_timeout_fault(&mut self) -> Result<String, LoopError> {
        let allowance = self.total_allowance().saturating_mul(2);
        let started = tokio::time::Instant::now();
        let deadline = started + allowance;
        loop {
            let frame = match tokio::time::timeout_at(deadline, self.recv(0.0)).await {
                Err(_) => return Err(self.timeout(0, allowance)),
                Ok(Err(LinkError::HangUp { .. })) => {
                    return Err(LoopError::Link(LinkError::Protocol {
                        link: self.port.name().to_owned(),
                        detail: "the node hung up without a LinkTimeout fault".into(),
                    }));
                }
                Ok(frame) => frame?,
            };
            if let Err(LoopError::NodeFault { kind, step, .. }) = self.classify(&frame, 0.0) {
                return Ok(format!(
                    "{kind:?} fault after {:?} of silence (node step {step})",
                    started.elapsed()
                ));
            }
        }
    }

    /// After a failure: commands zero current (best effort; the link may be gone).
    pub async fn command_zero(&mut self, k: u64) {
        let _ = self.send_command(k, ActuatorPair::default()).await;
    }

    /// At the end of a session (normal end or error path): closes the link's SLCAN channel
    /// (`C`), waiting a bounded time for the adapter's answer; see `CanLink::close`.
    ///
    /// # Errors
    /// The adapter's silence or a line error (a peer that is gone).
    pub async fn close(&mut self) -> Result<(), LinkError> {
        self.port.close().await
    }

    /// The CAN link itself, for conformance checks that go below the loop's messages.
    pub fn can_link_mut(&mut self) -> &mut CanLink {
        &mut self.port
    }

    /// Status and fault frames received so far.
    #[must_use]
    pub fn events(&self) -> &[NodeEvent] {
        &self.events
    }

    /// Distance frames received on this link (a sensor on CAN), in order, with their arrival.
    pub fn take_distances(&mut self) -> Vec<(u32, IldValue, tokio::time::Instant)> {
        std::mem::take(&mut self.distances)
    }

    /// The link's counters.
    #[must_use]
    pub fn counters(&self) -> MirrorLinkCounters {
        self.counters
    }

    /// The link's name.
    #[must_use]
    pub fn name(&self) -> &str {
        self.port.name()
    }

    /// Sets the loop time the next recorded frames are stamped with (lockstep).
    fn at(&self, t_s: f64) {
        if let Some(clock) = &self.clock {
            clock.set(Duration::from_secs_f64(t_s));
        }
    }

    async fn send(&mut self, message: &Message, t_s: f64) -> Result<(), LoopError> {
        let frame = message
            .encode()
            .map_err(|error| LoopError::Encode(error.to_string()))?;
        self.at(t_s);
        self.port.send(&frame).await?;
        Ok(())
    }

    async fn recv(&mut self, t_s: f64) -> Result<CanFrame, LinkError> {
        self.at(t_s);
        self.port.recv().await
    }

    fn total_allowance(&self) -> Duration {
        self.answer_allowance.saturating_mul(self.watchdog_periods)
    }

    fn timeout(&self, period: u64, waited: Duration) -> LoopError {
        LoopError::LinkTimeout {
            link: self.port.name().to_owned(),
            period,
            periods: self.watchdog_periods,
            waited,
        }
    }

    async fn await_reading(&mut self, k: u64, t_s: f64) -> Result<SensingPair, LoopError> {
        let allowance = self.total_allowance();
        let deadline = tokio::time::Instant::now() + allowance;
        loop {
            let frame = tokio::time::timeout_at(deadline, self.recv(t_s))
                .await
                .map_err(|_| self.timeout(k, allowance))??;
            if let Some((seq, angles)) = self.classify(&frame, t_s)? {
                self.counters.angle_readings += 1;
                if seq == k as u16 {
                    return Ok(angles);
                }
                self.counters.angle_sequence_gaps += 1;
            }
        }
    }

    /// Files a received frame; returns an angle reading's sequence counter and angles.
    fn classify(
        &mut self,
        frame: &CanFrame,
        t_s: f64,
    ) -> Result<Option<(u16, SensingPair)>, LoopError> {
        let message = match Message::decode(frame) {
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
                let now = tokio::time::Instant::now();
                self.distances.push((distance.counter, distance.value, now));
            }
            Message::AnglesDistanceFd { angles, distance } => {
                let now = tokio::time::Instant::now();
                self.distances.push((distance.counter, distance.value, now));
                return Ok(Some((angles.seq, angles.rad())));
            }
            Message::Status(status) if status.node != NodeId::Controller => {
                self.events.push(NodeEvent {
                    t_s,
                    node: status.node,
                    status: Some(status.state),
                    fault: None,
                    step: status.step,
                });
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
                        link: self.port.name().to_owned(),
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
}
