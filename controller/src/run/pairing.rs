//! Pairing distances with mirror angles by the sensor's own time, as a real sensor needs: the
//! sensor measures on its own clock, so a distance is placed at the instant its measured-value
//! counter stands for, and the mirror angles at that instant are interpolated between the two
//! angle readings around it. Arrival time plays no part, so pairing is deterministic.

use scanhil_protocol::plant_units::SensingPair;

/// The sensor's clock: its measuring rate and the instant of counter value 0 on the loop's
/// time axis (loop time 0 is the start of control period 0).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SensorClock {
    /// Measuring rate, in Hz.
    pub measuring_rate_hz: f64,
    /// Loop time of the sample with (unwrapped) counter 0, in seconds.
    pub counter_zero_s: f64,
}

impl SensorClock {
    /// The loop time a sample with the unwrapped counter `counter` was measured at.
    #[must_use]
    pub fn instant_s(&self, counter: u64) -> f64 {
        self.counter_zero_s + counter as f64 / self.measuring_rate_hz
    }
}

/// Where a wall-clock arrival lies on the loop's time axis, to estimate a sensor clock that
/// nobody declared (a real sensor): an upper bound of the loop time of anything measured
/// before that arrival.
#[derive(Debug, Clone, PartialEq)]
pub enum ArrivalClock {
    /// Real time: loop time runs with the wall clock from this instant (loop time 0).
    Epoch(tokio::time::Instant),
    /// Lockstep: loop time is virtual and advances one period per Step. `sent[k]` is when
    /// period `k`'s frames started going out; the node measures period `k` only after that,
    /// so anything that arrived after `sent[k]` may stand for loop time up to `(k + 1)` periods.
    Steps {
        /// The control period, s.
        period_s: f64,
        /// Per period, the instant its frames started going out.
        sent: Vec<tokio::time::Instant>,
    },
}

impl ArrivalClock {
    /// The loop time an arrival at `arrived` bounds from above, s.
    #[must_use]
    pub fn loop_time_s(&self, arrived: tokio::time::Instant) -> f64 {
        match self {
            ArrivalClock::Epoch(epoch) => arrived.saturating_duration_since(*epoch).as_secs_f64(),
            ArrivalClock::Steps { period_s, sent } => {
                sent.partition_point(|started| *started <= arrived) as f64 * period_s
            }
        }
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
/// at the end of control period `k`, loop time `(k + 1) * period_s`.
#[derive(Debug, Clone, Default)]
pub struct AngleTrack {
    period_s: f64,
    readings_rad: Vec<SensingPair>,
}

impl AngleTrack {
    /// An empty track for a loop with period `period_s`.
    #[must_use]
    pub fn new(period_s: f64) -> AngleTrack {
        AngleTrack::with_capacity(period_s, 0)
    }

    /// An empty track with room for `readings` readings (a run's planned periods: no
    /// reallocation, whose old and new buffers would both be held at once, on the way).
    #[must_use]
    pub fn with_capacity(period_s: f64, readings: usize) -> AngleTrack {
        AngleTrack {
            period_s,
            readings_rad: Vec::with_capacity(readings),
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

    /// Number of readings.
    #[must_use]
    pub fn len(&self) -> usize {
        self.readings_rad.len()
    }

    /// True when no reading arrived yet.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.readings_rad.is_empty()
    }

    /// All readings, in order.
    #[must_use]
    pub fn readings_rad(&self) -> &[SensingPair] {
        &self.readings_rad
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

    #[test]
    fn lockstep_arrivals_count_the_periods_started_before_them() {
        let start = tokio::time::Instant::now();
        let at = |us: u64| start + std::time::Duration::from_micros(us);
        let clock = ArrivalClock::Steps {
            period_s: 0.5,
            sent: vec![at(0), at(10), at(20)],
        };
        // Before any period started: loop time 0; after period 1 started: the end of period 1.
        assert_eq!(
            clock.loop_time_s(start - std::time::Duration::from_micros(1)),
            0.0
        );
        assert_eq!(clock.loop_time_s(at(15)), 1.0);
        assert_eq!(clock.loop_time_s(at(20)), 1.5);
        assert_eq!(clock.loop_time_s(at(99)), 1.5);
    }

    #[test]
    fn sensor_clock_places_counters_on_the_loop_time_axis() {
        let clock = SensorClock {
            measuring_rate_hz: 20_000.0,
            counter_zero_s: 1e-5,
        };
        assert!((clock.instant_s(20_000) - 1.00001).abs() < 1e-12);
    }
}
