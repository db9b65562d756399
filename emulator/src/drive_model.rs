//! The composed linear dynamics from coil current commands to mirror angles, built from the
//! scene's active parts only: the amplifiers (part `amplifier`: a first-order current loop, or
//! with part `current_loop` the PI loop with the coil and back-EMF), the rotation and coupling
//! (part `cross_talk`), eq. 4 on each moving sensing axis (part `axes`) with its second mode
//! (part `second_mode`), the coil currents picked up by the angle sensor (part
//! `cross_talk_pickup`) and the angle sensor's bandwidth (part `angle_sensor_bandwidth`).
//!
//! State vector, in this order, each block present only when its part is:
//! `[i_a, i_b]` (A, amplifier output currents) and, with `current_loop`, `[q_a, q_b]` (V, the
//! PI integrals); then per moving axis `[y, dy/dt]` (output units, output units/s) and, with
//! `second_mode`, `[z, dz/dt]`; then per moving axis the angle sensor's filter `[f]` (output
//! units). Inputs: the two limited coil current commands `[c_a, c_b]` in A and a constant 1
//! (the rail voltage of a saturated amplifier enters by it, [`DriveModel::saturated`]).
//! Without an amplifier part the commands drive the mirror directly.
//!
//! Two outputs per moving axis: the mechanical angle ([`DriveModel::angle_rows`]: what the
//! optics see) and the measured one ([`DriveModel::measured_rows`]: what the angle sensor
//! reports, before its latency, nonlinearity, noise and quantisation).

use nalgebra::DMatrix;

use scanhil_protocol::plant_units::{
    ActuatorPair, RAD_PER_OUTPUT_UNIT, SensingPair, sensing_from_actuator,
};

use crate::amplifier::AmplifierConfig;
use crate::cross_talk::{CrossTalkConfig, input_from_currents};
use crate::current_loop::CurrentLoop;
use crate::mirror::{MirrorConfig, SensingAxis};
use crate::scene::{Part, Scene};

/// Number of inputs: the two coil current commands and the constant 1.
pub const INPUTS: usize = 3;

/// An output `c x + d u` of the model.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputRow {
    /// The coefficients of the states.
    pub c: Vec<f64>,
    /// The coefficients of the inputs.
    pub d: [f64; INPUTS],
}

impl OutputRow {
    /// `c x + d u`.
    #[must_use]
    pub fn value(&self, x: &[f64], u: [f64; INPUTS]) -> f64 {
        let states: f64 = self.c.iter().zip(x).map(|(c, x)| c * x).sum();
        states + self.d.iter().zip(u).map(|(d, u)| d * u).sum::<f64>()
    }

    fn unit(n: usize, index: usize) -> OutputRow {
        let mut c = vec![0.0; n];
        c[index] = 1.0;
        OutputRow {
            c,
            d: [0.0; INPUTS],
        }
    }
}

/// Where the current loop's states are, and its values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurrentLoopStates {
    /// The loop's values.
    pub values: CurrentLoop,
    /// The coil currents' indices (`a`, `b`).
    pub current: [usize; 2],
    /// The PI integrals' indices (`a`, `b`).
    pub integral: [usize; 2],
}

impl CurrentLoopStates {
    /// The voltage each coil's controller asks for in state `x` with the commands `command_a`.
    #[must_use]
    pub fn demand_v(&self, x: &[f64], command_a: [f64; 2]) -> [f64; 2] {
        [0, 1].map(|k| {
            self.values
                .demand_v(command_a[k], x[self.current[k]], x[self.integral[k]])
        })
    }
}

/// The parts a drive model is built from; `None` / `false` are parts that are not active.
#[derive(Debug, Clone, Copy, Default)]
pub struct DriveParts<'a> {
    /// Eq. 4 per moving axis (part `axes`); `None`: no axis moves.
    pub mirror: Option<&'a MirrorConfig>,
    /// The mirror's second modes (part `second_mode`, from `mirror`).
    pub second_mode: bool,
    /// The first-order amplifier (part `amplifier`), unless `current_loop` replaces its lag.
    pub amplifier: Option<&'a AmplifierConfig>,
    /// The amplifier's current loop (part `current_loop`).
    pub current_loop: Option<CurrentLoop>,
    /// The coupling matrix (part `cross_talk`).
    pub cross_talk: Option<&'a CrossTalkConfig>,
    /// The coil currents seen by the angle sensor (part `cross_talk_pickup`), rad per A on
    /// alpha from beta's current and on beta from alpha's.
    pub pickup_rad_per_a: Option<SensingPair>,
    /// The angle sensor's bandwidth (part `angle_sensor_bandwidth`), Hz.
    pub angle_sensor_bandwidth_hz: Option<f64>,
}

impl<'a> DriveParts<'a> {
    /// The parts `scene` lists (the current loop's coil resistance, unless the scene sets its
    /// own, is [`Scene::coil_resistance_ohm`]).
    #[must_use]
    pub fn of_scene(scene: &'a Scene) -> DriveParts<'a> {
        let has = |part: Part| scene.has(part);
        let pickup = scene.cross_talk.pickup_urad_per_a;
        DriveParts {
            mirror: has(Part::Axes).then_some(&scene.mirror),
            second_mode: has(Part::SecondMode),
            amplifier: has(Part::Amplifier).then_some(&scene.amplifier),
            current_loop: has(Part::CurrentLoop).then(|| {
                scene
                    .current_loop
                    .resolve(scene.amplifier.bandwidth_hz, scene.coil_resistance_ohm())
            }),
            cross_talk: has(Part::CrossTalk).then_some(&scene.cross_talk),
            pickup_rad_per_a: has(Part::CrossTalkPickup).then_some(SensingPair {
                alpha: pickup.alpha_from_beta * 1e-6,
                beta: pickup.beta_from_alpha * 1e-6,
            }),
            angle_sensor_bandwidth_hz: has(Part::AngleSensorBandwidth)
                .then_some(scene.angle_sensor.bandwidth_hz),
        }
    }
}

/// `dx/dt = A x + B u` for the active parts, and its outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveModel {
    /// State matrix (n x n).
    pub a: DMatrix<f64>,
    /// Input matrix (n x [`INPUTS`]).
    pub b: DMatrix<f64>,
    /// Index of the amplifier's `i_a` state (`i_b` follows), if an amplifier is modelled.
    pub current_index: Option<usize>,
    /// The current loop's states, with part `current_loop`.
    pub current_loop: Option<CurrentLoopStates>,
    /// Index of each moving axis's first-mode angle state `y` (`[alpha, beta]`).
    pub mode_index: [Option<usize>; 2],
    /// Index of each axis's second-mode state `z`, with part `second_mode`.
    pub second_index: [Option<usize>; 2],
    /// Index of each axis's angle sensor filter state, with part `angle_sensor_bandwidth`.
    pub filter_index: [Option<usize>; 2],
    /// Each moving axis's mechanical angle, output units.
    pub angle_rows: [Option<OutputRow>; 2],
    /// Each moving axis's measured angle, output units.
    pub measured_rows: [Option<OutputRow>; 2],
}

impl DriveModel {
    /// Eq. 4 with the first-order amplifier and the coupling matrix; `None` arguments are
    /// parts that are not active.
    #[must_use]
    pub fn new(
        mirror: Option<&MirrorConfig>,
        amplifier: Option<&AmplifierConfig>,
        cross_talk: Option<&CrossTalkConfig>,
    ) -> DriveModel {
        DriveModel::build(&DriveParts {
            mirror,
            amplifier,
            cross_talk,
            ..DriveParts::default()
        })
    }

    /// Builds the model of `parts`.
    #[must_use]
    pub fn build(parts: &DriveParts) -> DriveModel {
        let moving = |axis: SensingAxis| parts.mirror.is_some_and(|m| m.moves(axis));
        // The layout.
        let mut n = 0;
        let mut take = |count: usize| {
            n += count;
            n - count
        };
        let amplified = parts.amplifier.is_some() || parts.current_loop.is_some();
        let current_index = amplified.then(|| take(2));
        let current_loop = parts.current_loop.map(|values| {
            let first = current_index.unwrap_or(0);
            CurrentLoopStates {
                values,
                current: [first, first + 1],
                integral: {
                    let q = take(2);
                    [q, q + 1]
                },
            }
        });
        let mut mode_index = [None, None];
        let mut second_index = [None, None];
        for ((slot, second), axis) in mode_index
            .iter_mut()
            .zip(&mut second_index)
            .zip(SensingAxis::BOTH)
        {
            if moving(axis) {
                *slot = Some(take(2));
                if parts.second_mode {
                    *second = Some(take(2));
                }
            }
        }
        let mut filter_index = [None, None];
        if parts.angle_sensor_bandwidth_hz.is_some() {
            for (slot, axis) in filter_index.iter_mut().zip(SensingAxis::BOTH) {
                if moving(axis) {
                    *slot = Some(take(1));
                }
            }
        }
        let mut a = DMatrix::zeros(n, n);
        let mut b = DMatrix::zeros(n, INPUTS);

        // The amplifiers.
        if let (Some(ci), None) = (current_index, current_loop) {
            let wb = parts.amplifier.map_or(0.0, AmplifierConfig::pole_rad_s);
            for k in 0..2 {
                a[(ci + k, ci + k)] = -wb;
                b[(ci + k, k)] = wb;
            }
        }
        if let Some(cl) = current_loop {
            let v = cl.values;
            let l = v.inductance_h;
            for k in 0..2 {
                let (i, q) = (cl.current[k], cl.integral[k]);
                a[(i, i)] = -(v.kp_v_per_a + v.resistance_ohm) / l;
                a[(i, q)] = 1.0 / l;
                b[(i, k)] = v.kp_v_per_a / l;
                a[(q, i)] = -v.ki_v_per_a_s;
                b[(q, k)] = v.ki_v_per_a_s;
            }
        }

        // The mechanics, driven by the currents through the rotation and coupling.
        let coupling = input_from_currents(parts.cross_talk);
        let mut angle_rows = [None, None];
        for (row, axis) in SensingAxis::BOTH.into_iter().enumerate() {
            let (Some(m), Some(y)) = (parts.mirror, mode_index[row]) else {
                continue;
            };
            let dynamics = m.axis(axis);
            let am = dynamics.state_matrix();
            let bm = dynamics.input_column();
            for r in 0..2 {
                for c in 0..2 {
                    a[(y + r, y + c)] = am[r][c];
                }
            }
            for (coil, &g) in coupling[row].iter().enumerate() {
                match current_index {
                    Some(ci) => a[(y + 1, ci + coil)] = bm[1] * g,
                    None => b[(y + 1, coil)] = bm[1] * g,
                }
            }
            if let Some(cl) = current_loop
                && cl.values.inertia_kg_m2 > 0.0
            {
                // Back-EMF: k_t coupling[axis][coil] omega, omega in rad/s.
                let ws = dynamics.natural_freq_rad_s;
                let torque_per_input =
                    cl.values.inertia_kg_m2 * ws * ws * dynamics.dc_gain * RAD_PER_OUTPUT_UNIT;
                for (coil, &g) in coupling[row].iter().enumerate() {
                    a[(cl.current[coil], y + 1)] -=
                        torque_per_input * g * RAD_PER_OUTPUT_UNIT / cl.values.inductance_h;
                }
            }
            let mut angle = OutputRow::unit(n, y);
            if let Some(z) = second_index[row] {
                let mode = dynamics.second_mode;
                let (am2, bm2) = mode.state_matrix();
                for r in 0..2 {
                    for c in 0..2 {
                        a[(z + r, z + c)] = am2[r][c];
                    }
                    a[(z + r, y)] = bm2[r];
                }
                let [of_y, of_z, of_dz] = mode.output_row();
                angle.c[y] = of_y;
                angle.c[z] = of_z;
                angle.c[z + 1] = of_dz;
            }
            angle_rows[row] = Some(angle);
        }

        // What the angle sensor sees: the angle and the other axis's current it picks up.
        let mut measured_rows = angle_rows.clone();
        if let Some(pickup) = parts.pickup_rad_per_a {
            let rotation = |coil: ActuatorPair| sensing_from_actuator(coil);
            let per_coil = [
                rotation(ActuatorPair { a: 1.0, b: 0.0 }),
                rotation(ActuatorPair { a: 0.0, b: 1.0 }),
            ];
            for (row, measured) in measured_rows.iter_mut().enumerate() {
                let Some(measured) = measured else { continue };
                for (coil, sensing) in per_coil.iter().enumerate() {
                    // Alpha picks up beta's current, beta alpha's.
                    let gain = if row == 0 {
                        pickup.alpha * sensing.beta
                    } else {
                        pickup.beta * sensing.alpha
                    } / RAD_PER_OUTPUT_UNIT;
                    match current_index {
                        Some(ci) => measured.c[ci + coil] += gain,
                        None => measured.d[coil] += gain,
                    }
                }
            }
        }
        if let Some(bandwidth_hz) = parts.angle_sensor_bandwidth_hz {
            let wf = std::f64::consts::TAU * bandwidth_hz;
            for (measured, slot) in measured_rows.iter_mut().zip(filter_index) {
                let (Some(raw), Some(f)) = (measured.as_ref(), slot) else {
                    continue;
                };
                for (j, c) in raw.c.iter().enumerate() {
                    a[(f, j)] += wf * c;
                }
                for (j, d) in raw.d.iter().enumerate() {
                    b[(f, j)] += wf * d;
                }
                a[(f, f)] -= wf;
                *measured = Some(OutputRow::unit(n, f));
            }
        }
        DriveModel {
            a,
            b,
            current_index,
            current_loop,
            mode_index,
            second_index,
            filter_index,
            angle_rows,
            measured_rows,
        }
    }

    /// Number of states.
    #[must_use]
    pub fn states(&self) -> usize {
        self.a.nrows()
    }

    /// The model with each coil whose entry is `Some(sign)` held at `sign x` the current
    /// loop's voltage limit (its PI integral frozen), the others unchanged. Only a model with
    /// a current loop has anything to saturate; any other is returned as it is.
    #[must_use]
    pub fn saturated(&self, signs: [Option<f64>; 2]) -> DriveModel {
        let mut model = self.clone();
        let Some(cl) = self.current_loop else {
            return model;
        };
        let v = cl.values;
        let l = v.inductance_h;
        for (k, sign) in signs.iter().enumerate() {
            let Some(sign) = sign else { continue };
            let (i, q) = (cl.current[k], cl.integral[k]);
            model.a[(i, i)] = -v.resistance_ohm / l;
            model.a[(i, q)] = 0.0;
            model.b[(i, k)] = 0.0;
            model.b[(i, 2)] = sign * v.max_voltage_v / l;
            for c in 0..self.states() {
                model.a[(q, c)] = 0.0;
            }
            model.b[(q, k)] = 0.0;
        }
        model
    }

    /// The state for mirror angles `initial_rad` at rest and cold amplifiers: the second mode
    /// and the sensor filter at their static values for those angles.
    #[must_use]
    pub fn initial_state(&self, initial_rad: [f64; 2]) -> Vec<f64> {
        let mut x = vec![0.0; self.states()];
        for (row, angle) in initial_rad.iter().enumerate() {
            let Some(y) = self.mode_index[row] else {
                continue;
            };
            let units = angle / RAD_PER_OUTPUT_UNIT;
            x[y] = units;
            if let Some(z) = self.second_index[row] {
                // At rest z'' = 0: w2^2 z = y, and the mode passes y unchanged.
                x[z] = units / -self.a[(z + 1, z)];
            }
            if let Some(f) = self.filter_index[row] {
                x[f] = units;
            }
        }
        x
    }

    /// The mechanical angle (rad) of a moving axis in state `x`.
    #[must_use]
    pub fn angle_rad(&self, x: &[f64], axis: SensingAxis) -> Option<f64> {
        self.angle_rows[axis_row(axis)]
            .as_ref()
            .map(|row| row.value(x, [0.0; INPUTS]) * RAD_PER_OUTPUT_UNIT)
    }

    /// The measured angle (rad) of a moving axis in state `x` with the inputs `u`, before the
    /// angle sensor's latency, nonlinearity, noise and quantisation.
    #[must_use]
    pub fn measured_rad(&self, x: &[f64], u: [f64; INPUTS], axis: SensingAxis) -> Option<f64> {
        self.measured_rows[axis_row(axis)]
            .as_ref()
            .map(|row| row.value(x, u) * RAD_PER_OUTPUT_UNIT)
    }
}

/// `[alpha, beta]` index of an axis.
fn axis_row(axis: SensingAxis) -> usize {
    match axis {
        SensingAxis::Alpha => 0,
        SensingAxis::Beta => 1,
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
        assert_eq!(model.mode_index, [None, Some(0)]);
        assert_eq!(model.second_index, [None, None]);
        assert_eq!(model.filter_index, [None, None]);
        assert!(model.current_loop.is_none());
    }

    #[test]
    fn the_richer_parts_add_their_states_in_the_documented_order() {
        let m = MirrorConfig::default();
        let amp = AmplifierConfig::default();
        let current_loop = crate::current_loop::CurrentLoopConfig::default().resolve(10e3, 3.0);
        let model = DriveModel::build(&DriveParts {
            mirror: Some(&m),
            second_mode: true,
            amplifier: Some(&amp),
            current_loop: Some(current_loop),
            angle_sensor_bandwidth_hz: Some(10e3),
            ..DriveParts::default()
        });
        // [i_a, i_b, q_a, q_b], alpha [y, y', z, z'], beta [y, y', z, z'], [f_alpha, f_beta].
        assert_eq!(model.states(), 14);
        assert_eq!(model.current_index, Some(0));
        let cl = model.current_loop.expect("the loop is modelled");
        assert_eq!((cl.current, cl.integral), ([0, 1], [2, 3]));
        assert_eq!(model.mode_index, [Some(4), Some(8)]);
        assert_eq!(model.second_index, [Some(6), Some(10)]);
        assert_eq!(model.filter_index, [Some(12), Some(13)]);
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
