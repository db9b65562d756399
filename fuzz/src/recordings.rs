//! Recordings as `scanhil decode` reads them, and as `scanhil-emulator replay` serves them.

use scanhil_controller::decode::{Format, Report, decode as decode_recording};
use scanhil_protocol::ild::MeasuringRange;

use scanhil_emulator::serve::lockstep::LockstepAnswers;
use scanhil_emulator::serve::lockstep_node::{NodeReply, NodeSend};
use scanhil_emulator::serve::recording::{Recording, parse_clock, parse_ild};
use scanhil_emulator::serve::replay_node::ReplayNode;
use scanhil_protocol::ild::stream::encode_cycle;
use scanhil_protocol::message::{Message, NodeState, Status};

use crate::select;

/// A recording (byte 0 picks candump, SLCAN or ILD) through `scanhil decode`'s reader: every
/// line it writes is one JSON object.
pub fn decode(data: &[u8]) {
    let Some((format, bytes)) = select(data, 3) else {
        return;
    };
    let format = [Format::Candump, Format::Slcan, Format::Ild][format];
    let mut out = Vec::new();
    let mut report = Report::writing_to("fuzz".to_owned(), Box::new(std::io::sink()));
    decode_recording(
        bytes,
        format,
        MeasuringRange::ILD2300_100,
        &mut out,
        &mut report,
    )
    .expect("memory reads and writes cannot fail");
    report.finish();
    for line in out.split(|&b| b == b'\n').filter(|l| !l.is_empty()) {
        let value: serde_json::Value = serde_json::from_slice(line).unwrap_or_else(|error| {
            panic!("{:?} is no JSON: {error}", String::from_utf8_lossy(line))
        });
        assert!(value.is_object(), "{value}");
    }
}

/// A recorded session (byte 0 picks `fsm.log`, `sensor.ild` or `report.json`) through the
/// replay's readers. A mirror recording that is accepted holds each period's reading where it
/// says, with the period's counter, and the replayed node answers every period's Step with it
/// and ends the run; an accepted ILD stream is its cycles written back, byte for byte.
pub fn replay(data: &[u8]) {
    let Some((file, bytes)) = select(data, 3) else {
        return;
    };
    let path = std::path::Path::new("fuzz");
    match file {
        0 => {
            let Ok(recording) = Recording::parse_fsm(bytes, path) else {
                return;
            };
            serve_every_period(recording);
        }
        1 => {
            if let Ok(cycles) = parse_ild(bytes, path) {
                let again: Vec<u8> = cycles
                    .iter()
                    .flat_map(|cycle| encode_cycle(cycle))
                    .collect();
                assert_eq!(again, bytes, "the cycles {cycles:?} do not write back");
            }
        }
        _ => {
            let _ = parse_clock(bytes, path);
        }
    }
}

/// Steps a replayed node through every recorded period, then ends the run.
fn serve_every_period(recording: Recording) {
    let periods = recording.periods.clone();
    let mut node = ReplayNode::new(recording, 1e-4, 20_000.0);
    for (k, period) in periods.iter().enumerate() {
        let reading = Message::decode(&period.frames[period.reading]);
        let seq = match reading {
            Ok(Message::AngleReading(angles) | Message::AnglesDistanceFd { angles, .. }) => {
                angles.seq
            }
            other => panic!("period {k}'s reading is {other:?}"),
        };
        assert_eq!(seq, k as u16, "period {k}'s reading");
        let step = Message::Step { step: k as u32 }.encode().expect("a Step");
        match node.on_frame(&step) {
            Ok(NodeReply::Send(sends)) => assert!(
                sends.contains(&NodeSend::Frame(period.frames[period.reading].into())),
                "period {k} is answered with its reading"
            ),
            other => panic!("period {k}: {other:?}"),
        }
    }
    let end = Message::Status(Status {
        node: scanhil_protocol::message::NodeId::Controller,
        state: NodeState::Ready,
        step: 0,
        node_time_us: 0,
    })
    .encode()
    .expect("a Status");
    assert!(matches!(node.on_frame(&end), Ok(NodeReply::EndOfRun(_))));
}
