//! Property tests of every codec: round trips, arbitrary input never panics, and
//! resynchronisation after dropped and flipped bytes.

use proptest::prelude::*;
use scanhil_protocol::can::{CanFrame, CanId, FD_LENGTHS, FrameFormat};
use scanhil_protocol::candump::{self, Direction, LogEntry, Timestamp};
use scanhil_protocol::ild::command::{
    AddValue, AddValueSet, IldOutputInfo, IldReply, MeasuringRate, ReplyCode,
};
use scanhil_protocol::ild::{IldCommand, IldDecoder, IldReplyParser, IldValue, encode_cycle};
use scanhil_protocol::message::{
    AngleReading, Carried, CoilCommand, Distance, Fault, FaultKind, I24_MAX, Message, NodeId,
    NodeState, Status, U18_MAX, U24_MAX,
};
use scanhil_protocol::slcan::bus_status::{BusError, BusState, StateReport, StatusFlags};
use scanhil_protocol::slcan::{self, SlcanDecoder, SlcanMessage};

fn arb_id() -> impl Strategy<Value = CanId> {
    prop_oneof![
        (0u16..=0x7FF).prop_map(|r| CanId::standard(r).unwrap()),
        (0u32..=0x1FFF_FFFF).prop_map(|r| CanId::extended(r).unwrap()),
    ]
}

/// Any valid frame; `esi` decides whether FD frames may carry the ESI flag (SLCAN cannot).
fn arb_frame(esi: bool) -> impl Strategy<Value = CanFrame> {
    let classical = (arb_id(), prop::collection::vec(any::<u8>(), 0..=8))
        .prop_map(|(id, data)| CanFrame::new(id, &data).unwrap());
    let remote = (arb_id(), 0u8..=8).prop_map(|(id, dlc)| CanFrame::new_remote(id, dlc).unwrap());
    let fd = (
        arb_id(),
        prop::sample::select(FD_LENGTHS.to_vec()),
        any::<u8>(),
        any::<bool>(),
        any::<bool>(),
    )
        .prop_map(move |(id, len, fill, brs, e)| {
            let data: Vec<u8> = (0..len).map(|i| fill.wrapping_add(i as u8)).collect();
            CanFrame::new_fd(id, &data, brs, e && esi).unwrap()
        });
    prop_oneof![classical, remote, fd]
}

fn arb_node() -> impl Strategy<Value = NodeId> {
    prop::sample::select(vec![NodeId::Controller, NodeId::Fsm, NodeId::Sensor])
}

fn arb_distance() -> impl Strategy<Value = Distance> {
    (0..=U18_MAX, 0..=U18_MAX, 0..=U24_MAX).prop_map(|(raw, counter, t)| Distance {
        value: IldValue::from_raw(raw),
        counter,
        sensor_time_us: t,
    })
}

fn arb_i24() -> std::ops::RangeInclusive<i32> {
    -I24_MAX - 1..=I24_MAX
}

/// Messages whose fields may not fit their signals: angles and currents beyond 24 bits,
/// statuses beyond 24-bit counters.
fn arb_unchecked_message() -> impl Strategy<Value = Message> {
    prop_oneof![
        arb_message(),
        (any::<u16>(), any::<i32>(), any::<i32>()).prop_map(|(seq, a, b)| {
            Message::AngleReading(AngleReading {
                seq,
                alpha_urad: a,
                beta_urad: b,
            })
        }),
        (any::<u16>(), any::<i32>(), any::<i32>()).prop_map(|(seq, a, b)| {
            Message::CoilCommand(CoilCommand {
                seq,
                current_a_ua: a,
                current_b_ua: b,
            })
        }),
        (arb_node(), 0u8..4, any::<u32>(), any::<u32>()).prop_map(|(node, s, step, t)| {
            Message::Status(Status {
                node,
                state: NodeState::from_code(s).unwrap(),
                step,
                node_time_us: t,
            })
        }),
    ]
}

fn arb_message() -> impl Strategy<Value = Message> {
    let coil = (any::<u16>(), arb_i24(), arb_i24()).prop_map(|(seq, a, b)| CoilCommand {
        seq,
        current_a_ua: a,
        current_b_ua: b,
    });
    let angles = (any::<u16>(), arb_i24(), arb_i24()).prop_map(|(seq, a, b)| AngleReading {
        seq,
        alpha_urad: a,
        beta_urad: b,
    });
    prop_oneof![
        (arb_node(), any::<u8>(), any::<i32>(), any::<u16>()).prop_map(
            |(node, k, detail, step)| {
                Message::Fault(Fault {
                    node,
                    kind: FaultKind::from_code(k),
                    detail,
                    step,
                })
            }
        ),
        any::<u32>().prop_map(|step| Message::Sync { step }),
        any::<u32>().prop_map(|step| Message::Step { step }),
        coil.clone().prop_map(Message::CoilCommand),
        angles.clone().prop_map(Message::AngleReading),
        arb_distance().prop_map(Message::Distance),
        (coil, any::<u32>()).prop_map(|(command, step)| Message::CommandStepFd { command, step }),
        (angles, arb_distance())
            .prop_map(|(angles, distance)| Message::AnglesDistanceFd { angles, distance }),
        (arb_node(), 0u8..4, 0..=U24_MAX, 0..=U24_MAX).prop_map(|(node, s, step, t)| {
            Message::Status(Status {
                node,
                state: NodeState::from_code(s).unwrap(),
                step,
                node_time_us: t,
            })
        }),
    ]
}

/// True when `wanted` appears in `got` in order (other items may sit between).
fn is_subsequence<T: PartialEq>(wanted: &[T], got: &[T]) -> bool {
    let mut got = got.iter();
    wanted.iter().all(|w| got.any(|g| g == w))
}

fn slcan_frames(bytes: &[u8]) -> Vec<CanFrame> {
    SlcanDecoder::new()
        .push(bytes)
        .into_iter()
        .filter_map(|e| match e {
            Ok(SlcanMessage::Frame(f)) => Some(f),
            _ => None,
        })
        .collect()
}

/// The frames whose line (CR included) does not contain byte `p`, nor follows a damaged CR.
fn untouched_lines(lines: &[String], frames: &[CanFrame], p: usize) -> Vec<CanFrame> {
    let mut start = 0;
    let mut kept = Vec::new();
    let mut previous_cr_damaged = false;
    for (line, frame) in lines.iter().zip(frames) {
        let end = start + line.len(); // exclusive; the CR is at end - 1
        let touched = (start..end).contains(&p);
        if !touched && !previous_cr_damaged {
            kept.push(*frame);
        }
        previous_cr_damaged = p == end - 1;
        start = end;
    }
    kept
}

proptest! {
    #[test]
    fn slcan_round_trips_every_frame(frames in prop::collection::vec(arb_frame(false), 0..20)) {
        let text: String = frames.iter().map(slcan::encode_frame).collect();
        // Split at an arbitrary point: the decoder is incremental.
        let mut decoder = SlcanDecoder::new();
        let (a, b) = text.as_bytes().split_at(text.len() / 3);
        let mut events = decoder.push(a);
        events.extend(decoder.push(b));
        let expected: Vec<_> = frames.into_iter().map(|f| Ok(SlcanMessage::Frame(f))).collect();
        prop_assert_eq!(events, expected);
        prop_assert_eq!(decoder.finish(), None);
    }

    #[test]
    fn slcan_stamped_frames_round_trip(
        frames in prop::collection::vec((arb_frame(false), 0u16..60_000), 0..20),
    ) {
        let text: String = frames
            .iter()
            .map(|(frame, ms)| slcan::encode_stamped_frame(frame, *ms))
            .collect();
        let expected: Vec<_> = frames
            .into_iter()
            .map(|(frame, timestamp_ms)| Ok(SlcanMessage::StampedFrame { frame, timestamp_ms }))
            .collect();
        prop_assert_eq!(SlcanDecoder::new().push(text.as_bytes()), expected);
    }

    #[test]
    fn slcan_resyncs_after_a_dropped_or_flipped_byte(
        frames in prop::collection::vec(arb_frame(false), 1..12),
        at in any::<prop::sample::Index>(),
        flip in prop::option::of(1u8..=255),
    ) {
        let lines: Vec<String> = frames.iter().map(slcan::encode_frame).collect();
        let mut bytes = lines.concat().into_bytes();
        let p = at.index(bytes.len());
        match flip {
            Some(mask) => bytes[p] ^= mask,
            None => { bytes.remove(p); }
        }
        let got = slcan_frames(&bytes);
        let kept = untouched_lines(&lines, &frames, p);
        prop_assert!(is_subsequence(&kept, &got), "kept {:?}\ngot {:?}", kept, got);
        prop_assert!(got.len() + 2 >= frames.len());
    }

    #[test]
    fn slcan_decoder_survives_any_bytes(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let mut decoder = SlcanDecoder::new();
        let events = decoder.push(&bytes);
        let _ = decoder.finish();
        // Whatever it accepted, it writes back to the same message.
        for message in events.into_iter().flatten() {
            let again = SlcanDecoder::new().push(message.encode().as_bytes());
            prop_assert_eq!(again, vec![Ok(message)]);
        }
    }

    #[test]
    fn slcan_commands_and_replies_round_trip(
        text in "[ -~]{0,12}",
        code in 0u8..=9,
        counters in (0u16..=999, 0u16..=999),
        errors in prop::collection::vec(prop::sample::select(BusError::ALL.to_vec()), 1..=8),
    ) {
        let text = text.trim().to_owned();
        let states = [BusState::ErrorActive, BusState::ErrorWarning, BusState::ErrorPassive, BusState::BusOff];
        let messages = vec![
            SlcanMessage::Open,
            SlcanMessage::ListenOnly,
            SlcanMessage::Close,
            SlcanMessage::Bitrate(code),
            SlcanMessage::DataBitrate(code),
            SlcanMessage::VersionRequest,
            SlcanMessage::SerialRequest,
            SlcanMessage::Version(format!("1{text}")),
            SlcanMessage::Serial(format!("A{text}")),
            SlcanMessage::TransmitAck { extended: code % 2 == 0 },
            SlcanMessage::StatusRequest,
            SlcanMessage::StatusFlags(StatusFlags(code.wrapping_mul(29))),
            SlcanMessage::Timestamps(code % 2 == 1),
            SlcanMessage::BusState(StateReport {
                state: states[usize::from(code) % 4],
                rx_errors: counters.0,
                tx_errors: counters.1,
            }),
            SlcanMessage::BusErrors(errors),
            SlcanMessage::Text(format!("x {text}")),
            SlcanMessage::Ack,
            SlcanMessage::Nack,
        ];
        let bytes: String = messages.iter().map(SlcanMessage::encode).collect();
        let got: Vec<_> = SlcanDecoder::new().push(bytes.as_bytes()).into_iter().collect();
        prop_assert_eq!(got, messages.into_iter().map(Ok).collect::<Vec<_>>());
    }

    #[test]
    fn candump_lines_are_std_formatted_and_round_trip(
        frame in arb_frame(true),
        secs in 0u64..4_000_000_000,
        micros in 0u32..1_000_000,
        below_a_micro_ns in 0u32..1000,
        interface in "[a-z][a-z0-9]{0,8}",
    ) {
        // The line, written without std formatting, is what std formatting writes...
        let mut line = Vec::new();
        let nanos = micros * 1000 + below_a_micro_ns;
        candump::push_line(&mut line, Timestamp { secs, nanos }, &interface, &frame);
        let id = match frame.id() {
            CanId::Standard(id) => format!("{:03X}", id.as_raw()),
            CanId::Extended(id) => format!("{:08X}", id.as_raw()),
        };
        let hex: String = frame.data().iter().map(|b| format!("{b:02X}")).collect();
        let body = match frame.format() {
            FrameFormat::Classical => format!("#{hex}"),
            FrameFormat::Remote if frame.dlc() == 0 => "#R".to_owned(),
            FrameFormat::Remote => format!("#R{}", frame.dlc()),
            FrameFormat::Fd { brs, esi } => {
                format!("##{:X}{hex}", u8::from(brs) | (u8::from(esi) << 1))
            }
        };
        let line = String::from_utf8(line).unwrap();
        prop_assert_eq!(&line, &format!("({secs}.{micros:06}) {interface} {id}{body}"));
        // ... and reads back as the entry (its timestamp truncated to the microsecond).
        let entry = LogEntry {
            timestamp: Timestamp { secs, nanos: micros * 1000 },
            interface,
            frame,
            len8_dlc: None,
            direction: None,
        };
        prop_assert_eq!(&entry.to_string(), &line);
        prop_assert_eq!(candump::parse_line(&line), Ok(entry));
    }

    #[test]
    fn candump_direction_and_len8_dlc_round_trip(
        frame in arb_frame(true),
        raw_dlc in 9u8..=15,
        direction in prop::option::of(prop::sample::select(vec![Direction::Received, Direction::Sent])),
    ) {
        // `_N` only on a classical frame of 8 bytes (data or remote), as can-utils writes it.
        let len8_dlc = (!matches!(frame.format(), FrameFormat::Fd { .. }) && frame.dlc() == 8)
            .then_some(raw_dlc);
        let entry = LogEntry {
            timestamp: Timestamp { secs: 1_764_671_234, nanos: 250_000 },
            interface: "can0".to_owned(),
            frame,
            len8_dlc,
            direction,
        };
        let line = entry.to_string();
        prop_assert_eq!(line.ends_with(" R"), direction == Some(Direction::Received));
        prop_assert_eq!(line.ends_with(" T"), direction == Some(Direction::Sent));
        prop_assert_eq!(candump::parse_line(&line), Ok(entry));
    }

    #[test]
    fn candump_reader_survives_any_text(text in "\\PC{0,200}") {
        for entry in candump::parse_log(&text).flatten() {
            let _ = entry.to_string();
        }
    }

    #[test]
    fn messages_round_trip(message in arb_message()) {
        let frame = message.encode().unwrap();
        prop_assert_eq!(Message::decode(&frame), Ok(message));
        let decoded = scanhil_protocol::message::decode_signals(&frame).unwrap();
        prop_assert_eq!(decoded.spec.id, message.id());
    }

    /// What a transport in one process hands over is what a link would: a message passes
    /// its check exactly when it encodes, and the receiver reads the message its frame decodes
    /// to.
    #[test]
    fn a_carried_message_reads_as_its_frame_decodes(message in arb_unchecked_message()) {
        match (message.encode(), Carried::checked(message)) {
            (Ok(frame), Ok(carried)) => {
                prop_assert_eq!(carried.message(), Message::decode(&frame));
                prop_assert_eq!(carried.frame(), Ok(frame));
                prop_assert_eq!(Carried::Frame(frame).message(), Ok(message));
            }
            (Err(encoding), Err(checking)) => prop_assert_eq!(encoding, checking),
            (encoded, checked) => prop_assert!(
                false,
                "encoding gave {:?}, the check {:?}",
                encoded,
                checked
            ),
        }
    }

    #[test]
    fn message_decoder_survives_any_frame(frame in arb_frame(true)) {
        if let Ok(message) = Message::decode(&frame) {
            prop_assert_eq!(message.encode().unwrap(), frame);
        }
    }

    #[test]
    fn any_payload_on_a_known_id_decodes_or_is_refused(
        spec in prop::sample::select(scanhil_protocol::message::spec::MESSAGES.to_vec()),
        payload in prop::collection::vec(any::<u8>(), 64),
    ) {
        let id = CanId::standard(spec.id).unwrap();
        let data = &payload[..usize::from(spec.len)];
        let frame = if spec.fd {
            CanFrame::new_fd(id, data, true, false).unwrap()
        } else {
            CanFrame::new(id, data).unwrap()
        };
        if let Ok(message) = Message::decode(&frame) {
            prop_assert_eq!(message.encode().unwrap(), frame);
        }
    }

    #[test]
    fn ild_stream_round_trips(cycles in prop::collection::vec(prop::collection::vec(0..=U18_MAX, 1..4), 0..20)) {
        let bytes: Vec<u8> = cycles.iter().flat_map(|c| encode_cycle(c)).collect();
        let words: Vec<_> = IldDecoder::new().push(&bytes).into_iter().map(Result::unwrap).collect();
        let expected: Vec<(u32, Option<u8>)> = cycles
            .iter()
            .flat_map(|c| c.iter().enumerate().map(|(i, &r)| (r, Some(i as u8))))
            .collect();
        let got: Vec<_> = words.iter().map(|w| (w.raw, w.index_in_cycle)).collect();
        prop_assert_eq!(got, expected);
    }

    #[test]
    fn ild_resyncs_after_a_dropped_or_flipped_byte(
        raws in prop::collection::vec(0..=U18_MAX, 1..30),
        at in any::<prop::sample::Index>(),
        flip in prop::option::of(1u8..=255),
    ) {
        let mut bytes = encode_cycle(&raws);
        let p = at.index(bytes.len());
        match flip {
            Some(mask) => bytes[p] ^= mask,
            None => { bytes.remove(p); }
        }
        let got: Vec<u32> = IldDecoder::new().push(&bytes).into_iter().flatten().map(|w| w.raw).collect();
        let kept: Vec<u32> = raws.iter().enumerate().filter(|(i, _)| i * 3 + 2 < p || i * 3 > p).map(|(_, &r)| r).collect();
        prop_assert!(is_subsequence(&kept, &got), "kept {:?} got {:?}", kept, got);
        prop_assert!(got.len() + 1 >= raws.len());
    }

    #[test]
    fn ild_decoders_survive_any_bytes(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let mut decoder = IldDecoder::new();
        let _ = decoder.push(&bytes);
        let _ = decoder.finish();
        let _ = IldReplyParser::new("GETINFO").push(&bytes);
        let _ = IldOutputInfo::from_reply(&IldReply { lines: vec![String::from_utf8_lossy(&bytes).into_owned()], ..IldReply::default() });
        let _ = IldCommand::parse(&String::from_utf8_lossy(&bytes));
    }

    #[test]
    fn ild_commands_round_trip(
        rate in prop::sample::select(MeasuringRate::ALL.to_vec()),
        on in any::<bool>(),
        adds in prop::collection::vec(prop::sample::select(AddValue::ALL.to_vec()), 0..4),
        baud in prop::sample::select(scanhil_protocol::ild::command::BAUD_RATES_UNCHECKED.to_vec()),
    ) {
        for command in [
            IldCommand::GetInfo,
            IldCommand::MeasRate(Some(rate)),
            IldCommand::Echo(Some(on)),
            IldCommand::OutDistRs422(Some(on)),
            IldCommand::OutAddRs422(Some(AddValueSet::of(&adds))),
            IldCommand::GetOutInfoRs422,
            IldCommand::Baudrate(Some(baud)),
            IldCommand::Baudrate(None),
        ] {
            prop_assert_eq!(IldCommand::parse(&command.encode()), Ok(command));
        }
    }

    #[test]
    fn ild_replies_round_trip(
        lines in prop::collection::vec("[A-Za-z][A-Za-z0-9 :.]{0,20}[A-Za-z0-9]", 0..4),
        error in prop::option::of((0u8..100, "[A-Za-z]{1,10}")),
    ) {
        let reply = IldReply {
            echo: Some("GETINFO".to_owned()),
            lines: lines.into_iter().filter(|l| !l.starts_with(['E', 'W'])).collect(),
            warnings: vec![],
            error: error.map(|(code, text)| ReplyCode { code, text }),
        };
        prop_assert_eq!(IldReplyParser::new("GETINFO").push(reply.encode().as_bytes()), vec![reply]);
    }
}
