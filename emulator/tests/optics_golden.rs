//! The optics without `multiple_reflections` are bit-identical to the optics before the
//! second bounce existed: fingerprints (FNV-1a over the f64 bits) of a mirror-angle sweep over
//! several surfaces and of a whole plant run on the Duplo scene, recorded from the code before
//! the change.
//!
//! The fingerprints depend on the platform's libm (sin, cos, tan), so they are checked where
//! they were recorded: x86_64 Linux.

use std::path::Path;

use scanhil_emulator::optics::{OpticalOutcome, Optics, OpticsConfig, SpotConfig};
use scanhil_emulator::plant::Plant;
use scanhil_emulator::scene::Scene;
use scanhil_protocol::ild::IldValue;
use scanhil_protocol::plant_units::{ActuatorPair, SensingPair};
use scanhil_scene::surface::{Surface, SurfaceConfig};

/// FNV-1a, 64 bit.
struct Fingerprint(u64);

impl Fingerprint {
    fn new() -> Self {
        Fingerprint(0xcbf2_9ce4_8422_2325)
    }
    fn add(&mut self, word: u64) {
        for byte in word.to_le_bytes() {
            self.0 ^= u64::from(byte);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}

fn fixture(name: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/scenes")
        .join(name);
    Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

const SURFACES: [&str; 4] = [
    r#"{"kind": "duplo_2x4"}"#,
    r#"{"kind": "step", "distance_mm": 130.0, "height_mm": 3.0, "axis": "y"}"#,
    r#"{"kind": "sphere", "radius_mm": 8.0, "center_distance_mm": 135.0, "base_distance_mm": 140.0}"#,
    r#"{"kind": "tilted_plane", "distance_mm": 130.0, "slope_x_deg": 20.0, "slope_y_deg": -10.0}"#,
];

/// A 61 x 61 sweep of +-1.5 deg over each surface, 7-ray spot, shading on: every outcome and
/// spot folded in.
fn sweep_fingerprint(config: &OpticsConfig) -> u64 {
    let mut f = Fingerprint::new();
    for json in SURFACES {
        let surface: SurfaceConfig = serde_json::from_str(json).unwrap();
        let optics = Optics::new(
            config,
            Surface::from_config(&surface, Path::new(".")).unwrap(),
        )
        .unwrap();
        for i in 0..61 {
            for j in 0..61 {
                let angle = |k: i32| (-1.5 + 0.05 * f64::from(k)).to_radians();
                let r = optics.observe(SensingPair {
                    alpha: angle(i),
                    beta: angle(j),
                });
                match r.outcome {
                    OpticalOutcome::Distance { z_meas_mm, .. } => {
                        f.add(1);
                        f.add(z_meas_mm.to_bits());
                    }
                    OpticalOutcome::Miss => f.add(2),
                    OpticalOutcome::Shaded(reason) => {
                        f.add(3);
                        f.add(reason.name().len() as u64);
                    }
                }
                if let Some(p) = r.spot_mm {
                    p.coords.iter().for_each(|v| f.add(v.to_bits()));
                }
            }
        }
    }
    f.0
}

fn default_sweep_config() -> OpticsConfig {
    OpticsConfig {
        spot: Some(SpotConfig {
            diameter_mm: 0.13,
            samples: 7,
        }),
        ..OpticsConfig::default()
    }
}

/// A plant run on the Duplo scene (whole plant, noise on): 4000 periods of a two-tone drive,
/// every sensor sample's raw value and time folded in.
fn plant_fingerprint(scene: &Scene) -> u64 {
    let mut plant = Plant::from_scene(scene).unwrap();
    let mut f = Fingerprint::new();
    let mut distances = 0;
    for k in 0..4000 {
        let t = f64::from(k) * 50e-6;
        let command = ActuatorPair {
            a: 0.6 * (2.0 * std::f64::consts::PI * 27.0 * t).sin(),
            b: 0.6 * (2.0 * std::f64::consts::PI * 52.0 * t).sin(),
        };
        for s in plant.step(command).unwrap().sensor_samples {
            distances += usize::from(matches!(s.value, IldValue::Distance(_)));
            f.add(u64::from(s.value.raw()));
            f.add(s.t_s.to_bits());
        }
    }
    assert!(
        distances > 3000,
        "only {distances} distances: the run sees no surface"
    );
    f.0
}

#[cfg(all(target_arch = "x86_64", target_os = "linux"))]
#[test]
fn option_off_sweep_is_bit_identical_to_the_optics_before_multipath() {
    let got = sweep_fingerprint(&default_sweep_config());
    assert_eq!(got, GOLDEN_SWEEP, "sweep fingerprint {got:#018x}");
}

#[cfg(all(target_arch = "x86_64", target_os = "linux"))]
#[test]
fn option_off_plant_run_is_bit_identical_to_the_plant_before_multipath() {
    let got = plant_fingerprint(&fixture("duplo-2x4-130mm.json"));
    assert_eq!(got, GOLDEN_PLANT, "plant fingerprint {got:#018x}");
}

/// Recorded from the optics before `multiple_reflections` existed.
const GOLDEN_SWEEP: u64 = 0x22dc_827b_281a_3649;
/// Recorded from the plant before `multiple_reflections` existed.
const GOLDEN_PLANT: u64 = 0x3170_a99a_a3a2_11fa;
