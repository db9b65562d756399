//! Coil resistance and the dissipated-power limit.
//!
//! The coil resistance is derived from the model, not chosen freely. The paper says the coil
//! power limit (30 W, "the peak power dissipation of the FSM") is reached at a drive frequency
//! of 52 Hz, the highest at which the full scan range is still reached. A full-range
//! (+-10 output units = +-1.5 deg) sine at 52 Hz on one sensing axis takes a current amplitude
//! `I = 10 / |G(j 2 pi 52)| * AMPS_PER_INPUT_UNIT` (3.856 A with the paper's model). scanhil
//! reads the sentence as: **a full-range 52 Hz sine on both sensing axes at once dissipates
//! 30 W on average** (equivalently: one full-range 52 Hz sine peaks at 30 W). The 45 degree
//! rotation preserves `i_a^2 + i_b^2`, so that drive's mean power over both coil axes is
//! `R (I^2/2 + I^2/2) = R I^2`, and `R = 30 W / I^2` (2.0172 ohm per actuator axis).
//!
//! The earlier reading, one full-range sine on one axis at 30 W mean (`R = 2 * 30 W / I^2`,
//! 4.034 ohm), leaves the paper's own scans over the limit: the host's estimate puts the
//! 52/27 Hz Lissajous under the dual-tone (cross-talk compensated) at 30.3 W and the 2/34 Hz
//! raster under the PID at 47.1 W. Under this reading they need 15.1 W and 23.6 W
//! (`docs/paper-readings.md`).
//!
//! The limit is on the mean power over a sliding rectangular thermal window (default 1 s, an
//! integer number of power cycles for 27 Hz and 52 Hz drives), computed from the coil currents
//! that act in each period (after the current limit). Before the first window has passed, the
//! missing periods count as zero power (the coils start cold). Over the limit, the scene's
//! `on_exceed` decides: `clamp` scales this period's currents down so the window mean stays at
//! the limit; `fault` latches a fault that holds the currents at zero until reset.

use serde::{Deserialize, Serialize};

use scanhil_protocol::plant_units::{
    AMPS_PER_INPUT_UNIT, ActuatorPair, OUTPUT_UNITS_AT_FULL_RANGE,
};

use crate::mirror::{AxisDynamics, MirrorConfig, SensingAxis};

/// The paper's coil power limit, in W.
pub const PAPER_POWER_LIMIT_W: f64 = 30.0;
/// The drive frequency at which a full-range sine reaches the limit in the paper, in Hz.
pub const PAPER_FULL_RANGE_LIMIT_HZ: f64 = 52.0;

/// A relative tolerance on the limit, so a drive exactly at the limit is not cut by rounding.
const LIMIT_TOLERANCE: f64 = 1e-9;

/// The coil resistance per actuator axis, in ohm, for which full-range sines at 52 Hz on both
/// sensing axes at once dissipate exactly [`PAPER_POWER_LIMIT_W`] on average (see the module
/// doc): `R = 2 x 30 W / (I_alpha^2 + I_beta^2)` with `I` each axis's
/// [`full_range_current_a`] at 52 Hz (`30 W / I^2` when the axes are alike).
#[must_use]
pub fn coil_resistance_ohm(mirror: &MirrorConfig) -> f64 {
    let sum_a2: f64 = SensingAxis::BOTH
        .iter()
        .map(|&axis| full_range_current_a(&mirror.axis(axis), PAPER_FULL_RANGE_LIMIT_HZ).powi(2))
        .sum();
    2.0 * PAPER_POWER_LIMIT_W / sum_a2
}

/// The coil current amplitude (A, on one sensing axis of dynamics `axis`) of a full-range
/// sine at `freq_hz`.
#[must_use]
pub fn full_range_current_a(axis: &AxisDynamics, freq_hz: f64) -> f64 {
    OUTPUT_UNITS_AT_FULL_RANGE / axis.gain_at(std::f64::consts::TAU * freq_hz) * AMPS_PER_INPUT_UNIT
}

/// What happens when the window mean would exceed the limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OnExceed {
    /// Scale the currents down to stay at the limit, and report it.
    Clamp,
    /// Latch a fault: currents held at zero until reset, and report it.
    Fault,
}

/// The coils and their power limit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PowerLimitConfig {
    /// The mean power limit over the window, in W (paper: 30).
    pub limit_w: f64,
    /// The thermal window length, in s.
    pub window_s: f64,
    /// Clamp or fault.
    pub on_exceed: OnExceed,
    /// Coil resistance per actuator axis in ohm; absent = derived by [`coil_resistance_ohm`].
    pub coil_resistance_ohm: Option<f64>,
}

impl Default for PowerLimitConfig {
    fn default() -> Self {
        PowerLimitConfig {
            limit_w: PAPER_POWER_LIMIT_W,
            window_s: 1.0,
            on_exceed: OnExceed::Clamp,
            coil_resistance_ohm: None,
        }
    }
}

/// The longest power-averaging window, s (the paper's bench averages over 1 s).
pub const MAX_WINDOW_S: f64 = 10.0;

impl PowerLimitConfig {
    /// Checks the parameters; on failure, the field name and why.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let positive = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err((
                    format!("power_limit.{name}"),
                    format!("must be finite and > 0, got {v}"),
                ))
            }
        };
        positive("limit_w", self.limit_w)?;
        // The window is held a sample a period: ten seconds at the highest rate is 16 MB.
        scanhil_protocol::validation::Allowed::above(0.0, MAX_WINDOW_S, "s")
            .check("power_limit.window_s", self.window_s)
            .map_err(|invalid| (invalid.field, invalid.reason))?;
        if let Some(r) = self.coil_resistance_ohm {
            positive("coil_resistance_ohm", r)?;
        }
        Ok(())
    }
}

/// What the power monitor did to one period's currents.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PowerAction {
    /// Within the limit, currents unchanged.
    Pass,
    /// Scaled down from `requested_w` to `allowed_w`.
    Clamped {
        /// The power the requested currents would have dissipated this period, in W.
        requested_w: f64,
        /// The power allowed this period, in W.
        allowed_w: f64,
    },
    /// The fault latched in this period; `mean_w` is the window mean it would have reached.
    Faulted {
        /// The window mean the requested currents would have reached, in W.
        mean_w: f64,
    },
    /// A fault latched earlier holds the currents at zero.
    HeldByFault,
}

/// The sliding-window power monitor (one value per control period).
#[derive(Debug, Clone)]
pub struct PowerMonitor {
    resistance_ohm: f64,
    limit_w: f64,
    on_exceed: OnExceed,
    window_w: Vec<f64>,
    next: usize,
    sum_w: f64,
    faulted: bool,
}

impl PowerMonitor {
    /// A cold monitor for control periods of `period_s`.
    #[must_use]
    pub fn new(config: &PowerLimitConfig, resistance_ohm: f64, period_s: f64) -> PowerMonitor {
        let len = ((config.window_s / period_s).round() as usize).max(1);
        PowerMonitor {
            resistance_ohm,
            limit_w: config.limit_w,
            on_exceed: config.on_exceed,
            window_w: vec![0.0; len],
            next: 0,
            sum_w: 0.0,
            faulted: false,
        }
    }

    /// Checks and records one period's currents; returns the currents that may flow.
    pub fn admit(&mut self, currents_a: ActuatorPair) -> (ActuatorPair, PowerAction) {
        let n = self.window_w.len() as f64;
        let others_w = self.sum_w - self.window_w[self.next];
        let requested_w = self.power_w(currents_a);
        let budget_w = self.limit_w * n * (1.0 + LIMIT_TOLERANCE) - others_w;
        let (admitted, action) = if self.faulted {
            (ActuatorPair::default(), PowerAction::HeldByFault)
        } else if requested_w <= budget_w {
            (currents_a, PowerAction::Pass)
        } else {
            match self.on_exceed {
                OnExceed::Clamp => {
                    let allowed_w = budget_w.max(0.0);
                    let scale = (allowed_w / requested_w).sqrt();
                    let clamped = ActuatorPair {
                        a: currents_a.a * scale,
                        b: currents_a.b * scale,
                    };
                    (
                        clamped,
                        PowerAction::Clamped {
                            requested_w,
                            allowed_w,
                        },
                    )
                }
                OnExceed::Fault => {
                    self.faulted = true;
                    let mean_w = (others_w + requested_w) / n;
                    (ActuatorPair::default(), PowerAction::Faulted { mean_w })
                }
            }
        };
        self.record(self.power_w(admitted));
        (admitted, action)
    }

    fn record(&mut self, power_w: f64) {
        let replaced_w = std::mem::replace(&mut self.window_w[self.next], power_w);
        self.sum_w += power_w - replaced_w;
        self.next += 1;
        if self.next == self.window_w.len() {
            self.next = 0;
            // Re-sum once per window so rounding in the running sum cannot accumulate.
            self.sum_w = self.window_w.iter().sum();
        }
    }

    /// `I^2 R` summed over both coil axes, in W.
    #[must_use]
    pub fn power_w(&self, currents_a: ActuatorPair) -> f64 {
        self.resistance_ohm * (currents_a.a * currents_a.a + currents_a.b * currents_a.b)
    }

    /// The mean power over the window, in W.
    #[must_use]
    pub fn mean_w(&self) -> f64 {
        self.sum_w / self.window_w.len() as f64
    }

    /// Whether a fault is latched.
    #[must_use]
    pub fn faulted(&self) -> bool {
        self.faulted
    }

    /// Clears a latched fault (the window keeps its history).
    pub fn reset_fault(&mut self) {
        self.faulted = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resistance_is_derived_from_the_model_and_near_two_ohm() {
        let mirror = MirrorConfig::default();
        let amplitude_a = full_range_current_a(&mirror.axis(SensingAxis::Alpha), 52.0);
        assert!((amplitude_a - 3.856).abs() < 1e-3, "{amplitude_a}");
        let r = coil_resistance_ohm(&mirror);
        assert!((r - 2.0172).abs() < 1e-4, "{r}");
        // Both sensing axes at full range: R (I^2/2 + I^2/2) = 30 W.
        assert!((r * amplitude_a * amplitude_a - PAPER_POWER_LIMIT_W).abs() < 1e-9);
        // A stiffer mirror needs less current, hence a larger resistance for the same 30 W.
        let stiffer = MirrorConfig {
            dc_gain: 22.8,
            ..mirror
        };
        assert!((coil_resistance_ohm(&stiffer) / r - 4.0).abs() < 1e-9);
        // Axes that differ: the two full-range currents share the 30 W.
        let beta_stiffer = MirrorConfig {
            beta: crate::mirror::AxisOverrides {
                dc_gain: Some(22.8),
                ..Default::default()
            },
            ..MirrorConfig::default()
        };
        let i_beta = amplitude_a / 2.0;
        let mixed = coil_resistance_ohm(&beta_stiffer);
        assert!(
            (mixed * (amplitude_a.powi(2) / 2.0 + i_beta.powi(2) / 2.0) - PAPER_POWER_LIMIT_W)
                .abs()
                < 1e-9
        );
    }

    #[test]
    fn fault_latches_and_holds_currents_at_zero_until_reset() {
        let config = PowerLimitConfig {
            limit_w: 1.0,
            window_s: 0.01,
            on_exceed: OnExceed::Fault,
            coil_resistance_ohm: Some(1.0),
        };
        let mut monitor = PowerMonitor::new(&config, 1.0, 0.001);
        let big = ActuatorPair { a: 10.0, b: 0.0 };
        let (out, action) = monitor.admit(big);
        assert!(matches!(action, PowerAction::Faulted { .. }));
        assert_eq!(out, ActuatorPair::default());
        let (_, action) = monitor.admit(ActuatorPair { a: 0.1, b: 0.0 });
        assert_eq!(action, PowerAction::HeldByFault);
        monitor.reset_fault();
        let (out, action) = monitor.admit(ActuatorPair { a: 0.1, b: 0.0 });
        assert_eq!((out.a, action), (0.1, PowerAction::Pass));
    }

    #[test]
    fn clamp_keeps_the_window_mean_at_the_limit() {
        let config = PowerLimitConfig {
            limit_w: 2.0,
            window_s: 0.01,
            on_exceed: OnExceed::Clamp,
            coil_resistance_ohm: None,
        };
        let mut monitor = PowerMonitor::new(&config, 0.5, 0.001);
        let mut clamped = 0;
        for _ in 0..100 {
            let (_, action) = monitor.admit(ActuatorPair { a: 3.0, b: -1.0 });
            clamped += usize::from(matches!(action, PowerAction::Clamped { .. }));
            assert!(
                monitor.mean_w() <= 2.0 * (1.0 + 1e-6),
                "{}",
                monitor.mean_w()
            );
        }
        assert!(clamped > 50);
        assert!((monitor.mean_w() - 2.0).abs() < 1e-6);
    }
}
