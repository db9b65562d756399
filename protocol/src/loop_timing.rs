//! Period timing of a real-time loop, reported the same way by both ends (the emulator as
//! clock master and the controller answering it): period jitter as min / median / p99 / max of
//! the measured periods, and the count of overruns (periods whose work missed the deadline).
//!
//! Pure arithmetic on durations the caller measured; nothing here reads a clock.

/// Collects measured periods (or answer latencies) and counts overruns.
#[derive(Debug, Clone, Default)]
pub struct PeriodRecorder {
    samples_s: Vec<f64>,
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
    /// An empty recorder with room for `capacity` periods.
    #[must_use]
    pub fn with_capacity(capacity: usize) -> PeriodRecorder {
        PeriodRecorder {
            samples_s: Vec::with_capacity(capacity),
            overruns: 0,
        }
    }

    /// Records one measured period (or latency), in seconds. Non-finite values are ignored.
    pub fn record(&mut self, measured_s: f64) {
        if measured_s.is_finite() {
            self.samples_s.push(measured_s);
        }
    }

    /// Counts one missed deadline.
    pub fn overrun(&mut self) {
        self.overruns += 1;
    }

    /// The summary against a nominal period; `None` when nothing was recorded.
    #[must_use]
    pub fn stats(&self, nominal_s: f64) -> Option<PeriodStats> {
        if self.samples_s.is_empty() {
            return None;
        }
        let mut sorted = self.samples_s.clone();
        sorted.sort_by(f64::total_cmp);
        let rank = |q: f64| {
            let index = (q * sorted.len() as f64).ceil() as usize;
            sorted[index.clamp(1, sorted.len()) - 1]
        };
        Some(PeriodStats {
            periods: sorted.len() as u64,
            nominal_s,
            min_s: sorted[0],
            median_s: rank(0.5),
            p99_s: rank(0.99),
            max_s: sorted[sorted.len() - 1],
            overruns: self.overruns,
            above_nominal: sorted.iter().filter(|&&v| v > nominal_s).count() as u64,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles_of_one_to_hundred() {
        let mut recorder = PeriodRecorder::default();
        for i in (1..=100).rev() {
            recorder.record(f64::from(i));
        }
        recorder.record(f64::NAN);
        recorder.overrun();
        let stats = recorder.stats(50.0).expect("samples were recorded");
        assert_eq!(stats.periods, 100);
        assert_eq!((stats.min_s, stats.median_s), (1.0, 50.0));
        assert_eq!((stats.p99_s, stats.max_s), (99.0, 100.0));
        assert_eq!(stats.overruns, 1);
        assert_eq!(stats.above_nominal, 50, "51..=100 are above 50");
    }

    #[test]
    fn nothing_recorded_gives_no_stats() {
        assert!(PeriodRecorder::default().stats(1.0).is_none());
    }
}
