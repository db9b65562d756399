//! SLCAN (Lawicel serial-line CAN): the ASCII protocol of USB-CAN adapters such as CANable,
//! spoken over any serial line or pty.
//!
//! Every message is one line ending in CR (`\r`), except the error reply BEL (0x07):
//!
//! | line | meaning |
//! |------|---------|
//! | `tIIILDD..` / `TIIIIIIIILDD..` | classical data frame, 11-bit / 29-bit id, DLC digit `L` |
//! | `rIIIL` / `RIIIIIIIIL` | remote frame |
//! | `dIIIL..` / `DIIIIIIIIL..` | CAN FD frame, DLC hex digit `0`-`F` |
//! | `bIIIL..` / `BIIIIIIIIL..` | CAN FD frame with bit-rate switch |
//! | any frame line + `SSSS` | a frame with the adapter's receive time: 4 hex digits of ms, `0000`-`EA5F` (Lawicel `Z1`) |
//! | `O`, `L`, `C`, `Sn` | open, open listen-only, close, bit rate digit `n` (the rate it sets depends on the adapter: [`family`]) |
//! | `Yn` | CAN FD data bit rate `n` (CANable 2.0 / python-can: `Y2` 2 Mbit/s, `Y5` 5 Mbit/s) |
//! | `V`, `N` | version / serial number request; `Vxxxx`, `Nxxxx` the Lawicel replies |
//! | `F`, `Fxx` | status flags request / reply (Lawicel, [`bus_status::StatusFlags`]) |
//! | `Z0`, `Z1` | receive timestamps off / on (Lawicel; stored in the adapter's EEPROM) |
//! | `sSRRRTTT` | bus state and error counters (the Linux slcan driver's state line) |
//! | `eNXX..` | N bus errors, one letter each (the Linux slcan driver's error line) |
//! | empty line (a bare CR) | OK reply (python-can also sends one as a no-op command) |
//! | BEL | error reply |
//! | `z`, `Z` | transmit acknowledgement Lawicel adapters send |
//! | any other line holding a space or tab | free text: CANable firmware answers `V` with its git version and remote (`b158aa7 git@github.com:...`) |
//!
//! [`SlcanDecoder`] is incremental (bytes in, messages out) and resynchronises at the next CR
//! after garbage; [`SlcanMessage::encode`] writes any message. The same types serve both ends:
//! a host reads frames and replies, a device (the emulator as an adapter) reads commands.
//! SLCAN cannot carry the FD error state indicator: it is written as nothing and read as false.
//!
//! # Layout
//! - [`family`]: adapter families and their `Sn` bit-rate tables.
//! - [`bus_status`]: `Fxx` flags, `s` and `e` lines, and what a host gathers from them.
//! - [`adapter_clock`]: an adapter's millisecond receive stamps placed on the host's clock.

pub mod adapter_clock;
pub mod bus_status;
pub mod family;

use crate::can::{
    CanFrame, CanId, FrameError, FrameFormat, fd_len_for_dlc, hex_digit, hex_upper, parse_hex,
    parse_hex_u32,
};
use adapter_clock::STAMP_MODULUS_MS;
use bus_status::{BusError, BusState, StateReport, StatusFlags};

/// The line terminator.
pub const CR: u8 = b'\r';
/// The error reply.
pub const BEL: u8 = 0x07;
/// The longest valid line: `D` + 8 id digits + DLC digit + 64 data bytes in hex + a 4-digit
/// receive timestamp.
pub const MAX_LINE_LEN: usize = 1 + 8 + 1 + 2 * crate::can::FD_MAX_LEN + TIMESTAMP_DIGITS;
/// Hex digits of a frame's receive timestamp (Lawicel `Z1`).
pub const TIMESTAMP_DIGITS: usize = 4;

/// One SLCAN message: a frame, a command or a reply.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SlcanMessage {
    /// A CAN or CAN FD frame (received from or to be sent on the bus).
    Frame(CanFrame),
    /// A frame an adapter received, with its receive time (Lawicel `Z1`): milliseconds on the
    /// adapter's clock, `0..60000`.
    StampedFrame {
        /// The frame.
        frame: CanFrame,
        /// The adapter's receive time, ms modulo 60 000.
        timestamp_ms: u16,
    },
    /// `O`: open the channel.
    Open,
    /// `L`: open the channel listen-only.
    ListenOnly,
    /// `C`: close the channel.
    Close,
    /// `Sn`: set the bit rate by the adapter's digit `n` (0-9; what it sets depends on the
    /// adapter's [`family::AdapterFamily`]).
    Bitrate(u8),
    /// `Yn`: set the CAN FD data bit rate by the adapter's digit `n` (`Y2` 2 Mbit/s, `Y5`
    /// 5 Mbit/s on CANable 2.0 and in python-can; other digits are firmware-specific). One
    /// digit, 0-9: a larger value is written as `Y9`.
    DataBitrate(u8),
    /// `V`: ask for the version.
    VersionRequest,
    /// `N`: ask for the serial number.
    SerialRequest,
    /// `Vxxxx`: the version reply (the text after `V`).
    Version(String),
    /// `Nxxxx`: the serial number reply (the text after `N`).
    Serial(String),
    /// `z` / `Z`: a transmit acknowledgement (11-bit / 29-bit frame sent).
    TransmitAck {
        /// True for `Z` (a 29-bit frame was sent).
        extended: bool,
    },
    /// `F`: ask for the status flags.
    StatusRequest,
    /// `Fxx`: the status flags.
    StatusFlags(StatusFlags),
    /// `Z0` / `Z1`: receive timestamps off / on.
    Timestamps(bool),
    /// `sSRRRTTT`: the adapter's bus state and error counters.
    BusState(StateReport),
    /// `eNXX..`: bus errors the adapter saw (one to eight).
    BusErrors(Vec<BusError>),
    /// A line of free text (it holds a space or a tab; no SLCAN message does): a CANable's
    /// version, an adapter's debug output.
    Text(String),
    /// A bare CR: the OK reply.
    Ack,
    /// BEL: the error reply.
    Nack,
}

/// What was wrong with an SLCAN line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SlcanErrorKind {
    /// The line starts with a character that is no SLCAN command.
    #[error("unknown command character {0:?}")]
    UnknownCommand(char),
    /// A frame line of the wrong length for its DLC.
    #[error("frame line has {got} characters, its DLC needs {expected}")]
    BadLength {
        /// Characters the DLC requires.
        expected: usize,
        /// Characters the line has.
        got: usize,
    },
    /// Identifier digits that are not hex or too large for the id format.
    #[error("bad identifier {0:?}")]
    BadId(String),
    /// A DLC character that is not allowed for the frame type.
    #[error("bad DLC character {0:?}")]
    BadDlc(char),
    /// Data characters that are not hex.
    #[error("data is not hex: {0:?}")]
    BadData(String),
    /// A frame the CAN rules reject.
    #[error(transparent)]
    Frame(#[from] FrameError),
    /// A command line that does not follow its format (`S` without one digit, `F7E0,7FF`).
    #[error("bad command {0:?}")]
    BadCommand(String),
    /// A frame's receive timestamp beyond `EA5F` (59 999 ms).
    #[error("receive timestamp {0:?} is beyond EA5F (59999 ms)")]
    BadTimestamp(String),
    /// A reply text with characters that are not printable ASCII.
    #[error("reply text is not printable ASCII")]
    BadReplyText,
    /// More than [`MAX_LINE_LEN`] characters before a CR.
    #[error("line longer than {MAX_LINE_LEN} characters")]
    LineTooLong,
    /// A line cut short by a BEL or by the end of the input.
    #[error("incomplete line {0:?}")]
    Incomplete(String),
}

/// A malformed SLCAN line and where it started in the byte stream.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("SLCAN byte offset {offset}: {kind}")]
pub struct SlcanError {
    /// Byte offset of the line's first character in the stream given to the decoder.
    pub offset: u64,
    /// What was wrong.
    pub kind: SlcanErrorKind,
}

/// What the decoder yields: a message, or a malformed line it skipped.
pub type SlcanEvent = Result<SlcanMessage, SlcanError>;

/// Incremental SLCAN parser: push bytes as they arrive, get whole messages back.
///
/// Garbage is reported once per line and skipped up to the next CR, so one bad byte costs
/// at most one line. A line feed at the start of a line is ignored (CR LF senders).
#[derive(Debug, Clone, Default)]
pub struct SlcanDecoder {
    line: Vec<u8>,
    line_start: u64,
    position: u64,
    overflow: bool,
}

impl SlcanDecoder {
    /// A decoder at the start of a stream.
    #[must_use]
    pub fn new() -> SlcanDecoder {
        SlcanDecoder::default()
    }

    /// Feeds `bytes`; returns the messages and errors they complete, in order.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<SlcanEvent> {
        let mut events = Vec::new();
        for &byte in bytes {
            self.push_byte(byte, &mut events);
        }
        events
    }

    /// Ends the stream: a partial line left over is reported as incomplete.
    pub fn finish(&mut self) -> Option<SlcanError> {
        let error = (!self.line.is_empty() || self.overflow).then(|| self.incomplete_line());
        self.start_line(self.position);
        error
    }

    /// Bytes consumed so far.
    #[must_use]
    pub fn position(&self) -> u64 {
        self.position
    }

    fn push_byte(&mut self, byte: u8, events: &mut Vec<SlcanEvent>) {
        let offset = self.position;
        self.position += 1;
        match byte {
            CR => {
                let event = if self.overflow {
                    Err(self.error(SlcanErrorKind::LineTooLong))
                } else {
                    parse_line(&self.line).map_err(|kind| self.error(kind))
                };
                events.push(event);
                self.start_line(self.position);
            }
            BEL => {
                if !self.line.is_empty() || self.overflow {
                    events.push(Err(self.incomplete_line()));
                }
                events.push(Ok(SlcanMessage::Nack));
                self.start_line(self.position);
            }
            b'\n' if self.line.is_empty() && !self.overflow => self.start_line(self.position),
            _ if self.line.len() < MAX_LINE_LEN => {
                if self.line.is_empty() {
                    self.line_start = offset;
                }
                self.line.push(byte);
            }
            _ => self.overflow = true,
        }
    }

    fn start_line(&mut self, at: u64) {
        self.line.clear();
        self.overflow = false;
        self.line_start = at;
    }

    fn incomplete_line(&self) -> SlcanError {
        let text = String::from_utf8_lossy(&self.line).into_owned();
        self.error(SlcanErrorKind::Incomplete(text))
    }

    fn error(&self, kind: SlcanErrorKind) -> SlcanError {
        SlcanError {
            offset: self.line_start,
            kind,
        }
    }
}

/// Parses one line without its CR: an SLCAN message, or free text when the line holds a space
/// or tab and nothing unprintable.
fn parse_line(line: &[u8]) -> Result<SlcanMessage, SlcanErrorKind> {
    parse_message(line).or_else(|kind| free_text(line).ok_or(kind))
}

/// The line as [`SlcanMessage::Text`] if it is free text.
fn free_text(line: &[u8]) -> Option<SlcanMessage> {
    let blank = line.iter().any(|&c| c == b' ' || c == b'\t');
    let printable = line
        .iter()
        .all(|&c| c == b'\t' || (b' '..=b'~').contains(&c));
    (blank && printable).then(|| SlcanMessage::Text(String::from_utf8_lossy(line).into_owned()))
}

/// Parses one line as an SLCAN message.
fn parse_message(line: &[u8]) -> Result<SlcanMessage, SlcanErrorKind> {
    let Some((&command, rest)) = line.split_first() else {
        return Ok(SlcanMessage::Ack);
    };
    match command {
        b't' | b'T' | b'r' | b'R' | b'd' | b'D' | b'b' | b'B' => {
            let (frame, timestamp) = parse_frame(command, rest)?;
            Ok(match timestamp {
                None => SlcanMessage::Frame(frame),
                Some(timestamp_ms) => SlcanMessage::StampedFrame {
                    frame,
                    timestamp_ms,
                },
            })
        }
        b'O' | b'L' | b'C' | b'N' | b'V' | b'z' | b'Z' | b'F' if rest.is_empty() => {
            Ok(match command {
                b'O' => SlcanMessage::Open,
                b'L' => SlcanMessage::ListenOnly,
                b'C' => SlcanMessage::Close,
                b'N' => SlcanMessage::SerialRequest,
                b'V' => SlcanMessage::VersionRequest,
                b'F' => SlcanMessage::StatusRequest,
                other => SlcanMessage::TransmitAck {
                    extended: other == b'Z',
                },
            })
        }
        b'S' | b'Y' => match rest {
            [digit] if digit.is_ascii_digit() => Ok(if command == b'S' {
                SlcanMessage::Bitrate(digit - b'0')
            } else {
                SlcanMessage::DataBitrate(digit - b'0')
            }),
            _ => Err(bad_command(line)),
        },
        b'Z' => match rest {
            [b'0'] => Ok(SlcanMessage::Timestamps(false)),
            [b'1'] => Ok(SlcanMessage::Timestamps(true)),
            _ => Err(bad_command(line)),
        },
        b'F' => match rest {
            [high, low] => match (hex_digit(*high), hex_digit(*low)) {
                (Some(high), Some(low)) => {
                    Ok(SlcanMessage::StatusFlags(StatusFlags(high << 4 | low)))
                }
                _ => Err(bad_command(line)),
            },
            _ => Err(bad_command(line)),
        },
        b's' => parse_state(rest)
            .map(SlcanMessage::BusState)
            .ok_or_else(|| bad_command(line)),
        b'e' => parse_errors(rest)
            .map(SlcanMessage::BusErrors)
            .ok_or_else(|| bad_command(line)),
        b'V' | b'N' => {
            if !rest.iter().all(|c| c.is_ascii_graphic() || *c == b' ') {
                return Err(SlcanErrorKind::BadReplyText);
            }
            let text = String::from_utf8_lossy(rest).into_owned();
            Ok(if command == b'V' {
                SlcanMessage::Version(text)
            } else {
                SlcanMessage::Serial(text)
            })
        }
        b'O' | b'L' | b'C' | b'z' => Err(bad_command(line)),
        other => Err(SlcanErrorKind::UnknownCommand(char::from(other))),
    }
}

fn bad_command(line: &[u8]) -> SlcanErrorKind {
    SlcanErrorKind::BadCommand(String::from_utf8_lossy(line).into_owned())
}

/// An `s` line after its `s`: state letter, then the receive and transmit error counters as
/// three decimal digits each.
fn parse_state(rest: &[u8]) -> Option<StateReport> {
    let [letter, digits @ ..] = rest else {
        return None;
    };
    if digits.len() != 6 || !digits.iter().all(u8::is_ascii_digit) {
        return None;
    }
    let counter = |digits: &[u8]| {
        digits
            .iter()
            .fold(0u16, |acc, &d| acc * 10 + u16::from(d - b'0'))
    };
    Some(StateReport {
        state: BusState::from_letter(*letter)?,
        rx_errors: counter(&digits[..3]),
        tx_errors: counter(&digits[3..]),
    })
}

/// An `e` line after its `e`: the count (1 to 8), then one letter per error.
fn parse_errors(rest: &[u8]) -> Option<Vec<BusError>> {
    let [count, letters @ ..] = rest else {
        return None;
    };
    let count = usize::from(count.checked_sub(b'0')?);
    if !(1..=MAX_BUS_ERRORS).contains(&count) || letters.len() != count {
        return None;
    }
    letters.iter().map(|&l| BusError::from_letter(l)).collect()
}

/// The most errors one `e` line carries (its count is one decimal digit, the driver takes
/// at most 8).
pub const MAX_BUS_ERRORS: usize = 8;

/// Parses a frame line after its command character: the frame, and its receive timestamp
/// when the line carries one.
fn parse_frame(command: u8, rest: &[u8]) -> Result<(CanFrame, Option<u16>), SlcanErrorKind> {
    let extended = command.is_ascii_uppercase();
    let id_digits = if extended { 8 } else { 3 };
    let header = id_digits + 1;
    if rest.len() < header {
        return Err(SlcanErrorKind::BadLength {
            expected: header + 1,
            got: rest.len() + 1,
        });
    }
    let (id_text, tail) = rest.split_at(id_digits);
    let raw_id = parse_hex_u32(id_text);
    let id = if extended {
        raw_id.and_then(CanId::extended)
    } else {
        raw_id
            .and_then(|r| u16::try_from(r).ok())
            .and_then(CanId::standard)
    }
    .ok_or_else(|| SlcanErrorKind::BadId(String::from_utf8_lossy(id_text).into_owned()))?;
    let dlc_char = tail[0];
    let is_fd = matches!(command, b'd' | b'D' | b'b' | b'B');
    let dlc = hex_digit(dlc_char)
        .filter(|&d| is_fd || d <= 8)
        .ok_or(SlcanErrorKind::BadDlc(char::from(dlc_char)))?;
    let is_remote = matches!(command, b'r' | b'R');
    let len = if is_fd {
        fd_len_for_dlc(dlc)
    } else {
        usize::from(dlc)
    };
    let expected_data_chars = if is_remote { 0 } else { 2 * len };
    let (data_text, stamp_text) = match tail[1..].len() {
        n if n == expected_data_chars + TIMESTAMP_DIGITS => tail[1..].split_at(expected_data_chars),
        _ => (&tail[1..], &[][..]),
    };
    if data_text.len() != expected_data_chars {
        return Err(SlcanErrorKind::BadLength {
            expected: 1 + header + expected_data_chars,
            got: 1 + rest.len(),
        });
    }
    let timestamp = if stamp_text.is_empty() {
        None
    } else {
        Some(parse_timestamp(stamp_text)?)
    };
    if is_remote {
        return Ok((CanFrame::new_remote(id, dlc)?, timestamp));
    }
    let data = parse_hex(data_text)
        .ok_or_else(|| SlcanErrorKind::BadData(String::from_utf8_lossy(data_text).into_owned()))?;
    let frame = if is_fd {
        CanFrame::new_fd(id, &data, matches!(command, b'b' | b'B'), false)?
    } else {
        CanFrame::new(id, &data)?
    };
    Ok((frame, timestamp))
}

/// Four hex digits of milliseconds, at most `EA5F`.
fn parse_timestamp(text: &[u8]) -> Result<u16, SlcanErrorKind> {
    parse_hex_u32(text)
        .and_then(|ms| u16::try_from(ms).ok())
        .filter(|&ms| ms < STAMP_MODULUS_MS)
        .ok_or_else(|| SlcanErrorKind::BadTimestamp(String::from_utf8_lossy(text).into_owned()))
}

impl SlcanMessage {
    /// The message as SLCAN text, terminator included (CR, or the bare BEL of [`Self::Nack`]).
    #[must_use]
    pub fn encode(&self) -> String {
        match self {
            SlcanMessage::Frame(frame) => return encode_frame(frame),
            SlcanMessage::StampedFrame {
                frame,
                timestamp_ms,
            } => return encode_stamped_frame(frame, *timestamp_ms),
            SlcanMessage::Nack => return char::from(BEL).to_string(),
            _ => {}
        }
        let body = match self {
            SlcanMessage::Open => "O".to_owned(),
            SlcanMessage::ListenOnly => "L".to_owned(),
            SlcanMessage::Close => "C".to_owned(),
            SlcanMessage::Bitrate(code) => format!("S{}", code.min(&9)),
            SlcanMessage::DataBitrate(code) => format!("Y{}", code.min(&9)),
            SlcanMessage::VersionRequest => "V".to_owned(),
            SlcanMessage::SerialRequest => "N".to_owned(),
            SlcanMessage::Version(text) => format!("V{text}"),
            SlcanMessage::Serial(text) => format!("N{text}"),
            SlcanMessage::TransmitAck { extended } => if *extended { "Z" } else { "z" }.to_owned(),
            SlcanMessage::StatusRequest => "F".to_owned(),
            SlcanMessage::StatusFlags(flags) => format!("F{:02X}", flags.0),
            SlcanMessage::Timestamps(on) => if *on { "Z1" } else { "Z0" }.to_owned(),
            SlcanMessage::BusState(report) => format!(
                "s{}{:03}{:03}",
                char::from(report.state.letter()),
                report.rx_errors.min(999),
                report.tx_errors.min(999)
            ),
            SlcanMessage::BusErrors(errors) => {
                let errors = &errors[..errors.len().min(MAX_BUS_ERRORS)];
                let letters: String = errors.iter().map(|e| char::from(e.letter())).collect();
                format!("e{}{letters}", errors.len())
            }
            SlcanMessage::Text(text) => text.clone(),
            SlcanMessage::Ack
            | SlcanMessage::Frame(_)
            | SlcanMessage::StampedFrame { .. }
            | SlcanMessage::Nack => String::new(),
        };
        body + "\r"
    }
}

/// A frame's line with the adapter's receive time `timestamp_ms` (taken modulo 60 000) as
/// four hex digits before the CR: `t1230EA5F\r`.
#[must_use]
pub fn encode_stamped_frame(frame: &CanFrame, timestamp_ms: u16) -> String {
    let mut line = encode_frame(frame);
    line.pop();
    line + &format!("{:04X}\r", timestamp_ms % STAMP_MODULUS_MS)
}

/// One frame as an SLCAN line with its CR: `t1238DEADBEEF01020304\r`.
#[must_use]
pub fn encode_frame(frame: &CanFrame) -> String {
    let command = match frame.format() {
        FrameFormat::Classical => 't',
        FrameFormat::Remote => 'r',
        FrameFormat::Fd { brs: false, .. } => 'd',
        FrameFormat::Fd { brs: true, .. } => 'b',
    };
    let command = if frame.id().is_extended() {
        command.to_ascii_uppercase()
    } else {
        command
    };
    format!(
        "{command}{}{:X}{}\r",
        frame.id(),
        frame.dlc(),
        hex_upper(frame.data())
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::new(CanId::standard(id).unwrap(), data).unwrap()
    }

    #[test]
    fn decodes_the_python_can_examples() {
        let mut decoder = SlcanDecoder::new();
        let events = decoder.push(b"t1238DEADBEEF01020304\rt3213010203\r");
        assert_eq!(
            events,
            vec![
                Ok(SlcanMessage::Frame(frame(
                    0x123,
                    &[0xDE, 0xAD, 0xBE, 0xEF, 1, 2, 3, 4]
                ))),
                Ok(SlcanMessage::Frame(frame(0x321, &[1, 2, 3]))),
            ]
        );
        assert_eq!(
            decoder.push(b"C\rS8\rO\r\r\x07"),
            vec![
                Ok(SlcanMessage::Close),
                Ok(SlcanMessage::Bitrate(8)),
                Ok(SlcanMessage::Open),
                Ok(SlcanMessage::Ack),
                Ok(SlcanMessage::Nack),
            ]
        );
    }

    #[test]
    fn garbage_costs_one_line_and_names_its_offset() {
        let mut decoder = SlcanDecoder::new();
        let events = decoder.push(b"t12\rxyz\rt1230\r");
        assert_eq!(events.len(), 3);
        assert_eq!(events[0].as_ref().unwrap_err().offset, 0);
        assert_eq!(
            events[1].as_ref().unwrap_err().kind,
            SlcanErrorKind::UnknownCommand('x')
        );
        assert_eq!(events[1].as_ref().unwrap_err().offset, 4);
        assert_eq!(events[2], Ok(SlcanMessage::Frame(frame(0x123, &[]))));
    }

    #[test]
    fn timestamped_frames_carry_the_adapters_milliseconds() {
        let mut decoder = SlcanDecoder::new();
        let events = decoder.push(b"t1238DEADBEEF01020304EA5F\rr1232002A\rt1230ea60\rt12300\r");
        assert_eq!(
            events[0],
            Ok(SlcanMessage::StampedFrame {
                frame: frame(0x123, &[0xDE, 0xAD, 0xBE, 0xEF, 1, 2, 3, 4]),
                timestamp_ms: 0xEA5F,
            })
        );
        let remote = CanFrame::new_remote(CanId::standard(0x123).unwrap(), 2).unwrap();
        assert_eq!(
            events[1],
            Ok(SlcanMessage::StampedFrame {
                frame: remote,
                timestamp_ms: 0x2A,
            })
        );
        // 60 000 ms is past the wrap; two extra digits are no timestamp.
        assert!(matches!(
            &events[2],
            Err(SlcanError { kind: SlcanErrorKind::BadTimestamp(text), .. }) if text == "ea60"
        ));
        assert!(matches!(
            &events[3],
            Err(SlcanError {
                kind: SlcanErrorKind::BadLength { .. },
                ..
            })
        ));
        assert_eq!(encode_stamped_frame(&remote, 0x2A), "r1232002A\r");
        assert_eq!(encode_stamped_frame(&remote, 60_001), "r12320001\r");
    }

    #[test]
    fn status_state_and_error_lines_parse_and_write_back() {
        let mut decoder = SlcanDecoder::new();
        let text = b"F\rF8a\rZ1\rZ0\rsb256256\rsa057033\re3bcO\re1a\r";
        let events: Vec<_> = decoder.push(text).into_iter().map(Result::unwrap).collect();
        let expected = vec![
            SlcanMessage::StatusRequest,
            SlcanMessage::StatusFlags(StatusFlags(0x8A)),
            SlcanMessage::Timestamps(true),
            SlcanMessage::Timestamps(false),
            SlcanMessage::BusState(StateReport {
                state: BusState::BusOff,
                rx_errors: 256,
                tx_errors: 256,
            }),
            SlcanMessage::BusState(StateReport {
                state: BusState::ErrorActive,
                rx_errors: 57,
                tx_errors: 33,
            }),
            SlcanMessage::BusErrors(vec![BusError::Bit0, BusError::Crc, BusError::TxOverrun]),
            SlcanMessage::BusErrors(vec![BusError::Ack]),
        ];
        assert_eq!(events, expected);
        let written: String = expected.iter().map(SlcanMessage::encode).collect();
        assert_eq!(written, "F\rF8A\rZ1\rZ0\rsb256256\rsa057033\re3bcO\re1a\r");
        for bad in [
            "F7E0,7FF",
            "F8",
            "Z2",
            "sx000000",
            "sa05703",
            "sa05a033",
            "e2a",
            "e0",
            "e9aaaaaaaaa",
            "e1x",
            "S",
            "SA",
        ] {
            let events = SlcanDecoder::new().push(format!("{bad}\r").as_bytes());
            assert!(
                matches!(
                    &events[0],
                    Err(SlcanError {
                        kind: SlcanErrorKind::BadCommand(_),
                        ..
                    })
                ),
                "{bad}: {events:?}"
            );
        }
        assert_eq!(
            SlcanDecoder::new().push(b"S9\r"),
            vec![Ok(SlcanMessage::Bitrate(9))]
        );
    }

    #[test]
    fn lines_with_blanks_are_free_text_unless_they_parse() {
        let mut decoder = SlcanDecoder::new();
        let events = decoder.push(
            b"b158aa7 git@github.com:normaldotcom/canable2-fw.git\r+Board: X\tMCU: Y\rV1 2\rt12 3\x01\r",
        );
        assert_eq!(
            events[0],
            Ok(SlcanMessage::Text(
                "b158aa7 git@github.com:normaldotcom/canable2-fw.git".into()
            ))
        );
        assert_eq!(
            events[1],
            Ok(SlcanMessage::Text("+Board: X\tMCU: Y".into()))
        );
        assert_eq!(events[2], Ok(SlcanMessage::Version("1 2".into())));
        assert!(events[3].is_err(), "an unprintable byte makes it garbage");
        assert_eq!(SlcanMessage::Text("a b".into()).encode(), "a b\r");
    }

    #[test]
    fn overlong_lines_are_cut_and_partial_lines_reported_at_the_end() {
        let mut decoder = SlcanDecoder::new();
        let mut input = vec![b't'; MAX_LINE_LEN + 10];
        input.push(CR);
        let events = decoder.push(&input);
        assert_eq!(
            events[0].as_ref().unwrap_err().kind,
            SlcanErrorKind::LineTooLong
        );
        assert!(decoder.push(b"t12").is_empty());
        assert!(decoder.finish().is_some());
    }

    #[test]
    fn fd_and_extended_frames_encode_as_expected() {
        let id = CanId::extended(0x1ABC_DEF0).unwrap();
        let fd = CanFrame::new_fd(id, &[0xAA; 12], true, false).unwrap();
        assert_eq!(
            encode_frame(&fd),
            format!("B1ABCDEF09{}\r", "AA".repeat(12))
        );
        let remote = CanFrame::new_remote(CanId::standard(0x7FF).unwrap(), 2).unwrap();
        assert_eq!(encode_frame(&remote), "r7FF2\r");
        assert_eq!(SlcanMessage::Nack.encode(), "\x07");
        assert_eq!(SlcanMessage::Version("1013".into()).encode(), "V1013\r");
    }
}
