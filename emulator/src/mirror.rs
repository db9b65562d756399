//! The mirror's mechanics: the paper's eq. 4 on each sensing axis, as a state-space model.
//!
//! `G(s) = K ws^2 / (s^2 + 2 zeta ws s + ws^2) * e^(-s Ta)` maps the amplifier's input ("input
//! units", `A / AMPS_PER_INPUT_UNIT`) to the angle sensor's output ("output units",
//! `rad / RAD_PER_OUTPUT_UNIT`). The delay `e^(-s Ta)` is exactly one control period and is
//! applied by the plant (see [`crate::plant`]), not here. Per axis the state is
//! `x = [y, dy/dt]` in output units and output units per second:
//!
//! ```text
//! dx/dt = [0, 1; -ws^2, -2 zeta ws] x + [0; K ws^2] u,    y = x[0]
//! ```

use serde::{Deserialize, Serialize};

pub use scanhil_protocol::plant_units::SensingAxis;
use scanhil_protocol::plant_units::SensingPair;

/// The mirror's mechanics (eq. 4 without its delay) and which axes are simulated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MirrorConfig {
    /// The sensing axes that move; an axis not listed stays at its initial angle.
    pub axes: Vec<SensingAxis>,
    /// DC gain K, output units per input unit (paper: 11.4).
    pub dc_gain: f64,
    /// Natural frequency ws in rad/s (paper: 140.68).
    pub natural_freq_rad_s: f64,
    /// Damping ratio zeta (paper: 3.21e-2); 0 is an undamped oscillator.
    pub damping_ratio: f64,
    /// Mechanical angles at t = 0, in rad.
    pub initial_angles_rad: SensingPair,
}

impl Default for MirrorConfig {
    fn default() -> Self {
        MirrorConfig {
            axes: SensingAxis::BOTH.to_vec(),
            dc_gain: 11.4,
            natural_freq_rad_s: 140.68,
            damping_ratio: 3.21e-2,
            initial_angles_rad: SensingPair::default(),
        }
    }
}

impl MirrorConfig {
    /// Checks the parameters; on failure, the field name and why.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let bad = |field: &str, reason: String| Err((format!("mirror.{field}"), reason));
        if !(self.dc_gain.is_finite() && self.dc_gain != 0.0) {
            return bad(
                "dc_gain",
                format!("must be finite and non-zero, got {}", self.dc_gain),
            );
        }
        if !(self.natural_freq_rad_s.is_finite() && self.natural_freq_rad_s > 0.0) {
            return bad(
                "natural_freq_rad_s",
                format!("must be finite and > 0, got {}", self.natural_freq_rad_s),
            );
        }
        if !(self.damping_ratio.is_finite() && self.damping_ratio >= 0.0) {
            return bad(
                "damping_ratio",
                format!(
                    "must be finite and >= 0 (a negatively damped mirror is unstable), got {}",
                    self.damping_ratio
                ),
            );
        }
        let init = self.initial_angles_rad;
        if !(init.alpha.is_finite() && init.beta.is_finite()) {
            return bad("initial_angles_rad", "must be finite".into());
        }
        for (i, axis) in self.axes.iter().enumerate() {
            if self.axes[..i].contains(axis) {
                return bad("axes", format!("axis {} is listed twice", axis.name()));
            }
        }
        Ok(())
    }

    /// Eq. 4's frequency response magnitude `|G(j w)|` (output units per input unit).
    #[must_use]
    pub fn gain_at(&self, omega_rad_s: f64) -> f64 {
        let ws2 = self.natural_freq_rad_s * self.natural_freq_rad_s;
        let re = ws2 - omega_rad_s * omega_rad_s;
        let im = 2.0 * self.damping_ratio * self.natural_freq_rad_s * omega_rad_s;
        (self.dc_gain * ws2).abs() / re.hypot(im)
    }

    /// The per-axis state matrix `A` (row-major 2x2) of the model above.
    #[must_use]
    pub fn state_matrix(&self) -> [[f64; 2]; 2] {
        let ws = self.natural_freq_rad_s;
        [[0.0, 1.0], [-ws * ws, -2.0 * self.damping_ratio * ws]]
    }

    /// The per-axis input column `B` of the model above.
    #[must_use]
    pub fn input_column(&self) -> [f64; 2] {
        let ws = self.natural_freq_rad_s;
        [0.0, self.dc_gain * ws * ws]
    }

    /// Whether `axis` is simulated.
    #[must_use]
    pub fn moves(&self, axis: SensingAxis) -> bool {
        self.axes.contains(&axis)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gain_is_dc_gain_at_zero_and_peaks_near_the_resonance() {
        let m = MirrorConfig::default();
        assert!((m.gain_at(0.0) - 11.4).abs() < 1e-12);
        let peak = m.gain_at(m.natural_freq_rad_s);
        assert!((peak - 11.4 / (2.0 * 3.21e-2)).abs() < 1e-9);
    }

    #[test]
    fn negative_damping_is_refused_with_the_field() {
        let m = MirrorConfig {
            damping_ratio: -0.01,
            ..MirrorConfig::default()
        };
        let (field, _) = m.validate().unwrap_err();
        assert_eq!(field, "mirror.damping_ratio");
    }
}
