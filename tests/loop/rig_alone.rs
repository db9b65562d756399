//! The host alone: a scan of devices `scanhil` did not start needs only a rig description and
//! a scenario without a scene (the technician's case; the devices here are an emulator started
//! by hand on its own ptys), and an emulated scene that disagrees with the rig is refused
//! before the loop starts.

use std::path::Path;

use crate::util::{ServedEmulator, assert_success, fixture, number, report, run_scanhil};

/// Writes a scenario file into `dir` with `fields` (JSON members, already formatted) and the
/// test-duplo-stud trajectory, controller and imaging.
fn write_scenario(dir: &Path, fields: &str) -> String {
    let path = dir.join("scenario.json");
    let text = format!(
        r#"{{
  "name": "rig-alone",
  {fields},
  "controller": "{controller}",
  "trajectory": {{ "kind": "lissajous", "alpha_hz": 52.0, "beta_hz": 27.0, "alpha_amplitude_rad": 0.015 }},
  "duration_s": 0.05,
  "seed": 7,
  "timing": {{ "mode": "lockstep", "watchdog_periods": 200, "lockstep_answer_allowance_s": 0.05 }},
  "imaging": {{ "pitch_mm": 0.1, "reconstruction": "exact_reflection", "progressive_steps": 4 }}
}}"#,
        controller = fixture("controllers/pid-series.json"),
    );
    std::fs::write(&path, text).expect("writing the scenario");
    path.display().to_string()
}

#[test]
fn a_scan_of_devices_it_did_not_start_needs_a_rig_and_no_scene() {
    let emulator = ServedEmulator::start(&[
        "--scene",
        &fixture("scenes/plane-120mm.json"),
        "--seed",
        "7",
        "--fsm",
        "slcan:pty",
        "--sensor",
        "ild:pty",
    ]);
    let dir = tempfile::tempdir().expect("a temporary folder");
    let links = format!(
        r#""rig": "{rig}",
  "truth": "{truth}",
  "links": {{ "fsm": "slcan:{fsm}", "sensor": "ild:{sensor}", "spawn_emulator": false }}"#,
        rig = fixture("rigs/paper-bench.json"),
        truth = fixture("scenes/plane-120mm.json"),
        fsm = emulator.path("fsm"),
        sensor = emulator.path("sensor"),
    );
    let scenario = write_scenario(dir.path(), &links);
    let out = dir.path().join("out");
    let output = run_scanhil(&["scan", &scenario, "--out", out.to_str().expect("UTF-8")]);
    assert_success(&output, "scanhil scan against hand-started devices");
    let report = report(&out);
    assert!(
        report["scenario"]["scene"].is_null(),
        "{}",
        report["scenario"]
    );
    assert_eq!(report["rig"]["name"], "paper-bench");
    assert!(report["emulator"].is_null(), "no emulator was started here");
    assert_eq!(report["outcome"]["complete"], true);
    // The plane scored against the truth the scenario named: noise-level error.
    let median = number(&report, "/imaging/truth_error/covered_median_abs_mm");
    assert!(median < 0.01, "median |error| {median} mm against a plane");
    assert!(number(&report, "/imaging/points") > 500.0);
    for file in [
        "points.ply",
        "height_map.png",
        "progressive.svg",
        "fsm.log",
        "sensor.ild",
    ] {
        assert!(out.join(file).exists(), "{file} written");
    }
}

/// Runs a scan of `scene` on the paper bench's rig; returns its exit code, stderr and whether
/// a report was written.
fn scan_on_the_paper_bench(scene: &str) -> (Option<i32>, String, bool) {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let fields = format!(
        r#""rig": "{rig}",
  "scene": "{scene}""#,
        rig = fixture("rigs/paper-bench.json"),
    );
    let scenario = write_scenario(dir.path(), &fields);
    let out = dir.path().join("out");
    let output = run_scanhil(&["scan", &scenario, "--out", out.to_str().expect("UTF-8")]);
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
        out.join("report.json").exists(),
    )
}

#[test]
fn an_emulated_sensor_at_another_rate_than_the_rigs_is_refused_naming_both() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let text = std::fs::read_to_string(fixture("scenes/plane-120mm.json")).expect("the scene");
    let scene = dir.path().join("plane-10khz.json");
    let changed = text.replace(
        "\"measuring_rate_hz\": 20000.0",
        "\"measuring_rate_hz\": 10000.0",
    );
    assert_ne!(changed, text, "the fixture states its sensor rate");
    std::fs::write(&scene, changed).expect("writing the scene");
    let (code, stderr, reported) = scan_on_the_paper_bench(scene.to_str().expect("UTF-8"));
    assert_eq!(code, Some(1), "refused before the loop: {stderr}");
    assert!(
        stderr.contains("plane-10khz.json")
            && stderr.contains("10000 Hz")
            && stderr.contains("20000 Hz"),
        "the refusal names the scene and both rates: {stderr}"
    );
    assert!(!reported, "no scan ran");
}

#[test]
fn an_emulated_scene_without_the_rigs_sensor_is_refused_before_the_loop() {
    let (code, stderr, reported) = scan_on_the_paper_bench(&fixture("scenes/loop-fast.json"));
    assert_eq!(code, Some(1), "refused before the loop: {stderr}");
    assert!(
        stderr.contains("loop-fast") && stderr.contains("no `sensor` part"),
        "the refusal names the scene and the sensor: {stderr}"
    );
    assert!(!reported, "no scan ran");
}

#[test]
fn a_scenario_for_emulated_devices_without_a_scene_is_refused_by_field() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let fields = format!(r#""rig": "{}""#, fixture("rigs/paper-bench.json"));
    let scenario = write_scenario(dir.path(), &fields);
    let output = run_scanhil(&["scan", &scenario, "--out", "unused"]);
    assert_eq!(output.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("scenario.json") && stderr.contains("field `scene`"),
        "{stderr}"
    );
}
