//! The active parts' costs: every active part listed once, in dependency order, with a
//! finite, non-negative cost; nothing listed that is not active; the parts' costs add up to at
//! least the whole plant's time above the bare step.

use std::path::Path;

use scanhil_emulator::part_cost::{CostTiming, dependency_order, measure};
use scanhil_emulator::scene::{Part, Scene};

fn scene(json: &str) -> Scene {
    Scene::from_json_str(json, Path::new("cost.json")).expect("test scene is valid")
}

const DUPLO_LIKE: &str = r#"{"name": "c", "parts": ["sensor_noise", "sensor", "shading", "optics",
    "angle_sensor_noise", "cross_talk", "axes"],
    "surface": {"kind": "plane", "distance_mm": 120.0}}"#;

#[test]
fn parts_come_after_the_parts_they_need() {
    let order = dependency_order(&scene(DUPLO_LIKE));
    assert_eq!(order.len(), 7);
    let at = |part: Part| order.iter().position(|p| *p == part).unwrap();
    assert!(at(Part::Axes) < at(Part::CrossTalk));
    assert!(at(Part::Optics) < at(Part::Shading));
    assert!(at(Part::Optics) < at(Part::Sensor));
    assert!(at(Part::Sensor) < at(Part::SensorNoise), "{order:?}");
}

#[test]
fn every_active_part_has_a_measured_cost_and_no_other_part_is_listed() {
    let s = scene(DUPLO_LIKE);
    let timing = CostTiming {
        periods: 100,
        repetitions: 2,
    };
    let costs = measure(&s, timing).unwrap();
    let listed: Vec<Part> = costs.parts.iter().map(|p| p.part).collect();
    assert_eq!(listed, dependency_order(&s));
    assert_eq!(costs.periods_timed, 100);
    assert!(
        costs
            .parts
            .iter()
            .all(|p| p.us_per_period.is_finite() && p.us_per_period >= 0.0),
        "{costs:?}"
    );
    let above_bare = costs.plant_us_per_period - costs.bare_us_per_period;
    let sum: f64 = costs.parts.iter().map(|p| p.us_per_period).sum();
    // Each difference is clamped at zero, so the sum never falls below the telescoped whole.
    assert!(sum >= above_bare - 1e-9, "{sum} < {above_bare}");
    let text = costs.describe();
    assert!(text.starts_with("axes ") && text.contains(" us"), "{text}");
}

#[test]
fn a_scene_without_parts_lists_none() {
    let costs = measure(
        &scene(r#"{"name": "n", "parts": []}"#),
        CostTiming::default(),
    )
    .unwrap();
    assert!(costs.parts.is_empty());
    assert_eq!(costs.describe(), "none");
}
