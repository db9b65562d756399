//! Decoding recordings into JSON lines, the core of `scanhil decode` (which adds the command
//! line, the input file and stdout): one JSON object per frame or value, in input order.
//!
//! - CAN (candump, slcan): `{"t": <seconds or null>, "id": <int>, "message": <DBC name>,
//!   "signals": {<DBC signal>: <physical value>, ...}}`; `t` is null for SLCAN (no clock).
//! - ILD: `{"offset": <byte>, "raw": <int>, "index": <position in the output cycle or null>}`
//!   plus, for a cycle's first value, `"mm": <distance>` or `"error": <name>`.
//! - What a technician's `candump -L -x -e -8 -d` adds: a frame's `"direction"` (`"R"`
//!   received, `"T"` sent by the logging host) and `"len8_dlc"` (its raw DLC, 9..15, when it
//!   has one); an error frame as `{"t": <seconds>, "error_frame": [<class>, ...], "id": <raw
//!   id, CAN_ERR_FLAG included>, "data": "<hex>"}`, counted by the [`Report`]; a `DROPCOUNT`
//!   notice said and its frames counted. Neither is malformed: a capture of a troubled bus
//!   decodes cleanly.
//!
//! Malformed input (bad lines, frames of a known id with the wrong shape, lost ILD sync) is
//! counted and said by a [`Report`] with its line or byte offset, and decoding goes on. Frames
//! with ids outside the message set are said too, but are not malformed (a shared bus carries
//! other traffic). Memory stays bounded whatever the input: a candump line is held to
//! [`MAX_CANDUMP_LINE`] bytes, the byte streams are read in chunks, and the report's lines are
//! capped.

use std::io::{BufRead, BufWriter, Read, Write};

use anyhow::Context;
use scanhil_protocol::can::CanFrame;
use scanhil_protocol::candump::{self, Direction, LogRecord};
use scanhil_protocol::ild::{IldDecoder, IldValue, MeasuringRange};
use scanhil_protocol::message::{MessageError, decode_signals};
use scanhil_protocol::slcan::{BEL, CR, SlcanDecoder, SlcanMessage};
use serde_json::{Value, json};

/// The input formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// candump `-L` log lines.
    Candump,
    /// An SLCAN byte stream (frames and replies).
    Slcan,
    /// An ILD 2300 RS422 byte stream.
    Ild,
}

/// Decodes `reader` as `format` into JSON lines on `out`; what is malformed goes to `report`.
/// `range` converts ILD distances to mm.
///
/// # Errors
/// Reading the input or writing `out` failed (malformed input is no error: it is counted).
pub fn decode(
    reader: impl BufRead,
    format: Format,
    range: MeasuringRange,
    out: &mut impl Write,
    report: &mut Report,
) -> anyhow::Result<()> {
    match format {
        Format::Candump => decode_candump(reader, out, report),
        Format::Slcan => decode_slcan(reader, out, report),
        Format::Ild => decode_ild(reader, range, out, report),
    }
}

/// Lines a [`Report`] writes at most; past that the items are counted, not shown.
pub const MAX_SHOWN: u64 = 1000;

/// Bytes of a bad line an error quotes at most (the byte count says how long it was).
const MAX_QUOTED: usize = 80;

/// The longest candump line read whole: a CAN FD frame with 64 data bytes, a nanosecond
/// timestamp and a long interface name are well under it. A longer line is skipped without
/// being held.
pub const MAX_CANDUMP_LINE: usize = 1024;

/// Counts what went wrong while decoding, and says it on stderr (or any writer): buffered, at
/// most [`MAX_SHOWN`] lines (a megabyte of garbage must not turn into gigabytes of messages).
pub struct Report {
    source: String,
    malformed: u64,
    error_frames: u64,
    dropped_frames: u64,
    shown: u64,
    stderr: Box<dyn Write>,
}

impl Report {
    /// A report on stderr; `source` (the input's name) starts each line.
    #[must_use]
    pub fn new(source: String) -> Report {
        Report::writing_to(source, Box::new(BufWriter::new(std::io::stderr())))
    }

    /// A report written to `stderr`; `source` (the input's name) starts each line.
    #[must_use]
    pub fn writing_to(source: String, stderr: Box<dyn Write>) -> Report {
        Report {
            source,
            malformed: 0,
            error_frames: 0,
            dropped_frames: 0,
            shown: 0,
            stderr,
        }
    }

    fn malformed(&mut self, what: impl std::fmt::Display) {
        self.malformed += 1;
        self.say(what);
    }

    fn notice(&mut self, what: impl std::fmt::Display) {
        self.say(what);
    }

    /// One line on stderr, while fewer than [`MAX_SHOWN`] were written. Write errors are
    /// ignored: stderr is where they would be said.
    fn say(&mut self, what: impl std::fmt::Display) {
        self.shown += 1;
        let _ = if self.shown <= MAX_SHOWN {
            writeln!(self.stderr, "scanhil decode: {}: {what}", self.source)
        } else if self.shown == MAX_SHOWN + 1 {
            writeln!(
                self.stderr,
                "scanhil decode: {}: more than {MAX_SHOWN} messages: the rest are counted, not \
                 shown",
                self.source
            )
        } else {
            Ok(())
        };
    }

    /// Malformed items counted so far.
    #[must_use]
    pub fn malformed_count(&self) -> u64 {
        self.malformed
    }

    /// candump error frames read so far.
    #[must_use]
    pub fn error_frame_count(&self) -> u64 {
        self.error_frames
    }

    /// Frames the logging socket dropped, as candump's `DROPCOUNT` notices said so far.
    #[must_use]
    pub fn dropped_frame_count(&self) -> u64 {
        self.dropped_frames
    }

    /// The closing counts, and everything buffered out.
    pub fn finish(&mut self) {
        if self.error_frames > 0 {
            let _ = writeln!(
                self.stderr,
                "scanhil decode: {}: {} error frame(s)",
                self.source, self.error_frames
            );
        }
        if self.dropped_frames > 0 {
            let _ = writeln!(
                self.stderr,
                "scanhil decode: {}: {} frame(s) dropped by the logging socket",
                self.source, self.dropped_frames
            );
        }
        if self.malformed > 0 {
            let _ = writeln!(
                self.stderr,
                "scanhil decode: {}: {} malformed item(s)",
                self.source, self.malformed
            );
        }
        let _ = self.stderr.flush();
    }
}

/// At most [`MAX_QUOTED`] bytes of a line (`start`, its first bytes) for an error message,
/// with its whole `length` when cut: `"t12xx"... (1048576 bytes)`.
fn quoted(start: &[u8], length: usize) -> String {
    let shown = String::from_utf8_lossy(&start[..start.len().min(MAX_QUOTED)]).into_owned();
    if length <= MAX_QUOTED && start.len() == length {
        format!("{shown:?}")
    } else {
        format!("{shown:?}... ({length} bytes)")
    }
}

/// Signals in the message's order (a JSON object whose keys keep the DBC order).
struct OrderedSignals(Vec<(&'static str, Value)>);

impl serde::Serialize for OrderedSignals {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_map(self.0.iter().map(|(k, v)| (k, v)))
    }
}

/// One decoded CAN frame, fields in the documented order.
#[derive(serde::Serialize)]
struct FrameLine {
    t: Option<f64>,
    id: u32,
    message: &'static str,
    signals: OrderedSignals,
    #[serde(skip_serializing_if = "Option::is_none")]
    direction: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    len8_dlc: Option<u8>,
}

/// One candump error frame.
#[derive(serde::Serialize)]
struct ErrorFrameLine {
    t: f64,
    error_frame: Vec<String>,
    id: u32,
    data: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    direction: Option<&'static str>,
}

/// A `-x` direction as its letter in the JSON.
fn direction_letter(direction: Option<Direction>) -> Option<&'static str> {
    direction.map(|direction| match direction {
        Direction::Received => "R",
        Direction::Sent => "T",
    })
}

/// The JSON line of a CAN frame, or `None` (after reporting) when it is not one of ours.
fn frame_json(
    t: Option<f64>,
    frame: &CanFrame,
    at: &str,
    report: &mut Report,
) -> Option<FrameLine> {
    match decode_signals(frame) {
        Ok(decoded) => {
            let signals = decoded
                .spec
                .signals
                .iter()
                .zip(&decoded.signals)
                .map(|(spec, &(name, value))| {
                    // Counts and codes print as integers, scaled signals as floats.
                    let value = if spec.scale == 1.0 && spec.offset == 0.0 {
                        json!(value as i64)
                    } else {
                        json!(value)
                    };
                    (name, value)
                })
                .collect();
            Some(FrameLine {
                t,
                id: frame.id().as_raw(),
                message: decoded.spec.name,
                signals: OrderedSignals(signals),
                direction: None,
                len8_dlc: None,
            })
        }
        Err(MessageError::UnknownId(id)) => {
            report.notice(format_args!("{at}: unknown id 0x{id}, skipped"));
            None
        }
        Err(err) => {
            report.malformed(format_args!("{at}: {err}"));
            None
        }
    }
}

fn write_line(out: &mut impl Write, value: &impl serde::Serialize) -> anyhow::Result<()> {
    serde_json::to_writer(&mut *out, value).context("cannot write to stdout")?;
    writeln!(out).context("cannot write to stdout")
}

fn decode_candump(
    mut reader: impl BufRead,
    out: &mut impl Write,
    report: &mut Report,
) -> anyhow::Result<()> {
    let mut line = Vec::new();
    let mut number = 0usize;
    loop {
        line.clear();
        let Some(length) = read_bounded_line(&mut reader, &mut line, MAX_CANDUMP_LINE)
            .context("cannot read input")?
        else {
            return Ok(());
        };
        number += 1;
        if length > line.len() {
            report.malformed(format_args!(
                "line {number}: longer than any candump line ({MAX_CANDUMP_LINE} bytes): {}",
                quoted(&line, length)
            ));
            continue;
        }
        let Ok(text) = std::str::from_utf8(&line) else {
            report.malformed(format_args!(
                "line {number}: not UTF-8: {}",
                quoted(&line, line.len())
            ));
            continue;
        };
        if text.trim().is_empty() {
            continue;
        }
        match candump::parse_record(text) {
            Ok(LogRecord::Frame(entry)) => {
                let at = format!("line {number}");
                let t = Some(entry.timestamp.as_secs_f64());
                if let Some(mut json) = frame_json(t, &entry.frame, &at, report) {
                    json.direction = direction_letter(entry.direction);
                    json.len8_dlc = entry.len8_dlc;
                    write_line(out, &json)?;
                }
            }
            Ok(LogRecord::Error(entry)) => {
                report.error_frames += 1;
                let line = ErrorFrameLine {
                    t: entry.timestamp.as_secs_f64(),
                    error_frame: entry.error.causes(),
                    id: entry.error.raw_id(),
                    data: scanhil_protocol::can::hex_upper(&entry.error.data),
                    direction: direction_letter(entry.direction),
                };
                write_line(out, &line)?;
            }
            Ok(LogRecord::Dropped(drop)) => {
                report.dropped_frames += u64::from(drop.dropped);
                report.notice(format_args!(
                    "line {number}: candump's socket dropped {} frame(s) on {} (total {})",
                    drop.dropped, drop.interface, drop.total
                ));
            }
            Err(err) => {
                // Quote at most the start of what the parser quoted.
                let message = err.to_string();
                if message.len() > 2 * MAX_QUOTED {
                    report.malformed(format_args!(
                        "line {number}: {}",
                        quoted(message.as_bytes(), message.len())
                    ));
                } else {
                    report.malformed(format_args!("line {number}: {message}"));
                }
            }
        }
    }
}

/// Reads one line (to `\n`, which is kept) into `line`, holding at most `limit` bytes of it
/// and skipping the rest; returns the line's whole length, `None` at the end of the input.
fn read_bounded_line(
    reader: &mut impl BufRead,
    line: &mut Vec<u8>,
    limit: usize,
) -> std::io::Result<Option<usize>> {
    let mut length = 0usize;
    loop {
        let buffer = match reader.fill_buf() {
            Ok(buffer) => buffer,
            Err(error) if error.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(error) => return Err(error),
        };
        if buffer.is_empty() {
            return Ok((length > 0).then_some(length));
        }
        let (taken, done) = match buffer.iter().position(|&b| b == b'\n') {
            Some(i) => (i + 1, true),
            None => (buffer.len(), false),
        };
        let room = limit.saturating_sub(line.len()).min(taken);
        line.extend_from_slice(&buffer[..room]);
        length += taken;
        reader.consume(taken);
        if done {
            return Ok(Some(length));
        }
    }
}

/// Reads the input in chunks and hands each to `feed`.
fn for_each_chunk(
    mut reader: impl Read,
    mut feed: impl FnMut(&[u8]) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let mut buf = vec![0u8; 64 * 1024];
    loop {
        let n = match reader.read(&mut buf) {
            Ok(0) => return Ok(()),
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e).context("cannot read input"),
        };
        feed(&buf[..n])?;
    }
}

fn decode_slcan(
    reader: impl Read,
    out: &mut impl Write,
    report: &mut Report,
) -> anyhow::Result<()> {
    let mut decoder = SlcanDecoder::new();
    // Fed up to each line's end (CR or BEL) so that each frame's line start is known for the
    // error messages.
    let mut line_start = 0u64;
    for_each_chunk(reader, |chunk| {
        for line in chunk.split_inclusive(|&byte| byte == CR || byte == BEL) {
            for event in decoder.push(line) {
                match event {
                    Ok(SlcanMessage::Frame(frame)) => {
                        let at = format!("byte offset {line_start}");
                        if let Some(json) = frame_json(None, &frame, &at, report) {
                            write_line(out, &json)?;
                        }
                    }
                    // Commands and replies carry no signals: nothing to print.
                    Ok(_) => {}
                    Err(err) => report.malformed(err),
                }
                line_start = decoder.position();
            }
        }
        Ok(())
    })?;
    if let Some(err) = decoder.finish() {
        report.malformed(err);
    }
    Ok(())
}

/// One ILD value; `mm` or `error` only for a cycle's first value (the distance).
#[derive(serde::Serialize)]
struct IldLine {
    offset: u64,
    raw: u32,
    index: Option<u8>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<&'static str>,
}

fn decode_ild(
    reader: impl Read,
    range: MeasuringRange,
    out: &mut impl Write,
    report: &mut Report,
) -> anyhow::Result<()> {
    let mut decoder = IldDecoder::new();
    for_each_chunk(reader, |chunk| {
        for event in decoder.push(chunk) {
            match event {
                Ok(word) => {
                    let value =
                        (word.index_in_cycle == Some(0)).then(|| IldValue::from_raw(word.raw));
                    let line = IldLine {
                        offset: word.offset,
                        raw: word.raw,
                        index: word.index_in_cycle,
                        mm: match value {
                            Some(IldValue::Distance(digital)) => range.digital_to_mm(digital),
                            _ => None,
                        },
                        error: match value {
                            Some(IldValue::Error(e)) => Some(e.name()),
                            _ => None,
                        },
                    };
                    write_line(out, &line)?;
                }
                Err(err) => report.malformed(err),
            }
        }
        Ok(())
    })?;
    if let Some(err) = decoder.finish() {
        report.malformed(err);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report() -> Report {
        Report::new("test".to_owned())
    }

    fn lines(out: &[u8]) -> Vec<Value> {
        String::from_utf8_lossy(out)
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect()
    }

    #[test]
    fn candump_lines_decode_in_order_and_bad_ones_are_counted() {
        let log = "(1.500000) vcan0 100#02016CE316FFFFFF\n\
                   (1.600000) vcan0 555#00\n\
                   garbage\n\
                   (1.700000) vcan0 021#E8030000\n";
        let mut out = Vec::new();
        let mut report = report();
        decode_candump(log.as_bytes(), &mut out, &mut report).unwrap();
        let text = String::from_utf8_lossy(&out).into_owned();
        assert!(
            text.starts_with(r#"{"t":1.5,"id":256,"message":"CoilCommand","signals":{"Seq":258,"CurrentA":1.500012"#),
            "{text}"
        );
        let decoded = lines(&out);
        assert_eq!(decoded.len(), 2, "unknown id and garbage print nothing");
        assert_eq!(decoded[1]["signals"]["Step"], 1000);
        assert_eq!(report.malformed, 1, "the unknown id is not malformed");
    }

    #[test]
    fn slcan_frames_decode_with_null_time_after_garbage() {
        let mut out = Vec::new();
        let mut report = report();
        decode_slcan(&b"xx\rt0214E8030000\rt02"[..], &mut out, &mut report).unwrap();
        let decoded = lines(&out);
        assert_eq!(decoded.len(), 1);
        assert_eq!(decoded[0]["t"], Value::Null);
        assert_eq!(decoded[0]["message"], "Step");
        assert_eq!(report.malformed, 2, "the garbage line and the cut-off line");
    }

    #[test]
    fn ild_values_give_mm_or_error_and_gaps_are_counted() {
        let range = MeasuringRange::ILD2300_100;
        let mut bytes =
            scanhil_protocol::ild::encode_cycle(&[range.mm_to_digital(120.0).unwrap(), 5]);
        bytes.push(0x80); // a stray H byte
        bytes.extend(scanhil_protocol::ild::encode_cycle(&[262_076]));
        let mut out = Vec::new();
        let mut report = report();
        decode_ild(&bytes[..], range, &mut out, &mut report).unwrap();
        let decoded = lines(&out);
        assert_eq!(decoded.len(), 3);
        let mm = decoded[0]["mm"].as_f64().unwrap();
        assert!((mm - 120.0).abs() <= range.mm_per_digit(), "{mm}");
        assert_eq!(decoded[1]["index"], 1);
        assert!(decoded[1].get("mm").is_none());
        assert_eq!(decoded[2]["error"], "no_peak");
        assert_eq!(report.malformed, 1);
    }

    #[test]
    fn a_megabyte_line_is_skipped_unheld_and_quoted_by_its_start() {
        let mut log = vec![b'x'; 1 << 20];
        log.extend_from_slice(b"\n(1.700000) vcan0 021#E8030000\n");
        let mut line = Vec::new();
        let mut reader = &log[..];
        let length = read_bounded_line(&mut reader, &mut line, MAX_CANDUMP_LINE).unwrap();
        assert_eq!(length, Some((1 << 20) + 1));
        assert_eq!(line.len(), MAX_CANDUMP_LINE, "no more than the limit held");
        let quote = quoted(&line, length.unwrap());
        assert_eq!(
            quote,
            format!("{:?}... (1048577 bytes)", "x".repeat(MAX_QUOTED))
        );
        let mut out = Vec::new();
        let mut report = report();
        decode_candump(&log[..], &mut out, &mut report).unwrap();
        assert_eq!(lines(&out).len(), 1, "the next line decodes");
        assert_eq!(report.malformed, 1);
    }

    #[test]
    fn stderr_is_capped_but_every_item_is_counted() {
        /// A writer whose bytes the test reads afterwards.
        #[derive(Clone, Default)]
        struct Shared(std::sync::Arc<std::sync::Mutex<Vec<u8>>>);
        impl Write for Shared {
            fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
                self.0.lock().unwrap().extend_from_slice(bytes);
                Ok(bytes.len())
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        let written = Shared::default();
        let mut report = Report::writing_to("test".into(), Box::new(written.clone()));
        for k in 0..3 * MAX_SHOWN {
            report.malformed(format_args!("item {k}"));
        }
        report.finish();
        let text = String::from_utf8(written.0.lock().unwrap().clone()).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines.len() as u64,
            MAX_SHOWN + 2,
            "capped, then the note and the count"
        );
        assert_eq!(lines[0], "scanhil decode: test: item 0");
        assert!(lines[MAX_SHOWN as usize].contains("the rest are counted, not shown"));
        assert_eq!(
            lines[MAX_SHOWN as usize + 1],
            format!("scanhil decode: test: {} malformed item(s)", 3 * MAX_SHOWN)
        );
    }
}
