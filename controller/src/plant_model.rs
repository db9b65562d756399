//! The nominal plant model: eq. 4 in the paper's units (input V -> output V), zero-order-hold
//! discretised at the control period, times one period of delay for `exp(-s Ta)`. This is the
//! emulator's timing convention: from the command sequence `u[k]` to the measurements `y[k]`
//! the plant is `z^-1 * ZOH(G)`.

use nalgebra::Complex;

use crate::continuous::{ContinuousSection, Quadratic};
use crate::discretise::{Method, discretise};
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
}

impl Default for PlantModel {
    fn default() -> Self {
        Self {
            dc_gain: 11.4,
            natural_freq_rad_s: 140.68,
            damping_ratio: 3.21e-2,
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

    /// `ZOH(G)` at `period_s`: fed the command of period k, its output is the angle at the
    /// end of period k+1 (the command acts one period late).
    #[must_use]
    pub fn zoh(&self, period_s: f64) -> Section {
        discretise(&self.section(), &Method::ZeroOrderHold, period_s)
    }

    /// `z^-1 * ZOH(G)` at `period_s`, as a cascade (at rest): the map from the command
    /// sequence `u[k]` to the measurement sequence `y[k] = angle(k T)`.
    #[must_use]
    pub fn discrete(&self, period_s: f64) -> Cascade {
        Cascade::new(1.0, vec![self.zoh(period_s), Section::delay()])
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
}
