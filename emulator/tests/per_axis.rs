//! Per-axis mirror parameters: each axis follows its own eq. 4 (gain, frequency, damping,
//! delay), the common set is read unchanged, and a bad value is named with its axis.

use std::path::Path;

use scanhil_emulator::mirror::{AxisDynamics, SensingAxis};
use scanhil_emulator::plant::Plant;
use scanhil_emulator::scene::{Scene, SceneError};
use scanhil_protocol::plant_units::{
    ActuatorPair, RAD_PER_OUTPUT_UNIT, SensingPair, actuator_from_sensing,
};

const TA: f64 = 50e-6;

fn scene(json: &str) -> Scene {
    Scene::from_json_str(json, Path::new("per-axis.json")).expect("test scene is valid")
}

/// The analytic unit-step response of `K ws^2 / (s^2 + 2 zeta ws s + ws^2)` at `t_s` (0 before
/// the step), 0 <= zeta < 1.
fn analytic_step(m: &AxisDynamics, t_s: f64) -> f64 {
    if t_s < 0.0 {
        return 0.0;
    }
    let (ws, z) = (m.natural_freq_rad_s, m.damping_ratio);
    let wd = ws * (1.0 - z * z).sqrt();
    let decay = (-z * ws * t_s).exp();
    m.dc_gain * (1.0 - decay * ((wd * t_s).cos() + z / (1.0 - z * z).sqrt() * (wd * t_s).sin()))
}

/// Steps of `amps` on the sensing axes, from rest, for `periods`.
fn step_response(
    plant: &mut Plant,
    amps: SensingPair,
    periods: usize,
) -> Vec<(SensingPair, SensingPair)> {
    let command = actuator_from_sensing(amps);
    (0..periods)
        .map(|_| {
            let out = plant.step(command).unwrap();
            (out.true_angles_rad, out.measured_angles_rad)
        })
        .collect()
}

const TWO_MIRRORS: &str = r#"{"name": "two", "parts": ["axes"],
    "mirror": {"alpha": {"dc_gain": 9.5, "natural_freq_rad_s": 180.0},
               "beta": {"natural_freq_rad_s": 120.0, "damping_ratio": 0.08}}}"#;

#[test]
fn each_axis_follows_its_own_eq_4() {
    let s = scene(TWO_MIRRORS);
    let alpha = s.mirror.axis(SensingAxis::Alpha);
    let beta = s.mirror.axis(SensingAxis::Beta);
    assert_eq!(
        (alpha.dc_gain, alpha.natural_freq_rad_s, alpha.damping_ratio),
        (9.5, 180.0, 3.21e-2)
    );
    assert_eq!(
        (beta.dc_gain, beta.natural_freq_rad_s, beta.damping_ratio),
        (11.4, 120.0, 0.08)
    );
    let mut plant = Plant::from_scene(&s).unwrap();
    let y = step_response(
        &mut plant,
        SensingPair {
            alpha: 0.1,
            beta: -0.2,
        },
        4000,
    );
    let mut worst: f64 = 0.0;
    for (k, (truth, measured)) in y.iter().enumerate() {
        let t = k as f64 * TA;
        assert_eq!(truth, measured);
        worst = worst
            .max((truth.alpha / RAD_PER_OUTPUT_UNIT - 0.1 * analytic_step(&alpha, t)).abs())
            .max((truth.beta / RAD_PER_OUTPUT_UNIT + 0.2 * analytic_step(&beta, t)).abs());
    }
    assert!(worst < 1e-9, "worst deviation {worst:e} output units");
}

#[test]
fn the_common_set_alone_is_read_as_before() {
    let common = scene(r#"{"name": "c", "parts": ["axes"], "mirror": {"dc_gain": 10.0}}"#);
    // `y` names alpha as in `axes`; naming an axis twice is refused.
    let by_alias = scene(r#"{"name": "c", "parts": ["axes"], "mirror": {"y": {"dc_gain": 7.0}}}"#);
    assert_eq!(by_alias.mirror.axis(SensingAxis::Alpha).dc_gain, 7.0);
    let twice = Scene::from_json_str(
        r#"{"name": "c", "parts": ["axes"], "mirror": {"alpha": {}, "y": {}}}"#,
        Path::new("twice.json"),
    )
    .unwrap_err();
    assert!(
        twice.to_string().contains("duplicate field `alpha`"),
        "{twice}"
    );
    for axis in SensingAxis::BOTH {
        let d = common.mirror.axis(axis);
        assert_eq!(
            (d.dc_gain, d.natural_freq_rad_s, d.damping_ratio, d.delay_s),
            (10.0, 140.68, 3.21e-2, None)
        );
    }
    // Serialised, a scene without axis values writes none (the file i21's fit reads back).
    let text = serde_json::to_string(&common.mirror).unwrap();
    assert!(
        !text.contains("alpha\":{") && !text.contains("delay_s"),
        "{text}"
    );
}

#[test]
fn a_per_axis_scene_round_trips_through_json() {
    let s = scene(TWO_MIRRORS);
    let text = serde_json::to_string_pretty(&s).unwrap();
    let back = Scene::from_json_str(&text, Path::new("again.json")).unwrap();
    assert_eq!(back.mirror, s.mirror);
}

#[test]
fn a_delay_beyond_one_period_delays_the_measured_angle_exactly() {
    // alpha: 1.5 periods (a fraction), beta: 3 periods (whole); the mechanics are unchanged.
    let delayed = scene(
        r#"{"name": "d", "parts": ["axes"], "mirror": {"delay_s": 7.5e-5, "beta": {"delay_s": 1.5e-4}}}"#,
    );
    let plain = scene(r#"{"name": "p", "parts": ["axes"]}"#);
    let amps = SensingPair {
        alpha: 0.3,
        beta: 0.2,
    };
    let y = step_response(&mut Plant::from_scene(&delayed).unwrap(), amps, 3000);
    let reference = step_response(&mut Plant::from_scene(&plain).unwrap(), amps, 3000);
    let axis = delayed.mirror.axis(SensingAxis::Alpha);
    let mut worst: f64 = 0.0;
    for (k, ((truth, measured), (truth_ref, _))) in y.iter().zip(&reference).enumerate() {
        assert_eq!(truth, truth_ref, "the delay must not move the mirror");
        // Step k reports t = (k+1) Ta; the command acts after delay_s.
        let t = (k + 1) as f64 * TA;
        worst = worst
            .max(
                (measured.alpha / RAD_PER_OUTPUT_UNIT - 0.3 * analytic_step(&axis, t - 7.5e-5))
                    .abs(),
            )
            .max(
                (measured.beta / RAD_PER_OUTPUT_UNIT - 0.2 * analytic_step(&axis, t - 1.5e-4))
                    .abs(),
            );
    }
    assert!(worst < 1e-9, "worst deviation {worst:e} output units");
    // Before the delay has passed, the reported angle is the resting one.
    assert_eq!(y[1].1.beta, 0.0);
    assert!(y[2].1.beta > 0.0 || y[3].1.beta > 0.0);
}

#[test]
fn a_delay_of_exactly_one_period_is_todays_plant() {
    let one =
        scene(r#"{"name": "o", "parts": ["axes", "amplifier"], "mirror": {"delay_s": 5e-5}}"#);
    let plain = scene(r#"{"name": "p", "parts": ["axes", "amplifier"]}"#);
    let amps = SensingPair {
        alpha: 0.3,
        beta: -0.1,
    };
    assert_eq!(
        step_response(&mut Plant::from_scene(&one).unwrap(), amps, 500),
        step_response(&mut Plant::from_scene(&plain).unwrap(), amps, 500)
    );
}

#[test]
fn a_bad_axis_value_names_the_file_and_the_axis_field() {
    for (json, field) in [
        (
            r#"{"name": "x", "parts": ["axes"], "mirror": {"beta": {"damping_ratio": -0.1}}}"#,
            "mirror.beta.damping_ratio",
        ),
        (
            r#"{"name": "x", "parts": ["axes"], "mirror": {"alpha": {"delay_s": 1e-5}}}"#,
            "mirror.alpha.delay_s",
        ),
        (
            r#"{"name": "x", "parts": ["axes"], "control_rate_hz": 1000, "mirror": {"delay_s": 5e-5}}"#,
            "mirror.delay_s",
        ),
    ] {
        match Scene::from_json_str(json, Path::new("bad.json")).unwrap_err() {
            err @ SceneError::Invalid { .. } => {
                let text = err.to_string();
                assert!(
                    text.starts_with("scene bad.json: field `") && text.contains(field),
                    "{text}"
                );
            }
            other => panic!("{other}"),
        }
    }
    let unknown = Scene::from_json_str(
        r#"{"name": "x", "parts": ["axes"], "mirror": {"beta": {"gain": 3}}}"#,
        Path::new("bad.json"),
    )
    .unwrap_err();
    assert!(unknown.to_string().contains("gain"), "{unknown}");
}

#[test]
fn an_axis_that_does_not_move_ignores_its_values() {
    let s = scene(
        r#"{"name": "a", "parts": ["axes"], "mirror": {"axes": ["alpha"], "beta": {"dc_gain": 3.0, "delay_s": 1e-4}}}"#,
    );
    let mut plant = Plant::from_scene(&s).unwrap();
    for _ in 0..10 {
        let out = plant.step(ActuatorPair { a: 1.0, b: 1.0 }).unwrap();
        assert_eq!(out.measured_angles_rad.beta, 0.0);
    }
}
