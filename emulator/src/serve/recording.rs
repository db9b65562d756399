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
use scanhil_protocol::message::{
    CoilCommand, Message, MessageError, NodeId, NodeState, check_period_counter,
};

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
    /// The AngleReading's stamp as recorded, s (loop time or epoch, as the log has it): a
    /// real-time replay keeps the recorded timing from it.
    pub reading_s: f64,
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
        if let Some(bytes) = read_optional(&ild_path)? {
            recording.cycles = parse_ild(&bytes, &ild_path)?;
        }
        let report_path = dir.join(REPORT);
        if let Some(bytes) = read_optional(&report_path)? {
            recording.clock = parse_clock(&bytes, &report_path)?;
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
        // Where the period's reading is in `pending`, and its stamp.
        let mut reading: Option<(usize, f64)> = None;
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
            let (frame, stamp_s) =
                match parse_record(&text_line).map_err(|error| bad(error.to_string()))? {
                    LogRecord::Frame(entry) => (entry.frame, entry.timestamp.as_secs_f64()),
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
                    if let Some((at, reading_s)) = reading {
                        recording.periods.push(RecordedPeriod {
                            frames: std::mem::take(&mut pending),
                            reading: at,
                            reading_s,
                        });
                    }
                    check_period_counter("AngleReading", seq, recording.periods.len())
                        .map_err(bad)?;
                    reading = Some((pending.len(), stamp_s));
                    pending.push(frame);
                }
                Sender::Node if ended => recording.end_of_run.push(frame),
                Sender::Node => pending.push(frame),
                Sender::Command(command) => {
                    check_period_counter("CoilCommand", command.seq, recording.commands.len())
                        .map_err(bad)?;
                    recording.commands.push(command);
                }
                Sender::EndOfRun => ended = true,
                Sender::Other => {}
            }
        }
        let Some((at, reading_s)) = reading else {
            return Err(RecordingError::File {
                path: path.to_owned(),
                reason: "no AngleReading: nothing to serve".into(),
            });
        };
        recording.periods.push(RecordedPeriod {
            frames: pending,
            reading: at,
            reading_s,
        });
        Ok(recording)
    }
}

/// A session's optional file: its bytes, or `None` when it is not there.
fn read_optional(path: &Path) -> Result<Option<Vec<u8>>, RecordingError> {
    match std::fs::read(path) {
        Ok(bytes) => Ok(Some(bytes)),
        Err(error) if error.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(source) => Err(RecordingError::Read {
            path: path.to_owned(),
            source,
        }),
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

#[cfg(test)]
mod tests {
    use scanhil_protocol::candump::{Timestamp, push_line};
    use scanhil_protocol::ild::stream::encode_cycle;
    use scanhil_protocol::message::{AngleReading, Status};

    use super::*;

    fn command(seq: u16, a_ua: i32) -> Message {
        Message::CoilCommand(CoilCommand {
            seq,
            current_a_ua: a_ua,
            current_b_ua: -a_ua,
        })
    }

    fn reading(seq: u16) -> Message {
        Message::AngleReading(AngleReading {
            seq,
            alpha_urad: i32::from(seq) * 10,
            beta_urad: -1,
        })
    }

    fn status(node: NodeId, state: NodeState, step: u32) -> Message {
        Message::Status(Status {
            node,
            state,
            step,
            node_time_us: step * 50,
        })
    }

    fn line(message: &Message) -> String {
        line_at(1.5, message)
    }

    fn line_at(t_s: f64, message: &Message) -> String {
        let mut out = Vec::new();
        push_line(
            &mut out,
            Timestamp::from_secs_f64(t_s),
            "can0",
            &message.encode().unwrap(),
        );
        String::from_utf8(out).unwrap()
    }

    /// A lockstep session of `periods` periods: command, Step, reading, a heartbeat after
    /// the reading of period 1, then the zero command, the controller's end and the node's
    /// answer.
    fn session(periods: u16) -> Vec<String> {
        let mut lines = Vec::new();
        for k in 0..periods {
            lines.push(line(&command(k, 100 * i32::from(k))));
            lines.push(line(&Message::Step { step: k.into() }));
            lines.push(line(&reading(k)));
            if k == 1 {
                lines.push(line(&status(NodeId::Fsm, NodeState::Running, 1)));
            }
        }
        lines.push(line(&command(periods, 0)));
        lines.push(line(&status(
            NodeId::Controller,
            NodeState::Ready,
            periods.into(),
        )));
        lines.push(line(&status(NodeId::Fsm, NodeState::Ready, periods.into())));
        lines
    }

    fn parse(lines: &[String]) -> Result<Recording, RecordingError> {
        Recording::parse_fsm(lines.join("\n").as_bytes(), Path::new("dir/fsm.log"))
    }

    fn refusal(lines: &[String]) -> String {
        parse(lines).unwrap_err().to_string()
    }

    #[test]
    fn each_period_holds_the_nodes_frames_from_its_reading_to_the_next() {
        let recording = parse(&session(3)).unwrap();
        let frames = |messages: &[Message]| -> Vec<CanFrame> {
            messages.iter().map(|m| m.encode().unwrap()).collect()
        };
        assert_eq!(recording.periods.len(), 3);
        assert_eq!(recording.periods[0].frames, frames(&[reading(0)]));
        assert_eq!(
            recording.periods[1].frames,
            frames(&[reading(1), status(NodeId::Fsm, NodeState::Running, 1)])
        );
        assert_eq!(recording.periods[2].frames, frames(&[reading(2)]));
        assert!(recording.periods.iter().all(|period| period.reading == 0));
        // The host's commands, the zero command at the end included; no Step is the node's.
        let amps: Vec<i32> = recording.commands.iter().map(|c| c.current_a_ua).collect();
        assert_eq!(amps, [0, 100, 200, 0]);
        assert_eq!(
            recording.end_of_run,
            frames(&[status(NodeId::Fsm, NodeState::Ready, 3)])
        );
        assert!(recording.cycles.is_empty() && recording.clock.is_none());
    }

    #[test]
    fn each_period_keeps_its_readings_stamp() {
        let lines = [
            line_at(1000.25, &Message::Sync { step: 0 }),
            line_at(1000.5, &reading(0)),
            line_at(1000.75, &status(NodeId::Fsm, NodeState::Running, 0)),
            line_at(1001.0, &reading(1)),
        ];
        let recording = parse(&lines).unwrap();
        let stamps: Vec<f64> = recording.periods.iter().map(|p| p.reading_s).collect();
        assert_eq!(stamps, [1000.5, 1001.0]);
    }

    #[test]
    fn node_frames_before_the_first_reading_go_with_period_0_before_it() {
        let mut lines = session(2);
        lines.insert(0, line(&Message::Sync { step: 0 }));
        let recording = parse(&lines).unwrap();
        assert_eq!(recording.periods[0].frames.len(), 2);
        assert_eq!(recording.periods[0].reading, 1);
        assert_eq!(recording.periods[0].frames[1], reading(0).encode().unwrap());
    }

    #[test]
    fn a_fault_is_the_nodes_frame_unless_the_controller_sent_it() {
        let fault = |node| {
            Message::Fault(scanhil_protocol::message::Fault {
                node,
                kind: scanhil_protocol::message::FaultKind::OverCurrent,
                detail: 1,
                step: 0,
            })
        };
        let mut lines = session(2);
        lines.insert(3, line(&fault(NodeId::Controller)));
        lines.insert(3, line(&fault(NodeId::Fsm)));
        let recording = parse(&lines).unwrap();
        assert_eq!(
            recording.periods[0].frames,
            [reading(0), fault(NodeId::Fsm)].map(|m| m.encode().unwrap())
        );
    }

    #[test]
    fn a_bench_captures_extra_lines_are_passed_over() {
        let mut lines = session(2);
        // `-x` directions, an error frame, a frame of another device, a controller's running
        // status and fault, blank lines.
        lines[2] += " R";
        lines.insert(3, "(1.500000) can0 20000040#0000000000000000 R".into());
        lines.insert(3, "(1.500000) can0 7FF#00".into());
        lines.insert(3, line(&status(NodeId::Controller, NodeState::Running, 0)));
        lines.insert(3, String::new());
        let recording = parse(&lines).unwrap();
        assert_eq!(recording.periods.len(), 2);
        assert_eq!(recording.periods[0].frames.len(), 1);
    }

    #[test]
    fn a_missing_reading_or_command_is_refused_at_the_next_one() {
        // Period 1's reading is line 6 (period 2's is then line 9: period 1's heartbeat stays);
        // its command line 4 (period 2's is then line 7).
        for (removed, line, what) in [(5, 9, "AngleReading"), (3, 7, "CoilCommand")] {
            let mut lines = session(3);
            lines.remove(removed);
            assert_eq!(
                refusal(&lines),
                format!(
                    "dir/fsm.log: line {line}: {what} counter 2 where period 1 (counter 1) was \
                     next"
                )
            );
        }
    }

    #[test]
    fn what_cannot_be_served_is_refused_naming_the_line() {
        let mut dropped = session(2);
        dropped.insert(
            2,
            "DROPCOUNT: dropped 3 CAN frames on 'can0' socket (total drops 3)".into(),
        );
        assert_eq!(
            refusal(&dropped),
            "dir/fsm.log: line 3: candump's socket dropped 3 frame(s) on can0: the recording \
             has a gap"
        );
        let mut garbage = session(2);
        garbage[1] = "not a candump line".into();
        assert!(
            refusal(&garbage).starts_with("dir/fsm.log: line 2: "),
            "{}",
            refusal(&garbage)
        );
        let mut malformed = session(2);
        malformed[2] = "(1.500000) can0 110#00".into();
        assert!(
            refusal(&malformed).starts_with("dir/fsm.log: line 3: AngleReading"),
            "{}",
            refusal(&malformed)
        );
        let mut late = session(2);
        late.push(line(&reading(2)));
        assert_eq!(
            refusal(&late),
            format!(
                "dir/fsm.log: line {}: an AngleReading after the end of the run",
                late.len()
            )
        );
        assert_eq!(
            refusal(&session(0)),
            "dir/fsm.log: no AngleReading: nothing to serve"
        );
        let bad_utf8 = Recording::parse_fsm(&b"\xff\xfe\n"[..], Path::new("dir/fsm.log"));
        assert!(
            bad_utf8
                .unwrap_err()
                .to_string()
                .starts_with("dir/fsm.log: line 1: "),
        );
    }

    #[test]
    fn can_fd_frames_count_as_the_command_and_the_reading_they_carry() {
        let distance = scanhil_protocol::message::Distance {
            value: scanhil_protocol::ild::IldValue::from_raw(1000),
            counter: 7,
            sensor_time_us: 0,
        };
        let lines = [
            line(&Message::CommandStepFd {
                command: CoilCommand {
                    seq: 0,
                    current_a_ua: 5,
                    current_b_ua: 6,
                },
                step: 0,
            }),
            line(&Message::AnglesDistanceFd {
                angles: AngleReading {
                    seq: 0,
                    alpha_urad: 1,
                    beta_urad: 2,
                },
                distance,
            }),
            line(&Message::Distance(distance)),
        ];
        let recording = parse(&lines).unwrap();
        assert_eq!(recording.commands.len(), 1);
        assert_eq!(recording.commands[0].current_b_ua, 6);
        assert_eq!(recording.periods.len(), 1);
        assert_eq!(recording.periods[0].frames.len(), 2);
    }

    #[test]
    fn the_ild_stream_is_read_into_its_cycles() {
        let mut bytes = encode_cycle(&[10, 20]);
        bytes.extend(encode_cycle(&[30]));
        bytes.extend(encode_cycle(&[40, 50, 60]));
        let cycles = parse_ild(&bytes, Path::new("sensor.ild")).unwrap();
        assert_eq!(cycles, [vec![10, 20], vec![30], vec![40, 50, 60]]);
        assert!(parse_ild(&[], Path::new("sensor.ild")).unwrap().is_empty());
    }

    #[test]
    fn an_ild_stream_that_cannot_be_served_is_refused_naming_the_byte() {
        let path = Path::new("sensor.ild");
        let two = encode_cycle(&[10, 20]);
        // Starting with the cycle's second value: its start is not in the recording.
        assert_eq!(
            parse_ild(&two[3..], path).unwrap_err().to_string(),
            "sensor.ild: byte offset 0: a value of an output cycle whose start is not in the \
             recording"
        );
        // Cut mid-value.
        assert_eq!(
            parse_ild(&two[..4], path).unwrap_err().to_string(),
            "sensor.ild: byte offset 3: the stream ends mid-value"
        );
        // A byte lost: the decoder skips to the next L byte.
        let mut lost = two.clone();
        lost.remove(1);
        lost.extend(encode_cycle(&[30]));
        let error = parse_ild(&lost, path).unwrap_err().to_string();
        assert!(error.starts_with("sensor.ild: byte offset 0: "), "{error}");
    }

    #[test]
    fn the_report_gives_the_clock_its_host_used() {
        let path = Path::new("report.json");
        let clock = |json: &str| parse_clock(json.as_bytes(), path);
        assert_eq!(
            clock(r#"{"samples":{"sensor_clock":{"counter_zero_s":-0.5,"counter_offset":12}}}"#)
                .unwrap(),
            Some(RecordedClock {
                counter_zero_s: -0.5,
                first_counter: 12
            })
        );
        assert_eq!(
            clock(r#"{"samples":{"sensor_clock":{"counter_zero_s":0.25}}}"#).unwrap(),
            Some(RecordedClock {
                counter_zero_s: 0.25,
                first_counter: 0
            })
        );
        assert_eq!(clock(r#"{"samples":{"sensor_clock":null}}"#).unwrap(), None);
        assert_eq!(clock("{}").unwrap(), None);
        for (bad, why) in [
            ("[", "report.json: EOF while parsing"),
            (
                r#"{"samples":{"sensor_clock":{}}}"#,
                "report.json: samples.sensor_clock.counter_zero_s: expected a number",
            ),
            (
                r#"{"samples":{"sensor_clock":{"counter_zero_s":0,"counter_offset":-1}}}"#,
                "report.json: samples.sensor_clock.counter_offset: expected a whole number",
            ),
        ] {
            let error = clock(bad).unwrap_err().to_string();
            assert!(error.starts_with(why), "{error}");
        }
    }

    #[test]
    fn a_session_folder_is_read_whole_and_its_optional_files_may_be_absent() {
        let dir = tempfile::tempdir().unwrap();
        let error = Recording::read(dir.path()).unwrap_err().to_string();
        assert!(error.contains("fsm.log: No such file"), "{error}");
        std::fs::write(dir.path().join(FSM_LOG), session(2).join("\n")).unwrap();
        let bare = Recording::read(dir.path()).unwrap();
        assert_eq!(bare.periods.len(), 2);
        assert!(bare.cycles.is_empty() && bare.clock.is_none());
        std::fs::write(dir.path().join(SENSOR_ILD), encode_cycle(&[7])).unwrap();
        std::fs::write(
            dir.path().join(REPORT),
            r#"{"samples":{"sensor_clock":{"counter_zero_s":1.0}}}"#,
        )
        .unwrap();
        let whole = Recording::read(dir.path()).unwrap();
        assert_eq!(whole.cycles, [vec![7]]);
        assert_eq!(whole.clock.map(|c| c.counter_zero_s), Some(1.0));
        // A file that is there but cannot be read is an error, not an absent file.
        std::fs::remove_file(dir.path().join(SENSOR_ILD)).unwrap();
        std::fs::create_dir(dir.path().join(SENSOR_ILD)).unwrap();
        let error = Recording::read(dir.path()).unwrap_err().to_string();
        assert!(error.contains("sensor.ild"), "{error}");
        std::fs::remove_dir(dir.path().join(SENSOR_ILD)).unwrap();
        std::fs::remove_file(dir.path().join(REPORT)).unwrap();
        std::fs::create_dir(dir.path().join(REPORT)).unwrap();
        let error = Recording::read(dir.path()).unwrap_err().to_string();
        assert!(error.contains("report.json"), "{error}");
    }
}
