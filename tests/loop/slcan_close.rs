//! The host closing the SLCAN channel (`C`) ends the emulator's run as a hang-up does, while
//! the host still holds the line open: the summary says `ended_by: host_closed_channel`.

use std::time::Duration;

use scanhil_protocol::message::{CoilCommand, Message};
use scanhil_protocol::plant_units::ActuatorPair;

use crate::util::{ServedEmulator, SlcanHost, fixture};

fn closing_ends_the_run(timing: &str) {
    let scene = fixture("scenes/step-alpha.json");
    let emulator = ServedEmulator::start(&[
        "--scene",
        &scene,
        "--fsm",
        "slcan:pty",
        "--timing",
        timing,
        "--duration-s",
        "600",
        // The host sends five commands, then nothing until its `C`: in real time a loaded
        // machine may take longer than the default 200 periods (10 ms) between the two, and
        // the watchdog would end the run first.
        "--watchdog-periods",
        "1000000",
    ]);
    let mut host = SlcanHost::open(&emulator.path("fsm"));
    for k in 0..5u32 {
        host.send(&Message::CoilCommand(CoilCommand::from_amps(
            k as u16,
            ActuatorPair::default(),
        )));
        host.send(&Message::Step { step: k });
    }
    // The node answers (lockstep: the steps; real time: its own clock).
    loop {
        match host.recv(Duration::from_secs(10)) {
            Some(Message::AngleReading(_)) => break,
            Some(_) => {}
            None => panic!("no AngleReading ({timing})"),
        }
    }
    host.write_line("C");
    let (code, summary) = emulator.finish(Duration::from_secs(10));
    assert_eq!(code, Some(0), "{summary}");
    assert_eq!(summary["outcome"], "finished", "{summary}");
    assert_eq!(summary["ended_by"], "host_closed_channel", "{summary}");
    drop(host);
}

#[test]
fn the_hosts_c_ends_a_lockstep_run() {
    closing_ends_the_run("lockstep");
}

#[test]
fn the_hosts_c_ends_a_real_time_run() {
    closing_ends_the_run("realtime");
}
