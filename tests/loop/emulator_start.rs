//! The emulator a scan starts goes with it: one that never says it is ready is stopped after
//! `timing.emulator_ready_s` (was a fixed 60 s), and one whose host is killed at any moment,
//! its start-up probe included, ends at once (the kernel's parent-death signal; was about 7 s
//! later, when its probe ended and it found the link closed).

use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::util::{children, exits_within, fixture, scanhil, signal};

/// The ids of the processes whose command line contains `marker`.
fn processes_with(marker: &str) -> Vec<u32> {
    std::fs::read_dir("/proc")
        .expect("/proc")
        .filter_map(Result::ok)
        .filter_map(|entry| entry.file_name().to_str()?.parse::<u32>().ok())
        .filter(|pid| {
            std::fs::read(format!("/proc/{pid}/cmdline"))
                .is_ok_and(|line| String::from_utf8_lossy(&line).contains(marker))
        })
        .collect()
}

/// Waits up to `limit` for `check` to hold.
fn within(limit: Duration, mut check: impl FnMut() -> bool) -> bool {
    let started = Instant::now();
    while started.elapsed() < limit {
        if check() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    check()
}

/// A stand-in emulator that never prints its ready line: it sleeps for `marker` seconds.
fn silent_emulator(dir: &Path, marker: &str) -> String {
    let path = dir.join("never-ready");
    std::fs::write(&path, format!("#!/bin/sh\nexec sleep {marker}\n")).expect("the script");
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    path.display().to_string()
}

#[test]
fn an_emulator_that_never_becomes_ready_is_stopped_after_the_allowance() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let marker = "3141.5926";
    let emulator = silent_emulator(dir.path(), marker);
    let out = dir.path().join("out");
    let started = Instant::now();
    let child = Command::new(scanhil())
        .args([
            "scan",
            &fixture("scenarios/test-loop-small.json"),
            "--emulator",
            &emulator,
            "--emulator-ready-s",
            "0.5",
            "--out",
            out.to_str().expect("UTF-8"),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting scanhil");
    let output = exits_within(child, Duration::from_secs(30), "a never-ready emulator");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("did not become ready within 0.5 s"),
        "{stderr}"
    );
    // Well before the old fixed 60 s (the allowance, the scan's set-up and a loaded machine).
    assert!(
        started.elapsed() < Duration::from_secs(20),
        "{:?}",
        started.elapsed()
    );
    assert!(
        within(Duration::from_secs(2), || processes_with(marker).is_empty()),
        "the stand-in emulator still runs: {:?}",
        processes_with(marker)
    );
}

#[test]
fn the_emulator_ready_allowance_is_checked_as_the_scenarios_field_is() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let output = Command::new(scanhil())
        .args([
            "scan",
            &fixture("scenarios/test-loop-small.json"),
            "--emulator-ready-s",
            "0",
            "--out",
            dir.path().join("out").to_str().expect("UTF-8"),
        ])
        .output()
        .expect("running scanhil");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("--emulator-ready-s: 0 s is not within (0, 600] s"),
        "{stderr}"
    );
}

#[test]
fn a_host_killed_during_the_emulators_start_up_probe_takes_the_emulator_with_it() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let out = dir.path().join("out");
    // A real-time scan: the host probes its wake-ups for 2 s, then starts the emulator,
    // which probes its own for 2 s before it is ready; the host is killed meanwhile.
    let mut child = Command::new(scanhil())
        .args([
            "scan",
            &fixture("scenarios/test-loop-small.json"),
            "--timing",
            "realtime",
            "--probe-s",
            "2",
            "--out",
            out.to_str().expect("UTF-8"),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("starting scanhil");
    let mut emulators = Vec::new();
    let started = within(Duration::from_secs(30), || {
        emulators = children(child.id());
        !emulators.is_empty()
    });
    if !started {
        let _ = child.kill();
        let _ = child.wait();
        panic!("scanhil started no emulator");
    }
    let emulator = emulators[0];
    signal(child.id(), "KILL");
    child.wait().expect("reaping scanhil");
    assert!(
        within(Duration::from_secs(2), || !alive(emulator)),
        "the emulator {emulator} outlived its host"
    );
}

/// Whether process `pid` exists and is not a zombie.
fn alive(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|stat| {
        stat.rsplit(") ")
            .next()
            .is_some_and(|rest| !rest.starts_with('Z'))
    })
}
