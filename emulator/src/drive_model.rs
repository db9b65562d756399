//! The composed linear dynamics from coil current commands to mirror angles, built from the
//! scene's active parts only: the amplifiers' current loops (part `amplifier`), the rotation
//! and coupling (part `cross_talk`), and eq. 4 on each moving sensing axis (part `axes`).
//!
//! State vector, in this order, each block present only when its part is:
//! `[i_a, i_b]` (A, amplifier output currents), then per moving axis `[y, dy/dt]` (output
//! units, output units/s). Input: the two limited coil current commands `[c_a, c_b]` in A.
//! Without the amplifier part the commands drive the mirror directly.

use nalgebra::DMatrix;

use scanhil_protocol::plant_units::RAD_PER_OUTPUT_UNIT;

use crate::amplifier::AmplifierConfig;
use crate::cross_talk::{CrossTalkConfig, input_from_currents};
use crate::mirror::{MirrorConfig, SensingAxis};

/// Number of inputs: the two coil current commands.
pub const INPUTS: usize = 2;

/// `dx/dt = A x + B u` for the active parts.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveModel {
    /// State matrix (n x n).
    pub a: DMatrix<f64>,
    /// Input matrix (n x 2).
    pub b: DMatrix<f64>,
    /// Index of the amplifier's `i_a` state (`i_b` follows), if the amplifier is modelled.
    pub current_index: Option<usize>,
    /// Index of each sensing axis's angle state (`[alpha, beta]`), if that axis moves.
    pub angle_index: [Option<usize>; 2],
}

impl DriveModel {
    /// Builds the model; `None` arguments are parts that are not active. `mirror` is `None`
    /// when the `axes` part is off (then no axis moves).
    #[must_use]
    pub fn new(
        mirror: Option<&MirrorConfig>,
        amplifier: Option<&AmplifierConfig>,
        cross_talk: Option<&CrossTalkConfig>,
    ) -> DriveModel {
        let current_index = amplifier.map(|_| 0);
        let mut n = if amplifier.is_some() { 2 } else { 0 };
        let mut angle_index = [None, None];
        if let Some(m) = mirror {
            for (slot, axis) in angle_index.iter_mut().zip(SensingAxis::BOTH) {
                if m.moves(axis) {
                    *slot = Some(n);
                    n += 2;
                }
            }
        }
        let mut a = DMatrix::zeros(n, n);
        let mut b = DMatrix::zeros(n, INPUTS);
        if let Some(amp) = amplifier {
            let wb = amp.pole_rad_s();
            for k in 0..2 {
                a[(k, k)] = -wb;
                b[(k, k)] = wb;
            }
        }
        if let Some(m) = mirror {
            let coupling = input_from_currents(cross_talk);
            for ((row, slot), axis) in angle_index.iter().enumerate().zip(SensingAxis::BOTH) {
                let Some(i) = *slot else { continue };
                let dynamics = m.axis(axis);
                let am = dynamics.state_matrix();
                let bm = dynamics.input_column();
                for r in 0..2 {
                    for c in 0..2 {
                        a[(i + r, i + c)] = am[r][c];
                    }
                }
                for (coil, &g) in coupling[row].iter().enumerate() {
                    match current_index {
                        Some(ci) => a[(i + 1, ci + coil)] = bm[1] * g,
                        None => b[(i + 1, coil)] = bm[1] * g,
                    }
                }
            }
        }
        DriveModel {
            a,
            b,
            current_index,
            angle_index,
        }
    }

    /// Number of states.
    #[must_use]
    pub fn states(&self) -> usize {
        self.a.nrows()
    }

    /// The state for mirror angles `initial_rad` at rest and cold amplifiers.
    #[must_use]
    pub fn initial_state(&self, initial_rad: [f64; 2]) -> Vec<f64> {
        let mut x = vec![0.0; self.states()];
        for (slot, angle) in self.angle_index.iter().zip(initial_rad) {
            if let Some(i) = slot {
                x[*i] = angle / RAD_PER_OUTPUT_UNIT;
            }
        }
        x
    }

    /// The mechanical angle (rad) of a moving axis in state `x`.
    #[must_use]
    pub fn angle_rad(&self, x: &[f64], axis: SensingAxis) -> Option<f64> {
        let slot = match axis {
            SensingAxis::Alpha => self.angle_index[0],
            SensingAxis::Beta => self.angle_index[1],
        };
        slot.map(|i| x[i] * RAD_PER_OUTPUT_UNIT)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_left_out_leave_no_states() {
        let m = MirrorConfig::default();
        assert_eq!(DriveModel::new(None, None, None).states(), 0);
        assert_eq!(DriveModel::new(Some(&m), None, None).states(), 4);
        let amp = AmplifierConfig::default();
        assert_eq!(DriveModel::new(Some(&m), Some(&amp), None).states(), 6);
        let single = MirrorConfig {
            axes: vec![SensingAxis::Beta],
            ..m
        };
        let model = DriveModel::new(Some(&single), None, None);
        assert_eq!(model.states(), 2);
        assert_eq!(model.angle_index, [None, Some(0)]);
    }

    #[test]
    fn dc_gain_from_current_to_angle_is_k_over_amps_per_unit() {
        // At DC: A x + B u = 0  =>  x = -A^-1 B u.
        let m = MirrorConfig::default();
        let amp = AmplifierConfig::default();
        let model = DriveModel::new(Some(&m), Some(&amp), None);
        let inv = model.a.clone().try_inverse().unwrap();
        let gain = -(inv * &model.b);
        // A pure-alpha command of 1 A is (1/sqrt2, 1/sqrt2) on the coils.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let alpha = gain[(2, 0)] * h + gain[(2, 1)] * h;
        let beta = gain[(4, 0)] * h + gain[(4, 1)] * h;
        assert!(
            (alpha - 11.4).abs() < 1e-9 && beta.abs() < 1e-9,
            "{alpha} {beta}"
        );
    }
}
