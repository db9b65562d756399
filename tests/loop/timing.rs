//! Real time (statistics present and sane; nothing timed is asserted) and the bus-load
//! refusal before a run.

use crate::util::{fixture, number, report, run_scanhil};

#[test]
fn a_realtime_scan_reports_jitter_on_both_sides() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let output = run_scanhil(&[
        "scan",
        &fixture("scenarios/test-loop-small.json"),
        "--timing",
        "realtime",
        "--duration-s",
        "0.2",
        // A generous watchdog (0.5 s): a loaded CI machine may stall for milliseconds, and
        // this test is about the statistics, not about the watchdog (tested on its own).
        "--watchdog-periods",
        "10000",
        "--out",
        out.path().to_str().expect("UTF-8 path"),
    ]);
    // A loaded machine may miss deadlines: the scan may stop, but it reports either way.
    assert!(output.status.code().is_some(), "scanhil ended by a signal");
    assert!(
        out.path().join("report.json").is_file(),
        "no report; stderr:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let report = report(out.path());
    for side in [
        "/timing/controller/reading_interval",
        "/timing/emulator/period_jitter",
    ] {
        let min = number(&report, &format!("{side}/min_s"));
        let median = number(&report, &format!("{side}/median_s"));
        let p99 = number(&report, &format!("{side}/p99_s"));
        let max = number(&report, &format!("{side}/max_s"));
        assert!(
            0.0 <= min && min <= median && median <= p99 && p99 <= max,
            "{side}"
        );
        assert!(number(&report, &format!("{side}/periods")) > 0.0, "{side}");
        assert!(
            number(&report, &format!("{side}/overruns")) >= 0.0,
            "{side}"
        );
    }
    assert!(
        report
            .pointer("/timing/emulator/deadline_held")
            .is_some_and(|v| v.is_boolean())
    );
    assert!(number(&report, "/timing/controller/answer_latency/median_s") > 0.0);
}

#[test]
fn a_loop_that_cannot_fit_its_bit_rate_is_refused_with_the_numbers() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let output = run_scanhil(&[
        "scan",
        &fixture("scenarios/test-loop-small.json"),
        "--fsm",
        "socketcan:vcan0@1000000",
        "--out",
        out.path().to_str().expect("UTF-8 path"),
    ]);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("does not fit on socketcan:vcan0@1000000"),
        "{stderr}"
    );
    assert!(stderr.contains("1000 kbit/s"), "{stderr}");
    assert!(stderr.contains("CoilCommand 20000/s"), "{stderr}");
    assert!(
        !out.path().join("fsm.log").exists(),
        "refused before any link was opened"
    );
}
