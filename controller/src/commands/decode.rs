//! `scanhil decode [FILE|-] --format candump|slcan|ild`: prints one JSON object per frame or
//! value, in input order, on stdout.
//!
//! - CAN (candump, slcan): `{"t": <seconds or null>, "id": <int>, "message": <DBC name>,
//!   "signals": {<DBC signal>: <physical value>, ...}}`; `t` is null for SLCAN (no clock).
//! - ILD: `{"offset": <byte>, "raw": <int>, "index": <position in the output cycle or null>}`
//!   plus, for a cycle's first value, `"mm": <distance>` or `"error": <name>`.
//!
//! Malformed input (bad lines, frames of a known id with the wrong shape, lost ILD sync) is
//! reported on stderr with its line or byte offset and decoding goes on; the exit status is
//! then 1. Frames with ids outside the message set are reported on stderr too, but are not
//! malformed (a shared bus carries other traffic) and leave the exit status alone.

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use scanhil_protocol::can::CanFrame;
use scanhil_protocol::candump;
use scanhil_protocol::ild::{IldDecoder, IldValue, MeasuringRange};
use scanhil_protocol::message::{MessageError, decode_signals};
use scanhil_protocol::slcan::{SlcanDecoder, SlcanMessage};
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

/// Arguments of `scanhil decode`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The input file; `-` or nothing reads stdin.
    #[arg(default_value = "-")]
    pub input: PathBuf,
    /// What the input is.
    #[arg(long, value_enum)]
    pub format: Format,
    /// ILD: start of the measuring range, mm (default: ILD 2300-100).
    #[arg(long, default_value_t = MeasuringRange::ILD2300_100.start_mm)]
    pub measuring_range_start_mm: f64,
    /// ILD: length of the measuring range, mm (default: ILD 2300-100).
    #[arg(long, default_value_t = MeasuringRange::ILD2300_100.span_mm)]
    pub measuring_range_span_mm: f64,
}

/// Counts what went wrong while decoding, and says it on stderr.
struct Report {
    source: String,
    malformed: u64,
}

impl Report {
    fn malformed(&mut self, what: impl std::fmt::Display) {
        self.malformed += 1;
        eprintln!("scanhil decode: {}: {what}", self.source);
    }

    fn notice(&self, what: impl std::fmt::Display) {
        eprintln!("scanhil decode: {}: {what}", self.source);
    }
}

/// Runs `scanhil decode`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let (reader, source): (Box<dyn Read>, String) = if args.input.as_os_str() == "-" {
        (Box::new(std::io::stdin().lock()), "<stdin>".to_owned())
    } else {
        let file = File::open(&args.input)
            .with_context(|| format!("cannot open {}", args.input.display()))?;
        (Box::new(file), args.input.display().to_string())
    };
    let range = MeasuringRange {
        start_mm: args.measuring_range_start_mm,
        span_mm: args.measuring_range_span_mm,
    };
    anyhow::ensure!(
        range.span_mm.is_finite() && range.span_mm > 0.0 && range.start_mm.is_finite(),
        "--measuring-range-span-mm must be a positive number and the start finite"
    );
    let mut report = Report {
        source,
        malformed: 0,
    };
    let mut out = BufWriter::new(std::io::stdout().lock());
    let reader = BufReader::new(reader);
    match args.format {
        Format::Candump => decode_candump(reader, &mut out, &mut report)?,
        Format::Slcan => decode_slcan(reader, &mut out, &mut report)?,
        Format::Ild => decode_ild(reader, range, &mut out, &mut report)?,
    }
    out.flush().context("cannot write to stdout")?;
    Ok(if report.malformed == 0 {
        ExitCode::SUCCESS
    } else {
        eprintln!(
            "scanhil decode: {}: {} malformed item(s)",
            report.source, report.malformed
        );
        ExitCode::FAILURE
    })
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
        if reader
            .read_until(b'\n', &mut line)
            .context("cannot read input")?
            == 0
        {
            return Ok(());
        }
        number += 1;
        let Ok(text) = std::str::from_utf8(&line) else {
            report.malformed(format_args!("line {number}: not UTF-8"));
            continue;
        };
        if text.trim().is_empty() {
            continue;
        }
        match candump::parse_line(text) {
            Ok(entry) => {
                let at = format!("line {number}");
                let t = Some(entry.timestamp.as_secs_f64());
                if let Some(json) = frame_json(t, &entry.frame, &at, report) {
                    write_line(out, &json)?;
                }
            }
            Err(err) => report.malformed(format_args!("line {number}: {err}")),
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
    // Fed byte by byte so that each frame's line start is known for the error messages.
    let mut line_start = 0u64;
    for_each_chunk(reader, |chunk| {
        for &byte in chunk {
            for event in decoder.push(&[byte]) {
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
        Report {
            source: "test".to_owned(),
            malformed: 0,
        }
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
}
