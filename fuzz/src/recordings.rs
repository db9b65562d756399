//! Recordings as `scanhil decode` reads them.

use scanhil_controller::decode::{Format, Report, decode as decode_recording};
use scanhil_protocol::ild::MeasuringRange;

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
