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
//! | `O`, `L`, `C`, `Sn` | open, open listen-only, close, bit rate `n` (`S0` 10 kbit/s .. `S8` 1 Mbit/s) |
//! | `Yn` | CAN FD data bit rate `n` (CANable 2.0 / python-can: `Y2` 2 Mbit/s, `Y5` 5 Mbit/s) |
//! | `V`, `N` | version / serial number request; `Vxxxx`, `Nxxxx` the replies |
//! | empty line (a bare CR) | OK reply (python-can also sends one as a no-op command) |
//! | BEL | error reply |
//! | `z`, `Z` | transmit acknowledgement some adapters send |
//!
//! [`SlcanDecoder`] is incremental (bytes in, messages out) and resynchronises at the next CR
//! after garbage; [`SlcanMessage::encode`] writes any message. The same types serve both ends:
//! a host reads frames and replies, a device (the emulator as an adapter) reads commands.
//! SLCAN cannot carry the FD error state indicator: it is written as nothing and read as false.

use crate::can::{
    CanFrame, CanId, FrameError, FrameFormat, fd_len_for_dlc, hex_digit, hex_upper, parse_hex,
    parse_hex_u32,
};

/// The line terminator.
pub const CR: u8 = b'\r';
/// The error reply.
pub const BEL: u8 = 0x07;
/// The longest valid line: `D` + 8 id digits + DLC digit + 64 data bytes in hex.
pub const MAX_LINE_LEN: usize = 1 + 8 + 1 + 2 * crate::can::FD_MAX_LEN;

/// The bit rates of the `Sn` command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SlcanBitrate {
    /// `S0`: 10 kbit/s.
    Kbit10,
    /// `S1`: 20 kbit/s.
    Kbit20,
    /// `S2`: 50 kbit/s.
    Kbit50,
    /// `S3`: 100 kbit/s.
    Kbit100,
    /// `S4`: 125 kbit/s.
    Kbit125,
    /// `S5`: 250 kbit/s.
    Kbit250,
    /// `S6`: 500 kbit/s.
    Kbit500,
    /// `S7`: 800 kbit/s.
    Kbit800,
    /// `S8`: 1 Mbit/s.
    Mbit1,
}

impl SlcanBitrate {
    const ALL: [SlcanBitrate; 9] = [
        SlcanBitrate::Kbit10,
        SlcanBitrate::Kbit20,
        SlcanBitrate::Kbit50,
        SlcanBitrate::Kbit100,
        SlcanBitrate::Kbit125,
        SlcanBitrate::Kbit250,
        SlcanBitrate::Kbit500,
        SlcanBitrate::Kbit800,
        SlcanBitrate::Mbit1,
    ];
    const BITS_PER_S: [u32; 9] = [
        10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
    ];

    /// The digit `n` of the `Sn` command.
    #[must_use]
    pub fn code(self) -> u8 {
        Self::ALL.iter().position(|&b| b == self).unwrap_or(0) as u8
    }

    /// The bit rate for the digit `n` of `Sn`, `None` above 8.
    #[must_use]
    pub fn from_code(code: u8) -> Option<SlcanBitrate> {
        Self::ALL.get(usize::from(code)).copied()
    }

    /// The bit rate in bit/s.
    #[must_use]
    pub fn bits_per_s(self) -> u32 {
        Self::BITS_PER_S[usize::from(self.code())]
    }

    /// The `Sn` setting for exactly `bits_per_s`, `None` if SLCAN has no code for it.
    #[must_use]
    pub fn from_bits_per_s(bits_per_s: u32) -> Option<SlcanBitrate> {
        Self::BITS_PER_S
            .iter()
            .position(|&b| b == bits_per_s)
            .map(|i| Self::ALL[i])
    }
}

/// One SLCAN message: a frame, a command or a reply.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SlcanMessage {
    /// A CAN or CAN FD frame (received from or to be sent on the bus).
    Frame(CanFrame),
    /// `O`: open the channel.
    Open,
    /// `L`: open the channel listen-only.
    ListenOnly,
    /// `C`: close the channel.
    Close,
    /// `Sn`: set the bit rate.
    Bitrate(SlcanBitrate),
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
    /// `Sn` with `n` not in 0..=8, or a malformed command line.
    #[error("bad command {0:?}")]
    BadCommand(String),
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

/// Parses one line without its CR.
fn parse_line(line: &[u8]) -> Result<SlcanMessage, SlcanErrorKind> {
    let Some((&command, rest)) = line.split_first() else {
        return Ok(SlcanMessage::Ack);
    };
    match command {
        b't' | b'T' | b'r' | b'R' | b'd' | b'D' | b'b' | b'B' => {
            parse_frame(command, rest).map(SlcanMessage::Frame)
        }
        b'O' | b'L' | b'C' | b'N' | b'V' | b'z' | b'Z' if rest.is_empty() => Ok(match command {
            b'O' => SlcanMessage::Open,
            b'L' => SlcanMessage::ListenOnly,
            b'C' => SlcanMessage::Close,
            b'N' => SlcanMessage::SerialRequest,
            b'V' => SlcanMessage::VersionRequest,
            other => SlcanMessage::TransmitAck {
                extended: other == b'Z',
            },
        }),
        b'S' => match rest {
            [digit] => digit
                .checked_sub(b'0')
                .and_then(SlcanBitrate::from_code)
                .map(SlcanMessage::Bitrate)
                .ok_or_else(|| bad_command(line)),
            _ => Err(bad_command(line)),
        },
        b'Y' => match rest {
            [digit] if digit.is_ascii_digit() => Ok(SlcanMessage::DataBitrate(digit - b'0')),
            _ => Err(bad_command(line)),
        },
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
        b'O' | b'L' | b'C' | b'z' | b'Z' => Err(bad_command(line)),
        other => Err(SlcanErrorKind::UnknownCommand(char::from(other))),
    }
}

fn bad_command(line: &[u8]) -> SlcanErrorKind {
    SlcanErrorKind::BadCommand(String::from_utf8_lossy(line).into_owned())
}

/// Parses a frame line after its command character.
fn parse_frame(command: u8, rest: &[u8]) -> Result<CanFrame, SlcanErrorKind> {
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
    let data_text = &tail[1..];
    let is_remote = matches!(command, b'r' | b'R');
    let len = if is_fd {
        fd_len_for_dlc(dlc)
    } else {
        usize::from(dlc)
    };
    let expected_data_chars = if is_remote { 0 } else { 2 * len };
    if data_text.len() != expected_data_chars {
        return Err(SlcanErrorKind::BadLength {
            expected: 1 + header + expected_data_chars,
            got: 1 + rest.len(),
        });
    }
    if is_remote {
        return Ok(CanFrame::new_remote(id, dlc)?);
    }
    let data = parse_hex(data_text)
        .ok_or_else(|| SlcanErrorKind::BadData(String::from_utf8_lossy(data_text).into_owned()))?;
    Ok(if is_fd {
        CanFrame::new_fd(id, &data, matches!(command, b'b' | b'B'), false)?
    } else {
        CanFrame::new(id, &data)?
    })
}

impl SlcanMessage {
    /// The message as SLCAN text, terminator included (CR, or the bare BEL of [`Self::Nack`]).
    #[must_use]
    pub fn encode(&self) -> String {
        match self {
            SlcanMessage::Frame(frame) => return encode_frame(frame),
            SlcanMessage::Nack => return char::from(BEL).to_string(),
            _ => {}
        }
        let body = match self {
            SlcanMessage::Open => "O".to_owned(),
            SlcanMessage::ListenOnly => "L".to_owned(),
            SlcanMessage::Close => "C".to_owned(),
            SlcanMessage::Bitrate(rate) => format!("S{}", rate.code()),
            SlcanMessage::DataBitrate(code) => format!("Y{}", code.min(&9)),
            SlcanMessage::VersionRequest => "V".to_owned(),
            SlcanMessage::SerialRequest => "N".to_owned(),
            SlcanMessage::Version(text) => format!("V{text}"),
            SlcanMessage::Serial(text) => format!("N{text}"),
            SlcanMessage::TransmitAck { extended } => if *extended { "Z" } else { "z" }.to_owned(),
            SlcanMessage::Ack | SlcanMessage::Frame(_) | SlcanMessage::Nack => String::new(),
        };
        body + "\r"
    }
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
                Ok(SlcanMessage::Bitrate(SlcanBitrate::Mbit1)),
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
