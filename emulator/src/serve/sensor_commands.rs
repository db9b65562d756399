//! The emulated ILD 2300's settings and its answers to the ASCII command subset the host uses
//! (`GETINFO`, `GETOUTINFO_RS422`, `MEASRATE`, `ECHO`, `OUTPUT`, `OUTDIST_RS422`,
//! `OUTADD_RS422`, `BAUDRATE`, `LASERPOW`), as the protocol's codec encodes them and the
//! operating instructions describe them (appendix A 6): a query is answered with the current
//! setting in the form of the command that sets it (`MEASRATE 20`), a set with an empty reply,
//! a refusal with its `Exx` line; with `ECHO ON` the command is repeated first, `<command> ok`
//! after a setting done; every reply ends at the `->` prompt. No I/O here:
//! [`super::sensor_port`] reads the lines and sends the replies, and asks
//! [`IldSettings::cycle`] what a sample's output cycle is.
//!
//! An output cycle is the distance (`DIST1`, when `OUTDIST_RS422` has it) and then the extra
//! values `OUTADD_RS422` selects, in the manual's order (TEMP, SHUTTER, COUNTER, TIMESTAMP,
//! INTENSITY, STATE); `GETOUTINFO_RS422` lists exactly that sequence. (The 2300's own order on
//! the line is what its `GETOUTINFO_RS422` says; the host reads it from there, so it follows a
//! real sensor's order as well as this one.)
//!
//! Decisions (the emulator's, not the manual's):
//! - The measuring rate is the scene's: the plant samples the sensor at that rate from the
//!   start, and changing it at run time would reshape the sensor's clock under the loop. So
//!   `MEASRATE` with that rate is accepted, and any other of the manual's rates is refused with
//!   the wrong-parameter error (`ERROR_WRONG_PARAMETER`, E04); the read-back always gives the
//!   scene's.
//! - The extra values are carried so a cycle has the configured shape, but only the counter
//!   and the timestamp are the sensor's own: the temperature is a constant 25 degC, the
//!   exposure 20 us, the intensity half scale, the state 0.
//! - `BAUDRATE` is stored and read back (it starts at the line's baud); the line keeps its
//!   rate (a real sensor switches after the reply, which the host would have to follow).
//! - `OUTPUT ETHERNET` is taken and stops the RS422 output (the emulator has no Ethernet).
//! - The state at start: echo off, `OUTPUT RS422`, `OUTDIST_RS422 DIST1`, `OUTADD_RS422 NONE`,
//!   laser on: a sensor streaming the distance alone, which the factory baud rate carries at
//!   the paper's 20 kHz, so a host that sends no commands (a bench tool, the conformance run)
//!   gets the stream.

use scanhil_protocol::ild::IldError;
use scanhil_protocol::ild::command::{
    AddValue, AddValueSet, ECHO_DONE_SUFFIX, IldCommand, IldCommandError, IldInfo, IldOutputInfo,
    IldReply, MeasuringRate, OUTPUT_RS422, OUTPUT_WORDS,
};
use scanhil_protocol::ild::value::RAW_MAX;
use scanhil_protocol::link::IldRequest;

use crate::sensor::IldSample;

/// What `GETINFO` names the emulated sensor.
pub const EMULATED_NAME: &str = "ILD2300";
/// The emulated sensor's serial number in `GETINFO`.
pub const EMULATED_SERIAL: &str = "EMULATED";
/// The emulated sensor's article in `GETINFO`.
pub const EMULATED_ARTICLE: &str = "scanhil-emulator";
/// The constant temperature the emulated sensor reports, in its 0.25 degC units (25 degC).
const TEMPERATURE_QUARTER_DEGC: u32 = 100;
/// The constant exposure time it reports, in its 12.5 ns units (20 us).
const SHUTTER_STEPS: u32 = 1_600;
/// The constant intensity it reports: half of the 18-bit scale.
const INTENSITY: u32 = RAW_MAX / 2;

/// The emulated sensor's settings, changed by the host's commands.
#[derive(Debug, Clone, PartialEq)]
pub struct IldSettings {
    /// The scene's measuring rate (fixed, see the module's decisions).
    measuring_rate: MeasuringRate,
    /// The measuring range's span, mm (`GETINFO`'s `Measuring range`).
    range_span_mm: f64,
    echo: bool,
    /// The `OUTPUT` word in force.
    output: String,
    distance_on: bool,
    extras: AddValueSet,
    baud: u32,
    laser_on: bool,
}

/// What the settings say about one sample: the raw values of its output cycle, or nothing.
pub type Cycle = Option<Vec<u32>>;

impl IldSettings {
    /// The start state for a sensor measuring at `measuring_rate` with a range of
    /// `range_span_mm` on a line at `baud`.
    #[must_use]
    pub fn new(measuring_rate: MeasuringRate, range_span_mm: f64, baud: u32) -> IldSettings {
        IldSettings {
            measuring_rate,
            range_span_mm,
            echo: false,
            output: OUTPUT_RS422.to_owned(),
            distance_on: true,
            extras: AddValueSet::NONE,
            baud,
            laser_on: true,
        }
    }

    /// The same sensor sending `extras` after each distance, as if `OUTADD_RS422` had set
    /// them (a host run in one process, which has no command line to set them over).
    #[must_use]
    pub fn with_extras(mut self, extras: AddValueSet) -> IldSettings {
        self.extras = extras;
        self
    }

    /// Whether the laser is on.
    #[must_use]
    pub fn laser_on(&self) -> bool {
        self.laser_on
    }

    /// The values of an RS422 output cycle, in order (what `GETOUTINFO_RS422` answers).
    #[must_use]
    pub fn output_info(&self) -> IldOutputInfo {
        let mut info = IldOutputInfo::distance_then(self.extras);
        if !self.distance_on {
            info.values.remove(0);
        }
        info
    }

    /// The output cycle of `sample`: nothing while RS422 output is off (or carries no value);
    /// otherwise the values [`Self::output_info`] lists, the distance the laser-off error code
    /// while the laser is off.
    #[must_use]
    pub fn cycle(&self, sample: &IldSample) -> Cycle {
        let mut values = Vec::with_capacity(1 + self.extras.len());
        self.cycle_into(sample, &mut values).then_some(values)
    }

    /// [`Self::cycle`] into `values` (cleared first, a buffer used again for every sample);
    /// whether there is a cycle.
    pub fn cycle_into(&self, sample: &IldSample, values: &mut Vec<u32>) -> bool {
        values.clear();
        if self.output != OUTPUT_RS422 {
            return false;
        }
        if self.distance_on {
            values.push(if self.laser_on {
                sample.value.raw()
            } else {
                IldError::LaserOff.code()
            });
        }
        values.extend(self.extras.iter().map(|extra| match extra {
            AddValue::Temperature => TEMPERATURE_QUARTER_DEGC,
            AddValue::Shutter => SHUTTER_STEPS,
            AddValue::Counter => sample.counter,
            // Bits 8 to 25 of the microsecond timestamp (chap. 8, p. 86).
            AddValue::Timestamp => ((sample.t_s.max(0.0) * 1e6) as u64 >> 8) as u32 & RAW_MAX,
            AddValue::Intensity => INTENSITY,
            AddValue::State => 0,
        }));
        !values.is_empty()
    }

    /// Carries out one command line and returns the reply to send.
    pub fn answer(&mut self, request: &IldRequest) -> IldReply {
        // The reply's echo follows the setting in force when the line came (also for ECHO).
        let echo = self.echo.then(|| request.line.clone());
        let command = match &request.command {
            Ok(command) => command,
            Err(error) => return IldReply::refusal(echo, error),
        };
        let lines = match command {
            IldCommand::GetInfo => Some(self.info().reply_lines()),
            IldCommand::GetOutInfoRs422 => Some(self.output_info().reply_lines()),
            _ => None,
        };
        if let Some(lines) = lines {
            return IldReply {
                echo,
                lines,
                ..IldReply::default()
            };
        }
        if command.is_query() {
            return IldReply::query_answer(echo, &self.setting(command));
        }
        match self.apply(command) {
            Ok(()) => IldReply {
                echo: echo.map(|line| line + ECHO_DONE_SUFFIX),
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
            IldCommand::MeasRate(_) => IldCommand::MeasRate(Some(self.measuring_rate)),
            IldCommand::Echo(_) => IldCommand::Echo(Some(self.echo)),
            IldCommand::OutDistRs422(_) => IldCommand::OutDistRs422(Some(self.distance_on)),
            IldCommand::OutAddRs422(_) => IldCommand::OutAddRs422(Some(self.extras)),
            IldCommand::Baudrate(_) => IldCommand::Baudrate(Some(self.baud)),
            IldCommand::Output(_) => IldCommand::Output(Some(self.output.clone())),
            IldCommand::LaserPower(_) => IldCommand::LaserPower(Some(self.laser_on)),
            IldCommand::GetInfo | IldCommand::GetOutInfoRs422 => query.clone(),
        }
    }

    /// Applies a set command, or says why it is refused.
    fn apply(&mut self, command: &IldCommand) -> Result<(), IldCommandError> {
        let wrong = |command: &IldCommand| IldCommandError::WrongParameter {
            command: command.name(),
            parameter: command.parameters(),
        };
        match command {
            IldCommand::MeasRate(Some(rate)) if *rate != self.measuring_rate => {
                return Err(wrong(command));
            }
            IldCommand::Echo(Some(on)) => self.echo = *on,
            IldCommand::OutDistRs422(Some(on)) => self.distance_on = *on,
            IldCommand::OutAddRs422(Some(values)) => self.extras = *values,
            IldCommand::Baudrate(Some(baud)) => self.baud = *baud,
            IldCommand::Output(Some(word)) if OUTPUT_WORDS.contains(&word.as_str()) => {
                word.clone_into(&mut self.output);
            }
            IldCommand::Output(Some(_)) => return Err(wrong(command)),
            IldCommand::LaserPower(Some(on)) => self.laser_on = *on,
            // Queries, GETINFO and GETOUTINFO_RS422 are answered before this.
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
            t_s: 0.001,
            counter: 7,
            value: IldValue::Distance(32_760),
            true_distance_mm: Some(120.0),
        }
    }

    fn sensor() -> IldSettings {
        IldSettings::new(MeasuringRate::Khz20, 100.0, 691_200)
    }

    #[test]
    fn the_subset_is_answered_and_changes_the_stream() {
        let mut sensor = sensor();
        assert_eq!(
            sensor.cycle(&sample()),
            Some(vec![32_760]),
            "the distance alone"
        );
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
        assert!(sensor.answer(&request("OUTADD_RS422 COUNTER")).is_ok());
        assert!(sensor.answer(&request("LASERPOW OFF")).is_ok());
        assert_eq!(
            sensor.cycle(&sample()),
            Some(vec![IldError::LaserOff.code(), 7])
        );
        assert!(sensor.answer(&request("OUTADD_RS422 NONE")).is_ok());
        assert!(sensor.answer(&request("LASERPOW FULL")).is_ok());
        assert_eq!(sensor.cycle(&sample()), Some(vec![32_760]));
        assert!(sensor.answer(&request("OUTPUT NONE")).is_ok());
        assert_eq!(sensor.cycle(&sample()), None);
        assert!(sensor.answer(&request("OUTPUT ETHERNET")).is_ok());
        assert_eq!(sensor.cycle(&sample()), None, "no RS422 output");
        assert!(!sensor.answer(&request("OUTPUT ANALOG")).is_ok());
        assert_eq!(
            sensor.answer(&request("BAUDRATE")).encode(),
            "BAUDRATE 691200\r\n->",
            "the line's rate"
        );
        assert!(sensor.answer(&request("BAUDRATE 921600")).is_ok());
        assert_eq!(
            sensor.answer(&request("BAUDRATE")).encode(),
            "BAUDRATE 921600\r\n->"
        );
    }

    #[test]
    fn with_echo_on_a_setting_is_repeated_with_ok_and_a_query_as_sent() {
        let mut sensor = sensor();
        assert_eq!(
            sensor.answer(&request("ECHO ON")).encode(),
            "->",
            "echo off when it came"
        );
        assert_eq!(
            sensor.answer(&request("measrate 20")).encode(),
            "measrate 20 ok\r\n->"
        );
        assert_eq!(
            sensor.answer(&request("OUTPUT")).encode(),
            "OUTPUT\r\nOUTPUT RS422\r\n->"
        );
        assert_eq!(
            sensor.answer(&request("FROB")).encode(),
            "FROB\r\nE01 Unknown command\r\n->"
        );
        assert_eq!(
            sensor.answer(&request("ECHO OFF")).encode(),
            "ECHO OFF ok\r\n->"
        );
        assert_eq!(sensor.answer(&request("MEASRATE 20")).encode(), "->");
    }

    #[test]
    fn getoutinfo_lists_the_values_in_the_order_they_go_out() {
        let mut sensor = sensor();
        assert!(
            sensor
                .answer(&request("OUTADD_RS422 COUNTER TEMP TIMESTAMP"))
                .is_ok()
        );
        assert_eq!(
            sensor.answer(&request("GETOUTINFO_RS422")).encode(),
            "DIST1\r\nTEMP\r\nCOUNTER\r\nTIMESTAMP\r\n->"
        );
        // 1 ms is 1000 us: bits 8 and up give 3.
        assert_eq!(
            sensor.cycle(&sample()),
            Some(vec![32_760, TEMPERATURE_QUARTER_DEGC, 7, 3])
        );
        assert_eq!(
            sensor.answer(&request("OUTADD_RS422")).encode(),
            "OUTADD_RS422 TEMP COUNTER TIMESTAMP\r\n->"
        );
        assert!(sensor.answer(&request("OUTDIST_RS422 NONE")).is_ok());
        assert_eq!(
            sensor.output_info().words(),
            "TEMP COUNTER TIMESTAMP",
            "without the distance"
        );
        assert_eq!(
            sensor.cycle(&sample()),
            Some(vec![TEMPERATURE_QUARTER_DEGC, 7, 3])
        );
        assert!(
            sensor
                .answer(&request("OUTADD_RS422 SHUTTER INTENSITY STATE"))
                .is_ok()
        );
        assert_eq!(
            sensor.cycle(&sample()),
            Some(vec![SHUTTER_STEPS, INTENSITY, 0])
        );
        assert!(sensor.answer(&request("OUTADD_RS422 NONE")).is_ok());
        assert_eq!(sensor.cycle(&sample()), None, "a cycle of no value is none");
    }
}
