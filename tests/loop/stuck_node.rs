//! A mirror node that stops reading its line (a hung adapter, a frozen node behind a buffer):
//! the host's next write fills the pty and would wait forever. A real-time scan was once found
//! that way, idle in `epoll_wait` with SIGTERM caught and ignored. The host must stop by its
//! watchdog (a send that cannot go out within the allowance is a link timeout) and, before
//! that, by SIGTERM, exiting 3 with its outputs written.
//!
//! The node is played here on a real pty: it answers the SLCAN set-up, then only writes
//! AngleReadings, never reading the host's commands again.

use std::io::{Read, Write};
use std::os::fd::OwnedFd;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use nix::fcntl::OFlag;
use scanhil_protocol::message::{AngleReading, Message};
use scanhil_protocol::plant_units::SensingPair;

use crate::util::{fixture, scanhil};

/// A pty whose master end plays a node that stops reading after the channel is open.
struct StuckNode {
    slave_path: String,
    /// Held so the line stays up while the host opens it.
    _slave: OwnedFd,
}

impl StuckNode {
    fn start() -> StuckNode {
        let master = nix::pty::posix_openpt(OFlag::O_RDWR | OFlag::O_NOCTTY).expect("a pty");
        nix::pty::grantpt(&master).expect("grantpt");
        nix::pty::unlockpt(&master).expect("unlockpt");
        let slave_path = nix::pty::ptsname_r(&master).expect("the slave's path");
        let slave: OwnedFd = nix::fcntl::open(
            slave_path.as_str(),
            OFlag::O_RDWR | OFlag::O_NOCTTY,
            nix::sys::stat::Mode::empty(),
        )
        .expect("opening the slave");
        let mut settings = nix::sys::termios::tcgetattr(&slave).expect("termios");
        nix::sys::termios::cfmakeraw(&mut settings);
        nix::sys::termios::tcsetattr(&slave, nix::sys::termios::SetArg::TCSANOW, &settings)
            .expect("raw mode");
        let mut line = std::fs::File::from(OwnedFd::from(master));
        std::thread::spawn(move || {
            // Answer every SLCAN command with CR until the channel is opened (`O`).
            let mut buf = [0u8; 256];
            let mut pending = Vec::new();
            'setup: while let Ok(n) = line.read(&mut buf) {
                if n == 0 {
                    return;
                }
                pending.extend_from_slice(&buf[..n]);
                while let Some(end) = pending.iter().position(|&b| b == b'\r') {
                    let command: Vec<u8> = pending.drain(..=end).collect();
                    if line.write_all(b"\r").is_err() {
                        return;
                    }
                    if command.first() == Some(&b'O') {
                        break 'setup;
                    }
                }
            }
            // Then only talk: a reading every 50 us of loop time, as fast as the line takes
            // them, and never read the host's answers (its writes fill the line).
            for k in 0u64.. {
                let reading =
                    Message::AngleReading(AngleReading::from_rad(k as u16, SensingPair::default()));
                let frame = reading.encode().expect("encodable");
                let text = scanhil_protocol::slcan::encode_frame(&frame);
                if line.write_all(text.as_bytes()).is_err() {
                    return;
                }
            }
        });
        StuckNode {
            slave_path,
            _slave: slave,
        }
    }
}

/// Starts a real-time scan of `test-loop-small` (mirror only) against the stuck node.
fn scan_against(
    node: &StuckNode,
    out: &std::path::Path,
    watchdog_periods: &str,
) -> std::process::Child {
    Command::new(scanhil())
        .args([
            "scan",
            &fixture("scenarios/test-loop-small.json"),
            "--timing",
            "realtime",
            "--duration-s",
            "30",
            "--no-emulator",
            "--fsm",
            &format!("slcan:{}", node.slave_path),
            "--watchdog-periods",
            watchdog_periods,
            "--out",
            out.to_str().expect("UTF-8 path"),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting scanhil")
}

/// Waits up to `limit` for `child` to exit; kills and reaps it (and fails) if it does not.
fn exits_within(
    mut child: std::process::Child,
    limit: Duration,
    what: &str,
) -> std::process::Output {
    let started = Instant::now();
    while child.try_wait().expect("polling scanhil").is_none() {
        if started.elapsed() > limit {
            let _ = child.kill();
            let output = child.wait_with_output().expect("reaping scanhil");
            panic!(
                "{what}: scanhil still running after {limit:?}; stderr:\n{}",
                String::from_utf8_lossy(&output.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    child
        .wait_with_output()
        .expect("collecting scanhil's output")
}

#[test]
fn sigterm_ends_a_scan_whose_node_stopped_reading() {
    let node = StuckNode::start();
    let out = tempfile::tempdir().expect("a temporary folder");
    // A watchdog far longer than the test: only the signal can end the scan in time.
    let child = scan_against(&node, out.path(), "100000000");
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
    let node = StuckNode::start();
    let out = tempfile::tempdir().expect("a temporary folder");
    // 2000 periods of 50 ms allowance each would be 100 s: the node's readings keep coming,
    // so only the host's blocked send can trip it; use a short watchdog instead.
    let child = scan_against(&node, out.path(), "20");
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
    let node = StuckNode::start();
    let out = tempfile::tempdir().expect("a temporary folder");
    let junit = out.path().join("conformance.xml");
    let child = Command::new(scanhil())
        .args([
            "conformance",
            "--fsm",
            &format!("slcan:{}", node.slave_path),
        ])
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
