//! Values that cannot run as meant are refused or warned about before the run, and an OS
//! error is said once: a trajectory at or above the loop's Nyquist frequency is refused
//! naming the field, the value and the limit; one whose planned drive saturates the
//! controller in most periods is warned about on stderr (and runs, as asked).

use std::path::Path;

use crate::util::{fixture, number, report, run_scanhil};

/// test-loop-small with `trajectory` and `power` (absolute paths), written into `dir`.
fn scenario_with(dir: &Path, trajectory: serde_json::Value, power: serde_json::Value) -> String {
    edited_scenario(dir, "test-loop-small", |scenario| {
        scenario["trajectory"] = trajectory;
        scenario["power"] = power;
    })
}

/// The fixture scenario `name` (its paths made absolute) changed by `edit`, written into `dir`.
pub fn edited_scenario(
    dir: &Path,
    name: &str,
    edit: impl FnOnce(&mut serde_json::Value),
) -> String {
    let path = fixture(&format!("scenarios/{name}.json"));
    let mut scenario: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("the fixture")).expect("JSON");
    let folder = Path::new(&path).parent().expect("scenarios/").to_owned();
    for key in ["rig", "scene", "controller", "truth"] {
        if let Some(relative) = scenario[key].as_str() {
            scenario[key] = folder.join(relative).display().to_string().into();
        }
    }
    edit(&mut scenario);
    let file = dir.join("scenario.json");
    std::fs::write(&file, scenario.to_string()).expect("writing the scenario");
    file.display().to_string()
}

/// Runs `scanhil` with `args` and asserts it exits 1 with `message` on stderr before `out`
/// exists (nothing written, nothing opened).
fn refused_before_any_output(args: &[&str], out: &Path, message: &str) {
    let output = run_scanhil(args);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{args:?}: {stderr}");
    assert!(stderr.contains(message), "{args:?}: {stderr}");
    assert!(
        !out.exists(),
        "{args:?}: refused before the output folder is made"
    );
}

#[test]
fn timing_values_no_end_can_run_are_refused_by_the_host_naming_file_field_or_flag() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let out = dir.path().join("out");
    let out_arg = out.to_str().expect("UTF-8");
    let scenario = edited_scenario(dir.path(), "test-loop-small", |scenario| {
        scenario["timing"]["lockstep_answer_allowance_s"] = 1e300.into();
    });
    let message = format!(
        "{scenario}: field `timing.lockstep_answer_allowance_s`: 1e300 s is not within (0, 60] s"
    );
    refused_before_any_output(&["scan", &scenario, "--out", out_arg], &out, &message);
    // Without an emulator the host itself once panicked on it (exit 101).
    refused_before_any_output(
        &[
            "scan",
            &scenario,
            "--no-emulator",
            "--fsm",
            "slcan:/nonexistent",
            "--out",
            out_arg,
        ],
        &out,
        &message,
    );
    let small = fixture("scenarios/test-loop-small.json");
    refused_before_any_output(
        &["scan", &small, "--watchdog-periods", "0", "--out", out_arg],
        &out,
        "--watchdog-periods: 0 periods is not within [1, 100000000] periods",
    );
    refused_before_any_output(
        &[
            "conformance",
            "--fsm",
            "pty",
            "--scene",
            &fixture("scenes/loop-fast.json"),
            "--answer-allowance-s",
            "1e300",
        ],
        &out,
        "--answer-allowance-s: 1e300 s is not within (0, 60] s",
    );
}

#[test]
fn imaging_and_calibration_values_no_machine_can_hold_are_refused_before_the_loop() {
    // Once found after the whole loop, with no report.json and no field named (1e-5 mm), or
    // run for 220 s into 9.9 GB of memory and a 2.79 GB height map (0.0013 mm).
    let dir = tempfile::tempdir().expect("a temporary folder");
    let out = dir.path().join("out");
    let out_arg = out.to_str().expect("UTF-8");
    for pitch in ["1e-5", "0.0013"] {
        let scenario = edited_scenario(dir.path(), "test-duplo-stud", |scenario| {
            scenario["imaging"]["pitch_mm"] = pitch.parse::<f64>().expect("a number").into();
        });
        refused_before_any_output(
            &["scan", &scenario, "--out", out_arg],
            &out,
            &format!(
                "{scenario}: field `imaging.pitch_mm`: {pitch} mm makes a height map of about"
            ),
        );
    }
    let rig_path = dir.path().join("rig.json");
    let mut rig: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(fixture("rigs/paper-bench.json")).expect("the rig"),
    )
    .expect("JSON");
    rig["scanner"]["calibration"]["distance_offset_mm"] = 1e300.into();
    std::fs::write(&rig_path, rig.to_string()).expect("writing the rig");
    let scenario = edited_scenario(dir.path(), "test-duplo-stud", |scenario| {
        scenario["rig"] = rig_path.display().to_string().into();
    });
    refused_before_any_output(
        &["scan", &scenario, "--out", out_arg],
        &out,
        &format!(
            "{}: field `scanner.calibration.distance_offset_mm`: 1e300 mm is not within \
             [-1000, 1000] mm",
            rig_path.display()
        ),
    );
}

#[test]
fn faults_that_could_never_fire_are_refused_naming_the_field() {
    // Once accepted silently: a period beyond the run, an AngleReading fault on the host's
    // direction, sensor faults on a rig without a sensor.
    let dir = tempfile::tempdir().expect("a temporary folder");
    let out = dir.path().join("out");
    let out_arg = out.to_str().expect("UTF-8");
    let beyond = edited_scenario(dir.path(), "test-loop-small", |scenario| {
        scenario["faults"] = serde_json::json!({
            "node_to_host": {"at": [{"period": 2000, "fault": "drop"}]}
        });
    });
    refused_before_any_output(
        &["scan", &beyond, "--out", out_arg],
        &out,
        &format!(
            "{beyond}: field `faults.node_to_host.at[0].period`: period 2000 is beyond the \
             run's 2000 periods"
        ),
    );
    let small = fixture("scenarios/test-loop-small.json");
    refused_before_any_output(
        &[
            "scan",
            &small,
            "--fault",
            r#"host_to_node.at=[{"period":5,"fault":"drop","message":"AngleReading"}]"#,
            "--out",
            out_arg,
        ],
        &out,
        "`AngleReading` is sent by the Fsm and never travels this way",
    );
    let no_sensor = edited_scenario(dir.path(), "test-loop-small", |scenario| {
        scenario["faults"] = serde_json::json!({
            "sensor": {"laser_off": [{"from_s": 0.01, "to_s": 0.02}]}
        });
    });
    refused_before_any_output(
        &["scan", &no_sensor, "--out", out_arg],
        &out,
        &format!("{no_sensor}: field `faults.sensor`: the rig has no sensor"),
    );
}

#[test]
fn the_report_says_the_emulator_ran_when_a_pty_link_started_it_despite_no_emulator() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let out = dir.path().join("out");
    let small = fixture("scenarios/test-loop-small.json");
    let output = run_scanhil(&[
        "scan",
        &small,
        "--no-emulator",
        "--duration-s",
        "0.01",
        "--out",
        out.to_str().expect("UTF-8"),
    ]);
    assert_eq!(
        output.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let report = report(&out);
    assert_eq!(report["scenario"]["links"]["spawn_emulator"], true);
    assert!(report["emulator"].is_object(), "the emulator's summary");
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
    // It runs as asked, every period, and its verdict says the loop did not track (exit 4).
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(4), "{stderr}");
    assert!(
        stderr.contains(
            "the scan completed but its result is not valid: the loop does not track on alpha"
        ),
        "{stderr}"
    );
    let warning = stderr
        .lines()
        .find(|line| line.starts_with("warning: trajectory "))
        .unwrap_or_else(|| panic!("a saturation warning on stderr:\n{stderr}"));
    assert!(
        warning.contains("past its command limits") && warning.contains("% of the frame's"),
        "{warning}"
    );
    let report = report(&out);
    assert_eq!(
        report["outcome"]["verdict"], "failed",
        "{}",
        report["outcome"]
    );
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
