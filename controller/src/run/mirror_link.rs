//! The controller's view of the mirror node: one exchange per period (coil command out, angle
//! reading back), the node's status and fault frames collected on the way, the watchdog, and
//! the Distance frames of a sensor that shares the mirror's CAN link.

use std::time::Duration;

use scanhil_protocol::can::CanFrame;
use scanhil_protocol::link::{ArrivalSource, CanLink, LinkError, VirtualClock};
use scanhil_protocol::plant_units::{ActuatorPair, SensingPair};

pub use super::host_inbox::{HostInbox, MirrorLinkCounters, NodeEvent};
use super::host_loop::{
    CoilsAtEnd, StampedMessage, coil_command_frame, period_frames, stop_frames,
};
use super::interrupt::Interrupt;
use super::link_faults::{InjectedFrameFaults, LinkFaults};
pub use super::loop_error::LoopError;
use super::sample_log::SampleLog;

/// How long the zero command and the channel's close may take on the way out of a stopped
/// run before they are given up (the node may have stopped reading its line).
pub const STOP_SEND_ALLOWANCE: Duration = Duration::from_millis(200);

/// The controller's end of the mirror node's link.
#[derive(Debug)]
pub struct MirrorLink {
    port: CanLink,
    clock: Option<VirtualClock>,
    period_s: f64,
    answer_allowance: Duration,
    watchdog_periods: u32,
    inbox: HostInbox,
    /// Injected frame faults between the loop and the link (lockstep).
    faults: Option<LinkFaults>,
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
        let inbox = HostInbox::new(port.name());
        MirrorLink {
            port,
            clock,
            period_s,
            answer_allowance,
            watchdog_periods: watchdog_periods.max(1),
            inbox,
            faults: None,
        }
    }

    /// Injects `faults` between the loop and the link from now on: what the host sends passes
    /// them on its way to the node, what the node sends on its way to the loop. The link's
    /// recording holds the node's side: the frames as the node received and sent them.
    pub fn set_faults(&mut self, faults: LinkFaults) {
        self.faults = Some(faults);
    }

    /// What the injected frame faults did (`None`: none were injected).
    #[must_use]
    pub fn fault_report(&self) -> Option<InjectedFrameFaults> {
        self.faults.as_ref().map(LinkFaults::report)
    }

    /// The watchdog's periods.
    #[must_use]
    pub fn watchdog_periods(&self) -> u32 {
        self.watchdog_periods
    }

    /// The wall-clock allowance for one answer.
    #[must_use]
    pub fn answer_allowance(&self) -> Duration {
        self.answer_allowance
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
        self.send_period(k, &period_frames(k, command_a, self.period_s)?)
            .await?;
        self.await_reading(k, (k + 1) as f64 * self.period_s).await
    }

    /// Conformance: lockstep period `k` as [`Self::exchange_lockstep`], but takes the first
    /// AngleReading not older than period `k` whatever its counter, waiting at most `wait`.
    /// Returns the counter's offset from `k` (0: in sequence; anything else is counted as a
    /// gap) and the angles. Older readings (late answers to earlier periods) are counted and
    /// skipped.
    ///
    /// # Errors
    /// As [`Self::exchange_lockstep`]; the timeout after `wait`.
    pub async fn exchange_lockstep_any_counter(
        &mut self,
        k: u64,
        command_a: ActuatorPair,
        wait: Duration,
    ) -> Result<(u16, SensingPair), LoopError> {
        self.send_period(k, &period_frames(k, command_a, self.period_s)?)
            .await?;
        let t_s = (k + 1) as f64 * self.period_s;
        self.await_reading_where(k, t_s, wait, |offset| offset.cast_signed() >= 0)
            .await
    }

    /// Real time: waits for the next AngleReading the clock master sends; returns its period
    /// (unwrapped against `expected`) and angles. Late readings and corrupted counters are
    /// passed over ([`HostInbox::place_reading`]).
    ///
    /// # Errors
    /// [`LoopError`] as for [`Self::exchange_lockstep`].
    pub async fn next_reading(&mut self, expected: u64) -> Result<(u64, SensingPair), LoopError> {
        self.next_reading_within(expected, self.total_allowance())
            .await
    }

    /// [`Self::next_reading`], waiting at most `allowance` (conformance waits past the
    /// watchdog's allowance to tell a late reading from a lost one).
    ///
    /// # Errors
    /// As [`Self::next_reading`]; the timeout after `allowance`.
    pub async fn next_reading_within(
        &mut self,
        expected: u64,
        allowance: Duration,
    ) -> Result<(u64, SensingPair), LoopError> {
        let t_s = (expected + 1) as f64 * self.period_s;
        let deadline = tokio::time::Instant::now() + allowance;
        loop {
            let frame = tokio::time::timeout_at(deadline, self.recv_at(t_s))
                .await
                .map_err(|_| self.timeout(expected, allowance))??;
            if let Some(reading) = self.place(&frame, t_s, expected)? {
                return Ok(reading);
            }
        }
    }

    /// Real time, busy-polling: the next AngleReading if one is already there (other frames
    /// on the way are filed), without waiting; its period (unwrapped against `expected`) and
    /// angles.
    ///
    /// # Errors
    /// [`LoopError`] as for [`Self::exchange_lockstep`], but no timeout (the caller keeps time).
    pub fn try_reading(&mut self, expected: u64) -> Result<Option<(u64, SensingPair)>, LoopError> {
        let t_s = (expected + 1) as f64 * self.period_s;
        while let Some(frame) = self.try_recv_at(t_s)? {
            if let Some(reading) = self.place(&frame, t_s, expected)? {
                return Ok(Some(reading));
            }
        }
        Ok(None)
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
            let carried = scanhil_protocol::message::Carried::Frame(frame);
            self.send_period(k, &[StampedMessage { carried, t_s }])
                .await?;
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
            let frame = match tokio::time::timeout_at(deadline, self.recv_at(0.0)).await {
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

    /// After a failure: answers period `k` with zero current, best effort (the link may be
    /// gone, or full because the node stopped reading), past any injected fault
    /// ([`Self::send_stop`]). Returns whether it went out.
    pub async fn command_zero(&mut self, k: u64) -> bool {
        let zero = coil_command_frame(k, ActuatorPair::default(), (k + 1) as f64 * self.period_s);
        match zero {
            Ok(frame) => self.send_stop(k, &[frame]).await.is_ok(),
            Err(_) => false,
        }
    }

    /// Ends a session of `periods` periods with the node still answering (a complete scan, an
    /// identification, a conformance run): [`Self::send_end`], then [`Self::await_end`].
    pub async fn end_session(&mut self, periods: u64) -> CoilsAtEnd {
        let zero_commanded = self.send_end(periods).await.is_ok();
        CoilsAtEnd {
            zero_commanded,
            acknowledged: zero_commanded && self.await_end(periods).await,
        }
    }

    /// The end of a session of `periods` periods: CoilCommand(0) and the controller's
    /// Status(ready) ([`stop_frames`]), past any injected fault ([`Self::send_stop`]).
    ///
    /// # Errors
    /// As [`Self::send_stop`].
    pub async fn send_end(&mut self, periods: u64) -> Result<(), LoopError> {
        let frames = stop_frames(periods, self.period_s)?;
        self.send_stop(periods, &frames).await
    }

    /// After [`Self::send_end`]: waits up to the watchdog's allowance for the node's
    /// Status(ready), which it sends after it took the zero command; true when it came (the
    /// frames on the way are filed as usual).
    pub async fn await_end(&mut self, periods: u64) -> bool {
        let t_s = periods as f64 * self.period_s;
        let deadline = tokio::time::Instant::now() + self.total_allowance();
        while let Ok(Ok(frame)) = tokio::time::timeout_at(deadline, self.recv_at(t_s)).await {
            let events = self.inbox.events().len();
            let _ = self.classify(&frame, t_s);
            if self.inbox.events().len() > events && self.inbox.node_ready_last() {
                return true;
            }
        }
        false
    }

    /// Sends the frames of a stop (the zero command, the end of the run) past any injected
    /// fault, so they reach the node as sent, within [`STOP_SEND_ALLOWANCE`]: a stopping
    /// loop's frames get the stop's allowance, not the watchdog's.
    ///
    /// # Errors
    /// [`LoopError::SendTimeout`], link errors.
    pub async fn send_stop(
        &mut self,
        period: u64,
        frames: &[StampedMessage],
    ) -> Result<(), LoopError> {
        let deadline = tokio::time::Instant::now() + STOP_SEND_ALLOWANCE;
        self.send_until(period, frames, deadline, false).await
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

    /// When the frame received last was on the bus, as the kernel (SocketCAN) or the adapter
    /// (SLCAN with timestamps) stamped it; without a stamp, now (the loop takes a frame as
    /// soon as it is read, and frames read in one chunk share their read time).
    #[must_use]
    pub fn last_arrival(&self) -> tokio::time::Instant {
        match self.port.last_arrival() {
            Some(arrival) if arrival.source != ArrivalSource::Read => arrival.on_bus_at,
            _ => tokio::time::Instant::now(),
        }
    }

    /// The node events so far (see [`NodeEvent`]: faults and changes of state).
    #[must_use]
    pub fn events(&self) -> &[NodeEvent] {
        self.inbox.events()
    }

    /// The Distance frames received on this link (a sensor on CAN).
    pub fn distances_mut(&mut self) -> &mut SampleLog {
        self.inbox.distances_mut()
    }

    /// The link's counters.
    #[must_use]
    pub fn counters(&self) -> MirrorLinkCounters {
        MirrorLinkCounters {
            bus_error_frames: self.port.stats().bus_error_frames,
            ..self.inbox.counters()
        }
    }

    /// Hands the inbox to a loop that files the frames itself ([`super::host_loop::HostLoop`]);
    /// [`Self::restore_inbox`] gives it back.
    pub fn take_inbox(&mut self) -> HostInbox {
        std::mem::replace(&mut self.inbox, HostInbox::new(self.port.name()))
    }

    /// Puts back the inbox [`Self::take_inbox`] handed out.
    pub fn restore_inbox(&mut self, inbox: HostInbox) {
        self.inbox = inbox;
    }

    /// Sends period `period`'s frames with one write (SLCAN), each recorded stamped with its
    /// loop time; declared frame faults act on them on the way out. A node that stopped
    /// reading fills the line: the send is given up after the watchdog's allowance.
    ///
    /// # Errors
    /// [`LoopError::SendTimeout`], link errors.
    pub async fn send_period(
        &mut self,
        period: u64,
        frames: &[StampedMessage],
    ) -> Result<(), LoopError> {
        let deadline = tokio::time::Instant::now() + self.total_allowance();
        self.send_until(period, frames, deadline, true).await
    }

    /// [`Self::send_period`], giving up at `deadline` or when a stopping signal comes: a full
    /// line never holds the loop past its watchdog or a Ctrl-C.
    ///
    /// # Errors
    /// [`LoopError::SendTimeout`], [`LoopError::Interrupted`], link errors.
    pub async fn send_within(
        &mut self,
        period: u64,
        frames: &[StampedMessage],
        deadline: tokio::time::Instant,
        interrupt: &mut Interrupt,
    ) -> Result<(), LoopError> {
        tokio::select! {
            sent = self.send_until(period, frames, deadline, true) => sent,
            signal = interrupt.recv() => Err(LoopError::Interrupted { signal }),
        }
    }

    /// Sends `frames` (through the declared faults when `faulted`), or
    /// [`LoopError::SendTimeout`] when they are not out by `deadline`.
    async fn send_until(
        &mut self,
        period: u64,
        frames: &[StampedMessage],
        deadline: tokio::time::Instant,
        faulted: bool,
    ) -> Result<(), LoopError> {
        let started = tokio::time::Instant::now();
        match tokio::time::timeout_at(deadline, self.write_frames(frames, faulted)).await {
            Ok(sent) => sent,
            Err(_elapsed) => Err(LoopError::SendTimeout {
                link: self.port.name().to_owned(),
                period,
                waited: started.elapsed(),
            }),
        }
    }

    /// Queues each frame (through the declared faults when `faulted`) and writes them with
    /// one flush.
    async fn write_frames(
        &mut self,
        frames: &[StampedMessage],
        faulted: bool,
    ) -> Result<(), LoopError> {
        for stamped in frames {
            self.at(stamped.t_s);
            let frame = stamped.frame()?;
            match self.faults.as_mut().filter(|_| faulted) {
                None => self.port.queue(&frame).await?,
                Some(faults) => {
                    let passed: Vec<CanFrame> = faults.outgoing(&frame, stamped.t_s).collect();
                    for frame in &passed {
                        self.port.queue(frame).await?;
                    }
                }
            }
        }
        self.port.flush().await?;
        Ok(())
    }

    /// Waits for the next frame, its recording stamped with loop time `t_s` (lockstep).
    /// Cancel-safe.
    ///
    /// # Errors
    /// Link errors ([`LinkError::HangUp`] when the node went away).
    pub async fn recv_at(&mut self, t_s: f64) -> Result<CanFrame, LinkError> {
        self.at(t_s);
        let Some(faults) = &mut self.faults else {
            return self.port.recv().await;
        };
        loop {
            if let Some(frame) = faults.next_incoming(t_s) {
                return Ok(frame);
            }
            // Cancel-safe: the link's receive is, and a received frame is filed at once.
            let frame = self.port.recv().await?;
            faults.incoming(&frame, t_s);
        }
    }

    /// [`Self::recv_at`] without waiting: the next frame if one is there (through the
    /// declared faults, as `recv_at`).
    ///
    /// # Errors
    /// Link errors.
    fn try_recv_at(&mut self, t_s: f64) -> Result<Option<CanFrame>, LinkError> {
        self.at(t_s);
        let Some(faults) = &mut self.faults else {
            return self.port.try_recv();
        };
        loop {
            if let Some(frame) = faults.next_incoming(t_s) {
                return Ok(Some(frame));
            }
            match self.port.try_recv()? {
                Some(frame) => faults.incoming(&frame, t_s),
                None => return Ok(None),
            }
        }
    }

    /// The watchdog's whole allowance: its periods times the allowance per answer.
    #[must_use]
    pub fn total_allowance(&self) -> Duration {
        self.answer_allowance.saturating_mul(self.watchdog_periods)
    }

    /// The error for no answer about `period` within `waited`.
    #[must_use]
    pub fn timeout(&self, period: u64, waited: Duration) -> LoopError {
        LoopError::LinkTimeout {
            link: self.port.name().to_owned(),
            period,
            periods: self.watchdog_periods,
            waited,
        }
    }

    /// The control period, s.
    #[must_use]
    pub fn period_s(&self) -> f64 {
        self.period_s
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

    async fn await_reading(&mut self, k: u64, t_s: f64) -> Result<SensingPair, LoopError> {
        let allowance = self.total_allowance();
        let (_, angles) = self
            .await_reading_where(k, t_s, allowance, |offset| offset == 0)
            .await?;
        Ok(angles)
    }

    /// Waits at most `wait` for an AngleReading whose counter's offset from period `k` is
    /// `accept`ed; every reading on the way is counted.
    async fn await_reading_where(
        &mut self,
        k: u64,
        t_s: f64,
        wait: Duration,
        accept: impl Fn(u16) -> bool,
    ) -> Result<(u16, SensingPair), LoopError> {
        let deadline = tokio::time::Instant::now() + wait;
        loop {
            let frame = tokio::time::timeout_at(deadline, self.recv_at(t_s))
                .await
                .map_err(|_| self.timeout(k, wait))??;
            if let Some((seq, angles)) = self.classify(&frame, t_s)? {
                let offset = self.inbox.count_reading(seq, k);
                if accept(offset) {
                    return Ok((offset, angles));
                }
            }
        }
    }

    /// Real time: files a received frame; the period and angles of a reading the loop takes.
    fn place(
        &mut self,
        frame: &CanFrame,
        t_s: f64,
        expected: u64,
    ) -> Result<Option<(u64, SensingPair)>, LoopError> {
        let Some((seq, angles)) = self.classify(frame, t_s)? else {
            return Ok(None);
        };
        let max_ahead = u64::from(self.watchdog_periods);
        Ok(self
            .inbox
            .place_reading(seq, expected, max_ahead)
            .map(|period| (period, angles)))
    }

    /// Files a received frame at loop time `t_s` (see [`HostInbox::classify`]), with its
    /// arrival on the bus as the link knows it.
    fn classify(
        &mut self,
        frame: &CanFrame,
        t_s: f64,
    ) -> Result<Option<(u16, SensingPair)>, LoopError> {
        let arrived = self.last_arrival();
        self.inbox.classify(&frame.into(), t_s, arrived)
    }
}
