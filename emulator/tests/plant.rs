//! The composed plant: coil power and its limit, parts lists, seeds, and scene errors.

use std::path::{Path, PathBuf};

use scanhil_emulator::mirror::{MirrorConfig, SensingAxis};
use scanhil_emulator::plant::{Plant, PlantEvent};
use scanhil_emulator::power::{coil_resistance_ohm, full_range_current_a};
use scanhil_emulator::scene::{Part, Scene, SceneError};
use scanhil_protocol::plant_units::{
    ActuatorPair, RAD_PER_OUTPUT_UNIT, SensingPair, actuator_from_sensing,
};
use scanhil_scene::json_file::JsonFileError;

fn scene(json: &str) -> Scene {
    Scene::from_json_str(json, Path::new("test-scene.json")).expect("test scene is valid")
}

fn scene_err(json: &str) -> SceneError {
    Scene::from_json_str(json, Path::new("bad.json")).unwrap_err()
}

/// Drives a 52 Hz sine of `amplitude_a` on both sensing axes at once (in phase) for
/// `periods`; returns the plant steps.
fn sine_52_hz(
    plant: &mut Plant,
    amplitude_a: f64,
    periods: usize,
) -> Vec<scanhil_emulator::plant::PlantStep> {
    let ta = plant.period_s();
    (0..periods)
        .map(|k| {
            let i = amplitude_a * (std::f64::consts::TAU * 52.0 * k as f64 * ta).sin();
            plant
                .step(actuator_from_sensing(SensingPair { alpha: i, beta: i }))
                .unwrap()
        })
        .collect()
}

const POWER_SCENE: &str = r#"{"name": "p", "parts": ["axes", "power_limit"],
    "power_limit": {"limit_w": 30.0, "window_s": 1.0, "on_exceed": "ON_EXCEED"}}"#;

#[test]
fn full_range_sines_at_52_hz_on_both_axes_dissipate_exactly_30_w_and_reach_one_and_a_half_degrees()
{
    let s = scene(&POWER_SCENE.replace("ON_EXCEED", "clamp"));
    let mut plant = Plant::from_scene(&s).unwrap();
    assert!(
        (plant.coil_resistance_ohm() - coil_resistance_ohm(&MirrorConfig::default())).abs() < 1e-15
    );
    let amplitude_a = full_range_current_a(&s.mirror.axis(SensingAxis::Alpha), 52.0);
    let steps = sine_52_hz(&mut plant, amplitude_a, 30_000);
    assert!(
        steps.iter().all(|s| s.events.is_empty()),
        "a drive at the limit must not be cut"
    );
    let mean = steps.last().unwrap().mean_power_w.unwrap();
    assert!((mean - 30.0).abs() < 1e-3, "mean power {mean} W");
    // After 1.5 s (about 7 decay times) the response is full range: 1.5 deg.
    let last_cycle = &steps[steps.len() - 385..];
    let peak_rad = last_cycle
        .iter()
        .map(|s| s.true_angles_rad.alpha.abs())
        .fold(0.0, f64::max);
    assert!(
        (peak_rad.to_degrees() / 1.5 - 1.0).abs() < 0.01,
        "peak {} deg",
        peak_rad.to_degrees()
    );
    assert!((peak_rad / RAD_PER_OUTPUT_UNIT / 10.0 - 1.0).abs() < 0.01);
}

#[test]
fn over_the_limit_clamp_holds_30_w_and_reports_it() {
    let s = scene(&POWER_SCENE.replace("ON_EXCEED", "clamp"));
    let mut plant = Plant::from_scene(&s).unwrap();
    let amplitude_a = 1.1 * full_range_current_a(&s.mirror.axis(SensingAxis::Alpha), 52.0);
    let steps = sine_52_hz(&mut plant, amplitude_a, 30_000);
    let clamped = steps
        .iter()
        .filter(|s| matches!(s.events.as_slice(), [PlantEvent::PowerClamped { .. }]))
        .count();
    assert!(clamped > 100, "{clamped}");
    assert!(
        steps
            .iter()
            .all(|s| s.mean_power_w.unwrap() <= 30.0 * (1.0 + 1e-6))
    );
    assert!(!steps.iter().any(|s| s.faulted));
}

#[test]
fn over_the_limit_fault_latches_zero_current_until_reset() {
    let s = scene(&POWER_SCENE.replace("ON_EXCEED", "fault"));
    let mut plant = Plant::from_scene(&s).unwrap();
    let amplitude_a = 1.1 * full_range_current_a(&s.mirror.axis(SensingAxis::Alpha), 52.0);
    let steps = sine_52_hz(&mut plant, amplitude_a, 30_000);
    let first = steps.iter().position(|s| s.faulted).expect("must fault");
    assert!(
        matches!(steps[first].events.as_slice(), [PlantEvent::PowerFault { mean_w }] if *mean_w > 30.0)
    );
    assert!(
        steps[first..]
            .iter()
            .all(|s| s.faulted && s.applied_currents_a == ActuatorPair::default())
    );
    plant.reset_fault();
    let after = plant.step(ActuatorPair { a: 0.1, b: 0.0 }).unwrap();
    assert!(!after.faulted);
}

#[test]
fn only_listed_parts_are_active_and_reported_in_canonical_order() {
    let s = scene(r#"{"name": "t", "parts": ["angle_sensor_noise", "axes"]}"#);
    let plant = Plant::from_scene(&s).unwrap();
    assert_eq!(plant.active_parts(), &[Part::Axes, Part::AngleSensorNoise]);
    // Without `axes` nothing is integrated and the mirror holds its initial angles.
    let still = scene(
        r#"{"name": "t", "parts": [], "mirror": {"initial_angles_rad": {"alpha": 0.01, "beta": -0.02}}}"#,
    );
    let mut plant = Plant::from_scene(&still).unwrap();
    assert_eq!(plant.integrator(), None);
    for _ in 0..10 {
        let out = plant.step(ActuatorPair { a: 3.0, b: 1.0 }).unwrap();
        assert_eq!(
            out.measured_angles_rad,
            SensingPair {
                alpha: 0.01,
                beta: -0.02
            }
        );
        assert_eq!(out.mean_power_w, None);
    }
}

#[test]
fn same_seed_same_run_other_seed_other_noise() {
    let run = |seed: u64| {
        let s = scene(&format!(
            r#"{{"name": "t", "seed": {seed}, "parts": ["axes", "cross_talk", "amplifier", "angle_sensor_noise"]}}"#
        ));
        let mut plant = Plant::from_scene(&s).unwrap();
        (0..500)
            .map(|_| {
                plant
                    .step(ActuatorPair { a: 0.3, b: -0.1 })
                    .unwrap()
                    .measured_angles_rad
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(run(5), run(5));
    assert_ne!(run(5), run(6));
}

#[test]
fn scene_errors_name_the_file_and_what_is_wrong() {
    let unknown_field = scene_err("{\n  \"name\": \"x\",\n  \"parts\": [],\n  \"colour\": 1\n}");
    match &unknown_field {
        SceneError::File(JsonFileError::Parse {
            path,
            line,
            column,
            message,
        }) => {
            assert_eq!(path, &PathBuf::from("bad.json"));
            assert_eq!((*line, *column), (4, 10));
            assert!(message.contains("colour"), "{message}");
        }
        other => panic!("{other}"),
    }
    assert!(
        unknown_field.to_string().starts_with("bad.json:4:10: "),
        "file, line and column lead the message: {unknown_field}"
    );
    match scene_err(r#"{"name": "x", "parts": ["shading"]}"#) {
        SceneError::Invalid { field, reason, .. } => {
            assert_eq!(field, "parts");
            assert!(
                reason.contains("shading") && reason.contains("optics"),
                "{reason}"
            );
        }
        other => panic!("{other}"),
    }
    match scene_err(r#"{"name": "x", "parts": ["axes"], "mirror": {"damping_ratio": -0.1}}"#) {
        SceneError::Invalid { field, .. } => assert_eq!(field, "mirror.damping_ratio"),
        other => panic!("{other}"),
    }
    match scene_err(r#"{"name": "x", "parts": ["bogus"]}"#) {
        SceneError::File(JsonFileError::Parse { message, .. }) => {
            assert!(message.contains("bogus"), "{message}");
        }
        other => panic!("{other}"),
    }
    let missing = Scene::load(Path::new("/nonexistent/scene.json")).unwrap_err();
    assert!(
        matches!(missing, SceneError::File(JsonFileError::Io { .. }))
            && missing.to_string().contains("/nonexistent/scene.json")
    );
}

#[test]
fn every_fixture_scene_loads_and_builds() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "json") {
            let s = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
            let mut plant =
                Plant::from_scene(&s).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            for _ in 0..20 {
                plant.step(ActuatorPair { a: 0.1, b: 0.1 }).unwrap();
            }
            count += 1;
        }
    }
    assert!(count >= 4, "only {count} scenes in {}", dir.display());
}
