//! The plant with its optical chain: sensor samples per period on the sensor's own clock,
//! ground truth, and parts switched by the scene's list.

use std::path::Path;

use scanhil_emulator::optics::receiver::SurfaceFinish;
use scanhil_emulator::plant::Plant;
use scanhil_emulator::scene::{Part, Scene};
use scanhil_protocol::ild::{IldError, IldValue};
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

/// The noise-free distances of the samples of `scene` driven by a 2 A, 50 Hz sine on coil A
/// for 0.02 s, by sample index.
fn driven_distances(scene: &Scene) -> Vec<(u32, f64)> {
    let mut plant = Plant::from_scene(scene).unwrap();
    let mut distances = Vec::new();
    for k in 0..400 {
        let t_s = k as f64 * 50e-6;
        let a = 2.0 * (std::f64::consts::TAU * 50.0 * t_s).sin();
        let out = plant.step(ActuatorPair { a, b: 0.0 }).unwrap();
        for sample in out.sensor_samples {
            if let Some(z_mm) = sample.true_distance_mm {
                distances.push((sample.counter, z_mm));
            }
        }
    }
    distances
}

#[test]
fn an_exposure_sees_the_moving_spot_at_the_middle_of_its_path() {
    // On the tilted plane the distance changes along the spot's path; over a 40 us exposure
    // the average is (to second order) the distance at the exposure's middle, 20 us before the
    // cycle's instant: the instantaneous sensor sampled 20 us earlier gives it.
    let mut scene = fixture("tilted-plane.json");
    scene
        .parts
        .retain(|part| part.name() != "sensor_noise" && part.name() != "angle_sensor_noise");
    let with = |exposure_us: f64, clock_offset_s: f64| {
        let mut scene = scene.clone();
        scene.sensor = Some(scanhil_emulator::sensor::SensorConfig {
            exposure_us,
            clock_offset_s,
            ..scene.sensor.unwrap_or_default()
        });
        driven_distances(&scene)
    };
    let exposed = with(40.0, 0.0);
    let middle = with(0.0, -20e-6);
    let instant = with(0.0, 0.0);
    let largest_gap = |other: &[(u32, f64)]| {
        exposed
            .iter()
            .filter_map(|(counter, z)| {
                let (_, z_other) = other.iter().find(|(c, _)| c == counter)?;
                Some((z - z_other).abs())
            })
            .fold(0.0, f64::max)
    };
    let from_middle_mm = largest_gap(&middle);
    let from_instant_mm = largest_gap(&instant);
    assert!(exposed.len() > 350, "{} samples", exposed.len());
    assert!(
        from_middle_mm < 1e-4 && from_instant_mm > 20.0 * from_middle_mm,
        "the exposure's average {from_middle_mm} mm from the middle's distance, {from_instant_mm} mm from the instant's"
    );
}

#[test]
fn the_receiver_parts_need_the_sensor_and_a_sound_finish() {
    let mut scene = fixture("plane-120mm.json");
    scene
        .parts
        .retain(|p| !matches!(p.name(), "sensor" | "sensor_noise"));
    scene.parts.push(Part::Speckle);
    let (field, reason) = scene.validate().unwrap_err();
    assert_eq!(field, "parts");
    assert!(reason.contains("`speckle` needs part `sensor`"), "{reason}");

    let mut scene = fixture("plane-120mm.json");
    scene.surface_finish = Some(SurfaceFinish {
        reflectance: 2.0,
        ..SurfaceFinish::default()
    });
    // A section whose parts are not listed is ignored; listed, it is checked.
    assert!(scene.validate().is_ok());
    scene.parts.push(Part::ReceiverIntensity);
    let (field, reason) = scene.validate().unwrap_err();
    assert_eq!(field, "surface_finish.reflectance");
    assert!(reason.contains("in [0, 1]"), "{reason}");
}

#[test]
fn speckle_moves_the_distances_by_its_rms_and_a_dark_surface_gives_no_peak() {
    let mut scene = fixture("plane-120mm.json");
    scene.parts.retain(|part| {
        !matches!(
            part.name(),
            "sensor_noise" | "angle_sensor_noise" | "angle_sensor_bandwidth"
        )
    });
    let plain = driven_distances(&scene);
    let mut speckled_scene = scene.clone();
    speckled_scene.parts.push(Part::Speckle);
    let speckled = driven_distances(&speckled_scene);
    assert_eq!(plain.len(), speckled.len());
    let errors_um: Vec<f64> = plain
        .iter()
        .zip(&speckled)
        .map(|((c, z), (c_s, z_s))| {
            assert_eq!(c, c_s);
            (z_s - z) * 1e3
        })
        .collect();
    let rms_um = (errors_um.iter().map(|e| e * e).sum::<f64>() / errors_um.len() as f64).sqrt();
    // Dorsch et al.'s lambda / (2 pi sin u sin theta) for this receiver and the paper's
    // 11-19 deg triangulation angle: 6-12 um at full contrast (a 0.2 um rough face). The
    // spot sweeps many diameters in 0.02 s, so the rms is the field's.
    assert!((3.0..20.0).contains(&rms_um), "{rms_um} um");

    let mut dark = scene.clone();
    dark.parts.push(Part::ReceiverIntensity);
    dark.surface_finish = Some(SurfaceFinish {
        reflectance: 0.005,
        ..SurfaceFinish::default()
    });
    let mut plant = Plant::from_scene(&dark).unwrap();
    let mut bright = Plant::from_scene(&{
        let mut bright = dark.clone();
        bright.surface_finish = Some(SurfaceFinish::default());
        bright
    })
    .unwrap();
    for _ in 0..100 {
        for sample in plant.step(ActuatorPair::default()).unwrap().sensor_samples {
            assert_eq!(sample.value, IldValue::Error(IldError::NoPeak));
            assert!(sample.true_distance_mm.is_some());
        }
        for sample in bright.step(ActuatorPair::default()).unwrap().sensor_samples {
            assert!(matches!(sample.value, IldValue::Distance(_)));
        }
    }
}
