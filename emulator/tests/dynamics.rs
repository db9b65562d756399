//! The mirror dynamics, timing convention, integrators and their stability check, on normal,
//! stiff and extreme cases.

use std::path::Path;

use scanhil_emulator::drive_model::DriveModel;
use scanhil_emulator::integrator::{IntegratorConfig, Method, Stepper};
use scanhil_emulator::mirror::{AxisDynamics, MirrorConfig, SensingAxis};
use scanhil_emulator::plant::{Plant, PlantError};
use scanhil_emulator::precision::{StudySetup, run_study};
use scanhil_emulator::scene::Scene;
use scanhil_protocol::plant_units::{
    ActuatorPair, RAD_PER_OUTPUT_UNIT, SensingPair, actuator_from_sensing,
};

fn scene(json: &str) -> Scene {
    Scene::from_json_str(json, Path::new("test-scene.json")).expect("test scene is valid")
}

/// The analytic unit-step response of `K ws^2 / (s^2 + 2 zeta ws s + ws^2)`, 0 <= zeta < 1.
fn analytic_step(m: &AxisDynamics, t_s: f64) -> f64 {
    let (ws, z) = (m.natural_freq_rad_s, m.damping_ratio);
    let wd = ws * (1.0 - z * z).sqrt();
    let decay = (-z * ws * t_s).exp();
    m.dc_gain * (1.0 - decay * ((wd * t_s).cos() + z / (1.0 - z * z).sqrt() * (wd * t_s).sin()))
}

/// Runs a single-axis (alpha) step of `amps` on the sensing axis; angles (output units)
/// returned by each step.
fn alpha_step_response(plant: &mut Plant, amps: f64, periods: usize) -> Vec<f64> {
    let command = actuator_from_sensing(SensingPair {
        alpha: amps,
        beta: 0.0,
    });
    (0..periods)
        .map(|_| plant.step(command).unwrap().true_angles_rad.alpha / RAD_PER_OUTPUT_UNIT)
        .collect()
}

fn single_axis_scene(rate_hz: f64, extra_mirror: &str) -> Scene {
    scene(&format!(
        r#"{{"name": "t", "control_rate_hz": {rate_hz}, "parts": ["axes"],
            "mirror": {{"axes": ["alpha"] {extra_mirror}}}}}"#
    ))
}

#[test]
fn step_response_is_the_delayed_analytic_response_at_20_khz_500_khz_2_mhz_and_1_khz() {
    for rate_hz in [20_000.0, 500_000.0, 2_000_000.0, 1_000.0] {
        let s = single_axis_scene(rate_hz, "");
        let mut plant = Plant::from_scene(&s).unwrap();
        let ta = plant.period_s();
        let periods = (0.3 / ta) as usize; // 0.3 s: the lightly damped mirror is still ringing
        let y = alpha_step_response(&mut plant, 0.1, periods);
        // Step k returns the angle at (k+1) Ta; the command acts from Ta on.
        assert_eq!(
            y[0], 0.0,
            "the first period must not see the command ({rate_hz} Hz)"
        );
        let mut worst: f64 = 0.0;
        for (k, yk) in y.iter().enumerate() {
            let exact = 0.1 * analytic_step(&s.mirror.axis(SensingAxis::Alpha), k as f64 * ta);
            worst = worst.max((yk - exact).abs());
        }
        assert!(
            worst < 1e-9,
            "rate {rate_hz} Hz: worst deviation {worst:e} output units"
        );
    }
}

#[test]
fn a_2000_sample_step_is_nowhere_near_settled() {
    let mut plant = Plant::from_scene(&single_axis_scene(20_000.0, "")).unwrap();
    let y = alpha_step_response(&mut plant, 0.1, 2000);
    let peak = y.iter().cloned().fold(f64::MIN, f64::max);
    // Lightly damped: overshoot near exp(-pi zeta / sqrt(1 - zeta^2)) = 90 %.
    assert!(peak > 1.8 * 1.14, "peak {peak}");
    assert!(
        (y[1999] - 1.14).abs() > 0.05,
        "settled already? {}",
        y[1999]
    );
}

#[test]
fn undamped_mirror_runs_exact_but_euler_is_refused_naming_method_step_and_eigenvalue() {
    let exact = single_axis_scene(20_000.0, r#", "damping_ratio": 0.0"#);
    assert!(Plant::from_scene(&exact).is_ok());
    let mut euler = exact.clone();
    euler.integrator = IntegratorConfig {
        method: Method::ExplicitEuler,
        substeps: 1,
    };
    let err = Plant::from_scene(&euler).unwrap_err();
    let PlantError::Unstable { cause: source, .. } = &err else {
        panic!("{err}")
    };
    assert_eq!(source.method, Method::ExplicitEuler);
    assert!((source.step_s - 50e-6).abs() < 1e-18);
    // Euler on an undamped oscillator: |1 + j ws h| = sqrt(1 + (ws h)^2).
    let expected = (1.0 + (140.68f64 * 50e-6).powi(2)).sqrt();
    assert!(
        (source.radius - expected).abs() < 1e-12,
        "{}",
        source.radius
    );
    assert!((source.eigenvalue.1.abs() - 140.68 * 50e-6).abs() < 1e-9);
    // Forward Euler is never stable on a pure oscillator; its growth per period only drops
    // below rounding at absurd sub-step counts.
    assert!(
        source.stable_substeps.is_none_or(|n| n >= 1 << 18),
        "{:?}",
        source.stable_substeps
    );
    let text = err.to_string();
    assert!(
        text.contains("explicit_euler") && text.contains("5e-5") && text.contains("eigenvalue"),
        "{text}"
    );
}

#[test]
fn stiff_amplifier_refuses_rk4_at_one_substep_and_suggests_two() {
    let s =
        scene(r#"{"name": "t", "parts": ["axes", "amplifier"], "integrator": {"method": "rk4"}}"#);
    let err = Plant::from_scene(&s).unwrap_err();
    let PlantError::Unstable { cause: source, .. } = err else {
        panic!()
    };
    // R(z) of RK4 at z = -2 pi 10 kHz * 50 us = -3.1416.
    let z = -std::f64::consts::TAU * 1e4 * 50e-6;
    let r = 1.0 + z + z * z / 2.0 + z.powi(3) / 6.0 + z.powi(4) / 24.0;
    assert!(
        (source.radius - r.abs()).abs() < 1e-9,
        "{} vs {}",
        source.radius,
        r
    );
    assert_eq!(source.stable_substeps, Some(2));
    let mut two = s.clone();
    two.integrator.substeps = 2;
    assert!(Plant::from_scene(&two).is_ok());
}

#[test]
fn natural_frequency_far_above_the_sampling_rate_is_exact_with_zoh_and_trapezoid_only() {
    // ws = 1e6 rad/s: ws * Ta = 50, 160 times above Nyquist.
    let s = single_axis_scene(
        20_000.0,
        r#", "natural_freq_rad_s": 1.0e6, "damping_ratio": 0.05"#,
    );
    let mut plant = Plant::from_scene(&s).unwrap();
    let y = alpha_step_response(&mut plant, 1.0, 200);
    for (k, yk) in y.iter().enumerate().skip(1) {
        let exact = analytic_step(&s.mirror.axis(SensingAxis::Alpha), k as f64 * 50e-6);
        assert!((yk - exact).abs() < 1e-6, "k {k}: {yk} vs {exact}");
    }
    assert!((y[199] - 11.4).abs() < 1e-6);
    for method in [Method::Rk4, Method::ExplicitEuler] {
        let mut bad = s.clone();
        bad.integrator.method = method;
        assert!(Plant::from_scene(&bad).is_err(), "{method} must be refused");
    }
    let mut trap = s.clone();
    trap.integrator.method = Method::Trapezoid;
    assert!(Plant::from_scene(&trap).is_ok());
}

#[test]
fn non_finite_commands_are_rejected_and_change_nothing() {
    let mut plant = Plant::from_scene(&single_axis_scene(20_000.0, "")).unwrap();
    plant.step(ActuatorPair { a: 0.2, b: 0.2 }).unwrap();
    let before = plant.true_angles_rad();
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let err = plant.step(ActuatorPair { a: 0.0, b: bad }).unwrap_err();
        assert!(
            matches!(
                err,
                PlantError::NonFiniteCommand {
                    period_index: 1,
                    ..
                }
            ),
            "{err}"
        );
    }
    assert_eq!(plant.period_index(), 1);
    assert_eq!(plant.true_angles_rad(), before);
    // The command latched before the refusals is the one that acts next.
    let next = plant.step(ActuatorPair::default()).unwrap();
    assert_eq!(next.applied_currents_a, ActuatorPair { a: 0.2, b: 0.2 });
}

#[test]
fn saturated_and_reversing_currents_are_limited_reported_and_stay_bounded() {
    let s = scene(
        r#"{"name": "t", "parts": ["axes", "cross_talk", "amplifier"],
                      "amplifier": {"current_limit_a": 2.0}}"#,
    );
    let mut plant = Plant::from_scene(&s).unwrap();
    let mut limited = 0;
    let mut max_angle: f64 = 0.0;
    for k in 0..4000 {
        // Reverse a 50 A command every period: the limit clamps it to +-2 A.
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        let out = plant
            .step(ActuatorPair {
                a: 50.0 * sign,
                b: -50.0 * sign,
            })
            .unwrap();
        limited += out.events.len();
        if k > 0 {
            assert_eq!(out.applied_currents_a.a.abs(), 2.0);
        }
        max_angle = max_angle
            .max(out.true_angles_rad.alpha.abs())
            .max(out.true_angles_rad.beta.abs());
    }
    assert_eq!(limited, 3999);
    // Alternating at Nyquist barely moves a 22 Hz mirror: what rings is the start-up impulse
    // (half a period of 2 A), about 0.1 output units = 3e-4 rad, 1 % of full range.
    assert!(max_angle.is_finite() && max_angle < 5e-4, "{max_angle}");
}

#[test]
fn exact_integrator_keeps_energy_and_phase_over_ten_million_steps() {
    let mirror = MirrorConfig {
        damping_ratio: 0.0,
        axes: vec![SensingAxis::Alpha],
        ..MirrorConfig::default()
    };
    let model = DriveModel::new(Some(&mirror), None, None);
    let ta = 50e-6;
    let mut stepper = Stepper::new(&model, ta, IntegratorConfig::default()).unwrap();
    let mut x = vec![1.0, 0.0];
    let steps = 10_000_000u64;
    for _ in 0..steps {
        stepper.step(&mut x, [0.0, 0.0]);
    }
    let ws = mirror.natural_freq_rad_s;
    let energy = x[0] * x[0] + (x[1] / ws).powi(2);
    assert!(
        (energy - 1.0).abs() < 1e-8,
        "energy drift {:e}",
        energy - 1.0
    );
    let phase = (-x[1] / ws).atan2(x[0]);
    let expected = (ws * ta * steps as f64).rem_euclid(std::f64::consts::TAU);
    let mut dphi = (phase - expected).rem_euclid(std::f64::consts::TAU);
    if dphi > std::f64::consts::PI {
        dphi -= std::f64::consts::TAU;
    }
    assert!(
        dphi.abs() < 1e-6,
        "phase drift {dphi:e} rad after {steps} steps"
    );
}

#[test]
fn integrators_converge_at_their_order() {
    let mirror = MirrorConfig::default();
    let setup = StudySetup {
        model: DriveModel::new(Some(&mirror), None, None),
        mirror,
        period_s: 50e-6,
        duration_s: 0.02,
        substeps: vec![2, 4],
    };
    let rows = run_study(&setup);
    let error = |method: Method, substeps: u32| {
        rows.iter()
            .find(|r| r.method == method && r.substeps == substeps)
            .and_then(|r| r.max_error_urad)
            .unwrap()
    };
    for (method, order) in [
        (Method::ExplicitEuler, 1),
        (Method::Trapezoid, 2),
        (Method::Rk4, 4),
    ] {
        let ratio = error(method, 2) / error(method, 4);
        let expected = f64::from(1 << order);
        assert!(
            (ratio / expected - 1.0).abs() < 0.2,
            "{method}: error ratio {ratio}, expected {expected}"
        );
    }
    assert!(error(Method::ExactZoh, 4) < 1e-6);
}
