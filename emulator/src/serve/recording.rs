//! A recorded session, parsed for replay (no I/O but [`Recording::read`]): what a scan's
//! output folder (or a bench capture) holds of the two devices, cut into control periods.
//!
//! - `fsm.log`: every frame on the mirror's link in candump `-L` form (any interface name,
//!   loop-time or epoch stamps; `-x` directions, `-8` raw DLCs and `-e` error frames are read
//!   and the error frames skipped). The node's frames are the AngleReadings (or CAN FD's
//!   AnglesDistanceFd), Distance frames, Sync, and the Status and Fault frames of any node but
//!   the controller; the host's are CoilCommand, Step, CommandStepFd and the controller's
//!   Status and Fault. Frames of ids outside the loop's message set are not the node's and are
//!   passed over (another device on a bench bus). Period k is the k-th AngleReading (its
//!   counter `k mod 2^16`) with the node's frames after it up to the next one; node frames
//!   before the first reading go with period 0. The controller's Status in a state other than
//!   running ends the run: the node's frames after it are its answer to that end. The host's
//!   k-th CoilCommand (counter `k mod 2^16`) is its command of period k.
//! - `sensor.ild` (optional): the ILD byte stream as the host received it, read into output
//!   cycles (raw values); it carries no timing, so the replay delivers the cycles at the
//!   sensor's measuring rate ([`super::replay_node`]).
//! - `report.json` (optional): the sensor clock the recording's host used
//!   (`samples.sensor_clock`), which the replay declares, so a host that runs again places
//!   every distance where the recording's host did.
//!
//! A recording that cannot be served is refused whole, before any link opens, naming the
//! file, the line (or byte offset) and why: a line that is no candump line, a frame of the
//! message set that does not decode, a reading or command out of sequence (a gap), a socket
//! that dropped frames, no reading at all, a byte stream that loses sync, or a tail cut
//! mid-value.

use std::io::BufRead;
use std::path::{Path, PathBuf};

use scanhil_protocol::can::CanFrame;
use scanhil_protocol::candump::{LogRecord, parse_record};
use scanhil_protocol::ild::stream::IldDecoder;
use scanhil_protocol::message::{CoilCommand, Message, MessageError, NodeId, NodeState};

/// The mirror link's recording in a session folder.
pub const FSM_LOG: &str = "fsm.log";
/// The ILD stream's recording in a session folder.
pub const SENSOR_ILD: &str = "sensor.ild";
/// The recording host's report in a session folder.
pub const REPORT: &str = "report.json";

/// One control period of a recording: the node's frames, in the order it sent them.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedPeriod {
    /// Every frame the node sent in the period (its AngleReading among them).
    pub frames: Vec<CanFrame>,
    /// Where the AngleReading is in `frames` (a repeated Step is answered with it alone).
    pub reading: usize,
}

/// The sensor clock a recording's host used: the loop time of the sensor's counter 0, and,
/// when its cycles carry no counter, the counter of the first cycle it counted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordedClock {
    /// Loop time of counter 0, s.
    pub counter_zero_s: f64,
    /// The counter of the first cycle counted (0 when the cycles carry their counter).
    pub first_counter: u64,
}

/// A session to serve: the node's frames per period, the host's commands, the sensor's cycles.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recording {
    /// The node's frames of period k (at least one period).
    pub periods: Vec<RecordedPeriod>,
    /// The host's coil command of period k (the recording may hold one past the last reading:
    /// the zero command at the end of the run).
    pub commands: Vec<CoilCommand>,
    /// The node's answer to the controller's end of the run (its Status), if recorded.
    pub end_of_run: Vec<CanFrame>,
    /// The sensor's output cycles, raw values, in the order received.
    pub cycles: Vec<Vec<u32>>,
    /// The sensor clock the recording's host used, when its report was there.
    pub clock: Option<RecordedClock>,
}

/// Why a recording cannot be served.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// A file could not be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A line of the mirror's recording cannot be served.
    #[error("{path}: line {line}: {reason}")]
    Line {
        /// The file.
        path: PathBuf,
        /// The line, counting from 1.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// The ILD stream loses sync or ends mid-value.
    #[error("{path}: byte offset {offset}: {reason}")]
    Stream {
        /// The file.
        path: PathBuf,
        /// The first bad byte.
        offset: u64,
        /// What is wrong.
        reason: String,
    },
    /// The whole file cannot be served (no reading in it, a report without the clock).
    #[error("{path}: {reason}")]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

/// Whose frame a line carries.
enum Sender {
    /// The node's reading of a period.
    Reading(u16),
    /// Another of the node's frames.
    Node,
    /// The host's coil command.
    Command(CoilCommand),
    /// The host ending the run.
    EndOfRun,
    /// Any other frame of the host's, or one outside the message set.
    Other,
}

fn sender(message: &Message) -> Sender {
    match message {
        Message::AngleReading(reading)
        | Message::AnglesDistanceFd {
            angles: reading, ..
        } => Sender::Reading(reading.seq),
        Message::CoilCommand(command) | Message::CommandStepFd { command, .. } => {
            Sender::Command(*command)
        }
        Message::Status(status)
            if status.node == NodeId::Controller && status.state != NodeState::Running =>
        {
            Sender::EndOfRun
        }
        Message::Status(status) if status.node == NodeId::Controller => Sender::Other,
        Message::Fault(fault) if fault.node == NodeId::Controller => Sender::Other,
        Message::Step { .. } => Sender::Other,
        Message::Distance(_) | Message::Sync { .. } | Message::Status(_) | Message::Fault(_) => {
            Sender::Node
        }
    }
}

impl Recording {
    /// Reads a session folder: `fsm.log`, and `sensor.ild` and `report.json` where present.
    ///
    /// # Errors
    /// [`RecordingError`] naming the file and the first bad line or byte.
    pub fn read(dir: &Path) -> Result<Recording, RecordingError> {
        let fsm_path = dir.join(FSM_LOG);
        let file = std::fs::File::open(&fsm_path).map_err(|source| RecordingError::Read {
            path: fsm_path.clone(),
            source,
        })?;
        let mut recording = Recording::parse_fsm(std::io::BufReader::new(file), &fsm_path)?;
        let ild_path = dir.join(SENSOR_ILD);
        match std::fs::read(&ild_path) {
            Ok(bytes) => recording.cycles = parse_ild(&bytes, &ild_path)?,
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => {}
            Err(source) => {
                return Err(RecordingError::Read {
                    path: ild_path,
                    source,
                });
            }
        }
        let report_path = dir.join(REPORT);
        match std::fs::read(&report_path) {
            Ok(bytes) => recording.clock = parse_clock(&bytes, &report_path)?,
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => {}
            Err(source) => {
                return Err(RecordingError::Read {
                    path: report_path,
                    source,
                });
            }
        }
        Ok(recording)
    }

    /// Parses the mirror link's recording line by line; `path` names it in errors. The
    /// recording's `cycles` and `clock` are left empty.
    ///
    /// # Errors
    /// [`RecordingError::Line`] at the first line that cannot be served,
    /// [`RecordingError::File`] when no period was recorded.
    pub fn parse_fsm(text: impl BufRead, path: &Path) -> Result<Recording, RecordingError> {
        let mut recording = Recording::default();
        // Node frames before the first reading, and those of the period being read.
        let mut pending: Vec<CanFrame> = Vec::new();
        let mut reading: Option<usize> = None;
        let mut ended = false;
        for (index, text_line) in text.lines().enumerate() {
            let line = index + 1;
            let bad = |reason: String| RecordingError::Line {
                path: path.to_owned(),
                line,
                reason,
            };
            let text_line = text_line.map_err(|error| bad(error.to_string()))?;
            if text_line.trim().is_empty() {
                continue;
            }
            let frame = match parse_record(&text_line).map_err(|error| bad(error.to_string()))? {
                LogRecord::Frame(entry) => entry.frame,
                LogRecord::Error(_) => continue,
                LogRecord::Dropped(drop) => {
                    return Err(bad(format!(
                        "candump's socket dropped {} frame(s) on {}: the recording has a gap",
                        drop.dropped, drop.interface
                    )));
                }
            };
            let message = match Message::decode(&frame) {
                Ok(message) => message,
                Err(MessageError::UnknownId(_)) => continue,
                Err(error) => return Err(bad(error.to_string())),
            };
            match sender(&message) {
                Sender::Reading(seq) => {
                    if ended {
                        return Err(bad("an AngleReading after the end of the run".into()));
                    }
                    if let Some(at) = reading {
                        recording.periods.push(RecordedPeriod {
                            frames: std::mem::take(&mut pending),
                            reading: at,
                        });
                    }
                    in_sequence("AngleReading", seq, recording.periods.len()).map_err(bad)?;
                    reading = Some(pending.len());
                    pending.push(frame);
                }
                Sender::Node if ended => recording.end_of_run.push(frame),
                Sender::Node => pending.push(frame),
                Sender::Command(command) => {
                    in_sequence("CoilCommand", command.seq, recording.commands.len())
                        .map_err(bad)?;
                    recording.commands.push(command);
                }
                Sender::EndOfRun => ended = true,
                Sender::Other => {}
            }
        }
        let Some(at) = reading else {
            return Err(RecordingError::File {
                path: path.to_owned(),
                reason: "no AngleReading: nothing to serve".into(),
            });
        };
        recording.periods.push(RecordedPeriod {
            frames: pending,
            reading: at,
        });
        Ok(recording)
    }
}

/// Whether a counter `seq` is that of period `next` (counters wrap at 2^16).
fn in_sequence(what: &str, seq: u16, next: usize) -> Result<(), String> {
    let expected = next as u16;
    if seq == expected {
        Ok(())
    } else {
        Err(format!(
            "{what} counter {seq} where period {next} (counter {expected}) was next: a period is \
             missing or out of order"
        ))
    }
}

/// Reads an ILD byte stream into its output cycles (raw values).
///
/// # Errors
/// [`RecordingError::Stream`] at the first byte out of L/M/H order, at a value whose cycle
/// start was not seen, or at a value cut off by the end of the file.
pub fn parse_ild(bytes: &[u8], path: &Path) -> Result<Vec<Vec<u32>>, RecordingError> {
    let bad = |offset: u64, reason: String| RecordingError::Stream {
        path: path.to_owned(),
        offset,
        reason,
    };
    let mut decoder = IldDecoder::new();
    let mut cycles: Vec<Vec<u32>> = Vec::new();
    for event in decoder.push(bytes) {
        let word = event.map_err(|gap| bad(gap.offset, gap.to_string()))?;
        if word.first_in_cycle {
            cycles.push(vec![word.raw]);
            continue;
        }
        match cycles.last_mut() {
            Some(cycle) => cycle.push(word.raw),
            None => {
                return Err(bad(
                    word.offset,
                    "a value of an output cycle whose start is not in the recording".into(),
                ));
            }
        }
    }
    if let Some(gap) = decoder.finish() {
        return Err(bad(gap.offset, "the stream ends mid-value".into()));
    }
    Ok(cycles)
}

/// Reads the sensor clock a recording's host used from its report (`samples.sensor_clock`;
/// `None` when the run had no sensor).
///
/// # Errors
/// [`RecordingError::File`] for a report that is no JSON, or whose clock lacks a field.
pub fn parse_clock(bytes: &[u8], path: &Path) -> Result<Option<RecordedClock>, RecordingError> {
    let bad = |reason: String| RecordingError::File {
        path: path.to_owned(),
        reason,
    };
    let report: serde_json::Value =
        serde_json::from_slice(bytes).map_err(|error| bad(error.to_string()))?;
    let clock = &report["samples"]["sensor_clock"];
    if clock.is_null() {
        return Ok(None);
    }
    let counter_zero_s = clock["counter_zero_s"]
        .as_f64()
        .ok_or_else(|| bad("samples.sensor_clock.counter_zero_s: expected a number".into()))?;
    let first_counter = match &clock["counter_offset"] {
        serde_json::Value::Null => 0,
        offset => offset.as_u64().ok_or_else(|| {
            bad("samples.sensor_clock.counter_offset: expected a whole number".into())
        })?,
    };
    Ok(Some(RecordedClock {
        counter_zero_s,
        first_counter,
    }))
}
