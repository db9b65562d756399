//! From coil currents to the mirror's model input on each sensing axis: the 45 degree axis
//! rotation ([`sensing_from_actuator`]), the amplifier scaling ([`AMPS_PER_INPUT_UNIT`]) and
//! the cross-talk coupling matrix (the paper measured about 20 dB below the direct path).
//!
//! `u_sensing = M * R * i / AMPS_PER_INPUT_UNIT`, with `R` the rotation and
//! `M = [1, alpha_from_beta; beta_from_alpha, 1]` (identity when the part is off). With it
//! alone the cross-talk is a constant fraction of the direct response, `0.1 G(s)`.
//!
//! # The cross-talk as a transfer function (part `cross_talk_pickup`)
//! The paper measured the cross-talk "over the relevant part of the frequency spectrum 20 dB
//! lower" than the direct response (Fig. 4): over that part, not everywhere. The part adds a
//! second path, the angle sensor's pickup of the other axis's coil current (the coils' field
//! and drive reaching the sensor's electronics): the measured angle of alpha gains
//! `pickup.alpha_from_beta x i_beta` (rad per A of beta's sensing-axis current, the coil
//! currents rotated without `M`), and likewise for beta. The mechanical path falls as
//! `G(s)` (-40 dB/decade above the 22 Hz resonance), the pickup follows the current (flat to
//! the amplifier's bandwidth), so the cross-talk over the direct response is
//! `0.1 + p A(s) / G(s)`: -20 dB at low frequency, rising at 40 dB/decade above the frequency
//! where the two paths are equal. The default `p` = 1.50 urad/A makes them equal at 1 kHz
//! (`0.1 |G(j 2 pi 1 kHz)|`, an assumed frequency: the cross-talk then stays within 2 dB of
//! -20 dB up to the paper's 422 Hz bandwidth, the relevant band). With both signs positive the
//! paths are in antiphase above the resonance and cancel near 1 kHz (a notch), then rise.

use serde::{Deserialize, Serialize};

use scanhil_protocol::plant_units::{AMPS_PER_INPUT_UNIT, ActuatorPair, sensing_from_actuator};

/// The off-diagonal terms of the coupling matrix, as amplitude ratios (0.1 = -20 dB), and
/// the angle sensor's pickup of the other axis's current.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CrossTalkConfig {
    /// How much of beta's input reaches the alpha axis.
    pub alpha_from_beta: f64,
    /// How much of alpha's input reaches the beta axis.
    pub beta_from_alpha: f64,
    /// The angle sensor's pickup of the other axis's current, urad per A (part
    /// `cross_talk_pickup`).
    pub pickup_urad_per_a: Pickup,
}

/// The pickup of the other axis's current in each measured angle, urad per A.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Pickup {
    /// In alpha's measured angle, per A of beta's current.
    pub alpha_from_beta: f64,
    /// In beta's measured angle, per A of alpha's current.
    pub beta_from_alpha: f64,
}

/// The default pickup: equal to the mechanical cross-talk at 1 kHz (module doc).
pub const DEFAULT_PICKUP_URAD_PER_A: f64 = 1.50;

impl Default for Pickup {
    fn default() -> Self {
        Pickup {
            alpha_from_beta: DEFAULT_PICKUP_URAD_PER_A,
            beta_from_alpha: DEFAULT_PICKUP_URAD_PER_A,
        }
    }
}

impl Default for CrossTalkConfig {
    fn default() -> Self {
        CrossTalkConfig {
            alpha_from_beta: 0.1,
            beta_from_alpha: 0.1,
            pickup_urad_per_a: Pickup::default(),
        }
    }
}

impl CrossTalkConfig {
    /// Checks the parameters; on failure, the field name and why.
    pub fn validate(&self) -> Result<(), (String, String)> {
        for (name, v) in [
            ("alpha_from_beta", self.alpha_from_beta),
            ("beta_from_alpha", self.beta_from_alpha),
        ] {
            if !(v.is_finite() && v.abs() < 1.0) {
                return Err((
                    format!("cross_talk.{name}"),
                    format!("must be finite with magnitude below 1, got {v}"),
                ));
            }
        }
        let p = self.pickup_urad_per_a;
        for (name, v) in [
            ("alpha_from_beta", p.alpha_from_beta),
            ("beta_from_alpha", p.beta_from_alpha),
        ] {
            if !v.is_finite() {
                return Err((
                    format!("cross_talk.pickup_urad_per_a.{name}"),
                    format!("must be finite, got {v}"),
                ));
            }
        }
        Ok(())
    }

    /// The coupling level of the stronger off-diagonal term in dB relative to the direct path.
    #[must_use]
    pub fn level_db(&self) -> f64 {
        20.0 * self
            .alpha_from_beta
            .abs()
            .max(self.beta_from_alpha.abs())
            .log10()
    }
}

/// The static map from coil currents (A, actuator axes a, b) to model input units on the
/// sensing axes (alpha, beta), as a row-major 2x2 matrix: rows alpha, beta; columns a, b.
#[must_use]
pub fn input_from_currents(cross_talk: Option<&CrossTalkConfig>) -> [[f64; 2]; 2] {
    let rot_a = sensing_from_actuator(ActuatorPair { a: 1.0, b: 0.0 });
    let rot_b = sensing_from_actuator(ActuatorPair { a: 0.0, b: 1.0 });
    let rotation = [[rot_a.alpha, rot_b.alpha], [rot_a.beta, rot_b.beta]];
    let (ab, ba) = cross_talk.map_or((0.0, 0.0), |c| (c.alpha_from_beta, c.beta_from_alpha));
    let coupling = [[1.0, ab], [ba, 1.0]];
    let mut m = [[0.0; 2]; 2];
    for (r, row) in m.iter_mut().enumerate() {
        for (c, cell) in row.iter_mut().enumerate() {
            *cell = (coupling[r][0] * rotation[0][c] + coupling[r][1] * rotation[1][c])
                / AMPS_PER_INPUT_UNIT;
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanhil_protocol::plant_units::{SensingPair, actuator_from_sensing};

    #[test]
    fn without_cross_talk_a_sensing_command_reaches_only_its_axis() {
        let m = input_from_currents(None);
        let i = actuator_from_sensing(SensingPair {
            alpha: 2.0,
            beta: 0.0,
        });
        let alpha = m[0][0] * i.a + m[0][1] * i.b;
        let beta = m[1][0] * i.a + m[1][1] * i.b;
        assert!((alpha - 2.0 / AMPS_PER_INPUT_UNIT).abs() < 1e-12 && beta.abs() < 1e-12);
    }

    #[test]
    fn default_cross_talk_is_twenty_db_down() {
        let c = CrossTalkConfig::default();
        assert!((c.level_db() + 20.0).abs() < 1e-9);
        let m = input_from_currents(Some(&c));
        let i = actuator_from_sensing(SensingPair {
            alpha: 1.0,
            beta: 0.0,
        });
        let beta = m[1][0] * i.a + m[1][1] * i.b;
        assert!((beta - 0.1).abs() < 1e-12);
    }
}
