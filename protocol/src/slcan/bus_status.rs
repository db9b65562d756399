//! What an SLCAN adapter says about its bus, and what a host makes of it:
//! - `Fxx`: the Lawicel status flags, the answer to `F` (CAN232/CANUSB manuals: bit 0 receive
//!   FIFO full, 1 transmit FIFO full, 2 error warning, 3 data overrun, 5 error passive,
//!   6 arbitration lost, 7 bus error; no bus-off flag);
//! - `sSRRRTTT`: a state line of the Linux slcan driver (`slc_bump_state` in
//!   drivers/net/can/slcan/slcan-core.c): state `a` error-active, `w` warning, `p` passive,
//!   `b` bus-off, then the receive and transmit error counters as 3 decimal digits each
//!   (`sb256256`);
//! - `eNXX..`: an error line of the same driver (`slc_bump_err`): N errors, each one letter
//!   (`a` ACK, `b` bit-0, `B` bit-1, `c` CRC, `f` form, `o` receive overrun, `O` transmit
//!   overrun, `s` stuff).
//!
//! [`AdapterBusStatus`] gathers them for a link's report; a bus-off state ends the link's
//! receive, as SocketCAN's bus-off error frame does.

/// The Lawicel `F` status flags (one byte, two hex digits on the wire).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize)]
pub struct StatusFlags(pub u8);

impl StatusFlags {
    /// Bit 0: the adapter's receive FIFO is full (frames are being lost).
    pub const RX_FIFO_FULL: u8 = 0x01;
    /// Bit 1: the adapter's transmit FIFO is full.
    pub const TX_FIFO_FULL: u8 = 0x02;
    /// Bit 2: an error counter passed the warning limit (96).
    pub const ERROR_WARNING: u8 = 0x04;
    /// Bit 3: data overrun in the CAN controller.
    pub const DATA_OVERRUN: u8 = 0x08;
    /// Bit 5: the controller is error-passive.
    pub const ERROR_PASSIVE: u8 = 0x20;
    /// Bit 6: arbitration was lost.
    pub const ARBITRATION_LOST: u8 = 0x40;
    /// Bit 7: a bus error.
    pub const BUS_ERROR: u8 = 0x80;

    /// The flags set, named (bit 4 is unused in the manual and named `bit4`).
    #[must_use]
    pub fn names(self) -> Vec<&'static str> {
        const NAMES: [(u8, &str); 8] = [
            (StatusFlags::RX_FIFO_FULL, "rx_fifo_full"),
            (StatusFlags::TX_FIFO_FULL, "tx_fifo_full"),
            (StatusFlags::ERROR_WARNING, "error_warning"),
            (StatusFlags::DATA_OVERRUN, "data_overrun"),
            (0x10, "bit4"),
            (StatusFlags::ERROR_PASSIVE, "error_passive"),
            (StatusFlags::ARBITRATION_LOST, "arbitration_lost"),
            (StatusFlags::BUS_ERROR, "bus_error"),
        ];
        NAMES
            .iter()
            .filter(|(bit, _)| self.0 & bit != 0)
            .map(|&(_, name)| name)
            .collect()
    }

    /// The error state the flags imply: passive, warning, or nothing said.
    #[must_use]
    pub fn implied_state(self) -> Option<BusState> {
        if self.0 & Self::ERROR_PASSIVE != 0 {
            Some(BusState::ErrorPassive)
        } else if self.0 & Self::ERROR_WARNING != 0 {
            Some(BusState::ErrorWarning)
        } else {
            None
        }
    }
}

/// A CAN controller's error state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BusState {
    /// Both error counters below 96.
    ErrorActive,
    /// An error counter at 96 or more.
    ErrorWarning,
    /// An error counter above 127: the controller only flags errors passively.
    ErrorPassive,
    /// The transmit error counter passed 255: the controller has left the bus.
    BusOff,
}

impl BusState {
    /// The state for its letter in an `s` line.
    #[must_use]
    pub fn from_letter(letter: u8) -> Option<BusState> {
        match letter {
            b'a' => Some(BusState::ErrorActive),
            b'w' => Some(BusState::ErrorWarning),
            b'p' => Some(BusState::ErrorPassive),
            b'b' => Some(BusState::BusOff),
            _ => None,
        }
    }

    /// Its letter in an `s` line.
    #[must_use]
    pub fn letter(self) -> u8 {
        match self {
            BusState::ErrorActive => b'a',
            BusState::ErrorWarning => b'w',
            BusState::ErrorPassive => b'p',
            BusState::BusOff => b'b',
        }
    }
}

/// An `s` line: the state and both error counters (0..=999 on the wire).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct StateReport {
    /// The controller's state.
    pub state: BusState,
    /// The receive error counter.
    pub rx_errors: u16,
    /// The transmit error counter.
    pub tx_errors: u16,
}

/// One error of an `e` line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BusError {
    /// `a`: no acknowledgement of a transmitted frame (no other node on the bus, or a missing
    /// termination).
    Ack,
    /// `b`: a dominant bit could not be sent.
    Bit0,
    /// `B`: a recessive bit could not be sent.
    Bit1,
    /// `c`: CRC error.
    Crc,
    /// `f`: form error.
    Form,
    /// `o`: receive overrun (frames lost in the adapter).
    RxOverrun,
    /// `O`: transmit overrun.
    TxOverrun,
    /// `s`: stuff error.
    Stuff,
}

impl BusError {
    /// Every error, in letter order of the driver's switch.
    pub const ALL: [BusError; 8] = [
        BusError::Ack,
        BusError::Bit0,
        BusError::Bit1,
        BusError::Crc,
        BusError::Form,
        BusError::RxOverrun,
        BusError::TxOverrun,
        BusError::Stuff,
    ];

    /// The error for its letter in an `e` line.
    #[must_use]
    pub fn from_letter(letter: u8) -> Option<BusError> {
        Self::ALL.into_iter().find(|error| error.letter() == letter)
    }

    /// Its letter in an `e` line.
    #[must_use]
    pub fn letter(self) -> u8 {
        match self {
            BusError::Ack => b'a',
            BusError::Bit0 => b'b',
            BusError::Bit1 => b'B',
            BusError::Crc => b'c',
            BusError::Form => b'f',
            BusError::RxOverrun => b'o',
            BusError::TxOverrun => b'O',
            BusError::Stuff => b's',
        }
    }
}

/// How many of each error the adapter's `e` lines named.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct BusErrorCounts {
    /// `a` lines' ACK errors.
    pub ack: u64,
    /// Bit-0 errors.
    pub bit0: u64,
    /// Bit-1 errors.
    pub bit1: u64,
    /// CRC errors.
    pub crc: u64,
    /// Form errors.
    pub form: u64,
    /// Receive overruns.
    pub rx_overrun: u64,
    /// Transmit overruns.
    pub tx_overrun: u64,
    /// Stuff errors.
    pub stuff: u64,
}

impl BusErrorCounts {
    fn count(&mut self, error: BusError) {
        let slot = match error {
            BusError::Ack => &mut self.ack,
            BusError::Bit0 => &mut self.bit0,
            BusError::Bit1 => &mut self.bit1,
            BusError::Crc => &mut self.crc,
            BusError::Form => &mut self.form,
            BusError::RxOverrun => &mut self.rx_overrun,
            BusError::TxOverrun => &mut self.tx_overrun,
            BusError::Stuff => &mut self.stuff,
        };
        *slot += 1;
    }
}

/// What an adapter has said about its bus so far (all zero/`None` for an adapter that says
/// nothing, such as a CANable).
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize)]
pub struct AdapterBusStatus {
    /// The latest state an `s` line reported or `Fxx` flags implied (`None`: never said).
    pub state: Option<BusState>,
    /// The receive error counter of the latest `s` line.
    pub rx_errors: Option<u16>,
    /// The transmit error counter of the latest `s` line.
    pub tx_errors: Option<u16>,
    /// `s` lines received.
    pub state_lines: u64,
    /// `e` lines received.
    pub error_lines: u64,
    /// The errors those lines named.
    pub errors: BusErrorCounts,
    /// `Fxx` replies received.
    pub status_replies: u64,
    /// The flags of the latest `Fxx` reply, named.
    pub last_status_flags: Option<Vec<&'static str>>,
}

impl AdapterBusStatus {
    /// Takes an `s` line; returns a description of a bus-off (the link must stop).
    pub fn on_state(&mut self, report: StateReport) -> Option<String> {
        self.state_lines += 1;
        self.state = Some(report.state);
        self.rx_errors = Some(report.rx_errors);
        self.tx_errors = Some(report.tx_errors);
        (report.state == BusState::BusOff).then(|| {
            format!(
                "the adapter reports bus-off (receive errors {}, transmit errors {})",
                report.rx_errors, report.tx_errors
            )
        })
    }

    /// Takes an `e` line.
    pub fn on_errors(&mut self, errors: &[BusError]) {
        self.error_lines += 1;
        for &error in errors {
            self.errors.count(error);
        }
    }

    /// Takes an `Fxx` reply (the flags' implied state replaces an older one; no flag clears
    /// a state an `s` line reported only back to error-active).
    pub fn on_flags(&mut self, flags: StatusFlags) {
        self.status_replies += 1;
        self.last_status_flags = Some(flags.names());
        self.state = Some(flags.implied_state().unwrap_or(BusState::ErrorActive));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn letters_round_trip() {
        for error in BusError::ALL {
            assert_eq!(BusError::from_letter(error.letter()), Some(error));
        }
        assert_eq!(BusError::from_letter(b'x'), None);
        for state in [
            BusState::ErrorActive,
            BusState::ErrorWarning,
            BusState::ErrorPassive,
            BusState::BusOff,
        ] {
            assert_eq!(BusState::from_letter(state.letter()), Some(state));
        }
        assert_eq!(BusState::from_letter(b'x'), None);
    }

    #[test]
    fn flags_are_named_and_imply_a_state() {
        assert_eq!(StatusFlags(0).names(), Vec::<&str>::new());
        assert_eq!(StatusFlags(0).implied_state(), None);
        assert_eq!(
            StatusFlags(0xFF).names(),
            [
                "rx_fifo_full",
                "tx_fifo_full",
                "error_warning",
                "data_overrun",
                "bit4",
                "error_passive",
                "arbitration_lost",
                "bus_error"
            ]
        );
        assert_eq!(
            StatusFlags(StatusFlags::ERROR_WARNING).implied_state(),
            Some(BusState::ErrorWarning)
        );
        assert_eq!(
            StatusFlags(StatusFlags::ERROR_WARNING | StatusFlags::ERROR_PASSIVE).implied_state(),
            Some(BusState::ErrorPassive)
        );
    }

    #[test]
    fn the_status_gathers_lines_and_names_a_bus_off() {
        let mut status = AdapterBusStatus::default();
        let passive = StateReport {
            state: BusState::ErrorPassive,
            rx_errors: 57,
            tx_errors: 133,
        };
        assert_eq!(status.on_state(passive), None);
        assert_eq!(status.state, Some(BusState::ErrorPassive));
        assert_eq!((status.rx_errors, status.tx_errors), (Some(57), Some(133)));
        status.on_errors(&[BusError::Ack, BusError::Ack, BusError::Crc]);
        assert_eq!(status.errors.ack, 2);
        assert_eq!(status.errors.crc, 1);
        assert_eq!(status.error_lines, 1);
        status.on_flags(StatusFlags(StatusFlags::DATA_OVERRUN));
        assert_eq!(status.state, Some(BusState::ErrorActive));
        assert_eq!(status.last_status_flags, Some(vec!["data_overrun"]));
        assert_eq!(status.status_replies, 1);
        let off = StateReport {
            state: BusState::BusOff,
            rx_errors: 0,
            tx_errors: 256,
        };
        let said = status.on_state(off).expect("bus-off is said");
        assert!(
            said.contains("bus-off") && said.contains("transmit errors 256"),
            "{said}"
        );
        assert_eq!(status.state_lines, 2);
    }
}
