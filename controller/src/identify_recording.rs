//! A recorded identification, analysed again without the device: what `scanhil identify
//! --record DIR` leaves (`DIR/fsm.log`, every frame on the mirror's link in candump `-L` form,
//! and `DIR/identify.json`, the run's result with its plans and rate) is all `scanhil identify
//! --from DIR` needs.
//!
//! Period k of the recording is the k-th CoilCommand (its sequence counter `k mod 2^16`) and
//! the AngleReading with the same counter: the angle at the end of period k. The analysis
//! pairs the command of period k with the angle at its start (the reading of period k - 1,
//! zero before the first), as the live run does, and feeds each plan's
//! [`Analyser`](crate::identify::Analyser) in the order they ran. CAN FD's combined frames
//! (CommandStepFd, AnglesDistanceFd) count as the command and the reading they carry. What
//! the node received is what is analysed: the commands as recorded (1 uA steps), the angles
//! as sent (1 urad steps). Only open-loop runs can be analysed again
//! (a closed loop's excitation, the reference, is not on the wire).

use std::io::BufRead;
use std::path::Path;

use scanhil_protocol::candump::parse_line;
use scanhil_protocol::message::{Message, check_period_counter};
use scanhil_protocol::plant_units::{
    AMPS_PER_INPUT_UNIT, RAD_PER_OUTPUT_UNIT, SensingPair, sensing_from_actuator,
};

use crate::identify::{Plan, ResponsePoint};

/// The recording's file name in the folder.
pub const RECORDING: &str = "fsm.log";
/// The result's file name in the folder.
pub const RESULT: &str = "identify.json";

/// Every period of a recording: the command (input units) and the reading (output units), on
/// the sensing axes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RecordedPeriods {
    /// Period k's coil command.
    pub commands: Vec<SensingPair>,
    /// Period k's angle reading (the angle at the end of period k).
    pub readings: Vec<SensingPair>,
}

/// Why a recording cannot be analysed.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A line is not a candump line, or its frame not of the message set.
    #[error("{path}: line {line}: {reason}")]
    Line {
        /// The file.
        path: String,
        /// The line, counting from 1.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// The recording ends before the plans do.
    #[error("{path}: {have} periods recorded ({what}), the plans run {need}")]
    Short {
        /// The file.
        path: String,
        /// What ran short.
        what: &'static str,
        /// How many there are.
        have: usize,
        /// How many the plans need.
        need: usize,
    },
}

impl RecordedPeriods {
    /// Reads a candump `-L` recording of the mirror's link.
    ///
    /// # Errors
    /// [`RecordingError`] naming the file and the first bad line (a malformed line, a frame
    /// that does not decode, a command or reading out of sequence).
    pub fn read(path: &Path) -> Result<RecordedPeriods, RecordingError> {
        let name = path.display().to_string();
        let file = std::fs::File::open(path).map_err(|source| RecordingError::Read {
            path: name.clone(),
            source,
        })?;
        Self::parse(std::io::BufReader::new(file), &name)
    }

    /// Parses a recording line by line (a long identification's recording is hundreds of MB);
    /// `name` names it in errors.
    ///
    /// # Errors
    /// As [`Self::read`].
    pub fn parse(text: impl BufRead, name: &str) -> Result<RecordedPeriods, RecordingError> {
        let mut periods = RecordedPeriods::default();
        let bad = |line: usize, reason: String| RecordingError::Line {
            path: name.to_owned(),
            line,
            reason,
        };
        for (index, text_line) in text.lines().enumerate() {
            let text_line = text_line.map_err(|source| RecordingError::Read {
                path: name.to_owned(),
                source,
            })?;
            if text_line.trim().is_empty() {
                continue;
            }
            let line = index + 1;
            let entry = parse_line(&text_line).map_err(|e| bad(line, e.to_string()))?;
            let message = Message::decode(&entry.frame).map_err(|e| bad(line, e.to_string()))?;
            let (command, reading) = match message {
                Message::CoilCommand(c) | Message::CommandStepFd { command: c, .. } => {
                    (Some(c), None)
                }
                Message::AngleReading(r) | Message::AnglesDistanceFd { angles: r, .. } => {
                    (None, Some(r))
                }
                _ => (None, None),
            };
            if let Some(command) = command {
                check_period_counter("CoilCommand", command.seq, periods.commands.len())
                    .map_err(|reason| bad(line, reason))?;
                let sensing = sensing_from_actuator(command.amps());
                periods.commands.push(SensingPair {
                    alpha: sensing.alpha / AMPS_PER_INPUT_UNIT,
                    beta: sensing.beta / AMPS_PER_INPUT_UNIT,
                });
            }
            if let Some(reading) = reading {
                check_period_counter("AngleReading", reading.seq, periods.readings.len())
                    .map_err(|reason| bad(line, reason))?;
                let angles = reading.rad();
                periods.readings.push(SensingPair {
                    alpha: angles.alpha / RAD_PER_OUTPUT_UNIT,
                    beta: angles.beta / RAD_PER_OUTPUT_UNIT,
                });
            }
        }
        Ok(periods)
    }

    /// Each plan's points, the plans taken in the order they ran from the first period.
    ///
    /// # Errors
    /// [`RecordingError::Short`] when the recording ends before the plans.
    pub fn analyse(
        &self,
        plans: &[Plan],
        period_s: f64,
        name: &str,
    ) -> Result<Vec<Vec<ResponsePoint>>, RecordingError> {
        let need: usize = plans.iter().map(|p| p.periods(period_s)).sum();
        let short = |what, have| RecordingError::Short {
            path: name.to_owned(),
            what,
            have,
            need,
        };
        if self.commands.len() < need {
            return Err(short("coil commands", self.commands.len()));
        }
        if self.readings.len() + 1 < need {
            return Err(short("angle readings", self.readings.len()));
        }
        let mut k: usize = 0;
        let mut out = Vec::with_capacity(plans.len());
        for plan in plans {
            let axis = plan.axis();
            let mut analyser = plan.analyser(period_s);
            while analyser.excitation().is_some() {
                let angle = k
                    .checked_sub(1)
                    .map_or(SensingPair::default(), |previous| self.readings[previous]);
                analyser.push(
                    axis.of(self.commands[k]),
                    axis.of(angle),
                    axis.other().of(angle),
                );
                k += 1;
            }
            out.push(analyser.finish());
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use scanhil_protocol::candump::{Timestamp, push_line};
    use scanhil_protocol::message::{AngleReading, CoilCommand};
    use scanhil_protocol::plant_units::ActuatorPair;

    use super::*;
    use crate::identify::{SteppedSine, Target, identify_plans};
    use crate::link::{LinkError, NominalPlantLink, PlantLink};
    use crate::plant_model::PlantModel;
    use crate::trajectory::SensingAxis;

    const T: f64 = 1e-4;

    /// The nominal plant, every exchange written as a node's link would carry it (a Step
    /// between command and reading, as in lockstep).
    struct Recorded {
        plant: NominalPlantLink,
        log: Vec<u8>,
        k: u32,
    }

    impl Recorded {
        fn line(&mut self, message: &Message) {
            let stamp = Timestamp::from_secs_f64(f64::from(self.k) * T);
            push_line(&mut self.log, stamp, "fsm", &message.encode().unwrap());
            self.log.push(b'\n');
        }
    }

    impl PlantLink for Recorded {
        fn exchange(&mut self, coil_currents_a: ActuatorPair) -> Result<SensingPair, LinkError> {
            let seq = self.k as u16;
            let command = CoilCommand::from_amps(seq, coil_currents_a);
            self.line(&Message::CoilCommand(command));
            self.line(&Message::Step { step: self.k });
            // The node acts on the command as sent (1 uA steps), and reads in 1 urad steps.
            let angles = self.plant.exchange(command.amps())?;
            let reading = AngleReading::from_rad(seq, angles);
            self.line(&Message::AngleReading(reading));
            self.k += 1;
            Ok(reading.rad())
        }

        fn period_s(&self) -> f64 {
            T
        }
    }

    fn plans() -> Vec<Plan> {
        let plan = Plan::Stepped(SteppedSine {
            axis: SensingAxis::Alpha,
            frequencies_hz: vec![3.0, 22.0, 150.0],
            amplitude: 0.05,
            settle_s: 0.3,
            cycles_per_block: 1,
            blocks: 2,
        });
        vec![plan.clone(), plan.on_axis(SensingAxis::Beta)]
    }

    fn recorded_run() -> (Vec<Vec<ResponsePoint>>, String) {
        let mut link = Recorded {
            plant: NominalPlantLink::new(&PlantModel::default(), T, 0.0, 0),
            log: Vec::new(),
            k: 0,
        };
        let live = identify_plans(&mut link, &plans(), &mut Target::OpenLoop).unwrap();
        // The end of a session: the coils at zero, one more command.
        link.line(&Message::CoilCommand(CoilCommand::from_amps(
            link.k as u16,
            ActuatorPair::default(),
        )));
        (live, String::from_utf8(link.log).unwrap())
    }

    #[test]
    fn a_recording_analysed_again_gives_the_live_points() {
        let (live, log) = recorded_run();
        let periods = RecordedPeriods::parse(log.as_bytes(), "fsm.log").unwrap();
        let need: usize = plans().iter().map(|p| p.periods(T)).sum();
        assert_eq!(periods.commands.len(), need + 1);
        assert_eq!(periods.readings.len(), need);
        let again = periods.analyse(&plans(), T, "fsm.log").unwrap();
        assert_eq!(again.len(), 2);
        for (live, again) in live.iter().zip(&again) {
            assert_eq!(live.len(), 3);
            for (a, b) in live.iter().zip(again) {
                assert_eq!(a.f_hz, b.f_hz);
                // The live analysis takes the exact sine, the recording the 1 uA steps sent.
                assert!(
                    (a.magnitude / b.magnitude - 1.0).abs() < 1e-4,
                    "{a:?} {b:?}"
                );
                assert!((a.phase_deg - b.phase_deg).abs() < 0.01, "{a:?} {b:?}");
                // The other axis reads the same angles (-inf dB while it is at rest).
                assert!(
                    a.cross_axis_db == b.cross_axis_db
                        || (a.cross_axis_db - b.cross_axis_db).abs() < 1e-4,
                    "{a:?} {b:?}"
                );
            }
        }
    }

    #[test]
    fn fd_frames_count_as_the_command_and_the_reading_they_carry() {
        let (_, log) = recorded_run();
        let classic = RecordedPeriods::parse(log.as_bytes(), "fsm.log").unwrap();
        let mut fd = Vec::new();
        for (k, (command, reading)) in classic.commands.iter().zip(&classic.readings).enumerate() {
            let seq = k as u16;
            let amps = scanhil_protocol::plant_units::actuator_from_sensing(SensingPair {
                alpha: command.alpha * AMPS_PER_INPUT_UNIT,
                beta: command.beta * AMPS_PER_INPUT_UNIT,
            });
            let rad = SensingPair {
                alpha: reading.alpha * RAD_PER_OUTPUT_UNIT,
                beta: reading.beta * RAD_PER_OUTPUT_UNIT,
            };
            for message in [
                Message::CommandStepFd {
                    command: CoilCommand::from_amps(seq, amps),
                    step: k as u32,
                },
                Message::AnglesDistanceFd {
                    angles: AngleReading::from_rad(seq, rad),
                    distance: scanhil_protocol::message::Distance {
                        value: scanhil_protocol::ild::IldValue::Distance(1000),
                        counter: k as u32,
                        sensor_time_us: 0,
                    },
                },
            ] {
                push_line(
                    &mut fd,
                    Timestamp::default(),
                    "can0",
                    &message.encode().unwrap(),
                );
                fd.push(b'\n');
            }
        }
        let periods = RecordedPeriods::parse(fd.as_slice(), "fd.log").unwrap();
        assert_eq!(periods.readings, classic.readings);
        assert_eq!(periods.commands.len(), classic.readings.len());
        for (a, b) in periods.commands.iter().zip(&classic.commands) {
            assert!((a.alpha - b.alpha).abs() < 2e-6 && (a.beta - b.beta).abs() < 2e-6);
        }
    }

    #[test]
    fn a_bad_line_a_missing_period_and_a_short_recording_are_named() {
        let (_, log) = recorded_run();
        let mut lines: Vec<&str> = log.lines().collect();
        lines[4] = "(0.000100) fsm 100#01";
        let error = RecordedPeriods::parse(lines.join("\n").as_bytes(), "fsm.log").unwrap_err();
        assert!(
            error.to_string().starts_with("fsm.log: line 5: "),
            "{error}"
        );

        let mut lines: Vec<&str> = log.lines().collect();
        lines.remove(3); // period 1's command
        let error = RecordedPeriods::parse(lines.join("\n").as_bytes(), "fsm.log").unwrap_err();
        assert_eq!(
            error.to_string(),
            "fsm.log: line 6: CoilCommand counter 2 where period 1 (counter 1) was next"
        );

        let lines: Vec<&str> = log.lines().collect();
        let half = lines[..lines.len() / 2].join("\n");
        let periods = RecordedPeriods::parse(half.as_bytes(), "fsm.log").unwrap();
        let error = periods.analyse(&plans(), T, "fsm.log").unwrap_err();
        assert!(
            error
                .to_string()
                .contains("periods recorded (coil commands), the plans run"),
            "{error}"
        );
    }
}
