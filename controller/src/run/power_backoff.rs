//! The host's back-off when the mirror node reports that its coil power limit acted (a
//! PowerLimit fault frame): the reference amplitude ramps down to a scale at which the
//! trajectory's estimated power is within `margin x limit`, along a raised cosine over several
//! periods of the mirror's resonance. Pure: the host loop asks [`PowerBackoff::scale_at`] for
//! each period's reference scale and calls [`PowerBackoff::on_power_limit`] on a fault.
//!
//! Why the ramp does not excite the 22.4 Hz mode: the reference becomes `e(t) r(t)`, whose
//! spectrum is `r`'s lines convolved with the envelope's. A raised cosine of length `T_r` has
//! a spectrum confined below about `2 / T_r` (its side lobes fall as `1/f^3`): over ten
//! resonance periods (0.45 s) that is 4.5 Hz, so a 60 Hz drive only gains sidebands at
//! 60 +- 4.5 Hz, nowhere near 22.4 Hz, and the loop stays linear (no clamp gain inside it).
//! The node's clamp, in contrast, scales the currents period by period inside the loop, a
//! time-varying gain that the loop answers with its lightly damped mode.
//!
//! Target: with the trajectory's estimate `P` (W at scale 1, from [`crate::power_budget`]),
//! `sqrt(margin limit / P)`, and no more than the current cap (the scale at which the estimated
//! peak axis current is `margin` times the controller's command limit: a loop left saturated
//! stays nonlinear, and saturation excites the mode as the clamp does); when that is not below
//! the present scale (the estimate was wrong) or there is no estimate, the present scale times
//! `margin`. Faults that arrive during
//! a ramp are counted, not acted on: the ramp is already taking the power down.

use serde::Serialize;

/// Ramps last this many periods of the plant's resonance.
pub const RAMP_RESONANCE_PERIODS: f64 = 10.0;

/// One back-off the host made.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BackoffStep {
    /// The period whose reading brought the fault.
    pub period: u64,
    /// The reference scale before the ramp.
    pub from_scale: f64,
    /// The reference scale after it.
    pub to_scale: f64,
    /// The ramp's length, periods.
    pub ramp_periods: u64,
}

/// What the back-off did in a run (in report.json).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BackoffLog {
    /// The ramps, in order.
    pub steps: Vec<BackoffStep>,
    /// PowerLimit faults received while a ramp was running (not acted on).
    pub faults_during_ramps: u64,
    /// The reference scale at the end.
    pub final_scale: f64,
}

/// The back-off state machine.
#[derive(Debug, Clone, PartialEq)]
pub struct PowerBackoff {
    active: bool,
    estimate_w: Option<f64>,
    current_cap: f64,
    budget_w: f64,
    margin: f64,
    ramp_periods: u64,
    from: f64,
    to: f64,
    start: u64,
    steps: Vec<BackoffStep>,
    faults_during_ramps: u64,
}

impl PowerBackoff {
    /// A back-off that never acts (scale 1 throughout).
    #[must_use]
    pub fn inactive() -> PowerBackoff {
        PowerBackoff {
            active: false,
            estimate_w: None,
            current_cap: f64::INFINITY,
            budget_w: 0.0,
            margin: 1.0,
            ramp_periods: 1,
            from: 1.0,
            to: 1.0,
            start: 0,
            steps: Vec::new(),
            faults_during_ramps: 0,
        }
    }

    /// A back-off for a trajectory estimated at `estimate_w` (None: unknown) against
    /// `margin x limit_w`, ramping over `ramp_periods` control periods.
    #[must_use]
    pub fn new(
        estimate_w: Option<f64>,
        limit_w: f64,
        margin: f64,
        ramp_periods: u64,
    ) -> PowerBackoff {
        PowerBackoff {
            active: true,
            estimate_w: estimate_w.filter(|w| w.is_finite() && *w > 0.0),
            budget_w: margin * limit_w,
            margin,
            ramp_periods: ramp_periods.max(1),
            ..PowerBackoff::inactive()
        }
    }

    /// The same back-off never ramping above `scale` (the current cap; see the module doc).
    #[must_use]
    pub fn with_current_cap(mut self, scale: f64) -> PowerBackoff {
        if scale.is_finite() && scale > 0.0 {
            self.current_cap = scale;
        }
        self
    }

    /// The ramp length for a plant resonance at `resonance_hz` and a control period `period_s`:
    /// [`RAMP_RESONANCE_PERIODS`] periods of the resonance.
    #[must_use]
    pub fn ramp_periods_for(resonance_hz: f64, period_s: f64) -> u64 {
        (RAMP_RESONANCE_PERIODS / resonance_hz / period_s).round() as u64
    }

    /// The reference scale of period `k`: a raised cosine from the last ramp's start to its
    /// target, then the target.
    #[must_use]
    pub fn scale_at(&self, k: u64) -> f64 {
        if k <= self.start {
            return if self.steps.is_empty() {
                self.to
            } else {
                self.from
            };
        }
        let x = (k - self.start) as f64 / self.ramp_periods as f64;
        if x >= 1.0 {
            self.to
        } else {
            let w = 0.5 * (1.0 - (std::f64::consts::PI * x).cos());
            self.from + (self.to - self.from) * w
        }
    }

    /// The node reported its power limit in the reading of period `k`: start a ramp, unless
    /// one is running.
    pub fn on_power_limit(&mut self, k: u64) {
        if !self.active {
            return;
        }
        if !self.steps.is_empty() && k < self.start + self.ramp_periods {
            self.faults_during_ramps += 1;
            return;
        }
        let present = self.scale_at(k + 1);
        let by_estimate = self
            .estimate_w
            .map(|w| (self.budget_w / w).sqrt().min(self.current_cap));
        let target = match by_estimate {
            Some(scale) if scale < present => scale,
            _ => present * self.margin,
        };
        self.from = present;
        self.to = target;
        self.start = k + 1;
        self.steps.push(BackoffStep {
            period: k,
            from_scale: present,
            to_scale: target,
            ramp_periods: self.ramp_periods,
        });
    }

    /// What it did, or None for an inactive back-off.
    #[must_use]
    pub fn log(&self) -> Option<BackoffLog> {
        self.active.then(|| BackoffLog {
            steps: self.steps.clone(),
            faults_during_ramps: self.faults_during_ramps,
            final_scale: self.to,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inactive_never_scales() {
        let mut backoff = PowerBackoff::inactive();
        backoff.on_power_limit(10);
        assert_eq!(backoff.scale_at(1_000_000), 1.0);
        assert_eq!(backoff.log(), None);
    }

    #[test]
    fn a_fault_ramps_smoothly_to_the_estimated_scale() {
        // 50 W estimated, 0.9 x 30 W allowed: sqrt(27 / 50).
        let mut backoff = PowerBackoff::new(Some(50.0), 30.0, 0.9, 1000);
        assert_eq!(backoff.scale_at(500), 1.0);
        backoff.on_power_limit(500);
        let target = (27.0f64 / 50.0).sqrt();
        assert_eq!(backoff.scale_at(501), 1.0);
        assert!((backoff.scale_at(1001) - (1.0 + target) / 2.0).abs() < 1e-12);
        assert!((backoff.scale_at(1501) - target).abs() < 1e-15);
        assert!((backoff.scale_at(9999) - target).abs() < 1e-15);
        // Monotone, and the largest step per period is pi/2 (1 - target) / N.
        let steps: Vec<f64> = (500..1600).map(|k| backoff.scale_at(k)).collect();
        let max_step = steps
            .windows(2)
            .map(|w| w[0] - w[1])
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(steps.windows(2).all(|w| w[1] <= w[0]));
        assert!(max_step <= std::f64::consts::FRAC_PI_2 * (1.0 - target) / 1000.0 + 1e-12);
        // During the ramp a fault changes nothing; after it, it steps down by the margin.
        backoff.on_power_limit(900);
        assert!((backoff.scale_at(1501) - target).abs() < 1e-15);
        backoff.on_power_limit(2000);
        assert!((backoff.scale_at(4000) - 0.9 * target).abs() < 1e-12);
        let log = backoff.log().unwrap();
        assert_eq!(log.steps.len(), 2);
        assert_eq!(log.faults_during_ramps, 1);
    }

    #[test]
    fn the_current_cap_lowers_the_target() {
        let mut backoff = PowerBackoff::new(Some(50.0), 30.0, 0.9, 10).with_current_cap(0.5);
        backoff.on_power_limit(0);
        assert!((backoff.scale_at(20) - 0.5).abs() < 1e-15);
    }

    #[test]
    fn without_an_estimate_each_fault_takes_the_margin() {
        let mut backoff = PowerBackoff::new(None, 30.0, 0.8, 10);
        backoff.on_power_limit(0);
        assert!((backoff.scale_at(20) - 0.8).abs() < 1e-15);
        assert_eq!(PowerBackoff::ramp_periods_for(22.39, 50e-6), 8933);
    }
}
