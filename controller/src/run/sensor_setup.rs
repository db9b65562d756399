//! Configuring the ILD 2300 over its ASCII command line before a scan, and reading the
//! configuration back, so a scan never runs against a sensor set up otherwise than the rig
//! expects.
//!
//! The sequence (each command must be answered without an `Exx` error within
//! [`COMMAND_TIMEOUT`]):
//! 1. `OUTPUT NONE`, then read until the line is quiet: a real sensor streams from power-up,
//!    and values on the line would mix with the replies (see the protocol's `IldLink`).
//! 2. `ECHO OFF`, so replies parse the same whatever the sensor's echo setting was.
//! 3. `GETINFO`: name, serial, article, version and the measuring range (the span: the
//!    manual's `Measuring range: 100.00mm`), which must match the expected span.
//! 4. `MEASRATE <expected kHz>`, then `MEASRATE` to read it back; both must give the expected
//!    rate. A refused set is reported with the rate the sensor reports instead.
//! 5. `OUTDIST_RS422 DIST1`, `OUTADD_RS422 COUNTER` (the counter after each distance, as the
//!    stream decoder expects), `LASERPOW FULL` (laser on; the command name is unchecked), then
//!    `BAUDRATE` read back for the report (the host does not change the baud rate: that
//!    would need reopening the port at the new rate).
//! 6. `OUTPUT RS422`: the stream starts.
//!
//! The start of the measuring range is not in `GETINFO` (it follows from the model: 70 mm for
//! the ILD 2300-100, unchecked); the report carries the expected one, marked as such.

use std::time::Duration;

use crate::rig::RigSensor;
use scanhil_protocol::ild::command::{
    AddValue, IldCommand, IldInfo, IldReply, MEASURING_RATES_KHZ,
};
use scanhil_protocol::link::LinkError;
use scanhil_protocol::link::ild::IldLink;

use super::LinkPlan;
use super::sensor_link::SensorLink;

/// How long each command may take to be answered.
pub const COMMAND_TIMEOUT: Duration = Duration::from_secs(1);
/// The line counts as quiet (the stream stopped) after this long without a cycle.
pub const QUIET: Duration = Duration::from_millis(20);
/// How long the stream may take to stop after `OUTPUT NONE`.
pub const STOP_WAIT: Duration = Duration::from_secs(1);
/// How far a reported measuring range may differ from the expected one, mm (`GETINFO` gives
/// two decimals).
const RANGE_TOLERANCE_MM: f64 = 0.005;
/// How far a read-back rate may differ from the expected one, kHz.
const RATE_TOLERANCE_KHZ: f64 = 1e-6;

/// What the set-up did, for `report.json` (`sensor_setup`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum SensorSetupReport {
    /// The sensor was configured and read back.
    Configured(ConfiguredSensor),
    /// No set-up was possible; the reason says why.
    Skipped {
        /// Why (e.g. Distance frames on the CAN link have no command line).
        reason: String,
    },
}

/// A configured sensor as it reported itself.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ConfiguredSensor {
    /// `GETINFO` `Name`.
    pub device_name: String,
    /// `GETINFO` `Serial`.
    pub serial: String,
    /// `GETINFO` `Article`.
    pub article: String,
    /// `GETINFO` `Version`.
    pub version: String,
    /// `GETINFO` `Measuring range` (the span), mm.
    pub range_span_mm: f64,
    /// The start of the range, mm: the expected one (`GETINFO` does not report it).
    pub range_start_mm_expected: f64,
    /// The measuring rate set, Hz.
    pub measuring_rate_set_hz: f64,
    /// The measuring rate read back, Hz.
    pub measuring_rate_read_back_hz: f64,
    /// The extra values per cycle (`OUTADD_RS422`).
    pub extra_values: Vec<String>,
    /// The laser was switched on.
    pub laser_on: bool,
    /// `BAUDRATE` read back (`None`: the sensor did not answer the query with a rate).
    pub baud_read_back: Option<u32>,
    /// The command lines sent, in order.
    pub commands: Vec<String>,
}

/// Why the sensor could not be set up as expected.
#[derive(Debug, thiserror::Error)]
pub enum SensorSetupError {
    /// The line failed or a reply did not come.
    #[error("sensor set-up: {0}")]
    Link(#[from] LinkError),
    /// The sensor refused a command.
    #[error("sensor refused `{command}`: E{code:02} {text}")]
    Refused {
        /// The command line.
        command: String,
        /// The error number.
        code: u8,
        /// Its text.
        text: String,
    },
    /// The expected rate is not one the sensor has.
    #[error(
        "the rig expects measuring rate {expected_hz} Hz, which the ILD 2300 does not have \
         (MEASRATE takes {MEASURING_RATES_KHZ:?} kHz)"
    )]
    UnknownRate {
        /// The expected rate, Hz.
        expected_hz: f64,
    },
    /// The sensor runs at another rate.
    #[error(
        "sensor reports measuring rate {reported_hz} Hz, the rig expects {expected_hz} Hz{refusal}"
    )]
    RateMismatch {
        /// The rate read back, Hz.
        reported_hz: f64,
        /// The expected rate, Hz.
        expected_hz: f64,
        /// How the sensor refused the set, if it did (empty or starting with " (").
        refusal: String,
    },
    /// The sensor has another measuring range.
    #[error(
        "sensor reports measuring range {reported_mm:.2} mm, the rig expects {expected_mm:.2} mm"
    )]
    RangeMismatch {
        /// `GETINFO`'s range, mm.
        reported_mm: f64,
        /// The expected span, mm.
        expected_mm: f64,
    },
    /// A reply that does not say what was asked.
    #[error("sensor's reply to `{command}` is unreadable: {detail}")]
    Unreadable {
        /// The command line.
        command: String,
        /// What was wrong.
        detail: String,
    },
    /// Values kept coming after `OUTPUT NONE`.
    #[error("sensor still streams {waited:?} after `OUTPUT NONE`")]
    StillStreaming {
        /// How long we waited.
        waited: Duration,
    },
}

/// The set-up a link plan asks for: `None` when it gives no expectation (conformance,
/// identification); skipped when the sensor has no ASCII line; otherwise the configured
/// sensor.
///
/// # Errors
/// [`SensorSetupError`] from [`configure`].
pub async fn for_plan(
    sensor: &mut SensorLink,
    plan: &LinkPlan,
) -> Result<Option<SensorSetupReport>, SensorSetupError> {
    let Some(expected) = &plan.sensor_expectation else {
        return Ok(None);
    };
    let reason = match (&plan.sensor, sensor.ild_link_mut()) {
        (_, Some(link)) => {
            return Ok(Some(SensorSetupReport::Configured(
                configure(link, expected).await?,
            )));
        }
        (None, None) => "this run has no sensor",
        (Some(_), None) => {
            "the sensor sends Distance frames on the mirror's CAN link (`fsm`): it has no ASCII \
             command line to configure"
        }
    };
    Ok(Some(SensorSetupReport::Skipped {
        reason: reason.to_owned(),
    }))
}

/// Configures the sensor on `link` as `expected` and reads it back (the module's sequence);
/// leaves the stream running with distance and counter per cycle.
///
/// # Errors
/// [`SensorSetupError`]: a refused command, a mismatch (naming both values), an unreadable
/// reply, a link failure.
pub async fn configure(
    link: &mut IldLink,
    expected: &RigSensor,
) -> Result<ConfiguredSensor, SensorSetupError> {
    let expected_khz = expected.measuring_rate_hz / 1e3;
    if !MEASURING_RATES_KHZ
        .iter()
        .any(|r| (r - expected_khz).abs() < RATE_TOLERANCE_KHZ)
    {
        return Err(SensorSetupError::UnknownRate {
            expected_hz: expected.measuring_rate_hz,
        });
    }
    let mut session = Session {
        link,
        commands: Vec::new(),
    };
    stop_output(session.link).await?;
    session
        .commands
        .push(output_none().encode().trim_end().to_owned());
    session.must(&IldCommand::Echo(Some(false))).await?;
    let info_reply = session.must(&IldCommand::GetInfo).await?;
    let info = IldInfo::from_reply(&info_reply).map_err(|e| SensorSetupError::Unreadable {
        command: "GETINFO".to_owned(),
        detail: e.to_string(),
    })?;
    if (info.measuring_range_mm - expected.range_span_mm).abs() > RANGE_TOLERANCE_MM {
        return Err(SensorSetupError::RangeMismatch {
            reported_mm: info.measuring_range_mm,
            expected_mm: expected.range_span_mm,
        });
    }
    let set = IldCommand::MeasRate(Some(expected_khz));
    let set_reply = session.send(&set).await?;
    let read_back_khz = session.measuring_rate_khz().await?;
    if let Some(error) = &set_reply.error {
        let refusal = format!(
            " (it refused `{}`: E{:02} {})",
            set.encode().trim_end(),
            error.code,
            error.text
        );
        return Err(SensorSetupError::RateMismatch {
            reported_hz: read_back_khz * 1e3,
            expected_hz: expected.measuring_rate_hz,
            refusal,
        });
    }
    if (read_back_khz - expected_khz).abs() > RATE_TOLERANCE_KHZ {
        return Err(SensorSetupError::RateMismatch {
            reported_hz: read_back_khz * 1e3,
            expected_hz: expected.measuring_rate_hz,
            refusal: String::new(),
        });
    }
    session.must(&IldCommand::OutDistRs422(Some(true))).await?;
    let extras = vec![AddValue::Counter];
    session
        .must(&IldCommand::OutAddRs422(Some(extras.clone())))
        .await?;
    session.must(&IldCommand::LaserPower(Some(true))).await?;
    let baud_reply = session.send(&IldCommand::Baudrate(None)).await?;
    let baud_read_back = match baud_reply.queried("BAUDRATE") {
        Some(IldCommand::Baudrate(baud)) => baud,
        _ => None,
    };
    session
        .must(&IldCommand::Output(Some("RS422".to_owned())))
        .await?;
    session.link.set_values_per_cycle(1 + extras.len());
    Ok(ConfiguredSensor {
        device_name: info.name,
        serial: info.serial,
        article: info.article,
        version: info.version,
        range_span_mm: info.measuring_range_mm,
        range_start_mm_expected: expected.range_start_mm,
        measuring_rate_set_hz: expected.measuring_rate_hz,
        measuring_rate_read_back_hz: read_back_khz * 1e3,
        extra_values: extras.iter().map(|v| v.word().to_owned()).collect(),
        laser_on: true,
        baud_read_back,
        commands: session.commands,
    })
}

/// `OUTPUT NONE`.
fn output_none() -> IldCommand {
    IldCommand::Output(Some("NONE".to_owned()))
}

/// Stops the sensor's output (`OUTPUT NONE`) and reads until the line is quiet for
/// [`QUIET`], dropping the values that were in flight.
///
/// # Errors
/// A refusal, [`SensorSetupError::StillStreaming`] after [`STOP_WAIT`], a link failure.
pub async fn stop_output(link: &mut IldLink) -> Result<(), SensorSetupError> {
    let command = output_none();
    let reply = link.command(&command, COMMAND_TIMEOUT).await?;
    refused(&command, &reply)?;
    let started = tokio::time::Instant::now();
    while link.recv_cycle_timeout(QUIET).await?.is_some() {
        if started.elapsed() > STOP_WAIT {
            return Err(SensorSetupError::StillStreaming { waited: STOP_WAIT });
        }
    }
    Ok(())
}

/// The refusal of `command`, if `reply` is one.
fn refused(command: &IldCommand, reply: &IldReply) -> Result<(), SensorSetupError> {
    match &reply.error {
        None => Ok(()),
        Some(error) => Err(SensorSetupError::Refused {
            command: command.encode().trim_end().to_owned(),
            code: error.code,
            text: error.text.clone(),
        }),
    }
}

/// The command exchange of one set-up, noting every line sent.
struct Session<'a> {
    link: &'a mut IldLink,
    commands: Vec<String>,
}

impl Session<'_> {
    /// Sends `command` and returns its reply, refused or not.
    async fn send(&mut self, command: &IldCommand) -> Result<IldReply, SensorSetupError> {
        self.commands.push(command.encode().trim_end().to_owned());
        Ok(self.link.command(command, COMMAND_TIMEOUT).await?)
    }

    /// Sends `command`; a refusal is an error.
    async fn must(&mut self, command: &IldCommand) -> Result<IldReply, SensorSetupError> {
        let reply = self.send(command).await?;
        refused(command, &reply)?;
        Ok(reply)
    }

    /// Reads the measuring rate back (`MEASRATE`), kHz.
    async fn measuring_rate_khz(&mut self) -> Result<f64, SensorSetupError> {
        let query = IldCommand::MeasRate(None);
        let reply = self.must(&query).await?;
        match reply.queried(query.name()) {
            Some(IldCommand::MeasRate(Some(khz))) => Ok(khz),
            _ => Err(SensorSetupError::Unreadable {
                command: query.name().to_owned(),
                detail: format!("no `MEASRATE <kHz>` line in {:?}", reply.lines),
            }),
        }
    }
}
