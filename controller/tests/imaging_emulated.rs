//! Imaging through the emulator's optics and sensor: the paper's Duplo scene.

mod imaging_support;

use std::path::PathBuf;

use imaging_support::{
    STUD_HEIGHT_MM, lissajous, raster, reconstruct_succeeds, scanhil_reconstruct,
};
use scanhil_controller::imaging::emulated::EmulatedScanner;
use scanhil_controller::imaging::feature::FeatureParams;
use scanhil_controller::imaging::pipeline::{ImagingOptions, image_samples};
use scanhil_controller::imaging::progressive::ScanScene;
use scanhil_controller::imaging::recording::write_recording_csv;

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
        let f = imaging.feature.unwrap();
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
    let z = scanner.optics.z_meas_mm(0.0, 0.0).unwrap();
    assert!(z > 70.0 && z < 170.0, "{z}");
    assert_eq!(scanner.optics.true_z_mm(0.0, -10.0), Some(-120.0));
}

#[test]
fn scanhil_reconstruct_scores_a_recording_against_its_scene() {
    let path = scene("plane-120mm.json");
    let mut scanner = EmulatedScanner::from_scene_file(&path).unwrap();
    let samples = scanner.simulate_samples(lissajous, 0.1);
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("rec.csv");
    write_recording_csv(std::fs::File::create(&input).unwrap(), &samples).unwrap();
    let out = dir.path().join("out");
    let (stdout, report) = reconstruct_succeeds(
        scanhil_reconstruct(&input, &out)
            .args([
                "--model",
                "exact-reflection",
                "--pitch-mm",
                "0.3",
                "--truth-scene",
            ])
            .arg(&path),
        &out,
    );
    assert!(stdout.contains("against the true surface"), "{stdout}");
    let e = report.truth_error.unwrap();
    // A plane: only the sensor's 1.5 um noise and 1.6 um digits remain (exact model).
    assert!(e.covered_rms_mm.unwrap() < 0.005, "{e:?}");
    assert!(e.coverage_fraction > 0.3, "{e:?}");
}
