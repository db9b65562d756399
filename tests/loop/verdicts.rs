//! Verdicts: a scan that ran every period but did not do what it was asked exits 4 with its
//! reasons in `report.json` `outcome` and on stderr (issue 20, defect 3): no period in the
//! frame, a reference scaled to nothing, a plant far from the host's model, a sensor whose
//! samples never pair. A scene without dynamics is complete, saying what was not judged.

use std::path::Path;

use crate::bad_input::edited_scenario;
use crate::util::{fixture, report, run_scanhil};

/// Runs `scanhil scan SCENARIO` into `dir/out`; returns the exit status, stderr and report.
fn scan(dir: &Path, scenario: &str) -> (Option<i32>, String, serde_json::Value) {
    let out = dir.join("out");
    let output = run_scanhil(&["scan", scenario, "--out", out.to_str().expect("UTF-8")]);
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    (output.status.code(), stderr, report(&out))
}

/// Asserts a failed verdict: exit 4, `outcome` failed and not complete, every reason in
/// `reasons` among the report's and on stderr.
fn assert_failed(scanned: &(Option<i32>, String, serde_json::Value), reasons: &[&str]) {
    let (code, stderr, report) = scanned;
    let outcome = &report["outcome"];
    assert_eq!(*code, Some(4), "{stderr}");
    assert_eq!(outcome["verdict"], "failed", "{outcome}");
    assert_eq!(outcome["complete"], false, "{outcome}");
    assert_eq!(outcome["stopped_by"], serde_json::Value::Null, "{outcome}");
    let listed = outcome["reasons"].as_array().expect("reasons");
    assert_eq!(listed.len(), reasons.len(), "{outcome}");
    for (reason, expected) in listed.iter().zip(reasons) {
        let reason = reason.as_str().expect("a reason");
        assert!(reason.contains(expected), "{expected:?} in {outcome}");
        assert!(stderr.contains(reason), "{reason:?} on stderr:\n{stderr}");
    }
    assert!(
        stderr.contains("scanhil: the scan completed but its result is not valid: "),
        "{stderr}"
    );
}

#[test]
fn a_run_of_no_period_or_of_a_reference_scaled_to_nothing_fails() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let scenario = edited_scenario(dir.path(), "test-loop-small", |scenario| {
        scenario["duration_s"] = 1e-9.into();
    });
    let scanned = scan(dir.path(), &scenario);
    assert_failed(&scanned, &["the recorded frame has no period"]);
    assert_eq!(scanned.2["periods"]["done"], 0);

    let dir = tempfile::tempdir().expect("a temporary folder");
    let scenario = edited_scenario(dir.path(), "test-loop-small", |scenario| {
        scenario["duration_s"] = 0.02.into();
        scenario["trajectory"]["alpha_amplitude_rad"] = 1e300.into();
        scenario["trajectory"]["beta_amplitude_rad"] = 1e300.into();
    });
    let scanned = scan(dir.path(), &scenario);
    assert_failed(&scanned, &["the reference does not move the mirror"]);
    assert_eq!(scanned.2["periods"]["done"], 400);
}

#[test]
fn a_plant_far_from_the_hosts_model_fails_its_tracking_limit_on_each_axis() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    // The paper's mirror with a natural frequency 21 times the host's nominal one.
    let scene = dir.path().join("far.json");
    let text = serde_json::json!({"name": "far", "control_rate_hz": 20000.0, "seed": 1,
        "parts": ["axes", "cross_talk"], "mirror": {"natural_freq_rad_s": 3000.0}});
    std::fs::write(&scene, text.to_string()).expect("writing the scene");
    let scenario = edited_scenario(dir.path(), "test-loop-small", |scenario| {
        scenario["duration_s"] = 0.02.into();
        scenario["scene"] = scene.display().to_string().into();
    });
    let scanned = scan(dir.path(), &scenario);
    assert_failed(
        &scanned,
        &[
            "the loop does not track on alpha",
            "the loop does not track on beta",
        ],
    );
    let limits = &scanned.2["outcome"]["tracking_limits"];
    assert_eq!(limits[1]["axis"], "beta", "{limits}");
    assert!(
        limits[1]["measured"].as_f64() > limits[1]["limit"].as_f64(),
        "{limits}"
    );
}

#[test]
fn a_scene_without_dynamics_is_complete_and_says_what_was_not_judged() {
    // The protocol-only scene: the mirror holds still (it once reported 70.7 % tracking against
    // a predicted 0.70 %).
    let dir = tempfile::tempdir().expect("a temporary folder");
    let scenario = edited_scenario(dir.path(), "test-loop-small", |scenario| {
        scenario["duration_s"] = 0.02.into();
        scenario["scene"] = fixture("scenes/protocol-only.json").into();
    });
    let out = dir.path().join("out");
    let output = run_scanhil(&["scan", &scenario, "--out", out.to_str().expect("UTF-8")]);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert_eq!(output.status.code(), Some(0), "{stdout}");
    let report = report(&out);
    let outcome = &report["outcome"];
    assert_eq!(outcome["verdict"], "complete", "{outcome}");
    assert_eq!(outcome["complete"], true, "{outcome}");
    assert_eq!(
        outcome["tracking_limits"],
        serde_json::json!([]),
        "{outcome}"
    );
    assert!(
        outcome["notes"][0]
            .as_str()
            .is_some_and(|note| note.contains("no dynamics")),
        "{outcome}"
    );
    assert!(
        report["predicted_tracking_error"].is_null(),
        "no prediction where none applies: {}",
        report["predicted_tracking_error"]
    );
    assert!(
        stdout.contains("(predicted -)") && stdout.contains("note: the emulated scene has no"),
        "{stdout}"
    );
}

#[test]
fn a_sensor_whose_samples_never_pair_fails() {
    // vcan-small over ptys (the whole plant, a sensor on its own line), its sensor's noise or
    // clock out of all reason: no point is imaged.
    for (sensor, reason) in [
        (
            serde_json::json!({"noise_rms_um": 1e300}),
            "none of the sensor's 1000 samples paired",
        ),
        (
            serde_json::json!({"clock_offset_s": 1e9}),
            "the sensor sent no sample",
        ),
    ] {
        let dir = tempfile::tempdir().expect("a temporary folder");
        let mut scene: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(fixture("scenes/step-3mm.json")).expect("the scene"),
        )
        .expect("JSON");
        scene["sensor"] = sensor;
        let scene_path = dir.path().join("scene.json");
        std::fs::write(&scene_path, scene.to_string()).expect("writing the scene");
        let scenario = edited_scenario(dir.path(), "vcan-small", |scenario| {
            scenario["scene"] = scene_path.display().to_string().into();
            scenario["links"] = serde_json::json!({"fsm": "pty", "sensor": "pty"});
        });
        let scanned = scan(dir.path(), &scenario);
        assert_failed(&scanned, &[reason]);
    }
}
