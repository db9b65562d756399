//! A SocketCAN interface as netlink reports it (`ip -details link show can0`): up or down,
//! its bit rate and sample point (`IFLA_CAN_BITTIMING`), its controller's state
//! (`IFLA_CAN_STATE`, `enum can_state` of linux/can/netlink.h) and its error counters
//! (`IFLA_CAN_BERR_COUNTER`). A vcan has none of the CAN ones; a real controller's driver
//! reports the bit rate and state, and the counters when it can read them.
//!
//! [`check`] decides whether a run may use the interface: a bit rate other than the one the run
//! expects is refused naming both, as is an interface that is down, bus-off, stopped or
//! asleep; what cannot be checked (a vcan's missing bit rate) and what deserves a look (an
//! error-passive controller) become notes.

/// A CAN controller's state (`enum can_state`: error counters below 96, 128, 256, at 256 and
/// above; stopped; sleeping).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ControllerState {
    /// Both error counters below 96: healthy.
    ErrorActive,
    /// An error counter at 96 or above.
    ErrorWarning,
    /// An error counter at 128 or above: the controller only sends passive error flags.
    ErrorPassive,
    /// The transmit error counter reached 256: the controller has left the bus.
    BusOff,
    /// The controller is stopped.
    Stopped,
    /// The controller is asleep.
    Sleeping,
}

/// A controller's transmit and receive error counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct ErrorCounters {
    /// Transmit error counter.
    pub tx: u16,
    /// Receive error counter.
    pub rx: u16,
}

/// What netlink said of an interface.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct InterfaceReading {
    /// Whether the interface is up (`IFF_UP`).
    pub is_up: bool,
    /// The bit rate, bit/s.
    pub bitrate: Option<u32>,
    /// The sample point, in tenths of a percent (875: 87.5 %).
    pub sample_point_permille: Option<u32>,
    /// The controller's state.
    pub state: Option<ControllerState>,
    /// The controller's error counters.
    pub error_counters: Option<ErrorCounters>,
}

impl InterfaceReading {
    /// Whether the interface reports none of a CAN controller's parameters (a vcan).
    #[must_use]
    pub fn has_no_controller(&self) -> bool {
        self.bitrate.is_none() && self.state.is_none() && self.error_counters.is_none()
    }
}

/// The bit rate a run expects of the interface, and who says so (`the URI's @BITRATE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExpectedBitrate<'a> {
    /// Bit/s.
    pub bitrate: u32,
    /// Where the expectation comes from, as a message names it.
    pub source: &'a str,
}

/// Whether a run may use interface `iface` as `reading` shows it, expecting `expected`.
///
/// # Errors
/// Why not, naming the values and the command that changes them: an interface that is down;
/// a bit rate other than the expected one (both named); a controller bus-off, stopped or
/// asleep.
pub fn check(
    iface: &str,
    reading: &InterfaceReading,
    expected: Option<ExpectedBitrate<'_>>,
) -> Result<Vec<String>, String> {
    if !reading.is_up {
        return Err(format!(
            "interface {iface} is down (bring it up: `sudo ip link set up {iface}`)"
        ));
    }
    let mut notes = Vec::new();
    match (reading.bitrate, expected) {
        (Some(actual), Some(expected)) => check_bitrate(iface, actual, expected)?,
        (Some(actual), None) => notes.push(format!(
            "interface {iface} runs at {actual} bit/s; no @BITRATE to check it against (the \
             bus-load check is skipped)"
        )),
        (None, Some(expected)) if reading.has_no_controller() => notes.push(format!(
            "interface {iface} reports no bit rate, state or error counters (a virtual \
             interface, vcan, has none): {} {} bit/s is used for the bus-load check only",
            expected.source, expected.bitrate
        )),
        (None, None) if reading.has_no_controller() => notes.push(format!(
            "interface {iface} reports no bit rate, state or error counters (a virtual \
             interface, vcan, has none)"
        )),
        (None, _) => notes.push(format!(
            "interface {iface} reports no bit rate: it is not checked"
        )),
    }
    let counters = reading.error_counters.map_or_else(String::new, |c| {
        format!(" (error counters: tx {}, rx {})", c.tx, c.rx)
    });
    match reading.state {
        Some(ControllerState::BusOff) => {
            return Err(format!(
                "interface {iface}'s controller is bus-off{counters} (restart it: `sudo ip link \
                 set {iface} type can restart`, or let `restart-ms` do it; then look for a \
                 missing termination or another bit rate on the bus)"
            ));
        }
        Some(state @ (ControllerState::Stopped | ControllerState::Sleeping)) => {
            let state = if state == ControllerState::Stopped {
                "stopped"
            } else {
                "asleep"
            };
            return Err(format!(
                "interface {iface}'s controller is {state} (`ip -details link show {iface}`)"
            ));
        }
        Some(state @ (ControllerState::ErrorWarning | ControllerState::ErrorPassive)) => {
            let state = if state == ControllerState::ErrorWarning {
                "error-warning"
            } else {
                "error-passive"
            };
            notes.push(format!(
                "interface {iface}'s controller is {state}{counters}: frames have failed on \
                 this bus (termination, bit rate and sample point of every node, `candump -e \
                 {iface}`)"
            ));
        }
        Some(ControllerState::ErrorActive) | None => {}
    }
    Ok(notes)
}

/// Whether interface `iface`, running at `actual` bit/s, runs at the `expected` rate.
///
/// # Errors
/// The two rates, who expects the other one, and the commands that set the interface.
pub fn check_bitrate(
    iface: &str,
    actual: u32,
    expected: ExpectedBitrate<'_>,
) -> Result<(), String> {
    if actual == expected.bitrate {
        return Ok(());
    }
    Err(format!(
        "interface {iface} runs at {actual} bit/s but {} says {} bit/s (set the interface: \
         `sudo ip link set {iface} down; sudo ip link set {iface} type can bitrate {}; sudo ip \
         link set {iface} up`, or correct {})",
        expected.source, expected.bitrate, expected.bitrate, expected.source
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    const URI: &str = "the URI's @BITRATE";

    fn can(bitrate: u32, state: ControllerState, tx: u16) -> InterfaceReading {
        InterfaceReading {
            is_up: true,
            bitrate: Some(bitrate),
            sample_point_permille: Some(875),
            state: Some(state),
            error_counters: Some(ErrorCounters { tx, rx: 0 }),
        }
    }

    fn vcan() -> InterfaceReading {
        InterfaceReading {
            is_up: true,
            ..InterfaceReading::default()
        }
    }

    fn expect(bitrate: u32) -> Option<ExpectedBitrate<'static>> {
        Some(ExpectedBitrate {
            bitrate,
            source: URI,
        })
    }

    #[test]
    fn a_healthy_controller_at_the_expected_rate_is_accepted_without_notes() {
        let reading = can(1_000_000, ControllerState::ErrorActive, 0);
        assert_eq!(check("can0", &reading, expect(1_000_000)), Ok(vec![]));
    }

    #[test]
    fn another_bit_rate_is_refused_naming_both() {
        let reading = can(500_000, ControllerState::ErrorActive, 0);
        let refusal = check("can0", &reading, expect(1_000_000)).unwrap_err();
        assert!(
            refusal.starts_with(
                "interface can0 runs at 500000 bit/s but the URI's @BITRATE says 1000000 bit/s"
            ),
            "{refusal}"
        );
        assert!(refusal.contains("type can bitrate 1000000"), "{refusal}");
        let rig = ExpectedBitrate {
            bitrate: 500_000,
            source: "the rig's bus.bitrate_bps",
        };
        assert_eq!(check_bitrate("can0", 500_000, rig), Ok(()));
        let refusal = check_bitrate("can0", 1_000_000, rig).unwrap_err();
        assert!(
            refusal.starts_with(
                "interface can0 runs at 1000000 bit/s but the rig's bus.bitrate_bps says 500000 \
                 bit/s"
            ),
            "{refusal}"
        );
    }

    #[test]
    fn a_vcan_has_no_controller_and_says_so() {
        assert!(vcan().has_no_controller());
        let notes = check("vcan0", &vcan(), expect(1_000_000)).unwrap();
        assert_eq!(
            notes,
            [
                "interface vcan0 reports no bit rate, state or error counters (a virtual \
              interface, vcan, has none): the URI's @BITRATE 1000000 bit/s is used for the \
              bus-load check only"
            ]
        );
        let notes = check("vcan0", &vcan(), None).unwrap();
        assert_eq!(
            notes,
            [
                "interface vcan0 reports no bit rate, state or error counters (a virtual \
              interface, vcan, has none)"
            ]
        );
    }

    #[test]
    fn any_one_controller_parameter_means_a_controller() {
        for reading in [
            InterfaceReading {
                bitrate: Some(1),
                ..vcan()
            },
            InterfaceReading {
                state: Some(ControllerState::ErrorActive),
                ..vcan()
            },
            InterfaceReading {
                error_counters: Some(ErrorCounters { tx: 0, rx: 0 }),
                ..vcan()
            },
        ] {
            assert!(!reading.has_no_controller(), "{reading:?}");
        }
        // A controller that reports no bit rate: said, not refused.
        let no_rate = InterfaceReading {
            state: Some(ControllerState::ErrorActive),
            ..vcan()
        };
        for expected in [expect(1_000_000), None] {
            assert_eq!(
                check("can0", &no_rate, expected),
                Ok(vec![
                    "interface can0 reports no bit rate: it is not checked".to_owned()
                ])
            );
        }
    }

    #[test]
    fn a_rate_with_nothing_to_check_it_against_is_said() {
        let reading = can(250_000, ControllerState::ErrorActive, 0);
        assert_eq!(
            check("can0", &reading, None),
            Ok(vec![
                "interface can0 runs at 250000 bit/s; no @BITRATE to check it against (the \
                 bus-load check is skipped)"
                    .to_owned()
            ])
        );
    }

    #[test]
    fn a_down_bus_off_stopped_or_sleeping_interface_is_refused() {
        let down = InterfaceReading {
            is_up: false,
            ..can(1_000_000, ControllerState::ErrorActive, 0)
        };
        assert_eq!(
            check("can0", &down, expect(1_000_000)),
            Err("interface can0 is down (bring it up: `sudo ip link set up can0`)".to_owned())
        );
        let bus_off =
            check("can0", &can(1_000_000, ControllerState::BusOff, 256), None).unwrap_err();
        assert!(
            bus_off.starts_with(
                "interface can0's controller is bus-off (error counters: tx 256, rx 0) (restart"
            ),
            "{bus_off}"
        );
        for (state, word) in [
            (ControllerState::Stopped, "stopped"),
            (ControllerState::Sleeping, "asleep"),
        ] {
            let reading = can(1_000_000, state, 0);
            assert_eq!(
                check("can0", &reading, expect(1_000_000)),
                Err(format!(
                    "interface can0's controller is {word} (`ip -details link show can0`)"
                ))
            );
        }
    }

    #[test]
    fn a_controller_that_saw_errors_is_accepted_with_a_note() {
        for (state, word, tx) in [
            (ControllerState::ErrorWarning, "error-warning", 100),
            (ControllerState::ErrorPassive, "error-passive", 130),
        ] {
            let notes = check("can0", &can(1_000_000, state, tx), expect(1_000_000)).unwrap();
            assert_eq!(notes.len(), 1, "{notes:?}");
            assert!(
                notes[0].starts_with(&format!(
                    "interface can0's controller is {word} (error counters: tx {tx}, rx 0): \
                     frames have failed"
                )),
                "{notes:?}"
            );
        }
        let without_counters = InterfaceReading {
            error_counters: None,
            ..can(1_000_000, ControllerState::ErrorPassive, 0)
        };
        let notes = check("can0", &without_counters, None).unwrap();
        assert!(
            notes[1].starts_with("interface can0's controller is error-passive: frames"),
            "{notes:?}"
        );
    }
}
