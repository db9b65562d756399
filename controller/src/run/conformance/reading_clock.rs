//! The real-time timing checks' bookkeeping: when each of the node's readings arrived, against
//! the rate the node declares. From it come `readings_on_time` (no silence between two
//! readings longer than the watchdog's allowance; the intervals as min / median / p99 / max),
//! `reading_rate` (the node's own period within [`RATE_TOLERANCE`] of the declared one) and
//! the missed readings of `angle_sequence_gapless` (counters the node skipped).
//!
//! The rate is estimated so that stalls do not move it. A reading can arrive late (the node's
//! or the host's stall, readings read in one chunk), never early, so the earliest arrival in
//! each of [`RATE_SEGMENTS`] stretches of the run, less its counter's nominal time, lies on a
//! line whose slope is the node's relative period error. The median of the slopes between
//! stretches two apart is kept: a few stretches spoiled by stalls, or one stall that delays
//! every later reading (a node whose clock stopped for a while), do not move it.

use scanhil_protocol::loop_timing::PeriodRecorder;

/// How far the node's period may be from the declared one, relative: a node configured for
/// another rate, or a clock far off, fails; a crystal's parts per million and what a pty or a
/// USB adapter adds to the arrival times pass.
pub const RATE_TOLERANCE: f64 = 0.02;
/// Stretches of the run whose earliest arrivals give the rate (an even number: the median of
/// the slopes between stretches two apart is the mean of the middle two).
pub const RATE_SEGMENTS: usize = 16;
const _: () = assert!(RATE_SEGMENTS.is_multiple_of(2) && RATE_SEGMENTS >= 4);

/// When each reading arrived, as the real-time checks keep it.
#[derive(Debug)]
pub struct ReadingClock {
    period_s: f64,
    allowance_s: f64,
    /// Each reading's counter and its arrival, s after the first one's.
    arrivals: Vec<(u64, f64)>,
    intervals: PeriodRecorder,
    late: u64,
    first_late: Option<String>,
    missed: u64,
    first_missed: Option<String>,
    /// Why the readings stopped before the drive's end (none came within twice the allowance,
    /// the link failed).
    pub lost: Option<String>,
}

impl ReadingClock {
    /// An empty record for a node declaring `period_s`, whose silences may last `allowance_s`
    /// (the watchdog's whole allowance).
    #[must_use]
    pub fn new(period_s: f64, allowance_s: f64) -> ReadingClock {
        ReadingClock {
            period_s,
            allowance_s,
            arrivals: Vec::new(),
            intervals: PeriodRecorder::new(period_s),
            late: 0,
            first_late: None,
            missed: 0,
            first_missed: None,
            lost: None,
        }
    }

    /// Reading `k` arrived `arrival_s` after the first one, while reading `expected` was
    /// awaited (the ones between never came).
    pub fn arrived(&mut self, k: u64, expected: u64, arrival_s: f64) {
        if k > expected {
            self.missed += k - expected;
            self.first_missed.get_or_insert_with(|| match k - expected {
                1 => format!("reading {expected} never came"),
                _ => format!("readings {expected} to {} never came", k - 1),
            });
        }
        if let Some(&(_, previous_s)) = self.arrivals.last() {
            let gap_s = arrival_s - previous_s;
            self.intervals.record(gap_s);
            if gap_s > self.allowance_s {
                self.late += 1;
                self.first_late.get_or_insert_with(|| {
                    format!(
                        "reading {k} came {:.3} ms after the one before, beyond the watchdog's {:.3} ms",
                        gap_s * 1e3,
                        self.allowance_s * 1e3
                    )
                });
            }
        }
        self.arrivals.push((k, arrival_s));
    }

    /// Readings that arrived.
    #[must_use]
    pub fn readings(&self) -> u64 {
        self.arrivals.len() as u64
    }

    /// Readings the node's counters skipped, and the first such stretch.
    #[must_use]
    pub fn missed(&self) -> (u64, Option<&str>) {
        (self.missed, self.first_missed.as_deref())
    }

    /// The node's relative period error (its period is the declared one times 1 + this), from
    /// the earliest arrivals of [`RATE_SEGMENTS`] stretches; `None` with fewer than two
    /// readings a stretch.
    #[must_use]
    pub fn period_error(&self) -> Option<f64> {
        let n = self.arrivals.len();
        if n < 2 * RATE_SEGMENTS {
            return None;
        }
        let earliest: Vec<(f64, f64)> = (0..RATE_SEGMENTS)
            .filter_map(|i| {
                self.arrivals[i * n / RATE_SEGMENTS..(i + 1) * n / RATE_SEGMENTS]
                    .iter()
                    .map(|&(k, t_s)| (k as f64, t_s - k as f64 * self.period_s))
                    .min_by(|a, b| a.1.total_cmp(&b.1))
            })
            .collect();
        // Counters rise from stretch to stretch, so every span is positive; RATE_SEGMENTS - 2
        // slopes, an even count: the median is the mean of the middle two.
        let mut slopes: Vec<f64> = earliest
            .windows(3)
            .map(|w| (w[2].1 - w[0].1) / ((w[2].0 - w[0].0) * self.period_s))
            .collect();
        slopes.sort_by(f64::total_cmp);
        let middle = slopes.len() / 2;
        Some(f64::midpoint(slopes[middle - 1], slopes[middle]))
    }

    /// `readings_on_time`: `Ok` (the intervals seen) when no silence between two readings
    /// outlasted the watchdog's allowance and none was lost; `Err` says which did.
    ///
    /// # Errors
    /// What was late or lost, as the verdict's detail.
    pub fn on_time(&self) -> Result<String, String> {
        let late = self.first_late.as_ref().map(|first| {
            format!(
                "{} of {} readings late; first: {first}",
                self.late,
                self.readings()
            )
        });
        match (&self.lost, late) {
            (Some(lost), Some(late)) => Err(format!("{lost}; {late}")),
            (Some(lost), None) => Err(lost.clone()),
            (None, Some(late)) => Err(late),
            (None, None) => match self.intervals.stats() {
                None => Err("fewer than two readings: no interval to check".to_owned()),
                Some(stats) => Ok(format!(
                    "{} readings, intervals min {:.3} / median {:.3} / p99 {:.3} / max {:.3} ms (period {:.3} ms), all within the watchdog's {:.3} ms",
                    self.readings(),
                    stats.min_s * 1e3,
                    stats.median_s * 1e3,
                    stats.p99_s * 1e3,
                    stats.max_s * 1e3,
                    self.period_s * 1e3,
                    self.allowance_s * 1e3
                )),
            },
        }
    }

    /// `reading_rate`: `Ok` (the rate measured) when the node's period is within
    /// [`RATE_TOLERANCE`] of the declared one; `Err` says what it is.
    ///
    /// # Errors
    /// The rate measured, or why none could be, as the verdict's detail.
    pub fn rate(&self) -> Result<String, String> {
        if let Some(lost) = &self.lost {
            return Err(format!(
                "not measured: the readings stopped after {} ({lost})",
                self.readings()
            ));
        }
        let Some(error) = self.period_error() else {
            return Err(format!(
                "{} readings: too few to measure the node's rate (at least {} needed)",
                self.readings(),
                2 * RATE_SEGMENTS
            ));
        };
        let declared_hz = 1.0 / self.period_s;
        let measured = format!(
            "the node reads at {:.2} Hz, {:+.3} % from the declared {declared_hz:.2} Hz over {} readings",
            declared_hz / (1.0 + error),
            -error / (1.0 + error) * 100.0,
            self.readings()
        );
        if error.abs() <= RATE_TOLERANCE {
            Ok(format!("{measured} (within {} %)", RATE_TOLERANCE * 100.0))
        } else {
            Err(format!(
                "{measured}, beyond {} % (its periods {:.3} us, declared {:.3} us)",
                RATE_TOLERANCE * 100.0,
                self.period_s * (1.0 + error) * 1e6,
                self.period_s * 1e6
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PERIOD_S: f64 = 1.0 / 2736.0;
    const ALLOWANCE_S: f64 = 0.1;

    /// `n` readings of a node whose periods are `factor` times the declared one, each delayed
    /// by `delay_s(k)`.
    fn clock(n: u64, factor: f64, delay_s: impl Fn(u64) -> f64) -> ReadingClock {
        let mut clock = ReadingClock::new(PERIOD_S, ALLOWANCE_S);
        for k in 0..n {
            clock.arrived(k, k, k as f64 * PERIOD_S * factor + delay_s(k));
        }
        clock
    }

    /// Delays as a loaded machine gives them: readings read in chunks of 13, and every
    /// 0.35 s a 30 ms stall after which the readings held up arrive at once.
    fn loaded(k: u64) -> f64 {
        let nominal_s = k as f64 * PERIOD_S;
        let read_s = (k / 13 + 1) as f64 * 13.0 * PERIOD_S;
        let stall_start_s = (read_s / 0.35).floor() * 0.35;
        let arrival_s = if read_s < stall_start_s + 0.03 {
            stall_start_s + 0.03
        } else {
            read_s
        };
        arrival_s - nominal_s
    }

    #[test]
    fn the_rate_is_measured_through_chunks_and_stalls() {
        for factor in [1.0, 1.0001, 0.999] {
            let error = clock(2736, factor, loaded).period_error().unwrap();
            assert!((error - (factor - 1.0)).abs() < 2e-4, "{factor}: {error}");
        }
        let steady = clock(2736, 1.0, loaded);
        let rate = steady.rate().unwrap();
        assert!(
            rate.contains("+0.000 % from the declared 2736.00 Hz"),
            "{rate}"
        );
    }

    #[test]
    fn a_stall_that_delays_every_later_reading_leaves_the_rate_alone_but_is_late() {
        let stalled = clock(2736, 1.0, |k| if k >= 1000 { 0.15 } else { 0.0 });
        assert!(stalled.period_error().unwrap().abs() < 1e-9);
        let late = stalled.on_time().unwrap_err();
        assert!(
            late.starts_with("1 of 2736 readings late; first: reading 1000 came 150.365 ms after the one before, beyond the watchdog's 100.000 ms"),
            "{late}"
        );
        let steady = clock(2736, 1.0, loaded).on_time().unwrap();
        assert!(
            steady.contains("2736 readings, intervals min 0.000"),
            "{steady}"
        );
        assert!(
            steady.contains("within the watchdog's 100.000 ms"),
            "{steady}"
        );
    }

    #[test]
    fn a_node_off_its_rate_fails_by_how_much() {
        let slow = clock(2736, 1.05, loaded).rate().unwrap_err();
        assert!(
            slow.contains("the node reads at 2605.71 Hz, -4.762 % from the declared 2736.00 Hz"),
            "{slow}"
        );
        assert!(slow.contains("beyond 2 %"), "{slow}");
        let fast = clock(2736, 0.97, loaded).rate().unwrap_err();
        assert!(fast.contains("+3.093 %"), "{fast}");
        // The first 1000 readings held up 20 ms (a congested start): each stretch's earliest
        // arrival is still on the node's clock, so the 5 % shows whole.
        let congested = clock(2736, 1.05, |k| if k < 1000 { 0.02 } else { 0.0 });
        assert!((congested.period_error().unwrap() - 0.05).abs() < 1e-9);
        // Two readings a stretch are enough.
        assert!(clock(32, 1.0, |_| 0.0).period_error().is_some());
        let within = clock(2736, 1.019, |_| 0.0).rate();
        assert!(within.is_ok_and(|ok| ok.contains("within 2 %")));
        let too_few = clock(31, 1.0, |_| 0.0).rate().unwrap_err();
        assert!(too_few.contains("31 readings: too few"), "{too_few}");
    }

    #[test]
    fn skipped_counters_are_missed_readings() {
        let mut clock = ReadingClock::new(PERIOD_S, ALLOWANCE_S);
        clock.arrived(0, 0, 0.0);
        clock.arrived(1, 1, PERIOD_S);
        clock.arrived(5, 2, 5.0 * PERIOD_S);
        clock.arrived(7, 6, 7.0 * PERIOD_S);
        assert_eq!(clock.missed(), (4, Some("readings 2 to 4 never came")));
        let mut once = ReadingClock::new(PERIOD_S, ALLOWANCE_S);
        once.arrived(0, 0, 0.0);
        once.arrived(2, 1, ALLOWANCE_S);
        assert_eq!(once.missed(), (1, Some("reading 1 never came")));
        // A silence of exactly the allowance is within it.
        assert!(once.on_time().is_ok());
        assert_eq!(clock.readings(), 4);
        assert!(clock.on_time().is_ok());
        clock.lost = Some("period 6: no reading".to_owned());
        assert_eq!(clock.on_time().unwrap_err(), "period 6: no reading");
        assert_eq!(
            clock.rate().unwrap_err(),
            "not measured: the readings stopped after 4 (period 6: no reading)"
        );
    }
}
