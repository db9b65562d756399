//! Tracking error: how far the measured mirror angles were from the reference, per sensing
//! axis: over the recorded frame (the steady-state figure), over the lead-in before it, over
//! the whole run, and per window of [`WINDOW_S`] so the start-up transient can be seen
//! decaying. Relative figures are the rms error over the reference's peak in the same stretch.

use scanhil_protocol::plant_units::SensingPair;

/// Error statistics of one axis, in microradians.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct AxisError {
    /// Root mean square error, urad.
    pub rms_urad: f64,
    /// Largest absolute error, urad.
    pub max_abs_urad: f64,
    /// RMS error as a fraction of the reference's peak magnitude (0 when the reference is 0).
    pub rms_relative: f64,
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

/// Accumulates reference and measured angles period by period.
#[derive(Debug, Clone, Default)]
pub struct TrackingRecorder {
    errors_rad: Vec<SensingPair>,
    references_rad: Vec<SensingPair>,
}

impl TrackingRecorder {
    /// Records one period: the reference at the sampling instant and the measured angles.
    pub fn record(&mut self, reference_rad: SensingPair, measured_rad: SensingPair) {
        self.references_rad.push(reference_rad);
        self.errors_rad.push(SensingPair {
            alpha: measured_rad.alpha - reference_rad.alpha,
            beta: measured_rad.beta - reference_rad.beta,
        });
    }

    /// The per-period errors, in rad (for plots).
    #[must_use]
    pub fn errors_rad(&self) -> &[SensingPair] {
        &self.errors_rad
    }

    /// The summary of a run whose first `lead_in_periods` periods were the lead-in, with
    /// windows of [`WINDOW_S`] at `period_s`.
    #[must_use]
    pub fn summary(&self, lead_in_periods: u64, period_s: f64) -> TrackingSummary {
        let n = self.errors_rad.len();
        let split = usize::try_from(lead_in_periods)
            .unwrap_or(usize::MAX)
            .min(n);
        let window = ((WINDOW_S / period_s).round() as usize).max(1);
        let windows = (0..n)
            .step_by(window)
            .map(|from| {
                let stretch = self.over(from..(from + window).min(n));
                WindowError {
                    // Reading k is the angle at (k + 1) periods.
                    start_s: (from + 1) as f64 * period_s,
                    alpha_rms_relative: stretch.alpha.rms_relative,
                    beta_rms_relative: stretch.beta.rms_relative,
                }
            })
            .collect();
        TrackingSummary {
            frame: self.over(split..n),
            lead_in: (split > 0).then(|| self.over(0..split)),
            whole_run: self.over(0..n),
            windows,
        }
    }

    fn over(&self, periods: std::ops::Range<usize>) -> TrackingError {
        let errors = &self.errors_rad[periods.clone()];
        let references = &self.references_rad[periods];
        let axis = |error: fn(&SensingPair) -> f64| {
            let n = errors.len().max(1) as f64;
            let rms = (errors.iter().map(|e| error(e).powi(2)).sum::<f64>() / n).sqrt();
            let max_abs = errors.iter().map(|e| error(e).abs()).fold(0.0, f64::max);
            let peak = references
                .iter()
                .map(|r| error(r).abs())
                .fold(0.0, f64::max);
            AxisError {
                rms_urad: rms * 1e6,
                max_abs_urad: max_abs * 1e6,
                rms_relative: if peak > 0.0 { rms / peak } else { 0.0 },
            }
        };
        TrackingError {
            periods: errors.len() as u64,
            alpha: axis(|p| p.alpha),
            beta: axis(|p| p.beta),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_error_gives_that_rms_and_max() {
        let mut recorder = TrackingRecorder::default();
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
        let summary = recorder.summary(1, 0.025);
        assert_eq!(summary.whole_run.periods, 4);
        assert_eq!(summary.frame.periods, 3);
        assert_eq!(summary.lead_in.map(|l| l.periods), Some(1));
        // Windows of 0.05 s at 0.025 s: two periods each.
        assert_eq!(summary.windows.len(), 2);
        assert!((summary.windows[1].start_s - 0.075).abs() < 1e-12);
        assert!((summary.windows[1].alpha_rms_relative - 2e-6 / 3e-3).abs() < 1e-12);
        assert!((summary.frame.alpha.rms_relative - 2e-6 / 3e-3).abs() < 1e-12);
        assert!((summary.whole_run.alpha.rms_urad - 2.0).abs() < 1e-9);
        assert!((summary.whole_run.beta.max_abs_urad - 1.0).abs() < 1e-9);
        assert!((summary.whole_run.alpha.rms_relative - 2e-6 / 3e-3).abs() < 1e-12);
        assert_eq!(summary.whole_run.beta.rms_relative, 0.0);
    }
}
