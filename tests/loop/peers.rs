//! Peers that stop reading: no write may block the safety logic. A host that stops reading
//! the mirror's link gets the emulator's coils zeroed and a reason; a sensor line nobody reads
//! never stalls the mirror; a node that stops reading ends the scan with exit 3 and a reason.

use std::time::Duration;

use scanhil_protocol::message::{CoilCommand, Message};
use scanhil_protocol::plant_units::ActuatorPair;

use crate::controller_watchdog::assert_stopped_cleanly;
use crate::deaf_node::DeafNode;
use crate::util::{ServedEmulator, SlcanHost, exits_within, fixture, start_scan_of_node};

/// The current: 1.5 A on both coils when the host stops reading.
const HELD_A: f64 = 1.5;

/// CoilCommand(k) at [`HELD_A`] and Step(k): one lockstep period.
fn period(k: u32) -> Vec<Message> {
    vec![
        Message::CoilCommand(CoilCommand::from_amps(
            k as u16,
            ActuatorPair {
                a: HELD_A,
                b: HELD_A,
            },
        )),
        Message::Step { step: k },
    ]
}

/// Sends lockstep period `k` and waits up to `wait` for its AngleReading; whether it came.
fn step(host: &mut SlcanHost, k: u32, wait: Duration) -> bool {
    for message in period(k) {
        host.send(&message);
    }
    loop {
        match host.recv(wait) {
            Some(Message::AngleReading(reading)) if reading.seq == k as u16 => return true,
            Some(_) => {}
            None => return false,
        }
    }
}

/// Runs lockstep periods `0..n` and waits for each AngleReading.
fn exchange(host: &mut SlcanHost, periods: std::ops::Range<u32>) {
    for k in periods {
        assert!(
            step(host, k, Duration::from_secs(10)),
            "no AngleReading for period {k}"
        );
    }
}

/// Runs 10 periods at [`HELD_A`] in `timing`, then the host keeps commanding but never reads
/// again: the node's answers fill the line and its writes can go nowhere, the line stays
/// open. The node must zero its coils, say why and exit 3 within its 1 s watchdog
/// allowance, the 2 s linger and a loaded machine's slack.
fn a_host_that_stops_reading(timing: &str, watchdog_periods: &str, allowance_s: &str) {
    let emulator = ServedEmulator::start(&[
        "--scene",
        &fixture("scenes/step-alpha.json"),
        "--fsm",
        "slcan:pty",
        "--timing",
        timing,
        "--watchdog-periods",
        watchdog_periods,
        "--lockstep-answer-allowance-s",
        allowance_s,
    ]);
    let mut host = SlcanHost::open(&emulator.path("fsm"));
    exchange(&mut host, 0..10);
    host.stop_reading();
    let writer = host.spawn_blind_writer(10, period);
    // Without the write deadline the node stays blocked in its write (lockstep) or keeps
    // dropping its frames (real time) for ever, with 1.5 A on the coils.
    let (code, summary) = emulator.finish(Duration::from_secs(20));
    assert_eq!(code, Some(3), "exit status 3: {summary}");
    assert_eq!(summary["ended_by"], "host_stopped_reading", "{summary}");
    assert_eq!(summary["final_state"], "fault", "{summary}");
    assert_eq!(summary["held_coil_currents_a"]["a"], 0.0, "{summary}");
    assert_eq!(summary["held_coil_currents_a"]["b"], 0.0, "{summary}");
    assert!(
        summary["error"]
            .as_str()
            .is_some_and(|e| e.contains("stopped reading")),
        "the summary says why: {summary}"
    );
    assert!(
        summary["node"]["periods"].as_u64().is_some_and(|p| p > 10),
        "the node ran past the host's last read: {summary}"
    );
    drop(host);
    let stopped_at = writer.join().expect("the writer thread");
    assert!(stopped_at > 10, "the host wrote blind periods");
}

#[test]
fn a_lockstep_host_that_stops_reading_gets_zero_coils_and_a_reason() {
    // 20 x 50 ms = 1 s: the node's watchdog, and how long a period's answers may take to go out.
    a_host_that_stops_reading("lockstep", "20", "0.05");
}

#[test]
fn a_real_time_host_that_stops_reading_gets_zero_coils_and_a_reason() {
    // 20 000 periods of 50 us = 1 s of wall time without a period's frames going out.
    a_host_that_stops_reading("realtime", "20000", "0.05");
}

/// The emulator serving the protocol-only scene's mirror and its sensor on an ILD pty, with
/// `options`.
fn serve_with_a_sensor_line(options: &[&str]) -> ServedEmulator {
    let scene = fixture("scenes/protocol-only.json");
    let mut args = vec![
        "--scene",
        &scene,
        "--fsm",
        "slcan:pty",
        "--sensor",
        "ild:pty",
    ];
    args.extend_from_slice(options);
    ServedEmulator::start(&args)
}

#[test]
fn a_lockstep_sensor_line_nobody_reads_ends_the_run_with_zero_coils_and_a_reason() {
    // Lockstep loses no sensor cycle: each period's 6-byte cycle waits for the host to read
    // the line. A pty's buffer fills within some thousands of periods; from then on the node
    // waits its watchdog's allowance (20 x 50 ms = 1 s) and ends as for an unread mirror link.
    let emulator = serve_with_a_sensor_line(&[
        "--watchdog-periods",
        "20",
        "--lockstep-answer-allowance-s",
        "0.05",
    ]);
    let sensor_line = emulator.ready["sensor"]
        .as_str()
        .expect("the sensor's line")
        .to_owned();
    let mut host = SlcanHost::open(&emulator.path("fsm"));
    // Far more periods than the line holds (about 3500): a node that drops cycles instead
    // runs them all.
    let answered = (0..20_000u32)
        .take_while(|&k| step(&mut host, k, Duration::from_secs(5)))
        .count();
    let (code, summary) = emulator.finish(Duration::from_secs(20));
    assert_eq!(code, Some(3), "exit status 3: {summary}");
    assert_eq!(summary["ended_by"], "host_stopped_reading", "{summary}");
    assert_eq!(summary["held_coil_currents_a"]["a"], 0.0, "{summary}");
    assert_eq!(summary["held_coil_currents_a"]["b"], 0.0, "{summary}");
    assert!(
        summary["error"]
            .as_str()
            .is_some_and(|e| e.contains(&format!("stopped reading {sensor_line}"))),
        "the summary names the sensor's line: {summary}"
    );
    let sensor = &summary["sensor"];
    assert_eq!(sensor["dropped_cycles"], 0, "nothing dropped: {sensor}");
    assert!(
        (100..20_000).contains(&answered),
        "the run went on while the line had room, then stopped: {answered} periods"
    );
}

#[test]
fn a_real_time_sensor_line_nobody_reads_never_stalls_the_mirror() {
    // Real time streams as a real sensor does: cycles the full line cannot take are dropped
    // (counted), and the mirror keeps its 20 kHz to the end of the run.
    let emulator = serve_with_a_sensor_line(&[
        "--timing",
        "realtime",
        "--duration-s",
        "1",
        "--watchdog-periods",
        "1000000",
    ]);
    let host = SlcanHost::open(&emulator.path("fsm"));
    // The mirror's line is read to the end of the run; the sensor's never.
    let mut readings = 0u64;
    while let Some(message) = host.recv(Duration::from_secs(3)) {
        if matches!(message, Message::AngleReading(_)) {
            readings += 1;
        }
    }
    let (code, summary) = emulator.finish(Duration::from_secs(20));
    assert_eq!(code, Some(0), "{summary}");
    assert_eq!(summary["ended_by"], "duration", "{summary}");
    let periods = summary["node"]["periods"].as_u64().expect("periods");
    assert!(
        readings > 1000,
        "the mirror kept answering: {readings} readings"
    );
    let sensor = &summary["sensor"];
    let sent = sensor["samples"].as_u64().expect("samples sent");
    let dropped = sensor["dropped_cycles"].as_u64().expect("cycles dropped");
    assert!(dropped > 0, "the full line dropped cycles: {sensor}");
    assert_eq!(
        sent + dropped,
        periods,
        "one sample per period, sent or dropped: {sensor}"
    );
}

#[test]
fn a_node_that_stops_reading_stops_the_scan_with_exit_3() {
    let node = DeafNode::start();
    let out = tempfile::tempdir().expect("a temporary folder");
    // 20 000 periods of 50 us = 1 s: how long a write may wait for the node to read.
    let child = start_scan_of_node(&node.fsm_uri(), "realtime", 60.0, 20_000, out.path());
    // Bound: the 1 s write allowance, the closing exchange's wait, and a loaded machine's
    // slack. Without the write deadline the host stays blocked in its write for ever.
    let output = exits_within(
        child,
        Duration::from_secs(30),
        "after the node stopped reading",
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    // Exit 3, the reason on stderr and in the report, a recording that decodes; the zero
    // command cannot go out on a line the node does not read.
    assert_stopped_cleanly(
        output.status.code(),
        &stderr,
        &out,
        "the node stopped reading",
        false,
    );
    assert!(node.readings_sent() > 100, "the node was talking");
}
