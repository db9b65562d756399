//! Injected faults on a stream of CAN frames: a pure, deterministic model of a bad wire, free
//! of I/O and clocks. One [`FrameInjector`] per direction (host to node, node to host) takes
//! each frame the sender sends, with the loop period it belongs to, and gives back what the
//! receiver gets: the frame, nothing (dropped), the frame twice (duplicated), the frame after
//! the next one (reordered), the frame some periods later (delayed), or the frame with one bit
//! flipped. Faults come at a rate (a seeded generator rolls for every frame: the same seed
//! gives the same faults) or at listed periods. The two-process scan and the in-process loop
//! both run it, and every frame is accounted for ([`FrameLedger`]). [`SensorFaults`] declares
//! the sensor losing its peak; the emulator's sensor applies it.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::can::{CanFrame, CanId, FrameFormat};
use crate::message::spec::{Sender, message_spec};

/// The kinds of fault a frame can suffer on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrameFault {
    /// The frame never arrives.
    Drop,
    /// The frame arrives `delay_periods` periods late.
    Delay,
    /// The frame arrives twice.
    Duplicate,
    /// The frame arrives after the next frame in the same direction.
    Reorder,
    /// One bit of the frame (of its payload; of its identifier when it has none) is inverted.
    BitFlip,
}

/// The most fault events a direction keeps in its log (the counts go on; memory stays flat).
pub const MAX_LOGGED_FAULTS: usize = 256;

/// The longest delay a direction may ask for, periods.
pub const MAX_DELAY_PERIODS: u32 = 10_000;

/// A fault at a listed period: the first frame of that period in this direction (of message
/// `message` when given, by its DBC name) suffers `fault`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FaultAt {
    /// The loop period.
    pub period: u64,
    /// What happens to the frame.
    pub fault: FrameFault,
    /// Only a frame of this message (its DBC name, such as `Step` or `AngleReading`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub message: Option<String>,
}

/// The faults of one direction: a rate per kind (each frame suffers at most one fault) and
/// faults at listed periods.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DirectionFaults {
    /// Probability that a frame is dropped.
    pub drop_rate: f64,
    /// Probability that a frame is delayed by `delay_periods`.
    pub delay_rate: f64,
    /// Periods a delayed frame is held (1 to [`MAX_DELAY_PERIODS`]; default 1).
    pub delay_periods: Option<u32>,
    /// Probability that a frame is duplicated.
    pub duplicate_rate: f64,
    /// Probability that a frame swaps places with the next one.
    pub reorder_rate: f64,
    /// Probability that a frame has one bit flipped.
    pub bit_flip_rate: f64,
    /// Faults at listed periods.
    pub at: Vec<FaultAt>,
}

/// A fault declaration that cannot run: the field (as a dotted path below the direction) and
/// why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("field `{field}`: {reason}")]
pub struct FaultConfigError {
    /// The offending field, such as `drop_rate` or `at[2].message`.
    pub field: String,
    /// Why it cannot run.
    pub reason: String,
}

impl DirectionFaults {
    /// Whether any fault is declared.
    #[must_use]
    pub fn is_active(&self) -> bool {
        self.total_rate() > 0.0 || !self.at.is_empty()
    }

    /// Periods a delayed frame is held.
    #[must_use]
    pub fn delay_periods(&self) -> u32 {
        self.delay_periods.unwrap_or(1)
    }

    fn rates(&self) -> [(&'static str, f64, FrameFault); 5] {
        [
            ("drop_rate", self.drop_rate, FrameFault::Drop),
            ("delay_rate", self.delay_rate, FrameFault::Delay),
            ("duplicate_rate", self.duplicate_rate, FrameFault::Duplicate),
            ("reorder_rate", self.reorder_rate, FrameFault::Reorder),
            ("bit_flip_rate", self.bit_flip_rate, FrameFault::BitFlip),
        ]
    }

    fn total_rate(&self) -> f64 {
        self.rates().iter().map(|(_, rate, _)| rate).sum()
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`FaultConfigError`] naming the field: a rate outside `[0, 1]` (or rates summing past
    /// 1), a delay outside 1 to [`MAX_DELAY_PERIODS`], a listed fault naming an unknown
    /// message.
    pub fn check(&self) -> Result<(), FaultConfigError> {
        let invalid = |field: String, reason: String| Err(FaultConfigError { field, reason });
        for (field, rate, _) in self.rates() {
            if !(rate.is_finite() && (0.0..=1.0).contains(&rate)) {
                return invalid(field.into(), format!("{rate} must be within 0 and 1"));
            }
        }
        let total = self.total_rate();
        if total > 1.0 {
            return invalid(
                "drop_rate".into(),
                format!("the rates add up to {total}, more than 1 (a frame suffers one fault)"),
            );
        }
        let delay = self.delay_periods();
        if !(1..=MAX_DELAY_PERIODS).contains(&delay) {
            return invalid(
                "delay_periods".into(),
                format!("{delay} must be within 1 and {MAX_DELAY_PERIODS}"),
            );
        }
        for (index, at) in self.at.iter().enumerate() {
            if let Some(name) = &at.message
                && message_id(name).is_none()
            {
                return invalid(
                    format!("at[{index}].message"),
                    format!("`{name}` is not a message of the set (its DBC name, such as `Step`)"),
                );
            }
        }
        Ok(())
    }

    /// Checks that each listed fault's message is one that `senders` send: a fault on a
    /// message that never travels in this direction could never fire.
    ///
    /// # Errors
    /// [`FaultConfigError`] naming `at[i].message` and who sends it.
    pub fn check_senders(&self, senders: &[Sender]) -> Result<(), FaultConfigError> {
        for (index, at) in self.at.iter().enumerate() {
            let Some(spec) = at
                .message
                .as_deref()
                .and_then(message_id)
                .and_then(message_spec)
            else {
                continue;
            };
            if !senders.contains(&spec.sender) {
                let named: Vec<&str> = senders.iter().map(|s| s.dbc_name()).collect();
                return Err(FaultConfigError {
                    field: format!("at[{index}].message"),
                    reason: format!(
                        "`{}` is sent by the {} and never travels this way (sent by {} only): \
                         the fault could never fire",
                        spec.name,
                        spec.sender.dbc_name(),
                        named.join(" and ")
                    ),
                });
            }
        }
        Ok(())
    }

    /// The first listed fault at or beyond `periods`, as `(index, period)`: one a run of that
    /// many periods never reaches.
    #[must_use]
    pub fn first_beyond(&self, periods: u64) -> Option<(usize, u64)> {
        self.at
            .iter()
            .enumerate()
            .find(|(_, at)| at.period >= periods)
            .map(|(index, at)| (index, at.period))
    }
}

/// A stretch of loop time, s: `from_s <= t < to_s`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeWindow {
    /// Start, s of loop time.
    pub from_s: f64,
    /// End (excluded), s of loop time.
    pub to_s: f64,
}

impl TimeWindow {
    /// Whether `t_s` is inside.
    #[must_use]
    pub fn contains(&self, t_s: f64) -> bool {
        self.from_s <= t_s && t_s < self.to_s
    }
}

/// Bursts of occlusion at random instants: the spot is shaded, no peak.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OcclusionBursts {
    /// Mean bursts per second of loop time (a burst starts at a sample with probability
    /// `bursts_per_s / measuring rate`).
    pub bursts_per_s: f64,
    /// How long each burst lasts, s.
    pub burst_s: f64,
}

/// The sensor losing its peak, reported as the ILD does (error values in place of distances):
/// the laser off (`laser_off`), the target beyond the range (`peak_after_range`), bursts of
/// occlusion (`no_peak`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorFaults {
    /// Windows with the laser off.
    pub laser_off: Vec<TimeWindow>,
    /// Windows with the target beyond the measuring range.
    pub out_of_range: Vec<TimeWindow>,
    /// Random bursts of occlusion.
    pub occlusion: Option<OcclusionBursts>,
}

impl SensorFaults {
    /// Whether any fault is declared.
    #[must_use]
    pub fn is_active(&self) -> bool {
        !self.laser_off.is_empty() || !self.out_of_range.is_empty() || self.occlusion.is_some()
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`FaultConfigError`] naming the field: a window that is not finite or ends before it
    /// starts, a burst rate or length that is negative or not finite.
    pub fn check(&self) -> Result<(), FaultConfigError> {
        for (name, windows) in [
            ("laser_off", &self.laser_off),
            ("out_of_range", &self.out_of_range),
        ] {
            for (index, window) in windows.iter().enumerate() {
                if !(window.from_s.is_finite()
                    && window.to_s.is_finite()
                    && window.from_s < window.to_s)
                {
                    return Err(FaultConfigError {
                        field: format!("{name}[{index}]"),
                        reason: format!(
                            "from_s {} s to to_s {} s must be finite and end after it starts",
                            window.from_s, window.to_s
                        ),
                    });
                }
            }
        }
        if let Some(bursts) = self.occlusion {
            for (field, value) in [
                ("occlusion.bursts_per_s", bursts.bursts_per_s),
                ("occlusion.burst_s", bursts.burst_s),
            ] {
                if !(value.is_finite() && value > 0.0) {
                    return Err(FaultConfigError {
                        field: field.into(),
                        reason: format!("{value} must be positive and finite"),
                    });
                }
            }
        }
        Ok(())
    }
}

/// The id of the message called `name` (its DBC name).
fn message_id(name: &str) -> Option<u16> {
    crate::message::spec::MESSAGES
        .iter()
        .find(|spec| spec.name == name)
        .map(|spec| spec.id)
}

/// One injected fault, as reported.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct InjectedFault {
    /// The loop period the frame belonged to.
    pub period: u64,
    /// What happened to it.
    pub fault: FrameFault,
    /// The frame's message (DBC name), or its id in hex when it is not in the set.
    pub message: String,
    /// For a bit flip: which bit (of the payload, bit 0 = least significant bit of byte 0; of
    /// the identifier when the frame has no payload).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bit: Option<u32>,
}

/// Every frame of one direction, accounted for: `offered - dropped + duplicated` frames reach
/// the receiver, less those still held (delayed or waiting to be reordered) at the end.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct FrameLedger {
    /// Frames the sender sent.
    pub offered: u64,
    /// Frames handed on to the receiver (duplicates included).
    pub delivered: u64,
    /// Frames dropped.
    pub dropped: u64,
    /// Frames delayed.
    pub delayed: u64,
    /// Extra copies of duplicated frames.
    pub duplicated: u64,
    /// Frames swapped with the next one.
    pub reordered: u64,
    /// Frames with a flipped bit.
    pub bit_flipped: u64,
    /// Frames held now (delayed, or waiting for a frame to follow).
    pub held: u64,
}

impl FrameLedger {
    /// The count of each kind of fault injected, by name (drop, delay, duplicate, reorder,
    /// bit flip).
    #[must_use]
    pub fn fault_counts(&self) -> [(&'static str, u64); 5] {
        [
            ("dropped", self.dropped),
            ("delayed", self.delayed),
            ("duplicated", self.duplicated),
            ("reordered", self.reordered),
            ("bit_flipped", self.bit_flipped),
        ]
    }

    /// Whether every frame is accounted for: delivered = offered - dropped + duplicated - held.
    #[must_use]
    pub fn balances(&self) -> bool {
        self.offered + self.duplicated == self.delivered + self.dropped + self.held
    }
}

/// The faults of one direction applied to its frames.
#[derive(Debug, Clone)]
pub struct FrameInjector {
    faults: DirectionFaults,
    /// Listed faults not yet applied.
    pending_at: Vec<FaultAt>,
    rng: ChaCha8Rng,
    /// Delayed frames with the period they are due in.
    delayed: std::collections::VecDeque<(u64, CanFrame)>,
    /// A frame waiting for the next one to pass it.
    reordered: Option<CanFrame>,
    ledger: FrameLedger,
    log: Vec<InjectedFault>,
}

impl FrameInjector {
    /// An injector of `faults` (checked with [`DirectionFaults::check`]) seeded with `seed`.
    #[must_use]
    pub fn new(faults: DirectionFaults, seed: u64) -> FrameInjector {
        FrameInjector {
            pending_at: faults.at.clone(),
            faults,
            rng: ChaCha8Rng::seed_from_u64(seed),
            delayed: std::collections::VecDeque::new(),
            reordered: None,
            ledger: FrameLedger::default(),
            log: Vec::new(),
        }
    }

    /// The sender sends `frame` in loop period `period`: appends what the receiver gets now to
    /// `out` (delayed frames due by `period` first).
    pub fn send(&mut self, frame: CanFrame, period: u64, out: &mut Vec<CanFrame>) {
        self.ledger.offered += 1;
        self.release_due(period, out);
        let fault = self.fault_for(&frame, period);
        let mut bit = None;
        match fault {
            None => self.deliver(frame, out),
            Some(FrameFault::Drop) => self.ledger.dropped += 1,
            Some(FrameFault::Delay) => {
                self.ledger.delayed += 1;
                let due = period + u64::from(self.faults.delay_periods());
                self.delayed.push_back((due, frame));
            }
            Some(FrameFault::Duplicate) => {
                self.ledger.duplicated += 1;
                self.deliver(frame, out);
                self.deliver(frame, out);
            }
            Some(FrameFault::Reorder) => {
                self.ledger.reordered += 1;
                // A frame already waiting goes first: one frame waits at a time.
                if let Some(waiting) = self.reordered.replace(frame) {
                    self.push(waiting, out);
                }
            }
            Some(FrameFault::BitFlip) => {
                self.ledger.bit_flipped += 1;
                let (flipped, flipped_bit) = self.flip_bit(&frame);
                bit = Some(flipped_bit);
                self.deliver(flipped, out);
            }
        }
        if let Some(fault) = fault
            && self.log.len() < MAX_LOGGED_FAULTS
        {
            self.log.push(InjectedFault {
                period,
                fault,
                message: message_name(&frame),
                bit,
            });
        }
        self.ledger.held = self.held();
    }

    /// Appends the delayed frames due by `period` to `out`.
    pub fn release_due(&mut self, period: u64, out: &mut Vec<CanFrame>) {
        while let Some(&(due, frame)) = self.delayed.front() {
            if due > period {
                break;
            }
            self.delayed.pop_front();
            self.push(frame, out);
        }
        self.ledger.held = self.held();
    }

    /// Frames held now (delayed or waiting to be reordered).
    #[must_use]
    pub fn held(&self) -> u64 {
        self.delayed.len() as u64 + u64::from(self.reordered.is_some())
    }

    /// The counts so far.
    #[must_use]
    pub fn ledger(&self) -> FrameLedger {
        self.ledger
    }

    /// The first [`MAX_LOGGED_FAULTS`] faults injected.
    #[must_use]
    pub fn log(&self) -> &[InjectedFault] {
        &self.log
    }

    /// The faults declared.
    #[must_use]
    pub fn faults(&self) -> &DirectionFaults {
        &self.faults
    }

    /// A frame reaches the receiver, and the one waiting to be reordered after it.
    fn deliver(&mut self, frame: CanFrame, out: &mut Vec<CanFrame>) {
        self.push(frame, out);
        if let Some(waiting) = self.reordered.take() {
            self.push(waiting, out);
        }
    }

    fn push(&mut self, frame: CanFrame, out: &mut Vec<CanFrame>) {
        self.ledger.delivered += 1;
        out.push(frame);
    }

    /// The fault this frame suffers (listed faults first).
    fn fault_for(&mut self, frame: &CanFrame, period: u64) -> Option<FrameFault> {
        let raw_id = frame.id().as_raw();
        let listed = self.pending_at.iter().position(|at| {
            at.period == period
                && at
                    .message
                    .as_deref()
                    .is_none_or(|name| message_id(name).map(u32::from) == Some(raw_id))
        });
        match listed {
            Some(index) => Some(self.pending_at.swap_remove(index).fault),
            None if self.faults.total_rate() > 0.0 => {
                let roll: f64 = self.rng.random();
                let mut below = 0.0;
                self.faults
                    .rates()
                    .into_iter()
                    .find_map(|(_, rate, fault)| {
                        below += rate;
                        (roll < below).then_some(fault)
                    })
            }
            None => None,
        }
    }

    /// `frame` with one bit inverted (of its payload, or of its id without one), and which.
    fn flip_bit(&mut self, frame: &CanFrame) -> (CanFrame, u32) {
        let data = frame.data();
        if data.is_empty() || frame.is_remote() {
            let id_bits = if frame.id().is_extended() { 29 } else { 11 };
            let bit = self.rng.random_range(0..id_bits);
            let raw = frame.id().as_raw() ^ (1 << bit);
            let id = if frame.id().is_extended() {
                CanId::extended(raw)
            } else {
                CanId::standard(raw as u16)
            }
            .expect("flipping a bit below the id's width keeps it in range");
            let flipped = if frame.is_remote() {
                CanFrame::new_remote(id, frame.dlc())
            } else {
                CanFrame::new(id, &[])
            };
            return (flipped.expect("the same length as a valid frame"), bit);
        }
        let bit = self.rng.random_range(0..data.len() as u32 * 8);
        let mut payload = data.to_vec();
        payload[(bit / 8) as usize] ^= 1 << (bit % 8);
        let flipped = match frame.format() {
            FrameFormat::Fd { brs, esi } => CanFrame::new_fd(frame.id(), &payload, brs, esi),
            FrameFormat::Classical | FrameFormat::Remote => CanFrame::new(frame.id(), &payload),
        };
        (flipped.expect("the same length as a valid frame"), bit)
    }
}

/// The frame's message name, or its id in hex.
fn message_name(frame: &CanFrame) -> String {
    u16::try_from(frame.id().as_raw())
        .ok()
        .filter(|_| !frame.id().is_extended())
        .and_then(message_spec)
        .map_or_else(|| format!("0x{}", frame.id()), |spec| spec.name.to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::message::{Message, ids};

    fn step(k: u32) -> CanFrame {
        Message::Step { step: k }.encode().unwrap()
    }

    fn run(faults: DirectionFaults, seed: u64, frames: u32) -> (Vec<CanFrame>, FrameInjector) {
        let mut injector = FrameInjector::new(faults, seed);
        let mut out = Vec::new();
        for k in 0..frames {
            injector.send(step(k), u64::from(k), &mut out);
        }
        (out, injector)
    }

    #[test]
    fn without_faults_every_frame_passes_unchanged() {
        let (out, injector) = run(DirectionFaults::default(), 1, 100);
        assert_eq!(out, (0..100).map(step).collect::<Vec<_>>());
        assert!(injector.ledger().balances());
        assert!(injector.log().is_empty());
    }

    #[test]
    fn listed_faults_hit_their_period_and_message() {
        let faults = DirectionFaults {
            at: vec![
                FaultAt {
                    period: 2,
                    fault: FrameFault::Drop,
                    message: None,
                },
                FaultAt {
                    period: 4,
                    fault: FrameFault::Duplicate,
                    message: Some("Step".into()),
                },
                FaultAt {
                    period: 6,
                    fault: FrameFault::Reorder,
                    message: None,
                },
                FaultAt {
                    period: 8,
                    fault: FrameFault::Delay,
                    message: None,
                },
                // Another message's period: never applied to a Step.
                FaultAt {
                    period: 9,
                    fault: FrameFault::Drop,
                    message: Some("CoilCommand".into()),
                },
            ],
            delay_periods: Some(3),
            ..DirectionFaults::default()
        };
        faults.check().unwrap();
        let (out, injector) = run(faults, 1, 12);
        let steps: Vec<u32> = out
            .iter()
            .map(|frame| match Message::decode(frame).unwrap() {
                Message::Step { step } => step,
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(steps, [0, 1, 3, 4, 4, 5, 7, 6, 9, 10, 8, 11]);
        let ledger = injector.ledger();
        assert_eq!(
            (
                ledger.dropped,
                ledger.duplicated,
                ledger.reordered,
                ledger.delayed
            ),
            (1, 1, 1, 1)
        );
        assert!(ledger.balances(), "{ledger:?}");
        assert_eq!(injector.log().len(), 4);
        assert_eq!(injector.log()[0].message, "Step");
    }

    #[test]
    fn a_flipped_bit_changes_exactly_one_bit() {
        let faults = DirectionFaults {
            bit_flip_rate: 1.0,
            ..DirectionFaults::default()
        };
        let (out, injector) = run(faults, 9, 50);
        for (k, frame) in out.iter().enumerate() {
            let original = step(k as u32);
            let differing: u32 = original
                .data()
                .iter()
                .zip(frame.data())
                .map(|(a, b)| (a ^ b).count_ones())
                .sum();
            assert_eq!(differing, 1, "frame {k}");
            assert_eq!(frame.id().as_raw(), u32::from(ids::STEP));
        }
        assert_eq!(injector.ledger().bit_flipped, 50);
        assert!(injector.log().iter().all(|fault| fault.bit.is_some()));
        // Past the log's length (filled by listed drops) no bit is written into an older
        // entry.
        let faults = DirectionFaults {
            bit_flip_rate: 1.0,
            at: (0..MAX_LOGGED_FAULTS as u64)
                .map(|period| FaultAt {
                    period,
                    fault: FrameFault::Drop,
                    message: None,
                })
                .collect(),
            ..DirectionFaults::default()
        };
        let (_, injector) = run(faults, 4, 300);
        assert_eq!(injector.log().len(), MAX_LOGGED_FAULTS);
        assert!(
            injector
                .log()
                .iter()
                .all(|fault| (fault.fault == FrameFault::BitFlip) == fault.bit.is_some())
        );
    }

    #[test]
    fn rates_are_met_and_the_same_seed_gives_the_same_faults() {
        let faults = DirectionFaults {
            drop_rate: 0.01,
            delay_rate: 0.01,
            delay_periods: Some(5),
            duplicate_rate: 0.01,
            reorder_rate: 0.01,
            bit_flip_rate: 0.01,
            at: Vec::new(),
        };
        let (out, injector) = run(faults.clone(), 3, 100_000);
        let ledger = injector.ledger();
        for (kind, count) in ledger.fault_counts() {
            // 1000 expected, sigma about 31.
            assert!((850..1150).contains(&count), "{kind}: {ledger:?}");
        }
        assert!(ledger.balances(), "{ledger:?}");
        assert_eq!(injector.log().len(), MAX_LOGGED_FAULTS);
        let (again, _) = run(faults, 3, 100_000);
        assert_eq!(out, again);
    }

    #[test]
    fn bad_declarations_name_their_field() {
        let cases = [
            (
                DirectionFaults {
                    drop_rate: 1.5,
                    ..DirectionFaults::default()
                },
                "drop_rate",
            ),
            (
                DirectionFaults {
                    bit_flip_rate: f64::NAN,
                    ..DirectionFaults::default()
                },
                "bit_flip_rate",
            ),
            (
                DirectionFaults {
                    delay_periods: Some(0),
                    ..DirectionFaults::default()
                },
                "delay_periods",
            ),
            (
                DirectionFaults {
                    at: vec![FaultAt {
                        period: 1,
                        fault: FrameFault::Drop,
                        message: Some("Stpe".into()),
                    }],
                    ..DirectionFaults::default()
                },
                "at[0].message",
            ),
        ];
        for (faults, field) in cases {
            assert_eq!(faults.check().unwrap_err().field, field);
        }
    }
}
