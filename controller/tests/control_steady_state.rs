//! The steady-state prediction (`steady_state::predict`) against a time-domain run of the same
//! controller on the nominal plant (`NominalPlantLink`, no noise): after the transient, the
//! measured relative rms tracking error equals the predicted one. The prediction comes from
//! the loop's frequency response, the measurement from stepping the difference equations: two
//! independent computations of one figure.

use std::path::Path;

use scanhil_controller::link::{NominalPlantLink, PlantLink};
use scanhil_controller::settings::ControllerSettings;
use scanhil_controller::steady_state::{PredictedTracking, predict};
use scanhil_controller::trajectory::{SensingAxis, Trajectory};
use scanhil_protocol::plant_units::SensingPair;

fn settings(name: &str) -> ControllerSettings {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/controllers")
        .join(name);
    ControllerSettings::load(&path).expect("the controller file loads")
}

/// Runs `trajectory` under the controller for `settle_s`, then measures the relative rms
/// error per axis over the next `window_s` (a whole number of the reference's periods).
fn measured(
    settings: &ControllerSettings,
    trajectory: &Trajectory,
    settle_s: f64,
    window_s: f64,
) -> PredictedTracking {
    let mut controller = settings.build().expect("a stable controller");
    let period_s = controller.period_s();
    let mut plant = NominalPlantLink::new(&settings.plant, period_s, 0.0, 0);
    let settle = (settle_s / period_s).round() as u64;
    let window = (window_s / period_s).round() as u64;
    let mut measured = SensingPair::default();
    let (mut sum_a, mut sum_b) = (0.0, 0.0);
    for k in 0..settle + window {
        let reference = trajectory.reference_rad(k as f64 * period_s);
        let command = controller.step(reference, measured);
        measured = plant.exchange(command).expect("a finite command");
        if k >= settle {
            let at = trajectory.reference_rad((k + 1) as f64 * period_s);
            sum_a += (measured.alpha - at.alpha).powi(2);
            sum_b += (measured.beta - at.beta).powi(2);
        }
    }
    let rms = |sum: f64, axis| {
        let peak = trajectory.peak_rad(axis);
        (peak > 0.0).then(|| (sum / window as f64).sqrt() / peak)
    };
    PredictedTracking {
        alpha_rms_relative: rms(sum_a, SensingAxis::Alpha),
        beta_rms_relative: rms(sum_b, SensingAxis::Beta),
    }
}

fn assert_close(measured: Option<f64>, predicted: Option<f64>, relative: f64, what: &str) {
    let (m, p) = (measured.expect(what), predicted.expect(what));
    assert!(
        (m - p).abs() <= relative * p,
        "{what}: measured {m:.6e}, predicted {p:.6e} (tolerance {relative})"
    );
}

#[test]
fn a_lissajous_under_the_pid_tracks_as_predicted() {
    let settings = settings("pid-series.json");
    let trajectory = Trajectory::Lissajous {
        alpha_hz: 52.0,
        beta_hz: 27.0,
        alpha_amplitude_rad: 0.01,
        beta_amplitude_rad: 0.01,
        relative_phase_rad: 0.0,
    };
    let axis = settings.axis_controller().expect("the controller");
    let predicted = predict(&settings.nominal_loop(&axis), &trajectory);
    let measured = measured(&settings, &trajectory, 1.0, 1.0);
    // PID at 52 / 27 Hz: a few per cent of error, the loop's |S| there.
    assert!(predicted.alpha_rms_relative.unwrap() > 0.01);
    assert_close(
        measured.alpha_rms_relative,
        predicted.alpha_rms_relative,
        0.01,
        "alpha",
    );
    assert_close(
        measured.beta_rms_relative,
        predicted.beta_rms_relative,
        0.01,
        "beta",
    );
}

#[test]
fn a_raster_under_the_pid_tracks_as_its_harmonics_predict() {
    let settings = settings("pid-series.json");
    // Small amplitudes: the triangle's corners stay inside the current limit (linear loop).
    let trajectory = Trajectory::Raster {
        slow_hz: 2.0,
        fast_hz: 34.0,
        slow_axis: SensingAxis::Alpha,
        alpha_amplitude_rad: 0.002,
        beta_amplitude_rad: 0.002,
        fast_max_harmonic: None,
    };
    let axis = settings.axis_controller().expect("the controller");
    let predicted = predict(&settings.nominal_loop(&axis), &trajectory);
    let measured = measured(&settings, &trajectory, 1.0, 1.0);
    assert_close(
        measured.beta_rms_relative,
        predicted.beta_rms_relative,
        0.02,
        "fast beta",
    );
    assert_close(
        measured.alpha_rms_relative,
        predicted.alpha_rms_relative,
        0.02,
        "slow alpha",
    );
    // The fast triangle's harmonics reach past the loop's bandwidth: more error than its
    // fundamental alone would leave.
    let fundamental_only = Trajectory::Sine {
        axis: SensingAxis::Beta,
        frequency_hz: 34.0,
        amplitude_rad: 0.002 * 8.0 / (std::f64::consts::PI * std::f64::consts::PI),
    };
    let fundamental = predict(&settings.nominal_loop(&axis), &fundamental_only);
    assert!(predicted.beta_rms_relative.unwrap() > 1.5 * fundamental.beta_rms_relative.unwrap());
}

#[test]
fn the_dual_tone_with_tones_on_the_drive_leaves_almost_no_error_and_table_i_some() {
    let trajectory = Trajectory::Lissajous {
        alpha_hz: 52.0,
        beta_hz: 27.0,
        alpha_amplitude_rad: 0.01,
        beta_amplitude_rad: 0.01,
        relative_phase_rad: 0.0,
    };
    let exact = settings("dual-tone-exact-tones.json");
    let printed = settings("dual-tone.json");
    let at = |s: &ControllerSettings| {
        predict(&s.nominal_loop(&s.axis_controller().unwrap()), &trajectory)
    };
    let (exact_p, printed_p) = (at(&exact), at(&printed));
    eprintln!("exact tones {exact_p:?}, Table I {printed_p:?}");
    // Tones on the drive: under 1 % (the tones' finite peak gain leaves a little); Table I's
    // tones, 56 / 44 mHz off the drive, several times more.
    for (exact, printed) in [
        (exact_p.alpha_rms_relative, printed_p.alpha_rms_relative),
        (exact_p.beta_rms_relative, printed_p.beta_rms_relative),
    ] {
        let (exact, printed) = (exact.unwrap(), printed.unwrap());
        assert!(exact < 0.01, "exact tones: {exact}");
        assert!(
            printed > 3.0 * exact,
            "Table I {printed} against exact {exact}"
        );
    }
    let measured_exact = measured(&exact, &trajectory, 6.0, 1.0);
    assert_close(
        measured_exact.alpha_rms_relative,
        exact_p.alpha_rms_relative,
        0.02,
        "alpha",
    );
    assert_close(
        measured_exact.beta_rms_relative,
        exact_p.beta_rms_relative,
        0.02,
        "beta",
    );
    // Table I after its slow transient (slowest pole |z| = 0.999917: 0.6 s) is as predicted.
    let measured = measured(&printed, &trajectory, 6.0, 1.0);
    assert_close(
        measured.alpha_rms_relative,
        printed_p.alpha_rms_relative,
        0.02,
        "alpha",
    );
    assert_close(
        measured.beta_rms_relative,
        printed_p.beta_rms_relative,
        0.02,
        "beta",
    );
}

#[test]
fn the_dual_tone_designed_for_the_bus_rate_tracks_as_predicted() {
    // `scanhil design --rate-hz bus` on the 1 Mbit/s rig: 2736 Hz, the paper's full-range
    // Lissajous (the coils stay linear: 6 A limit). Its slowest pole settles in 1.5 s.
    let designed = settings("dual-tone-2736hz-designed.json");
    let trajectory = Trajectory::Lissajous {
        alpha_hz: 52.0,
        beta_hz: 27.0,
        alpha_amplitude_rad: 1.5f64.to_radians(),
        beta_amplitude_rad: 1.5f64.to_radians(),
        relative_phase_rad: 0.0,
    };
    let predicted = predict(
        &designed.nominal_loop(&designed.axis_controller().unwrap()),
        &trajectory,
    );
    let measured = measured(&designed, &trajectory, 3.0, 1.0);
    assert_close(
        measured.alpha_rms_relative,
        predicted.alpha_rms_relative,
        0.02,
        "alpha",
    );
    assert_close(
        measured.beta_rms_relative,
        predicted.beta_rms_relative,
        0.02,
        "beta",
    );
    assert!(
        predicted.alpha_rms_relative.unwrap() < 0.005,
        "{predicted:?}"
    );
}

#[test]
fn references_without_a_steady_state_have_no_prediction() {
    let settings = settings("pid-series.json");
    let axis = settings.axis_controller().expect("the controller");
    let step = Trajectory::Step {
        axis: SensingAxis::Alpha,
        amplitude_rad: 0.01,
        at_s: 0.0,
    };
    let predicted = predict(&settings.nominal_loop(&axis), &step);
    assert_eq!(predicted.alpha_rms_relative, None);
    assert_eq!(predicted.beta_rms_relative, None);
}
