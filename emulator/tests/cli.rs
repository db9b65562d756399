//! The `step` and `precision` commands as a user runs them: output, JSON shape, and errors.

mod support;

use std::path::PathBuf;

use support::{emulator, fixture};

fn temp_path(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!(
        "scanhil-emulator-cli-{}-{name}",
        std::process::id()
    ))
}

#[test]
fn step_json_reports_parts_and_the_delayed_response_on_the_chosen_axis() {
    let scene = fixture("loop-fast.json");
    let out = emulator(&[
        "step",
        "--scene",
        &scene,
        "--axis",
        "x",
        "--amplitude",
        "0.2",
        "--samples",
        "50",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["axis"], "beta");
    assert_eq!(
        report["active_parts"],
        serde_json::json!(["axes", "cross_talk"])
    );
    let costed: Vec<&str> = report["parts"]["parts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["part"].as_str().unwrap())
        .collect();
    assert_eq!(costed, ["axes", "cross_talk"]);
    let samples = report["samples"].as_array().unwrap();
    assert_eq!(samples.len(), 50);
    assert_eq!(samples[0]["true_angles_rad"]["beta"], 0.0);
    let beta = samples[49]["true_angles_rad"]["beta"].as_f64().unwrap();
    let alpha = samples[49]["true_angles_rad"]["alpha"].as_f64().unwrap();
    assert!(beta > 0.0);
    // Cross-talk: the other axis moves about 20 dB less.
    assert!(
        (alpha / beta).abs() > 0.05 && (alpha / beta).abs() < 0.2,
        "{alpha} {beta}"
    );
}

#[test]
fn step_table_names_the_active_parts() {
    let out = emulator(&[
        "step",
        "--scene",
        &fixture("step-alpha.json"),
        "--samples",
        "3",
    ]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("active parts: [axes]"), "{text}");
    assert!(
        text.lines().nth(1).is_some_and(
            |line| line.starts_with("part costs, us per period") && line.contains("axes ")
        ),
        "{text}"
    );
    assert_eq!(text.lines().count(), 3 + 3);
}

#[test]
fn bad_axis_and_unstable_integrator_fail_with_a_clear_message() {
    let out = emulator(&[
        "step",
        "--scene",
        &fixture("step-alpha.json"),
        "--axis",
        "z",
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("alpha|beta"));

    let scene = temp_path("rk4.json");
    std::fs::write(
        &scene,
        r#"{"name": "rk4", "parts": ["axes", "amplifier"], "integrator": {"method": "rk4"}}"#,
    )
    .unwrap();
    let out = emulator(&["step", "--scene", scene.to_str().unwrap()]);
    std::fs::remove_file(&scene).ok();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("rk4") && err.contains("5e-5") && err.contains("eigenvalue"),
        "{err}"
    );
}

#[test]
fn precision_json_and_plot() {
    let plot = temp_path("wp.svg");
    let out = emulator(&[
        "precision",
        "--json",
        "--duration-s",
        "0.005",
        "--max-substeps",
        "4",
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let rows = report["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 4 * 3);
    let refused: Vec<_> = rows
        .iter()
        .filter(|r| !r["refused"].is_null())
        .map(|r| {
            (
                r["method"].as_str().unwrap(),
                r["substeps"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(refused, [("rk4", 1), ("explicit_euler", 1)]);
    let svg = std::fs::read_to_string(&plot).unwrap();
    std::fs::remove_file(&plot).ok();
    assert!(svg.contains("<svg") && svg.contains("trapezoid"));
}

#[test]
fn step_refuses_a_response_too_long_to_hold() {
    let scene = fixture("scenes/loop-fast.json");
    for samples in ["0", "10000000"] {
        let out = emulator(&["step", "--scene", &scene, "--samples", samples]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{samples}: {stderr}");
        assert!(stderr.contains(&format!("--samples {samples}")), "{stderr}");
    }
}

#[test]
fn serve_refuses_timing_values_it_cannot_run_before_its_ready_line() {
    let scene = fixture("loop-fast.json");
    for (flags, message) in [
        (
            &["--lockstep-answer-allowance-s", "1e300"][..],
            "--lockstep-answer-allowance-s: 1e300 s is not within (0, 60] s",
        ),
        (
            &["--lockstep-answer-allowance-s", "nan"],
            "--lockstep-answer-allowance-s: NaN s is not within (0, 60] s",
        ),
        (
            &["--lockstep-answer-allowance-s", "-1"],
            "--lockstep-answer-allowance-s: -1 s is not within (0, 60] s",
        ),
        (
            &["--watchdog-periods", "0"],
            "--watchdog-periods: 0 periods is not within [1, 100000000] periods",
        ),
        (
            &[
                "--watchdog-periods",
                "100000000",
                "--lockstep-answer-allowance-s",
                "1",
            ],
            "--watchdog-periods: 100000000 periods of 1 s wait 100000000 s in all",
        ),
        (
            &["--heartbeat-hz", "0"],
            "--heartbeat-hz: 0 Hz is not within (0, 20000] Hz",
        ),
        (
            &["--timing", "realtime", "--duration-s", "nan"],
            "--duration-s: NaN s is not within (0, 3600] s",
        ),
        (
            &["--probe-s", "100"],
            "--probe-s: 100 s is not within [0, 60] s",
        ),
    ] {
        let mut args = vec!["serve", "--scene", &scene, "--fsm", "slcan:pty"];
        args.extend_from_slice(flags);
        let out = emulator(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{flags:?}: {stderr}");
        assert!(stderr.contains(message), "{flags:?}: {stderr}");
        assert!(out.stdout.is_empty(), "no ready line: {flags:?}");
    }
}
