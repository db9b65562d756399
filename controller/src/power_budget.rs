//! The steady-state mean coil power a trajectory needs, estimated before a run from the plant
//! model, the nominal closed loop and the rig's coils.
//!
//! The reference is split into its Fourier content ([`Trajectory::tones`]): a sine is one
//! tone; a triangle (raster) its odd harmonics up to Nyquist; a step its DC value. The loop filters each tone: the plant input per unit of reference is the control
//! effort `C / (1 + L) = T / G` of the nominal loop ([`NominalLoop::control_effort`]). The
//! mirror's cross-talk `M = [1, c_ab; c_ba, 1]` on the sensing inputs is undone by the loop, so
//! the currents on the sensing axes are `u = M^-1 v`. The 45 degree rotation preserves
//! `i_a^2 + i_b^2`, so the mean power of both coils is `R sum_f w_f (|u_alpha|^2 + |u_beta|^2)`
//! with `w_f = 1/2` for a tone and 1 for DC (one sine: `P = R I^2 / 2`). A swept sine is
//! charged the largest steady-state power over its band.
//!
//! The estimate is linear: the current and power limits, the controller's output limit and
//! the start-up transient are not in it. Power scales with the square of the amplitude.

use std::f64::consts::{FRAC_1_SQRT_2, TAU};

use nalgebra::Complex;
use scanhil_protocol::plant_units::{
    AMPS_PER_INPUT_UNIT, RAD_PER_OUTPUT_UNIT, SensingPair, actuator_from_sensing,
};

use crate::loop_analysis::NominalLoop;
use crate::rig::{RigCrossTalk, RigMirror};
use crate::trajectory::{Tone, Trajectory, swept_sine_phase};

/// Below this frequency a tone is evaluated here instead (a controller with an integrator has
/// no finite response at 0 Hz; its effort there is `1 / G(0)`), Hz.
const DC_PROBE_HZ: f64 = 1e-4;
/// Log-spaced frequencies at which a swept sine's band is evaluated.
const SWEEP_POINTS: usize = 400;

/// What a trajectory needs at steady state.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PowerEstimate {
    /// Mean power of both coils together, W.
    pub mean_power_w: f64,
    /// rms current on the alpha sensing axis, A.
    pub alpha_rms_a: f64,
    /// rms current on the beta sensing axis, A.
    pub beta_rms_a: f64,
    /// An upper bound of the peak current on the alpha sensing axis (amplitudes summed), A.
    pub alpha_peak_bound_a: f64,
    /// An upper bound of the peak current on the beta sensing axis (amplitudes summed), A.
    pub beta_peak_bound_a: f64,
    /// An upper bound of the peak current of either coil (the tones' amplitudes summed), A.
    pub peak_coil_current_bound_a: f64,
    /// The number of tones summed (for a swept sine: at its worst frequency).
    pub tones: usize,
    /// A swept sine's worst frequency, Hz.
    pub worst_hz: Option<f64>,
}

/// The coil current (A, sensing-axis input) per rad of reference under `nominal`: the control
/// effort in the paper's units, scaled to A and rad.
pub fn loop_effort(nominal: &NominalLoop) -> impl Fn(f64) -> Complex<f64> + '_ {
    move |f_hz| {
        nominal.control_effort(f_hz.max(DC_PROBE_HZ)) * (AMPS_PER_INPUT_UNIT / RAD_PER_OUTPUT_UNIT)
    }
}

/// The mean power of `tones` through `effort` (A per rad of reference at a frequency) into
/// `mirror`'s coils.
#[must_use]
pub fn estimate_tones(
    tones: &[Tone],
    mirror: &RigMirror,
    effort: &dyn Fn(f64) -> Complex<f64>,
) -> PowerEstimate {
    let (mut alpha_sq, mut beta_sq, mut peak_a, mut peak_b) = (0.0, 0.0, 0.0, 0.0);
    let (mut peak_alpha, mut peak_beta) = (0.0, 0.0);
    for tone in tones {
        let (u_alpha, u_beta) = sensing_currents(tone, &mirror.cross_talk, effort);
        let weight = if tone.f_hz > 0.0 { 0.5 } else { 1.0 };
        alpha_sq += weight * u_alpha.norm_sqr();
        beta_sq += weight * u_beta.norm_sqr();
        peak_alpha += u_alpha.norm();
        peak_beta += u_beta.norm();
        peak_a += ((u_alpha - u_beta) * FRAC_1_SQRT_2).norm();
        peak_b += ((u_alpha + u_beta) * FRAC_1_SQRT_2).norm();
    }
    PowerEstimate {
        mean_power_w: mirror.coil_resistance_ohm * (alpha_sq + beta_sq),
        alpha_rms_a: alpha_sq.sqrt(),
        beta_rms_a: beta_sq.sqrt(),
        alpha_peak_bound_a: peak_alpha,
        beta_peak_bound_a: peak_beta,
        peak_coil_current_bound_a: f64::max(peak_a, peak_b),
        tones: tones.len(),
        worst_hz: None,
    }
}

/// The currents (A phasors) on the sensing axes' inputs that make `tone` through `effort`,
/// with the mirror's `cross_talk` undone by the loop (`u = M^-1 v`).
fn sensing_currents(
    tone: &Tone,
    cross_talk: &RigCrossTalk,
    effort: &dyn Fn(f64) -> Complex<f64>,
) -> (Complex<f64>, Complex<f64>) {
    let c = cross_talk;
    let det = 1.0 - c.alpha_from_beta * c.beta_from_alpha;
    let e = effort(tone.f_hz);
    let (v_alpha, v_beta) = (e * tone.alpha_rad, e * tone.beta_rad);
    (
        (v_alpha - v_beta * c.alpha_from_beta) / det,
        (v_beta - v_alpha * c.beta_from_alpha) / det,
    )
}

/// The command limits the planned drive is held against ([`saturated_share`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveLimits {
    /// The controller's command limit per sensing axis, A.
    pub axis_a: f64,
    /// The coil current limit (each actuator coil), A.
    pub coil_a: f64,
}

/// Instants sampled over a frame by [`saturated_share`] at most.
const SATURATION_SAMPLES: usize = 100_000;

/// The share of a frame of `duration_s` in which the steady-state drive of `trajectory`
/// (through `effort`, with `cross_talk` undone) is beyond `limits`: an axis command at or
/// over its limit, or a coil current over the coil limit, as the controller counts a saturated
/// period. Sampled at the control period (`period_s`), or at 100 000 evenly
/// spread instants over a longer frame; a swept sine at its instantaneous frequency. Linear
/// like [`estimate`]: the start-up transient is not in it.
#[must_use]
pub fn saturated_share(
    trajectory: &Trajectory,
    cross_talk: &RigCrossTalk,
    effort: &dyn Fn(f64) -> Complex<f64>,
    limits: DriveLimits,
    period_s: f64,
    duration_s: f64,
) -> f64 {
    let nyquist_hz = 0.5 / period_s;
    let samples = ((duration_s / period_s).round() as usize).clamp(1, SATURATION_SAMPLES);
    let step_s = duration_s / samples as f64;
    // Each tone with its currents, when they do not change over the frame.
    let fixed: Vec<(f64, Complex<f64>, Complex<f64>)> = match trajectory {
        Trajectory::SweptSine { .. } => Vec::new(),
        _ => trajectory
            .tones(nyquist_hz)
            .iter()
            .map(|tone| {
                let (alpha, beta) = sensing_currents(tone, cross_talk, effort);
                (tone.f_hz, alpha, beta)
            })
            .collect(),
    };
    let currents_at = |t_s: f64| -> (f64, f64) {
        let rotate = |phase: f64, (alpha, beta): (Complex<f64>, Complex<f64>)| {
            let turn = Complex::from_polar(1.0, phase);
            ((alpha * turn).re, (beta * turn).re)
        };
        match *trajectory {
            Trajectory::SweptSine {
                axis,
                start_hz,
                stop_hz,
                duration_s: sweep_s,
                amplitude_rad,
            } => {
                if t_s > sweep_s {
                    return (0.0, 0.0);
                }
                let ratio = (stop_hz / start_hz).powf(t_s / sweep_s);
                let tone = Tone::sine(axis, start_hz * ratio, amplitude_rad, 0.0);
                let phase = swept_sine_phase(start_hz, stop_hz, sweep_s, t_s);
                rotate(phase, sensing_currents(&tone, cross_talk, effort))
            }
            _ => fixed
                .iter()
                .map(|&(f_hz, alpha, beta)| rotate(TAU * f_hz * t_s, (alpha, beta)))
                .fold((0.0, 0.0), |(a, b), (da, db)| (a + da, b + db)),
        }
    };
    let saturated = (0..samples)
        .filter(|&k| {
            let (alpha, beta) = currents_at((k as f64 + 1.0) * step_s);
            let coils = actuator_from_sensing(SensingPair { alpha, beta });
            alpha.abs() >= limits.axis_a
                || beta.abs() >= limits.axis_a
                || coils.a.abs() > limits.coil_a
                || coils.b.abs() > limits.coil_a
        })
        .count();
    saturated as f64 / samples as f64
}

/// The steady-state mean coil power of `trajectory` into `mirror`'s coils, with `effort` the
/// coil current per rad of reference ([`loop_effort`]) and tones up to `nyquist_hz`.
#[must_use]
pub fn estimate(
    trajectory: &Trajectory,
    mirror: &RigMirror,
    effort: &dyn Fn(f64) -> Complex<f64>,
    nyquist_hz: f64,
) -> PowerEstimate {
    if let Trajectory::SweptSine {
        axis,
        start_hz,
        stop_hz,
        amplitude_rad,
        ..
    } = *trajectory
    {
        let (lo, hi) = (start_hz.min(stop_hz).ln(), start_hz.max(stop_hz).ln());
        return (0..SWEEP_POINTS)
            .map(|i| (lo + (hi - lo) * i as f64 / (SWEEP_POINTS - 1) as f64).exp())
            .map(|f_hz| {
                let tone = Tone::sine(axis, f_hz, amplitude_rad, 0.0);
                PowerEstimate {
                    worst_hz: Some(f_hz),
                    ..estimate_tones(&[tone], mirror, effort)
                }
            })
            .max_by(|a, b| a.mean_power_w.total_cmp(&b.mean_power_w))
            .expect("the sweep grid is not empty");
    }
    estimate_tones(&trajectory.tones(nyquist_hz), mirror, effort)
}

/// The amplitude factor that brings `estimate_w` to `budget_w` (power goes with its square);
/// 1 when it is within.
#[must_use]
pub fn shrink_factor(estimate_w: f64, budget_w: f64) -> f64 {
    if estimate_w <= budget_w {
        1.0
    } else {
        (budget_w / estimate_w).sqrt()
    }
}

/// The ideal tracking effort `1 / G(j 2 pi f)` of eq. 4 (T = 1), A per rad, for checks and
/// studies without a controller.
pub fn ideal_effort(plant: &crate::plant_model::PlantModel) -> impl Fn(f64) -> Complex<f64> + '_ {
    move |f_hz| {
        let g = plant.section().eval(Complex::new(0.0, TAU * f_hz));
        AMPS_PER_INPUT_UNIT / RAD_PER_OUTPUT_UNIT / g
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant_model::PlantModel;
    use crate::rig::RigCrossTalk;
    use scanhil_protocol::plant_units::{FULL_RANGE_DEG, SensingAxis};

    const R_OHM: f64 = 2.0;

    fn mirror(c: f64) -> RigMirror {
        RigMirror {
            coil_resistance_ohm: R_OHM,
            power_limit_w: 30.0,
            amplifier_current_limit_a: None,
            cross_talk: RigCrossTalk {
                alpha_from_beta: c,
                beta_from_alpha: c,
            },
        }
    }

    fn full_rad() -> f64 {
        FULL_RANGE_DEG.to_radians()
    }

    #[test]
    fn one_sine_is_r_i_squared_over_two() {
        let plant = PlantModel::default();
        let effort = ideal_effort(&plant);
        let sine = Trajectory::Sine {
            axis: SensingAxis::Beta,
            frequency_hz: 52.0,
            amplitude_rad: full_rad(),
        };
        let estimate = estimate(&sine, &mirror(0.0), &effort, 10_000.0);
        // 10 output units over |G(j 2 pi 52)| = 3.856 A.
        let g = plant.section().eval(Complex::new(0.0, TAU * 52.0)).norm();
        let i_a = 10.0 / g;
        assert!((i_a - 3.856).abs() < 1e-3);
        assert!((estimate.mean_power_w - R_OHM * i_a * i_a / 2.0).abs() < 1e-9);
        assert!((estimate.beta_rms_a - i_a / 2f64.sqrt()).abs() < 1e-12);
        assert_eq!(estimate.alpha_rms_a, 0.0);
        assert!((estimate.beta_peak_bound_a - i_a).abs() < 1e-12);
        // On one sensing axis each coil carries I / sqrt 2.
        assert!((estimate.peak_coil_current_bound_a - i_a / 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn a_triangle_through_a_flat_effort_is_a_third_of_its_square() {
        // Parseval: a triangle of amplitude A has mean square A^2 / 3.
        let effort = |_f: f64| Complex::new(1.0, 0.0);
        let raster = Trajectory::Raster {
            slow_hz: 2.0,
            fast_hz: 34.0,
            slow_axis: SensingAxis::Beta,
            alpha_amplitude_rad: 3.0,
            beta_amplitude_rad: 0.0,
            fast_max_harmonic: None,
        };
        let estimate = estimate(&raster, &mirror(0.0), &effort, 10_000.0);
        let truncated = R_OHM * 9.0 / 3.0;
        assert!(
            (estimate.mean_power_w / truncated - 1.0).abs() < 1e-4,
            "{}",
            estimate.mean_power_w
        );
        // The slow triangle's 2500 odd harmonics below 10 kHz; the fast one's (34, 102, ...)
        // fall on every 17th of them and are merged.
        assert_eq!(estimate.tones, 2500);
    }

    #[test]
    fn cross_talk_costs_its_closed_form() {
        // Two tones at distinct frequencies: u = M^-1 v gives (1 + c^2) / (1 - c^2)^2.
        let effort = |_f: f64| Complex::new(1.0, 0.0);
        let lissajous = Trajectory::Lissajous {
            alpha_hz: 52.0,
            beta_hz: 27.0,
            alpha_amplitude_rad: 1.0,
            beta_amplitude_rad: 1.0,
            relative_phase_rad: 0.3,
        };
        let none = estimate(&lissajous, &mirror(0.0), &effort, 10_000.0).mean_power_w;
        assert!((none - R_OHM).abs() < 1e-12);
        let c: f64 = 0.1;
        let with = estimate(&lissajous, &mirror(c), &effort, 10_000.0).mean_power_w;
        let factor = (1.0 + c * c) / (1.0 - c * c).powi(2);
        assert!((with / none - factor).abs() < 1e-12, "{with}");
    }

    #[test]
    fn equal_frequencies_add_coherently_and_steps_count_in_full() {
        let effort = |_f: f64| Complex::new(1.0, 0.0);
        let in_phase = Trajectory::Lissajous {
            alpha_hz: 60.0,
            beta_hz: 60.0,
            alpha_amplitude_rad: 1.0,
            beta_amplitude_rad: 1.0,
            relative_phase_rad: 0.0,
        };
        let estimate_in_phase = estimate(&in_phase, &mirror(0.5), &effort, 10_000.0);
        assert_eq!(estimate_in_phase.tones, 1);
        // u = v / (1 + c) on both axes: 2 * R / 2 / 1.5^2.
        assert!((estimate_in_phase.mean_power_w - R_OHM / 2.25).abs() < 1e-12);
        let step = Trajectory::Step {
            axis: SensingAxis::Alpha,
            amplitude_rad: 2.0,
            at_s: 0.0,
        };
        assert!(
            (estimate(&step, &mirror(0.0), &effort, 1e4).mean_power_w - 4.0 * R_OHM).abs() < 1e-12
        );
    }

    #[test]
    fn a_sweep_is_charged_its_worst_frequency_and_shrink_is_a_square_root() {
        let plant = PlantModel::default();
        let effort = ideal_effort(&plant);
        let sweep = Trajectory::SweptSine {
            axis: SensingAxis::Alpha,
            start_hz: 10.0,
            stop_hz: 100.0,
            duration_s: 1.0,
            amplitude_rad: 0.01,
        };
        let worst = estimate(&sweep, &mirror(0.0), &effort, 1e4);
        // Above the resonance the effort grows with f^2: the worst is the top of the band.
        assert!((worst.worst_hz.unwrap() - 100.0).abs() < 1e-6);
        assert_eq!(shrink_factor(10.0, 20.0), 1.0);
        assert!((shrink_factor(40.0, 10.0) - 0.5).abs() < 1e-15);
    }
}
