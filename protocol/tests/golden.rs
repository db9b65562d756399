//! The golden table: representative messages as bytes, candump lines and SLCAN lines, ILD
//! stream bytes and command lines. Any change to the wire shows up as a reviewed snapshot
//! diff (`protocol/tests/snapshots/`).

use std::fmt::Write;

use scanhil_protocol::bus_load::{Bitrates, FrameShape};
use scanhil_protocol::can::hex_upper;
use scanhil_protocol::candump::{LogEntry, Timestamp};
use scanhil_protocol::ild::command::{AddValue, AddValueSet, IldReply, MeasuringRate};
use scanhil_protocol::ild::{IldCommand, IldError, IldValue, MeasuringRange, encode_cycle};
use scanhil_protocol::message::{
    AngleReading, CoilCommand, Distance, Fault, FaultKind, Message, NodeId, NodeState, Status,
};
use scanhil_protocol::plant_units::{ActuatorPair, SensingPair};
use scanhil_protocol::slcan;

/// One example of every message, with values that exercise signs, limits and error codes.
fn representative_messages() -> Vec<Message> {
    let distance = Distance {
        value: IldValue::Distance(MeasuringRange::ILD2300_100.mm_to_digital(120.0).unwrap()),
        counter: 262_143,
        sensor_time_us: 16_777_215,
    };
    vec![
        Message::Fault(Fault {
            node: NodeId::Fsm,
            kind: FaultKind::OverCurrent,
            detail: -8_388_608,
            step: 65_535,
        }),
        Message::Fault(Fault {
            node: NodeId::Sensor,
            kind: FaultKind::SensorError,
            detail: IldError::LaserOff.code() as i32,
            step: 1,
        }),
        Message::Fault(Fault {
            node: NodeId::Controller,
            kind: FaultKind::LinkTimeout,
            detail: 20,
            step: 2,
        }),
        Message::Sync { step: 0 },
        Message::Step {
            step: 4_294_967_295,
        },
        Message::CoilCommand(CoilCommand::from_amps(
            1,
            ActuatorPair {
                a: 3.856,
                b: -3.856,
            },
        )),
        Message::CoilCommand(CoilCommand::from_amps(
            65_535,
            ActuatorPair {
                a: 100.0,
                b: -100.0,
            },
        )),
        Message::AngleReading(AngleReading::from_rad(
            1,
            SensingPair {
                alpha: 1.5f64.to_radians(),
                beta: -0.000_001,
            },
        )),
        Message::Distance(distance),
        Message::Distance(Distance {
            value: IldValue::Error(IldError::NoPeak),
            counter: 0,
            sensor_time_us: 50,
        }),
        Message::CommandStepFd {
            command: CoilCommand::from_amps(7, ActuatorPair { a: 0.5, b: 0.25 }),
            step: 7,
        },
        Message::AnglesDistanceFd {
            angles: AngleReading::from_rad(
                7,
                SensingPair {
                    alpha: -0.01,
                    beta: 0.02,
                },
            ),
            distance,
        },
        Message::Status(Status {
            node: NodeId::Controller,
            state: NodeState::Boot,
            step: 0,
            node_time_us: 0,
        }),
        Message::Status(Status {
            node: NodeId::Fsm,
            state: NodeState::Running,
            step: 40_000,
            node_time_us: 2_000_000,
        }),
        Message::Status(Status {
            node: NodeId::Sensor,
            state: NodeState::Fault,
            step: 16_777_215,
            node_time_us: 1,
        }),
    ]
}

#[test]
fn can_messages() {
    let mut table = String::new();
    for (i, message) in representative_messages().iter().enumerate() {
        let frame = message.encode().unwrap();
        let entry = LogEntry {
            timestamp: Timestamp {
                secs: 1_700_000_000,
                nanos: i as u32 * 50_000,
            },
            interface: "vcan0".to_owned(),
            frame,
            len8_dlc: None,
            direction: None,
        };
        let bits = FrameShape::of_frame(&frame).bits();
        let _ = writeln!(
            table,
            "{:<16} id {:#05x} {}\n  hex     {}\n  candump {}\n  slcan   {}\n  bus     {} nominal + {} data bits, {:.2} us at 1M/5M",
            message.spec().name,
            message.id(),
            if frame.is_fd() { "FD" } else { "classical" },
            hex_upper(frame.data()),
            entry,
            slcan::encode_frame(&frame).trim_end(),
            bits.nominal,
            bits.data_phase,
            bits.duration_s(Bitrates::FD_1M_5M) * 1e6,
        );
    }
    insta::assert_snapshot!(table);
}

#[test]
fn ild_stream_and_commands() {
    let range = MeasuringRange::ILD2300_100;
    let mut table = String::new();
    let mut values: Vec<(String, u32)> = [70.0, 120.0, 170.0]
        .iter()
        .map(|&mm| (format!("{mm} mm"), range.mm_to_digital(mm).unwrap()))
        .collect();
    values.extend(
        IldError::KNOWN
            .iter()
            .map(|e| (e.name().to_owned(), IldValue::Error(*e).raw())),
    );
    for (name, raw) in values {
        let _ = writeln!(
            table,
            "{name:<18} raw {raw:>6}  bytes {}",
            hex_upper(&encode_cycle(&[raw]))
        );
    }
    let _ = writeln!(
        table,
        "cycle distance+counter  bytes {}",
        hex_upper(&encode_cycle(&[32_760, 262_143]))
    );
    for command in [
        IldCommand::GetInfo,
        IldCommand::MeasRate(Some(MeasuringRate::Khz20)),
        IldCommand::MeasRate(Some(MeasuringRate::Khz49)),
        IldCommand::MeasRate(None),
        IldCommand::Echo(Some(true)),
        IldCommand::OutDistRs422(Some(true)),
        IldCommand::OutAddRs422(Some(AddValueSet::of(&[AddValue::Counter]))),
        IldCommand::GetOutInfoRs422,
        IldCommand::Baudrate(Some(691_200)),
        IldCommand::Output(Some("RS422".to_owned())),
    ] {
        let _ = writeln!(table, "command {:?}", command.encode());
    }
    let refused = IldCommand::parse("MEASRATE 7").unwrap_err();
    let _ = writeln!(
        table,
        "reply   {:?}",
        IldReply::refusal(Some("MEASRATE 7".to_owned()), &refused).encode()
    );
    insta::assert_snapshot!(table);
}
