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
//! upper case); the reader accepts 6 or 9 decimals and hex of either case, and what a
//! technician's own `candump -L` adds, as can-utils writes it (`snprintf_canframe` in lib.c,
//! the log branch of candump.c):
//!
//! ```text
//! (1600000000.123456) can0 123#1122334455667788_C     8 bytes sent with DLC 12 (`-8`, len8_dlc)
//! (1600000000.123456) can0 123#DEADBEEF R             `-x`: ` R` received, ` T` sent here
//! (1600000000.123456) can0 20000040#0000000000000000  an error frame (`-e`): CAN_ERR_FLAG in the id
//! DROPCOUNT: dropped 3 CAN frames on 'can0' socket (total drops 5)
//! ```
//!
//! [`parse_record`] reads any of these lines; [`parse_line`] only frame lines.

pub mod error_frame;

use std::fmt;

use self::error_frame::{CAN_ERR_FLAG, ErrorFrame};
use crate::can::{
    CanFrame, CanId, FrameError, FrameFormat, hex_digit, parse_hex, push_hex_number, push_hex_upper,
};

/// FD flags digit: bit-rate switch.
const FD_FLAG_BRS: u8 = 0x1;
/// FD flags digit: error state indicator.
const FD_FLAG_ESI: u8 = 0x2;
/// The separator of a classical frame's raw DLC (`CC_DLC_DELIM` in can-utils' lib.c).
const LEN8_DLC_SEPARATOR: char = '_';
/// The start of candump's dropped-frames notice.
const DROPCOUNT_PREFIX: &str = "DROPCOUNT: dropped ";

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

/// One frame line of a log: when, on which interface, which frame, and what candump's `-8`
/// and `-x` options add.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogEntry {
    /// Reception time.
    pub timestamp: Timestamp,
    /// Interface name (`vcan0`, `can0`, ...).
    pub interface: String,
    /// The frame.
    pub frame: CanFrame,
    /// A classical frame's raw DLC above 8 (9..=15, the `_N` suffix), with 8 data bytes.
    pub len8_dlc: Option<u8>,
    /// Whether the frame was received or sent by the logging host (the ` R`/` T` column).
    pub direction: Option<Direction>,
}

impl fmt::Display for LogEntry {
    /// The `-L` line, without a line end; the timestamp truncated to microseconds
    /// ([`push_line`]).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut line = Vec::with_capacity(64);
        push_line(&mut line, self.timestamp, &self.interface, &self.frame);
        f.write_str(&String::from_utf8_lossy(&line))?;
        if let Some(dlc) = self.len8_dlc {
            write!(f, "{LEN8_DLC_SEPARATOR}{dlc:X}")?;
        }
        if let Some(direction) = self.direction {
            write!(f, " {}", direction.letter())?;
        }
        Ok(())
    }
}

/// Which way a frame went, as `candump -x` marks it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Received from the bus (` R`).
    Received,
    /// Sent by the logging host itself (` T`).
    Sent,
}

impl Direction {
    /// Its letter in a `-L` line.
    #[must_use]
    pub fn letter(self) -> char {
        match self {
            Direction::Received => 'R',
            Direction::Sent => 'T',
        }
    }

    fn from_field(field: &str) -> Option<Direction> {
        match field {
            "R" => Some(Direction::Received),
            "T" => Some(Direction::Sent),
            _ => None,
        }
    }
}

/// An error-frame line of a log (`candump -e`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ErrorEntry {
    /// Reception time.
    pub timestamp: Timestamp,
    /// Interface name.
    pub interface: String,
    /// The error frame.
    pub error: ErrorFrame,
    /// The ` R`/` T` column, when logged with `-x`.
    pub direction: Option<Direction>,
}

/// candump's notice that the socket dropped frames (`DROPCOUNT: dropped N CAN frame(s) on
/// 'IFACE' socket (total drops M)`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DropCount {
    /// Frames dropped since the previous notice.
    pub dropped: u32,
    /// The interface.
    pub interface: String,
    /// Frames dropped since the socket opened.
    pub total: u32,
}

/// What one line of a candump log holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LogRecord {
    /// A data, remote or FD frame.
    Frame(LogEntry),
    /// An error frame.
    Error(ErrorEntry),
    /// Frames the logging socket dropped.
    Dropped(DropCount),
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
    /// A `_N` raw DLC that is not 9..=F on a classical frame with 8 data bytes.
    #[error("bad raw DLC {0:?} (want `_9`..`_F` after 8 data bytes of a classical frame)")]
    BadLen8Dlc(String),
    /// A fourth field that is not `R` or `T`.
    #[error("bad direction {0:?} (candump -x writes `R` or `T`)")]
    BadDirection(String),
    /// A `DROPCOUNT:` line not as candump writes it.
    #[error("bad DROPCOUNT line {0:?}")]
    BadDropCount(String),
    /// A valid line that holds no data frame (where only frames are wanted).
    #[error("{0}, not a data frame")]
    NotAFrame(&'static str),
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

/// Parses one `-L` frame line (surrounding blanks ignored): a data, remote or FD frame.
///
/// # Errors
/// [`CandumpErrorKind`] naming the bad field; [`CandumpErrorKind::NotAFrame`] for an error
/// frame or a `DROPCOUNT` line.
pub fn parse_line(line: &str) -> Result<LogEntry, CandumpErrorKind> {
    match parse_record(line)? {
        LogRecord::Frame(entry) => Ok(entry),
        LogRecord::Error(_) => Err(CandumpErrorKind::NotAFrame("an error frame")),
        LogRecord::Dropped(_) => Err(CandumpErrorKind::NotAFrame("a DROPCOUNT notice")),
    }
}

/// Parses one line of a log (surrounding blanks ignored): a frame, an error frame or a
/// `DROPCOUNT` notice.
///
/// # Errors
/// [`CandumpErrorKind`] naming the bad field.
pub fn parse_record(line: &str) -> Result<LogRecord, CandumpErrorKind> {
    let line = line.trim();
    if let Some(rest) = line.strip_prefix(DROPCOUNT_PREFIX) {
        return parse_drop_count(rest)
            .map(LogRecord::Dropped)
            .ok_or_else(|| CandumpErrorKind::BadDropCount(line.to_owned()));
    }
    let fields: Vec<&str> = line.split_ascii_whitespace().collect();
    let (stamp, interface, frame, direction) = match fields[..] {
        [stamp, interface, frame] => (stamp, interface, frame, None),
        [stamp, interface, frame, direction] => (
            stamp,
            interface,
            frame,
            Some(
                Direction::from_field(direction)
                    .ok_or_else(|| CandumpErrorKind::BadDirection(direction.to_owned()))?,
            ),
        ),
        _ => return Err(CandumpErrorKind::FieldCount(fields.len())),
    };
    let timestamp = parse_timestamp(stamp)?;
    let interface = interface.to_owned();
    Ok(match parse_frame(frame)? {
        ParsedFrame::Frame { frame, len8_dlc } => LogRecord::Frame(LogEntry {
            timestamp,
            interface,
            frame,
            len8_dlc,
            direction,
        }),
        ParsedFrame::Error(error) => LogRecord::Error(ErrorEntry {
            timestamp,
            interface,
            error,
            direction,
        }),
    })
}

/// Parses every non-blank frame line of a log; errors carry their line number.
pub fn parse_log(text: &str) -> impl Iterator<Item = Result<LogEntry, CandumpError>> + '_ {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| parse_line(l).map_err(|kind| CandumpError { line: i + 1, kind }))
}

/// `N CAN frame(s) on 'IFACE' socket (total drops M)`.
fn parse_drop_count(rest: &str) -> Option<DropCount> {
    let (dropped, rest) = rest.split_once(' ')?;
    let rest = rest
        .strip_prefix("CAN frames on '")
        .or_else(|| rest.strip_prefix("CAN frame on '"))?;
    let (interface, rest) = rest.split_once("' socket (total drops ")?;
    let total = rest.strip_suffix(')')?;
    Some(DropCount {
        dropped: dropped.parse().ok()?,
        interface: interface.to_owned(),
        total: total.parse().ok()?,
    })
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

/// What the frame field of a line holds.
enum ParsedFrame {
    Frame {
        frame: CanFrame,
        len8_dlc: Option<u8>,
    },
    Error(ErrorFrame),
}

fn parse_frame(text: &str) -> Result<ParsedFrame, CandumpErrorKind> {
    let (id_text, rest) = text
        .split_once('#')
        .ok_or_else(|| CandumpErrorKind::NoSeparator(text.to_owned()))?;
    let bad_id = || CandumpErrorKind::BadId(id_text.to_owned());
    let raw = crate::can::parse_hex_u32(id_text.as_bytes()).ok_or_else(bad_id)?;
    let data = |hex: &str| {
        parse_hex(hex.as_bytes()).ok_or_else(|| CandumpErrorKind::BadData(hex.to_owned()))
    };
    if id_text.len() == 8 && raw & CAN_ERR_FLAG != 0 {
        return ErrorFrame::new(raw, &data(rest)?)
            .map(ParsedFrame::Error)
            .ok_or_else(|| CandumpErrorKind::BadData(rest.to_owned()));
    }
    let id = match id_text.len() {
        3 => u16::try_from(raw).ok().and_then(CanId::standard),
        8 => CanId::extended(raw),
        _ => None,
    }
    .ok_or_else(bad_id)?;
    if let Some(fd) = rest.strip_prefix('#') {
        let flags = fd
            .bytes()
            .next()
            .and_then(hex_digit)
            .ok_or_else(|| CandumpErrorKind::BadFlags(fd.to_owned()))?;
        let payload = data(&fd[1..])?;
        let frame = CanFrame::new_fd(
            id,
            &payload,
            flags & FD_FLAG_BRS != 0,
            flags & FD_FLAG_ESI != 0,
        )?;
        return Ok(ParsedFrame::Frame {
            frame,
            len8_dlc: None,
        });
    }
    let (body, len8_dlc) = split_len8_dlc(rest)?;
    let frame = if let Some(dlc) = body.strip_prefix(['R', 'r']) {
        let dlc = match dlc.as_bytes() {
            [] => 0,
            [d] if d.is_ascii_digit() => d - b'0',
            _ => return Err(CandumpErrorKind::BadData(rest.to_owned())),
        };
        CanFrame::new_remote(id, dlc)?
    } else {
        CanFrame::new(id, &data(body)?)?
    };
    if len8_dlc.is_some() && frame.dlc() != 8 {
        return Err(CandumpErrorKind::BadLen8Dlc(rest.to_owned()));
    }
    Ok(ParsedFrame::Frame { frame, len8_dlc })
}

/// A classical frame's body and its `_N` raw DLC (9..=15), if it has one.
fn split_len8_dlc(rest: &str) -> Result<(&str, Option<u8>), CandumpErrorKind> {
    let Some((body, dlc)) = rest.split_once(LEN8_DLC_SEPARATOR) else {
        return Ok((rest, None));
    };
    match dlc.as_bytes() {
        &[digit] => match hex_digit(digit) {
            Some(dlc @ 9..=15) => Ok((body, Some(dlc))),
            _ => Err(CandumpErrorKind::BadLen8Dlc(rest.to_owned())),
        },
        _ => Err(CandumpErrorKind::BadLen8Dlc(rest.to_owned())),
    }
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

    /// Lines as can-utils writes them (`snprintf_canframe` in lib.c, the log branch of
    /// candump.c, linux-can/can-utils at 95aae6b): `-x` direction, `-e` error frames, `-8` raw
    /// DLC, `-d` drop notices.
    #[test]
    fn a_technicians_candump_lines_are_read() {
        let entry = parse_line("(1764671234.000250) can0 100#0100922E1257B8DB_F T").unwrap();
        assert_eq!(entry.len8_dlc, Some(15));
        assert_eq!(entry.direction, Some(Direction::Sent));
        assert_eq!(entry.frame.data().len(), 8);
        assert_eq!(
            entry.to_string(),
            "(1764671234.000250) can0 100#0100922E1257B8DB_F T"
        );
        let received = parse_line("(1764671234.000000) can0 701#0101000000E80300 R").unwrap();
        assert_eq!(received.direction, Some(Direction::Received));
        assert_eq!(received.len8_dlc, None);
        assert_eq!(
            parse_line("(1.000000) can0 123#R8_9").map(|e| (e.frame.dlc(), e.len8_dlc)),
            Ok((8, Some(9)))
        );
        let LogRecord::Error(error) =
            parse_record("(1764671234.000400) can0 20000040#0000000000000000 R").unwrap()
        else {
            panic!("not an error frame");
        };
        assert!(error.error.is_bus_off());
        assert_eq!(error.direction, Some(Direction::Received));
        assert_eq!(error.interface, "can0");
        assert_eq!(
            parse_line("(1.000000) can0 20000004#0004000000000000"),
            Err(CandumpErrorKind::NotAFrame("an error frame"))
        );
        assert_eq!(
            parse_record("DROPCOUNT: dropped 1 CAN frame on 'vcan0' socket (total drops 7)"),
            Ok(LogRecord::Dropped(DropCount {
                dropped: 1,
                interface: "vcan0".to_owned(),
                total: 7
            }))
        );
        // A padded interface column (`candump -L can0 vcan12`: `%*s`) is still one field.
        assert_eq!(
            parse_line("(1.000000)   can0 123#00").unwrap().interface,
            "can0"
        );
    }

    #[test]
    fn bad_suffixes_are_named() {
        for (line, expected) in [
            ("(1.000000) can0 123#0011_C", "BadLen8Dlc"),
            ("(1.000000) can0 123#1122334455667788_8", "BadLen8Dlc"),
            ("(1.000000) can0 123#1122334455667788_CC", "BadLen8Dlc"),
            ("(1.000000) can0 123##1001122_C", "BadData"),
            ("(1.000000) can0 123#00 X", "BadDirection"),
            ("(1.000000) can0 2000004#00", "BadId"),
            ("(1.000000) can0 20000004#001122334455667788", "BadData"),
            (
                "DROPCOUNT: dropped many CAN frames on 'can0' socket (total drops 7)",
                "BadDropCount",
            ),
        ] {
            let error = format!("{:?}", parse_record(line).unwrap_err());
            assert!(error.starts_with(expected), "{line}: {error}");
        }
    }
}
