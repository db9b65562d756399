//! The wire: SLCAN lines, candump log lines, the ILD value stream, CAN message payloads.

use scanhil_protocol::can::{CanFrame, CanId, FD_LENGTHS};
use scanhil_protocol::candump::{self, Timestamp};
use scanhil_protocol::ild::stream::IldEvent;
use scanhil_protocol::ild::{IldDecoder, IldValue, MeasuringRange};
use scanhil_protocol::message::{Message, decode_signals};
use scanhil_protocol::slcan::{SlcanDecoder, SlcanEvent};

use crate::cut;

/// SLCAN bytes, as a host reads an adapter's and a device reads a host's: decoded whole and in
/// two chunks (the same events), every message encoding back to itself, every error's offset
/// inside the stream.
pub fn slcan(data: &[u8]) {
    let events = decode_whole_and_in_two::<SlcanDecoder>(data);
    for event in &events {
        match event {
            Ok(message) => {
                let text = message.encode();
                assert_eq!(
                    SlcanDecoder::new().push(text.as_bytes()),
                    vec![Ok(message.clone())],
                    "{message:?} does not decode from its encoding {text:?}"
                );
            }
            Err(error) => assert!(error.offset < data.len() as u64, "{error}"),
        }
    }
}

/// An incremental decoder of a byte stream: bytes in, events out, a last event at the end.
trait StreamDecoder: Default {
    type Event: PartialEq + std::fmt::Debug;
    fn push(&mut self, bytes: &[u8]) -> Vec<Self::Event>;
    fn finish(&mut self) -> Option<Self::Event>;
}

impl StreamDecoder for SlcanDecoder {
    type Event = SlcanEvent;
    fn push(&mut self, bytes: &[u8]) -> Vec<SlcanEvent> {
        SlcanDecoder::push(self, bytes)
    }
    fn finish(&mut self) -> Option<SlcanEvent> {
        SlcanDecoder::finish(self).map(Err)
    }
}

impl StreamDecoder for IldDecoder {
    type Event = IldEvent;
    fn push(&mut self, bytes: &[u8]) -> Vec<IldEvent> {
        IldDecoder::push(self, bytes)
    }
    fn finish(&mut self) -> Option<IldEvent> {
        IldDecoder::finish(self).map(Err)
    }
}

/// The events of `data` decoded whole, after checking that two chunks give the same.
fn decode_whole_and_in_two<D: StreamDecoder>(data: &[u8]) -> Vec<D::Event> {
    let decode = |chunks: &[&[u8]]| {
        let mut decoder = D::default();
        let mut events: Vec<D::Event> = chunks.iter().flat_map(|c| decoder.push(c)).collect();
        events.extend(decoder.finish());
        events
    };
    let whole = decode(&[data]);
    let (head, tail) = data.split_at(cut(data));
    assert_eq!(
        whole,
        decode(&[head, tail]),
        "chunking at {} changed the decode",
        head.len()
    );
    whole
}

/// A candump `-L` log: every line read back from what the writer makes of it (the timestamp to
/// the microsecond).
pub fn candump(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    for entry in candump::parse_log(&text).flatten() {
        let line = entry.to_string();
        let again = candump::parse_line(&line).unwrap_or_else(|error| {
            panic!("{line:?} written from {entry:?} is unreadable: {error}")
        });
        let micros = Timestamp {
            secs: entry.timestamp.secs,
            nanos: entry.timestamp.nanos / 1000 * 1000,
        };
        assert_eq!(again.timestamp, micros, "{line:?}");
        assert_eq!(again.interface, entry.interface, "{line:?}");
        assert_eq!(again.frame, entry.frame, "{line:?}");
        assert_eq!(again.len8_dlc, entry.len8_dlc, "{line:?}");
        assert_eq!(again.direction, entry.direction, "{line:?}");
    }
}

/// The ILD value stream: the same values and gaps whole and in two chunks, every byte in a
/// value or a gap, each cycle's first value read as a distance or an error.
pub fn ild_stream(data: &[u8]) {
    let whole = decode_whole_and_in_two::<IldDecoder>(data);
    let accounted: u64 = whole
        .iter()
        .map(|event| match event {
            Ok(_) => scanhil_protocol::ild::stream::BYTES_PER_VALUE as u64,
            Err(gap) => gap.len,
        })
        .sum();
    assert_eq!(accounted, data.len() as u64, "bytes lost or counted twice");
    // The manual's reserves reach 1 % of the span beyond either end of the range.
    let range = MeasuringRange::ILD2300_100;
    let reserve_mm = 0.01 * range.span_mm;
    let readable_mm = range.start_mm - reserve_mm..=range.start_mm + range.span_mm + reserve_mm;
    for word in whole.iter().flatten() {
        if let IldValue::Distance(digital) = IldValue::from_raw(word.raw) {
            let mm = range.digital_to_mm(digital);
            assert!(
                mm.is_some_and(|mm| readable_mm.contains(&mm)),
                "distance {digital} read as {mm:?} mm"
            );
        }
    }
}

/// A CAN frame made from the bytes (format, id, payload) through the message decoders: a frame
/// that decodes re-encodes to a frame carrying the same message, and the signal decoder agrees
/// with the message decoder.
pub fn can_messages(data: &[u8]) {
    let Some(frame) = frame_from(data) else {
        return;
    };
    let decoded = Message::decode(&frame);
    assert_eq!(
        decoded.is_ok(),
        decode_signals(&frame).is_ok(),
        "the decoders disagree on {frame:?}"
    );
    if let Ok(message) = decoded {
        let encoded = message
            .encode()
            .unwrap_or_else(|error| panic!("{message:?} from {frame:?} does not encode: {error}"));
        assert_eq!(Message::decode(&encoded), Ok(message), "from {frame:?}");
        assert_eq!(u32::from(message.id()), frame.id().as_raw());
    }
}

/// A frame: byte 0 the format (bit 0 extended id, bits 1-2 classical, remote, FD, FD with
/// bit-rate switch), bytes 1-4 the id (little-endian, masked), the rest the payload, cut to
/// the longest length the format allows.
fn frame_from(data: &[u8]) -> Option<CanFrame> {
    let (&format, rest) = data.split_first()?;
    let (id_bytes, payload) = rest.split_at_checked(4)?;
    let raw = u32::from_le_bytes(id_bytes.try_into().ok()?);
    let id = if format & 1 == 0 {
        CanId::standard((raw & 0x7FF) as u16)?
    } else {
        CanId::extended(raw & 0x1FFF_FFFF)?
    };
    let frame = match (format >> 1) & 3 {
        0 => CanFrame::new(id, &payload[..payload.len().min(8)]),
        1 => CanFrame::new_remote(id, payload.first().map_or(0, |dlc| dlc % 9)),
        fd => {
            let len = FD_LENGTHS
                .iter()
                .copied()
                .filter(|&l| l <= payload.len())
                .max()
                .unwrap_or(0);
            CanFrame::new_fd(id, &payload[..len], fd == 3, false)
        }
    };
    Some(frame.expect("the lengths are the format's"))
}
