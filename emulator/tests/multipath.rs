//! Multiple reflections on the Duplo stud (`fixtures/scenes/duplo-2x4-130mm-multipath.json`):
//! the second bounce biases the distance near the stud's walls and changes nothing elsewhere.
//!
//! The figures in `docs/optics-and-sensor.md` come from
//! `cargo test -p scanhil-emulator --test multipath -- --nocapture`.

use std::path::Path;

use scanhil_emulator::optics::multipath::MultipathConfig;
use scanhil_emulator::optics::{OpticalOutcome, Optics, OpticsConfig};
use scanhil_emulator::plant::Plant;
use scanhil_emulator::scene::{Part, Scene};
use scanhil_protocol::plant_units::SensingPair;
use scanhil_scene::surface::{Surface, SurfaceConfig, duplo};

/// Spots closer than this to a stud wall count as "near an edge", mm.
const NEAR_WALL_MM: f64 = 0.5;
/// Positions whose option-off error is below this have the whole spot on one face (elsewhere
/// the 7-ray average mixes two levels and its error hides the bounce's), mm.
const ONE_FACE_ERROR_MM: f64 = 1e-3;
/// Mirror positions per axis over +-1.5 deg (0.01 deg apart: about 25 um on the brick).
const GRID: usize = 301;

fn fixture(name: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/scenes")
        .join(name);
    Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// The scene's optics as the plant builds them, with `multiple_reflections` replaced.
fn optics(scene: &Scene, multipath: Option<MultipathConfig>) -> Optics {
    let config = OpticsConfig {
        multiple_reflections: multipath,
        ..scene.optics.clone().unwrap()
    };
    let surface =
        Surface::from_config(scene.surface.as_ref().unwrap(), scene.base_dir().unwrap()).unwrap();
    Optics::new(&config, surface)
        .unwrap()
        .with_shading(scene.has(Part::Shading))
}

/// Distance from (x, y) to the nearest stud wall (bore or outer), mm.
fn wall_distance_mm(scene: &Scene, x_mm: f64, y_mm: f64) -> f64 {
    let Some(SurfaceConfig::Duplo2x4 {
        center_x_mm,
        center_y_mm,
        rotation_deg,
        ..
    }) = scene.surface
    else {
        panic!("not a Duplo scene")
    };
    assert_eq!(rotation_deg, 0.0);
    duplo::stud_centers()
        .into_iter()
        .map(|[sx, sy]| {
            let r = (x_mm - center_x_mm - sx).hypot(y_mm - center_y_mm - sy);
            let walls = [
                duplo::STUD_BORE_DIAMETER_MM / 2.0,
                duplo::STUD_OUTER_DIAMETER_MM / 2.0,
            ];
            walls
                .into_iter()
                .map(|w| (r - w).abs())
                .fold(f64::INFINITY, f64::min)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Distance errors against the true surface over the grid, off against on.
#[derive(Debug, Default)]
struct EdgeStatistics {
    near: usize,
    far: usize,
    /// Positions whose outcome differs between off and on.
    changed_near: usize,
    changed_far: usize,
    /// Positions near a wall with a distance and the whole spot on one face.
    one_face_near: usize,
    /// Largest |error| near a wall (whole spot on one face), off / on, mm.
    max_error_near_off_mm: f64,
    max_error_near_on_mm: f64,
    /// RMS error near a wall (whole spot on one face), off / on, mm.
    rms_near_off_mm: f64,
    rms_near_on_mm: f64,
    /// Largest |error| far from the walls (on = off there), mm.
    max_error_far_mm: f64,
    /// Largest |on - off| and the wall distance where it occurs, mm.
    largest_change_mm: f64,
    largest_change_wall_mm: f64,
    /// The farthest from a wall any change occurs, mm.
    farthest_change_wall_mm: f64,
    /// Changes that read a shorter distance (the surface higher) than without the bounce.
    changes_shorter: usize,
}

fn edge_statistics(scene: &Scene, on: &Optics, off: &Optics) -> EdgeStatistics {
    let mut s = EdgeStatistics::default();
    let (mut sum_sq_off, mut sum_sq_on, mut with_distance) = (0.0, 0.0, 0usize);
    for i in 0..GRID {
        for j in 0..GRID {
            let angle = |k: usize| (-1.5 + 3.0 * k as f64 / (GRID - 1) as f64).to_radians();
            let angles = SensingPair {
                alpha: angle(i),
                beta: angle(j),
            };
            let (r_off, r_on) = (off.observe(angles), on.observe(angles));
            assert_eq!(r_off.spot_mm, r_on.spot_mm);
            let Some(spot) = r_off.spot_mm else { continue };
            let wall_mm = wall_distance_mm(scene, spot.x, spot.y);
            let near = wall_mm < NEAR_WALL_MM;
            let same = match (r_off.outcome, r_on.outcome) {
                (
                    OpticalOutcome::Distance { z_meas_mm: a, .. },
                    OpticalOutcome::Distance { z_meas_mm: b, .. },
                ) => a.to_bits() == b.to_bits(),
                (a, b) => a == b,
            };
            if near {
                s.near += 1;
            } else {
                s.far += 1;
            }
            if !same {
                if near {
                    s.changed_near += 1;
                } else {
                    s.changed_far += 1;
                }
                s.farthest_change_wall_mm = s.farthest_change_wall_mm.max(wall_mm);
            }
            // The true distance: along the beam to the surface at the spot's centre.
            let beam = r_off.beam;
            let true_mm = beam.z_meas_at((spot - beam.origin_mm).norm() / beam.direction.norm());
            let (
                OpticalOutcome::Distance {
                    z_meas_mm: z_off, ..
                },
                OpticalOutcome::Distance {
                    z_meas_mm: z_on, ..
                },
            ) = (r_off.outcome, r_on.outcome)
            else {
                // The bounce never turns a peak into none or back: shading is the primary's.
                assert!(same, "{:?} vs {:?}", r_off.outcome, r_on.outcome);
                continue;
            };
            if z_on < z_off {
                s.changes_shorter += 1;
            }
            if (z_on - z_off).abs() > s.largest_change_mm {
                s.largest_change_mm = (z_on - z_off).abs();
                s.largest_change_wall_mm = wall_mm;
            }
            let (e_off, e_on) = (z_off - true_mm, z_on - true_mm);
            if near && e_off.abs() < ONE_FACE_ERROR_MM {
                s.max_error_near_off_mm = s.max_error_near_off_mm.max(e_off.abs());
                s.max_error_near_on_mm = s.max_error_near_on_mm.max(e_on.abs());
                sum_sq_off += e_off * e_off;
                sum_sq_on += e_on * e_on;
                with_distance += 1;
            }
            if !near {
                s.max_error_far_mm = s.max_error_far_mm.max(e_on.abs());
            }
        }
    }
    s.rms_near_off_mm = (sum_sq_off / with_distance as f64).sqrt();
    s.rms_near_on_mm = (sum_sq_on / with_distance as f64).sqrt();
    s.one_face_near = with_distance;
    s
}

fn print(label: &str, s: &EdgeStatistics) {
    println!(
        "{label}: {GRID} x {GRID} mirror positions over +-1.5 deg; {} spots within {NEAR_WALL_MM} mm of a stud wall, {} farther",
        s.near, s.far
    );
    println!(
        "  changed by the bounce: {} near, {} far (farthest change {:.3} mm from a wall; {} read shorter)",
        s.changed_near, s.changed_far, s.farthest_change_wall_mm, s.changes_shorter
    );
    println!(
        "  near a wall, {} spots wholly on one face: max |error| off {:.2} um, on {:.1} um; RMS off {:.2} um, on {:.2} um",
        s.one_face_near,
        1e3 * s.max_error_near_off_mm,
        1e3 * s.max_error_near_on_mm,
        1e3 * s.rms_near_off_mm,
        1e3 * s.rms_near_on_mm
    );
    println!(
        "  far from the walls: max |error| {:.2} um, off and on",
        1e3 * s.max_error_far_mm
    );
    println!(
        "  largest change {:.1} um, {:.3} mm from a wall",
        1e3 * s.largest_change_mm,
        s.largest_change_wall_mm
    );
}

#[test]
fn the_second_bounce_biases_distances_at_the_stud_walls_only() {
    let scene = fixture("duplo-2x4-130mm-multipath.json");
    let config = scene.optics.as_ref().unwrap().multiple_reflections;
    assert_eq!(
        config,
        Some(MultipathConfig {
            specular_share: 0.1
        })
    );
    let s = edge_statistics(&scene, &optics(&scene, config), &optics(&scene, None));
    print("duplo-2x4-130mm-multipath", &s);
    assert!(s.near > 1000 && s.far > s.near, "{s:?}");
    // Far from any wall: identical, bit for bit.
    assert_eq!(s.changed_far, 0, "{s:?}");
    // Near the walls: the bounce changes distances, and the errors against the true surface
    // grow by tens of micrometres (the ILD resolves 1.5 um).
    assert!(s.changed_near > 100, "{s:?}");
    assert!(s.one_face_near > 1000, "{s:?}");
    assert!(s.max_error_near_off_mm < 1e-3, "{s:?}");
    assert!(s.max_error_near_on_mm > 0.05, "{s:?}");
    assert!(s.rms_near_on_mm > 2.0 * s.rms_near_off_mm, "{s:?}");
    assert!(
        s.largest_change_mm > 0.05 && s.largest_change_mm < 0.5,
        "{s:?}"
    );
    // The secondary spot sits on the wall above the floor: the surface reads higher.
    assert_eq!(s.changes_shorter, s.changed_near, "{s:?}");
}

/// The same sweep with the bounce disabled (no specular share): nothing changes, so the
/// assertions above fail without the bounce.
#[test]
fn without_a_specular_share_nothing_changes() {
    let scene = fixture("duplo-2x4-130mm-multipath.json");
    let zero = Some(MultipathConfig {
        specular_share: 0.0,
    });
    let s = edge_statistics(&scene, &optics(&scene, zero), &optics(&scene, None));
    assert_eq!((s.changed_near, s.changed_far), (0, 0), "{s:?}");
    assert_eq!(s.max_error_near_on_mm, s.max_error_near_off_mm);
}

#[test]
fn the_plant_takes_the_option_from_the_scene() {
    let on = Plant::from_scene(&fixture("duplo-2x4-130mm-multipath.json")).unwrap();
    assert!(on.optics().unwrap().multiple_reflections());
    let off = Plant::from_scene(&fixture("duplo-2x4-130mm.json")).unwrap();
    assert!(!off.optics().unwrap().multiple_reflections());
    // The fixture is the Duplo scene with the option on, and nothing else changed.
    let (mut a, b) = (
        fixture("duplo-2x4-130mm-multipath.json"),
        fixture("duplo-2x4-130mm.json"),
    );
    a.optics.as_mut().unwrap().multiple_reflections = None;
    assert_eq!(
        (a.optics, a.surface, a.parts, a.sensor),
        (b.optics, b.surface, b.parts, b.sensor)
    );
}

#[test]
fn a_bad_specular_share_is_named() {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../fixtures/scenes/duplo-2x4-130mm-multipath.json"),
    )
    .unwrap()
    .replace("\"specular_share\": 0.1", "\"specular_share\": 1.5");
    let scene = Scene::from_json_str(&text, Path::new("bad.json")).unwrap();
    let err = Plant::from_scene(&scene).unwrap_err().to_string();
    assert!(err.contains("multiple_reflections.specular_share"), "{err}");
}
