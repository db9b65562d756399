//! Values that cannot run as meant are refused or warned about before the run, and an OS
//! error is said once: a trajectory at or above the loop's Nyquist frequency is refused
//! naming the field, the value and the limit; one whose planned drive saturates the
//! controller in most periods is warned about on stderr (and runs, as asked).

use std::path::Path;

use crate::util::{assert_success, fixture, number, report, run_scanhil};

/// test-loop-small with `trajectory` and `power` (absolute paths), written into `dir`.
fn scenario_with(dir: &Path, trajectory: serde_json::Value, power: serde_json::Value) -> String {
    let path = fixture("scenarios/test-loop-small.json");
    let mut scenario: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("the fixture")).expect("JSON");
    let folder = Path::new(&path).parent().expect("scenarios/").to_owned();
    for key in ["rig", "scene", "controller"] {
        let relative = scenario[key].as_str().expect("a path").to_owned();
        scenario[key] = folder.join(relative).display().to_string().into();
    }
    scenario["trajectory"] = trajectory;
    scenario["power"] = power;
    let file = dir.join("scenario.json");
    std::fs::write(&file, scenario.to_string()).expect("writing the scenario");
    file.display().to_string()
}

#[test]
fn a_trajectory_at_or_above_nyquist_is_refused_naming_field_value_and_limit() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let scenario = scenario_with(
        dir.path(),
        serde_json::json!({"kind": "sine", "frequency_hz": 1e7, "amplitude_rad": 0.01}),
        serde_json::json!({}),
    );
    let out = dir.path().join("out");
    let output = run_scanhil(&["scan", &scenario, "--out", out.to_str().expect("UTF-8")]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "{scenario}: field `trajectory.frequency_hz`: 10000000 Hz"
        )) && stderr.contains("10000 Hz, the Nyquist frequency of the 20000 Hz control rate"),
        "{stderr}"
    );
    assert!(!out.exists(), "refused before the output folder is made");
}

#[test]
fn a_trajectory_that_saturates_most_periods_is_warned_about_before_the_run() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    // 1 rad on both axes, run as written: the paper's mirror saturates almost always.
    let scenario = scenario_with(
        dir.path(),
        serde_json::json!({"kind": "lissajous", "alpha_hz": 52.0, "beta_hz": 27.0,
            "alpha_amplitude_rad": 1.0, "beta_amplitude_rad": 1.0}),
        serde_json::json!({"policy": "off"}),
    );
    let out = dir.path().join("out");
    let output = run_scanhil(&["scan", &scenario, "--out", out.to_str().expect("UTF-8")]);
    assert_success(&output, "a saturated scan runs as asked");
    let stderr = String::from_utf8_lossy(&output.stderr);
    let warning = stderr
        .lines()
        .find(|line| line.starts_with("warning: trajectory "))
        .unwrap_or_else(|| panic!("a saturation warning on stderr:\n{stderr}"));
    assert!(
        warning.contains("past its command limits") && warning.contains("% of the frame's"),
        "{warning}"
    );
    let report = report(&out);
    let planned = number(&report, "/periods/planned_saturated_share");
    let done = number(&report, "/periods/saturated") / number(&report, "/periods/done");
    assert!(
        planned > 0.9 && done > 0.9,
        "planned {planned}, done {done}"
    );
    assert!(
        warning.contains(&format!("{:.1} %", 100.0 * planned)),
        "the warning states the share in the report: {warning}"
    );
}

#[test]
fn an_os_error_is_said_once() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let scenario = fixture("scenarios/test-loop-small.json");
    let output = run_scanhil(&[
        "scan",
        &scenario,
        "--fsm",
        "slcan:/nonexistent/fsm",
        "--no-emulator",
        "--out",
        out.path().to_str().expect("UTF-8"),
    ]);
    assert_eq!(output.status.code(), Some(1));
    assert_eq!(
        String::from_utf8_lossy(&output.stderr),
        format!(
            "scanhil: error: scan {scenario}: cannot open slcan:/nonexistent/fsm: {}\n",
            std::io::Error::from_raw_os_error(2) // ENOENT
        )
    );
}
