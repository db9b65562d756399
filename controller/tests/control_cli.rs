//! `scanhil analyze`, `identify`, `design` and `trajectory` as a user runs them, and numbers on
//! the command line.

use std::path::{Path, PathBuf};
use std::process::Command;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/controllers")
        .join(name)
}

fn scanhil(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_scanhil"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn analyze_reports_json_and_plots_the_bode_diagram() {
    let dir = tempfile::tempdir().unwrap();
    let plot = dir.path().join("t.svg");
    let out = scanhil(&[
        "analyze",
        "--controller",
        fixture("dual-tone-exact-tones.json").to_str().unwrap(),
        "--json",
        "--at",
        "27,52",
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["nominal_loop"]["stable"], true);
    assert_eq!(json["discrete"]["sections"].as_array().unwrap().len(), 4);
    let at = json["nominal_loop"]["at"].as_array().unwrap();
    assert_eq!(at.len(), 2);
    assert!(at[0]["magnitude_db"].as_f64().unwrap().abs() < 0.2);
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.contains("magnitude") && svg.contains("phase"));
}

#[test]
fn analyze_of_an_unstable_choice_says_so_and_fails() {
    let out = scanhil(&[
        "analyze",
        "--controller",
        fixture("dual-tone-forward-euler.json").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(3));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("refused") && text.contains("-1.035"),
        "{text}"
    );
}

#[test]
fn analyze_names_a_missing_file() {
    let out = scanhil(&["analyze", "--controller", "no/such.json"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no/such.json"));
}

#[test]
fn trajectory_prints_the_derived_figures() {
    let out = scanhil(&[
        "trajectory",
        "--lissajous",
        "52,27",
        "--range-mm",
        "11.5,18.5",
    ]);
    assert!(out.status.success());
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let mm = json["figures"]["resolution_mm"].as_f64().unwrap();
    assert!((mm - 1.07).abs() < 0.01, "{mm}");
    let out = scanhil(&["trajectory", "--raster", "2"]);
    assert!(!out.status.success());
}

#[test]
fn a_negative_number_is_a_value_for_every_numeric_flag() {
    // A phase of -90 degrees is a trajectory like any other.
    let out = scanhil(&["trajectory", "--lissajous", "52,27", "--phase-deg", "-90"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["figures"]["kind"], "lissajous");
    // A list starting with a minus is a value too (once "unexpected argument '-5'"), and
    // reaches the trajectory's own check, which names the flag.
    for (flag, list, message) in [
        (
            "--lissajous",
            "-52,27",
            "--lissajous: -52 Hz must be positive and finite",
        ),
        (
            "--raster",
            "-2,34",
            "--raster: -2 Hz must be positive and finite",
        ),
        (
            "--range-mm",
            "-11.5,18.5",
            "--range-mm: -11.5 mm must be positive and finite",
        ),
    ] {
        let mut args = vec!["trajectory", flag, list];
        if flag == "--range-mm" {
            args.extend(["--lissajous", "52,27"]);
        }
        let out = scanhil(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains(message), "{stderr}");
    }
    // From a file, the file and the field are named.
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("t.json");
    std::fs::write(
        &file,
        r#"{"kind": "lissajous", "alpha_hz": -52.0, "beta_hz": 27.0}"#,
    )
    .unwrap();
    let file = file.to_str().unwrap();
    let out = scanhil(&["trajectory", "--file", file]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "{file}: field `trajectory.alpha_hz`: -52 Hz must be positive"
        )),
        "{stderr}"
    );
    // An override that cannot run reaches the scenario's validation, which names the flag.
    let scenario =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenarios/test-loop-small.json");
    let dir = tempfile::tempdir().unwrap();
    let out = scanhil(&[
        "scan",
        scenario.to_str().unwrap(),
        "--duration-s",
        "-1",
        "--out",
        dir.path().join("out").to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("scanhil: error: --duration-s: -1 s is not within (0, 3600] s"),
        "{stderr}"
    );
    // An integer flag says its value is out of range, naming the flag.
    let out = scanhil(&[
        "scan",
        scenario.to_str().unwrap(),
        "--watchdog-periods",
        "-1",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("invalid value '-1' for '--watchdog-periods"),
        "{stderr}"
    );
}

#[test]
fn identify_writes_json_with_coherence() {
    let dir = tempfile::tempdir().unwrap();
    let out_file = dir.path().join("fr.json");
    let out = scanhil(&[
        "identify",
        "--plant",
        "nominal",
        "--from-hz",
        "10",
        "--to-hz",
        "100",
        "--points",
        "3",
        "--out",
        out_file.to_str().unwrap(),
        "--plot",
        dir.path().join("fr.png").to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&out_file).unwrap()).unwrap();
    let points = json["points"].as_array().unwrap();
    assert_eq!(points.len(), 3);
    assert!(
        points
            .iter()
            .all(|p| p["measured"]["coherence"].as_f64().unwrap() > 0.999)
    );
    assert!(dir.path().join("fr.png").exists());
}

/// The `value` of the estimate `name` of `axis` in an identify result.
fn estimate(result: &serde_json::Value, axis: &str, name: &str) -> f64 {
    result["fit"]["axes"]
        .as_array()
        .and_then(|axes| axes.iter().find(|a| a["axis"] == axis))
        .and_then(|fit| fit["estimates"].as_array())
        .and_then(|e| e.iter().find(|e| e["name"] == name))
        .and_then(|e| e["value"].as_f64())
        .unwrap_or_else(|| panic!("no estimate {name} of {axis} in {result:#}"))
}

#[test]
fn identify_fit_recovers_eq_4_and_writes_a_scene_and_rig_design_reads() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).display().to_string();
    let rig = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/rigs/paper-mirror-only.json");
    let out = scanhil(&[
        "identify",
        "--plant",
        "nominal",
        "--fit",
        "--rate-hz",
        "10000",
        "--points",
        "10",
        "--settle-s",
        "4",
        "--cycles",
        "1",
        "--blocks",
        "2",
        "--out",
        &path("fit.json"),
        "--write-scene",
        &path("twin.json"),
        "--rig",
        rig.to_str().unwrap(),
        "--write-rig",
        &path("rig.json"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The summary on stdout when the JSON goes to a file.
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.starts_with("fit alpha: Eq4: dc_gain 1.14"),
        "{stdout}"
    );
    let result: serde_json::Value =
        serde_json::from_slice(&std::fs::read(path("fit.json")).unwrap()).unwrap();
    for axis in ["alpha", "beta"] {
        for (name, want) in [
            ("dc_gain", 11.4),
            ("natural_freq_rad_s", 140.68),
            ("damping_ratio", 3.21e-2),
            ("delay_s", 1e-4),
        ] {
            let got = estimate(&result, axis, name);
            assert!((got / want - 1.0).abs() < 1e-3, "{axis} {name}: {got}");
        }
    }
    // The in-process plant is uncoupled: no cross-talk part.
    let scene: serde_json::Value =
        serde_json::from_slice(&std::fs::read(path("twin.json")).unwrap()).unwrap();
    assert_eq!(scene["parts"], serde_json::json!(["axes"]));
    assert_eq!(scene["control_rate_hz"], 10000.0);
    assert_eq!(scene["mirror"]["beta"]["delay_s"], 1e-4);
    let rig: serde_json::Value =
        serde_json::from_slice(&std::fs::read(path("rig.json")).unwrap()).unwrap();
    assert_eq!(rig["control_rate_hz"], 10000.0);
    assert_eq!(rig["name"], "paper-mirror-only");
    // `scanhil design` takes the written scene as its plant and the written rig.
    let out = scanhil(&[
        "design",
        "--rig",
        &path("rig.json"),
        "--plant",
        &path("twin.json"),
        "--kind",
        "pid",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let design: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(design["design"]["rate_hz"], 10000.0, "{design:#}");
    let source = design["design"]["plant_source"].as_str().unwrap();
    assert!(
        source.ends_with("twin.json: the scene's mirror"),
        "{source}"
    );
}

#[test]
fn identify_refuses_what_it_cannot_do_before_it_runs() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nothing-here");
    for (args, expected) in [
        (
            vec!["--record", missing.to_str().unwrap()],
            "--record keeps the frames of a link: give --fsm",
        ),
        (
            vec!["--fit", "--mode", "closed-loop"],
            "--fit fits the open-loop plant: --mode open-loop",
        ),
        (vec!["--from", missing.to_str().unwrap()], "identify.json"),
        (vec!["--fit", "--write-rig", "r.json"], "--rig"),
    ] {
        let mut all = vec!["identify"];
        all.extend(&args);
        let out = scanhil(&all);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} ran");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
    }
    assert!(!missing.exists(), "nothing is created by a refused run");
}

#[test]
fn conformance_refuses_rates_and_allowances_that_cannot_run_instead_of_panicking() {
    for (flag, value) in [
        ("--rate-hz", "0"),
        ("--rate-hz", "nan"),
        ("--rate-hz", "1e300"),
        ("--answer-allowance-s", "0"),
        ("--answer-allowance-s", "1e300"),
        ("--watchdog-periods", "0"),
    ] {
        let out = scanhil(&["conformance", "--fsm", "slcan:/nonexistent", flag, value]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{flag} {value}: {stderr}");
        assert!(
            stderr.contains(&format!("error: {flag}: ")),
            "{flag} {value}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

#[test]
fn conformance_in_real_time_refuses_the_lockstep_allowance_and_a_too_long_watchdog() {
    // In real time the allowance is one period: a lockstep allowance given is refused, and the
    // watchdog is checked in periods of --rate-hz (5e4 periods at 0.5 Hz is over a day; of
    // lockstep's 0.01 s it would be 500 s).
    for (extra, flag, reason) in [
        (
            ["--answer-allowance-s", "0.01"],
            "--answer-allowance-s",
            "applies to --timing lockstep only",
        ),
        (
            ["--watchdog-periods", "50000"],
            "--watchdog-periods",
            "50000 periods of 2 s wait 100000 s in all, more than 86400 s",
        ),
    ] {
        let mut args = vec![
            "conformance",
            "--fsm",
            "slcan:/nonexistent",
            "--timing",
            "realtime",
            "--rate-hz",
            "0.5",
        ];
        args.extend(extra);
        let out = scanhil(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains(&format!("error: {flag}: ")) && stderr.contains(reason),
            "{stderr}"
        );
        assert!(
            !stderr.contains("nonexistent"),
            "refused before the link opens: {stderr}"
        );
    }
}

#[test]
fn a_closed_pipe_on_stdout_ends_the_program_quietly_not_with_a_panic() {
    use std::os::unix::process::ExitStatusExt;
    for args in [
        vec![
            "analyze",
            "--controller",
            fixture("pid-series.json").to_str().unwrap(),
        ],
        vec!["trajectory", "--lissajous", "52,27"],
    ] {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let out = Command::new(env!("CARGO_BIN_EXE_scanhil"))
            .args(&args)
            .stdout(writer)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        // Ended by SIGPIPE like any filter (13), or done before writing: never a panic's 101.
        assert!(
            out.status.signal() == Some(13) || out.status.success(),
            "{args:?}: {:?} {stderr}",
            out.status
        );
    }
}

#[test]
fn analyze_refuses_a_comparison_too_long_to_run() {
    for duration in ["1e9", "inf", "0.5"] {
        let out = scanhil(&[
            "analyze",
            "--controller",
            fixture("pid-series.json").to_str().unwrap(),
            "--compare-methods",
            "--compare-duration-s",
            duration,
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{duration}: {stderr}");
        assert!(stderr.contains("--compare-duration-s"), "{stderr}");
    }
}

#[test]
fn design_writes_a_controller_that_loads_or_refuses_with_exit_1() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("designed.json");
    let rigs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/rigs");
    let design = |rig: &str, extra: &[&str]| {
        let rig = rigs.join(rig);
        let mut args = vec!["design", "--rig", rig.to_str().unwrap(), "--rate-hz", "bus"];
        args.extend(extra);
        scanhil(&args)
    };
    let run = design(
        "paper-bench-1mbit.json",
        &[
            "--kind",
            "dual-tone",
            "--json",
            "--out",
            out.to_str().unwrap(),
        ],
    );
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(json["design"]["rate_hz"], 2736.0);
    assert!(json["reach"]["dual_tone"]["drive_hz"].is_array());
    let written = scanhil_controller::settings::ControllerSettings::load(&out).unwrap();
    written
        .build()
        .expect("the written controller loads and is stable");
    assert_eq!(written.control_rate_hz, 2736.0);

    let never = dir.path().join("never.json");
    let refused = design(
        "paper-bench-1mbit.json",
        &[
            "--kind",
            "pid",
            "--crossover-hz",
            "211",
            "--out",
            never.to_str().unwrap(),
        ],
    );
    assert_eq!(refused.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        stderr.contains("below the 45 deg asked") && stderr.contains("poles"),
        "{stderr}"
    );
    assert!(!never.exists());

    let no_bus = design("paper-bench.json", &["--kind", "dual-tone"]);
    assert_eq!(no_bus.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&no_bus.stderr).contains("states no `bus`"));
}
