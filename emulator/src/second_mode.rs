//! The mirror's second mechanical mode (part `second_mode`): a resonance above eq. 4's first
//! one, in series with it, optionally with an anti-resonance.
//!
//! The paper calls eq. 4's `ws` "the first resonance frequency": a real mirror has more. The
//! second is modelled as what the first mode's motion passes through on its way to the mirror
//! surface and the angle sensor (a structural mode between the moving magnets and the mirror):
//!
//! ```text
//! H2(s) = (w2^2 / wz^2) (s^2 + 2 zeta_z wz s + wz^2) / (s^2 + 2 zeta_2 w2 s + w2^2)
//! ```
//!
//! with `H2(0) = 1`, so eq. 4's DC gain K is the whole mirror's (what a DC measurement and a
//! fit of eq. 4 give), and without `zero_freq_hz` the numerator is `w2^2` (a pure resonance:
//! +1/(2 zeta_2) at `w2`, then -40 dB/decade and 180 deg more lag). States `[z, dz/dt]` with
//! `z'' = y - 2 zeta_2 w2 z' - w2^2 z` driven by the first mode's angle `y`; the mode's output
//! is a fixed combination of `y`, `z` and `z'` ([`SecondModeConfig::output_row`]).

use scanhil_protocol::validation::Allowed;
use serde::{Deserialize, Serialize};

use crate::mode_limits::{MAX_DAMPING_RATIO, MAX_NATURAL_FREQ_RAD_S};

/// The second mode of one axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SecondModeConfig {
    /// Its natural frequency, in Hz.
    pub natural_freq_hz: f64,
    /// Its damping ratio (> 0).
    pub damping_ratio: f64,
    /// The anti-resonance's natural frequency, in Hz; absent: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zero_freq_hz: Option<f64>,
    /// The anti-resonance's damping ratio (default: the mode's own).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zero_damping_ratio: Option<f64>,
}

impl Default for SecondModeConfig {
    /// 1.2 kHz, damping 0.02, no anti-resonance: the bench scene's values (assumed; the
    /// reasoning is in `docs/bench-scene.md`).
    fn default() -> Self {
        SecondModeConfig {
            natural_freq_hz: 1200.0,
            damping_ratio: 0.02,
            zero_freq_hz: None,
            zero_damping_ratio: None,
        }
    }
}

impl SecondModeConfig {
    /// Checks the values; on failure, the field (after `prefix`) and why.
    pub fn validate(&self, prefix: &str) -> Result<(), (String, String)> {
        let field = |name: &str| format!("{prefix}{name}");
        let frequency = Allowed::above(0.0, MAX_NATURAL_FREQ_RAD_S / std::f64::consts::TAU, "Hz");
        let damping = Allowed::above(0.0, MAX_DAMPING_RATIO, "");
        for (name, value, allowed) in [
            ("natural_freq_hz", Some(self.natural_freq_hz), frequency),
            ("damping_ratio", Some(self.damping_ratio), damping),
            ("zero_freq_hz", self.zero_freq_hz, frequency),
            ("zero_damping_ratio", self.zero_damping_ratio, damping),
        ] {
            allowed
                .check_some(name, value)
                .map_err(|invalid| (field(name), invalid.reason))?;
        }
        Ok(())
    }

    /// `w2`, in rad/s.
    #[must_use]
    pub fn pole_rad_s(&self) -> f64 {
        std::f64::consts::TAU * self.natural_freq_hz
    }

    /// The state matrix of `[z, dz/dt]` and the column its input `y` enters by.
    #[must_use]
    pub fn state_matrix(&self) -> ([[f64; 2]; 2], [f64; 2]) {
        let w2 = self.pole_rad_s();
        (
            [[0.0, 1.0], [-w2 * w2, -2.0 * self.damping_ratio * w2]],
            [0.0, 1.0],
        )
    }

    /// The mode's output as `[coefficient of y, of z, of dz/dt]`.
    #[must_use]
    pub fn output_row(&self) -> [f64; 3] {
        let w2 = self.pole_rad_s();
        match self.zero_freq_hz {
            None => [0.0, w2 * w2, 0.0],
            Some(zero_hz) => {
                // (w2^2/wz^2) (z'' + 2 zeta_z wz z' + wz^2 z), z'' from the state equation.
                let wz = std::f64::consts::TAU * zero_hz;
                let zeta_z = self.zero_damping_ratio.unwrap_or(self.damping_ratio);
                let scale = w2 * w2 / (wz * wz);
                [
                    scale,
                    scale * (wz * wz - w2 * w2),
                    scale * (2.0 * zeta_z * wz - 2.0 * self.damping_ratio * w2),
                ]
            }
        }
    }

    /// `H2(j omega)` as (re, im): the factor the mode puts on eq. 4's response.
    #[must_use]
    pub fn response_at(&self, omega_rad_s: f64) -> (f64, f64) {
        let w2 = self.pole_rad_s();
        let den = (
            w2 * w2 - omega_rad_s * omega_rad_s,
            2.0 * self.damping_ratio * w2 * omega_rad_s,
        );
        let num = match self.zero_freq_hz {
            None => (w2 * w2, 0.0),
            Some(zero_hz) => {
                let wz = std::f64::consts::TAU * zero_hz;
                let zeta_z = self.zero_damping_ratio.unwrap_or(self.damping_ratio);
                let scale = w2 * w2 / (wz * wz);
                (
                    scale * (wz * wz - omega_rad_s * omega_rad_s),
                    scale * 2.0 * zeta_z * wz * omega_rad_s,
                )
            }
        };
        let d2 = den.0 * den.0 + den.1 * den.1;
        (
            (num.0 * den.0 + num.1 * den.1) / d2,
            (num.1 * den.0 - num.0 * den.1) / d2,
        )
    }
}
