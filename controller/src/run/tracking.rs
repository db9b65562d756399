//! Tracking error: how far the measured mirror angles were from the reference, per sensing
//! axis: over the recorded frame (the steady-state figure), over the lead-in before it, over
//! the whole run, and per window of [`WINDOW_S`] so the start-up transient can be seen
//! decaying. Relative figures are the rms error over the reference's peak in the same stretch.

use scanhil_protocol::plant_units::{SensingAxis, SensingPair};

/// Error statistics of one axis, in microradians, with the reference's and the measured
/// angle's extent over the same stretch (what the run's verdict judges motion by).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct AxisError {
    /// Root mean square error, urad.
    pub rms_urad: f64,
    /// Largest absolute error, urad.
    pub max_abs_urad: f64,
    /// RMS error as a fraction of the reference's peak magnitude (0 when the reference is 0).
    pub rms_relative: f64,
    /// The reference's peak magnitude, urad.
    pub reference_peak_urad: f64,
    /// The reference's span (largest minus smallest), urad.
    pub reference_span_urad: f64,
    /// The measured angle's span (largest minus smallest), urad: 0 for a mirror that never
    /// moved.
    pub measured_span_urad: f64,
}

/// Tracking error of both axes over a stretch of the run.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct TrackingError {
    /// Periods included.
    pub periods: u64,
    /// The alpha axis.
    pub alpha: AxisError,
    /// The beta axis.
    pub beta: AxisError,
}

impl TrackingError {
    /// The figures of `axis`.
    #[must_use]
    pub fn axis(&self, axis: SensingAxis) -> AxisError {
        match axis {
            SensingAxis::Alpha => self.alpha,
            SensingAxis::Beta => self.beta,
        }
    }
}

/// The length of a tracking window, s.
pub const WINDOW_S: f64 = 0.05;

/// The stretches the report gives.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct TrackingSummary {
    /// The recorded frame: the steady-state figure.
    pub frame: TrackingError,
    /// The lead-in before the frame (`None` without one).
    pub lead_in: Option<TrackingError>,
    /// Every period of the run.
    pub whole_run: TrackingError,
    /// Consecutive windows of [`WINDOW_S`] over the whole run.
    pub windows: Vec<WindowError>,
}

/// The relative tracking error over one window.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct WindowError {
    /// The window's start in loop time, s.
    pub start_s: f64,
    /// Alpha's rms error over the reference's peak.
    pub alpha_rms_relative: f64,
    /// Beta's.
    pub beta_rms_relative: f64,
}

/// Points the tracking plot keeps at most (about; every `stride`-th period of the planned run).
pub const PLOT_POINTS: u64 = 4000;

/// One period kept for the tracking plot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlotPoint {
    /// Loop time of the reading, s.
    pub t_s: f64,
    /// The measured angles, rad.
    pub measured_rad: SensingPair,
    /// Measured minus reference, rad.
    pub error_rad: SensingPair,
}

/// The smallest and largest value of one axis seen so far.
#[derive(Debug, Clone, Copy)]
struct Extent {
    min: f64,
    max: f64,
}

impl Default for Extent {
    fn default() -> Extent {
        Extent {
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
        }
    }
}

impl Extent {
    fn add(&mut self, value: f64) {
        self.min = self.min.min(value);
        self.max = self.max.max(value);
    }

    /// Largest minus smallest; 0 before any value.
    fn span(&self) -> f64 {
        if self.max >= self.min {
            self.max - self.min
        } else {
            0.0
        }
    }
}

/// Running error statistics of one stretch: sums, not samples, so a stretch of any length
/// takes the same memory.
#[derive(Debug, Clone, Copy, Default)]
struct Stretch {
    periods: u64,
    squared_error_sum: SensingPair,
    max_abs_error: SensingPair,
    reference_peak: SensingPair,
    reference: [Extent; 2],
    measured: [Extent; 2],
}

impl Stretch {
    fn add(&mut self, reference: SensingPair, error: SensingPair) {
        self.periods += 1;
        let measured = [reference.alpha + error.alpha, reference.beta + error.beta];
        for (i, value) in [reference.alpha, reference.beta].into_iter().enumerate() {
            self.reference[i].add(value);
            self.measured[i].add(measured[i]);
        }
        self.squared_error_sum.alpha += error.alpha.powi(2);
        self.squared_error_sum.beta += error.beta.powi(2);
        self.max_abs_error.alpha = self.max_abs_error.alpha.max(error.alpha.abs());
        self.max_abs_error.beta = self.max_abs_error.beta.max(error.beta.abs());
        self.reference_peak.alpha = self.reference_peak.alpha.max(reference.alpha.abs());
        self.reference_peak.beta = self.reference_peak.beta.max(reference.beta.abs());
    }

    fn error(&self) -> TrackingError {
        let n = self.periods.max(1) as f64;
        let axis = |i: usize, squared_sum: f64, max_abs: f64, peak: f64| {
            let rms = (squared_sum / n).sqrt();
            AxisError {
                rms_urad: rms * 1e6,
                max_abs_urad: max_abs * 1e6,
                rms_relative: if peak > 0.0 { rms / peak } else { 0.0 },
                reference_peak_urad: peak * 1e6,
                reference_span_urad: self.reference[i].span() * 1e6,
                measured_span_urad: self.measured[i].span() * 1e6,
            }
        };
        TrackingError {
            periods: self.periods,
            alpha: axis(
                0,
                self.squared_error_sum.alpha,
                self.max_abs_error.alpha,
                self.reference_peak.alpha,
            ),
            beta: axis(
                1,
                self.squared_error_sum.beta,
                self.max_abs_error.beta,
                self.reference_peak.beta,
            ),
        }
    }
}

/// Accumulates reference and measured angles period by period, in memory that does not grow
/// with the run: running sums per stretch (lead-in, frame, whole run, the current window), one
/// [`WindowError`] per finished window, and every `stride`-th period for the plot
/// ([`PLOT_POINTS`] over the planned run).
#[derive(Debug, Clone)]
pub struct TrackingRecorder {
    period_s: f64,
    lead_in_periods: u64,
    window_periods: u64,
    plot_stride: u64,
    recorded: u64,
    lead_in: Stretch,
    frame: Stretch,
    whole_run: Stretch,
    window: Stretch,
    windows: Vec<WindowError>,
    plot: Vec<PlotPoint>,
}

impl TrackingRecorder {
    /// A recorder for a run of `planned_periods` of `period_s`, the first `lead_in_periods`
    /// of them the lead-in.
    #[must_use]
    pub fn new(period_s: f64, planned_periods: u64, lead_in_periods: u64) -> TrackingRecorder {
        TrackingRecorder {
            period_s,
            lead_in_periods,
            window_periods: ((WINDOW_S / period_s).round() as u64).max(1),
            plot_stride: (planned_periods / PLOT_POINTS).max(1),
            recorded: 0,
            lead_in: Stretch::default(),
            frame: Stretch::default(),
            whole_run: Stretch::default(),
            window: Stretch::default(),
            windows: Vec::new(),
            plot: Vec::new(),
        }
    }

    /// Records the next period: the reference at the sampling instant and the measured angles.
    pub fn record(&mut self, reference_rad: SensingPair, measured_rad: SensingPair) {
        let k = self.recorded;
        let error = SensingPair {
            alpha: measured_rad.alpha - reference_rad.alpha,
            beta: measured_rad.beta - reference_rad.beta,
        };
        if k < self.lead_in_periods {
            self.lead_in.add(reference_rad, error);
        } else {
            self.frame.add(reference_rad, error);
        }
        self.whole_run.add(reference_rad, error);
        self.window.add(reference_rad, error);
        if self.window.periods == self.window_periods {
            self.windows.push(self.window_error(k + 1));
            self.window = Stretch::default();
        }
        if k.is_multiple_of(self.plot_stride) {
            self.plot.push(PlotPoint {
                // Reading k is the angle at (k + 1) periods.
                t_s: (k + 1) as f64 * self.period_s,
                measured_rad,
                error_rad: error,
            });
        }
        self.recorded += 1;
    }

    /// Periods recorded.
    #[must_use]
    pub fn periods(&self) -> u64 {
        self.recorded
    }

    /// The periods kept for plotting.
    #[must_use]
    pub fn plot_points(&self) -> &[PlotPoint] {
        &self.plot
    }

    /// The summary so far (a window still open counts as the last one).
    #[must_use]
    pub fn summary(&self) -> TrackingSummary {
        let mut windows = self.windows.clone();
        if self.window.periods > 0 {
            windows.push(self.window_error(self.recorded));
        }
        TrackingSummary {
            frame: self.frame.error(),
            lead_in: (self.lead_in.periods > 0).then(|| self.lead_in.error()),
            whole_run: self.whole_run.error(),
            windows,
        }
    }

    /// The current window as it stands after `recorded` periods.
    fn window_error(&self, recorded: u64) -> WindowError {
        let error = self.window.error();
        let from = recorded - self.window.periods;
        WindowError {
            // Reading k is the angle at (k + 1) periods.
            start_s: (from + 1) as f64 * self.period_s,
            alpha_rms_relative: error.alpha.rms_relative,
            beta_rms_relative: error.beta.rms_relative,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_error_gives_that_rms_and_max() {
        // Windows of 0.05 s at 0.025 s: two periods each.
        let mut recorder = TrackingRecorder::new(0.025, 4, 1);
        for k in 0..4 {
            let reference = SensingPair {
                alpha: 1e-3 * f64::from(k),
                beta: 0.0,
            };
            let measured = SensingPair {
                alpha: reference.alpha + 2e-6,
                beta: -1e-6,
            };
            recorder.record(reference, measured);
        }
        let summary = recorder.summary();
        assert_eq!(summary.whole_run.periods, 4);
        assert_eq!(summary.frame.periods, 3);
        assert_eq!(summary.lead_in.map(|l| l.periods), Some(1));
        assert_eq!(summary.windows.len(), 2);
        assert!((summary.windows[1].start_s - 0.075).abs() < 1e-12);
        assert!((summary.windows[1].alpha_rms_relative - 2e-6 / 3e-3).abs() < 1e-12);
        assert!((summary.frame.alpha.rms_relative - 2e-6 / 3e-3).abs() < 1e-12);
        assert!((summary.whole_run.alpha.rms_urad - 2.0).abs() < 1e-9);
        assert!((summary.whole_run.beta.max_abs_urad - 1.0).abs() < 1e-9);
        assert!((summary.whole_run.alpha.rms_relative - 2e-6 / 3e-3).abs() < 1e-12);
        assert_eq!(summary.whole_run.beta.rms_relative, 0.0);
        // Extents: the reference 0 to 3 mrad on alpha, beta held at -1 urad.
        let alpha = summary.whole_run.axis(SensingAxis::Alpha);
        assert!((alpha.reference_span_urad - 3000.0).abs() < 1e-9);
        assert!((alpha.measured_span_urad - 3000.0).abs() < 1e-9);
        assert!((alpha.reference_peak_urad - 3000.0).abs() < 1e-9);
        let beta = summary.whole_run.axis(SensingAxis::Beta);
        assert_eq!(
            (beta.reference_span_urad, beta.measured_span_urad),
            (0.0, 0.0)
        );
        assert!((summary.frame.alpha.reference_span_urad - 2000.0).abs() < 1e-9);
        assert_eq!(
            TrackingRecorder::new(0.025, 4, 0)
                .summary()
                .frame
                .alpha
                .measured_span_urad,
            0.0
        );
    }

    #[test]
    fn running_sums_agree_with_the_stretches_computed_whole() {
        // An independent batch computation over the kept series, for a run whose lead-in, frame
        // and last window end mid-window.
        let period_s = 1e-3; // windows of 50 periods
        let (planned, lead_in) = (2_630u64, 725u64);
        let pair = |k: u64| {
            let t = k as f64;
            let reference = SensingPair {
                alpha: 0.01 * (t * 0.013).sin(),
                beta: 0.005 * (t * 0.007).cos(),
            };
            let measured = SensingPair {
                alpha: reference.alpha + 3e-6 * (t * 0.31).sin() + 1e-6 * (-t / 300.0).exp(),
                beta: reference.beta - 2e-6 * (t * 0.17).cos(),
            };
            (reference, measured)
        };
        let mut recorder = TrackingRecorder::new(period_s, planned, lead_in);
        for k in 0..planned {
            let (reference, measured) = pair(k);
            recorder.record(reference, measured);
        }
        let batch = |from: u64, to: u64| {
            let n = (to - from) as f64;
            let (mut squared, mut max_abs, mut peak) = (0.0f64, 0.0f64, 0.0f64);
            for k in from..to {
                let (reference, measured) = pair(k);
                let error = measured.beta - reference.beta;
                squared += error * error;
                max_abs = max_abs.max(error.abs());
                peak = peak.max(reference.beta.abs());
            }
            (
                (squared / n).sqrt() * 1e6,
                max_abs * 1e6,
                (squared / n).sqrt() / peak,
            )
        };
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1e-30);
        let summary = recorder.summary();
        for (stretch, (from, to)) in [
            (summary.frame, (lead_in, planned)),
            (summary.lead_in.unwrap(), (0, lead_in)),
            (summary.whole_run, (0, planned)),
        ] {
            let (rms_urad, max_abs_urad, relative) = batch(from, to);
            assert_eq!(stretch.periods, to - from);
            assert!(close(stretch.beta.rms_urad, rms_urad), "{stretch:?}");
            assert!(
                close(stretch.beta.max_abs_urad, max_abs_urad),
                "{stretch:?}"
            );
            assert!(close(stretch.beta.rms_relative, relative), "{stretch:?}");
        }
        // 52 whole windows and a last one of 30 periods.
        assert_eq!(summary.windows.len(), 53);
        let last = summary.windows[52];
        assert!(close(last.start_s, 2_601.0 * period_s));
        assert!(close(last.beta_rms_relative, batch(2_600, planned).2));
        assert!(close(
            summary.windows[7].beta_rms_relative,
            batch(350, 400).2
        ));
        // The plot keeps every period here (fewer than PLOT_POINTS planned), at (k + 1) Ta.
        assert_eq!(recorder.plot_points().len() as u64, planned);
        let point = recorder.plot_points()[9];
        assert!(close(point.t_s, 10.0 * period_s));
        assert!(close(point.error_rad.beta, pair(9).1.beta - pair(9).0.beta));
    }

    #[test]
    fn the_plot_keeps_about_plot_points_of_a_long_run() {
        let planned = 1_000_000;
        let mut recorder = TrackingRecorder::new(5e-5, planned, 0);
        for _ in 0..planned {
            recorder.record(SensingPair::default(), SensingPair::default());
        }
        assert_eq!(recorder.plot_points().len() as u64, PLOT_POINTS);
        assert_eq!(recorder.summary().windows.len(), 1_000);
        assert_eq!(recorder.summary().whole_run.periods, planned);
    }
}
