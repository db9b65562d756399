//! The plant with its optical chain: sensor samples per period on the sensor's own clock,
//! ground truth, and parts switched by the scene's list.

use std::path::Path;

use scanhil_emulator::plant::Plant;
use scanhil_emulator::scene::Scene;
use scanhil_protocol::ild::IldValue;
use scanhil_protocol::plant_units::ActuatorPair;

fn fixture(name: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/scenes")
        .join(name);
    Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn protocol_only_scene_has_no_dynamics_and_one_identical_sample_per_period() {
    let scene = fixture("protocol-only.json");
    let mut plant = Plant::from_scene(&scene).unwrap();
    assert_eq!(plant.integrator(), None);
    let mut values = Vec::new();
    for k in 0..200 {
        let out = plant.step(ActuatorPair { a: 1.0, b: -1.0 }).unwrap();
        assert_eq!(out.sensor_samples.len(), 1, "period {k}");
        let sample = out.sensor_samples[0];
        assert!(sample.t_s > k as f64 * 50e-6 && sample.t_s <= (k + 1) as f64 * 50e-6 + 1e-12);
        values.push(sample.value);
    }
    assert!(
        matches!(values[0], IldValue::Distance(_)),
        "{:?}",
        values[0]
    );
    assert!(values.iter().all(|v| *v == values[0]));
}

#[test]
fn sensor_samples_follow_the_sensor_clock_not_the_control_clock() {
    let mut scene = fixture("plane-120mm.json");
    let mut sensor = scene.sensor.unwrap_or_default();
    sensor.measuring_rate_hz = 49_140.0;
    scene.sensor = Some(sensor);
    let mut plant = Plant::from_scene(&scene).unwrap();
    let periods = 2000; // 0.1 s
    let mut count = 0;
    let mut last_t = f64::MIN;
    for _ in 0..periods {
        let out = plant.step(ActuatorPair::default()).unwrap();
        for s in &out.sensor_samples {
            assert!(s.t_s > last_t);
            last_t = s.t_s;
        }
        count += out.sensor_samples.len();
    }
    let expected = 49_140.0 * 0.1;
    assert!(
        (count as f64 - expected).abs() <= 2.0,
        "{count} samples in 0.1 s"
    );
}

#[test]
fn ground_truth_is_queryable_and_sensor_sees_the_plane() {
    let scene = fixture("plane-120mm.json");
    let mut plant = Plant::from_scene(&scene).unwrap();
    let z = plant.surface().unwrap().height_at(0.0, -10.0).unwrap();
    assert!((z + 120.0).abs() < 1e-9, "{z}");
    let out = plant.step(ActuatorPair::default()).unwrap();
    let sample = out.sensor_samples[0];
    let IldValue::Distance(raw) = sample.value else {
        panic!("{:?}", sample.value)
    };
    let mm = plant.sensor().unwrap().range().digital_to_mm(raw).unwrap();
    // At rest the folded path to a plane at |z| = 120 mm is 130 mm (api-geometry.md).
    assert!((mm - 130.0).abs() < 0.05, "{mm}");
}

#[test]
fn leaving_out_sensor_and_shading_builds_neither() {
    let mut scene = fixture("step-3mm.json");
    scene
        .parts
        .retain(|p| !matches!(p.name(), "sensor" | "sensor_noise" | "shading"));
    let mut plant = Plant::from_scene(&scene).unwrap();
    assert!(plant.sensor().is_none());
    assert!(!plant.optics().unwrap().shading());
    assert!(
        plant
            .step(ActuatorPair::default())
            .unwrap()
            .sensor_samples
            .is_empty()
    );
    let full = Plant::from_scene(&fixture("step-3mm.json")).unwrap();
    assert!(full.optics().unwrap().shading() && full.sensor().is_some());
}
