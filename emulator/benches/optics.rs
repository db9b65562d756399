//! What the optics and the sensor cost per sample: `Optics::observe` on each surface kind,
//! with shading off, on, and with 7-ray spot averaging, and `Ild2300::measure` after it. The
//! mirror sweeps a Lissajous-like path over the full +-1.5 deg so edges and shading are hit.
//!
//! Run: `cargo bench -p scanhil-emulator --bench optics`.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};

use scanhil_emulator::optics::{Optics, OpticsConfig, SpotConfig};
use scanhil_emulator::sensor::{Ild2300, SensorConfig};
use scanhil_protocol::plant_units::SensingPair;
use scanhil_scene::surface::{Surface, SurfaceConfig};

/// One surface of each kind (the height map is the 101 x 101 dimple fixture).
const SURFACES: [(&str, &str); 6] = [
    ("plane", r#"{"kind": "plane", "distance_mm": 130.0}"#),
    (
        "tilted_plane",
        r#"{"kind": "tilted_plane", "distance_mm": 130.0, "slope_x_deg": 10.0}"#,
    ),
    (
        "step",
        r#"{"kind": "step", "distance_mm": 130.0, "height_mm": 3.0, "axis": "y"}"#,
    ),
    (
        "sphere",
        r#"{"kind": "sphere", "radius_mm": 8.0, "center_distance_mm": 135.0, "base_distance_mm": 135.0}"#,
    ),
    (
        "height_map",
        r#"{"kind": "height_map", "file": "dimple.csv", "distance_mm": 130.0, "pixel_mm": 0.1}"#,
    ),
    ("duplo_2x4", r#"{"kind": "duplo_2x4"}"#),
];

/// Mirror positions along a 27/52 Hz Lissajous figure at full range, 1000 samples.
fn lissajous() -> Vec<SensingPair> {
    let full = 1.5f64.to_radians();
    (0..1000)
        .map(|k| {
            let t = f64::from(k) / 1000.0;
            SensingPair {
                alpha: full * (std::f64::consts::TAU * 52.0 * t).sin(),
                beta: full * (std::f64::consts::TAU * 27.0 * t).sin(),
            }
        })
        .collect()
}

fn optics_for(json: &str, config: &OpticsConfig) -> Optics {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/surfaces");
    let surface: SurfaceConfig = serde_json::from_str(json).expect("bench surface");
    Optics::new(
        config,
        Surface::from_config(&surface, &fixtures).expect("bench surface"),
    )
    .expect("bench optics")
}

fn bench_optics(c: &mut Criterion) {
    let path = lissajous();
    let variants = [
        (
            "no_shading",
            OpticsConfig {
                shading: false,
                ..OpticsConfig::default()
            },
        ),
        ("shading", OpticsConfig::default()),
        (
            "shading+spot7",
            OpticsConfig {
                spot: Some(SpotConfig {
                    diameter_mm: 0.13,
                    samples: 7,
                }),
                ..OpticsConfig::default()
            },
        ),
    ];
    let mut group = c.benchmark_group("optics_observe_per_sample");
    for (surface, json) in SURFACES {
        for (variant, config) in &variants {
            let optics = optics_for(json, config);
            let mut k = 0;
            group.bench_function(format!("{surface}/{variant}"), |b| {
                b.iter(|| {
                    k = (k + 1) % path.len();
                    black_box(optics.observe(black_box(path[k])))
                })
            });
        }
    }
    group.finish();
}

fn bench_sensor(c: &mut Criterion) {
    let path = lissajous();
    let optics = optics_for(SURFACES[5].1, &OpticsConfig::default());
    let mut sensor = Ild2300::new(&SensorConfig::default(), 7, true).expect("bench sensor");
    let mut group = c.benchmark_group("sensor_per_sample");
    let reading = optics.observe(path[0]);
    group.bench_function("measure_with_noise", |b| {
        let instant = sensor
            .sample_instants(0.0, 5e-5)
            .next()
            .expect("one instant");
        b.iter(|| black_box(sensor.measure(instant, black_box(&reading.outcome))))
    });
    let mut k = 0;
    group.bench_function("duplo_observe+measure", |b| {
        let instant = sensor
            .sample_instants(0.0, 5e-5)
            .next()
            .expect("one instant");
        b.iter(|| {
            k = (k + 1) % path.len();
            let r = optics.observe(black_box(path[k]));
            black_box(sensor.measure(instant, &r.outcome))
        })
    });
    group.finish();
}

criterion_group!(benches, bench_optics, bench_sensor);
criterion_main!(benches);
