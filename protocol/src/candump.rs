//! candump `-L` log lines (can-utils), the format `canplayer`, cantools and python-can read:
//!
//! ```text
//! (1600000000.123456) vcan0 123#DEADBEEF        classical, 11-bit id
//! (1600000000.123456) vcan0 1ABCDEF0#00         classical, 29-bit id (8 digits)
//! (1600000000.123456) vcan0 123#R               remote frame (`#R5`: DLC 5)
//! (1600000000.123456) vcan0 140##1001122...     CAN FD: `##`, flags digit (1 BRS, 2 ESI), data
//! ```
//!
//! The writer puts 6 timestamp decimals and upper-case hex (cantools' reader needs
//! upper case); the reader accepts 6 or 9 decimals and hex of either case.

use std::fmt;

use crate::can::{
    CanFrame, CanId, FrameError, FrameFormat, hex_digit, parse_hex, push_hex_number, push_hex_upper,
};

/// FD flags digit: bit-rate switch.
const FD_FLAG_BRS: u8 = 0x1;
/// FD flags digit: error state indicator.
const FD_FLAG_ESI: u8 = 0x2;

/// A log timestamp: seconds and nanoseconds (exact, no float rounding).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Timestamp {
    /// Whole seconds.
    pub secs: u64,
    /// Nanoseconds, `0..1_000_000_000`.
    pub nanos: u32,
}

impl Timestamp {
    /// The timestamp for a time in seconds (rounded to the nanosecond; negative and non-finite
    /// times give zero).
    #[must_use]
    pub fn from_secs_f64(secs: f64) -> Timestamp {
        if !secs.is_finite() || secs <= 0.0 {
            return Timestamp::default();
        }
        let total_nanos = (secs * 1e9).round();
        Timestamp {
            secs: (total_nanos / 1e9).floor() as u64,
            nanos: (total_nanos % 1e9) as u32,
        }
    }

    /// The time in seconds.
    #[must_use]
    pub fn as_secs_f64(self) -> f64 {
        self.secs as f64 + f64::from(self.nanos) * 1e-9
    }
}

/// One log line: when, on which interface, which frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogEntry {
    /// Reception time.
    pub timestamp: Timestamp,
    /// Interface name (`vcan0`, `can0`, ...).
    pub interface: String,
    /// The frame.
    pub frame: CanFrame,
}

impl fmt::Display for LogEntry {
    /// The `-L` line, without a line end; the timestamp truncated to microseconds
    /// ([`push_line`]).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut line = Vec::with_capacity(64);
        push_line(&mut line, self.timestamp, &self.interface, &self.frame);
        f.write_str(&String::from_utf8_lossy(&line))
    }
}

/// Appends the `-L` line of `frame` on `interface` at `timestamp` to `out`, without a line
/// end, the timestamp truncated to microseconds: what [`LogEntry`] displays, without building
/// an entry or going through the formatting machinery (a capture writes three lines a period).
pub fn push_line(out: &mut Vec<u8>, timestamp: Timestamp, interface: &str, frame: &CanFrame) {
    out.push(b'(');
    push_decimal(out, timestamp.secs, 1);
    out.push(b'.');
    push_decimal(out, u64::from(timestamp.nanos / 1000), 6);
    out.extend_from_slice(b") ");
    out.extend_from_slice(interface.as_bytes());
    out.push(b' ');
    match frame.id() {
        CanId::Standard(id) => push_hex_number(out, u32::from(id.as_raw()), 3),
        CanId::Extended(id) => push_hex_number(out, id.as_raw(), 8),
    }
    match frame.format() {
        FrameFormat::Classical => {
            out.push(b'#');
            push_hex_upper(out, frame.data());
        }
        FrameFormat::Remote => {
            out.extend_from_slice(b"#R");
            if frame.dlc() != 0 {
                push_decimal(out, u64::from(frame.dlc()), 1);
            }
        }
        FrameFormat::Fd { brs, esi } => {
            let flags = (u8::from(brs) * FD_FLAG_BRS) | (u8::from(esi) * FD_FLAG_ESI);
            out.extend_from_slice(b"##");
            push_hex_number(out, u32::from(flags), 1);
            push_hex_upper(out, frame.data());
        }
    }
}

/// Appends `value` in decimal, zero-padded to at least `width` digits.
fn push_decimal(out: &mut Vec<u8>, value: u64, width: usize) {
    let mut digits = [0u8; 20];
    let mut rest = value;
    let mut len = 0;
    loop {
        digits[len] = b'0' + (rest % 10) as u8;
        len += 1;
        rest /= 10;
        if rest == 0 {
            break;
        }
    }
    out.extend(std::iter::repeat_n(b'0', width.saturating_sub(len)));
    out.extend(digits[..len].iter().rev());
}

/// What was wrong with a log line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CandumpErrorKind {
    /// No `(seconds.fraction)` at the start.
    #[error("bad timestamp {0:?} (want `(seconds.micros)` with 6 or 9 decimals)")]
    BadTimestamp(String),
    /// Not `timestamp interface frame`.
    #[error("want `(timestamp) interface frame`, got {0} field(s)")]
    FieldCount(usize),
    /// The frame has no `#`.
    #[error("frame {0:?} has no `#`")]
    NoSeparator(String),
    /// The id is not 3 or 8 hex digits, or too large.
    #[error("bad id {0:?} (want 3 hex digits for 11-bit or 8 for 29-bit)")]
    BadId(String),
    /// The data is not hex pairs.
    #[error("bad data {0:?}")]
    BadData(String),
    /// The FD flags digit is not hex.
    #[error("bad FD flags {0:?}")]
    BadFlags(String),
    /// The frame breaks a CAN rule (length).
    #[error(transparent)]
    Frame(#[from] FrameError),
}

/// A malformed log line and its number.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("candump line {line}: {kind}")]
pub struct CandumpError {
    /// Line number, counting from 1.
    pub line: usize,
    /// What was wrong.
    pub kind: CandumpErrorKind,
}

/// Parses one `-L` line (surrounding blanks ignored).
///
/// # Errors
/// [`CandumpErrorKind`] naming the bad field.
pub fn parse_line(line: &str) -> Result<LogEntry, CandumpErrorKind> {
    let fields: Vec<&str> = line.split_ascii_whitespace().collect();
    let [stamp, interface, frame] = fields[..] else {
        return Err(CandumpErrorKind::FieldCount(fields.len()));
    };
    Ok(LogEntry {
        timestamp: parse_timestamp(stamp)?,
        interface: interface.to_owned(),
        frame: parse_frame(frame)?,
    })
}

/// Parses every non-blank line of a log; errors carry their line number.
pub fn parse_log(text: &str) -> impl Iterator<Item = Result<LogEntry, CandumpError>> + '_ {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| parse_line(l).map_err(|kind| CandumpError { line: i + 1, kind }))
}

fn parse_timestamp(text: &str) -> Result<Timestamp, CandumpErrorKind> {
    let bad = || CandumpErrorKind::BadTimestamp(text.to_owned());
    let inner = text
        .strip_prefix('(')
        .and_then(|t| t.strip_suffix(')'))
        .ok_or_else(bad)?;
    let (secs, fraction) = inner.split_once('.').ok_or_else(bad)?;
    let all_digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    if !all_digits(secs) || !all_digits(fraction) || !matches!(fraction.len(), 6 | 9) {
        return Err(bad());
    }
    let scale = if fraction.len() == 6 { 1000 } else { 1 };
    Ok(Timestamp {
        secs: secs.parse().map_err(|_| bad())?,
        nanos: fraction.parse::<u32>().map_err(|_| bad())? * scale,
    })
}

fn parse_frame(text: &str) -> Result<CanFrame, CandumpErrorKind> {
    let (id_text, rest) = text
        .split_once('#')
        .ok_or_else(|| CandumpErrorKind::NoSeparator(text.to_owned()))?;
    let bad_id = || CandumpErrorKind::BadId(id_text.to_owned());
    let raw = crate::can::parse_hex_u32(id_text.as_bytes()).ok_or_else(bad_id)?;
    let id = match id_text.len() {
        3 => u16::try_from(raw).ok().and_then(CanId::standard),
        8 => CanId::extended(raw),
        _ => None,
    }
    .ok_or_else(bad_id)?;
    let data = |hex: &str| {
        parse_hex(hex.as_bytes()).ok_or_else(|| CandumpErrorKind::BadData(hex.to_owned()))
    };
    if let Some(fd) = rest.strip_prefix('#') {
        let flags = fd
            .bytes()
            .next()
            .and_then(hex_digit)
            .ok_or_else(|| CandumpErrorKind::BadFlags(fd.to_owned()))?;
        let payload = data(&fd[1..])?;
        return Ok(CanFrame::new_fd(
            id,
            &payload,
            flags & FD_FLAG_BRS != 0,
            flags & FD_FLAG_ESI != 0,
        )?);
    }
    if let Some(dlc) = rest.strip_prefix(['R', 'r']) {
        let dlc = match dlc.as_bytes() {
            [] => 0,
            [d] if d.is_ascii_digit() => d - b'0',
            _ => return Err(CandumpErrorKind::BadData(rest.to_owned())),
        };
        return Ok(CanFrame::new_remote(id, dlc)?);
    }
    Ok(CanFrame::new(id, &data(rest)?)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_and_writes_the_documented_examples() {
        for line in [
            "(1600000000.123456) vcan0 123#DEADBEEF",
            "(1600000000.000001) can1 1ABCDEF0#00",
            "(0.000000) vcan0 123#R",
            "(0.000000) vcan0 123#R5",
            "(1.500000) vcan0 140##1000102030405060708090A0B",
        ] {
            let entry = parse_line(line).unwrap();
            assert_eq!(entry.to_string(), line);
        }
    }

    #[test]
    fn nine_decimals_and_lower_case_are_read() {
        let entry = parse_line("(12.123456789) vcan0 1ab#deadbeef").unwrap();
        assert_eq!(
            entry.timestamp,
            Timestamp {
                secs: 12,
                nanos: 123_456_789
            }
        );
        assert_eq!(entry.to_string(), "(12.123456) vcan0 1AB#DEADBEEF");
    }

    #[test]
    fn bad_fields_are_named() {
        assert!(matches!(
            parse_line("(1.12) vcan0 123#00"),
            Err(CandumpErrorKind::BadTimestamp(_))
        ));
        assert!(matches!(
            parse_line("(1.123456) vcan0 1234#00"),
            Err(CandumpErrorKind::BadId(_))
        ));
        assert!(matches!(
            parse_line("(1.123456) vcan0 800#00"),
            Err(CandumpErrorKind::BadId(_))
        ));
        assert!(matches!(
            parse_line("(1.123456) vcan0 123#0011223344556677889"),
            Err(CandumpErrorKind::BadData(_))
        ));
        assert!(matches!(
            parse_line("(1.123456) vcan0 123#001122334455667788"),
            Err(CandumpErrorKind::Frame(_))
        ));
        let errors: Vec<_> = parse_log("\n(1.000000) a 123#\nnonsense\n")
            .filter_map(Result::err)
            .collect();
        assert_eq!(errors.len(), 1);
        assert_eq!(errors[0].line, 3);
    }
}
