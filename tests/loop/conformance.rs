//! `scanhil conformance` against the emulator, and against deliberately non-conforming nodes
//! (`scanhil-emulator serve --misbehave RULE`), each failing exactly the check(s) for its rule
//! with the reason in the JUnit XML and what to look at on the bench; on a real link (a node
//! conformance did not start) without `--destructive`, no command beyond the amplifiers' limit
//! and no garbage line ever reaches the node; `--check`/`--skip` select the checks.

use std::time::Duration;

use crate::util::{ServedEmulator, assert_success, fixture, run_scanhil};

/// The mirror node's checks, in the order conformance runs them (SLCAN link, no sensor).
const FSM_CHECKS: [&str; 8] = [
    "answers_in_time",
    "angle_sequence_gapless",
    "angles_in_range",
    "status_frames",
    "over_current_fault",
    "survives_malformed_frames",
    "survives_garbage_slcan_lines",
    "link_timeout_fault",
];

/// The sensor's checks (on its ILD line).
const SENSOR_CHECKS: [&str; 4] = [
    "sensor_values_decode",
    "sensor_counter_gapless",
    "sensor_values_in_range",
    "sensor_survives_bad_commands",
];

#[test]
fn the_emulator_passes_every_conformance_check() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let junit = out.path().join("conformance.xml");
    let output = run_scanhil(&[
        "conformance",
        "--fsm",
        "pty",
        "--sensor",
        "pty",
        "--scene",
        &fixture("scenes/duplo-2x4-130mm.json"),
        "--junit",
        junit.to_str().expect("UTF-8 path"),
    ]);
    assert_success(&output, "scanhil conformance");
    let table = String::from_utf8_lossy(&output.stdout);
    for check in FSM_CHECKS.iter().chain(&SENSOR_CHECKS) {
        let line = table
            .lines()
            .find(|line| line.contains(check))
            .unwrap_or_else(|| panic!("{check} missing from:\n{table}"));
        assert!(line.contains("PASS"), "{line}");
    }
    let xml = std::fs::read_to_string(&junit).expect("JUnit XML written");
    assert!(xml.contains("tests=\"12\" failures=\"0\""), "{xml}");
    assert_eq!(xml.matches("<testcase ").count(), 12, "{xml}");
    // The checks say what they sent and that the device still answered (or moved).
    for (check, seen) in [
        ("survives_garbage_slcan_lines", "still answering"),
        ("sensor_survives_bad_commands", "GETINFO still answered"),
        ("angles_in_range", "peak to peak under 0.3 A sines"),
    ] {
        let line = table.lines().find(|line| line.contains(check)).unwrap();
        assert!(line.contains(seen), "{line}");
    }
}

/// What `scanhil conformance` made of a deliberately non-conforming node.
pub struct Verdict {
    /// The rule the node broke.
    rule: String,
    /// The mirror node's checks that ran, in order.
    checks: &'static [&'static str],
    /// `scanhil conformance`'s exit code.
    code: Option<i32>,
    /// The pass/fail table it printed.
    table: String,
    /// The JUnit XML it wrote.
    xml: String,
    /// The emulator's exit code once conformance was done (`None`: still running).
    pub emulator_code: Option<i32>,
}

/// A hand-started emulator's mirror node on an SLCAN pty, `extra` added to its arguments: the
/// Duplo scene and the watchdog of 50 periods of 10 ms conformance expects, unless `extra`
/// gives its own.
pub fn served_node(extra: &[&str]) -> ServedEmulator {
    let scene = fixture("scenes/duplo-2x4-130mm.json");
    let mut args = vec!["--fsm", "slcan:pty"];
    if !extra.contains(&"--scene") {
        args.extend(["--scene", &scene]);
    }
    if !extra.contains(&"--watchdog-periods") {
        args.extend(["--watchdog-periods", "50"]);
    }
    args.extend_from_slice(extra);
    ServedEmulator::start(&args)
}

/// Runs `scanhil conformance` on `emulator`'s mirror node (a real link to conformance: it did
/// not start the node) with `extra` arguments; returns its output and JUnit XML.
pub fn conformance_of(emulator: &ServedEmulator, extra: &[&str]) -> (std::process::Output, String) {
    let out = tempfile::tempdir().expect("a temporary folder");
    let junit = out.path().join("conformance.xml");
    let fsm = format!("slcan:{}", emulator.path("fsm"));
    let mut args = vec![
        "conformance",
        "--fsm",
        &fsm,
        "--junit",
        junit.to_str().expect("UTF-8 path"),
    ];
    if !extra.contains(&"--watchdog-periods") {
        args.extend(["--watchdog-periods", "50"]);
    }
    args.extend_from_slice(extra);
    let output = run_scanhil(&args);
    (output, std::fs::read_to_string(&junit).unwrap_or_default())
}

/// Runs `scanhil conformance --destructive` on the mirror node of a hand-started emulator
/// served with `--misbehave rule`.
fn conformance_against(rule: &str) -> Verdict {
    misbehaving_node_verdict(rule, &FSM_CHECKS, &[], &[])
}

/// Runs `scanhil conformance --destructive` with `conformance_args` on the mirror node of a
/// hand-started emulator served with `--misbehave rule` and `serve_args`; `checks` are the
/// mirror node's checks that run.
pub fn misbehaving_node_verdict(
    rule: &str,
    checks: &'static [&'static str],
    serve_args: &[&str],
    conformance_args: &[&str],
) -> Verdict {
    let mut serve = vec!["--misbehave", rule];
    serve.extend_from_slice(serve_args);
    let mut emulator = served_node(&serve);
    assert_eq!(emulator.ready["misbehave"], rule, "{}", emulator.ready);
    let mut args = vec!["--destructive"];
    args.extend_from_slice(conformance_args);
    let (output, xml) = conformance_of(&emulator, &args);
    let emulator_code = emulator
        .child
        .try_wait()
        .expect("asking after the emulator")
        .and_then(|status| status.code());
    drop(emulator);
    Verdict {
        rule: rule.to_owned(),
        checks,
        code: output.status.code(),
        table: String::from_utf8_lossy(&output.stdout).into_owned(),
        xml,
        emulator_code,
    }
}

impl Verdict {
    /// Asserts that exactly `failing` of the mirror node's checks failed (in the table, the
    /// JUnit XML and the exit code), every other one passed, and that each failure's JUnit
    /// message contains all of its `reasons`.
    pub fn assert_fails_exactly(&self, failing: &[(&str, &[&str])]) {
        let Verdict {
            rule, table, xml, ..
        } = self;
        assert_eq!(self.code, Some(1), "{rule}: conformance fails:\n{table}");
        for &check in self.checks {
            let line = table
                .lines()
                .find(|line| line.starts_with("fsm ") && line.contains(check))
                .unwrap_or_else(|| panic!("{rule}: {check} missing from:\n{table}"));
            let expected = if failing.iter().any(|(name, _)| *name == check) {
                "FAIL"
            } else {
                "PASS"
            };
            assert!(
                line.contains(expected),
                "{rule}: {check} should {expected}: {line}"
            );
        }
        assert_eq!(
            xml.matches("<testcase ").count(),
            self.checks.len(),
            "{xml}"
        );
        assert!(
            xml.contains(&format!("failures=\"{}\"", failing.len())),
            "{rule}: {xml}"
        );
        assert_eq!(xml.matches("<failure ").count(), failing.len(), "{xml}");
        for (check, reasons) in failing {
            assert!(
                table.contains(&format!("\non the bench, {check}: look at ")),
                "{rule}: {check}'s bench line missing from:\n{table}"
            );
            let message = failure_message(xml, check);
            for reason in *reasons {
                assert!(
                    message.contains(reason),
                    "{rule}: the {check} failure should say `{reason}`: {message}"
                );
            }
        }
    }
}

/// The `message` of `check`'s JUnit `failure` element (unescaped).
fn failure_message(xml: &str, check: &str) -> String {
    let case = xml
        .split("<testcase ")
        .find(|case| case.contains(&format!("name=\"{check}\"")))
        .unwrap_or_else(|| panic!("no testcase {check} in:\n{xml}"));
    let message = case
        .split_once("<failure message=\"")
        .and_then(|(_, rest)| rest.split_once('"'))
        .unwrap_or_else(|| panic!("no failure message for {check}: {case}"))
        .0;
    message
        .replace("&quot;", "\"")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&amp;", "&")
}

#[test]
fn a_node_without_a_watchdog_fails_the_link_timeout_check() {
    // A node that keeps its coils driven when the host goes silent.
    conformance_against("no-watchdog").assert_fails_exactly(&[(
        "link_timeout_fault",
        &[
            "no LinkTimeout fault from the node within 1s",
            "watchdog's 500ms",
        ],
    )]);
}

#[test]
fn a_node_answering_late_fails_the_timing_check() {
    // Period 1000 is answered after 750 ms, beyond the 500 ms allowance; its counter is right.
    conformance_against("late-answers").assert_fails_exactly(&[(
        "answers_in_time",
        &[
            "1 of 2500 answers late",
            "period 1000: AngleReading 7",
            "after its Step, beyond the watchdog's 500ms allowance",
        ],
    )]);
}

#[test]
fn a_node_skipping_a_counter_fails_the_sequence_check() {
    conformance_against("sequence-gaps").assert_fails_exactly(&[(
        "angle_sequence_gapless",
        &[
            "1500 of 2500 readings out of sequence",
            "period 1000: AngleReading counter 1001, expected 1000",
        ],
    )]);
}

#[test]
fn a_node_reporting_angles_out_of_range_fails_the_range_check() {
    // A hundred times the true angles: near zero at rest, beyond the mirror's range under the
    // drive (in real time too, where the drive is a third of lockstep's).
    conformance_against("out-of-range").assert_fails_exactly(&[(
        "angles_in_range",
        &["alpha", "mrad, beyond the mirror's +-31.416 mrad"],
    )]);
}

#[test]
fn a_node_with_frozen_angles_fails_the_range_check() {
    conformance_against("frozen-angles").assert_fails_exactly(&[(
        "angles_in_range",
        &[
            "alpha swung 0.000 mrad, beta 0.000 mrad peak to peak under 0.3 A sines",
            "at least 1.000 mrad each expected",
        ],
    )]);
}

#[test]
fn a_node_without_fault_frames_fails_the_over_current_check() {
    conformance_against("no-fault-frame").assert_fails_exactly(&[(
        "over_current_fault",
        &[
            "no OverCurrent fault frame after 3 periods at 8 A",
            "(one expected)",
        ],
    )]);
}

#[test]
fn a_node_without_status_frames_fails_the_status_check() {
    conformance_against("no-status-frame").assert_fails_exactly(&[(
        "status_frames",
        &["no Status frame from the node in 2500 periods"],
    )]);
}

#[test]
fn a_node_dying_on_garbage_fails_the_garbage_check_and_leaves_no_watchdog() {
    // It exits at the first frame after the garbage lines: the exchange after them fails, and
    // a node that is gone sends no LinkTimeout fault either.
    let verdict = conformance_against("dies-on-garbage");
    verdict.assert_fails_exactly(&[
        (
            "survives_garbage_slcan_lines",
            &[
                "unknown command `xyz`: BEL",
                "a 200-byte line: BEL; then the next exchange failed",
                "hung up",
            ],
        ),
        (
            "link_timeout_fault",
            &["the node hung up without a LinkTimeout fault"],
        ),
    ]);
    assert_eq!(
        verdict.emulator_code,
        Some(1),
        "the node died with an error"
    );
}

#[test]
fn a_slow_clock_is_refused_in_lockstep() {
    let output = std::process::Command::new(crate::util::emulator())
        .args(["serve", "--scene", &fixture("scenes/duplo-2x4-130mm.json")])
        .args(["--fsm", "slcan:pty", "--misbehave", "slow-clock"])
        .output()
        .expect("running scanhil-emulator");
    assert!(!output.status.success(), "refused");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("--misbehave: slow-clock needs --timing realtime"),
        "{stderr}"
    );
}

/// The rig's amplifier limit, A (fixtures/rigs/paper-bench.json).
fn amplifier_limit_a() -> f64 {
    let rig: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(fixture("rigs/paper-bench.json")).expect("the rig file"),
    )
    .expect("rig JSON");
    rig["mirror"]["amplifier_current_limit_a"]
        .as_f64()
        .expect("an amplifier limit")
}

/// After a conformance run without `--destructive` on `emulator`'s node: the last check
/// tripped its watchdog on purpose (it ended there, coils at zero), the largest coil command
/// it received was the drive's `drive_a` (nothing beyond the amplifier limit), and no garbage
/// SLCAN line reached it.
pub fn assert_only_the_drive_reached(emulator: ServedEmulator, drive_a: f64) {
    let (_, summary) = emulator.finish(Duration::from_secs(20));
    assert_eq!(summary["ended_by"], "watchdog", "{summary}");
    assert_eq!(
        summary["held_coil_currents_a"],
        serde_json::json!({"a": 0.0, "b": 0.0}),
        "{summary}"
    );
    let largest_a = summary["node"]["largest_command_a"].as_f64().unwrap();
    assert!(
        largest_a <= amplifier_limit_a() && (largest_a - drive_a).abs() < 0.01 * drive_a,
        "the {drive_a} A drive reached the node, nothing beyond {} A: {largest_a} A",
        amplifier_limit_a()
    );
    assert_eq!(summary["link"]["slcan_malformed_lines"], 0, "{summary}");
}

#[test]
fn a_real_link_without_destructive_never_commands_beyond_the_amplifier_limit() {
    // The node checks every command it received: the largest current any asked for, and the
    // garbage SLCAN lines that reached it.
    let emulator = served_node(&[]);
    let (output, xml) = conformance_of(&emulator, &[]);
    assert_success(&output, "scanhil conformance on a real link");
    assert_only_the_drive_reached(emulator, 0.3);
    let table = String::from_utf8_lossy(&output.stdout);
    for check in ["over_current_fault", "survives_garbage_slcan_lines"] {
        let line = table.lines().find(|line| line.contains(check)).unwrap();
        assert!(
            line.contains("SKIP") && line.contains("not run on a real link without --destructive"),
            "{line}"
        );
    }
    assert!(
        table.contains("8 checks, 6 passed, 0 failed, 2 skipped"),
        "{table}"
    );
    assert!(
        xml.contains("failures=\"0\" errors=\"0\" skipped=\"2\""),
        "{xml}"
    );
    assert_eq!(xml.matches("<skipped message=").count(), 2, "{xml}");
    // With --destructive the same node is told 8 A and sent garbage (the check can fail).
    let emulator = served_node(&[]);
    let (output, _) = conformance_of(&emulator, &["--destructive"]);
    assert_success(&output, "scanhil conformance --destructive");
    let (_, summary) = emulator.finish(Duration::from_secs(20));
    assert_eq!(summary["node"]["largest_command_a"], 8.0, "{summary}");
    assert!(summary["link"]["slcan_malformed_lines"].as_u64().unwrap() > 0);
}

#[test]
fn check_and_skip_select_the_checks_and_the_session_still_ends_at_zero() {
    let emulator = served_node(&[]);
    let (output, xml) = conformance_of(
        &emulator,
        &[
            "--check",
            "angles_in_range",
            "--check",
            "status_frames",
            "--check",
            "link_timeout_fault",
            "--skip",
            "link_timeout_fault",
        ],
    );
    assert_success(&output, "scanhil conformance --check --skip");
    let table = String::from_utf8_lossy(&output.stdout);
    let rows: Vec<&str> = table
        .lines()
        .filter(|line| line.starts_with("fsm "))
        .collect();
    assert_eq!(rows.len(), 2, "{table}");
    assert!(rows[0].contains("angles_in_range") && rows[1].contains("status_frames"));
    assert_eq!(xml.matches("<testcase ").count(), 2, "{xml}");
    // No watchdog check: the session ends with the zero command the node acknowledges.
    let (code, summary) = emulator.finish(Duration::from_secs(20));
    assert_eq!(code, Some(0), "{summary}");
    assert_eq!(summary["outcome"], "finished", "{summary}");
    assert_eq!(summary["final_state"], "ready", "{summary}");
    assert_eq!(
        summary["held_coil_currents_a"],
        serde_json::json!({"a": 0.0, "b": 0.0}),
        "{summary}"
    );
}

#[test]
fn an_unknown_or_unsafe_check_is_refused_before_any_link_opens() {
    // The link does not exist: a refusal naming the flag comes before any attempt to open it.
    for (args, expected) in [
        (
            vec!["--check", "frob"],
            "--check: no conformance check `frob` (the checks: answers_in_time,",
        ),
        (
            vec!["--check", "over_current_fault"],
            "`over_current_fault` can harm a real bench and runs on one only with --destructive",
        ),
    ] {
        let mut all = vec!["conformance", "--fsm", "slcan:/nonexistent/tty"];
        all.extend(args);
        let output = run_scanhil(&all);
        assert!(!output.status.success());
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(stderr.contains(expected), "{stderr}");
        assert!(!stderr.contains("nonexistent"), "{stderr}");
    }
}

#[test]
fn a_conformance_run_interrupted_keeps_its_results_and_says_it_ended_early() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let junit = out.path().join("conformance.xml");
    // The link-timeout check waits out 200 answer allowances of silence (2 s): the signal
    // comes during it, once the checks before it are in the JUnit file.
    let child = std::process::Command::new(crate::util::scanhil())
        .args([
            "conformance",
            "--fsm",
            "pty",
            "--scene",
            &fixture("scenes/loop-fast.json"),
            "--watchdog-periods",
            "200",
            "--junit",
            junit.to_str().expect("UTF-8 path"),
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("starting scanhil");
    let started = std::time::Instant::now();
    while !std::fs::read_to_string(&junit)
        .is_ok_and(|xml| xml.contains("survives_garbage_slcan_lines"))
    {
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "the checks before the link timeout never reached the JUnit file"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    crate::util::signal(child.id(), "INT");
    let output = crate::util::exits_within(child, Duration::from_secs(30), "conformance");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert_eq!(output.status.code(), Some(1), "{stdout}");
    let xml = std::fs::read_to_string(&junit).expect("JUnit XML written");
    for written in [&*stdout, &xml] {
        assert!(written.contains("run_ended_early"), "{written}");
        assert!(written.contains("interrupted by SIGINT"), "{written}");
        assert!(
            written.contains("survives_garbage_slcan_lines"),
            "{written}"
        );
        assert!(!written.contains("link_timeout_fault"), "{written}");
    }
}

/// The emulator conformance starts gets the watchdog and answer allowance conformance was
/// given: its LinkTimeout comes after their product of silence, not the defaults'.
#[test]
fn an_emulated_node_keeps_the_watchdog_conformance_was_given() {
    let output = run_scanhil(&[
        "conformance",
        "--fsm",
        "pty",
        "--scene",
        &fixture("scenes/duplo-2x4-130mm.json"),
        "--answer-allowance-s",
        "0.02",
        "--watchdog-periods",
        "60",
        "--check",
        "link_timeout_fault",
    ]);
    assert_success(&output, "scanhil conformance --answer-allowance-s 0.02");
    let table = String::from_utf8_lossy(&output.stdout);
    let row = table
        .lines()
        .find(|line| line.contains("link_timeout_fault"))
        .unwrap_or_else(|| panic!("no row in:\n{table}"));
    // "LinkTimeout fault after 1.21s of silence": 60 periods of 20 ms, not 50 of 10 ms.
    let silence_s: f64 = row
        .split("after ")
        .nth(1)
        .and_then(|rest| rest.split("s of silence").next())
        .and_then(|seconds| seconds.parse().ok())
        .unwrap_or_else(|| panic!("no silence in {row}"));
    assert!((1.2..2.4).contains(&silence_s), "{row}");
}
