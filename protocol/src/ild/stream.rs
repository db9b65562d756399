//! The ILD 2300's RS422 measured-value stream: three bytes per 18-bit value, L, M, H, with
//! two flag bits per byte that tell its place:
//!
//! | byte | bits 7..6 | bits 5..0 |
//! |------|-----------|-----------|
//! | L    | `00`      | D5..D0    |
//! | M    | `01`      | D11..D6   |
//! | H    | `1x`      | D17..D12, `x` = 0 for the first value of an output cycle, 1 for the others |
//!
//! An output cycle carries the distance and then the extra values `OUTADD_RS422` enabled
//! (counter, timestamp, ...). [`IldDecoder`] resynchronises after lost or corrupted bytes
//! at the next L byte and reports the bytes it skipped once per gap, with their offset. A
//! corrupted byte that keeps its flag bits cannot be detected (the stream has no checksum).

use super::value::RAW_MAX;

/// Flag bits (7..6) of an L byte.
const FLAG_L: u8 = 0b00;
/// Flag bits (7..6) of an M byte.
const FLAG_M: u8 = 0b01;
/// Bit 7 marks an H byte; bit 6 of an H byte marks a further value of the same cycle.
const H_BIT: u8 = 0x80;
const H_MORE_BIT: u8 = 0x40;
const PAYLOAD_MASK: u8 = 0x3F;
/// Bytes per value on the line.
pub const BYTES_PER_VALUE: usize = 3;
/// Bits one byte takes on the line: start bit, 8 data bits, stop bit (8N1).
pub const BITS_PER_BYTE: f64 = 10.0;
/// Bits per value the manual's baud-rate rule counts: "per value transmitted 3 bytes are
/// transmitted, with real 11 bit used on the serial line" (chap. 7, p. 57, Fig. 32), so the rule
/// `BR > 33 * MR * m / ODR` keeps 10 % over the 30 bits 8N1 takes.
pub const BAUD_RULE_BITS_PER_VALUE: f64 = 33.0;
/// The factory baud rate.
pub const FACTORY_BAUD: u32 = 691_200;

/// The baud rate the manual's rule (chap. 7, p. 57, Fig. 32) asks more than for
/// `values_per_cycle` values at `measuring_rate_hz`, with every `reduction`-th cycle output
/// (`OUTREDUCE`, the rule's ODR).
#[must_use]
pub fn required_baud(measuring_rate_hz: f64, values_per_cycle: u32, reduction: u32) -> f64 {
    BAUD_RULE_BITS_PER_VALUE * measuring_rate_hz * f64::from(values_per_cycle)
        / f64::from(reduction.max(1))
}

/// How long the line takes to carry one output cycle of `values_per_cycle` values at `baud`,
/// s (3 bytes of 10 bits a value): the delay from the cycle's first bit to its last.
#[must_use]
pub fn cycle_transmit_s(values_per_cycle: u32, baud: u32) -> f64 {
    (BYTES_PER_VALUE as f64 * BITS_PER_BYTE * f64::from(values_per_cycle)) / f64::from(baud.max(1))
}

/// A sensor configuration whose values per cycle do not fit its line: the manual's rule
/// `BR > 33 * MR * m / ODR` (chap. 7, p. 57) does not hold, and a real sensor would hold back
/// cycles the line cannot carry.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "the ILD line at {baud} baud cannot carry {values_per_cycle} value(s) per cycle ({values}) \
     at {rate_khz} kHz: the manual's rule BR > 33 x MR x m / ODR needs more than \
     {required_baud:.0} baud",
    rate_khz = measuring_rate_hz / 1e3
)]
pub struct BaudShortfall {
    /// The measuring rate, Hz.
    pub measuring_rate_hz: f64,
    /// The values of a cycle, named (`DIST1 COUNTER`).
    pub values: String,
    /// How many values a cycle has.
    pub values_per_cycle: u32,
    /// The line's baud rate.
    pub baud: u32,
    /// The baud rate the rule asks more than.
    pub required_baud: f64,
}

/// Checks that `values_per_cycle` values (named `values`) per cycle at `measuring_rate_hz`,
/// every cycle output, fit a line at `baud` (the manual's rule, strictly greater).
///
/// # Errors
/// [`BaudShortfall`] naming the rate, the values, the baud and the baud the rule needs.
pub fn check_baud(
    measuring_rate_hz: f64,
    values: &str,
    values_per_cycle: u32,
    baud: u32,
) -> Result<(), BaudShortfall> {
    let required = required_baud(measuring_rate_hz, values_per_cycle, 1);
    if f64::from(baud) > required {
        Ok(())
    } else {
        Err(BaudShortfall {
            measuring_rate_hz,
            values: values.to_owned(),
            values_per_cycle,
            baud,
            required_baud: required,
        })
    }
}

/// One 18-bit value from the stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct IldWord {
    /// The 18-bit raw value (a distance / error code for the cycle's first value; the meaning
    /// of the others depends on `OUTADD_RS422`).
    pub raw: u32,
    /// True for the first value of an output cycle (H byte bit 6 clear).
    pub first_in_cycle: bool,
    /// Position in the output cycle, `None` when sync was lost since the cycle began.
    pub index_in_cycle: Option<u8>,
    /// Byte offset of the value's L byte in the stream.
    pub offset: u64,
}

/// Bytes the decoder had to skip to find the next value.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("ILD byte offset {offset}: skipped {len} byte(s) out of L/M/H order (lost sync)")]
pub struct IldStreamError {
    /// Offset of the first skipped byte.
    pub offset: u64,
    /// How many bytes were skipped.
    pub len: u64,
}

/// What the decoder yields: a value, or a gap it skipped.
pub type IldEvent = Result<IldWord, IldStreamError>;

/// The three bytes of one value. `raw` is masked to 18 bits.
#[must_use]
pub fn encode_word(raw: u32, first_in_cycle: bool) -> [u8; BYTES_PER_VALUE] {
    let raw = raw & RAW_MAX;
    let more = if first_in_cycle { 0 } else { H_MORE_BIT };
    [
        (raw & 0x3F) as u8,
        (FLAG_M << 6) | ((raw >> 6) & 0x3F) as u8,
        H_BIT | more | ((raw >> 12) & 0x3F) as u8,
    ]
}

/// One output cycle: the first value marked as such, the others as further values.
#[must_use]
pub fn encode_cycle(raws: &[u32]) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(raws.len() * BYTES_PER_VALUE);
    encode_cycle_into(raws, &mut bytes);
    bytes
}

/// [`encode_cycle`], appended to `bytes` (a buffer used again for every cycle).
pub fn encode_cycle_into(raws: &[u32], bytes: &mut Vec<u8>) {
    for (i, &raw) in raws.iter().enumerate() {
        bytes.extend_from_slice(&encode_word(raw, i == 0));
    }
}

/// Incremental decoder of the value stream.
#[derive(Debug, Clone, Default)]
pub struct IldDecoder {
    /// The L and M bytes of the value being read (0, 1 or 2 of them).
    held: Vec<u8>,
    held_offset: u64,
    position: u64,
    /// Start and length of the current run of skipped bytes.
    gap: Option<(u64, u64)>,
    next_index: Option<u8>,
}

impl IldDecoder {
    /// A decoder at the start of a stream (the first value's cycle position is unknown until
    /// a cycle starts).
    #[must_use]
    pub fn new() -> IldDecoder {
        IldDecoder::default()
    }

    /// Feeds `bytes`; returns the values and gaps they complete, in order.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<IldEvent> {
        let mut events = Vec::new();
        for &byte in bytes {
            self.push_byte(byte, &mut events);
        }
        events
    }

    /// Ends the stream: a partial value or a gap at the end is reported.
    pub fn finish(&mut self) -> Option<IldStreamError> {
        let held = std::mem::take(&mut self.held);
        if !held.is_empty() {
            self.skip(self.held_offset, held.len() as u64);
        }
        self.gap
            .take()
            .map(|(offset, len)| IldStreamError { offset, len })
    }

    /// Bytes consumed so far.
    #[must_use]
    pub fn position(&self) -> u64 {
        self.position
    }

    fn push_byte(&mut self, byte: u8, events: &mut Vec<IldEvent>) {
        let offset = self.position;
        self.position += 1;
        let is_l = byte >> 6 == FLAG_L;
        let expected = match self.held.len() {
            0 => is_l,
            1 => byte >> 6 == FLAG_M,
            _ => byte & H_BIT != 0,
        };
        if !expected {
            // Whatever was held is part of the gap; an L byte starts a new value.
            let held = std::mem::take(&mut self.held);
            if !held.is_empty() {
                self.skip(self.held_offset, held.len() as u64);
            }
            self.next_index = None;
            if !is_l {
                self.skip(offset, 1);
                return;
            }
        }
        if self.held.is_empty() {
            if let Some((offset, len)) = self.gap.take() {
                events.push(Err(IldStreamError { offset, len }));
            }
            self.held_offset = offset;
        }
        if self.held.len() < 2 {
            self.held.push(byte);
            return;
        }
        let raw = u32::from(self.held[0] & PAYLOAD_MASK)
            | u32::from(self.held[1] & PAYLOAD_MASK) << 6
            | u32::from(byte & PAYLOAD_MASK) << 12;
        let first_in_cycle = byte & H_MORE_BIT == 0;
        let index_in_cycle = if first_in_cycle {
            Some(0)
        } else {
            self.next_index
        };
        self.next_index = index_in_cycle.and_then(|i| i.checked_add(1));
        self.held.clear();
        events.push(Ok(IldWord {
            raw,
            first_in_cycle,
            index_in_cycle,
            offset: self.held_offset,
        }));
    }

    /// Adds `len` bytes at `offset` to the current gap.
    fn skip(&mut self, offset: u64, len: u64) {
        match &mut self.gap {
            Some((_, gap_len)) => *gap_len += len,
            None => self.gap = Some((offset, len)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encodes_the_manual_byte_layout() {
        // 0x2_ABCD = 10 1010 1011 1100 1101: D5..0 = 001101, D11..6 = 101111, D17..12 = 101010.
        assert_eq!(encode_word(0x2ABCD, true), [0x0D, 0x6F, 0xAA]);
        assert_eq!(encode_word(0x2ABCD, false), [0x0D, 0x6F, 0xEA]);
    }

    #[test]
    fn decodes_cycles_with_their_positions() {
        let mut bytes = encode_cycle(&[1000, 77, 5]);
        bytes.extend(encode_cycle(&[2000, 78, 6]));
        let words: Vec<_> = IldDecoder::new()
            .push(&bytes)
            .into_iter()
            .map(|e| e.map(|w| (w.raw, w.index_in_cycle)))
            .collect();
        assert_eq!(
            words,
            vec![
                Ok((1000, Some(0))),
                Ok((77, Some(1))),
                Ok((5, Some(2))),
                Ok((2000, Some(0))),
                Ok((78, Some(1))),
                Ok((6, Some(2))),
            ]
        );
    }

    #[test]
    fn a_dropped_byte_costs_one_value_and_is_reported_once() {
        let mut bytes = encode_cycle(&[1000, 77]);
        bytes.remove(1); // drop the first value's M byte
        bytes.extend(encode_cycle(&[2000]));
        let events = IldDecoder::new().push(&bytes);
        assert_eq!(events.len(), 3, "{events:?}");
        assert_eq!(events[0], Err(IldStreamError { offset: 0, len: 2 }));
        assert_eq!(events[1].as_ref().unwrap().raw, 77);
        assert_eq!(events[1].as_ref().unwrap().index_in_cycle, None);
        assert_eq!(events[2].as_ref().unwrap().index_in_cycle, Some(0));
    }

    #[test]
    fn a_partial_value_at_the_end_is_reported() {
        let mut decoder = IldDecoder::new();
        assert!(decoder.push(&encode_word(5, true)[..2]).is_empty());
        assert_eq!(decoder.finish(), Some(IldStreamError { offset: 0, len: 2 }));
    }

    #[test]
    fn twenty_khz_with_one_value_needs_more_than_660_kbaud() {
        assert!((required_baud(20_000.0, 1, 1) - 660_000.0).abs() < 1e-6);
        assert!(f64::from(FACTORY_BAUD) > required_baud(20_000.0, 1, 1));
        assert!((required_baud(20_000.0, 2, 2) - 660_000.0).abs() < 1e-6);
        assert!((required_baud(20_000.0, 2, 0) - 1_320_000.0).abs() < 1e-6);
    }

    #[test]
    fn the_baud_rule_refuses_the_counter_at_20_khz_and_names_the_numbers() {
        assert_eq!(check_baud(20_000.0, "DIST1", 1, FACTORY_BAUD), Ok(()));
        let error = check_baud(20_000.0, "DIST1 COUNTER", 2, FACTORY_BAUD).unwrap_err();
        assert_eq!(
            error.to_string(),
            "the ILD line at 691200 baud cannot carry 2 value(s) per cycle (DIST1 COUNTER) at \
             20 kHz: the manual's rule BR > 33 x MR x m / ODR needs more than 1320000 baud"
        );
        assert!(check_baud(20_000.0, "DIST1 COUNTER", 2, 921_600).is_err());
        assert!(check_baud(10_000.0, "DIST1 COUNTER", 2, FACTORY_BAUD).is_ok());
        // Strictly greater: exactly the rule's figure is not enough.
        assert!(check_baud(20_000.0, "DIST1", 1, 660_000).is_err());
        assert!(check_baud(20_000.0, "DIST1", 1, 660_001).is_ok());
    }

    #[test]
    fn a_cycle_takes_thirty_bits_a_value() {
        assert!((cycle_transmit_s(1, 691_200) - 30.0 / 691_200.0).abs() < 1e-15);
        assert!((cycle_transmit_s(2, 921_600) - 60.0 / 921_600.0).abs() < 1e-15);
    }
}
