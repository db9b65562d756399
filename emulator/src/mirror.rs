//! The mirror's mechanics: the paper's eq. 4 on each sensing axis, as a state-space model,
//! with its parameters set per axis.
//!
//! `G(s) = K ws^2 / (s^2 + 2 zeta ws s + ws^2) * e^(-s Ta)` maps the amplifier's input ("input
//! units", `A / AMPS_PER_INPUT_UNIT`) to the angle sensor's output ("output units",
//! `rad / RAD_PER_OUTPUT_UNIT`). The delay `e^(-s Ta)` is at least one control period, which
//! the plant applies to the command (see [`crate::plant`]); a longer delay on an axis
//! (`delay_s`) is the rest, applied to that axis's measured angle ([`crate::latency`]). Per
//! axis the state is `x = [y, dy/dt]` in output units and output units per second:
//!
//! ```text
//! dx/dt = [0, 1; -ws^2, -2 zeta ws] x + [0; K ws^2] u,    y = x[0]
//! ```
//!
//! # Per-axis parameters
//! The scene's `mirror` section holds one set of eq. 4 parameters for both axes (the paper's:
//! "the frequency response of both axes are identical"), and optional `alpha` and `beta`
//! sections whose fields replace the common ones on that axis alone:
//!
//! ```json
//! "mirror": {"dc_gain": 11.4, "natural_freq_rad_s": 140.68, "damping_ratio": 0.0321,
//!            "beta": {"dc_gain": 10.9, "natural_freq_rad_s": 151.0, "delay_s": 6.2e-5}}
//! ```
//!
//! [`MirrorConfig::axis`] resolves one axis's parameters ([`AxisDynamics`]).

use serde::{Deserialize, Serialize};

use scanhil_protocol::validation::Allowed;

use crate::mode_limits::{MAX_DAMPING_RATIO, MAX_DC_GAIN, MAX_NATURAL_FREQ_RAD_S};
use crate::second_mode::SecondModeConfig;
pub use scanhil_protocol::plant_units::SensingAxis;
use scanhil_protocol::plant_units::SensingPair;

/// The longest delay an axis may have, in control periods (its history is held in memory).
pub const MAX_DELAY_PERIODS: f64 = 1024.0;

/// Eq. 4's parameters of one sensing axis, resolved from the common values and the axis's
/// own ([`MirrorConfig::axis`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AxisDynamics {
    /// DC gain K, output units per input unit.
    pub dc_gain: f64,
    /// Natural frequency ws in rad/s.
    pub natural_freq_rad_s: f64,
    /// Damping ratio zeta.
    pub damping_ratio: f64,
    /// Eq. 4's delay Ta on this axis, in s; `None` is one control period.
    pub delay_s: Option<f64>,
    /// The axis's second mechanical mode (acts with part `second_mode`).
    pub second_mode: SecondModeConfig,
}

impl AxisDynamics {
    /// Eq. 4's frequency response magnitude `|G(j w)|` (output units per input unit).
    #[must_use]
    pub fn gain_at(&self, omega_rad_s: f64) -> f64 {
        let ws2 = self.natural_freq_rad_s * self.natural_freq_rad_s;
        let re = ws2 - omega_rad_s * omega_rad_s;
        let im = 2.0 * self.damping_ratio * self.natural_freq_rad_s * omega_rad_s;
        (self.dc_gain * ws2).abs() / re.hypot(im)
    }

    /// The state matrix `A` (row-major 2x2) of the model above.
    #[must_use]
    pub fn state_matrix(&self) -> [[f64; 2]; 2] {
        let ws = self.natural_freq_rad_s;
        [[0.0, 1.0], [-ws * ws, -2.0 * self.damping_ratio * ws]]
    }

    /// The input column `B` of the model above.
    #[must_use]
    pub fn input_column(&self) -> [f64; 2] {
        let ws = self.natural_freq_rad_s;
        [0.0, self.dc_gain * ws * ws]
    }

    /// The delay beyond one control period of `period_s`, in s (0 when `delay_s` is unset).
    #[must_use]
    pub fn extra_delay_s(&self, period_s: f64) -> f64 {
        self.delay_s.map_or(0.0, |d| (d - period_s).max(0.0))
    }
}

/// One axis's own values; a field left out takes the common value of [`MirrorConfig`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AxisOverrides {
    /// DC gain K of this axis.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dc_gain: Option<f64>,
    /// Natural frequency ws of this axis, in rad/s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub natural_freq_rad_s: Option<f64>,
    /// Damping ratio zeta of this axis.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub damping_ratio: Option<f64>,
    /// Eq. 4's delay Ta on this axis, in s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub delay_s: Option<f64>,
    /// This axis's second mode (part `second_mode`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub second_mode: Option<SecondModeConfig>,
}

impl AxisOverrides {
    /// Whether no field is set (then the axis is the common model).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        *self == AxisOverrides::default()
    }
}

/// The mirror's mechanics (eq. 4), per axis, and which axes are simulated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MirrorConfig {
    /// The sensing axes that move; an axis not listed stays at its initial angle.
    pub axes: Vec<SensingAxis>,
    /// DC gain K, output units per input unit (paper: 11.4), for both axes.
    pub dc_gain: f64,
    /// Natural frequency ws in rad/s (paper: 140.68), for both axes.
    pub natural_freq_rad_s: f64,
    /// Damping ratio zeta (paper: 3.21e-2); 0 is an undamped oscillator.
    pub damping_ratio: f64,
    /// Eq. 4's delay Ta from a coil command to the measured angle, in s, for both axes; absent
    /// is one control period (the paper's 50 us at 20 kHz). At least one control period and
    /// at most [`MAX_DELAY_PERIODS`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub delay_s: Option<f64>,
    /// The second mechanical mode of both axes, acting with part `second_mode` (default: the
    /// bench scene's 1.2 kHz, [`SecondModeConfig::default`]).
    pub second_mode: SecondModeConfig,
    /// Mechanical angles at t = 0, in rad.
    pub initial_angles_rad: SensingPair,
    /// The alpha axis's own values (`y` is accepted for `alpha`, as in `axes`).
    #[serde(alias = "y", skip_serializing_if = "AxisOverrides::is_empty")]
    pub alpha: AxisOverrides,
    /// The beta axis's own values (`x` is accepted for `beta`).
    #[serde(alias = "x", skip_serializing_if = "AxisOverrides::is_empty")]
    pub beta: AxisOverrides,
}

impl Default for MirrorConfig {
    fn default() -> Self {
        MirrorConfig {
            axes: SensingAxis::BOTH.to_vec(),
            dc_gain: 11.4,
            natural_freq_rad_s: 140.68,
            damping_ratio: 3.21e-2,
            delay_s: None,
            second_mode: SecondModeConfig::default(),
            initial_angles_rad: SensingPair::default(),
            alpha: AxisOverrides::default(),
            beta: AxisOverrides::default(),
        }
    }
}

impl MirrorConfig {
    /// Checks the parameters for a plant stepped every `period_s`; on failure, the field
    /// name (`mirror.dc_gain`, or `mirror.beta.dc_gain` for an axis's own value) and why.
    pub fn validate(&self, period_s: f64) -> Result<(), (String, String)> {
        let common = AxisOverrides {
            dc_gain: Some(self.dc_gain),
            natural_freq_rad_s: Some(self.natural_freq_rad_s),
            damping_ratio: Some(self.damping_ratio),
            delay_s: self.delay_s,
            second_mode: Some(self.second_mode),
        };
        validate_values(&common, "mirror.", period_s)?;
        for axis in SensingAxis::BOTH {
            validate_values(
                self.overrides(axis),
                &format!("mirror.{}.", axis.name()),
                period_s,
            )?;
        }
        let init = self.initial_angles_rad;
        if !(init.alpha.is_finite() && init.beta.is_finite()) {
            return Err(("mirror.initial_angles_rad".into(), "must be finite".into()));
        }
        for (i, axis) in self.axes.iter().enumerate() {
            if self.axes[..i].contains(axis) {
                return Err((
                    "mirror.axes".into(),
                    format!("axis {} is listed twice", axis.name()),
                ));
            }
        }
        Ok(())
    }

    /// The parameters of `axis`: its own values where it has them, else the common ones.
    #[must_use]
    pub fn axis(&self, axis: SensingAxis) -> AxisDynamics {
        let own = self.overrides(axis);
        AxisDynamics {
            dc_gain: own.dc_gain.unwrap_or(self.dc_gain),
            natural_freq_rad_s: own.natural_freq_rad_s.unwrap_or(self.natural_freq_rad_s),
            damping_ratio: own.damping_ratio.unwrap_or(self.damping_ratio),
            delay_s: own.delay_s.or(self.delay_s),
            second_mode: own.second_mode.unwrap_or(self.second_mode),
        }
    }

    /// The values `axis` sets for itself.
    #[must_use]
    pub fn overrides(&self, axis: SensingAxis) -> &AxisOverrides {
        match axis {
            SensingAxis::Alpha => &self.alpha,
            SensingAxis::Beta => &self.beta,
        }
    }

    /// Whether `axis` is simulated.
    #[must_use]
    pub fn moves(&self, axis: SensingAxis) -> bool {
        self.axes.contains(&axis)
    }
}

/// Checks the values set in `values`, naming each field with `prefix`.
fn validate_values(
    values: &AxisOverrides,
    prefix: &str,
    period_s: f64,
) -> Result<(), (String, String)> {
    let bad = |field: &str, reason: String| Err((format!("{prefix}{field}"), reason));
    let ranged = |field: &str, allowed: Allowed, value: Option<f64>| {
        allowed
            .check_some(field, value)
            .map_err(|invalid| (format!("{prefix}{}", invalid.field), invalid.reason))
    };
    if values.dc_gain == Some(0.0) {
        return bad("dc_gain", "must be non-zero".into());
    }
    ranged(
        "dc_gain",
        Allowed::closed(-MAX_DC_GAIN, MAX_DC_GAIN, ""),
        values.dc_gain,
    )?;
    ranged(
        "natural_freq_rad_s",
        Allowed::above(0.0, MAX_NATURAL_FREQ_RAD_S, "rad/s"),
        values.natural_freq_rad_s,
    )?;
    // A negatively damped mirror is unstable.
    ranged(
        "damping_ratio",
        Allowed::closed(0.0, MAX_DAMPING_RATIO, ""),
        values.damping_ratio,
    )?;
    if let Some(mode) = &values.second_mode {
        mode.validate(&format!("{prefix}second_mode."))?;
    }
    if let Some(delay) = values.delay_s {
        // A relative tolerance lets a delay written as one period in decimal pass.
        let shortest = period_s * (1.0 - 1e-9);
        let longest = period_s * MAX_DELAY_PERIODS;
        if !(delay.is_finite() && delay >= shortest && delay <= longest) {
            return bad(
                "delay_s",
                format!(
                    "must lie between one control period ({period_s:e} s: a command acts one \
                     period after it is given) and {MAX_DELAY_PERIODS} periods ({longest:e} s), \
                     got {delay}"
                ),
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const TA: f64 = 50e-6;

    #[test]
    fn gain_is_dc_gain_at_zero_and_peaks_near_the_resonance() {
        let m = MirrorConfig::default().axis(SensingAxis::Alpha);
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
        let (field, _) = m.validate(TA).unwrap_err();
        assert_eq!(field, "mirror.damping_ratio");
    }

    #[test]
    fn values_beyond_what_the_plant_can_step_are_refused_with_the_field_and_the_limits_pass() {
        // A natural frequency of 1e40 rad/s once kept `scanhil-emulator step` spinning in the
        // exact discretisation's matrix exponential.
        let refused = |m: MirrorConfig| m.validate(TA).map_err(|(field, _)| field);
        let with = |dc_gain: f64, natural_freq_rad_s: f64, damping_ratio: f64| MirrorConfig {
            dc_gain,
            natural_freq_rad_s,
            damping_ratio,
            ..MirrorConfig::default()
        };
        let nominal = MirrorConfig::default();
        let (k, ws, zeta) = (
            nominal.dc_gain,
            nominal.natural_freq_rad_s,
            nominal.damping_ratio,
        );
        for (m, field) in [
            (with(k, 1e40, zeta), "mirror.natural_freq_rad_s"),
            (
                with(k, MAX_NATURAL_FREQ_RAD_S * 1.01, zeta),
                "mirror.natural_freq_rad_s",
            ),
            (with(k, ws, 1e40), "mirror.damping_ratio"),
            (
                with(k, ws, MAX_DAMPING_RATIO * 1.01),
                "mirror.damping_ratio",
            ),
            (with(1e300, ws, zeta), "mirror.dc_gain"),
            (with(-MAX_DC_GAIN * 1.01, ws, zeta), "mirror.dc_gain"),
            (with(0.0, ws, zeta), "mirror.dc_gain"),
        ] {
            assert_eq!(refused(m).err().as_deref(), Some(field));
        }
        assert_eq!(
            refused(with(MAX_DC_GAIN, MAX_NATURAL_FREQ_RAD_S, MAX_DAMPING_RATIO)),
            Ok(())
        );
        assert_eq!(refused(with(-MAX_DC_GAIN, ws, 0.0)), Ok(()));
    }

    #[test]
    fn an_axis_takes_its_own_values_and_the_common_ones_for_the_rest() {
        let m = MirrorConfig {
            delay_s: Some(60e-6),
            beta: AxisOverrides {
                dc_gain: Some(10.0),
                damping_ratio: Some(0.05),
                ..AxisOverrides::default()
            },
            ..MirrorConfig::default()
        };
        let alpha = m.axis(SensingAxis::Alpha);
        let beta = m.axis(SensingAxis::Beta);
        assert_eq!(
            (alpha.dc_gain, alpha.damping_ratio, alpha.delay_s),
            (11.4, 3.21e-2, Some(60e-6))
        );
        assert_eq!(
            (beta.dc_gain, beta.natural_freq_rad_s, beta.damping_ratio),
            (10.0, 140.68, 0.05)
        );
        assert_eq!(beta.delay_s, Some(60e-6));
        assert!((alpha.extra_delay_s(TA) - 10e-6).abs() < 1e-18);
        assert_eq!(
            MirrorConfig::default()
                .axis(SensingAxis::Beta)
                .extra_delay_s(TA),
            0.0
        );
    }

    #[test]
    fn an_axis_value_is_checked_and_named_with_its_axis() {
        for (overrides, field) in [
            (
                AxisOverrides {
                    dc_gain: Some(0.0),
                    ..AxisOverrides::default()
                },
                "mirror.beta.dc_gain",
            ),
            (
                AxisOverrides {
                    natural_freq_rad_s: Some(-1.0),
                    ..AxisOverrides::default()
                },
                "mirror.beta.natural_freq_rad_s",
            ),
            (
                AxisOverrides {
                    damping_ratio: Some(f64::NAN),
                    ..AxisOverrides::default()
                },
                "mirror.beta.damping_ratio",
            ),
            (
                AxisOverrides {
                    delay_s: Some(0.5 * TA),
                    ..AxisOverrides::default()
                },
                "mirror.beta.delay_s",
            ),
            (
                AxisOverrides {
                    delay_s: Some(1025.0 * TA),
                    ..AxisOverrides::default()
                },
                "mirror.beta.delay_s",
            ),
        ] {
            let m = MirrorConfig {
                beta: overrides,
                ..MirrorConfig::default()
            };
            assert_eq!(m.validate(TA).unwrap_err().0, field, "{overrides:?}");
        }
        let exactly_one_period = MirrorConfig {
            delay_s: Some(TA),
            alpha: AxisOverrides {
                delay_s: Some(MAX_DELAY_PERIODS * TA),
                ..AxisOverrides::default()
            },
            ..MirrorConfig::default()
        };
        assert_eq!(exactly_one_period.validate(TA), Ok(()));
    }
}
