//! Writes a candump `-L` log of a short synthetic lockstep exchange that uses every message
//! of the set (the golden recording `fixtures/recordings/lockstep-golden.log` and the input of
//! the cantools interop check). Deterministic: virtual time `k * 50 us`, no randomness.
//!
//! `cargo run -p scanhil-protocol --example write-candump -- [PATH]` (stdout without a path).

use std::io::Write;
use std::process::ExitCode;

use scanhil_protocol::candump::{LogEntry, Timestamp};
use scanhil_protocol::ild::{IldError, IldValue, MeasuringRange};
use scanhil_protocol::message::{
    AngleReading, CoilCommand, Distance, Fault, FaultKind, Message, NodeId, NodeState, Status,
};
use scanhil_protocol::plant_units::{ActuatorPair, SensingPair};

/// The control period, s (20 kHz).
const PERIOD_S: f64 = 50e-6;
/// Periods in the recording.
const PERIODS: u32 = 40;
/// Start of the recording's clock, s.
const START_S: u64 = 1_700_000_000;

fn messages() -> Vec<(u32, Message)> {
    let mut out = Vec::new();
    for node in [NodeId::Controller, NodeId::Fsm, NodeId::Sensor] {
        out.push((
            0,
            Message::Status(Status {
                node,
                state: NodeState::Ready,
                step: 0,
                node_time_us: 1_000,
            }),
        ));
    }
    let range = MeasuringRange::ILD2300_100;
    for k in 0..PERIODS {
        let phase = f64::from(k) * 2.0 * std::f64::consts::PI / 20.0;
        let currents = ActuatorPair {
            a: 3.856 * phase.sin(),
            b: -2.5 * phase.cos(),
        };
        let angles = SensingPair {
            alpha: 0.026 * (phase - 0.3).sin(),
            beta: -0.013 * (phase - 0.2).cos(),
        };
        let seq = k as u16;
        let value = if k % 13 == 12 {
            IldValue::Error(IldError::NoPeak)
        } else {
            IldValue::Distance(range.mm_to_digital(120.0 + 30.0 * phase.sin()).unwrap_or(0))
        };
        let distance = Distance {
            value,
            counter: 100_000 + k,
            sensor_time_us: 1_000 + k * 50,
        };
        if k % 10 == 9 {
            // Every tenth period in the CAN FD packing.
            out.push((
                k,
                Message::CommandStepFd {
                    command: CoilCommand::from_amps(seq, currents),
                    step: k,
                },
            ));
            out.push((
                k,
                Message::AnglesDistanceFd {
                    angles: AngleReading::from_rad(seq, angles),
                    distance,
                },
            ));
            continue;
        }
        out.push((
            k,
            Message::CoilCommand(CoilCommand::from_amps(seq, currents)),
        ));
        out.push((k, Message::Step { step: k }));
        out.push((
            k,
            Message::AngleReading(AngleReading::from_rad(seq, angles)),
        ));
        out.push((k, Message::Distance(distance)));
    }
    out.push((PERIODS, Message::Sync { step: PERIODS }));
    out.push((
        PERIODS,
        Message::Fault(Fault {
            node: NodeId::Fsm,
            kind: FaultKind::PowerLimit,
            detail: 30_500,
            step: PERIODS as u16,
        }),
    ));
    out.push((
        PERIODS,
        Message::Status(Status {
            node: NodeId::Fsm,
            state: NodeState::Fault,
            step: PERIODS,
            node_time_us: 1_000 + PERIODS * 50,
        }),
    ));
    out
}

fn main() -> ExitCode {
    let mut text = String::new();
    for (k, message) in messages() {
        let frame = match message.encode() {
            Ok(frame) => frame,
            Err(err) => {
                eprintln!("write-candump: {err}");
                return ExitCode::FAILURE;
            }
        };
        let t = f64::from(k) * PERIOD_S;
        let entry = LogEntry {
            timestamp: Timestamp {
                secs: START_S,
                nanos: (t * 1e9).round() as u32,
            },
            interface: "vcan0".to_owned(),
            frame,
            len8_dlc: None,
            direction: None,
        };
        text.push_str(&entry.to_string());
        text.push('\n');
    }
    let written = match std::env::args().nth(1) {
        Some(path) => std::fs::write(&path, &text).map_err(|e| format!("{path}: {e}")),
        None => std::io::stdout()
            .write_all(text.as_bytes())
            .map_err(|e| e.to_string()),
    };
    match written {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("write-candump: cannot write {err}");
            ExitCode::FAILURE
        }
    }
}
