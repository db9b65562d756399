//! Pairing distances with mirror angles by the sensor's own time, as a real sensor needs: the
//! sensor measures on its own clock, so a distance is placed at the instant its measured-value
//! counter stands for, and the mirror angles at that instant are interpolated between the two
//! angle readings around it. Arrival time plays no part, so pairing is deterministic.

use std::collections::BTreeMap;

use scanhil_protocol::ild::{IldValue, MeasuringRange};
use scanhil_protocol::plant_units::SensingPair;

use super::chunked::Chunked;
use crate::imaging::reconstruct::ScanSample;

/// The sensor's clock: its measuring rate and the instant of counter value 0 on the loop's
/// time axis (loop time 0 is the start of control period 0).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SensorClock {
    /// Measuring rate, in Hz.
    pub measuring_rate_hz: f64,
    /// Loop time of the sample with (unwrapped) counter 0, in seconds.
    pub counter_zero_s: f64,
    /// Added to a sample's counter before it is placed: the sensor's counter at the first
    /// sample a host counted when the cycles carry no counter (the host counts them from 0;
    /// an emulated sensor declares where its own counter stood), else 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub counter_offset: u64,
}

fn is_zero(value: &u64) -> bool {
    *value == 0
}

impl SensorClock {
    /// A clock with counter 0 at `counter_zero_s` and no offset.
    #[must_use]
    pub fn new(measuring_rate_hz: f64, counter_zero_s: f64) -> SensorClock {
        SensorClock {
            measuring_rate_hz,
            counter_zero_s,
            counter_offset: 0,
        }
    }

    /// The loop time a sample with the unwrapped counter `counter` was measured at.
    #[must_use]
    pub fn instant_s(&self, counter: u64) -> f64 {
        self.counter_zero_s + (counter + self.counter_offset) as f64 / self.measuring_rate_hz
    }
}

/// Pairs a scan's sensor samples, in the order they were measured, with the angles at their
/// instants, and counts what could not be paired: samples measured before the frame (the
/// lead-in), samples outside the angle record, and error values by name (a paired sample
/// without a distance). Angle readings the samples have passed are freed as it goes.
#[derive(Debug)]
pub struct FramePairing {
    clock: SensorClock,
    frame_start_s: f64,
    angles: Option<AngleTrack>,
    range: Option<MeasuringRange>,
    /// Samples measured before the frame.
    pub in_lead_in: u64,
    /// Samples outside the angle record.
    pub unpaired: u64,
    /// Samples paired.
    pub paired: usize,
    /// Paired samples with a distance.
    pub with_distance: usize,
    /// Paired samples without a distance, by the sensor's error name.
    pub missing_by_reason: BTreeMap<String, usize>,
}

impl FramePairing {
    /// Pairs by `clock` against `angles` the samples measured from `frame_start_s` on;
    /// distances in mm by `range` (`None`: none).
    #[must_use]
    pub fn new(
        clock: SensorClock,
        frame_start_s: f64,
        angles: Option<AngleTrack>,
        range: Option<MeasuringRange>,
    ) -> FramePairing {
        FramePairing {
            clock,
            frame_start_s,
            angles,
            range,
            in_lead_in: 0,
            unpaired: 0,
            paired: 0,
            with_distance: 0,
            missing_by_reason: BTreeMap::new(),
        }
    }

    /// The next sample (its unwrapped counter and value) paired, or `None` (counted) when it
    /// cannot be. Samples must come in the order they were measured: the angle readings
    /// before this one's are freed.
    pub fn pair(&mut self, counter: u64, value: IldValue) -> Option<ScanSample> {
        let t_s = self.clock.instant_s(counter);
        if t_s < self.frame_start_s {
            self.in_lead_in += 1;
            return None;
        }
        let Some(angles) = self.angles.as_mut().and_then(|track| {
            let angles = track.at(t_s);
            track.release_before(t_s);
            angles
        }) else {
            self.unpaired += 1;
            return None;
        };
        let z_meas_mm = match value {
            IldValue::Distance(digital) => self.range.and_then(|r| r.digital_to_mm(digital)),
            IldValue::Error(error) => {
                *self
                    .missing_by_reason
                    .entry(error.name().into())
                    .or_default() += 1;
                None
            }
        };
        self.paired += 1;
        self.with_distance += usize::from(z_meas_mm.is_some());
        Some(ScanSample {
            t_s,
            d_alpha_rad: angles.alpha,
            d_beta_rad: angles.beta,
            z_meas_mm,
        })
    }
}

/// The bound on a sensor's counter-0 instant that arrivals give, kept as samples arrive (a
/// real sensor declares no clock): a sample arrives after it was measured, so the earliest
/// `loop time of arrival - counter / rate` bounds counter 0's instant from above. Nothing is
/// kept per sample, so a long run's samples cost only their counter and value.
///
/// On the wall clock (real time), loop time 0 (the epoch) is settled only at the end of the
/// run, from the earliest reading; the bound is kept as the earliest `arrival - counter /
/// rate` from the first arrival and placed on the loop's axis by
/// [`ArrivalBound::counter_zero_s`]. In lockstep, loop time advances one period per Step: an
/// arrival after the start of period `k` stands for loop time up to `(k + 1)` periods, so the
/// starts are noted as they happen ([`ArrivalBound::period_started`]). Only the last
/// [`RECENT_PERIOD_STARTS`] are kept: a sample is noted when its cycle is read, periods
/// before that have long started (an arrival older than the kept starts counts as after all
/// of them: a looser bound, never a wrong one).
#[derive(Debug, Clone)]
pub struct ArrivalBound {
    measuring_rate_hz: f64,
    /// The least time from a sample's measurement to its arrival: the line's transmit time of
    /// a cycle (0 on CAN), s.
    transmit_s: f64,
    axis: ArrivalAxis,
}

/// How many of the latest period starts a lockstep [`ArrivalBound`] keeps (51 ms at 20 kHz).
pub const RECENT_PERIOD_STARTS: usize = 1024;

/// Where an [`ArrivalBound`] places arrivals.
#[derive(Debug, Clone)]
enum ArrivalAxis {
    /// Real time: the earliest `(arrival - origin) - counter / rate`, s, from the first
    /// arrival (`origin`).
    WallClock {
        origin: Option<tokio::time::Instant>,
        earliest_s: f64,
    },
    /// Lockstep: the latest period starts, how many started before them, and the bound so far.
    Steps {
        period_s: f64,
        recent_starts: std::collections::VecDeque<tokio::time::Instant>,
        earlier_starts: u64,
        bound_s: f64,
    },
}

impl ArrivalBound {
    /// Arrivals on the wall clock (a real-time loop), of a sensor measuring at
    /// `measuring_rate_hz`.
    #[must_use]
    pub fn wall_clock(measuring_rate_hz: f64) -> ArrivalBound {
        ArrivalBound {
            measuring_rate_hz,
            transmit_s: 0.0,
            axis: ArrivalAxis::WallClock {
                origin: None,
                earliest_s: f64::INFINITY,
            },
        }
    }

    /// Arrivals counted in lockstep periods of `period_s`.
    #[must_use]
    pub fn steps(period_s: f64, measuring_rate_hz: f64) -> ArrivalBound {
        ArrivalBound {
            measuring_rate_hz,
            transmit_s: 0.0,
            axis: ArrivalAxis::Steps {
                period_s,
                recent_starts: std::collections::VecDeque::with_capacity(RECENT_PERIOD_STARTS),
                earlier_starts: 0,
                bound_s: f64::INFINITY,
            },
        }
    }

    /// The same bound for samples that take at least `transmit_s` from their measurement to
    /// their arrival (an ILD line's transmit time of one cycle: its last byte arrives that
    /// long after the cycle went out), so the bound is that much tighter.
    #[must_use]
    pub fn after_transmit(mut self, transmit_s: f64) -> ArrivalBound {
        self.transmit_s = transmit_s;
        self
    }

    /// Lockstep: the next period's frames started going out at `at` (nothing on the wall
    /// clock).
    pub fn period_started(&mut self, at: tokio::time::Instant) {
        if let ArrivalAxis::Steps {
            recent_starts,
            earlier_starts,
            ..
        } = &mut self.axis
        {
            if recent_starts.len() == RECENT_PERIOD_STARTS {
                recent_starts.pop_front();
                *earlier_starts += 1;
            }
            recent_starts.push_back(at);
        }
    }

    /// A sample with the unwrapped counter `counter` arrived at `arrived`.
    pub fn note(&mut self, arrived: tokio::time::Instant, counter: u64) {
        let counter_s = counter as f64 / self.measuring_rate_hz + self.transmit_s;
        match &mut self.axis {
            ArrivalAxis::WallClock { origin, earliest_s } => {
                let origin = *origin.get_or_insert(arrived);
                *earliest_s = earliest_s.min(seconds_between(origin, arrived) - counter_s);
            }
            ArrivalAxis::Steps {
                period_s,
                recent_starts,
                earlier_starts,
                bound_s,
            } => {
                let started = *earlier_starts
                    + recent_starts.partition_point(|start| *start <= arrived) as u64;
                *bound_s = bound_s.min(started as f64 * *period_s - counter_s);
            }
        }
    }

    /// The bound on counter 0's loop time, s, with loop time 0 at `epoch` on the wall clock
    /// (the real-time loop's; unused in lockstep); `None` before any sample.
    #[must_use]
    pub fn counter_zero_s(&self, epoch: Option<tokio::time::Instant>) -> Option<f64> {
        let bound_s = match &self.axis {
            ArrivalAxis::WallClock { origin, earliest_s } => {
                earliest_s + seconds_between(epoch?, (*origin)?)
            }
            ArrivalAxis::Steps { bound_s, .. } => *bound_s,
        };
        bound_s.is_finite().then_some(bound_s)
    }

    /// The sensor's measuring rate, Hz.
    #[must_use]
    pub fn measuring_rate_hz(&self) -> f64 {
        self.measuring_rate_hz
    }
}

/// `to - from`, s, negative when `to` is earlier.
fn seconds_between(from: tokio::time::Instant, to: tokio::time::Instant) -> f64 {
    match to.checked_duration_since(from) {
        Some(after) => after.as_secs_f64(),
        None => -from.duration_since(to).as_secs_f64(),
    }
}

/// Unwraps a counter that wraps at `modulus` (the ILD's 18-bit measured-value counter, a CAN
/// sequence counter) into a monotonic count, and counts the values that went missing.
#[derive(Debug, Clone)]
pub struct CounterUnwrapper {
    modulus: u64,
    last: Option<u64>,
    missing: u64,
}

impl CounterUnwrapper {
    /// An unwrapper for a counter running `0..modulus`.
    #[must_use]
    pub fn new(modulus: u64) -> CounterUnwrapper {
        CounterUnwrapper {
            modulus: modulus.max(1),
            last: None,
            missing: 0,
        }
    }

    /// The unwrapped value of the next received counter. The first value received is taken as
    /// is; each later one is placed at the smallest step forward (a step of 0 is a repeat).
    pub fn unwrap(&mut self, raw: u64) -> u64 {
        let raw = raw % self.modulus;
        let value = match self.last {
            None => raw,
            Some(last) => {
                let step = (raw + self.modulus - last % self.modulus) % self.modulus;
                self.missing += step.saturating_sub(1);
                last + step
            }
        };
        self.last = Some(value);
        value
    }

    /// Counter values skipped so far (gaps between consecutive received values).
    #[must_use]
    pub fn missing(&self) -> u64 {
        self.missing
    }
}

/// The mirror angle readings of a run on a regular time axis: reading `k` is the angle sampled
/// at the end of control period `k`, loop time `(k + 1) * period_s`. Held in chunks: pairing,
/// which reads it forward, frees the readings it has passed ([`AngleTrack::release_before`]).
#[derive(Debug, Clone, Default)]
pub struct AngleTrack {
    period_s: f64,
    readings_rad: Chunked<SensingPair>,
}

impl AngleTrack {
    /// An empty track for a loop with period `period_s`.
    #[must_use]
    pub fn new(period_s: f64) -> AngleTrack {
        AngleTrack {
            period_s,
            readings_rad: Chunked::new(),
        }
    }

    /// Appends reading `k = self.len()`.
    pub fn push(&mut self, angles_rad: SensingPair) {
        self.readings_rad.push(angles_rad);
    }

    /// The control period, s.
    #[must_use]
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Number of readings (released ones included).
    #[must_use]
    pub fn len(&self) -> usize {
        self.readings_rad.len()
    }

    /// True when no reading arrived yet.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.readings_rad.is_empty()
    }

    /// Frees readings no time from `t_s` on needs (whole chunks before it); [`AngleTrack::at`]
    /// is `None` before them afterwards.
    pub fn release_before(&mut self, t_s: f64) {
        let position = t_s / self.period_s - 1.0;
        if position.is_finite() && position >= 1.0 {
            self.readings_rad.release_before(position.floor() as usize);
        }
    }

    /// The angles at loop time `t_s`, linearly interpolated between the readings around it;
    /// `None` outside the span of the readings.
    #[must_use]
    pub fn at(&self, t_s: f64) -> Option<SensingPair> {
        let position = t_s / self.period_s - 1.0;
        if !position.is_finite() || position < 0.0 {
            return None;
        }
        let below = position.floor() as usize;
        let fraction = position - below as f64;
        let first = *self.readings_rad.get(below)?;
        if fraction == 0.0 {
            return Some(first);
        }
        let second = *self.readings_rad.get(below + 1)?;
        Some(SensingPair {
            alpha: first.alpha + fraction * (second.alpha - first.alpha),
            beta: first.beta + fraction * (second.beta - first.beta),
        })
    }
}

#[cfg(test)]
mod tests {
    use scanhil_protocol::ild::IldError;

    use super::*;

    #[test]
    fn counter_unwraps_past_the_modulus_and_counts_gaps() {
        let mut counter = CounterUnwrapper::new(1 << 18);
        assert_eq!(counter.unwrap(262_142), 262_142);
        assert_eq!(counter.unwrap(262_143), 262_143);
        assert_eq!(counter.unwrap(0), 262_144);
        assert_eq!(counter.unwrap(3), 262_147);
        assert_eq!(counter.missing(), 2);
    }

    #[test]
    fn angles_interpolate_between_readings_and_not_beyond() {
        let mut track = AngleTrack::new(0.5);
        track.push(SensingPair {
            alpha: 0.0,
            beta: 1.0,
        });
        track.push(SensingPair {
            alpha: 2.0,
            beta: 1.0,
        });
        let mid = track.at(0.75).expect("inside the track");
        assert_eq!((mid.alpha, mid.beta), (1.0, 1.0));
        assert_eq!(track.at(1.0).map(|p| p.alpha), Some(2.0));
        assert!(track.at(0.25).is_none());
        assert!(track.at(1.25).is_none());
    }

    /// A track of `n` readings at 1 kHz, reading `k` given by `reading(k)`.
    fn track_of(n: u32, reading: impl Fn(f64) -> SensingPair) -> AngleTrack {
        let mut track = AngleTrack::new(1e-3);
        for k in 0..n {
            track.push(reading(f64::from(k)));
        }
        track
    }

    #[test]
    fn released_readings_are_only_those_before_the_time_asked_for() {
        let mut track = track_of(200_000, |k| SensingPair { alpha: k, beta: -k });
        // Between readings 150 000 and 150 001 (loop times 150.001 and 150.002 s).
        let t_s = 150.0015;
        let before = track.at(t_s).expect("inside the track");
        track.release_before(t_s);
        assert_eq!(track.at(t_s), Some(before));
        assert_eq!(before.alpha, 150_000.5);
        assert!(track.at(t_s + 10.0).is_some());
        assert!(track.at(1.0).is_none(), "the first chunks are freed");
        assert_eq!(track.len(), 200_000);
    }

    #[test]
    fn pairing_in_order_frees_angles_without_changing_a_pair() {
        // 200 000 readings at 1 kHz, a sample every 0.7 periods from counter 0 at -0.1 s:
        // before the frame (5 s), inside, and past the last reading; every 97th an error.
        let period_s = 1e-3;
        let track = track_of(200_000, |k| SensingPair {
            alpha: (k * 1e-3).sin(),
            beta: k,
        });
        let clock = SensorClock::new(1.0 / (0.7 * period_s), -0.1);
        let range = MeasuringRange {
            start_mm: 100.0,
            span_mm: 50.0,
        };
        let value = |counter: u64| {
            if counter.is_multiple_of(97) {
                IldValue::Error(IldError::NoPeak)
            } else {
                IldValue::Distance(1000 + (counter % 5000) as u32)
            }
        };
        let mut pairing = FramePairing::new(clock, 5.0, Some(track.clone()), Some(range));
        let mut paired = 0;
        for counter in 0..300_000u64 {
            let got = pairing.pair(counter, value(counter));
            let t_s = clock.instant_s(counter);
            let expected = (t_s >= 5.0)
                .then(|| track.at(t_s))
                .flatten()
                .map(|angles| (angles.alpha, angles.beta));
            assert_eq!(
                got.map(|s| (s.d_alpha_rad, s.d_beta_rad)),
                expected,
                "{counter}"
            );
            if let Some(sample) = got {
                paired += 1;
                assert_eq!(sample.t_s, t_s);
                let distance = match value(counter) {
                    IldValue::Distance(digital) => range.digital_to_mm(digital),
                    IldValue::Error(_) => None,
                };
                assert_eq!(sample.z_meas_mm, distance);
            }
        }
        assert_eq!(pairing.paired, paired);
        assert_eq!(pairing.in_lead_in, 7286, "5.1 s / 0.7 ms");
        assert_eq!(
            pairing.in_lead_in + pairing.unpaired + paired as u64,
            300_000
        );
        assert_eq!(
            pairing.missing_by_reason["no_peak"],
            paired - pairing.with_distance
        );
        let held = pairing
            .angles
            .as_ref()
            .expect("the track")
            .readings_rad
            .iter()
            .count();
        assert!(held < 2 * (1 << 16), "angles passed are freed: {held} held");
    }

    #[test]
    fn lockstep_arrivals_count_the_periods_started_before_them() {
        let start = tokio::time::Instant::now();
        let at = |us: u64| start + std::time::Duration::from_micros(us);
        // The loop time one arrival bounds (a sample with counter 0), periods of 0.5 s.
        let loop_time_s = |arrived| {
            let mut bound = ArrivalBound::steps(0.5, 1.0);
            for started in [at(0), at(10), at(20)] {
                bound.period_started(started);
            }
            bound.note(arrived, 0);
            bound.counter_zero_s(None).expect("one arrival")
        };
        // Before any period started: loop time 0; after period 1 started: the end of period 1.
        assert_eq!(
            loop_time_s(start - std::time::Duration::from_micros(1)),
            0.0
        );
        assert_eq!(loop_time_s(at(15)), 1.0);
        assert_eq!(loop_time_s(at(20)), 1.5);
        assert_eq!(loop_time_s(at(99)), 1.5);
    }

    #[test]
    fn a_lines_transmit_time_tightens_the_bound_on_either_axis() {
        let start = tokio::time::Instant::now();
        let mut steps = ArrivalBound::steps(0.5, 1.0).after_transmit(0.125);
        steps.period_started(start);
        steps.note(start + std::time::Duration::from_micros(1), 0);
        assert_eq!(steps.counter_zero_s(None), Some(0.375));
        let mut wall = ArrivalBound::wall_clock(2.0).after_transmit(0.25);
        wall.note(start + std::time::Duration::from_secs(1), 1);
        assert_eq!(wall.counter_zero_s(Some(start)), Some(0.25));
    }

    #[test]
    fn lockstep_bound_kept_as_samples_arrive_is_the_bound_over_all_period_starts() {
        // 5000 periods 10 us apart; the sensor's samples (two a period, counter zero at
        // -3 us) arrive 1 to 9 us into the period after the one they were measured in. Kept
        // as they come (only the latest starts held), the bound is the one over every start.
        let start = tokio::time::Instant::now();
        let at = |ns: u64| start + std::time::Duration::from_nanos(ns);
        let (period_s, rate_hz) = (0.5, 2.0 / 0.5);
        let mut bound = ArrivalBound::steps(period_s, rate_hz);
        let mut sent = Vec::new();
        let mut arrivals = Vec::new();
        for k in 0..5000u64 {
            let started = at(k * 10_000);
            sent.push(started);
            bound.period_started(started);
            for (i, delay_ns) in [(0, 1000 + (k * 7919) % 8000), (1, 9000)] {
                let counter = 2 * k + i;
                let arrived = started + std::time::Duration::from_nanos(delay_ns);
                bound.note(arrived, counter);
                arrivals.push((counter, arrived));
            }
        }
        assert!(
            sent.len() > RECENT_PERIOD_STARTS,
            "the window must be passed"
        );
        // Every start kept: an arrival after period k's start stands for loop time (k + 1)
        // periods.
        let loop_time_s =
            |arrived| sent.partition_point(|start| *start <= arrived) as f64 * period_s;
        let over_all = arrivals
            .iter()
            .map(|&(counter, arrived)| loop_time_s(arrived) - counter as f64 / rate_hz)
            .fold(f64::INFINITY, f64::min);
        assert_eq!(bound.counter_zero_s(None), Some(over_all));
        assert_eq!(
            ArrivalBound::steps(period_s, rate_hz).counter_zero_s(None),
            None
        );
    }

    #[test]
    fn sensor_clock_places_counters_on_the_loop_time_axis() {
        let clock = SensorClock::new(20_000.0, 1e-5);
        assert!((clock.instant_s(20_000) - 1.00001).abs() < 1e-12);
    }
}
