//! A scan killed outright (SIGKILL: no handler runs, nothing is flushed on the way out) keeps
//! its candump recording up to the period in flight: the recording is written once per
//! period, before the host waits for the node, not held until the end.

use std::time::Duration;

use crate::util::{
    assert_gapless, decode_candump, recording_grows, scan_against_served_emulator, signal,
};

#[test]
fn a_killed_scan_keeps_its_recording_up_to_the_period_in_flight() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let (emulator, mut child) =
        scan_against_served_emulator(out.path(), &[], &["--duration-s", "60"]);
    if !recording_grows(out.path(), 20_000) {
        let _ = child.kill();
        let _ = child.wait();
        panic!("the scan never recorded 20 000 bytes");
    }
    // Freeze the host, give the node time to answer everything it received (its watchdog
    // allows 200 x 50 ms), then kill the host: the node's period count is then exactly the
    // Step frames the host sent.
    signal(child.id(), "STOP");
    std::thread::sleep(Duration::from_millis(300));
    signal(child.id(), "KILL");
    child.wait().expect("reaping scanhil");
    let (_, summary) = emulator.finish(Duration::from_secs(10));
    let stepped = summary["node"]["periods"]
        .as_u64()
        .unwrap_or_else(|| panic!("the node's period count in {summary}"));

    let log = out.path().join("fsm.log");
    let text = std::fs::read_to_string(&log).expect("fsm.log");
    assert!(text.ends_with('\n'), "fsm.log ends in a whole line");
    let recording = decode_candump(&log);
    assert_gapless(&recording.command_seqs, "recorded coil commands");
    assert_gapless(&recording.angle_seqs, "recorded angle readings");
    // The node stepped periods 0..stepped: the host sent CoilCommand and Step up to period
    // stepped - 1 and received readings up to stepped - 2 before that. The period in flight
    // (the last reading and the commands after it) may be lost, nothing before it.
    let commands = recording.command_seqs.len() as u64;
    let readings = recording.angle_seqs.len() as u64;
    assert!(
        commands + 1 >= stepped && commands <= stepped,
        "{commands} coil commands recorded, the node stepped {stepped} periods"
    );
    assert!(
        readings + 2 >= stepped && readings <= stepped,
        "{readings} angle readings recorded, the node stepped {stepped} periods"
    );
}
