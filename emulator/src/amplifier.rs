//! The coil current amplifiers (the paper's OPA544T stages): a current limit on the command
//! and a first-order current loop with about 10 kHz bandwidth.
//!
//! Per actuator axis the coil current `i` follows the limited command `c`:
//! `di/dt = wb (c - i)` with `wb = 2 pi bandwidth_hz`. At a 20 kHz control rate `wb Ta` is
//! about 3.1, which makes this state stiff for explicit integrators (RK4 and Euler are refused
//! without sub-steps); the exact ZOH and the trapezoid rule handle it.

use serde::{Deserialize, Serialize};

use scanhil_protocol::plant_units::ActuatorPair;

/// The amplifiers' parameters (both actuator axes alike).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AmplifierConfig {
    /// -3 dB bandwidth of the current loop, in Hz (paper: 10 kHz).
    pub bandwidth_hz: f64,
    /// The largest coil current magnitude per actuator axis, in A. The default, 4 A, passes a
    /// full-range 52 Hz sine on one sensing axis (2.73 A per coil axis) with margin.
    pub current_limit_a: f64,
}

impl Default for AmplifierConfig {
    fn default() -> Self {
        AmplifierConfig {
            bandwidth_hz: 10_000.0,
            current_limit_a: 4.0,
        }
    }
}

impl AmplifierConfig {
    /// Checks the parameters; on failure, the field name and why.
    pub fn validate(&self) -> Result<(), (String, String)> {
        if !(self.bandwidth_hz.is_finite() && self.bandwidth_hz > 0.0) {
            return Err((
                "amplifier.bandwidth_hz".into(),
                format!("must be finite and > 0, got {}", self.bandwidth_hz),
            ));
        }
        if !(self.current_limit_a.is_finite() && self.current_limit_a > 0.0) {
            return Err((
                "amplifier.current_limit_a".into(),
                format!("must be finite and > 0, got {}", self.current_limit_a),
            ));
        }
        Ok(())
    }

    /// The current loop's pole magnitude `2 pi bandwidth_hz`, in rad/s.
    #[must_use]
    pub fn pole_rad_s(&self) -> f64 {
        std::f64::consts::TAU * self.bandwidth_hz
    }

    /// Clamps a command to the current limit; the second value says whether it was clamped.
    #[must_use]
    pub fn limit(&self, command_a: ActuatorPair) -> (ActuatorPair, bool) {
        let lim = self.current_limit_a;
        let limited = ActuatorPair {
            a: command_a.a.clamp(-lim, lim),
            b: command_a.b.clamp(-lim, lim),
        };
        (limited, limited != command_a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limit_clamps_each_axis_and_says_so() {
        let amp = AmplifierConfig::default();
        let (out, clamped) = amp.limit(ActuatorPair { a: 9.0, b: -0.5 });
        assert_eq!(out, ActuatorPair { a: 4.0, b: -0.5 });
        assert!(clamped);
        let (out, clamped) = amp.limit(ActuatorPair { a: -3.0, b: 2.0 });
        assert_eq!(out, ActuatorPair { a: -3.0, b: 2.0 });
        assert!(!clamped);
    }
}
