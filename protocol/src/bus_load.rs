//! Bus load: how long each frame occupies a real CAN bus (worst-case bit stuffing), and the
//! load a loop rate and message set put on a bit rate. vcan has no bit rate, so the programs
//! use this to refuse or warn about a loop that cannot fit on a real bus.
//!
//! Classical frames (Davis, Burns, Bril, Lukkien 2007, with the 3-bit interframe space):
//! `47 + 8n + floor((34 + 8n - 1) / 4)` bits for 11-bit ids, `67 + 8n + floor((54 + 8n - 1)
//! / 4)` for 29-bit ids; 8 bytes with an 11-bit id: 135 bits.
//!
//! CAN FD (ISO 11898-1:2015): the arbitration phase (SOF to BRS) and the tail (ACK, EOF,
//! interframe space) run at the nominal rate, the data phase (ESI, DLC, data, stuff count,
//! CRC with its fixed stuff bits, CRC delimiter) at the data rate when BRS is set. Dynamic
//! stuff bits are bounded by one per 4 bits in each phase (`ceil(bits / 4)`), a slight
//! over-estimate of the true worst case: a budget that fits here fits on the bus.

use crate::can::{CanFrame, FrameFormat};
use crate::message::spec::MessageSpec;

/// The bit rates of a bus.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Bitrates {
    /// Nominal (arbitration) bit rate, bit/s.
    pub nominal_bps: f64,
    /// CAN FD data-phase bit rate, bit/s (used by FD frames with BRS only).
    pub data_bps: f64,
}

impl Bitrates {
    /// Classical CAN at 1 Mbit/s.
    pub const CLASSICAL_1M: Bitrates = Bitrates {
        nominal_bps: 1e6,
        data_bps: 1e6,
    };
    /// CAN FD, 1 Mbit/s nominal, 5 Mbit/s data.
    pub const FD_1M_5M: Bitrates = Bitrates {
        nominal_bps: 1e6,
        data_bps: 5e6,
    };
}

/// What decides a frame's length on the bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FrameShape {
    /// 29-bit id.
    pub extended: bool,
    /// Data bytes (0 for a remote frame).
    pub len: usize,
    /// CAN FD (with or without bit-rate switch) or classical.
    pub fd: Option<FdShape>,
}

/// The CAN FD part of a [`FrameShape`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FdShape {
    /// Bit-rate switch: the data phase runs at the data rate.
    pub brs: bool,
}

impl FrameShape {
    /// The shape of a frame.
    #[must_use]
    pub fn of_frame(frame: &CanFrame) -> FrameShape {
        FrameShape {
            extended: frame.id().is_extended(),
            len: frame.data().len(),
            fd: match frame.format() {
                FrameFormat::Fd { brs, .. } => Some(FdShape { brs }),
                _ => None,
            },
        }
    }

    /// The shape of a message of the set (FD messages use BRS).
    #[must_use]
    pub fn of_message(spec: &MessageSpec) -> FrameShape {
        FrameShape {
            extended: false,
            len: usize::from(spec.len),
            fd: spec.fd.then_some(FdShape { brs: true }),
        }
    }

    /// Worst-case bits on the bus, split by phase.
    #[must_use]
    pub fn bits(&self) -> FrameBits {
        let data = 8 * self.len as u32;
        match self.fd {
            None => {
                let (fixed, stuffed) = if self.extended { (67, 54) } else { (47, 34) };
                let stuffed = stuffed + data;
                FrameBits {
                    nominal: fixed + data + (stuffed - 1) / 4,
                    data_phase: 0,
                }
            }
            Some(fd) => {
                let arbitration: u32 = if self.extended { 36 } else { 17 };
                let crc: u32 = if self.len <= 16 { 17 } else { 21 };
                let crc_field = 4 + crc; // stuff count (3 gray + parity) and CRC
                let fixed_stuff = crc_field.div_ceil(4);
                let dynamic = 5 + data; // ESI, DLC, data
                let nominal = arbitration + arbitration.div_ceil(4) + 12; // ACK, delim, EOF, IFS
                let data_phase = dynamic + dynamic.div_ceil(4) + crc_field + fixed_stuff + 1;
                if fd.brs {
                    FrameBits {
                        nominal,
                        data_phase,
                    }
                } else {
                    FrameBits {
                        nominal: nominal + data_phase,
                        data_phase: 0,
                    }
                }
            }
        }
    }
}

/// A frame's worst-case length in bits, by the bit rate each part runs at.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct FrameBits {
    /// Bits at the nominal rate.
    pub nominal: u32,
    /// Bits at the data rate (FD with BRS only).
    pub data_phase: u32,
}

impl FrameBits {
    /// How long the frame occupies the bus, in seconds.
    #[must_use]
    pub fn duration_s(&self, rates: Bitrates) -> f64 {
        f64::from(self.nominal) / rates.nominal_bps + f64::from(self.data_phase) / rates.data_bps
    }
}

/// One periodic frame of a traffic budget.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Traffic {
    /// What it is (a message name).
    pub name: String,
    /// Its worst-case bits.
    pub bits: FrameBits,
    /// How often it is sent, Hz.
    pub rate_hz: f64,
}

impl Traffic {
    /// A message of the set sent at `rate_hz`.
    #[must_use]
    pub fn message(spec: &MessageSpec, rate_hz: f64) -> Traffic {
        Traffic {
            name: spec.name.to_owned(),
            bits: FrameShape::of_message(spec).bits(),
            rate_hz,
        }
    }
}

/// The load a traffic budget puts on a bus.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BusLoad {
    /// The bit rates.
    pub rates: Bitrates,
    /// Bus time used per second of time, as a fraction (1.0 = saturated).
    pub load: f64,
    /// Each frame's share: (name, frames per second, fraction of the bus).
    pub shares: Vec<(String, f64, f64)>,
}

/// A budget that does not fit: its numbers are in the message.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "bus load {load_pct:.1} % exceeds {limit_pct:.0} % at {nominal_kbps:.0} kbit/s nominal / {data_kbps:.0} kbit/s data ({detail})"
)]
pub struct BusOverload {
    /// The load, percent.
    pub load_pct: f64,
    /// The limit, percent.
    pub limit_pct: f64,
    /// Nominal rate, kbit/s.
    pub nominal_kbps: f64,
    /// Data rate, kbit/s.
    pub data_kbps: f64,
    /// The biggest shares, e.g. `CoilCommand 20000/s 270.0 %`.
    pub detail: String,
}

/// Load limits: above `warn` a loop runs with a warning, above `refuse` it is refused.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LoadLimits {
    /// Warn above this fraction.
    pub warn: f64,
    /// Refuse above this fraction.
    pub refuse: f64,
}

impl LoadLimits {
    /// Warn above 70 %, refuse above 100 % (a saturated bus loses frames).
    pub const DEFAULT: LoadLimits = LoadLimits {
        warn: 0.7,
        refuse: 1.0,
    };
}

impl BusLoad {
    /// The load of `traffic` on a bus with `rates`.
    #[must_use]
    pub fn of(traffic: &[Traffic], rates: Bitrates) -> BusLoad {
        let shares: Vec<(String, f64, f64)> = traffic
            .iter()
            .map(|t| {
                (
                    t.name.clone(),
                    t.rate_hz,
                    t.rate_hz * t.bits.duration_s(rates),
                )
            })
            .collect();
        BusLoad {
            rates,
            load: shares.iter().map(|s| s.2).sum(),
            shares,
        }
    }

    /// Checks the load against `limits`.
    ///
    /// # Errors
    /// [`BusOverload`] above `limits.refuse`. Between `warn` and `refuse` the `Ok` value
    /// carries the warning text (with the numbers); below `warn` it is `None`.
    pub fn check(&self, limits: LoadLimits) -> Result<Option<String>, BusOverload> {
        let overload = |limit: f64| BusOverload {
            load_pct: self.load * 100.0,
            limit_pct: limit * 100.0,
            nominal_kbps: self.rates.nominal_bps / 1e3,
            data_kbps: self.rates.data_bps / 1e3,
            detail: self.detail(),
        };
        if self.load > limits.refuse {
            Err(overload(limits.refuse))
        } else if self.load > limits.warn {
            Ok(Some(overload(limits.warn).to_string()))
        } else {
            Ok(None)
        }
    }

    /// The three biggest shares as text.
    fn detail(&self) -> String {
        let mut shares = self.shares.clone();
        shares.sort_by(|a, b| b.2.total_cmp(&a.2));
        shares
            .iter()
            .take(3)
            .map(|(name, rate, share)| format!("{name} {rate:.0}/s {:.1} %", share * 100.0))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::message::{ids, spec::message_spec};

    fn shape(len: usize, extended: bool, fd: Option<FdShape>) -> FrameShape {
        FrameShape { extended, len, fd }
    }

    #[test]
    fn classical_worst_cases_match_the_literature() {
        assert_eq!(shape(8, false, None).bits().nominal, 135);
        assert_eq!(shape(0, false, None).bits().nominal, 55);
        assert_eq!(shape(8, true, None).bits().nominal, 160);
        // About 7400 eight-byte frames per second fit on 1 Mbit/s.
        let per_s = 1.0
            / shape(8, false, None)
                .bits()
                .duration_s(Bitrates::CLASSICAL_1M);
        assert!((per_s - 7407.4).abs() < 0.1, "{per_s}");
    }

    #[test]
    fn fd_with_brs_moves_the_payload_to_the_data_rate() {
        let brs = shape(16, false, Some(FdShape { brs: true })).bits();
        let slow = shape(16, false, Some(FdShape { brs: false })).bits();
        assert_eq!(brs.nominal + brs.data_phase, slow.nominal);
        assert_eq!(brs.nominal, 17 + 5 + 12);
        // ESI+DLC+128 data = 133, +34 stuff, +21 CRC field, +6 fixed stuff, +1 delimiter.
        assert_eq!(brs.data_phase, 133 + 34 + 21 + 6 + 1);
        assert!(brs.duration_s(Bitrates::FD_1M_5M) < slow.duration_s(Bitrates::FD_1M_5M) / 2.0);
    }

    #[test]
    fn a_20_khz_classical_loop_is_refused_with_numbers() {
        let coil = message_spec(ids::COIL_COMMAND).unwrap();
        let angles = message_spec(ids::ANGLE_READING).unwrap();
        let load = BusLoad::of(
            &[
                Traffic::message(coil, 20_000.0),
                Traffic::message(angles, 20_000.0),
            ],
            Bitrates::CLASSICAL_1M,
        );
        assert!((load.load - 5.4).abs() < 1e-9, "{}", load.load);
        let err = load.check(LoadLimits::DEFAULT).unwrap_err();
        assert!(err.to_string().contains("540.0 %"), "{err}");
        assert!(
            err.to_string().contains("CoilCommand 20000/s 270.0 %"),
            "{err}"
        );
        let slow = BusLoad::of(&[Traffic::message(coil, 2_000.0)], Bitrates::CLASSICAL_1M);
        assert_eq!(slow.check(LoadLimits::DEFAULT), Ok(None));
    }
}
