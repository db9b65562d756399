//! Properties of the plant over random part subsets and command sequences.

use std::path::Path;

use proptest::prelude::*;

use scanhil_emulator::plant::Plant;
use scanhil_emulator::scene::{Part, Scene};
use scanhil_protocol::plant_units::ActuatorPair;

/// The drive parts that need no surface, in an order that respects their dependencies.
const DRIVE_PARTS: [Part; 5] = [
    Part::Axes,
    Part::CrossTalk,
    Part::Amplifier,
    Part::PowerLimit,
    Part::AngleSensorNoise,
];

fn scene_with(mask: u8, seed: u64) -> Scene {
    let mut parts: Vec<&str> = DRIVE_PARTS
        .iter()
        .enumerate()
        .filter(|(i, _)| mask & (1 << i) != 0)
        .map(|(_, p)| p.name())
        .collect();
    if parts.contains(&"cross_talk") && !parts.contains(&"axes") {
        parts.retain(|p| *p != "cross_talk");
    }
    let list = parts
        .iter()
        .map(|p| format!("\"{p}\""))
        .collect::<Vec<_>>()
        .join(",");
    let json = format!(
        r#"{{"name": "prop", "seed": {seed}, "parts": [{list}], "integrator": {{"method": "trapezoid"}}}}"#
    );
    Scene::from_json_str(&json, Path::new("prop.json")).expect("valid")
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn any_finite_commands_give_finite_deterministic_bounded_output(
        mask in 0u8..32,
        seed in any::<u64>(),
        commands in proptest::collection::vec((-1.0e6f64..1.0e6, -1.0e6f64..1.0e6), 1..300),
    ) {
        let scene = scene_with(mask, seed);
        let run = || {
            let mut plant = Plant::from_scene(&scene).unwrap();
            commands
                .iter()
                .map(|&(a, b)| plant.step(ActuatorPair { a, b }).unwrap())
                .collect::<Vec<_>>()
        };
        let first = run();
        prop_assert_eq!(&first, &run());
        for step in &first {
            let m = step.measured_angles_rad;
            prop_assert!(m.alpha.is_finite() && m.beta.is_finite());
            prop_assert!(step.coil_power_w.is_finite() && step.coil_power_w >= 0.0);
            if scene.has(Part::Amplifier) {
                let limit = scene.amplifier.current_limit_a;
                prop_assert!(step.applied_currents_a.a.abs() <= limit);
                prop_assert!(step.applied_currents_a.b.abs() <= limit);
            }
            if let Some(mean) = step.mean_power_w {
                prop_assert!(mean <= scene.power_limit.limit_w * (1.0 + 1e-6), "{mean}");
            }
        }
    }
}
