//! The emulator's side of the watchdog, with the test playing the controller over SLCAN.

use std::time::Duration;

use scanhil_protocol::message::{CoilCommand, FaultKind, Message, NodeId, NodeState};
use scanhil_protocol::plant_units::ActuatorPair;

use crate::util::{ServedEmulator, SlcanHost, fixture};

#[test]
fn a_silent_controller_gets_zero_currents_and_a_link_timeout_fault() {
    let scene = fixture("scenes/step-alpha.json");
    let emulator = ServedEmulator::start(&[
        "--scene",
        &scene,
        "--fsm",
        "slcan:pty",
        "--watchdog-periods",
        "20",
        // 20 periods of 50 ms = 1 s of silence: the test's own exchanges below must never
        // come near it under parallel load (a 100 ms budget could fire between two of them).
        "--lockstep-answer-allowance-s",
        "0.05",
    ]);
    let mut host = SlcanHost::open(&emulator.path("fsm"));
    let current = ActuatorPair { a: 0.3, b: 0.3 };
    for k in 0..10u32 {
        host.send(&Message::CoilCommand(CoilCommand::from_amps(
            k as u16, current,
        )));
        host.send(&Message::Step { step: k });
        let answer = loop {
            match host.recv(Duration::from_secs(10)) {
                Some(Message::AngleReading(reading)) => break reading,
                Some(_) => {}
                None => panic!("no AngleReading for period {k}"),
            }
        };
        assert_eq!(answer.seq, k as u16);
    }
    // Silence: 20 periods of 50 ms allowance.
    let mut fault = None;
    let mut fault_status = false;
    while let Some(message) = host.recv(Duration::from_secs(5)) {
        match message {
            Message::Fault(f) => fault = Some(f),
            Message::Status(s) if s.state == NodeState::Fault => {
                fault_status = true;
                break;
            }
            _ => {}
        }
    }
    let fault = fault.expect("a fault frame after the silence");
    assert_eq!(
        (fault.node, fault.kind),
        (NodeId::Fsm, FaultKind::LinkTimeout)
    );
    assert_eq!(fault.detail, 20, "the detail carries the missed periods");
    assert!(fault_status, "a Status(fault) frame follows the fault");
    drop(host);
    let (code, summary) = emulator.finish(Duration::from_secs(10));
    assert_eq!(
        code,
        Some(3),
        "exit status 3 after a link timeout: {summary}"
    );
    assert_eq!(summary["outcome"], "link_timeout", "{summary}");
    assert_eq!(summary["final_state"], "fault");
    assert_eq!(summary["held_coil_currents_a"]["a"], 0.0);
    assert_eq!(summary["held_coil_currents_a"]["b"], 0.0);
    assert_eq!(summary["node"]["periods"], 10);
}
