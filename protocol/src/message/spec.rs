//! The single source of truth for the wire layout: one [`MessageSpec`] per CAN message with
//! its [`SignalSpec`]s. Packing, the DBC file, `scanhil decode`'s signal names and the bus
//! load budget all derive from [`MESSAGES`].
//!
//! Every signal is little-endian (Intel byte order; the DBC's `@1`): `start_bit` is the
//! position of its least significant bit, counting bit 0 of byte 0 as 0 and bit 0 of byte 1
//! as 8. Physical value = raw * scale + offset.

use super::{ids, node};

/// One signal of a message: where its bits are and what they mean.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SignalSpec {
    /// The signal's name, as in the DBC file and `scanhil decode`'s JSON.
    pub name: &'static str,
    /// Bit position of the least significant bit (little-endian numbering).
    pub start_bit: u16,
    /// Number of bits, 1 to 64.
    pub length: u8,
    /// Two's complement signed (true) or unsigned.
    pub signed: bool,
    /// Physical units per count.
    pub scale: f64,
    /// Physical value of raw 0.
    pub offset: f64,
    /// Physical unit (empty for counts and codes).
    pub unit: &'static str,
    /// Named raw values (the DBC's value table), empty for plain numbers.
    pub choices: &'static [(u64, &'static str)],
    /// A short description (the DBC's signal comment).
    pub comment: &'static str,
}

impl SignalSpec {
    /// The smallest raw value the field can hold.
    #[must_use]
    pub const fn raw_min(&self) -> i64 {
        if self.signed {
            -(1i64 << (self.length - 1))
        } else {
            0
        }
    }

    /// The largest raw value the field can hold.
    #[must_use]
    pub const fn raw_max(&self) -> i64 {
        if self.signed {
            (1i64 << (self.length - 1)) - 1
        } else if self.length >= 63 {
            i64::MAX
        } else {
            (1i64 << self.length) - 1
        }
    }

    /// The smallest physical value (raw minimum, scaled).
    #[must_use]
    pub fn min(&self) -> f64 {
        self.physical(self.raw_min())
    }

    /// The largest physical value (raw maximum, scaled).
    #[must_use]
    pub fn max(&self) -> f64 {
        self.physical(self.raw_max())
    }

    /// The physical value of a raw value. A scale of `1/n` (such as 1e-6) divides by `n`,
    /// so that `-12741` counts print as `-0.012741`, not with binary rounding noise.
    #[must_use]
    pub fn physical(&self, raw: i64) -> f64 {
        let inverse = 1.0 / self.scale;
        let per_unit = inverse.round();
        let scaled = if per_unit >= 1.0 && (inverse - per_unit).abs() < 1e-9 * per_unit {
            raw as f64 / per_unit
        } else {
            raw as f64 * self.scale
        };
        scaled + self.offset
    }
}

/// Which node sends a message (the DBC's transmitter).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sender {
    /// The controller (host).
    Controller,
    /// The fast steering mirror node.
    Fsm,
    /// The triangulation sensor node.
    Sensor,
}

impl Sender {
    /// The DBC node name.
    #[must_use]
    pub fn dbc_name(self) -> &'static str {
        match self {
            Sender::Controller => "Controller",
            Sender::Fsm => "Fsm",
            Sender::Sensor => "Sensor",
        }
    }
}

/// One CAN message: id, payload length, frame type and signals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MessageSpec {
    /// The 11-bit identifier.
    pub id: u16,
    /// The message name, as in the DBC file and `scanhil decode`'s JSON.
    pub name: &'static str,
    /// Payload length in bytes.
    pub len: u8,
    /// True for a CAN FD frame (with bit-rate switch).
    pub fd: bool,
    /// The sending node.
    pub sender: Sender,
    /// The signals, in bit order.
    pub signals: &'static [SignalSpec],
    /// What the message is for (the DBC's message comment).
    pub comment: &'static str,
}

impl MessageSpec {
    /// The signal called `name`.
    #[must_use]
    pub fn signal(&self, name: &str) -> Option<&'static SignalSpec> {
        self.signals.iter().find(|s| s.name == name)
    }
}

const fn signal(
    name: &'static str,
    start_bit: u16,
    length: u8,
    signed: bool,
    scale: f64,
    unit: &'static str,
    comment: &'static str,
) -> SignalSpec {
    SignalSpec {
        name,
        start_bit,
        length,
        signed,
        scale,
        offset: 0.0,
        unit,
        choices: &[],
        comment,
    }
}

const fn with_choices(spec: SignalSpec, choices: &'static [(u64, &'static str)]) -> SignalSpec {
    SignalSpec { choices, ..spec }
}

/// Sequence counter (command/reading period index modulo 2^16), shared by the loop messages.
const SEQ: SignalSpec = signal("Seq", 0, 16, false, 1.0, "", "Period index k modulo 2^16");
const CURRENT_A: SignalSpec = signal(
    "CurrentA",
    16,
    24,
    true,
    1e-6,
    "A",
    "Coil current on actuator axis a, 1 uA per count",
);
const CURRENT_B: SignalSpec = signal(
    "CurrentB",
    40,
    24,
    true,
    1e-6,
    "A",
    "Coil current on actuator axis b, 1 uA per count",
);
const ALPHA: SignalSpec = signal(
    "Alpha",
    16,
    24,
    true,
    1e-6,
    "rad",
    "Mechanical mirror angle on sensing axis alpha, 1 urad per count",
);
const BETA: SignalSpec = signal(
    "Beta",
    40,
    24,
    true,
    1e-6,
    "rad",
    "Mechanical mirror angle on sensing axis beta, 1 urad per count",
);

/// The value table of the distance status (the class of the ILD raw value).
pub const DISTANCE_STATUS_CHOICES: &[(u64, &str)] = &[
    (0, "distance"),
    (1, "too_much_data"),
    (2, "no_peak"),
    (3, "peak_before_range"),
    (4, "peak_after_range"),
    (5, "cannot_evaluate"),
    (6, "peak_too_wide"),
    (7, "laser_off"),
    (8, "unknown_error"),
];

/// The four distance signals at bit offset `base` (0 in Distance, 64 in AnglesDistanceFd).
const fn distance_signals(base: u16) -> [SignalSpec; 4] {
    [
        signal(
            "IldRaw",
            base,
            18,
            false,
            1.0,
            "",
            "ILD 2300 raw 18-bit value as on RS422 (distance digits or error code)",
        ),
        signal(
            "IldCounter",
            base + 18,
            18,
            false,
            1.0,
            "",
            "ILD 2300 18-bit measured-value counter",
        ),
        signal(
            "SensorTime",
            base + 36,
            24,
            false,
            1.0,
            "us",
            "Sensor node clock at the measurement, microseconds, wraps at 2^24",
        ),
        with_choices(
            signal(
                "Status",
                base + 60,
                4,
                false,
                1.0,
                "",
                "Class of IldRaw: 0 distance, 1-8 ILD error",
            ),
            DISTANCE_STATUS_CHOICES,
        ),
    ]
}

/// Node ids in fault and status frames.
pub const NODE_CHOICES: &[(u64, &str)] = &[
    (node::CONTROLLER as u64, "controller"),
    (node::FSM as u64, "fsm"),
    (node::SENSOR as u64, "sensor"),
];
/// Node states in status frames.
pub const STATE_CHOICES: &[(u64, &str)] =
    &[(0, "boot"), (1, "ready"), (2, "running"), (3, "fault")];
/// Fault kinds in fault frames.
pub const FAULT_KIND_CHOICES: &[(u64, &str)] = &[
    (1, "over_current"),
    (2, "power_limit"),
    (3, "sensor_error"),
    (4, "link_timeout"),
];

const STEP_ONLY: &[SignalSpec] = &[signal("Step", 0, 32, false, 1.0, "", "Period index k")];
const COIL_COMMAND: &[SignalSpec] = &[SEQ, CURRENT_A, CURRENT_B];
const ANGLE_READING: &[SignalSpec] = &[SEQ, ALPHA, BETA];
const DISTANCE: &[SignalSpec] = &distance_signals(0);
const FAULT: &[SignalSpec] = &[
    with_choices(
        signal("Node", 0, 8, false, 1.0, "", "Sending node id"),
        NODE_CHOICES,
    ),
    with_choices(
        signal("Kind", 8, 8, false, 1.0, "", "Fault kind"),
        FAULT_KIND_CHOICES,
    ),
    signal(
        "Detail",
        16,
        32,
        true,
        1.0,
        "",
        "Kind-specific: uA commanded (over_current), mW (power_limit), ILD code (sensor_error), missed periods (link_timeout)",
    ),
    signal(
        "Step",
        48,
        16,
        false,
        1.0,
        "",
        "Period index k modulo 2^16 when the fault happened",
    ),
];
const STATUS: &[SignalSpec] = &[
    with_choices(
        signal("Node", 0, 8, false, 1.0, "", "Sending node id"),
        NODE_CHOICES,
    ),
    with_choices(
        signal("State", 8, 8, false, 1.0, "", "Node state"),
        STATE_CHOICES,
    ),
    signal(
        "Step",
        16,
        24,
        false,
        1.0,
        "",
        "Period index k modulo 2^24 the node is at",
    ),
    signal(
        "NodeTime",
        40,
        24,
        false,
        1.0,
        "us",
        "The node's own clock at period Step, microseconds, wraps at 2^24",
    ),
];
const COMMAND_STEP_FD: &[SignalSpec] = &[
    SEQ,
    CURRENT_A,
    CURRENT_B,
    signal(
        "Step",
        64,
        32,
        false,
        1.0,
        "",
        "Period index k: advance one period",
    ),
];
const ANGLES_DISTANCE_FD: &[SignalSpec] = &{
    let d = distance_signals(64);
    [SEQ, ALPHA, BETA, d[0], d[1], d[2], d[3]]
};

const fn classical(
    id: u16,
    name: &'static str,
    len: u8,
    sender: Sender,
    signals: &'static [SignalSpec],
    comment: &'static str,
) -> MessageSpec {
    MessageSpec {
        id,
        name,
        len,
        fd: false,
        sender,
        signals,
        comment,
    }
}

/// Every message of the set, by ascending id (= descending bus priority).
pub const MESSAGES: &[MessageSpec] = &[
    classical(
        ids::FAULT_CONTROLLER,
        "FaultController",
        8,
        Sender::Controller,
        FAULT,
        "Fault raised by the controller",
    ),
    classical(
        ids::FAULT_FSM,
        "FaultFsm",
        8,
        Sender::Fsm,
        FAULT,
        "Fault raised by the mirror node",
    ),
    classical(
        ids::FAULT_SENSOR,
        "FaultSensor",
        8,
        Sender::Sensor,
        FAULT,
        "Fault raised by the sensor node",
    ),
    classical(
        ids::SYNC,
        "Sync",
        4,
        Sender::Fsm,
        STEP_ONLY,
        "Real-time clock master tick: period k starts",
    ),
    classical(
        ids::STEP,
        "Step",
        4,
        Sender::Controller,
        STEP_ONLY,
        "Lockstep: advance exactly one period",
    ),
    classical(
        ids::COIL_COMMAND,
        "CoilCommand",
        8,
        Sender::Controller,
        COIL_COMMAND,
        "Coil currents for actuator axes a and b",
    ),
    classical(
        ids::ANGLE_READING,
        "AngleReading",
        8,
        Sender::Fsm,
        ANGLE_READING,
        "Mirror angles on sensing axes alpha and beta",
    ),
    classical(
        ids::DISTANCE,
        "Distance",
        8,
        Sender::Sensor,
        DISTANCE,
        "One ILD 2300 measured value with its counter and time",
    ),
    MessageSpec {
        id: ids::COMMAND_STEP_FD,
        name: "CommandStepFd",
        len: 12,
        fd: true,
        sender: Sender::Controller,
        signals: COMMAND_STEP_FD,
        comment: "CAN FD option: CoilCommand and Step in one frame",
    },
    MessageSpec {
        id: ids::ANGLES_DISTANCE_FD,
        name: "AnglesDistanceFd",
        len: 16,
        fd: true,
        sender: Sender::Fsm,
        signals: ANGLES_DISTANCE_FD,
        comment: "CAN FD option: AngleReading and Distance of one period in one frame",
    },
    classical(
        ids::STATUS_CONTROLLER,
        "StatusController",
        8,
        Sender::Controller,
        STATUS,
        "Heartbeat of the controller",
    ),
    classical(
        ids::STATUS_FSM,
        "StatusFsm",
        8,
        Sender::Fsm,
        STATUS,
        "Heartbeat of the mirror node",
    ),
    classical(
        ids::STATUS_SENSOR,
        "StatusSensor",
        8,
        Sender::Sensor,
        STATUS,
        "Heartbeat of the sensor node",
    ),
];

/// The spec of message `id`, `None` for an id not in the set.
#[must_use]
pub fn message_spec(id: u16) -> Option<&'static MessageSpec> {
    let index = *SPEC_INDEX_BY_ID.get(usize::from(id))?;
    MESSAGES.get(usize::from(index))
}

/// Each 11-bit id's index into [`MESSAGES`] (`u8::MAX`: no message has it), built from the
/// table when the crate compiles: every frame's lookup is one load, not a search.
const SPEC_INDEX_BY_ID: [u8; 0x800] = {
    let mut index = [u8::MAX; 0x800];
    let mut i = 0;
    while i < MESSAGES.len() {
        index[MESSAGES[i].id as usize] = i as u8;
        i += 1;
    }
    index
};

/// Writes the raw values (one per signal, in the spec's order) into `payload`.
///
/// Values are truncated to their field width; callers check ranges first (the typed
/// messages do). Bits outside `payload` are dropped, never a panic.
pub fn pack(signals: &[SignalSpec], raw: &[i64], payload: &mut [u8]) {
    for (spec, &value) in signals.iter().zip(raw) {
        let bits = value as u64;
        for span in byte_spans(spec) {
            // Bits from here on fall outside the payload, and so do the later signals'.
            let Some(byte) = payload.get_mut(span.byte) else {
                return;
            };
            let chunk = (bits >> span.value_shift) as u8 & span.width_mask;
            let mask = span.width_mask << span.byte_shift;
            *byte = (*byte & !mask) | (chunk << span.byte_shift);
        }
    }
}

/// Reads one signal's raw value (sign-extended when signed); bits beyond `payload` read 0.
#[must_use]
pub fn unpack(spec: &SignalSpec, payload: &[u8]) -> i64 {
    let mut bits = 0u64;
    for span in byte_spans(spec) {
        if let Some(byte) = payload.get(span.byte) {
            let chunk = byte >> span.byte_shift & span.width_mask;
            bits |= u64::from(chunk) << span.value_shift;
        }
    }
    if spec.signed && spec.length < 64 && bits >> (spec.length - 1) & 1 == 1 {
        bits |= u64::MAX << spec.length;
    }
    bits as i64
}

/// The part of a signal that lies in one payload byte.
struct ByteSpan {
    /// The payload byte.
    byte: usize,
    /// Position of the part's lowest bit in the byte.
    byte_shift: u32,
    /// Position of the part's lowest bit in the signal's value.
    value_shift: u32,
    /// The part's width as a mask of its low bits (1 to 8 bits set).
    width_mask: u8,
}

/// The bytes a signal's bits occupy, lowest first, a whole byte at a time.
fn byte_spans(spec: &SignalSpec) -> impl Iterator<Item = ByteSpan> {
    let start = u32::from(spec.start_bit);
    let end = start + u32::from(spec.length);
    let first = start / 8;
    let last = end.div_ceil(8);
    (first..last).map(move |byte| {
        let low = start.max(byte * 8);
        let high = end.min(byte * 8 + 8);
        ByteSpan {
            byte: byte as usize,
            byte_shift: low - byte * 8,
            value_shift: low - start,
            width_mask: (0xFFu16 >> (8 - (high - low))) as u8,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_id_index_finds_what_a_search_of_the_table_finds() {
        assert!(MESSAGES.len() < usize::from(u8::MAX), "indices fit a u8");
        for id in 0..=u16::MAX {
            let searched = MESSAGES.iter().find(|m| m.id == id);
            assert_eq!(
                message_spec(id).map(|m| m.id),
                searched.map(|m| m.id),
                "{id:#x}"
            );
        }
    }

    #[test]
    fn signals_fit_their_payload_and_do_not_overlap() {
        for message in MESSAGES {
            let mut used = vec![false; usize::from(message.len) * 8];
            for s in message.signals {
                for bit in s.start_bit..s.start_bit + u16::from(s.length) {
                    let slot = used.get_mut(usize::from(bit)).unwrap_or_else(|| {
                        panic!("{}.{} beyond the payload", message.name, s.name)
                    });
                    assert!(!*slot, "{}.{} overlaps at bit {bit}", message.name, s.name);
                    *slot = true;
                }
            }
        }
    }

    #[test]
    fn ids_are_unique_ascending_and_11_bit() {
        for pair in MESSAGES.windows(2) {
            assert!(
                pair[0].id < pair[1].id,
                "{} / {}",
                pair[0].name,
                pair[1].name
            );
        }
        assert!(MESSAGES.iter().all(|m| m.id <= crate::can::STANDARD_ID_MAX));
    }

    /// The bit-at-a-time packing the byte-wise one replaced: the oracle.
    fn pack_bit_by_bit(signals: &[SignalSpec], raw: &[i64], payload: &mut [u8]) {
        for (spec, &value) in signals.iter().zip(raw) {
            for i in 0..u16::from(spec.length) {
                let bit = spec.start_bit + i;
                let Some(byte) = payload.get_mut(usize::from(bit / 8)) else {
                    return;
                };
                let mask = 1u8 << (bit % 8);
                if (value as u64) >> i & 1 == 1 {
                    *byte |= mask;
                } else {
                    *byte &= !mask;
                }
            }
        }
    }

    /// The bit-at-a-time unpacking the byte-wise one replaced: the oracle.
    fn unpack_bit_by_bit(spec: &SignalSpec, payload: &[u8]) -> i64 {
        let mut bits = 0u64;
        for i in 0..u16::from(spec.length) {
            let bit = spec.start_bit + i;
            let set = payload
                .get(usize::from(bit / 8))
                .is_some_and(|b| b >> (bit % 8) & 1 == 1);
            bits |= u64::from(set) << i;
        }
        if spec.signed && spec.length < 64 && bits >> (spec.length - 1) & 1 == 1 {
            bits |= u64::MAX << spec.length;
        }
        bits as i64
    }

    proptest::proptest! {
        #[test]
        fn byte_wise_packing_agrees_with_bit_by_bit(
            start_bit in 0u16..80,
            length in 1u8..=64,
            signed in proptest::bool::ANY,
            value in proptest::num::i64::ANY,
            gap in 0u16..10,
            next_value in proptest::num::i64::ANY,
            background in proptest::collection::vec(proptest::num::u8::ANY, 0..12),
        ) {
            let spec = SignalSpec { start_bit, length, signed, ..SEQ };
            // A second signal after a gap (whose bits must be left alone), and running off
            // the payload stops both.
            let next_start = start_bit + u16::from(length) + gap;
            let next = SignalSpec { start_bit: next_start, length: 11, ..SEQ };
            let (mut fast, mut slow) = (background.clone(), background);
            pack(&[spec, next], &[value, next_value], &mut fast);
            pack_bit_by_bit(&[spec, next], &[value, next_value], &mut slow);
            proptest::prop_assert_eq!(&fast, &slow);
            proptest::prop_assert_eq!(unpack(&spec, &fast), unpack_bit_by_bit(&spec, &fast));
            proptest::prop_assert_eq!(unpack(&next, &fast), unpack_bit_by_bit(&next, &fast));
        }
    }

    #[test]
    fn signed_fields_sign_extend() {
        let spec = CURRENT_A;
        let mut payload = [0u8; 8];
        pack(&[SEQ, spec], &[0xBEEF, -5], &mut payload);
        assert_eq!(payload, [0xEF, 0xBE, 0xFB, 0xFF, 0xFF, 0, 0, 0]);
        assert_eq!(unpack(&spec, &payload), -5);
        assert_eq!(unpack(&SEQ, &payload), 0xBEEF);
        assert_eq!(
            (spec.raw_min(), spec.raw_max()),
            (-(1 << 23), (1 << 23) - 1)
        );
    }
}
