//! Recorded scan samples as text: CSV or JSON lines, one sample per line.
//!
//! Columns (CSV header, any order) or keys (JSON lines):
//! - `t_s`: sample time, s;
//! - `d_alpha_rad`, `d_beta_rad`: the mechanical mirror deflections, rad;
//! - exactly one of `z_meas_mm` (the distance in mm; empty in CSV or `null` in JSON for a
//!   missing point) or `ild_raw` (the sensor's 18-bit raw value: a distance through the
//!   measuring range, or an error code, which is a missing point).
//!
//! CSV lines starting with `#` and blank lines are skipped. JSON lines may carry further keys
//! (ignored). A file whose first non-blank character is `{` is read as JSON lines.

use std::collections::BTreeMap;
use std::path::Path;

use scanhil_protocol::ild::value::RAW_MAX;
use scanhil_protocol::ild::{IldValue, MeasuringRange};

use super::reconstruct::ScanSample;

/// Samples read from a recording, with the reasons of the missing ones.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// The samples, in file order.
    pub samples: Vec<ScanSample>,
    /// Missing distances by reason (`empty` for an empty/null `z_meas_mm`, else the ILD
    /// error name such as `no_peak`).
    pub missing_by_reason: BTreeMap<String, usize>,
}

/// Why a recording could not be read.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A line is malformed.
    #[error("{path}:{line}: {field}: {reason}")]
    Line {
        /// The file.
        path: String,
        /// 1-based line number.
        line: usize,
        /// The column or key at fault (or `header`/`line`).
        field: String,
        /// What was wrong.
        reason: String,
    },
}

/// Which distance column a recording carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum DistanceColumn {
    Millimetres,
    IldRaw,
}

/// Reads the recording at `path`; `range` converts `ild_raw` values to millimetres.
pub fn read_recording(path: &Path, range: &MeasuringRange) -> Result<Recording, RecordingError> {
    let text = std::fs::read_to_string(path).map_err(|source| RecordingError::Io {
        path: path.display().to_string(),
        source,
    })?;
    parse_recording(&text, &path.display().to_string(), range)
}

/// Parses recording text; `origin` names it in errors.
pub fn parse_recording(
    text: &str,
    origin: &str,
    range: &MeasuringRange,
) -> Result<Recording, RecordingError> {
    let mut recording = Recording {
        samples: Vec::new(),
        missing_by_reason: BTreeMap::new(),
    };
    let json = text.trim_start().starts_with('{');
    let mut csv_columns: Option<(Vec<String>, DistanceColumn)> = None;
    for (i, line) in text.lines().enumerate() {
        let line_no = i + 1;
        let err = |field: &str, reason: String| RecordingError::Line {
            path: origin.to_string(),
            line: line_no,
            field: field.to_string(),
            reason,
        };
        let trimmed = line.trim();
        if trimmed.is_empty() || (!json && trimmed.starts_with('#')) {
            continue;
        }
        let fields: BTreeMap<String, Option<String>> = if json {
            let value: serde_json::Value = serde_json::from_str(trimmed)
                .map_err(|e| err("line", format!("not a JSON object: {e}")))?;
            let object = value
                .as_object()
                .ok_or_else(|| err("line", "not a JSON object".into()))?;
            object
                .iter()
                .map(|(k, v)| {
                    let text = match v {
                        serde_json::Value::Null => None,
                        serde_json::Value::Number(n) => Some(n.to_string()),
                        other => Some(other.to_string()),
                    };
                    (k.clone(), text)
                })
                .collect()
        } else {
            let Some((names, _)) = &csv_columns else {
                csv_columns = Some(csv_header(trimmed).map_err(|r| err("header", r))?);
                continue;
            };
            let values: Vec<&str> = trimmed.split(',').map(str::trim).collect();
            if values.len() != names.len() {
                return Err(err(
                    "line",
                    format!("{} values for {} columns", values.len(), names.len()),
                ));
            }
            names
                .iter()
                .zip(values)
                .map(|(n, v)| (n.clone(), (!v.is_empty()).then(|| v.to_string())))
                .collect()
        };
        let number = |name: &str| -> Result<f64, RecordingError> {
            let text = fields
                .get(name)
                .ok_or_else(|| err(name, "missing".into()))?
                .as_deref()
                .ok_or_else(|| err(name, "empty".into()))?;
            let v: f64 = text
                .parse()
                .map_err(|_| err(name, format!("'{text}' is not a number")))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(err(name, format!("'{text}' is not finite")))
            }
        };
        let column = match &csv_columns {
            Some((_, c)) => *c,
            None => {
                distance_column(fields.keys().map(String::as_str)).map_err(|r| err("line", r))?
            }
        };
        let z_meas_mm = match column {
            DistanceColumn::Millimetres => match fields.get("z_meas_mm").cloned().flatten() {
                None => {
                    *recording
                        .missing_by_reason
                        .entry("empty".into())
                        .or_default() += 1;
                    None
                }
                Some(_) => Some(number("z_meas_mm")?),
            },
            DistanceColumn::IldRaw => {
                let raw = number("ild_raw")?;
                if raw.fract() != 0.0 || !(0.0..=f64::from(RAW_MAX)).contains(&raw) {
                    // An 18-bit value: beyond it, masking once turned 300000 into 127.93 mm.
                    return Err(err(
                        "ild_raw",
                        format!(
                            "{raw} is not an 18-bit raw value (an integer from 0 to {RAW_MAX})"
                        ),
                    ));
                }
                match IldValue::from_raw(raw as u32) {
                    IldValue::Distance(d) => range.digital_to_mm(d),
                    IldValue::Error(e) => {
                        *recording
                            .missing_by_reason
                            .entry(e.name().into())
                            .or_default() += 1;
                        None
                    }
                }
            }
        };
        recording.samples.push(ScanSample {
            t_s: number("t_s")?,
            d_alpha_rad: number("d_alpha_rad")?,
            d_beta_rad: number("d_beta_rad")?,
            z_meas_mm,
        });
    }
    Ok(recording)
}

fn csv_header(line: &str) -> Result<(Vec<String>, DistanceColumn), String> {
    let names: Vec<String> = line.split(',').map(|s| s.trim().to_string()).collect();
    for required in ["t_s", "d_alpha_rad", "d_beta_rad"] {
        if !names.iter().any(|n| n == required) {
            return Err(format!("no '{required}' column in '{line}'"));
        }
    }
    let column = distance_column(names.iter().map(String::as_str))?;
    Ok((names, column))
}

fn distance_column<'a>(names: impl Iterator<Item = &'a str>) -> Result<DistanceColumn, String> {
    let names: Vec<&str> = names.collect();
    match (names.contains(&"z_meas_mm"), names.contains(&"ild_raw")) {
        (true, false) => Ok(DistanceColumn::Millimetres),
        (false, true) => Ok(DistanceColumn::IldRaw),
        (true, true) => Err("both 'z_meas_mm' and 'ild_raw' given; keep one".into()),
        (false, false) => Err("neither 'z_meas_mm' nor 'ild_raw' given".into()),
    }
}

/// Writes samples as CSV with a `z_meas_mm` column (empty for a missing distance).
pub fn write_recording_csv<W: std::io::Write>(
    mut out: W,
    samples: &[ScanSample],
) -> std::io::Result<()> {
    writeln!(out, "t_s,d_alpha_rad,d_beta_rad,z_meas_mm")?;
    for s in samples {
        let z = s.z_meas_mm.map(|z| format!("{z:?}")).unwrap_or_default();
        writeln!(
            out,
            "{:?},{:?},{:?},{z}",
            s.t_s, s.d_alpha_rad, s.d_beta_rad
        )?;
    }
    out.flush()
}
