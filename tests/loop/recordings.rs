//! Recordings a technician's tools read: `--record-epoch` and `--record-iface` stamp `fsm.log`
//! with Unix times inside the run's wall-clock window and the given interface name, and
//! `scanhil decode` reads it.

use std::time::{SystemTime, UNIX_EPOCH};

use scanhil_protocol::candump::{Timestamp, parse_line};

use crate::util::{assert_success, fixture, report, run_scanhil};

/// The test scenario's control period, s (20 kHz).
const PERIOD_S: f64 = 50e-6;

fn now() -> Timestamp {
    let since = SystemTime::now().duration_since(UNIX_EPOCH).unwrap();
    Timestamp {
        secs: since.as_secs(),
        nanos: since.subsec_nanos(),
    }
}

#[test]
fn an_epoch_recording_on_can0_is_stamped_within_the_run_and_decodes() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let out_dir = out.path().to_str().expect("UTF-8 path");
    let before = now();
    let output = run_scanhil(&[
        "scan",
        &fixture("scenarios/test-duplo-stud.json"),
        "--duration-s",
        "0.02",
        "--lead-in-s",
        "0.01",
        "--record-epoch",
        "--record-iface",
        "can0",
        "--out",
        out_dir,
    ]);
    let after = now();
    assert_success(&output, "scanhil scan --record-epoch --record-iface can0");
    let log = out.path().join("fsm.log");
    let text = std::fs::read_to_string(&log).expect("fsm.log");
    let entries: Vec<_> = text
        .lines()
        .map(|line| parse_line(line).unwrap_or_else(|e| panic!("{line}: {e}")))
        .collect();
    assert!(entries.len() > 1000, "{} lines", entries.len());
    let first = entries[0].timestamp;
    let last = entries[entries.len() - 1].timestamp;
    assert!(
        before <= first && last <= after,
        "stamps {first:?}..{last:?} outside the run {before:?}..{after:?}"
    );
    for pair in entries.windows(2) {
        let step_s = pair[1].timestamp.as_secs_f64() - pair[0].timestamp.as_secs_f64();
        let periods = step_s / PERIOD_S;
        // Loop time in whole periods, printed to the microsecond.
        assert!(
            step_s >= 0.0 && (periods - periods.round()).abs() * PERIOD_S <= 1.5e-6,
            "{} then {}",
            pair[0],
            pair[1]
        );
    }
    // The stamps span the loop's periods (lead-in and frame), the first at period 0; the
    // closing zero command comes at most a period after the last.
    let periods = report(out.path())["periods"]["done"]
        .as_u64()
        .expect("periods done");
    let span_us = (last.secs - first.secs) * 1_000_000 + u64::from(last.nanos / 1000)
        - u64::from(first.nanos / 1000);
    let period_us = (PERIOD_S * 1e6) as u64;
    assert!(
        ((periods - 1) * period_us..=periods * period_us).contains(&span_us),
        "{span_us} us for {periods} periods"
    );
    assert!(entries.iter().all(|entry| entry.interface == "can0"));

    let decoded = run_scanhil(&["decode", "--format", "candump", log.to_str().unwrap()]);
    assert_success(&decoded, "scanhil decode fsm.log");
    let objects = String::from_utf8(decoded.stdout).expect("UTF-8");
    assert_eq!(objects.lines().count(), entries.len());
}

#[test]
fn a_recording_interface_that_is_no_interface_name_is_refused_naming_the_flag() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let output = run_scanhil(&[
        "scan",
        &fixture("scenarios/test-duplo-stud.json"),
        "--record-iface",
        "can/0",
        "--out",
        out.path().to_str().expect("UTF-8 path"),
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("--record-iface: interface name `can/0` contains '/' at byte 3"),
        "{stderr}"
    );
    assert!(
        !out.path().join("fsm.log").exists(),
        "refused before any output"
    );
}
