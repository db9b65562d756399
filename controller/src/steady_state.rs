//! The steady-state tracking error the nominal loop predicts for a periodic reference.
//!
//! After the transient, each line of the reference's spectrum (a sine: one; a triangle: its
//! odd harmonics up to Nyquist) is tracked with the sensitivity `S = 1 / (1 + L)` of the
//! nominal loop (`L = C P`, discrete, with the one-period command delay), so the error on an
//! axis is periodic with rms `sqrt(sum_n |S(f_n)|^2 a_n^2 / 2)`. Reported relative to the
//! reference's peak, as the loop's tracking error is. The nominal loop is one axis without
//! cross-talk, amplifier dynamics, limits or noise; a loop run on the emulated plant differs
//! from it by those.

use scanhil_protocol::plant_units::SensingAxis;

use crate::loop_analysis::NominalLoop;
use crate::trajectory::Trajectory;

/// The predicted steady-state tracking error of a trajectory, per axis.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PredictedTracking {
    /// Alpha: rms error over the reference's peak (`None`: not periodic, or at rest).
    pub alpha_rms_relative: Option<f64>,
    /// Beta, likewise.
    pub beta_rms_relative: Option<f64>,
}

/// The steady-state error of `trajectory` through `nominal` (see the module doc).
#[must_use]
pub fn predict(nominal: &NominalLoop, trajectory: &Trajectory) -> PredictedTracking {
    let tones = trajectory.tones(0.5 / nominal.period_s());
    let axis = |axis: SensingAxis| {
        let peak = trajectory.peak_rad(axis);
        if !trajectory.is_periodic() || peak == 0.0 {
            return None;
        }
        let power: f64 = tones
            .iter()
            .map(|tone| {
                let s = (nominal.loop_gain(tone.f_hz) + 1.0).inv();
                let amplitude = match axis {
                    SensingAxis::Alpha => tone.alpha_rad,
                    SensingAxis::Beta => tone.beta_rad,
                };
                s.norm_sqr() * amplitude.norm_sqr() / 2.0
            })
            .sum();
        Some(power.sqrt() / peak)
    };
    PredictedTracking {
        alpha_rms_relative: axis(SensingAxis::Alpha),
        beta_rms_relative: axis(SensingAxis::Beta),
    }
}
