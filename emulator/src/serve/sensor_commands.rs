//! The emulated ILD 2300's settings and its answers to the ASCII command subset the host uses
//! (`GETINFO`, `MEASRATE`, `ECHO`, `OUTPUT`, `OUTDIST_RS422`, `OUTADD_RS422`, `BAUDRATE`,
//! `LASERPOW`), as the protocol's codec encodes them: a query is answered with the current
//! setting (`MEASRATE 20`), a set with an empty reply, a refusal with its `Exx` line; every
//! reply ends at the `->` prompt. No I/O here: [`super::sensor_port`] reads the lines and sends
//! the replies, and asks [`IldSettings::cycle`] what a sample's output cycle is.
//!
//! Decisions (the emulator's, not the manual's):
//! - The measuring rate is the scene's: the plant samples the sensor at that rate from the
//!   start, and changing it at run time would reshape the sensor's clock under the loop. So
//!   `MEASRATE` with that rate is accepted, and any other listed rate is refused with the
//!   wrong-parameter error (`ERROR_WRONG_PARAMETER`, E04); the read-back always gives the scene's.
//! - `OUTADD_RS422` takes `NONE` or `COUNTER` only (the emulator models no exposure time,
//!   timestamp, temperature, intensity or state); others are refused as wrong parameters.
//! - `BAUDRATE` is stored and read back; a pty has no baud rate, so it changes nothing.
//! - The state at start: echo off, `OUTPUT RS422`, `OUTDIST_RS422 DIST1`,
//!   `OUTADD_RS422 COUNTER`, 691200 baud, laser on: a sensor already set up as the loop needs
//!   it, so a host that sends no commands (a bench tool, the conformance run) gets the stream.

use scanhil_protocol::ild::IldError;
use scanhil_protocol::ild::command::{
    AddValue, IldCommand, IldCommandError, IldInfo, IldReply, OUTPUT_WORDS_UNCHECKED,
};
use scanhil_protocol::ild::stream::FACTORY_BAUD;
use scanhil_protocol::link::IldRequest;

use crate::sensor::IldSample;

/// What `GETINFO` names the emulated sensor.
pub const EMULATED_NAME: &str = "ILD2300";
/// The emulated sensor's serial number in `GETINFO`.
pub const EMULATED_SERIAL: &str = "EMULATED";
/// The emulated sensor's article in `GETINFO`.
pub const EMULATED_ARTICLE: &str = "scanhil-emulator";

/// The `OUTPUT` word that puts measured values on RS422.
const OUTPUT_RS422: &str = "RS422";

/// The emulated sensor's settings, changed by the host's commands.
#[derive(Debug, Clone, PartialEq)]
pub struct IldSettings {
    /// The scene's measuring rate, kHz (fixed, see the module's decisions).
    measuring_rate_khz: f64,
    /// The measuring range's span, mm (`GETINFO`'s `Measuring range`).
    range_span_mm: f64,
    echo: bool,
    /// The `OUTPUT` word in force.
    output: String,
    distance_on: bool,
    counter_on: bool,
    baud: u32,
    laser_on: bool,
}

/// What the settings say about one sample: the raw values of its output cycle, or nothing.
pub type Cycle = Option<Vec<u32>>;

impl IldSettings {
    /// The start state for a sensor sampling at `measuring_rate_hz` with a range of
    /// `range_span_mm`.
    #[must_use]
    pub fn new(measuring_rate_hz: f64, range_span_mm: f64) -> IldSettings {
        IldSettings {
            measuring_rate_khz: measuring_rate_hz / 1e3,
            range_span_mm,
            echo: false,
            output: OUTPUT_RS422.to_owned(),
            distance_on: true,
            counter_on: true,
            baud: FACTORY_BAUD,
            laser_on: true,
        }
    }

    /// Whether the laser is on.
    #[must_use]
    pub fn laser_on(&self) -> bool {
        self.laser_on
    }

    /// The output cycle of `sample`: nothing while RS422 output is off (or carries no value);
    /// otherwise the distance (the laser-off error code while the laser is off) and, when
    /// enabled, the counter.
    #[must_use]
    pub fn cycle(&self, sample: &IldSample) -> Cycle {
        if self.output != OUTPUT_RS422 {
            return None;
        }
        let mut values = Vec::with_capacity(2);
        if self.distance_on {
            values.push(if self.laser_on {
                sample.value.raw()
            } else {
                IldError::LaserOff.code()
            });
        }
        if self.counter_on {
            values.push(sample.counter);
        }
        (!values.is_empty()).then_some(values)
    }

    /// Carries out one command line and returns the reply to send.
    pub fn answer(&mut self, request: &IldRequest) -> IldReply {
        // The reply's echo follows the setting in force when the line came (also for ECHO).
        let echo = self.echo.then(|| request.line.clone());
        let command = match &request.command {
            Ok(command) => command,
            Err(error) => return IldReply::refusal(echo, error),
        };
        if *command == IldCommand::GetInfo {
            return IldReply {
                echo,
                lines: self.info().reply_lines(),
                ..IldReply::default()
            };
        }
        if command.is_query() {
            return IldReply::query_answer(echo, &self.setting(command));
        }
        match self.apply(command) {
            Ok(()) => IldReply {
                echo,
                ..IldReply::default()
            },
            Err(error) => IldReply::refusal(echo, &error),
        }
    }

    /// What `GETINFO` reports.
    #[must_use]
    pub fn info(&self) -> IldInfo {
        IldInfo {
            name: EMULATED_NAME.to_owned(),
            serial: EMULATED_SERIAL.to_owned(),
            article: EMULATED_ARTICLE.to_owned(),
            measuring_range_mm: self.range_span_mm,
            version: env!("CARGO_PKG_VERSION").to_owned(),
        }
    }

    /// The current setting of the queried command, as the set command that would make it.
    fn setting(&self, query: &IldCommand) -> IldCommand {
        match query {
            IldCommand::MeasRate(_) => IldCommand::MeasRate(Some(self.measuring_rate_khz)),
            IldCommand::Echo(_) => IldCommand::Echo(Some(self.echo)),
            IldCommand::OutDistRs422(_) => IldCommand::OutDistRs422(Some(self.distance_on)),
            IldCommand::OutAddRs422(_) => IldCommand::OutAddRs422(Some(
                self.counter_on
                    .then_some(AddValue::Counter)
                    .into_iter()
                    .collect(),
            )),
            IldCommand::Baudrate(_) => IldCommand::Baudrate(Some(self.baud)),
            IldCommand::Output(_) => IldCommand::Output(Some(self.output.clone())),
            IldCommand::LaserPower(_) => IldCommand::LaserPower(Some(self.laser_on)),
            IldCommand::GetInfo => IldCommand::GetInfo,
        }
    }

    /// Applies a set command, or says why it is refused.
    fn apply(&mut self, command: &IldCommand) -> Result<(), IldCommandError> {
        let wrong = |command: &IldCommand| IldCommandError::WrongParameter {
            command: command.name(),
            parameter: command.parameters(),
        };
        match command {
            IldCommand::MeasRate(Some(khz)) if (khz - self.measuring_rate_khz).abs() > 1e-6 => {
                return Err(wrong(command));
            }
            IldCommand::Echo(Some(on)) => self.echo = *on,
            IldCommand::OutDistRs422(Some(on)) => self.distance_on = *on,
            IldCommand::OutAddRs422(Some(values)) => match values.as_slice() {
                [] => self.counter_on = false,
                [AddValue::Counter] => self.counter_on = true,
                _ => return Err(wrong(command)),
            },
            IldCommand::Baudrate(Some(baud)) => self.baud = *baud,
            IldCommand::Output(Some(word)) if OUTPUT_WORDS_UNCHECKED.contains(&word.as_str()) => {
                word.clone_into(&mut self.output);
            }
            IldCommand::Output(Some(_)) => return Err(wrong(command)),
            IldCommand::LaserPower(Some(on)) => self.laser_on = *on,
            // Queries and GETINFO are answered before this.
            _ => {}
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanhil_protocol::ild::IldValue;
    use scanhil_protocol::ild::command::ERROR_WRONG_PARAMETER;

    fn request(line: &str) -> IldRequest {
        IldRequest {
            line: line.to_owned(),
            command: IldCommand::parse(line),
        }
    }

    fn sample() -> IldSample {
        IldSample {
            t_s: 0.0,
            counter: 7,
            value: IldValue::Distance(32_760),
            true_distance_mm: Some(120.0),
        }
    }

    #[test]
    fn the_subset_is_answered_and_changes_the_stream() {
        let mut sensor = IldSettings::new(20_000.0, 100.0);
        assert_eq!(sensor.cycle(&sample()), Some(vec![32_760, 7]));
        let info = sensor.answer(&request("GETINFO"));
        assert!(info.encode().contains("Measuring range: 100.00mm\r\n"));
        assert_eq!(
            sensor.answer(&request("MEASRATE")).encode(),
            "MEASRATE 20\r\n->"
        );
        assert!(sensor.answer(&request("MEASRATE 20")).is_ok());
        let refused = sensor.answer(&request("MEASRATE 10"));
        assert_eq!(refused.encode(), "E04 Wrong parameter\r\n->");
        assert_eq!(refused.error.map(|e| e.code), Some(ERROR_WRONG_PARAMETER.0));
        assert!(sensor.answer(&request("LASERPOW OFF")).is_ok());
        assert_eq!(
            sensor.cycle(&sample()),
            Some(vec![IldError::LaserOff.code(), 7])
        );
        assert!(sensor.answer(&request("OUTADD_RS422 NONE")).is_ok());
        assert!(sensor.answer(&request("LASERPOW FULL")).is_ok());
        assert_eq!(sensor.cycle(&sample()), Some(vec![32_760]));
        assert!(!sensor.answer(&request("OUTADD_RS422 TEMP")).is_ok());
        assert!(sensor.answer(&request("OUTPUT NONE")).is_ok());
        assert_eq!(sensor.cycle(&sample()), None);
        assert!(sensor.answer(&request("BAUDRATE 921600")).is_ok());
        assert_eq!(
            sensor.answer(&request("BAUDRATE")).encode(),
            "BAUDRATE 921600\r\n->"
        );
        assert!(sensor.answer(&request("ECHO ON")).is_ok());
        assert_eq!(
            sensor.answer(&request("OUTPUT")).encode(),
            "OUTPUT\r\nOUTPUT NONE\r\n->"
        );
        assert_eq!(
            sensor.answer(&request("FROB")).encode(),
            "FROB\r\nE01 Unknown command\r\n->"
        );
    }
}
