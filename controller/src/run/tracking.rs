//! Tracking error: how far the measured mirror angles were from the reference, per sensing
//! axis, over the whole run and over its second half (after the lightly damped mirror's start
//! transient has had time to decay).

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

/// Both stretches the report gives.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct TrackingSummary {
    /// Every period of the run.
    pub whole_run: TrackingError,
    /// The second half of the run.
    pub second_half: TrackingError,
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

    /// The summary over the whole run and its second half.
    #[must_use]
    pub fn summary(&self) -> TrackingSummary {
        let half = self.errors_rad.len() / 2;
        TrackingSummary {
            whole_run: self.over(0),
            second_half: self.over(half),
        }
    }

    fn over(&self, from: usize) -> TrackingError {
        let errors = &self.errors_rad[from..];
        let references = &self.references_rad[from..];
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
        let summary = recorder.summary();
        assert_eq!(summary.whole_run.periods, 4);
        assert_eq!(summary.second_half.periods, 2);
        assert!((summary.whole_run.alpha.rms_urad - 2.0).abs() < 1e-9);
        assert!((summary.whole_run.beta.max_abs_urad - 1.0).abs() < 1e-9);
        assert!((summary.whole_run.alpha.rms_relative - 2e-6 / 3e-3).abs() < 1e-12);
        assert_eq!(summary.whole_run.beta.rms_relative, 0.0);
    }
}
