//! A system analyser in software: stepped-sine ([`identify`]) or swept-sine
//! ([`identify_swept`]) excitation of one sensing axis through a [`PlantLink`], and the frequency response with its coherence, of the open-loop plant
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
use crate::trajectory::{SensingAxis, swept_sine_phase};

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

/// Drives one axis through the link, one period per call, in either target mode.
struct Exciter<'a> {
    link: &'a mut dyn PlantLink,
    target: &'a mut Target,
    axis: SensingAxis,
    measured: SensingPair,
}

impl<'a> Exciter<'a> {
    /// Excites `axis` through `link`, starting from a zero measurement.
    fn new(link: &'a mut dyn PlantLink, target: &'a mut Target, axis: SensingAxis) -> Self {
        Exciter {
            link,
            target,
            axis,
            measured: SensingPair::default(),
        }
    }

    /// Applies `excitation` for one period; returns this period's measured response on the
    /// excited and on the other axis (paper output units open loop, rad closed loop).
    fn period(&mut self, excitation: f64) -> Result<(f64, f64), LinkError> {
        let axis = self.axis;
        let measured = self.measured;
        let (command, scale) = match self.target {
            Target::OpenLoop => (
                actuator_from_sensing(axis.pair(excitation * AMPS_PER_INPUT_UNIT)),
                1.0 / RAD_PER_OUTPUT_UNIT,
            ),
            Target::ClosedLoop(controller) => {
                (controller.step(axis.pair(excitation), measured), 1.0)
            }
        };
        self.measured = self.link.exchange(command)?;
        Ok((axis.of(measured) * scale, axis.other().of(measured) * scale))
    }
}

/// Sums of cross and auto spectra over blocks, at one frequency.
#[derive(Default)]
struct SpectralSums {
    syu: Complex<f64>,
    sxu: Complex<f64>,
    suu: f64,
    syy: f64,
}

impl SpectralSums {
    /// Adds one block's Fourier coefficients of excitation, response and other axis.
    fn add(&mut self, u: Complex<f64>, y: Complex<f64>, x: Complex<f64>) {
        self.syu += y * u.conj();
        self.sxu += x * u.conj();
        self.suu += u.norm_sqr();
        self.syy += y.norm_sqr();
    }

    fn point(&self, f_hz: f64) -> ResponsePoint {
        let h = self.syu / self.suu;
        ResponsePoint {
            f_hz,
            magnitude: h.norm(),
            magnitude_db: 20.0 * h.norm().log10(),
            phase_deg: h.arg().to_degrees(),
            coherence: self.syu.norm_sqr() / (self.suu * self.syy),
            cross_axis_db: 20.0 * (self.sxu / self.suu).norm().log10(),
        }
    }
}

/// Runs the stepped-sine plan through `link` and returns one point per frequency.
pub fn identify(
    link: &mut dyn PlantLink,
    plan: &SteppedSine,
    target: &mut Target,
) -> Result<Vec<ResponsePoint>, LinkError> {
    let period_s = link.period_s();
    let mut exciter = Exciter::new(link, target, plan.axis);
    let mut points = Vec::with_capacity(plan.frequencies_hz.len());
    for &requested in &plan.frequencies_hz {
        let cycles = f64::from(plan.cycles_per_block);
        let block_len = ((cycles / (requested * period_s)).round() as usize).max(2);
        let f_hz = cycles / (block_len as f64 * period_s);
        let settle = (plan.settle_s / period_s).round() as usize;
        let w = std::f64::consts::TAU * f_hz * period_s;
        let mut sums = SpectralSums::default();
        let mut k = 0usize;
        for block in 0..=plan.blocks as usize {
            let len = if block == 0 { settle } else { block_len };
            let zero = Complex::new(0.0, 0.0);
            let (mut u_sum, mut y_sum, mut x_sum) = (zero, zero, zero);
            for _ in 0..len {
                let excitation = plan.amplitude * (w * k as f64).sin();
                let (response, other) = exciter.period(excitation)?;
                let basis = Complex::from_polar(1.0, -w * k as f64);
                u_sum += basis * excitation;
                y_sum += basis * response;
                x_sum += basis * other;
                k += 1;
            }
            if block > 0 {
                sums.add(u_sum, y_sum, x_sum);
            }
        }
        points.push(sums.point(f_hz));
    }
    Ok(points)
}

/// A logarithmic swept-sine plan: `sweeps` repetitions, each a sweep from `start_hz` to
/// `stop_hz` over `sweep_s` followed by `quiet_s` of zero excitation, so the response has died
/// out before the next sweep and each repetition's record holds the whole response. Then
/// `Y(f) = H(f) U(f)` holds exactly for the records' Fourier transforms at any frequency, and
/// the repetitions give the coherence.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SweptSinePlan {
    /// The excited sensing axis.
    pub axis: SensingAxis,
    /// Sweep start frequency, Hz.
    pub start_hz: f64,
    /// Sweep stop frequency, Hz.
    pub stop_hz: f64,
    /// Duration of one sweep, s.
    pub sweep_s: f64,
    /// Zero excitation after each sweep, s (several decay times of the plant or loop).
    pub quiet_s: f64,
    /// Repetitions (the coherence needs at least two).
    pub sweeps: u32,
    /// Amplitude, as for [`SteppedSine::amplitude`].
    pub amplitude: f64,
    /// The frequencies at which the response is estimated, Hz (inside the sweep's band).
    pub frequencies_hz: Vec<f64>,
}

/// Runs the swept-sine plan through `link` and returns one point per analysis frequency.
pub fn identify_swept(
    link: &mut dyn PlantLink,
    plan: &SweptSinePlan,
    target: &mut Target,
) -> Result<Vec<ResponsePoint>, LinkError> {
    let period_s = link.period_s();
    let mut exciter = Exciter::new(link, target, plan.axis);
    let sweep_len = (plan.sweep_s / period_s).round() as usize;
    let record_len = sweep_len + (plan.quiet_s / period_s).round() as usize;
    let mut sums: Vec<SpectralSums> = plan
        .frequencies_hz
        .iter()
        .map(|_| SpectralSums::default())
        .collect();
    let (mut u, mut y, mut x) = (
        vec![0.0; record_len],
        vec![0.0; record_len],
        vec![0.0; record_len],
    );
    for _ in 0..plan.sweeps {
        for k in 0..record_len {
            let t_s = k as f64 * period_s;
            u[k] = if k < sweep_len {
                plan.amplitude
                    * swept_sine_phase(plan.start_hz, plan.stop_hz, plan.sweep_s, t_s).sin()
            } else {
                0.0
            };
            (y[k], x[k]) = exciter.period(u[k])?;
        }
        for (sum, &f_hz) in sums.iter_mut().zip(&plan.frequencies_hz) {
            let w = std::f64::consts::TAU * f_hz * period_s;
            sum.add(dft_at(&u, w), dft_at(&y, w), dft_at(&x, w));
        }
    }
    Ok(sums
        .iter()
        .zip(&plan.frequencies_hz)
        .map(|(s, &f)| s.point(f))
        .collect())
}

/// The Fourier transform of `samples` at `w` rad per sample.
fn dft_at(samples: &[f64], w: f64) -> Complex<f64> {
    samples
        .iter()
        .enumerate()
        .map(|(k, &v)| Complex::from_polar(v, -w * k as f64))
        .sum()
}
