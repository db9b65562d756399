//! CAN error frames as the Linux kernel reports them (`include/uapi/linux/can/error.h`): the
//! error flag `CAN_ERR_FLAG` (0x2000_0000) in the id, the error classes as bits of the id's
//! low 29 bits, and 8 data bytes detailing them (`CAN_ERR_DLC`). `candump -e` logs them with
//! the flag in an 8-digit id (`20000040#0000000000000000`: bus-off).

/// `CAN_ERR_FLAG`: the id bit marking an error frame.
pub const CAN_ERR_FLAG: u32 = 0x2000_0000;
/// `CAN_ERR_MASK`: the id bits that carry the error classes.
pub const CAN_ERR_MASK: u32 = 0x1FFF_FFFF;
/// `CAN_ERR_DLC`: the data bytes of an error frame.
pub const CAN_ERR_DLC: usize = 8;
/// `CAN_ERR_BUSOFF`: the controller went bus-off.
pub const CAN_ERR_BUSOFF: u32 = 0x0000_0040;
/// `CAN_ERR_CNT`: data bytes 6 and 7 hold the transmit and receive error counters.
pub const CAN_ERR_CNT: u32 = 0x0000_0200;

/// Each error class bit with its name (error.h's comment on it).
const CLASSES: [(u32, &str); 10] = [
    (0x0000_0001, "tx_timeout"),
    (0x0000_0002, "lost_arbitration"),
    (0x0000_0004, "controller"),
    (0x0000_0008, "protocol_violation"),
    (0x0000_0010, "transceiver"),
    (0x0000_0020, "no_ack"),
    (CAN_ERR_BUSOFF, "bus_off"),
    (0x0000_0080, "bus_error"),
    (0x0000_0100, "restarted"),
    (CAN_ERR_CNT, "error_counters"),
];

/// A kernel error frame: its classes and its detail bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ErrorFrame {
    /// The error classes (the id without `CAN_ERR_FLAG`).
    pub class: u32,
    /// The detail bytes (`data[0]` lost-arbitration bit, `data[1]` controller status, ...).
    pub data: [u8; CAN_ERR_DLC],
}

impl ErrorFrame {
    /// The frame for the raw id (with or without `CAN_ERR_FLAG`) and up to 8 data bytes (the
    /// rest zero); `None` for more than 8 bytes.
    #[must_use]
    pub fn new(raw_id: u32, data: &[u8]) -> Option<ErrorFrame> {
        let mut bytes = [0; CAN_ERR_DLC];
        bytes.get_mut(..data.len())?.copy_from_slice(data);
        Some(ErrorFrame {
            class: raw_id & CAN_ERR_MASK,
            data: bytes,
        })
    }

    /// The raw id as candump prints it, `CAN_ERR_FLAG` included.
    #[must_use]
    pub fn raw_id(self) -> u32 {
        CAN_ERR_FLAG | self.class
    }

    /// The classes set, named (`bit13` and so on for bits error.h does not name).
    #[must_use]
    pub fn causes(self) -> Vec<String> {
        let named: u32 = CLASSES.iter().map(|(bit, _)| bit).sum();
        let mut causes: Vec<String> = CLASSES
            .iter()
            .filter(|(bit, _)| self.class & bit != 0)
            .map(|(_, name)| (*name).to_owned())
            .collect();
        causes.extend(
            (0..29)
                .filter(|bit| self.class & !named & (1 << bit) != 0)
                .map(|bit| format!("bit{bit}")),
        );
        causes
    }

    /// Whether the controller went bus-off.
    #[must_use]
    pub fn is_bus_off(self) -> bool {
        self.class & CAN_ERR_BUSOFF != 0
    }

    /// The transmit and receive error counters, when the frame carries them (`CAN_ERR_CNT`).
    #[must_use]
    pub fn error_counters(self) -> Option<(u8, u8)> {
        (self.class & CAN_ERR_CNT != 0).then_some((self.data[6], self.data[7]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classes_are_named_and_counters_read() {
        let frame = ErrorFrame::new(0x2000_0244, &[0, 0x10, 0, 0, 0, 0, 0x80, 0x7F]).unwrap();
        assert_eq!(frame.class, 0x244);
        assert_eq!(frame.raw_id(), 0x2000_0244);
        assert_eq!(frame.causes(), ["controller", "bus_off", "error_counters"]);
        assert!(frame.is_bus_off());
        assert_eq!(frame.error_counters(), Some((0x80, 0x7F)));
        let unnamed = ErrorFrame::new(0x0000_2020, &[]).unwrap();
        assert_eq!(unnamed.causes(), ["no_ack", "bit13"]);
        assert!(!unnamed.is_bus_off());
        assert_eq!(unnamed.error_counters(), None);
        assert_eq!(unnamed.data, [0; 8]);
        assert_eq!(ErrorFrame::new(CAN_ERR_FLAG, &[0; 9]), None);
    }
}
