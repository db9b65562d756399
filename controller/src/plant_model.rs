//! The nominal plant model: eq. 4 in the paper's units (input V -> output V), zero-order-hold
//! discretised at the control period, times one period of delay for `exp(-s Ta)`. This is the
//! emulator's timing convention: from the command sequence `u[k]` to the measurements `y[k]`
//! the plant is `z^-1 * ZOH(G)`. A bench whose commands arrive later than the next period
//! (a bus's transit, a fitted delay) states the surplus in `extra_delay_s`: the held command
//! then acts `Ta = T + extra_delay_s` after the sample it was computed from (the modified
//! z-transform, [`crate::discretise::zero_order_hold_delayed`]).

use nalgebra::Complex;

use crate::continuous::{ContinuousSection, Quadratic};
use crate::discretise::{Method, discretise, zero_order_hold_delayed};
use crate::sos::{Cascade, Section};

/// Eq. 4's parameters (`G(s) = K ws^2 / (s^2 + 2 zeta ws s + ws^2) exp(-s Ta)`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantModel {
    /// K, output units per input unit at DC (11.4).
    pub dc_gain: f64,
    /// ws, the first resonance in rad/s (140.68).
    pub natural_freq_rad_s: f64,
    /// zeta, the damping ratio (3.21e-2).
    pub damping_ratio: f64,
    /// Delay beyond the one period of the emulator's convention, s (eq. 4's `Ta` is the period
    /// plus this; 0, the default, is the paper's `Ta` of one period).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub extra_delay_s: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl Default for PlantModel {
    fn default() -> Self {
        Self {
            dc_gain: 11.4,
            natural_freq_rad_s: 140.68,
            damping_ratio: 3.21e-2,
            extra_delay_s: 0.0,
        }
    }
}

impl PlantModel {
    /// The delay-free part of eq. 4 as one continuous section.
    #[must_use]
    pub fn section(&self) -> ContinuousSection {
        let w = self.natural_freq_rad_s;
        ContinuousSection {
            num: Quadratic::constant(self.dc_gain * w * w),
            den: Quadratic::second_order(w, self.damping_ratio),
        }
    }

    /// Eq. 4 at `f_hz` with its delay `exp(-s delay_s)` (output units per input unit).
    #[must_use]
    pub fn continuous_response(&self, f_hz: f64, delay_s: f64) -> Complex<f64> {
        let w = std::f64::consts::TAU * f_hz;
        self.section().eval(Complex::new(0.0, w)) * Complex::from_polar(1.0, -w * delay_s)
    }

    /// `ZOH(G)` at `period_s`, with `extra_delay_s` on its input: fed the command of period
    /// k, its output is the angle at the end of period k+1 (the command acts one period late,
    /// plus the extra delay).
    #[must_use]
    pub fn sampled(&self, period_s: f64) -> Cascade {
        let extra = self.extra_delay_s.max(0.0);
        if extra == 0.0 {
            return Cascade::new(
                1.0,
                vec![discretise(
                    &self.section(),
                    &Method::ZeroOrderHold,
                    period_s,
                )],
            );
        }
        let whole_periods = (extra / period_s).floor();
        let fraction_s = (extra - whole_periods * period_s).clamp(0.0, period_s * (1.0 - 1e-12));
        let mut sections = vec![
            zero_order_hold_delayed(&self.section(), period_s, fraction_s),
            Section::delay(),
        ];
        sections.extend(std::iter::repeat_n(
            Section::delay(),
            whole_periods as usize,
        ));
        Cascade::new(1.0, sections)
    }

    /// `z^-1 * ZOH(G)` at `period_s` (with the extra delay), as a cascade (at rest): the map
    /// from the command sequence `u[k]` to the measurement sequence `y[k] = angle(k T)`.
    #[must_use]
    pub fn discrete(&self, period_s: f64) -> Cascade {
        let sampled = self.sampled(period_s);
        let mut sections = sampled.sections().to_vec();
        sections.push(Section::delay());
        Cascade::new(sampled.gain(), sections)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn discrete_model_matches_eq4_with_a_period_and_a_half_of_delay() {
        let (plant, t) = (PlantModel::default(), 50e-6);
        let d = plant.discrete(t);
        for f in [1.0, 22.39, 100.0, 400.0] {
            // ZOH adds half a period of delay (and a sinc magnitude, < 1e-3 here).
            let c = plant.continuous_response(f, 1.5 * t);
            let z = d.response(f, t);
            assert!((z - c).norm() < 2e-3 * c.norm(), "{f} Hz: {z} vs {c}");
        }
        let dc = d.response(0.0, t);
        assert!((dc.re - 11.4).abs() < 1e-9);
    }

    #[test]
    fn an_extra_delay_adds_its_phase_and_whole_periods() {
        let t = 1.0 / 2740.0;
        for extra_s in [0.3 * t, 2.0 * t, 2.6 * t] {
            let plant = PlantModel {
                extra_delay_s: extra_s,
                ..PlantModel::default()
            };
            let d = plant.discrete(t);
            for f in [1.0, 22.39, 52.0, 200.0] {
                let c = plant.continuous_response(f, 1.5 * t + extra_s);
                let z = d.response(f, t);
                // The hold's sinc and aliasing: 2e-3 up to 200 Hz at 2.74 kHz.
                assert!(
                    (z - c).norm() < 1e-2 * c.norm(),
                    "{extra_s} s, {f} Hz: {z} vs {c}"
                );
            }
            assert!((d.response(0.0, t).re - 11.4).abs() < 1e-9);
        }
        // Without an extra delay nothing changes: the plain hold and one delay.
        let plain = PlantModel::default().discrete(t);
        assert_eq!(plain.sections().len(), 2);
        assert_eq!(plain.sections()[1], Section::delay());
    }
}
