//! The `probe` command as a user runs it: JSON shape, and errors that name what is wrong.

mod support;

use support::{emulator, fixture};

#[test]
fn probe_json_on_the_plane_reports_spot_truth_and_raw_value() {
    let scene = fixture("protocol-only.json");
    let out = emulator(&[
        "probe",
        "--scene",
        &scene,
        "--d-alpha",
        "-1.5",
        "--d-beta",
        "0.5",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("probe JSON");
    assert_eq!(report["surface"], "plane");
    assert_eq!(report["model"], "exact_reflection");
    assert_eq!(report["true_height_mm"], -120.0);
    let spot_z = report["spot_mm"][2].as_f64().unwrap();
    assert!((spot_z + 120.0).abs() < 1e-9);
    // Negative alpha moves the spot towards +y from the resting -10 mm.
    assert!(report["spot_mm"][1].as_f64().unwrap() > -10.0);
    let raw = report["sensor"]["raw"].as_u64().unwrap();
    let distance = report["sensor"]["distance_mm"].as_f64().unwrap();
    let truth = report["optics"]["true_distance_mm"].as_f64().unwrap();
    // Noise-free scene: the raw value is the true distance rounded to one step (1.557 um).
    assert!((distance - truth).abs() <= 0.78e-3, "{distance} vs {truth}");
    assert!(raw > 643 && raw < 64_876);
    let z = report["sensor"]["reconstructed_mm"][2].as_f64().unwrap();
    assert!((z + 120.0).abs() < 1e-3, "{z}");
}

#[test]
fn probe_reports_the_spot_s_intensity_and_the_receiver_s_verdict_on_it() {
    // Without `receiver_intensity` every spot counts as 1; with it, the realistic sensor's
    // Duplo top at rest sends its matte share plus its gloss lobe's, and a black finish
    // (reflectance 0.001, no gloss) is too dark for the receiver.
    let probe = |scene: &str| {
        let out = emulator(&[
            "probe",
            "--scene",
            scene,
            "--d-alpha",
            "0",
            "--d-beta",
            "0",
            "--json",
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice::<serde_json::Value>(&out.stdout).expect("probe JSON")
    };
    let plain = probe(&fixture("duplo-2x4-130mm.json"));
    assert_eq!(plain["optics"]["intensity"], 1.0);
    let realistic_path = fixture("duplo-2x4-130mm-realistic-sensor.json");
    let realistic = probe(&realistic_path);
    let intensity = realistic["optics"]["intensity"].as_f64().unwrap();
    // Matte alone: 0.5 cos(view) (120 / 140)^2 = 0.36; the gloss adds about as much again.
    assert!((0.4..1.5).contains(&intensity), "{intensity}");
    assert!(realistic["sensor"]["distance_mm"].as_f64().is_some());

    let dir = tempfile::tempdir().unwrap();
    let mut scene: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&realistic_path).unwrap()).unwrap();
    scene["surface_finish"] = serde_json::json!({ "reflectance": 0.001 });
    let black = dir.path().join("black.json");
    std::fs::write(&black, scene.to_string()).unwrap();
    let dark = probe(black.to_str().unwrap());
    assert!(dark["optics"]["intensity"].as_f64().unwrap() < 0.01);
    assert_eq!(dark["sensor"]["error"], "no_peak");
}

#[test]
fn probe_text_names_a_shaded_position_as_an_error() {
    let scene = fixture("step-3mm.json");
    // Sweep until the wall shades the spot; the text then says no_peak, never a distance.
    let shaded = (0..=60)
        .map(|k| format!("{:.3}", -1.5 + 0.05 * f64::from(k)))
        .map(|alpha| {
            emulator(&[
                "probe",
                "--scene",
                &scene,
                "--d-alpha",
                &alpha,
                "--d-beta",
                "0",
            ])
        })
        .map(|out| String::from_utf8(out.stdout).unwrap())
        .find(|text| text.contains("shaded"))
        .expect("a shaded position on the step");
    assert!(
        shaded.contains("error no_peak") && shaded.contains("raw 262076"),
        "{shaded}"
    );
}

#[test]
fn bad_input_is_refused_with_its_name_and_a_failure_exit() {
    let missing = emulator(&[
        "probe",
        "--scene",
        "no/such/scene.json",
        "--d-alpha",
        "0",
        "--d-beta",
        "0",
    ]);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("no/such/scene.json"));
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bad.json");
    std::fs::write(
        &scene,
        r#"{"name": "bad", "parts": ["optics"], "surface": {"kind": "sphere", "radius_mm": -2.0, "center_distance_mm": 100.0}}"#,
    )
    .unwrap();
    let out = emulator(&[
        "probe",
        "--scene",
        scene.to_str().unwrap(),
        "--d-alpha",
        "0",
        "--d-beta",
        "0",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("radius_mm") && err.contains("bad"), "{err}");
}
