//! `scanhil conformance --timing realtime`: a node on its own clock (no Step frames) is
//! checked by its readings' intervals, rate and counters, and by the same fault, malformed-
//! input and watchdog checks as in lockstep. The emulator in real time passes every check; each
//! deliberately non-conforming node (`serve --timing realtime --misbehave RULE`) fails exactly
//! the check(s) for its rule.
//!
//! The nodes run the Duplo scene at 2 736 Hz (the rate a 1 Mbit/s bus carries) with a watchdog
//! of 1 000 periods (365 ms): a debug build over ptys on a loaded machine stalls for tens of
//! milliseconds, which a 20 kHz node with a 2.5 ms watchdog would take for a silent host.

use crate::conformance::{
    Verdict, assert_only_the_drive_reached, conformance_of, misbehaving_node_verdict, served_node,
};
use crate::util::{assert_success, fixture, run_scanhil};

/// The mirror node's checks in real time, in the order conformance runs them.
const REALTIME_CHECKS: [&str; 9] = [
    "readings_on_time",
    "reading_rate",
    "angle_sequence_gapless",
    "angles_in_range",
    "status_frames",
    "over_current_fault",
    "survives_malformed_frames",
    "survives_garbage_slcan_lines",
    "link_timeout_fault",
];

/// The scene of the real-time nodes.
const SCENE: &str = "scenes/duplo-2x4-130mm-2736hz.json";
/// Their watchdog, periods.
const WATCHDOG_PERIODS: &str = "1000";

/// Conformance in real time against a node served in real time breaking `rule`.
fn realtime_conformance_against(rule: &str) -> Verdict {
    let scene = fixture(SCENE);
    misbehaving_node_verdict(
        rule,
        &REALTIME_CHECKS,
        &[
            "--timing",
            "realtime",
            "--scene",
            &scene,
            "--watchdog-periods",
            WATCHDOG_PERIODS,
        ],
        &[
            "--timing",
            "realtime",
            "--rate-hz",
            "2736",
            "--watchdog-periods",
            WATCHDOG_PERIODS,
        ],
    )
}

#[test]
fn the_emulator_in_real_time_passes_every_conformance_check() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let junit = out.path().join("conformance.xml");
    let output = run_scanhil(&[
        "conformance",
        "--fsm",
        "pty",
        "--sensor",
        "pty",
        "--scene",
        &fixture(SCENE),
        "--timing",
        "realtime",
        "--rate-hz",
        "2736",
        "--watchdog-periods",
        WATCHDOG_PERIODS,
        "--junit",
        junit.to_str().expect("UTF-8 path"),
    ]);
    assert_success(&output, "scanhil conformance --timing realtime");
    let table = String::from_utf8_lossy(&output.stdout);
    assert!(
        !table.contains("answers_in_time"),
        "a lockstep check: {table}"
    );
    let xml = std::fs::read_to_string(&junit).expect("JUnit XML written");
    assert!(xml.contains("tests=\"13\" failures=\"0\""), "{xml}");
    // Each check says what it measured.
    for (check, seen) in [
        ("readings_on_time", "2736 readings, intervals min "),
        ("readings_on_time", "all within the watchdog's 365.497 ms"),
        (
            "reading_rate",
            "from the declared 2736.00 Hz over 2736 readings (within 2 %)",
        ),
        ("angle_sequence_gapless", "none missed or out of sequence"),
        ("survives_garbage_slcan_lines", "still answering"),
        ("sensor_survives_bad_commands", "GETINFO still answered"),
        ("link_timeout_fault", "LinkTimeout fault after 3"),
    ] {
        let line = table.lines().find(|line| line.contains(check)).unwrap();
        assert!(
            line.contains("PASS") && line.contains(seen),
            "{seen}: {line}"
        );
    }
}

#[test]
fn a_node_stalling_past_its_watchdog_fails_on_time_only() {
    // Reading 1000 comes 1.5 watchdogs (548 ms) late and every later one keeps the delay:
    // late, but at the right rate and with no reading missed.
    realtime_conformance_against("late-answers").assert_fails_exactly(&[(
        "readings_on_time",
        &[
            "1 of 2736 readings late; first: reading 1000 came 5",
            "ms after the one before, beyond the watchdog's 365.497 ms",
        ],
    )]);
}

#[test]
fn a_node_on_a_slow_clock_fails_the_rate_check() {
    realtime_conformance_against("slow-clock").assert_fails_exactly(&[(
        "reading_rate",
        &[
            "the node reads at 26",
            "-4.7",
            "from the declared 2736.00 Hz",
            "beyond 2 %",
        ],
    )]);
}

#[test]
fn a_node_skipping_a_counter_misses_a_reading() {
    realtime_conformance_against("sequence-gaps").assert_fails_exactly(&[(
        "angle_sequence_gapless",
        &["1 missed", "first missed: reading 1000 never came"],
    )]);
}

#[test]
fn angles_out_of_range_or_frozen_fail_the_range_check_in_real_time() {
    realtime_conformance_against("out-of-range").assert_fails_exactly(&[(
        "angles_in_range",
        &["mrad, beyond the mirror's +-31.416 mrad"],
    )]);
    realtime_conformance_against("frozen-angles").assert_fails_exactly(&[(
        "angles_in_range",
        &["alpha swung 0.000 mrad, beta 0.000 mrad peak to peak"],
    )]);
}

#[test]
fn missing_fault_or_status_frames_fail_their_checks_in_real_time() {
    realtime_conformance_against("no-fault-frame").assert_fails_exactly(&[(
        "over_current_fault",
        &["no OverCurrent fault frame after 3 periods at 8 A"],
    )]);
    realtime_conformance_against("no-status-frame").assert_fails_exactly(&[(
        "status_frames",
        &["no Status frame from the node in 2736 periods"],
    )]);
}

#[test]
fn a_node_without_a_watchdog_fails_the_link_timeout_check_in_real_time() {
    realtime_conformance_against("no-watchdog").assert_fails_exactly(&[(
        "link_timeout_fault",
        &[
            "no LinkTimeout fault from the node within 730.99",
            "watchdog's 365.49",
        ],
    )]);
}

#[test]
fn a_node_dying_on_garbage_fails_in_real_time() {
    let verdict = realtime_conformance_against("dies-on-garbage");
    verdict.assert_fails_exactly(&[
        (
            "survives_garbage_slcan_lines",
            // Its BEL for the first line may or may not be out before it exits.
            &["unknown command `xyz`", "hung up"],
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
fn a_real_link_in_real_time_never_gets_more_than_the_drive_without_destructive() {
    // The node records every command it received: without --destructive nothing beyond the
    // 0.1 A real-time drive reaches it and no garbage line, and its watchdog ends the run at
    // zero.
    let scene = fixture(SCENE);
    let emulator = served_node(&[
        "--timing",
        "realtime",
        "--scene",
        &scene,
        "--watchdog-periods",
        WATCHDOG_PERIODS,
    ]);
    let (output, xml) = conformance_of(
        &emulator,
        &[
            "--timing",
            "realtime",
            "--rate-hz",
            "2736",
            "--watchdog-periods",
            WATCHDOG_PERIODS,
        ],
    );
    assert_success(
        &output,
        "scanhil conformance --timing realtime on a real link",
    );
    assert!(
        xml.contains("tests=\"9\" failures=\"0\" errors=\"0\" skipped=\"2\""),
        "{xml}"
    );
    assert_only_the_drive_reached(emulator, 0.1);
}
