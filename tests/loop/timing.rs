//! Real time: the statistics add up (structural facts that can fail; nothing is timed against
//! the wall clock), a short stall of the emulator under a tight watchdog completes every
//! planned period, a long stall of the host trips the watchdogs with the coils at zero; and
//! the bus-load refusal before a run.

use std::time::Duration;

use crate::util::{
    ServedEmulator, assert_coils_at_zero, assert_ran_every_period, decode_candump, fixture, number,
    realtime_scan_args, recording_grows, report, run_scanhil, scan_against_served_emulator, signal,
};

/// Asserts what must hold of one [`PeriodStats`] block at `side` in `report`, whatever the
/// machine's load: ordered and positive figures, `intervals` measured values.
fn assert_stats_add_up(report: &serde_json::Value, side: &str, intervals: f64) {
    let min = number(report, &format!("{side}/min_s"));
    let median = number(report, &format!("{side}/median_s"));
    let p99 = number(report, &format!("{side}/p99_s"));
    let max = number(report, &format!("{side}/max_s"));
    assert!(
        0.0 < min && min <= median && median <= p99 && p99 <= max,
        "{side}: min {min} median {median} p99 {p99} max {max}"
    );
    assert_eq!(
        number(report, &format!("{side}/periods")),
        intervals,
        "{side}: measured values"
    );
    let above = number(report, &format!("{side}/above_nominal"));
    assert!(above <= intervals, "{side}");
    assert_eq!(
        above > 0.0,
        max > number(report, &format!("{side}/nominal_s")),
        "{side}: values above the period exist exactly when max is above it"
    );
}

#[test]
fn a_realtime_scan_completes_and_its_timing_figures_add_up() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let args = realtime_scan_args(out.path(), "0.2", &[]);
    let output = run_scanhil(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let report = assert_ran_every_period(&output, out.path());
    assert_coils_at_zero(&report);
    let planned = 4000.0; // 0.2 s at 20 kHz
    // Controller: every planned period was either answered or counted missed; the reading
    // intervals are one fewer than the readings; a late answer is exactly an answer slower
    // than one period in the same latencies.
    let answered = number(&report, "/timing/controller/answer_latency/periods");
    let missed = number(&report, "/timing/controller/missed_readings");
    assert_eq!(answered + missed, planned, "answered + missed = planned");
    assert_stats_add_up(&report, "/timing/controller/answer_latency", answered);
    assert_stats_add_up(
        &report,
        "/timing/controller/reading_interval",
        answered - 1.0,
    );
    assert_eq!(
        number(&report, "/timing/controller/answer_latency/overruns"),
        number(&report, "/timing/controller/answer_latency/above_nominal"),
        "overruns counted = latencies above one period"
    );
    // Emulator: one tick per planned period, one interval fewer; overruns and stale periods
    // are among the ticks; deadline_held only when nothing was late.
    let summary = &report["emulator"]["summary"];
    assert_eq!(number(summary, "/node/periods"), planned, "{summary}");
    assert_stats_add_up(&report, "/timing/emulator/period_jitter", planned - 1.0);
    let overruns = number(&report, "/timing/emulator/period_jitter/overruns");
    let stale = number(&report, "/timing/emulator/stale_command_periods");
    assert!(
        overruns <= planned && stale <= planned,
        "{}",
        report["timing"]
    );
    let held = report["timing"]["emulator"]["deadline_held"]
        .as_bool()
        .expect("deadline_held is a boolean");
    assert!(
        !held || (overruns == 0.0 && stale <= 1.0),
        "{}",
        report["timing"]
    );
}

/// A real-time emulator with a watchdog of `watchdog_periods` periods, and a `scanhil scan`
/// of `duration_s` against it whose own watchdog is `host_watchdog_periods` periods (in real
/// time both are periods of 50 us). Returns both once the scan has recorded `bytes` of
/// `fsm.log`.
fn realtime_run(
    watchdog_periods: u32,
    host_watchdog_periods: u32,
    duration_s: f64,
    bytes: u64,
) -> (ServedEmulator, std::process::Child, tempfile::TempDir) {
    let periods = watchdog_periods.to_string();
    let out = tempfile::tempdir().expect("a temporary folder");
    let (emulator, mut child) = scan_against_served_emulator(
        out.path(),
        &["--timing", "realtime", "--watchdog-periods", &periods],
        &[
            "--timing",
            "realtime",
            "--duration-s",
            &duration_s.to_string(),
            "--watchdog-periods",
            &host_watchdog_periods.to_string(),
        ],
    );
    if recording_grows(out.path(), bytes) {
        return (emulator, child, out);
    }
    let _ = child.kill();
    let _ = child.wait();
    panic!("the real-time scan never recorded {bytes} bytes");
}

#[test]
fn a_short_emulator_stall_under_a_tight_watchdog_completes_every_period() {
    // The emulator's watchdog: 1000 periods (50 ms); the host's 10 000 (0.5 s). The emulator
    // freezes for 150 ms (3000 periods) mid-run; the host was never silent (its answers wait
    // in the pty), so the catch-up ticks must read them and the run completes. Before the fix
    // the catch-up never read the link and the node's watchdog fired on a host that had
    // answered everything.
    let (emulator, child, out) = realtime_run(1000, 10_000, 1.0, 200_000);
    signal(emulator.child.id(), "STOP");
    std::thread::sleep(Duration::from_millis(150));
    signal(emulator.child.id(), "CONT");
    let output = child.wait_with_output().expect("waiting for scanhil");
    let (code, summary) = emulator.finish(Duration::from_secs(30));
    assert_eq!(code, Some(0), "{summary}");
    assert_eq!(summary["outcome"], "finished", "{summary}");
    let report = assert_ran_every_period(&output, out.path());
    let answered = number(&report, "/timing/controller/answer_latency/periods");
    let missed = number(&report, "/timing/controller/missed_readings");
    assert_eq!(answered + missed, 20_000.0, "every planned period");
    // The stall happened inside the run: one of the node's tick intervals spans it.
    assert!(
        number(&summary, "/timing/period_jitter/max_s") >= 0.15,
        "{summary}"
    );
}

#[test]
fn a_long_host_stall_trips_the_watchdogs_with_coils_at_zero() {
    // The host freezes for 1 s under 1000-period (50 ms) watchdogs on both sides: the node
    // zeroes its coils and reports a LinkTimeout; the host, resumed, stops on a link timeout
    // (its own or the node's), commands zero and exits 3.
    let (emulator, child, out) = realtime_run(1000, 1000, 10.0, 200_000);
    signal(child.id(), "STOP");
    std::thread::sleep(Duration::from_secs(1));
    signal(child.id(), "CONT");
    let output = child.wait_with_output().expect("waiting for scanhil");
    let (code, summary) = emulator.finish(Duration::from_secs(30));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(3), "stderr:\n{stderr}");
    assert!(
        stderr.contains("link timeout") || stderr.contains("reported LinkTimeout"),
        "{stderr}"
    );
    assert_eq!(code, Some(3), "{summary}");
    assert_eq!(summary["outcome"], "link_timeout", "{summary}");
    assert_eq!(summary["final_state"], "fault", "{summary}");
    assert_eq!(summary["held_coil_currents_a"]["a"], 0.0, "{summary}");
    assert_eq!(summary["held_coil_currents_a"]["b"], 0.0, "{summary}");
    let report = report(out.path());
    assert_eq!(report["outcome"]["complete"], false);
    let recording = decode_candump(&out.path().join("fsm.log"));
    assert!(recording.angle_seqs.len() > 100, "the loop ran before");
    assert!(
        recording
            .last_command_a
            .is_some_and(|last| last.a == 0.0 && last.b == 0.0),
        "the host's last command is zero: {:?}",
        recording.last_command_a
    );
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
