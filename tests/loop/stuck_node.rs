//! A mirror node that stops reading its line (a hung adapter, a frozen node behind a buffer):
//! the host's next write fills the pty and would wait forever. A real-time scan was once found
//! that way, idle in `epoll_wait` with SIGTERM caught and ignored. The host must stop by its
//! watchdog (a send that cannot go out within the allowance is a link timeout) and, before
//! that, by SIGTERM, exiting 3 with its outputs written.
//!
//! The node is played on a real pty ([`DeafNode`]).

use std::process::{Child, Command, Stdio};
use std::time::Duration;

use crate::deaf_node::DeafNode;
use crate::util::{exits_within, scanhil, start_scan_of_node};

/// Starts a 30 s real-time scan of `test-loop-small` (mirror only) against `node`.
fn scan_against(node: &DeafNode, out: &std::path::Path, watchdog_periods: u32) -> Child {
    start_scan_of_node(&node.fsm_uri(), "realtime", 30.0, watchdog_periods, out)
}

#[test]
fn sigterm_ends_a_scan_whose_node_stopped_reading() {
    let node = DeafNode::start();
    let out = tempfile::tempdir().expect("a temporary folder");
    // A watchdog far longer than the test: only the signal can end the scan in time.
    let child = scan_against(&node, out.path(), 100_000_000);
    // Long enough for the host's answers to fill the line (a few thousand readings).
    std::thread::sleep(Duration::from_secs(3));
    crate::util::signal(child.id(), "TERM");
    let output = exits_within(child, Duration::from_secs(20), "after SIGTERM");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(3), "exit 3; stderr:\n{stderr}");
    assert!(
        stderr.contains("interrupted by SIGTERM"),
        "says why: {stderr}"
    );
    let report = crate::util::report(out.path());
    assert!(
        report["periods"]["done"].as_u64().expect("periods done") > 0,
        "what ran is reported"
    );
}

#[test]
fn a_send_the_node_never_takes_is_a_link_timeout() {
    let node = DeafNode::start();
    let out = tempfile::tempdir().expect("a temporary folder");
    // A 100 ms watchdog (2000 periods of 50 us): the node's readings keep coming, so only the
    // host's blocked send can trip it, and a node thread held off the CPU by a loaded machine
    // for a millisecond or two (a 20-period watchdog's whole allowance) does not.
    let child = scan_against(&node, out.path(), 2000);
    let output = exits_within(child, Duration::from_secs(20), "with a full line");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(3), "exit 3; stderr:\n{stderr}");
    assert!(
        stderr.contains("could not be sent within"),
        "says the node stopped reading: {stderr}"
    );
}

#[test]
fn conformance_against_a_node_that_stopped_reading_fails_within_its_watchdog() {
    let node = DeafNode::start();
    let out = tempfile::tempdir().expect("a temporary folder");
    let junit = out.path().join("conformance.xml");
    let child = Command::new(scanhil())
        .args(["conformance", "--fsm", &node.fsm_uri()])
        .args(["--watchdog-periods", "50", "--junit"])
        .arg(&junit)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting scanhil conformance");
    let output = exits_within(child, Duration::from_secs(60), "with a full line");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert_ne!(output.status.code(), Some(0), "checks fail: {stdout}");
    let xml = std::fs::read_to_string(&junit).expect("the JUnit report is written");
    assert!(
        xml.contains("could not be sent within"),
        "a failure says the node stopped reading: {xml}"
    );
}
