//! A system analyser in software: stepped-sine excitation of one sensing axis through a
//! [`PlantLink`], and the frequency response with its coherence, of the open-loop plant
//! (coil command to angle, in the paper's units) or of the closed loop (reference to angle).
//!
//! At each frequency the sine is first run for `settle_s` so transients die out, then for
//! `blocks` blocks of `cycles_per_block` whole periods. The frequency is adjusted so a block
//! holds a whole number of samples (no leakage). Per block, the Fourier coefficients `U_i`,
//! `Y_i` at that frequency give the H1 estimate `H = sum(Y U*) / sum(|U|^2)` and the
//! coherence `gamma^2 = |sum(Y U*)|^2 / (sum(|U|^2) sum(|Y|^2))`: 1 for a noise-free linear
//! plant, below 1 with noise or distortion.

use nalgebra::Complex;
use scanhil_protocol::plant_units::{
    AMPS_PER_INPUT_UNIT, RAD_PER_OUTPUT_UNIT, SensingPair, actuator_from_sensing,
};

use crate::link::{LinkError, PlantLink};
use crate::scan_controller::ScanController;
use crate::trajectory::SensingAxis;

/// The stepped-sine plan.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SteppedSine {
    /// The excited sensing axis.
    pub axis: SensingAxis,
    /// The requested frequencies, Hz (each is adjusted to a whole number of samples per block).
    pub frequencies_hz: Vec<f64>,
    /// Open loop: coil command amplitude in input units (A at 1 A/V); closed loop: reference
    /// amplitude in rad.
    pub amplitude: f64,
    /// Settling time before measuring at each frequency, s.
    pub settle_s: f64,
    /// Whole periods per block.
    pub cycles_per_block: u32,
    /// Blocks averaged per frequency (the coherence needs at least two).
    pub blocks: u32,
}

impl SteppedSine {
    /// `points` frequencies spaced logarithmically from `from_hz` to `to_hz`.
    #[must_use]
    pub fn log_frequencies(from_hz: f64, to_hz: f64, points: usize) -> Vec<f64> {
        if points < 2 {
            return vec![from_hz];
        }
        let ratio = (to_hz / from_hz).ln();
        (0..points)
            .map(|i| from_hz * (ratio * i as f64 / (points - 1) as f64).exp())
            .collect()
    }
}

/// What is measured.
#[derive(Debug)]
pub enum Target {
    /// The plant: the excitation is the coil command on the axis, the response that axis'
    /// angle (both in the paper's units: output V per input V).
    OpenLoop,
    /// The closed loop with this controller: the excitation is the reference, the response
    /// the measured angle (T).
    ClosedLoop(Box<ScanController>),
}

/// One measured frequency.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ResponsePoint {
    /// The frequency actually used, Hz.
    pub f_hz: f64,
    /// |H|.
    pub magnitude: f64,
    /// |H| in dB.
    pub magnitude_db: f64,
    /// arg H, degrees in (-180, 180].
    pub phase_deg: f64,
    /// Coherence gamma^2 between excitation and response, 0..1.
    pub coherence: f64,
    /// H1 estimate of the other axis' response to this axis' excitation, dB (cross-talk).
    pub cross_axis_db: f64,
}

/// Runs the plan through `link` and returns one point per frequency.
pub fn identify(
    link: &mut dyn PlantLink,
    plan: &SteppedSine,
    target: &mut Target,
) -> Result<Vec<ResponsePoint>, LinkError> {
    let period_s = link.period_s();
    let mut measured = SensingPair::default();
    let mut points = Vec::with_capacity(plan.frequencies_hz.len());
    for &requested in &plan.frequencies_hz {
        let block_len =
            ((f64::from(plan.cycles_per_block) / (requested * period_s)).round() as usize).max(2);
        let f_hz = f64::from(plan.cycles_per_block) / (block_len as f64 * period_s);
        let settle = (plan.settle_s / period_s).round() as usize;
        let w = std::f64::consts::TAU * f_hz * period_s;
        let (mut syu, mut sxu, mut suu, mut syy) =
            (Complex::new(0.0, 0.0), Complex::new(0.0, 0.0), 0.0, 0.0);
        let mut k = 0usize;
        for block in 0..=plan.blocks as usize {
            let len = if block == 0 { settle } else { block_len };
            let (mut u_sum, mut y_sum, mut x_sum) = (
                Complex::new(0.0, 0.0),
                Complex::new(0.0, 0.0),
                Complex::new(0.0, 0.0),
            );
            for _ in 0..len {
                let excitation = plan.amplitude * (w * k as f64).sin();
                let (command, response, other) = match target {
                    Target::OpenLoop => {
                        let command =
                            actuator_from_sensing(plan.axis.pair(excitation * AMPS_PER_INPUT_UNIT));
                        let to_units = |rad: f64| rad / RAD_PER_OUTPUT_UNIT;
                        let response = to_units(plan.axis.of(measured));
                        let other = to_units(plan.axis.other().of(measured));
                        (command, response, other)
                    }
                    Target::ClosedLoop(controller) => {
                        let reference = plan.axis.pair(excitation);
                        let command = controller.step(reference, measured);
                        (
                            command,
                            plan.axis.of(measured),
                            plan.axis.other().of(measured),
                        )
                    }
                };
                if block > 0 {
                    let basis = Complex::from_polar(1.0, -w * k as f64);
                    u_sum += basis * excitation;
                    y_sum += basis * response;
                    x_sum += basis * other;
                }
                measured = link.exchange(command)?;
                k += 1;
            }
            if block > 0 {
                syu += y_sum * u_sum.conj();
                suu += u_sum.norm_sqr();
                syy += y_sum.norm_sqr();
                sxu += x_sum * u_sum.conj();
            }
        }
        let h = syu / suu;
        points.push(ResponsePoint {
            f_hz,
            magnitude: h.norm(),
            magnitude_db: 20.0 * h.norm().log10(),
            phase_deg: h.arg().to_degrees(),
            coherence: syu.norm_sqr() / (suu * syy),
            cross_axis_db: 20.0 * (sxu / suu).norm().log10(),
        });
    }
    Ok(points)
}
