//! The host's lockstep loop as a state machine, free of I/O and clocks (as
//! `scanhil_emulator::serve::mirror_node` is for the node). It holds the controller, the
//! trajectory and the [`LoopRecord`]; a transport asks it for the [`HostAction`] to take,
//! sends the frames it gives (each stamped with its loop time), hands it the frames that
//! arrive and reports a link that failed or stayed silent.
//!
//! Per period k: the command from the newest angle reading, CoilCommand(k) and Step(k) at loop
//! time `k * Ta`, then AngleReading(k), awaited at loop time `(k + 1) * Ta`. A node's
//! LinkTimeout fault or a failed link stops the loop (zero current commanded, best effort);
//! after the last period the run ends with CoilCommand(0) and the controller's Status(ready)
//! at `periods * Ta`, and the node's Status(ready) (or its hang-up or silence) is the last
//! thing awaited: the node answers the end after it took the zero command, so its answer
//! acknowledges the coils at zero ([`CoilsAtEnd`]). The frames of a stop ([`HostAction::SendStop`])
//! never pass through injected faults.
//!
//! [`super::lockstep`] runs it over a real link; the `scanhil-lab` crate runs it in process.

use scanhil_protocol::can::CanFrame;
use scanhil_protocol::link::LinkError;
use scanhil_protocol::message::{
    Carried, CoilCommand, FaultKind, Message, NodeId, NodeState, Status, U24_MAX,
};
use scanhil_protocol::plant_units::{ActuatorPair, SensingPair};

use super::controller_timing::ControllerTiming;
use super::host_inbox::{HostInbox, plausible_angles};
use super::loop_error::LoopError;
use super::pairing::AngleTrack;
use super::power_backoff::{BackoffLog, PowerBackoff};
use super::tracking::TrackingRecorder;
pub use crate::link::CoilsAtEnd;
use crate::scan_controller::ScanController;
use crate::trajectory::Trajectory;

/// What a loop run produced. Its memory does not grow with the run's length, except for the
/// frame's angle history kept to pair sensor samples with ([`Self::keeping_angles`]; the
/// lead-in's readings are freed as the loop passes them).
#[derive(Debug)]
pub struct LoopRecord {
    /// The control period, s.
    pub period_s: f64,
    /// The angle readings, reading k at loop time `(k + 1) * period`; `None` when not kept
    /// (no sensor samples to pair them with).
    pub angles: Option<AngleTrack>,
    /// Reference against measurement.
    pub tracking: TrackingRecorder,
    /// Periods completed.
    pub periods_done: u64,
    /// Periods asked for: the lead-in's and the recorded frame's.
    pub periods_planned: u64,
    /// Periods of lead-in before the recorded frame ([`super::lead_in`]).
    pub lead_in_periods: u64,
    /// Periods in which the coil command was clipped.
    pub saturated_periods: u64,
    /// Of those, the ones in the lead-in.
    pub saturated_in_lead_in: u64,
    /// Why the run stopped early, if it did.
    pub stopped_by: Option<LoopError>,
    /// Real time only: the controller's side of the timing.
    pub controller_timing: Option<ControllerTiming>,
    /// Real time: loop time 0 on the wall clock (the earliest reading's arrival minus its
    /// loop time), where a real sensor's arrival bounds are placed
    /// ([`super::pairing::ArrivalBound::counter_zero_s`]). `None` in lockstep and in process.
    pub wall_clock_epoch: Option<tokio::time::Instant>,
    /// What the power back-off did (None: not active).
    pub power_backoff: Option<BackoffLog>,
    /// Step frames sent again because no reading came within one answer allowance.
    pub repeated_steps: u64,
    /// The zero command the run ended with, and whether the node acknowledged it.
    pub coils_at_end: CoilsAtEnd,
}

impl LoopRecord {
    /// An empty record for a loop of `periods` periods of `period_s`, keeping the angle history.
    #[must_use]
    pub fn new(period_s: f64, periods: u64) -> LoopRecord {
        LoopRecord {
            period_s,
            angles: Some(AngleTrack::new(period_s)),
            tracking: TrackingRecorder::new(period_s, periods, 0),
            periods_done: 0,
            periods_planned: periods,
            lead_in_periods: 0,
            saturated_periods: 0,
            saturated_in_lead_in: 0,
            stopped_by: None,
            controller_timing: None,
            wall_clock_epoch: None,
            power_backoff: None,
            repeated_steps: 0,
            coils_at_end: CoilsAtEnd::default(),
        }
    }

    /// The record of a loop whose first `lead_in_periods` periods are the lead-in (set before
    /// the first reading: the tracking figures split there as they are recorded).
    #[must_use]
    pub fn with_lead_in(mut self, lead_in_periods: u64) -> LoopRecord {
        debug_assert_eq!(
            self.tracking.periods(),
            0,
            "the lead-in is set before the run"
        );
        self.lead_in_periods = lead_in_periods;
        self.tracking = TrackingRecorder::new(self.period_s, self.periods_planned, lead_in_periods);
        self
    }

    /// The record keeping the angle history (`true`, the default: a run with sensor samples to
    /// pair) or not (`false`: memory flat in the run's length).
    #[must_use]
    pub fn keeping_angles(mut self, keep: bool) -> LoopRecord {
        self.angles = keep.then(|| AngleTrack::new(self.period_s));
        self
    }

    /// Periods in which the coil command was clipped during the recorded frame: none when the
    /// run stopped in its lead-in.
    #[must_use]
    pub fn saturated_in_frame(&self) -> u64 {
        if self.periods_done <= self.lead_in_periods {
            0
        } else {
            self.saturated_periods - self.saturated_in_lead_in
        }
    }

    /// Records reading `k` (the angles at loop time `(k + 1) * period`) against the reference
    /// at that instant.
    pub fn push_reading(&mut self, trajectory: &Trajectory, k: u64, angles: SensingPair) {
        let reference = trajectory.reference_rad((k + 1) as f64 * self.period_s);
        self.push_reading_against(reference, k, angles);
    }

    /// Records reading `k` against `reference`, the reference at loop time
    /// `(k + 1) * period` as the loop follows it (scaled by the power back-off).
    pub fn push_reading_against(&mut self, reference: SensingPair, k: u64, angles: SensingPair) {
        if let Some(track) = &mut self.angles {
            track.push(angles);
            // Samples are paired only from the frame's start on: the lead-in's readings go
            // as the loop passes them.
            track.release_before(self.lead_in_periods as f64 * self.period_s);
        }
        self.tracking.record(reference, angles);
        self.periods_done = k + 1;
    }
}

/// A message to send and the loop time its recording is stamped with, s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StampedMessage {
    /// The message (checked: its frame encodes), or a frame as it is.
    pub carried: Carried,
    /// Loop time, s.
    pub t_s: f64,
}

/// What the transport does next.
#[derive(Debug, Clone, PartialEq)]
pub enum HostAction {
    /// Send the period's CoilCommand and Step, in order; report a failure with
    /// [`HostLoop::on_error`].
    Send([StampedMessage; 2]),
    /// Send the frames of a stop (the zero command, the end of the run) in order, past any
    /// injected fault: they must reach the node as sent. A failure is reported like any.
    SendStop(Vec<StampedMessage>),
    /// Wait for AngleReading(`period`) within the watchdog's allowance; frames received
    /// meanwhile are stamped with loop time `t_s` and go to [`HostLoop::on_frame`].
    AwaitReading {
        /// The period whose reading is awaited.
        period: u64,
        /// Loop time of receptions, s.
        t_s: f64,
    },
    /// The run is ending: wait for the node's Status(ready) within the watchdog's allowance
    /// (its hang-up or silence end the run as well).
    AwaitNodeReady {
        /// Loop time of receptions, s.
        t_s: f64,
    },
    /// The run is over: [`HostLoop::finish`].
    Done,
}

/// What a received frame meant for the loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Heard {
    /// Nothing for the loop's progress (filed in the inbox).
    Nothing,
    /// The awaited reading of this period: the period is done.
    Reading(u64),
    /// The loop stops (a node's LinkTimeout fault).
    Stopped,
    /// The node's Status(ready) after the controller's: the run is over.
    Ended,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Period k's frames go out next.
    Start(u64),
    /// AngleReading(k) is awaited.
    Reading(u64),
    /// Stopped in period k: the zero command goes out next.
    Stopping(u64),
    /// The zero command and the controller's Status(ready) go out next.
    Closing,
    /// The node's Status(ready) is awaited.
    NodeReady,
    /// Over.
    Done,
}

/// The host's side of a lockstep run.
#[derive(Debug)]
pub struct HostLoop<'a> {
    controller: &'a mut ScanController,
    trajectory: &'a Trajectory,
    period_s: f64,
    inbox: HostInbox,
    record: LoopRecord,
    measured: SensingPair,
    phase: Phase,
    backoff: PowerBackoff,
    /// Answer allowances a reading may take, each after the first with its Step sent again.
    tries_per_reading: u32,
    /// Allowances used up waiting for the current reading.
    silent_tries: u32,
    /// The reference of a period, kept from its previous period's reading (which is recorded
    /// against it) for its command: each is computed once. The back-off cannot change between
    /// the two: a power-limit fault is taken only while a reading is awaited.
    next_reference: Option<(u64, SensingPair)>,
}

impl<'a> HostLoop<'a> {
    /// A run of `controller` along `trajectory` for the periods `record` plans (its lead-in
    /// and angle history as it is set up), filing what it receives into `inbox`.
    pub fn new(
        controller: &'a mut ScanController,
        trajectory: &'a Trajectory,
        record: LoopRecord,
        inbox: HostInbox,
    ) -> HostLoop<'a> {
        let period_s = controller.period_s();
        HostLoop {
            controller,
            trajectory,
            period_s,
            inbox,
            record,
            measured: SensingPair::default(),
            phase: Phase::Start(0),
            backoff: PowerBackoff::inactive(),
            tries_per_reading: 1,
            silent_tries: 0,
            next_reference: None,
        }
    }

    /// The same loop, waiting up to `tries` answer allowances for each reading and sending
    /// the period's Step again after each silent one ([`Self::on_silence`]); a reading with an
    /// implausible angle (`host_inbox::plausible_angles`) is then taken as corrupted and
    /// waited for again. 1 (the default) never repeats a Step and takes every reading.
    #[must_use]
    pub fn with_tries_per_reading(mut self, tries: u32) -> HostLoop<'a> {
        self.tries_per_reading = tries.max(1);
        self
    }

    /// No frame came within one answer allowance while a reading was awaited: returns the
    /// period's Step to send again (the node answers a repeated Step with the same reading),
    /// or `None` when the reading's tries are used up (the transport then reports the link
    /// timeout with [`Self::on_error`]).
    pub fn on_silence(&mut self) -> Option<StampedMessage> {
        let Phase::Reading(k) = self.phase else {
            return None;
        };
        self.silent_tries += 1;
        if self.silent_tries >= self.tries_per_reading {
            return None;
        }
        let frame = stamped(&Message::Step { step: k as u32 }, k as f64 * self.period_s).ok()?;
        self.record.repeated_steps += 1;
        Some(frame)
    }

    /// The same loop, backing off the reference when the node reports its power limit.
    #[must_use]
    pub fn with_backoff(mut self, backoff: PowerBackoff) -> HostLoop<'a> {
        self.backoff = backoff;
        self
    }

    /// What to do next. Frames returned in [`HostAction::Send`] count as sent.
    pub fn next_action(&mut self) -> HostAction {
        match self.phase {
            Phase::Start(k) if k >= self.record.periods_planned => {
                self.phase = Phase::Closing;
                self.next_action()
            }
            Phase::Start(k) => {
                if k == self.record.lead_in_periods {
                    self.record.saturated_in_lead_in = self.controller.saturated_periods();
                }
                let reference = match self.next_reference.take() {
                    Some((period, reference)) if period == k => reference,
                    _ => self.reference_at(k),
                };
                let command = self.controller.step(reference, self.measured);
                match period_frames(k, command, self.period_s) {
                    Ok(frames) => {
                        self.phase = Phase::Reading(k);
                        HostAction::Send(frames)
                    }
                    Err(error) => {
                        self.stop(k, error);
                        self.next_action()
                    }
                }
            }
            Phase::Reading(k) => HostAction::AwaitReading {
                period: k,
                t_s: (k + 1) as f64 * self.period_s,
            },
            Phase::Stopping(k) => {
                self.phase = Phase::Done;
                let t_s = (k + 1) as f64 * self.period_s;
                match coil_command_frame(k, ActuatorPair::default(), t_s) {
                    Ok(frame) => {
                        self.record.coils_at_end.zero_commanded = true;
                        HostAction::SendStop(vec![frame])
                    }
                    Err(_) => HostAction::Done,
                }
            }
            Phase::Closing => match stop_frames(self.record.periods_done, self.period_s) {
                Ok(frames) => {
                    self.phase = Phase::NodeReady;
                    self.record.coils_at_end.zero_commanded = true;
                    HostAction::SendStop(frames.to_vec())
                }
                Err(error) => {
                    self.record.stopped_by = Some(error);
                    self.phase = Phase::Done;
                    HostAction::Done
                }
            },
            Phase::NodeReady => HostAction::AwaitNodeReady {
                t_s: self.end_time_s(),
            },
            Phase::Done => HostAction::Done,
        }
    }

    /// A frame (or, in one process, a message) arrived at wall-clock `arrived` (kept with
    /// Distance frames).
    pub fn on_frame(&mut self, frame: impl Into<Carried>, arrived: tokio::time::Instant) -> Heard {
        let frame = frame.into();
        match self.phase {
            Phase::Reading(k) => {
                let t_s = (k + 1) as f64 * self.period_s;
                let events = self.inbox.events().len();
                let classified = self.inbox.classify(&frame, t_s, arrived);
                if self.inbox.events()[events..]
                    .iter()
                    .any(|event| event.fault == Some(FaultKind::PowerLimit))
                {
                    self.backoff.on_power_limit(k);
                }
                match classified {
                    Err(error) => {
                        self.stop(k, error);
                        Heard::Stopped
                    }
                    Ok(Some((seq, angles))) => {
                        if self.inbox.count_reading(seq, k) != 0 {
                            // Another period's reading: counted as a gap, still waiting.
                            return Heard::Nothing;
                        }
                        if self.tries_per_reading > 1 && !plausible_angles(angles) {
                            // Corrupted on the way: waited for again (the Step is repeated).
                            self.inbox.count_implausible();
                            return Heard::Nothing;
                        }
                        self.measured = angles;
                        let reference = self.reference_at(k + 1);
                        self.record.push_reading_against(reference, k, angles);
                        self.next_reference = Some((k + 1, reference));
                        self.phase = Phase::Start(k + 1);
                        self.silent_tries = 0;
                        Heard::Reading(k)
                    }
                    Ok(None) => Heard::Nothing,
                }
            }
            Phase::NodeReady => {
                let events = self.inbox.events().len();
                match self.inbox.classify(&frame, self.end_time_s(), arrived) {
                    Err(error) => {
                        self.record.stopped_by = Some(error);
                        self.phase = Phase::Done;
                        Heard::Stopped
                    }
                    Ok(_) if self.inbox.events().len() > events && self.inbox.node_ready_last() => {
                        self.phase = Phase::Done;
                        self.record.coils_at_end.acknowledged = true;
                        Heard::Ended
                    }
                    Ok(_) => Heard::Nothing,
                }
            }
            // Nothing is awaited: filed, but it changes nothing.
            Phase::Start(_) | Phase::Stopping(_) | Phase::Closing | Phase::Done => {
                let _ = self.inbox.classify(&frame, self.end_time_s(), arrived);
                Heard::Nothing
            }
        }
    }

    /// The link failed, or stayed silent for the watchdog's allowance
    /// ([`LoopError::LinkTimeout`]). While a reading is awaited the loop stops; at the end a
    /// hang-up or silence ends the run as planned (the scan is complete), anything else is
    /// recorded as what stopped it. A failed send of the stop's zero command is ignored.
    pub fn on_error(&mut self, error: LoopError) {
        match self.phase {
            Phase::Reading(k) => self.stop(k, error),
            Phase::NodeReady => {
                let quiet_end = matches!(
                    error,
                    LoopError::LinkTimeout { .. } | LoopError::Link(LinkError::HangUp { .. })
                );
                if !quiet_end {
                    self.record.stopped_by = Some(error);
                }
                self.phase = Phase::Done;
            }
            Phase::Start(_) | Phase::Stopping(_) | Phase::Closing | Phase::Done => {}
        }
    }

    /// The record so far.
    #[must_use]
    pub fn record(&self) -> &LoopRecord {
        &self.record
    }

    /// The newest angle reading taken (zero before the first).
    #[must_use]
    pub fn latest_reading(&self) -> SensingPair {
        self.measured
    }

    /// The inbox so far, to note on its Distance frames' log when a period starts
    /// ([`super::sample_log::SampleLog::period_started`]).
    pub fn inbox_mut(&mut self) -> &mut HostInbox {
        &mut self.inbox
    }

    /// The inbox so far.
    #[must_use]
    pub fn inbox(&self) -> &HostInbox {
        &self.inbox
    }

    /// Ends the run: the record (with the controller's saturated periods) and the inbox.
    #[must_use]
    pub fn finish(mut self) -> (LoopRecord, HostInbox) {
        self.record.saturated_periods = self.controller.saturated_periods();
        self.record.power_backoff = self.backoff.log();
        (self.record, self.inbox)
    }

    /// The reference of period `k` (at loop time `k * period`), scaled by the power back-off.
    fn reference_at(&self, k: u64) -> SensingPair {
        let scale = self.backoff.scale_at(k);
        let reference = self.trajectory.reference_rad(k as f64 * self.period_s);
        SensingPair {
            alpha: reference.alpha * scale,
            beta: reference.beta * scale,
        }
    }

    fn stop(&mut self, k: u64, error: LoopError) {
        self.record.stopped_by = Some(error);
        self.phase = Phase::Stopping(k);
    }

    /// Loop time of the run's end, s.
    fn end_time_s(&self) -> f64 {
        self.record.periods_done as f64 * self.period_s
    }
}

/// Lockstep period `k`'s frames: CoilCommand(k) and Step(k), at loop time `k * period_s`.
///
/// # Errors
/// [`LoopError::Encode`] when the command cannot be encoded.
pub fn period_frames(
    k: u64,
    command_a: ActuatorPair,
    period_s: f64,
) -> Result<[StampedMessage; 2], LoopError> {
    let t_s = k as f64 * period_s;
    Ok([
        coil_command_frame(k, command_a, t_s)?,
        stamped(&Message::Step { step: k as u32 }, t_s)?,
    ])
}

/// CoilCommand(seq = k mod 2^16) at loop time `t_s`.
///
/// # Errors
/// [`LoopError::Encode`] when the command cannot be encoded.
pub fn coil_command_frame(
    k: u64,
    command_a: ActuatorPair,
    t_s: f64,
) -> Result<StampedMessage, LoopError> {
    let command = Message::CoilCommand(CoilCommand::from_amps(k as u16, command_a));
    stamped(&command, t_s)
}

/// The end of a run after `periods_done` periods, at loop time `periods_done * period_s`:
/// CoilCommand(0) (its sequence counter the next period's) and the controller's Status(ready).
/// The node answers the Status after it took the command, so its Status(ready) acknowledges
/// the coils at zero.
///
/// # Errors
/// [`LoopError::Encode`] when a frame cannot be encoded.
pub fn stop_frames(periods_done: u64, period_s: f64) -> Result<[StampedMessage; 2], LoopError> {
    let t_s = periods_done as f64 * period_s;
    Ok([
        coil_command_frame(periods_done, ActuatorPair::default(), t_s)?,
        end_frame(periods_done, period_s)?,
    ])
}

/// The controller's Status(ready) after `periods_done` periods, at loop time
/// `periods_done * period_s`: the end of a run.
///
/// # Errors
/// [`LoopError::Encode`] when the status cannot be encoded.
fn end_frame(periods_done: u64, period_s: f64) -> Result<StampedMessage, LoopError> {
    let t_s = periods_done as f64 * period_s;
    let status = Message::Status(Status {
        node: NodeId::Controller,
        state: NodeState::Ready,
        step: (periods_done & u64::from(U24_MAX)) as u32,
        node_time_us: ((t_s * 1e6).round() as u64 & u64::from(U24_MAX)) as u32,
    });
    stamped(&status, t_s)
}

/// `message` to send at loop time `t_s`, its fields checked as encoding checks them.
fn stamped(message: &Message, t_s: f64) -> Result<StampedMessage, LoopError> {
    let carried =
        Carried::checked(*message).map_err(|error| LoopError::Encode(error.to_string()))?;
    Ok(StampedMessage { carried, t_s })
}

impl StampedMessage {
    /// The frame a link sends.
    ///
    /// # Errors
    /// [`LoopError::Encode`] when the message cannot be encoded (never for one [`HostLoop`] made: it was checked).
    pub fn frame(&self) -> Result<CanFrame, LoopError> {
        self.carried
            .frame()
            .map_err(|error| LoopError::Encode(error.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reading_is_recorded_against_the_reference_at_the_instant_it_was_taken() {
        let trajectory = Trajectory::Lissajous {
            alpha_hz: 52.0,
            beta_hz: 27.0,
            alpha_amplitude_rad: 0.01,
            beta_amplitude_rad: 0.005,
            relative_phase_rad: 0.0,
        };
        let period_s = 5e-5;
        let mut record = LoopRecord::new(period_s, 100);
        for k in 0..100 {
            let at_reading = trajectory.reference_rad((k + 1) as f64 * period_s);
            record.push_reading(&trajectory, k, at_reading);
        }
        let run = record.tracking.summary().whole_run;
        assert_eq!(record.periods_done, 100);
        assert_eq!((run.alpha.max_abs_urad, run.beta.max_abs_urad), (0.0, 0.0));
        assert!(run.alpha.reference_peak_urad > 1000.0, "{run:?}");
    }

    #[test]
    fn saturation_in_the_frame_counts_none_of_the_lead_ins_and_none_before_the_frame() {
        // A scan stopped in its lead-in once reported 21 saturated periods for a frame of 0.
        let mut record = LoopRecord::new(5e-5, 300).with_lead_in(100);
        record.periods_done = 100;
        record.saturated_periods = 21;
        assert_eq!(record.saturated_in_frame(), 0);
        record.periods_done = 150;
        record.saturated_in_lead_in = 21;
        record.saturated_periods = 30;
        assert_eq!(record.saturated_in_frame(), 9);
    }

    #[test]
    fn the_lead_ins_angle_readings_go_as_the_loop_passes_them() {
        let trajectory: Trajectory = serde_json::from_value(serde_json::json!({
            "kind": "lissajous", "alpha_hz": 52.0, "beta_hz": 27.0
        }))
        .expect("a trajectory");
        let period_s = 5e-5;
        let (lead_in, frame) = (300_000u64, 1000u64);
        let mut record = LoopRecord::new(period_s, lead_in + frame).with_lead_in(lead_in);
        for k in 0..lead_in + frame {
            let angle = k as f64 * 1e-9;
            record.push_reading(
                &trajectory,
                k,
                SensingPair {
                    alpha: angle,
                    beta: -angle,
                },
            );
        }
        let track = record.angles.as_ref().expect("angles kept by default");
        assert_eq!(track.len() as u64, lead_in + frame);
        let frame_start_s = lead_in as f64 * period_s;
        // Every reading the frame's samples need is there; the lead-in's early ones are gone.
        for t_s in [
            frame_start_s,
            frame_start_s + 0.7 * period_s,
            (lead_in + frame) as f64 * period_s,
        ] {
            assert!(track.at(t_s).is_some(), "{t_s}");
        }
        assert_eq!(
            track.at(frame_start_s).map(|a| a.alpha),
            Some((lead_in - 1) as f64 * 1e-9)
        );
        assert!(
            track.at(1.0).is_none(),
            "the lead-in's first readings are freed"
        );
    }
}
