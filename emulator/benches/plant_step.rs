//! What each part of the plant costs per control period: `Plant::step` with the parts added
//! one at a time, and each integrator on the full drive model.
//!
//! Run: `cargo bench -p scanhil-emulator --bench plant_step`.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};

use scanhil_emulator::drive_model::DriveModel;
use scanhil_emulator::integrator::{IntegratorConfig, Method, Stepper};
use scanhil_emulator::plant::Plant;
use scanhil_emulator::scene::Scene;
use scanhil_protocol::plant_units::ActuatorPair;

/// The whole drive, the parts every optical rung adds to.
const DRIVE: &str = r#""axes", "cross_talk", "amplifier", "power_limit", "angle_sensor_noise""#;

/// Scenes from nothing to the whole plant, each adding one part: (name, parts, extra JSON).
fn ladder() -> Vec<(&'static str, String)> {
    let plane = r#", "surface": {"kind": "plane", "distance_mm": 120.0}"#;
    let optical = |parts: &str| format!("[{DRIVE}, {parts}]{plane}");
    vec![
        ("none", "[]".into()),
        (
            "axes_alpha_only",
            r#"["axes"], "mirror": {"axes": ["alpha"]}"#.into(),
        ),
        ("axes", r#"["axes"]"#.into()),
        ("+cross_talk", r#"["axes", "cross_talk"]"#.into()),
        (
            "+amplifier",
            r#"["axes", "cross_talk", "amplifier"]"#.into(),
        ),
        (
            "+power_limit",
            r#"["axes", "cross_talk", "amplifier", "power_limit"]"#.into(),
        ),
        ("+angle_sensor_noise", format!("[{DRIVE}]")),
        ("+optics_plane", optical(r#""optics""#)),
        ("+shading", optical(r#""optics", "shading""#)),
        ("+sensor_20khz", optical(r#""optics", "shading", "sensor""#)),
        (
            "+sensor_noise",
            optical(r#""optics", "shading", "sensor", "sensor_noise""#),
        ),
    ]
}

fn plant_for(parts: &str) -> Plant {
    let json = format!(r#"{{"name": "bench", "parts": {parts}}}"#);
    let scene = Scene::from_json_str(&json, Path::new("bench.json")).expect("bench scene");
    Plant::from_scene(&scene).expect("bench plant")
}

fn parts_ladder(c: &mut Criterion) {
    let mut group = c.benchmark_group("plant_step");
    for (name, parts) in ladder() {
        let mut plant = plant_for(&parts);
        let mut k = 0u32;
        group.bench_function(name, |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let i = f64::from(k % 64) * 0.01;
                black_box(
                    plant
                        .step(black_box(ActuatorPair { a: i, b: -i }))
                        .expect("finite"),
                )
            });
        });
    }
    group.finish();
}

fn integrators(c: &mut Criterion) {
    let scene = Scene::from_json_str(
        r#"{"name": "bench", "parts": ["axes", "cross_talk", "amplifier"]}"#,
        Path::new("bench.json"),
    )
    .expect("bench scene");
    let model = DriveModel::new(
        Some(&scene.mirror),
        Some(&scene.amplifier),
        Some(&scene.cross_talk),
    );
    let mut group = c.benchmark_group("integrator_period");
    for method in Method::ALL {
        // The fewest sub-steps that are stable on the stiff amplifier (2 for RK4 and Euler).
        for substeps in [1, 2, 8] {
            let config = IntegratorConfig { method, substeps };
            let Ok(mut stepper) = Stepper::new(&model, scene.period_s(), config) else {
                continue;
            };
            let mut x = model.initial_state([0.0, 0.0]);
            group.bench_function(format!("{method}_x{substeps}"), |b| {
                b.iter(|| stepper.step(black_box(&mut x), black_box([0.1, -0.1])));
            });
        }
    }
    group.finish();
}

criterion_group!(benches, parts_ladder, integrators);
criterion_main!(benches);
