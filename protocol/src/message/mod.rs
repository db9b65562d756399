//! The scanhil CAN message set: typed messages, their ids, and encoding to / decoding from
//! [`CanFrame`]s. The bit layout lives once, in [`spec::MESSAGES`]; `protocol/scanhil.dbc`
//! is generated from it ([`crate::dbc`]) and a test proves they agree.
//!
//! All frames use 11-bit ids; lower ids win arbitration, so faults come first, then the
//! loop's timing frames, the loop data, the FD options, and heartbeats last.
//! Every signal is little-endian (Intel).
//!
//! | id | message | from | bytes | layout (bit ranges) |
//! |----|---------|------|-------|---------------------|
//! | 0x011/0x012/0x013 | FaultController/Fsm/Sensor | that node | 8 | Node u8 0-7, Kind u8 8-15, Detail i32 16-47, Step u16 48-63 |
//! | 0x020 | Sync | fsm (clock master) | 4 | Step u32 0-31 |
//! | 0x021 | Step | controller | 4 | Step u32 0-31 |
//! | 0x100 | CoilCommand | controller | 8 | Seq u16 0-15, CurrentA i24 16-39, CurrentB i24 40-63 (1 uA, +-8.388607 A) |
//! | 0x110 | AngleReading | fsm | 8 | Seq u16 0-15, Alpha i24 16-39, Beta i24 40-63 (1 urad, +-8.388607 rad) |
//! | 0x120 | Distance | sensor | 8 | IldRaw u18 0-17, IldCounter u18 18-35, SensorTime u24 36-59 (us), Status u4 60-63 |
//! | 0x140 | CommandStepFd | controller | 12 (FD) | CoilCommand layout, Step u32 64-95 |
//! | 0x150 | AnglesDistanceFd | fsm | 16 (FD) | AngleReading layout, Distance layout at 64-127 |
//! | 0x701/0x702/0x703 | StatusController/Fsm/Sensor | that node | 8 | Node u8 0-7, State u8 8-15, Step u24 16-39, NodeTime u24 40-63 (us) |
//!
//! # Layout
//! - [`spec`]: the signal table, bit packing and unpacking.
//! - [`carried`]: a message on its way, as a frame or (in one process) as itself.
//! - this module: ids, node ids, the typed messages and [`Message`].

pub mod carried;
pub mod spec;

pub use carried::Carried;

use crate::can::{CanFrame, CanId, FrameFormat};
use crate::ild::IldValue;
use crate::plant_units::{ActuatorPair, SensingPair};
use spec::{MessageSpec, SignalSpec, message_spec, pack, unpack};

/// The message ids, named once.
pub mod ids {
    use super::node;

    /// Base of the fault ids: a node's fault frame is `FAULT_BASE + node id`.
    pub const FAULT_BASE: u16 = 0x010;
    /// Fault raised by the controller.
    pub const FAULT_CONTROLLER: u16 = FAULT_BASE + node::CONTROLLER as u16;
    /// Fault raised by the mirror node.
    pub const FAULT_FSM: u16 = FAULT_BASE + node::FSM as u16;
    /// Fault raised by the sensor node.
    pub const FAULT_SENSOR: u16 = FAULT_BASE + node::SENSOR as u16;
    /// Real-time clock master tick.
    pub const SYNC: u16 = 0x020;
    /// Lockstep step.
    pub const STEP: u16 = 0x021;
    /// Coil current command.
    pub const COIL_COMMAND: u16 = 0x100;
    /// Mirror angle reading.
    pub const ANGLE_READING: u16 = 0x110;
    /// ILD distance.
    pub const DISTANCE: u16 = 0x120;
    /// CAN FD: coil command and step.
    pub const COMMAND_STEP_FD: u16 = 0x140;
    /// CAN FD: angle reading and distance.
    pub const ANGLES_DISTANCE_FD: u16 = 0x150;
    /// Base of the status ids: a node's heartbeat is `STATUS_BASE + node id`.
    pub const STATUS_BASE: u16 = 0x700;
    /// Heartbeat of the controller.
    pub const STATUS_CONTROLLER: u16 = STATUS_BASE + node::CONTROLLER as u16;
    /// Heartbeat of the mirror node.
    pub const STATUS_FSM: u16 = STATUS_BASE + node::FSM as u16;
    /// Heartbeat of the sensor node.
    pub const STATUS_SENSOR: u16 = STATUS_BASE + node::SENSOR as u16;
}

/// Node ids, named once.
pub mod node {
    /// The controller (host).
    pub const CONTROLLER: u8 = 1;
    /// The fast steering mirror node.
    pub const FSM: u8 = 2;
    /// The triangulation sensor node.
    pub const SENSOR: u8 = 3;
}

/// A node on the bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NodeId {
    /// The controller (host).
    Controller,
    /// The fast steering mirror node.
    Fsm,
    /// The triangulation sensor node.
    Sensor,
}

impl NodeId {
    /// The id on the wire.
    #[must_use]
    pub fn code(self) -> u8 {
        match self {
            NodeId::Controller => node::CONTROLLER,
            NodeId::Fsm => node::FSM,
            NodeId::Sensor => node::SENSOR,
        }
    }

    /// The node with wire id `code`.
    #[must_use]
    pub fn from_code(code: u8) -> Option<NodeId> {
        [NodeId::Controller, NodeId::Fsm, NodeId::Sensor]
            .into_iter()
            .find(|n| n.code() == code)
    }
}

/// A node's state in its heartbeat.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NodeState {
    /// Powered, not configured.
    Boot,
    /// Configured, waiting for the loop to start.
    Ready,
    /// Running the loop.
    Running,
    /// Faulted (the mirror node's coil currents are zero).
    Fault,
}

impl NodeState {
    const ALL: [NodeState; 4] = [
        NodeState::Boot,
        NodeState::Ready,
        NodeState::Running,
        NodeState::Fault,
    ];

    /// The code on the wire (0 boot, 1 ready, 2 running, 3 fault).
    #[must_use]
    pub fn code(self) -> u8 {
        Self::ALL.iter().position(|&s| s == self).unwrap_or(0) as u8
    }

    /// The state with wire code `code`.
    #[must_use]
    pub fn from_code(code: u8) -> Option<NodeState> {
        Self::ALL.get(usize::from(code)).copied()
    }
}

/// What a fault frame reports. Unknown codes are kept, not dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// Code 1: a coil command beyond the current limit (Detail: commanded uA).
    OverCurrent,
    /// Code 2: the coil power limit was reached (Detail: power in mW).
    PowerLimit,
    /// Code 3: the sensor failed (Detail: the ILD raw error code).
    SensorError,
    /// Code 4: the link went silent (Detail: missed periods).
    LinkTimeout,
    /// Any other code.
    Unknown(u8),
}

impl FaultKind {
    /// The code on the wire.
    #[must_use]
    pub fn code(self) -> u8 {
        match self {
            FaultKind::OverCurrent => 1,
            FaultKind::PowerLimit => 2,
            FaultKind::SensorError => 3,
            FaultKind::LinkTimeout => 4,
            FaultKind::Unknown(code) => code,
        }
    }

    /// The kind with wire code `code` (unknown codes kept as [`FaultKind::Unknown`]).
    #[must_use]
    pub fn from_code(code: u8) -> FaultKind {
        match code {
            1 => FaultKind::OverCurrent,
            2 => FaultKind::PowerLimit,
            3 => FaultKind::SensorError,
            4 => FaultKind::LinkTimeout,
            other => FaultKind::Unknown(other),
        }
    }
}

/// Why a message could not be encoded or a frame could not be decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MessageError {
    /// The frame's id is not in the message set.
    #[error("unknown id {0}")]
    UnknownId(CanId),
    /// The frame's length or format differs from the message's.
    #[error("{message}: expected {expected}, got {got}")]
    WrongShape {
        /// The message the id stands for.
        message: &'static str,
        /// The expected length and format.
        expected: String,
        /// The frame's length and format.
        got: String,
    },
    /// A field value outside its signal's range (encoding).
    #[error("{message}.{signal}: {value} outside {min}..={max}")]
    OutOfRange {
        /// The message.
        message: &'static str,
        /// The signal.
        signal: &'static str,
        /// The offered raw value.
        value: i64,
        /// Smallest raw value.
        min: i64,
        /// Largest raw value.
        max: i64,
    },
    /// A code that the message does not define (decoding).
    #[error("{message}.{signal}: undefined code {value}")]
    UndefinedCode {
        /// The message.
        message: &'static str,
        /// The signal.
        signal: &'static str,
        /// The raw code.
        value: i64,
    },
    /// Two fields that must agree do not (decoding).
    #[error("{message}: {what}")]
    Inconsistent {
        /// The message.
        message: &'static str,
        /// What disagrees with what.
        what: String,
    },
}

/// Coil current command, controller -> mirror node (`CoilCommand`, 0x100).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct CoilCommand {
    /// Period index k modulo 2^16.
    pub seq: u16,
    /// Coil current on actuator axis a, uA (24-bit signed).
    pub current_a_ua: i32,
    /// Coil current on actuator axis b, uA (24-bit signed).
    pub current_b_ua: i32,
}

/// The largest magnitude a 24-bit signed field holds (8 388 607).
pub const I24_MAX: i32 = (1 << 23) - 1;
/// The largest 18-bit value (ILD raw values and counters).
pub const U18_MAX: u32 = (1 << 18) - 1;
/// The largest 24-bit unsigned value (node clocks, status step).
pub const U24_MAX: u32 = (1 << 24) - 1;

/// Whether a 16-bit sequence counter `seq` (CoilCommand, AngleReading) is that of period
/// `next` (counters wrap at 2^16): a recording's reader checks that no period is missing. The
/// error names `what`, the counter found and the one expected.
///
/// # Errors
/// The text of the mismatch.
pub fn check_period_counter(what: &str, seq: u16, next: usize) -> Result<(), String> {
    let expected = next as u16;
    if seq == expected {
        Ok(())
    } else {
        Err(format!(
            "{what} counter {seq} where period {next} (counter {expected}) was next"
        ))
    }
}

/// Rounds `value / unit` to the nearest count, saturated to the 24-bit signed range; NaN
/// gives 0.
fn saturating_i24(value: f64, unit: f64) -> i32 {
    let counts = (value / unit).round();
    if counts.is_nan() {
        0
    } else {
        counts.clamp(-f64::from(I24_MAX) - 1.0, f64::from(I24_MAX)) as i32
    }
}

/// Amperes per count of the coil current fields.
pub const AMPS_PER_COUNT: f64 = 1e-6;
/// Radians per count of the angle fields.
pub const RAD_PER_COUNT: f64 = 1e-6;

impl CoilCommand {
    /// The command for coil currents in amperes, rounded to 1 uA and saturated to
    /// +-8.388607 A (what a DAC does with a value beyond its range).
    #[must_use]
    pub fn from_amps(seq: u16, currents_a: ActuatorPair) -> CoilCommand {
        CoilCommand {
            seq,
            current_a_ua: saturating_i24(currents_a.a, AMPS_PER_COUNT),
            current_b_ua: saturating_i24(currents_a.b, AMPS_PER_COUNT),
        }
    }

    /// The coil currents in amperes.
    #[must_use]
    pub fn amps(&self) -> ActuatorPair {
        ActuatorPair {
            a: f64::from(self.current_a_ua) * AMPS_PER_COUNT,
            b: f64::from(self.current_b_ua) * AMPS_PER_COUNT,
        }
    }

    fn raw(&self) -> [i64; 3] {
        [
            i64::from(self.seq),
            i64::from(self.current_a_ua),
            i64::from(self.current_b_ua),
        ]
    }

    fn from_fields(f: &[i64]) -> CoilCommand {
        CoilCommand {
            seq: f[0] as u16,
            current_a_ua: f[1] as i32,
            current_b_ua: f[2] as i32,
        }
    }
}

/// Mirror angle reading, mirror node -> controller (`AngleReading`, 0x110).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct AngleReading {
    /// Period index k modulo 2^16 (answers the command with the same seq).
    pub seq: u16,
    /// Mechanical angle on sensing axis alpha, urad (24-bit signed).
    pub alpha_urad: i32,
    /// Mechanical angle on sensing axis beta, urad (24-bit signed).
    pub beta_urad: i32,
}

impl AngleReading {
    /// The reading for angles in radians, rounded to 1 urad and saturated to the field.
    #[must_use]
    pub fn from_rad(seq: u16, angles_rad: SensingPair) -> AngleReading {
        AngleReading {
            seq,
            alpha_urad: saturating_i24(angles_rad.alpha, RAD_PER_COUNT),
            beta_urad: saturating_i24(angles_rad.beta, RAD_PER_COUNT),
        }
    }

    /// The angles in radians.
    #[must_use]
    pub fn rad(&self) -> SensingPair {
        SensingPair {
            alpha: f64::from(self.alpha_urad) * RAD_PER_COUNT,
            beta: f64::from(self.beta_urad) * RAD_PER_COUNT,
        }
    }

    fn raw(&self) -> [i64; 3] {
        [
            i64::from(self.seq),
            i64::from(self.alpha_urad),
            i64::from(self.beta_urad),
        ]
    }

    fn from_fields(f: &[i64]) -> AngleReading {
        AngleReading {
            seq: f[0] as u16,
            alpha_urad: f[1] as i32,
            beta_urad: f[2] as i32,
        }
    }
}

/// One ILD measured value, sensor node -> controller (`Distance`, 0x120).
///
/// `value.raw()` is the same 18-bit integer the sensor sends on RS422; the Status signal on
/// the wire is derived from it (0 distance, 1-8 the error class) and checked on decoding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Distance {
    /// The measured value: distance digits or an error.
    pub value: IldValue,
    /// The ILD's 18-bit measured-value counter.
    pub counter: u32,
    /// The sensor node's clock at the measurement, us, modulo 2^24.
    pub sensor_time_us: u32,
}

impl Distance {
    /// The Status code for a value (index into [`spec::DISTANCE_STATUS_CHOICES`]).
    #[must_use]
    pub fn status_code(value: IldValue) -> u8 {
        use crate::ild::IldError;
        match value {
            IldValue::Distance(_) => 0,
            IldValue::Error(e) => match e {
                IldError::TooMuchData => 1,
                IldError::NoPeak => 2,
                IldError::PeakBeforeRange => 3,
                IldError::PeakAfterRange => 4,
                IldError::CannotEvaluate => 5,
                IldError::PeakTooWide => 6,
                IldError::LaserOff => 7,
                IldError::Unknown(_) => 8,
            },
        }
    }

    fn raw(&self) -> [i64; 4] {
        [
            i64::from(self.value.raw()),
            i64::from(self.counter),
            i64::from(self.sensor_time_us),
            i64::from(Self::status_code(self.value)),
        ]
    }

    fn from_fields(message: &'static str, f: &[i64]) -> Result<Distance, MessageError> {
        let value = IldValue::from_raw(f[0] as u32);
        let status = f[3];
        if status != i64::from(Self::status_code(value)) {
            return Err(MessageError::Inconsistent {
                message,
                what: format!(
                    "Status {status} disagrees with IldRaw {} (status {})",
                    f[0],
                    Self::status_code(value)
                ),
            });
        }
        Ok(Distance {
            value,
            counter: f[1] as u32,
            sensor_time_us: f[2] as u32,
        })
    }
}

/// A node's fault report (`FaultController`/`FaultFsm`/`FaultSensor`, 0x010 + node id).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Fault {
    /// The reporting node (also selects the frame id).
    pub node: NodeId,
    /// What went wrong.
    pub kind: FaultKind,
    /// Kind-specific detail (see [`FaultKind`]).
    pub detail: i32,
    /// Period index k modulo 2^16 when it happened.
    pub step: u16,
}

/// A node's heartbeat (`StatusController`/`StatusFsm`/`StatusSensor`, 0x700 + node id).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Status {
    /// The reporting node (also selects the frame id).
    pub node: NodeId,
    /// Its state.
    pub state: NodeState,
    /// Period index k modulo 2^24 the node is at.
    pub step: u32,
    /// The node's own clock at period `step`, us, modulo 2^24 (the sensor node declares its
    /// clock offset this way: pair it with the Distance frames' `sensor_time_us`).
    pub node_time_us: u32,
}

/// One message of the set, typed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Message {
    /// A node's fault report.
    Fault(Fault),
    /// Real-time tick: period `k` starts (clock master -> all).
    Sync {
        /// Period index k.
        step: u32,
    },
    /// Lockstep: advance exactly one period (controller -> nodes).
    Step {
        /// Period index k.
        step: u32,
    },
    /// Coil current command.
    CoilCommand(CoilCommand),
    /// Mirror angle reading.
    AngleReading(AngleReading),
    /// One ILD measured value.
    Distance(Distance),
    /// CAN FD: coil command and step in one frame.
    CommandStepFd {
        /// The command.
        command: CoilCommand,
        /// Period index k to advance.
        step: u32,
    },
    /// CAN FD: one period's angle reading and distance in one frame.
    AnglesDistanceFd {
        /// The angles.
        angles: AngleReading,
        /// The distance.
        distance: Distance,
    },
    /// A node's heartbeat.
    Status(Status),
}

impl Message {
    /// The message's id.
    #[must_use]
    pub fn id(&self) -> u16 {
        match self {
            Message::Fault(f) => ids::FAULT_BASE + u16::from(f.node.code()),
            Message::Sync { .. } => ids::SYNC,
            Message::Step { .. } => ids::STEP,
            Message::CoilCommand(_) => ids::COIL_COMMAND,
            Message::AngleReading(_) => ids::ANGLE_READING,
            Message::Distance(_) => ids::DISTANCE,
            Message::CommandStepFd { .. } => ids::COMMAND_STEP_FD,
            Message::AnglesDistanceFd { .. } => ids::ANGLES_DISTANCE_FD,
            Message::Status(s) => ids::STATUS_BASE + u16::from(s.node.code()),
        }
    }

    /// The message's layout.
    #[must_use]
    pub fn spec(&self) -> &'static MessageSpec {
        // Every id `Message::id` returns is in the table (a test checks it).
        message_spec(self.id()).unwrap_or(&spec::MESSAGES[0])
    }

    /// The raw field values in the spec's signal order.
    fn raw(&self) -> Fields {
        match self {
            Message::Fault(f) => Fields::from([
                i64::from(f.node.code()),
                i64::from(f.kind.code()),
                i64::from(f.detail),
                i64::from(f.step),
            ]),
            Message::Sync { step } | Message::Step { step } => Fields::from([i64::from(*step)]),
            Message::CoilCommand(c) => Fields::from(c.raw()),
            Message::AngleReading(a) => Fields::from(a.raw()),
            Message::Distance(d) => Fields::from(d.raw()),
            Message::CommandStepFd { command, step } => {
                Fields::of(&[&command.raw(), &[i64::from(*step)]])
            }
            Message::AnglesDistanceFd { angles, distance } => {
                Fields::of(&[&angles.raw(), &distance.raw()])
            }
            Message::Status(s) => Fields::from([
                i64::from(s.node.code()),
                i64::from(s.state.code()),
                i64::from(s.step),
                i64::from(s.node_time_us),
            ]),
        }
    }

    /// The frame that carries this message.
    ///
    /// # Errors
    /// [`MessageError::OutOfRange`] when a field does not fit its signal (e.g. a coil
    /// current beyond +-8 388 607 uA, a counter beyond 18 bits).
    pub fn encode(&self) -> Result<CanFrame, MessageError> {
        let spec = self.spec();
        let raw = self.raw();
        check_ranges(spec, &raw)?;
        let mut buffer = [0u8; crate::can::FD_MAX_LEN];
        let payload = &mut buffer[..usize::from(spec.len)];
        pack(spec.signals, &raw, payload);
        let id = CanId::standard(spec.id).ok_or_else(|| MessageError::Inconsistent {
            message: spec.name,
            what: "id beyond 11 bits".to_owned(),
        })?;
        let frame = if spec.fd {
            CanFrame::new_fd(id, payload, true, false)
        } else {
            CanFrame::new(id, payload)
        };
        frame.map_err(|e| MessageError::Inconsistent {
            message: spec.name,
            what: e.to_string(),
        })
    }

    /// Checks that every field fits its signal, as [`Self::encode`] does, without building
    /// the frame: a message that passes is one the frame carries unchanged
    /// (`decode(encode(m)) == m`), so a transport inside one process can hand it over as it is.
    ///
    /// # Errors
    /// [`MessageError::OutOfRange`], as [`Self::encode`].
    pub fn check(&self) -> Result<(), MessageError> {
        check_ranges(self.spec(), &self.raw())
    }

    /// The message a frame carries.
    ///
    /// # Errors
    /// [`MessageError::UnknownId`] for an id not in the set, [`MessageError::WrongShape`]
    /// for a wrong length or format, [`MessageError::UndefinedCode`] /
    /// [`MessageError::Inconsistent`] for field values the message does not allow.
    pub fn decode(frame: &CanFrame) -> Result<Message, MessageError> {
        let (spec, f) = raw_fields(frame)?;
        let code = |i: usize| -> Result<u8, MessageError> {
            u8::try_from(f[i]).map_err(|_| undefined(spec, &spec.signals[i], f[i]))
        };
        let node = |i: usize| -> Result<NodeId, MessageError> {
            let node = NodeId::from_code(code(i)?)
                .ok_or_else(|| undefined(spec, &spec.signals[i], f[i]))?;
            let id_node = u16::from(node.code());
            if spec.id & 0x00F != id_node {
                return Err(MessageError::Inconsistent {
                    message: spec.name,
                    what: format!("Node {} sent on id {:#05x}", node.code(), spec.id),
                });
            }
            Ok(node)
        };
        Ok(match spec.id {
            ids::SYNC => Message::Sync { step: f[0] as u32 },
            ids::STEP => Message::Step { step: f[0] as u32 },
            ids::COIL_COMMAND => Message::CoilCommand(CoilCommand::from_fields(&f)),
            ids::ANGLE_READING => Message::AngleReading(AngleReading::from_fields(&f)),
            ids::DISTANCE => Message::Distance(Distance::from_fields(spec.name, &f)?),
            ids::COMMAND_STEP_FD => Message::CommandStepFd {
                command: CoilCommand::from_fields(&f[..3]),
                step: f[3] as u32,
            },
            ids::ANGLES_DISTANCE_FD => Message::AnglesDistanceFd {
                angles: AngleReading::from_fields(&f[..3]),
                distance: Distance::from_fields(spec.name, &f[3..])?,
            },
            ids::FAULT_CONTROLLER | ids::FAULT_FSM | ids::FAULT_SENSOR => Message::Fault(Fault {
                node: node(0)?,
                kind: FaultKind::from_code(code(1)?),
                detail: f[2] as i32,
                step: f[3] as u16,
            }),
            _ => Message::Status(Status {
                node: node(0)?,
                state: NodeState::from_code(code(1)?)
                    .ok_or_else(|| undefined(spec, &spec.signals[1], f[1]))?,
                step: f[2] as u32,
                node_time_us: f[3] as u32,
            }),
        })
    }
}

/// Every raw field of `spec`'s message within its signal's range.
fn check_ranges(spec: &MessageSpec, raw: &Fields) -> Result<(), MessageError> {
    for (signal, &value) in spec.signals.iter().zip(raw.iter()) {
        if value < signal.raw_min() || value > signal.raw_max() {
            return Err(MessageError::OutOfRange {
                message: spec.name,
                signal: signal.name,
                value,
                min: signal.raw_min(),
                max: signal.raw_max(),
            });
        }
    }
    Ok(())
}

fn undefined(spec: &MessageSpec, signal: &SignalSpec, value: i64) -> MessageError {
    MessageError::UndefinedCode {
        message: spec.name,
        signal: signal.name,
        value,
    }
}

/// A frame's message spec and raw signal values, after checking id, length and format.
fn raw_fields(frame: &CanFrame) -> Result<(&'static MessageSpec, Fields), MessageError> {
    let spec = match frame.id() {
        CanId::Standard(id) => message_spec(id.as_raw()),
        CanId::Extended(_) => None,
    }
    .ok_or(MessageError::UnknownId(frame.id()))?;
    let shape =
        |len: usize, fd: bool| format!("{len} bytes {}", if fd { "FD" } else { "classical" });
    let format_ok = match frame.format() {
        FrameFormat::Classical => !spec.fd,
        FrameFormat::Fd { .. } => spec.fd,
        FrameFormat::Remote => false,
    };
    if !format_ok || frame.data().len() != usize::from(spec.len) {
        let got = if frame.is_remote() {
            "remote frame".to_owned()
        } else {
            shape(frame.data().len(), frame.is_fd())
        };
        return Err(MessageError::WrongShape {
            message: spec.name,
            expected: shape(usize::from(spec.len), spec.fd),
            got,
        });
    }
    let mut fields = Fields::default();
    for signal in spec.signals {
        fields.push(unpack(signal, frame.data()));
    }
    Ok((spec, fields))
}

/// Most signals a message has (a test checks every message against it).
const MAX_FIELDS: usize = 8;

/// A message's raw field values in its spec's signal order, kept inline: encoding and decoding
/// a frame allocate nothing.
#[derive(Debug, Clone, Copy, Default)]
struct Fields {
    values: [i64; MAX_FIELDS],
    len: usize,
}

impl Fields {
    /// The values of `parts`, one after the other.
    fn of(parts: &[&[i64]]) -> Fields {
        let mut fields = Fields::default();
        for &value in parts.iter().copied().flatten() {
            fields.push(value);
        }
        fields
    }

    /// Appends `value`; past [`MAX_FIELDS`] values are dropped (no message has that many).
    fn push(&mut self, value: i64) {
        if let Some(slot) = self.values.get_mut(self.len) {
            *slot = value;
            self.len += 1;
        }
    }
}

impl<const N: usize> From<[i64; N]> for Fields {
    /// The values of one message part (past [`MAX_FIELDS`] values are dropped, as by
    /// [`Fields::push`]).
    fn from(values: [i64; N]) -> Fields {
        let mut fields = Fields::default();
        for (slot, value) in fields.values.iter_mut().zip(values) {
            *slot = value;
        }
        fields.len = N.min(MAX_FIELDS);
        fields
    }
}

impl std::ops::Deref for Fields {
    type Target = [i64];

    fn deref(&self) -> &[i64] {
        &self.values[..self.len]
    }
}

/// A frame decoded signal by signal into physical values (what `scanhil decode` prints).
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedSignals {
    /// The message's layout (its `name` is the DBC message name).
    pub spec: &'static MessageSpec,
    /// `(DBC signal name, physical value)` in the spec's order.
    pub signals: Vec<(&'static str, f64)>,
}

/// Decodes a frame into its signals' physical values, after the same checks as
/// [`Message::decode`] (so a frame that decodes here is a valid message).
///
/// # Errors
/// As [`Message::decode`].
pub fn decode_signals(frame: &CanFrame) -> Result<DecodedSignals, MessageError> {
    Message::decode(frame)?;
    let (spec, fields) = raw_fields(frame)?;
    let signals = spec
        .signals
        .iter()
        .zip(fields.iter())
        .map(|(s, &raw)| (s.name, s.physical(raw)))
        .collect();
    Ok(DecodedSignals { spec, signals })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_period_counter_wraps_at_2_to_the_16() {
        assert_eq!(check_period_counter("AngleReading", 0, 65_536), Ok(()));
        assert_eq!(check_period_counter("AngleReading", 4, 65_540), Ok(()));
        assert_eq!(
            check_period_counter("CoilCommand", 1, 65_536),
            Err("CoilCommand counter 1 where period 65536 (counter 0) was next".to_owned())
        );
    }
    use crate::ild::IldError;

    fn examples() -> Vec<Message> {
        let distance = Distance {
            value: IldValue::Distance(32_760),
            counter: 12_345,
            sensor_time_us: 1_000_050,
        };
        vec![
            Message::Fault(Fault {
                node: NodeId::Fsm,
                kind: FaultKind::PowerLimit,
                detail: 30_500,
                step: 7,
            }),
            Message::Sync { step: 40_000 },
            Message::Step { step: 40_001 },
            Message::CoilCommand(CoilCommand::from_amps(
                9,
                ActuatorPair { a: 1.5, b: -3.856 },
            )),
            Message::AngleReading(AngleReading::from_rad(
                9,
                SensingPair {
                    alpha: 0.026,
                    beta: -0.001,
                },
            )),
            Message::Distance(distance),
            Message::CommandStepFd {
                command: CoilCommand::default(),
                step: 3,
            },
            Message::AnglesDistanceFd {
                angles: AngleReading::default(),
                distance: Distance {
                    value: IldValue::Error(IldError::NoPeak),
                    ..distance
                },
            },
            Message::Status(Status {
                node: NodeId::Sensor,
                state: NodeState::Running,
                step: 99,
                node_time_us: 5,
            }),
        ]
    }

    #[test]
    fn every_message_round_trips_and_its_id_is_in_the_table() {
        for message in examples() {
            assert!(message_spec(message.id()).is_some(), "{message:?}");
            let frame = message.encode().unwrap();
            assert_eq!(Message::decode(&frame), Ok(message));
        }
    }

    #[test]
    fn every_message_fits_the_inline_fields() {
        for message in spec::MESSAGES {
            assert!(message.signals.len() <= MAX_FIELDS, "{}", message.name);
        }
        for message in examples() {
            assert_eq!(
                message.raw().len(),
                message.spec().signals.len(),
                "{message:?}"
            );
        }
    }

    #[test]
    fn coil_command_layout_is_as_documented() {
        let frame = Message::CoilCommand(CoilCommand {
            seq: 0x0102,
            current_a_ua: 1_500_000,
            current_b_ua: -1,
        })
        .encode()
        .unwrap();
        assert_eq!(frame.id().as_raw(), 0x100);
        assert_eq!(
            frame.data(),
            &[0x02, 0x01, 0x60, 0xE3, 0x16, 0xFF, 0xFF, 0xFF]
        );
        let decoded = decode_signals(&frame).unwrap();
        assert_eq!(decoded.spec.name, "CoilCommand");
        assert_eq!(decoded.signals[1].0, "CurrentA");
        assert!((decoded.signals[1].1 - 1.5).abs() < 1e-12);
    }

    #[test]
    fn out_of_range_and_inconsistent_fields_are_refused() {
        let too_big = Message::CoilCommand(CoilCommand {
            current_a_ua: I24_MAX + 1,
            ..CoilCommand::default()
        });
        assert!(matches!(
            too_big.encode(),
            Err(MessageError::OutOfRange {
                signal: "CurrentA",
                ..
            })
        ));
        let saturated = CoilCommand::from_amps(
            0,
            ActuatorPair {
                a: 100.0,
                b: f64::NAN,
            },
        );
        assert_eq!(
            (saturated.current_a_ua, saturated.current_b_ua),
            (I24_MAX, 0)
        );
        // Status frame of the sensor sent on the fsm's id.
        let id = CanId::standard(ids::STATUS_FSM).unwrap();
        let frame = CanFrame::new(id, &[node::SENSOR, 2, 0, 0, 0, 0, 0, 0]).unwrap();
        assert!(matches!(
            Message::decode(&frame),
            Err(MessageError::Inconsistent { .. })
        ));
        let frame = CanFrame::new(id, &[node::FSM, 9, 0, 0, 0, 0, 0, 0]).unwrap();
        assert!(matches!(
            Message::decode(&frame),
            Err(MessageError::UndefinedCode {
                signal: "State",
                ..
            })
        ));
        let short = CanFrame::new(CanId::standard(ids::COIL_COMMAND).unwrap(), &[0; 7]).unwrap();
        assert!(matches!(
            Message::decode(&short),
            Err(MessageError::WrongShape { .. })
        ));
        let unknown = CanFrame::new(CanId::standard(0x555).unwrap(), &[]).unwrap();
        assert!(matches!(
            decode_signals(&unknown),
            Err(MessageError::UnknownId(_))
        ));
    }
}
