//! CAN frames as values: identifiers (11-bit and 29-bit) and frames (classical data, remote,
//! CAN FD), each validated at construction so that every `CanFrame` that exists can be put on
//! a real bus.

use std::fmt;

/// The largest 11-bit (standard) identifier.
pub const STANDARD_ID_MAX: u16 = 0x7FF;
/// The largest 29-bit (extended) identifier.
pub const EXTENDED_ID_MAX: u32 = 0x1FFF_FFFF;
/// The largest payload of a classical CAN data frame, in bytes.
pub const CLASSICAL_MAX_LEN: usize = 8;
/// The largest payload of a CAN FD frame, in bytes.
pub const FD_MAX_LEN: usize = 64;
/// The payload lengths a CAN FD frame can have, indexed by its 4-bit DLC code.
pub const FD_LENGTHS: [usize; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64];

/// An 11-bit CAN identifier, `0..=0x7FF`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct StandardId(u16);

impl StandardId {
    /// The identifier `raw`, or `None` if it does not fit in 11 bits.
    #[must_use]
    pub const fn new(raw: u16) -> Option<StandardId> {
        if raw <= STANDARD_ID_MAX {
            Some(StandardId(raw))
        } else {
            None
        }
    }

    /// The raw 11-bit value.
    #[must_use]
    pub const fn as_raw(self) -> u16 {
        self.0
    }
}

/// A 29-bit CAN identifier, `0..=0x1FFF_FFFF`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ExtendedId(u32);

impl ExtendedId {
    /// The identifier `raw`, or `None` if it does not fit in 29 bits.
    #[must_use]
    pub const fn new(raw: u32) -> Option<ExtendedId> {
        if raw <= EXTENDED_ID_MAX {
            Some(ExtendedId(raw))
        } else {
            None
        }
    }

    /// The raw 29-bit value.
    #[must_use]
    pub const fn as_raw(self) -> u32 {
        self.0
    }
}

/// A CAN identifier: 11-bit (standard) or 29-bit (extended).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum CanId {
    /// An 11-bit identifier.
    Standard(StandardId),
    /// A 29-bit identifier.
    Extended(ExtendedId),
}

impl CanId {
    /// The 11-bit identifier `raw`, or `None` if it does not fit.
    #[must_use]
    pub const fn standard(raw: u16) -> Option<CanId> {
        match StandardId::new(raw) {
            Some(id) => Some(CanId::Standard(id)),
            None => None,
        }
    }

    /// The 29-bit identifier `raw`, or `None` if it does not fit.
    #[must_use]
    pub const fn extended(raw: u32) -> Option<CanId> {
        match ExtendedId::new(raw) {
            Some(id) => Some(CanId::Extended(id)),
            None => None,
        }
    }

    /// The raw identifier value (without any format flag).
    #[must_use]
    pub const fn as_raw(self) -> u32 {
        match self {
            CanId::Standard(id) => id.0 as u32,
            CanId::Extended(id) => id.0,
        }
    }

    /// True for a 29-bit identifier.
    #[must_use]
    pub const fn is_extended(self) -> bool {
        matches!(self, CanId::Extended(_))
    }
}

impl fmt::Display for CanId {
    /// Upper-case hex, 3 digits for 11-bit and 8 digits for 29-bit ids (the candump style).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CanId::Standard(id) => write!(f, "{:03X}", id.0),
            CanId::Extended(id) => write!(f, "{:08X}", id.0),
        }
    }
}

/// Which kind of frame a [`CanFrame`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FrameFormat {
    /// A classical CAN data frame, 0 to 8 bytes.
    Classical,
    /// A classical remote (request) frame: no data, only a requested length (its DLC).
    Remote,
    /// A CAN FD frame, 0 to 64 bytes in the lengths of [`FD_LENGTHS`].
    Fd {
        /// Bit-rate switch: the data phase runs at the data bit rate.
        brs: bool,
        /// Error state indicator: the sender is error-passive.
        esi: bool,
    },
}

/// Why a frame could not be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// A classical data frame with more than 8 bytes.
    #[error("classical CAN frame with {len} data bytes (at most 8)")]
    ClassicalTooLong {
        /// The offered payload length.
        len: usize,
    },
    /// A remote frame asking for more than 8 bytes.
    #[error("remote frame with DLC {dlc} (at most 8)")]
    RemoteDlcTooLarge {
        /// The offered DLC.
        dlc: u8,
    },
    /// An FD payload length that no DLC code stands for.
    #[error("CAN FD frame with {len} data bytes (allowed: 0-8, 12, 16, 20, 24, 32, 48, 64)")]
    FdInvalidLength {
        /// The offered payload length.
        len: usize,
    },
}

/// One CAN or CAN FD frame: identifier, format and payload.
///
/// Constructors check the payload length against the format, so a frame is always valid.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: CanId,
    format: FrameFormat,
    /// Payload length for data frames; requested length (DLC) for remote frames.
    len: u8,
    data: [u8; FD_MAX_LEN],
}

impl CanFrame {
    /// A classical data frame with 0 to 8 bytes of `data`.
    ///
    /// # Errors
    /// [`FrameError::ClassicalTooLong`] for more than 8 bytes.
    pub fn new(id: CanId, data: &[u8]) -> Result<CanFrame, FrameError> {
        if data.len() > CLASSICAL_MAX_LEN {
            return Err(FrameError::ClassicalTooLong { len: data.len() });
        }
        Ok(Self::with_payload(id, FrameFormat::Classical, data))
    }

    /// A classical remote frame requesting `dlc` (0 to 8) bytes.
    ///
    /// # Errors
    /// [`FrameError::RemoteDlcTooLarge`] for a DLC above 8.
    pub fn new_remote(id: CanId, dlc: u8) -> Result<CanFrame, FrameError> {
        if usize::from(dlc) > CLASSICAL_MAX_LEN {
            return Err(FrameError::RemoteDlcTooLarge { dlc });
        }
        let mut frame = Self::with_payload(id, FrameFormat::Remote, &[]);
        frame.len = dlc;
        Ok(frame)
    }

    /// A CAN FD frame; `data.len()` must be one of [`FD_LENGTHS`].
    ///
    /// # Errors
    /// [`FrameError::FdInvalidLength`] for any other length.
    pub fn new_fd(id: CanId, data: &[u8], brs: bool, esi: bool) -> Result<CanFrame, FrameError> {
        if !FD_LENGTHS.contains(&data.len()) {
            return Err(FrameError::FdInvalidLength { len: data.len() });
        }
        Ok(Self::with_payload(id, FrameFormat::Fd { brs, esi }, data))
    }

    /// Builds the frame; the caller has checked `data.len()` against the format.
    fn with_payload(id: CanId, format: FrameFormat, data: &[u8]) -> CanFrame {
        let mut buf = [0; FD_MAX_LEN];
        buf[..data.len()].copy_from_slice(data);
        CanFrame {
            id,
            format,
            len: data.len() as u8,
            data: buf,
        }
    }

    /// The identifier.
    #[must_use]
    pub fn id(&self) -> CanId {
        self.id
    }

    /// The frame's format (classical, remote, FD with its flags).
    #[must_use]
    pub fn format(&self) -> FrameFormat {
        self.format
    }

    /// The payload (empty for a remote frame).
    #[must_use]
    pub fn data(&self) -> &[u8] {
        match self.format {
            FrameFormat::Remote => &[],
            _ => &self.data[..usize::from(self.len)],
        }
    }

    /// The 4-bit DLC code on the wire: the length for classical and remote frames, the
    /// [`FD_LENGTHS`] index for FD frames.
    #[must_use]
    pub fn dlc(&self) -> u8 {
        match self.format {
            FrameFormat::Fd { .. } => fd_dlc_for_len(usize::from(self.len)).unwrap_or(15),
            _ => self.len,
        }
    }

    /// True for a CAN FD frame.
    #[must_use]
    pub fn is_fd(&self) -> bool {
        matches!(self.format, FrameFormat::Fd { .. })
    }

    /// True for a remote (request) frame.
    #[must_use]
    pub fn is_remote(&self) -> bool {
        self.format == FrameFormat::Remote
    }
}

impl fmt::Debug for CanFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("CanFrame")
            .field("id", &format_args!("{}", self.id))
            .field("format", &self.format)
            .field("dlc", &self.dlc())
            .field("data", &format_args!("{}", hex_upper(self.data())))
            .finish()
    }
}

/// The FD DLC code for a payload length, `None` if no code stands for it.
#[must_use]
pub fn fd_dlc_for_len(len: usize) -> Option<u8> {
    FD_LENGTHS.iter().position(|&l| l == len).map(|i| i as u8)
}

/// The payload length an FD DLC code stands for (codes above 15 are masked to 4 bits).
#[must_use]
pub fn fd_len_for_dlc(dlc: u8) -> usize {
    FD_LENGTHS[usize::from(dlc & 0x0F)]
}

/// Bytes as upper-case hex with no separators (`DEADBEEF`).
#[must_use]
pub fn hex_upper(bytes: &[u8]) -> String {
    let mut text = Vec::with_capacity(bytes.len() * 2);
    push_hex_upper(&mut text, bytes);
    String::from_utf8(text).unwrap_or_default()
}

/// Appends `bytes` to `out` as upper-case hex with no separators, without the formatting
/// machinery (recordings write several frames a period).
pub fn push_hex_upper(out: &mut Vec<u8>, bytes: &[u8]) {
    for &byte in bytes {
        out.push(HEX_UPPER[usize::from(byte >> 4)]);
        out.push(HEX_UPPER[usize::from(byte & 0x0F)]);
    }
}

/// Appends `value` to `out` as upper-case hex, zero-padded to at least `width` digits (as
/// `{value:0width$X}` formats it).
pub fn push_hex_number(out: &mut Vec<u8>, value: u32, width: usize) {
    let digits = (u32::BITS - value.leading_zeros()).div_ceil(4).max(1) as usize;
    out.extend(std::iter::repeat_n(b'0', width.saturating_sub(digits)));
    for digit in (0..digits).rev() {
        out.push(HEX_UPPER[((value >> (4 * digit)) & 0x0F) as usize]);
    }
}

/// The upper-case hex digits.
const HEX_UPPER: &[u8; 16] = b"0123456789ABCDEF";

/// Parses an even-length hex string (either case) into bytes; `None` on any other input.
#[must_use]
pub fn parse_hex(text: &[u8]) -> Option<Vec<u8>> {
    if !text.len().is_multiple_of(2) {
        return None;
    }
    text.chunks_exact(2)
        .map(|pair| Some(hex_digit(pair[0])? << 4 | hex_digit(pair[1])?))
        .collect()
}

/// The value of one hex digit (either case), `None` for anything else.
#[must_use]
pub fn hex_digit(c: u8) -> Option<u8> {
    match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'a'..=b'f' => Some(c - b'a' + 10),
        b'A'..=b'F' => Some(c - b'A' + 10),
        _ => None,
    }
}

/// Parses hex digits (either case, at least one) into a number; `None` on other input or
/// overflow of `u32`.
#[must_use]
pub fn parse_hex_u32(text: &[u8]) -> Option<u32> {
    if text.is_empty() || text.len() > 8 {
        return None;
    }
    text.iter()
        .try_fold(0u32, |acc, &c| Some(acc << 4 | u32::from(hex_digit(c)?)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_checked_at_construction() {
        assert!(StandardId::new(0x7FF).is_some());
        assert!(StandardId::new(0x800).is_none());
        assert!(ExtendedId::new(0x1FFF_FFFF).is_some());
        assert!(ExtendedId::new(0x2000_0000).is_none());
        assert_eq!(CanId::standard(0x12).unwrap().to_string(), "012");
        assert_eq!(CanId::extended(0x12).unwrap().to_string(), "00000012");
    }

    #[test]
    fn payload_lengths_are_checked_per_format() {
        let id = CanId::standard(1).unwrap();
        assert!(CanFrame::new(id, &[0; 8]).is_ok());
        assert_eq!(
            CanFrame::new(id, &[0; 9]),
            Err(FrameError::ClassicalTooLong { len: 9 })
        );
        assert!(CanFrame::new_fd(id, &[0; 12], true, false).is_ok());
        assert_eq!(
            CanFrame::new_fd(id, &[0; 9], true, false),
            Err(FrameError::FdInvalidLength { len: 9 })
        );
        let fd = CanFrame::new_fd(id, &[7; 64], false, false).unwrap();
        assert_eq!((fd.dlc(), fd.data().len()), (15, 64));
        let remote = CanFrame::new_remote(id, 5).unwrap();
        assert_eq!((remote.dlc(), remote.data()), (5, &[][..]));
        assert!(CanFrame::new_remote(id, 9).is_err());
    }

    #[test]
    fn hex_helpers_reject_bad_digits() {
        assert_eq!(parse_hex(b"DEadBE"), Some(vec![0xDE, 0xAD, 0xBE]));
        assert_eq!(parse_hex(b"ABC"), None);
        assert_eq!(parse_hex(b"G0"), None);
        assert_eq!(parse_hex_u32(b"1FFFFFFF"), Some(0x1FFF_FFFF));
        assert_eq!(parse_hex_u32(b"123456789"), None);
        assert_eq!(hex_upper(&[0xde, 0x01]), "DE01");
        for (value, width) in [
            (0, 3),
            (0x7FF, 3),
            (0x21, 3),
            (0x1ABC_DEF0, 8),
            (0x5, 8),
            (0x1234, 1),
        ] {
            let mut out = Vec::new();
            push_hex_number(&mut out, value, width);
            assert_eq!(String::from_utf8(out).unwrap(), format!("{value:0width$X}"));
        }
    }
}
