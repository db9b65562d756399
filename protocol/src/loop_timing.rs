//! Period timing of a real-time loop, reported the same way by both ends (the emulator as
//! clock master and the controller answering it): period jitter as min / median / p99 / max of
//! the measured periods, and the count of overruns (periods whose work missed the deadline).
//!
//! Also who missed a deadline: each period the clock master stepped without a fresh command
//! is attributed to the side whose own timestamps show the larger delay ([`attribute_misses`]).
//!
//! Pure arithmetic on durations the caller measured; nothing here reads a clock.

/// The longest value the percentiles resolve, ns (an hour; longer ones count as an hour there).
const HISTOGRAM_MAX_NS: u64 = 3_600_000_000_000;

/// Collects measured periods (or answer latencies) against a nominal period and counts
/// overruns, in memory that does not grow with the run: the count, the extremes and the
/// values above the nominal period are kept exactly, the median and the 99th percentile come
/// from a histogram of nanoseconds with 3 significant digits ([`hdrhistogram`]: within 0.1 %,
/// under 300 KB whatever the run's length).
#[derive(Debug, Clone)]
pub struct PeriodRecorder {
    nominal_s: f64,
    histogram_ns: hdrhistogram::Histogram<u64>,
    periods: u64,
    min_s: f64,
    max_s: f64,
    above_nominal: u64,
    overruns: u64,
}

/// Summary of a [`PeriodRecorder`]: what a run report says about its timing.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PeriodStats {
    /// How many periods were measured.
    pub periods: u64,
    /// The nominal period, in seconds.
    pub nominal_s: f64,
    /// Shortest measured period, in seconds.
    pub min_s: f64,
    /// Median measured period, in seconds.
    pub median_s: f64,
    /// 99th percentile of the measured periods (nearest rank), in seconds.
    pub p99_s: f64,
    /// Longest measured period, in seconds.
    pub max_s: f64,
    /// Periods whose deadline was missed.
    pub overruns: u64,
    /// Measured values above the nominal period, counted from the same samples as the
    /// percentiles (where an overrun means "longer than one period", as for an answer latency,
    /// it must equal `overruns`: a check on the bookkeeping that can fail).
    #[serde(default)]
    pub above_nominal: u64,
}

impl PeriodRecorder {
    /// An empty recorder of periods (or latencies) against `nominal_s`.
    #[must_use]
    pub fn new(nominal_s: f64) -> PeriodRecorder {
        PeriodRecorder {
            nominal_s,
            histogram_ns: hdrhistogram::Histogram::new_with_bounds(1, HISTOGRAM_MAX_NS, 3)
                .expect("bounds and 3 significant digits that hdrhistogram accepts"),
            periods: 0,
            min_s: f64::INFINITY,
            max_s: f64::NEG_INFINITY,
            above_nominal: 0,
            overruns: 0,
        }
    }

    /// Records one measured period (or latency), in seconds. Non-finite values are ignored.
    pub fn record(&mut self, measured_s: f64) {
        if !measured_s.is_finite() {
            return;
        }
        self.periods += 1;
        self.min_s = self.min_s.min(measured_s);
        self.max_s = self.max_s.max(measured_s);
        self.above_nominal += u64::from(measured_s > self.nominal_s);
        // Whole nanoseconds within the histogram's range (the extremes above stay exact).
        let ns = (measured_s * 1e9)
            .round()
            .clamp(1.0, HISTOGRAM_MAX_NS as f64) as u64;
        self.histogram_ns.saturating_record(ns);
    }

    /// Counts one missed deadline.
    pub fn overrun(&mut self) {
        self.overruns += 1;
    }

    /// The summary; `None` when nothing was recorded. The median and the 99th percentile are
    /// the histogram's (nearest rank, within 0.1 %), kept within the exact extremes.
    #[must_use]
    pub fn stats(&self) -> Option<PeriodStats> {
        if self.periods == 0 {
            return None;
        }
        let quantile_s = |q: f64| {
            (self.histogram_ns.value_at_quantile(q) as f64 * 1e-9).clamp(self.min_s, self.max_s)
        };
        Some(PeriodStats {
            periods: self.periods,
            nominal_s: self.nominal_s,
            min_s: self.min_s,
            median_s: quantile_s(0.5),
            p99_s: quantile_s(0.99),
            max_s: self.max_s,
            overruns: self.overruns,
            above_nominal: self.above_nominal,
        })
    }
}

/// A period the clock master stepped without a fresh command for it: a missed deadline, with
/// what the master measured of the reading that command would have answered.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MissedDeadline {
    /// The period that ran on an old command (its command answers reading `period - 1`).
    pub period: u64,
    /// How long after its period's start the master finished sending reading `period - 1`, in
    /// seconds (the node's delay); `None` when that reading's frames were dropped.
    pub reading_late_s: Option<f64>,
}

/// The deadline misses blamed on one side, and by how much that side was late.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct SideMisses {
    /// Misses blamed on this side.
    pub count: u64,
    /// Of them, misses without a measured delay (the node dropped the reading; the host never
    /// answered it).
    pub unmeasured: u64,
    /// The side's longest delay among its misses, in seconds.
    pub worst_s: Option<f64>,
    /// The 99th percentile (nearest rank) of the side's delays among its misses, in seconds.
    pub p99_s: Option<f64>,
}

/// Deadline misses split between the sides; `node.count + host.count + link.count == total`.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct MissAttribution {
    /// Periods the master stepped without a fresh command (period 0, which no reading
    /// precedes, is not a miss).
    pub total: u64,
    /// The node (clock master) late to send the reading: its delay is the reading's lateness
    /// after the period start.
    pub node: SideMisses,
    /// The host late to send the command: its delay is its answer latency (reading in to
    /// command out).
    pub host: SideMisses,
    /// Neither: the node's and the host's delays add up to less than a period, so the link
    /// (transfer, and the wake-up of the reader at either end) took the rest; its delay is
    /// that rest, a lower bound of the round trip's transit.
    pub link: SideMisses,
}

/// Blames each miss on a side, each side's delay measured on its own clock: the node's
/// lateness in sending reading `period - 1` against the host's latency in answering it
/// (`host_latency_s(reading)`, `None` when the host never answered it). When the two add up to
/// less than `period_s` the link took the rest; otherwise the side with the larger delay
/// missed. A dropped reading is the node's; an unanswered one the host's.
pub fn attribute_misses(
    misses: &[MissedDeadline],
    period_s: f64,
    host_latency_s: impl Fn(u64) -> Option<f64>,
) -> MissAttribution {
    let mut node = (SideMisses::default(), PeriodRecorder::new(0.0));
    let mut host = (SideMisses::default(), PeriodRecorder::new(0.0));
    let mut link = (SideMisses::default(), PeriodRecorder::new(0.0));
    for miss in misses {
        let Some(reading) = miss.period.checked_sub(1) else {
            continue;
        };
        let (side, delay_s) = match (miss.reading_late_s, host_latency_s(reading)) {
            (None, _) => (&mut node, None),
            (Some(_), None) => (&mut host, None),
            (Some(node_s), Some(host_s)) if node_s + host_s < period_s => {
                (&mut link, Some(period_s - node_s - host_s))
            }
            (Some(node_s), Some(host_s)) if node_s >= host_s => (&mut node, Some(node_s)),
            (Some(_), Some(host_s)) => (&mut host, Some(host_s)),
        };
        side.0.count += 1;
        match delay_s {
            Some(delay_s) => side.1.record(delay_s),
            None => side.0.unmeasured += 1,
        }
    }
    let summary = |(mut side, delays): (SideMisses, PeriodRecorder)| {
        if let Some(stats) = delays.stats() {
            side.worst_s = Some(stats.max_s);
            side.p99_s = Some(stats.p99_s);
        }
        side
    };
    let (node, host, link) = (summary(node), summary(host), summary(link));
    MissAttribution {
        total: node.count + host.count + link.count,
        node,
        host,
        link,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn miss(period: u64, reading_late_s: Option<f64>) -> MissedDeadline {
        MissedDeadline {
            period,
            reading_late_s,
        }
    }

    #[test]
    fn each_miss_goes_to_the_side_with_the_larger_delay() {
        let misses = [
            miss(0, Some(1.0)),    // period 0 answers no reading: not a miss
            miss(5, Some(45e-6)),  // host answered reading 4 in 10 us: node (55 us in all)
            miss(8, Some(2e-6)),   // host took 60 us over reading 7: host
            miss(9, None),         // the node dropped reading 8: node, unmeasured
            miss(12, Some(5e-6)),  // the host never answered reading 11: host, unmeasured
            miss(20, Some(80e-6)), // node 80 us against host 70 us: node
            miss(30, Some(10e-6)), // 10 + 15 us of a 50 us period: the link took 25 us
        ];
        let host_latency = |reading: u64| match reading {
            4 => Some(10e-6),
            7 => Some(60e-6),
            8 => Some(1.0),
            19 => Some(70e-6),
            29 => Some(15e-6),
            _ => None,
        };
        let blame = attribute_misses(&misses, 50e-6, host_latency);
        assert_eq!(blame.total, 6);
        assert_eq!(
            blame.node.count + blame.host.count + blame.link.count,
            blame.total
        );
        assert_eq!((blame.link.count, blame.link.unmeasured), (1, 0));
        assert!((blame.link.worst_s.unwrap() - 25e-6).abs() < 1e-12);
        assert_eq!((blame.node.count, blame.node.unmeasured), (3, 1));
        assert_eq!((blame.host.count, blame.host.unmeasured), (2, 1));
        assert_eq!(blame.node.worst_s, Some(80e-6));
        assert_eq!(blame.host.worst_s, Some(60e-6));
        assert_eq!(blame.host.p99_s, Some(60e-6));
    }

    #[test]
    fn no_misses_blame_nobody() {
        let blame = attribute_misses(&[], 50e-6, |_| Some(1.0));
        assert_eq!(blame, MissAttribution::default());
        assert_eq!(blame.node.worst_s, None);
    }

    #[test]
    fn nearest_rank_percentiles_of_one_to_hundred() {
        let mut recorder = PeriodRecorder::new(50.0);
        for i in (1..=100).rev() {
            recorder.record(f64::from(i));
        }
        recorder.record(f64::NAN);
        recorder.overrun();
        let stats = recorder.stats().expect("samples were recorded");
        assert_eq!(stats.periods, 100);
        assert_eq!(
            (stats.min_s, stats.max_s),
            (1.0, 100.0),
            "the extremes are exact"
        );
        let within = |got: f64, want: f64| (got - want).abs() <= 1e-3 * want;
        assert!(within(stats.median_s, 50.0), "{}", stats.median_s);
        assert!(within(stats.p99_s, 99.0), "{}", stats.p99_s);
        assert_eq!(stats.overruns, 1);
        assert_eq!(stats.above_nominal, 50, "51..=100 are above 50");
    }

    #[test]
    fn percentiles_of_a_long_run_of_microseconds_stay_within_a_thousandth() {
        // Two million 20 kHz periods spread over 40-60 us with a tail: memory stays the
        // histogram's, and the percentiles agree with the sorted values to 0.1 %.
        let mut recorder = PeriodRecorder::new(50e-6);
        let mut values: Vec<f64> = (0..2_000_000u64)
            .map(|i| 40e-6 + 20e-6 * ((i * 7919) % 10_007) as f64 / 10_007.0)
            .chain([3e-3, 8e-3])
            .collect();
        for &value in &values {
            recorder.record(value);
        }
        values.sort_by(f64::total_cmp);
        let rank = |q: f64| values[(q * values.len() as f64).ceil() as usize - 1];
        let stats = recorder.stats().expect("recorded");
        for (got, want) in [(stats.median_s, rank(0.5)), (stats.p99_s, rank(0.99))] {
            assert!((got - want).abs() <= 1e-3 * want, "{got} against {want}");
        }
        assert_eq!(stats.max_s, 8e-3);
        assert_eq!(
            stats.above_nominal,
            values.iter().filter(|&&v| v > 50e-6).count() as u64
        );
    }

    #[test]
    fn nothing_recorded_gives_no_stats() {
        assert!(PeriodRecorder::new(1.0).stats().is_none());
    }
}
