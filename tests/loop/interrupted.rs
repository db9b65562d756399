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

/// A signal while the points are imaged (the loop's handlers gone: a second Ctrl-C, a CI
/// timeout's SIGTERM) ends the process by that signal, and the report written before the
/// imaging stays: it says the imaging did not finish and lists its outputs as not written.
fn interrupt_imaging_with(signal: &str) {
    use std::os::unix::process::ExitStatusExt;

    let dir = tempfile::tempdir().expect("a temporary folder");
    // A fine grid makes the imaging take seconds after the loop's fraction of a second.
    let scenario = crate::bad_input::edited_scenario(dir.path(), "test-duplo-stud", |scenario| {
        scenario["imaging"]["pitch_mm"] = 0.01.into();
        scenario["duration_s"] = 0.05.into();
    });
    let out = dir.path().join("out");
    let mut child = std::process::Command::new(crate::util::scanhil())
        .args(["scan", &scenario, "--out", out.to_str().expect("UTF-8")])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("starting scanhil");
    let report_path = out.join("report.json");
    let started = std::time::Instant::now();
    while !report_path.exists() {
        if let Some(status) = child.try_wait().expect("polling scanhil") {
            panic!("scanhil ended ({status}) before any report was written");
        }
        assert!(
            started.elapsed() < crate::util::RUN_LIMIT,
            "no report.json before the imaging"
        );
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    crate::util::signal(child.id(), signal);
    let status = child.wait().expect("waiting for scanhil");
    assert!(
        status.signal().is_some(),
        "ended by SIG{signal} during the imaging, not by finishing it: {status}"
    );
    let report = report(&out);
    let unfinished = "the run ended while its points were imaged";
    assert_eq!(
        report["imaging_error"], unfinished,
        "{}",
        report["imaging_error"]
    );
    assert_eq!(report["outcome"]["verdict"], "failed");
    for file in ["points.ply", "height_map.csv", "height_map.png"] {
        assert_eq!(
            report["outputs"]["failed"][file], unfinished,
            "{file}: {}",
            report["outputs"]["failed"]
        );
    }
    // The loop's part of it is whole: every period ran, its recordings are complete.
    assert_eq!(report["periods"]["done"], report["periods"]["planned"]);
}

#[test]
fn sigterm_during_imaging_leaves_a_report_that_says_the_imaging_did_not_finish() {
    interrupt_imaging_with("TERM");
}

#[test]
fn ctrl_c_during_imaging_leaves_a_report_that_says_the_imaging_did_not_finish() {
    interrupt_imaging_with("INT");
}
