//! A mirror node that stops reading its line (a hung adapter, a frozen node behind a buffer):
//! the host's next write fills the pty and would wait forever. A real-time scan was once found
//! that way, idle in `epoll_wait` with SIGTERM caught and ignored. The host must stop by its
//! watchdog (a send that cannot go out within the allowance is a link timeout) and, before
//! that, by SIGTERM, exiting 3 with its outputs written.
//!
//! The node is played on a real pty ([`spawn_deaf_node`]): it answers the SLCAN set-up, then
//! only writes AngleReadings, never reading the host's commands again.

use std::time::Duration;

use scanhil_protocol::link::PtyPair;

use crate::util::{exits_within, report, scanhil, signal, spawn_deaf_node, start_scan_of_node};

/// Starts a real-time scan of `test-loop-small` (mirror only, 30 s) with a watchdog of
/// `watchdog_periods` against a node that stops reading once the channel is open.
fn scan_against_a_deaf_node(out: &std::path::Path, watchdog_periods: u32) -> std::process::Child {
    // Built (if need be) before the node's clock starts.
    let _ = scanhil();
    let pair = PtyPair::open().expect("a pty pair");
    let fsm = format!("slcan:{}", pair.slave_path().display());
    let _node = spawn_deaf_node(pair, Duration::from_secs(60));
    start_scan_of_node(&fsm, "realtime", 30.0, watchdog_periods, out)
}

#[test]
fn sigterm_ends_a_scan_whose_node_stopped_reading() {
    let out = tempfile::tempdir().expect("a temporary folder");
    // A watchdog far longer than the test: only the signal can end the scan in time.
    let child = scan_against_a_deaf_node(out.path(), 100_000_000);
    // Long enough for the host's answers to fill the line (a few thousand readings).
    std::thread::sleep(Duration::from_secs(3));
    signal(child.id(), "TERM");
    let output = exits_within(child, Duration::from_secs(20), "after SIGTERM");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(3), "exit 3; stderr:\n{stderr}");
    assert!(
        stderr.contains("interrupted by SIGTERM"),
        "says why: {stderr}"
    );
    let report = report(out.path());
    assert!(
        report["periods"]["done"].as_u64().expect("periods done") > 0,
        "what ran is reported"
    );
}

#[test]
fn a_send_the_node_never_takes_is_a_link_timeout() {
    let out = tempfile::tempdir().expect("a temporary folder");
    // A short watchdog: the node's readings keep coming, so only the host's blocked send can
    // trip it.
    let child = scan_against_a_deaf_node(out.path(), 20);
    let output = exits_within(child, Duration::from_secs(20), "with a full line");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(3), "exit 3; stderr:\n{stderr}");
    assert!(
        stderr.contains("could not be sent within"),
        "says the node stopped reading: {stderr}"
    );
}
