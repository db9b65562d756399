//! Adapter families: which CAN bit rate each `Sn` digit sets. The digits agree up to `S6`;
//! `S7` is 750 kbit/s on CANable firmware (and in python-can's table) but 800 kbit/s on
//! Lawicel adapters and in the Linux slcan driver, and `S9` (83.3 kbit/s) exists on CANable
//! 2.x only. A host sending `S7` for 800 kbit/s to a CANable runs its bus at 750 kbit/s
//! without a word, so a link names its adapter's family and a rate the family cannot set is
//! refused.
//!
//! Sources (docs/decisions.md, "SLCAN adapters"): normaldotcom/canable2-fw `inc/can.h` and
//! `src/can.c` (`CAN_BITRATE_750K` is digit 7, `CAN_BITRATE_83_3K` digit 9), normaldotcom/
//! canable-fw `inc/can.h` (digits 0-8, 7 = 750k), python-can `can/interfaces/slcan.py`
//! (`_BITRATES`), Linux `drivers/net/can/slcan/slcan-core.c` (`slcan_bitrate_const`), the
//! Lawicel CAN232/CANUSB manuals (`S7` 800 kbit/s).

use std::fmt;
use std::str::FromStr;

/// An SLCAN adapter family, by its `Sn` bit-rate table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AdapterFamily {
    /// CANable 1.x/2.x slcan firmware (normaldotcom), python-can's table: `S7` 750 kbit/s,
    /// `S9` 83.3 kbit/s. The default: the most common USB-CAN adapter.
    #[default]
    Canable,
    /// Lawicel CANUSB/CAN232 and adapters built to their manual: `S7` 800 kbit/s.
    Lawicel,
    /// The Linux slcan driver's table (`slcand -s`): as Lawicel's.
    Linux,
}

/// `S0`..`S9` on CANable firmware, bit/s (index = digit).
const CANABLE_BITRATES: [u32; 10] = [
    10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 750_000, 1_000_000, 83_300,
];
/// `S0`..`S8` on Lawicel adapters and in the Linux driver, bit/s (index = digit).
const LAWICEL_BITRATES: [u32; 9] = [
    10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
];

impl AdapterFamily {
    /// Every family, in the order messages list them.
    pub const ALL: [AdapterFamily; 3] = [
        AdapterFamily::Canable,
        AdapterFamily::Lawicel,
        AdapterFamily::Linux,
    ];

    /// The family's name in a link URI (`?family=NAME`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            AdapterFamily::Canable => "canable",
            AdapterFamily::Lawicel => "lawicel",
            AdapterFamily::Linux => "linux",
        }
    }

    /// The bit rates of `S0`, `S1`, ... in bit/s.
    #[must_use]
    pub fn bitrates(self) -> &'static [u32] {
        match self {
            AdapterFamily::Canable => &CANABLE_BITRATES,
            AdapterFamily::Lawicel | AdapterFamily::Linux => &LAWICEL_BITRATES,
        }
    }

    /// The digit `n` of the `Sn` command that sets exactly `bits_per_s`, if the family has
    /// one.
    #[must_use]
    pub fn code_for(self, bits_per_s: u32) -> Option<u8> {
        self.bitrates()
            .iter()
            .position(|&rate| rate == bits_per_s)
            .and_then(|code| u8::try_from(code).ok())
    }

    /// The bit rate `Sn` sets for digit `code`, if the family has that digit.
    #[must_use]
    pub fn bits_per_s(self, code: u8) -> Option<u32> {
        self.bitrates().get(usize::from(code)).copied()
    }

    /// The family's table for messages: `S0..S8: 10000, 20000, ... bit/s`.
    #[must_use]
    pub fn table_text(self) -> String {
        let rates: Vec<String> = self.bitrates().iter().map(u32::to_string).collect();
        format!(
            "S0..S{}: {} bit/s",
            self.bitrates().len() - 1,
            rates.join(", ")
        )
    }

    /// The families that can set `bits_per_s`, for a refusal's hint.
    #[must_use]
    pub fn families_setting(bits_per_s: u32) -> Vec<AdapterFamily> {
        Self::ALL
            .into_iter()
            .filter(|family| family.code_for(bits_per_s).is_some())
            .collect()
    }
}

impl fmt::Display for AdapterFamily {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A family name that is none of [`AdapterFamily::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown SLCAN adapter family `{0}` (expected canable, lawicel or linux)")]
pub struct UnknownFamily(pub String);

impl FromStr for AdapterFamily {
    type Err = UnknownFamily;

    fn from_str(name: &str) -> Result<Self, UnknownFamily> {
        Self::ALL
            .into_iter()
            .find(|family| family.name() == name)
            .ok_or_else(|| UnknownFamily(name.to_owned()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn s7_is_750k_on_canable_and_800k_on_lawicel_and_linux() {
        assert_eq!(AdapterFamily::Canable.bits_per_s(7), Some(750_000));
        assert_eq!(AdapterFamily::Lawicel.bits_per_s(7), Some(800_000));
        assert_eq!(AdapterFamily::Linux.bits_per_s(7), Some(800_000));
        assert_eq!(AdapterFamily::Canable.code_for(800_000), None);
        assert_eq!(AdapterFamily::Lawicel.code_for(750_000), None);
        assert_eq!(AdapterFamily::Canable.code_for(83_300), Some(9));
        assert_eq!(AdapterFamily::Linux.bits_per_s(9), None);
        for family in AdapterFamily::ALL {
            assert_eq!(family.code_for(1_000_000), Some(8), "{family}");
            assert_eq!(family.code_for(10_000), Some(0), "{family}");
            assert_eq!(family.code_for(123_456), None, "{family}");
        }
    }

    #[test]
    fn names_round_trip_and_the_table_is_spelled_out() {
        for family in AdapterFamily::ALL {
            assert_eq!(family.name().parse::<AdapterFamily>(), Ok(family));
            assert_eq!(family.to_string(), family.name());
        }
        assert!("peak".parse::<AdapterFamily>().is_err());
        assert_eq!(AdapterFamily::default(), AdapterFamily::Canable);
        assert_eq!(
            AdapterFamily::Lawicel.table_text(),
            "S0..S8: 10000, 20000, 50000, 100000, 125000, 250000, 500000, 800000, 1000000 bit/s"
        );
        assert!(AdapterFamily::Canable.table_text().starts_with("S0..S9: "));
        assert_eq!(
            AdapterFamily::families_setting(800_000),
            vec![AdapterFamily::Lawicel, AdapterFamily::Linux]
        );
    }
}
