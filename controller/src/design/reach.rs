//! How far a control rate carries each rule: the highest trajectory frequencies its design
//! tracks to 1 % (rms error over the reference's peak, as the scan reports it), with the
//! margins kept.
//!
//! - PID: the alpha-tuned PID with the highest crossover that keeps the margins
//!   ([`DesignRequest::highest_pid`]); the highest sine frequency whose error `|S| / sqrt 2`
//!   stays within 1 %.
//! - Dual-tone: the trajectory's drive frequencies scaled together (their ratio kept) to the
//!   highest factor whose design keeps the margins and predicts at most 1 % on every axis
//!   (prewarp frequencies scaled with them).
//!   At a high rate the tones' damping sets the limit (the error at a tone is about
//!   `damping f / width`); towards Nyquist the margins do.

use serde::Serialize;

use super::alpha_tuning::AlphaTuning;
use super::tones::ToneRule;
use super::{DesignRequest, Rule};
use crate::discretise::Method;
use crate::steady_state::PredictedTracking;
use crate::trajectory::Trajectory;

/// The tracking error the reach is measured at: 1 % rms of the peak.
pub const TRACK_TO: f64 = 0.01;

/// What the PID rule reaches at a rate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PidReach {
    /// The highest crossover that keeps the margins, Hz.
    pub crossover_hz: f64,
    /// The highest sine frequency tracked to 1 %, Hz.
    pub sine_hz: f64,
}

/// What the dual-tone rule reaches at a rate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ToneReach {
    /// The highest drive frequencies (the trajectory's, scaled together), Hz.
    pub drive_hz: Vec<f64>,
    /// The predicted error there.
    pub predicted_tracking: PredictedTracking,
}

/// The PID rule's reach (`None`: no alpha-tuned PID keeps the margins at this rate).
#[must_use]
pub fn pid_reach(request: &DesignRequest, template: &AlphaTuning) -> Option<PidReach> {
    let design = request.highest_pid(template).ok()?;
    let controller = design.settings.build().ok()?;
    let nominal = design.settings.nominal_loop(controller.axis());
    let error = |f: f64| (nominal.loop_gain(f) + 1.0).inv().norm() / std::f64::consts::SQRT_2;
    let nyquist = request.rate_hz / 2.0;
    let mut tracked = None;
    let mut f = 1e-3;
    while f < nyquist && error(f) <= TRACK_TO {
        tracked = Some(f);
        f *= 1.01;
    }
    let mut low = tracked?;
    let mut high = f.min(nyquist);
    for _ in 0..40 {
        let mid = (low * high).sqrt();
        if error(mid) <= TRACK_TO {
            low = mid;
        } else {
            high = mid;
        }
    }
    let crossover_hz = match &design.rule {
        Rule::AlphaTuning(tuning) => tuning.crossover_hz,
        Rule::DualTone(_) => unreachable!("highest_pid designs PIDs"),
    };
    Some(PidReach {
        crossover_hz,
        sine_hz: low,
    })
}

/// The dual-tone rule's reach for the request's trajectory (a Lissajous or a sine), with the
/// template's width, damping and roll-off (`None`: no trajectory of sines, or no scaling
/// works).
#[must_use]
pub fn tone_reach(request: &DesignRequest, template: &ToneRule) -> Option<ToneReach> {
    let trajectory = request.trajectory.as_ref()?;
    let top_hz = request.drive_hz().into_iter().reduce(f64::max)?;
    let nyquist = request.rate_hz / 2.0;
    let attempt = |factor: f64| -> Option<ToneReach> {
        let scaled = with_drive_scaled(trajectory, factor)?;
        let method = match &request.method {
            Method::TustinPrewarped { prewarp_hz } => Method::TustinPrewarped {
                prewarp_hz: prewarp_hz.iter().map(|f| f * factor).collect(),
            },
            other => other.clone(),
        };
        let scaled_request = DesignRequest {
            trajectory: Some(scaled),
            method,
            ..request.clone()
        };
        let rule = ToneRule {
            tones_hz: scaled_request.drive_hz(),
            ..template.clone()
        };
        let design = scaled_request.design(&Rule::DualTone(rule.clone())).ok()?;
        let predicted = design.figures.predicted_tracking?;
        let within = [predicted.alpha_rms_relative, predicted.beta_rms_relative]
            .into_iter()
            .flatten()
            .all(|e| e <= TRACK_TO);
        within.then_some(ToneReach {
            drive_hz: rule.tones_hz,
            predicted_tracking: predicted,
        })
    };
    let mut failed = 0.999 * nyquist / top_hz;
    if let Some(reach) = attempt(failed) {
        return Some(reach);
    }
    let (mut passed, mut reach) = (failed, None);
    for _ in 0..40 {
        passed *= 0.8;
        reach = attempt(passed);
        if reach.is_some() {
            break;
        }
        failed = passed;
    }
    let mut reach = reach?;
    for _ in 0..12 {
        let mid = (passed * failed).sqrt();
        match attempt(mid) {
            Some(found) => {
                passed = mid;
                reach = found;
            }
            None => failed = mid,
        }
    }
    Some(reach)
}

/// The trajectory with its frequencies multiplied by `factor` (Lissajous and sine only).
fn with_drive_scaled(trajectory: &Trajectory, factor: f64) -> Option<Trajectory> {
    let mut scaled = trajectory.clone();
    match &mut scaled {
        Trajectory::Lissajous {
            alpha_hz, beta_hz, ..
        } => {
            *alpha_hz *= factor;
            *beta_hz *= factor;
        }
        Trajectory::Sine { frequency_hz, .. } => *frequency_hz *= factor,
        _ => return None,
    }
    Some(scaled)
}
