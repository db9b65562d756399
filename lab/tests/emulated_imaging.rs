//! Imaging through the emulator's optics and sensor: the paper's Duplo scene.

#[path = "../../controller/tests/imaging_support/mod.rs"]
mod imaging_support;

use std::path::PathBuf;

use imaging_support::{STUD_HEIGHT_MM, lissajous, raster};
use scanhil_controller::imaging::feature::FeatureParams;
use scanhil_controller::imaging::pipeline::{ImagingOptions, image_samples};
use scanhil_controller::imaging::progressive::ScanScene;
use scanhil_lab::emulated_imaging::EmulatedScanner;

fn scene(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/scenes")
        .join(name)
}

#[test]
fn the_duplo_stud_measures_its_height_from_both_trajectories() {
    for (name, angles) in [
        ("lissajous", lissajous as imaging_support::Angles),
        ("raster", raster),
    ] {
        let mut scanner = EmulatedScanner::from_scene_file(&scene("duplo-2x4-130mm.json")).unwrap();
        let samples = scanner.simulate_samples(angles, 0.3);
        assert_eq!(samples.len(), 6_000, "{name}");
        let imaging = image_samples(
            &samples,
            &ImagingOptions {
                feature: Some(FeatureParams::default()),
                ..ImagingOptions::default()
            },
        )
        .unwrap();
        let f = imaging.feature.unwrap().unwrap();
        eprintln!(
            "{name}: {:.4} mm std {:.4} mm n {} missing {} plane tilt {:.4} deg",
            f.height_mm,
            f.std_mm,
            f.points,
            imaging.reconstruction.missing_samples,
            f.plane.plane.tilt_rad().to_degrees()
        );
        assert!((f.height_mm - STUD_HEIGHT_MM).abs() < 0.05, "{name}: {f:?}");
        assert!(f.std_mm < 0.2, "{name}: {f:?}");
        // The stud's walls shade some samples: missing points, not wrong distances.
        assert!(imaging.reconstruction.missing_samples > 0, "{name}");
    }
}

#[test]
fn optics_is_a_scan_scene_with_ground_truth() {
    let scanner = EmulatedScanner::from_scene_file(&scene("plane-120mm.json")).unwrap();
    let z = scanner.z_meas_mm(0.0, 0.0).unwrap();
    assert!(z > 70.0 && z < 170.0, "{z}");
    assert_eq!(scanner.true_z_mm(0.0, -10.0), Some(-120.0));
}
