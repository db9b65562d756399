//! The fast steering mirror node's device contract: units on the wire, the paper's model
//! units, and the 45 degree rotation between sensing and actuator axes.
//!
//! The paper's plant model (eq. 4, `K = 11.4`) maps the current amplifier's input ("input
//! units", volts) to the mirror angle sensor's output ("output units", volts). The wire carries
//! physical quantities instead: coil currents in amperes and mechanical mirror angles in
//! radians (scaled to integers by the message definitions). These two scalings connect them;
//! both programs use these nominal values unless a scene or controller file overrides them.
//!
//! - [`AMPS_PER_INPUT_UNIT`] = 1 A/V: the amplifier is a 1 A/V transconductance stage.
//! - [`RAD_PER_OUTPUT_UNIT`]: +-10 output units span the mirror's +-1.5 deg mechanical range.
//!
//! With these, a full-range (+-1.5 deg) sine at 52 Hz on one sensing axis needs a coil current
//! amplitude of `10 / |G(j 2 pi 52)| = 3.856 A`; the emulator picks the coil resistance so that
//! this dissipates exactly the paper's 30 W (see the emulator's drive module).
//!
//! Axis names: the sensing axes are `alpha` (mirror tilt about x, moves the spot along y; the
//! paper's 52 Hz axis) and `beta` (tilt about the yz' axis, moves the spot along x; 27 Hz).
//! The actuator (coil) axes `a` and `b` are rotated by 45 degrees against them.

use std::f64::consts::FRAC_1_SQRT_2;

/// Coil current per unit of the paper's model input, in amperes per volt.
pub const AMPS_PER_INPUT_UNIT: f64 = 1.0;

/// The mirror's mechanical full range on each sensing axis, in degrees (+- this value).
pub const FULL_RANGE_DEG: f64 = 1.5;

/// Output units (angle sensor volts) at the full mechanical range.
pub const OUTPUT_UNITS_AT_FULL_RANGE: f64 = 10.0;

/// Mechanical mirror angle per unit of the paper's model output, in radians per volt.
pub const RAD_PER_OUTPUT_UNIT: f64 =
    FULL_RANGE_DEG * std::f64::consts::PI / 180.0 / OUTPUT_UNITS_AT_FULL_RANGE;

/// A pair of values on the two sensing axes (`alpha`, `beta`).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct SensingPair {
    /// The alpha axis (spot along y).
    pub alpha: f64,
    /// The beta axis (spot along x).
    pub beta: f64,
}

/// One of the two sensing axes. Files write it `alpha` or `beta`, or by the direction the spot
/// moves: `y` (alpha) or `x` (beta). With the cargo feature `clap` it is also a command-line
/// value (`alpha`, `beta`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum SensingAxis {
    /// Tilt about x; moves the spot along y (the paper's 52 Hz axis).
    #[serde(alias = "y")]
    Alpha,
    /// Tilt about the yz' axis; moves the spot along x (the paper's 27 Hz axis).
    #[serde(alias = "x")]
    Beta,
}

impl SensingAxis {
    /// Both axes, alpha first.
    pub const BOTH: [SensingAxis; 2] = [SensingAxis::Alpha, SensingAxis::Beta];

    /// This axis' value of `pair`.
    #[must_use]
    pub fn of(self, pair: SensingPair) -> f64 {
        match self {
            SensingAxis::Alpha => pair.alpha,
            SensingAxis::Beta => pair.beta,
        }
    }

    /// A pair that is `value` on this axis and zero on the other.
    #[must_use]
    pub fn pair(self, value: f64) -> SensingPair {
        match self {
            SensingAxis::Alpha => SensingPair {
                alpha: value,
                beta: 0.0,
            },
            SensingAxis::Beta => SensingPair {
                alpha: 0.0,
                beta: value,
            },
        }
    }

    /// The other axis.
    #[must_use]
    pub fn other(self) -> SensingAxis {
        match self {
            SensingAxis::Alpha => SensingAxis::Beta,
            SensingAxis::Beta => SensingAxis::Alpha,
        }
    }

    /// The axis' name as written in files and output (`alpha`, `beta`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            SensingAxis::Alpha => "alpha",
            SensingAxis::Beta => "beta",
        }
    }
}

/// A pair of values on the two actuator (coil) axes (`a`, `b`).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct ActuatorPair {
    /// Coil axis a.
    pub a: f64,
    /// Coil axis b.
    pub b: f64,
}

/// Rotates per-sensing-axis values onto the coil axes: `a = (alpha - beta)/sqrt 2`,
/// `b = (alpha + beta)/sqrt 2`. The controller applies this to its outputs.
#[must_use]
pub fn actuator_from_sensing(s: SensingPair) -> ActuatorPair {
    ActuatorPair {
        a: (s.alpha - s.beta) * FRAC_1_SQRT_2,
        b: (s.alpha + s.beta) * FRAC_1_SQRT_2,
    }
}

/// The inverse of [`actuator_from_sensing`]: what coil-axis values do on the sensing axes.
/// The emulator applies this (before its cross-talk matrix) to the coil currents it receives.
#[must_use]
pub fn sensing_from_actuator(a: ActuatorPair) -> SensingPair {
    SensingPair {
        alpha: (a.a + a.b) * FRAC_1_SQRT_2,
        beta: (a.b - a.a) * FRAC_1_SQRT_2,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_range_is_one_and_a_half_degrees() {
        let full_rad = RAD_PER_OUTPUT_UNIT * OUTPUT_UNITS_AT_FULL_RANGE;
        assert!((full_rad.to_degrees() - 1.5).abs() < 1e-12);
    }

    #[test]
    fn rotation_round_trips_and_is_45_degrees() {
        let s = SensingPair {
            alpha: 0.3,
            beta: -1.7,
        };
        let back = sensing_from_actuator(actuator_from_sensing(s));
        assert!((back.alpha - s.alpha).abs() < 1e-15 && (back.beta - s.beta).abs() < 1e-15);
        let pure_alpha = actuator_from_sensing(SensingPair {
            alpha: 1.0,
            beta: 0.0,
        });
        assert!((pure_alpha.a - FRAC_1_SQRT_2).abs() < 1e-15);
        assert!((pure_alpha.b - FRAC_1_SQRT_2).abs() < 1e-15);
    }

    #[test]
    fn axis_names_and_aliases_follow_the_spot_direction() {
        let parse = |text: &str| serde_json::from_str::<SensingAxis>(text).unwrap();
        assert_eq!(parse("\"alpha\""), SensingAxis::Alpha);
        assert_eq!(parse("\"beta\""), SensingAxis::Beta);
        assert_eq!(parse("\"y\""), SensingAxis::Alpha);
        assert_eq!(parse("\"x\""), SensingAxis::Beta);
        assert!(serde_json::from_str::<SensingAxis>("\"z\"").is_err());
        for axis in SensingAxis::BOTH {
            assert_eq!(
                serde_json::to_string(&axis).unwrap(),
                format!("\"{}\"", axis.name())
            );
        }
    }

    #[test]
    fn axis_selects_and_builds_its_half_of_a_pair() {
        let pair = SensingPair {
            alpha: 2.0,
            beta: -3.0,
        };
        assert_eq!(SensingAxis::Alpha.of(pair), 2.0);
        assert_eq!(SensingAxis::Beta.of(pair), -3.0);
        assert_eq!(
            SensingAxis::Beta.pair(4.0),
            SensingPair {
                alpha: 0.0,
                beta: 4.0
            }
        );
        assert_eq!(SensingAxis::Alpha.other(), SensingAxis::Beta);
        assert_eq!(SensingAxis::Beta.other(), SensingAxis::Alpha);
    }
}
