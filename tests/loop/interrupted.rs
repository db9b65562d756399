//! An interrupted scan (Ctrl-C, SIGTERM) stops the loop, commands zero current, closes the
//! mirror's SLCAN channel (`C`, so the emulator ends its run by the host's close), writes
//! everything recorded up to then, says so, and exits 3.

use crate::util::{decode_candump, report, start_long_scan};

/// Starts a long scan, waits until its recording grows, sends `signal`, and checks the stop.
fn interrupt_with(signal: &str) {
    let out = tempfile::tempdir().expect("a temporary folder");
    let child = start_long_scan(out.path(), 20_000);
    let log = out.path().join("fsm.log");
    crate::util::signal(child.id(), signal);
    let output = child.wait_with_output().expect("waiting for scanhil");
    let stderr = String::from_utf8_lossy(&output.stderr);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert_eq!(
        output.status.code(),
        Some(3),
        "exit 3 after {signal}; stderr:\n{stderr}"
    );
    assert!(
        stderr.contains(&format!("interrupted by SIG{signal}")),
        "says why: {stderr}"
    );
    assert!(stdout.contains("outputs in"), "says where: {stdout}");

    let report = report(out.path());
    assert_eq!(report["outcome"]["complete"], false);
    let why = report["outcome"]["stopped_by"].as_str().unwrap_or_default();
    assert!(why.contains(signal), "{why}");
    let done = report["periods"]["done"].as_u64().expect("periods done");
    assert!(
        done > 100 && done < 2_400_000,
        "{done} periods before the signal"
    );
    // The emulator ended its run because the host closed the channel, holding zero current.
    let summary = &report["emulator"]["summary"];
    assert_eq!(summary["ended_by"], "host_closed_channel", "{summary}");
    assert_eq!(report["emulator"]["killed"], false);
    assert_eq!(summary["held_coil_currents_a"]["a"], 0.0, "{summary}");
    assert_eq!(summary["held_coil_currents_a"]["b"], 0.0, "{summary}");

    // The recording is whole: every line decodes, and the last command sent is zero current.
    let text = std::fs::read_to_string(&log).expect("fsm.log");
    assert!(text.ends_with('\n'), "fsm.log ends in a whole line");
    let last_command = decode_candump(&log)
        .last_command_a
        .expect("coil commands recorded");
    assert_eq!((last_command.a, last_command.b), (0.0, 0.0));
    for file in ["report.json", "tracking.svg"] {
        assert!(out.path().join(file).exists(), "{file} written");
    }
}

#[test]
fn ctrl_c_stops_the_scan_cleanly_and_keeps_what_it_recorded() {
    interrupt_with("INT");
}

#[test]
fn sigterm_stops_the_scan_cleanly_and_keeps_what_it_recorded() {
    interrupt_with("TERM");
}
