//! The precision study: for each integrator and a range of sub-step counts, the error of the
//! simulated mirror response against the exact solution, and the run time per simulated
//! second (a work-precision diagram).
//!
//! The drive is the paper's Lissajous drive in open loop: on each sensing axis the coil
//! current amplitude that gives full range (10 output units) at that frequency, 52 Hz on
//! alpha and 27 Hz on beta, rotated onto the coils and held per control period. The exact
//! solution is the exact ZOH map over one whole period (the input is piecewise constant, so
//! the matrix exponential is exact to rounding); it is the reference the other rows are
//! measured against. Errors are the largest and rms deviation of the mechanical angles at the
//! period ends, over both axes.
//!
//! Run time is wall-clock time spent stepping (the best of several repetitions), so it depends
//! on the machine; errors do not.

use std::time::Instant;

use serde::Serialize;

use scanhil_protocol::plant_units::{SensingPair, actuator_from_sensing};

use crate::drive_model::DriveModel;
use crate::drive_stepper::DriveStepper;
use crate::integrator::{IntegratorConfig, Method};
use crate::mirror::{MirrorConfig, SensingAxis};
use crate::power::full_range_current_a;

/// The drive frequency on alpha, in Hz.
pub const ALPHA_DRIVE_HZ: f64 = 52.0;
/// The drive frequency on beta, in Hz.
pub const BETA_DRIVE_HZ: f64 = 27.0;
/// The least wall-clock time spent timing one row, in s.
const MIN_TIMING_S: f64 = 0.05;

/// What the study runs.
#[derive(Debug, Clone)]
pub struct StudySetup {
    /// The dynamics under study.
    pub model: DriveModel,
    /// Its mirror parameters (for the drive amplitudes).
    pub mirror: MirrorConfig,
    /// The control period, in s.
    pub period_s: f64,
    /// The simulated duration, in s.
    pub duration_s: f64,
    /// The sub-step counts tried for every method.
    pub substeps: Vec<u32>,
}

/// One row of the study.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudyRow {
    /// The integrator.
    pub method: Method,
    /// Sub-steps per control period.
    pub substeps: u32,
    /// The sub-step length, in s.
    pub step_s: f64,
    /// Largest angle error against the exact solution, in urad (`None` when refused).
    pub max_error_urad: Option<f64>,
    /// Rms angle error against the exact solution, in urad (`None` when refused).
    pub rms_error_urad: Option<f64>,
    /// Wall-clock stepping time per simulated second, in s/s (`None` when refused).
    pub run_time_per_sim_s: Option<f64>,
    /// Why the combination was refused (the stability check's message), if it was.
    pub refused: Option<String>,
}

/// The coil current commands of the study's drive, one per control period.
#[must_use]
pub fn lissajous_drive_a(mirror: &MirrorConfig, period_s: f64, periods: usize) -> Vec<[f64; 2]> {
    let amp_alpha = full_range_current_a(&mirror.axis(SensingAxis::Alpha), ALPHA_DRIVE_HZ);
    let amp_beta = full_range_current_a(&mirror.axis(SensingAxis::Beta), BETA_DRIVE_HZ);
    (0..periods)
        .map(|k| {
            let t = k as f64 * period_s;
            let coils = actuator_from_sensing(SensingPair {
                alpha: amp_alpha * (std::f64::consts::TAU * ALPHA_DRIVE_HZ * t).sin(),
                beta: amp_beta * (std::f64::consts::TAU * BETA_DRIVE_HZ * t).sin(),
            });
            [coils.a, coils.b]
        })
        .collect()
}

/// Steps `stepper` through `drive` from rest; the angles (rad) at every period end.
pub fn simulate(
    model: &DriveModel,
    stepper: &mut DriveStepper,
    drive: &[[f64; 2]],
) -> Vec<[f64; 2]> {
    let mut x = model.initial_state([0.0, 0.0]);
    drive
        .iter()
        .map(|&u| {
            stepper.step(&mut x, u);
            SensingAxis::BOTH.map(|axis| model.angle_rad(&x, axis).unwrap_or(0.0))
        })
        .collect()
}

/// Runs the study; rows in the order of [`Method::ALL`], then sub-steps.
#[must_use]
pub fn run_study(setup: &StudySetup) -> Vec<StudyRow> {
    let periods = (setup.duration_s / setup.period_s).round().max(1.0) as usize;
    let drive = lissajous_drive_a(&setup.mirror, setup.period_s, periods);
    let mut reference_stepper =
        DriveStepper::new(&setup.model, setup.period_s, IntegratorConfig::default())
            .expect("the exact ZOH map of a stable model is stable");
    let reference = simulate(&setup.model, &mut reference_stepper, &drive);
    let simulated_s = periods as f64 * setup.period_s;
    let mut rows = Vec::new();
    for method in Method::ALL {
        for &substeps in &setup.substeps {
            let config = IntegratorConfig { method, substeps };
            let step_s = setup.period_s / f64::from(substeps.max(1));
            let row = match DriveStepper::new(&setup.model, setup.period_s, config) {
                Err(refusal) => StudyRow {
                    method,
                    substeps,
                    step_s,
                    max_error_urad: None,
                    rms_error_urad: None,
                    run_time_per_sim_s: None,
                    refused: Some(refusal.to_string()),
                },
                Ok(mut stepper) => {
                    let angles = simulate(&setup.model, &mut stepper, &drive);
                    let (max_rad, rms_rad) = errors(&angles, &reference);
                    let run_s = best_time_s(|| {
                        std::hint::black_box(simulate(&setup.model, &mut stepper, &drive));
                    });
                    StudyRow {
                        method,
                        substeps,
                        step_s,
                        max_error_urad: Some(max_rad * 1e6),
                        rms_error_urad: Some(rms_rad * 1e6),
                        run_time_per_sim_s: Some(run_s / simulated_s),
                        refused: None,
                    }
                }
            };
            rows.push(row);
        }
    }
    rows
}

/// Largest and rms difference over all samples and both axes.
fn errors(angles: &[[f64; 2]], reference: &[[f64; 2]]) -> (f64, f64) {
    let mut max: f64 = 0.0;
    let mut sum2 = 0.0;
    for (a, r) in angles.iter().zip(reference) {
        for axis in 0..2 {
            let d = (a[axis] - r[axis]).abs();
            max = max.max(d);
            sum2 += d * d;
        }
    }
    (max, (sum2 / (2 * angles.len().max(1)) as f64).sqrt())
}

/// The best wall-clock time of `run` over repetitions totalling at least `MIN_TIMING_S`.
fn best_time_s(mut run: impl FnMut()) -> f64 {
    let mut best = f64::INFINITY;
    let mut total = 0.0;
    let mut repetitions = 0;
    while total < MIN_TIMING_S || repetitions < 3 {
        let start = Instant::now();
        run();
        let t = start.elapsed().as_secs_f64();
        best = best.min(t);
        total += t;
        repetitions += 1;
    }
    best
}
