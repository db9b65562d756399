//! `scanhil decode [FILE|-] --format candump|slcan|ild`: prints one JSON object per frame or
//! value, in input order, on stdout. The decoding is [`scanhil_controller::decode`]; this is
//! its shell: the arguments, the input file or stdin, stdout and the exit status.
//!
//! Malformed input (bad lines, frames of a known id with the wrong shape, lost ILD sync) is
//! reported on stderr with its line or byte offset and decoding goes on; the exit status is
//! then 1. Frames with ids outside the message set are reported on stderr too, but are not
//! malformed (a shared bus carries other traffic) and leave the exit status alone.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use scanhil_controller::decode::{Format, Report, decode};
use scanhil_protocol::ild::MeasuringRange;

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
    #[arg(long, default_value_t = MeasuringRange::ILD2300_100.start_mm, allow_negative_numbers = true)]
    pub measuring_range_start_mm: f64,
    /// ILD: length of the measuring range, mm (default: ILD 2300-100).
    #[arg(long, default_value_t = MeasuringRange::ILD2300_100.span_mm, allow_negative_numbers = true)]
    pub measuring_range_span_mm: f64,
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
    let mut report = Report::new(source);
    let mut out = BufWriter::with_capacity(1 << 16, std::io::stdout().lock());
    let reader = BufReader::with_capacity(1 << 16, reader);
    let decoded = decode(reader, args.format, range, &mut out, &mut report);
    report.finish();
    decoded?;
    out.flush().context("cannot write to stdout")?;
    Ok(if report.malformed_count() == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
