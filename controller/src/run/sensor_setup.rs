//! Configuring the ILD 2300 over its ASCII command line before a scan, and reading the
//! configuration back, so a scan never runs against a sensor set up otherwise than the rig
//! expects.
//!
//! The sequence (each command must be answered without an `Exx` error within
//! [`COMMAND_TIMEOUT`]; every line ends in CR LF):
//! 1. `OUTPUT NONE`, then read until the line is quiet: a real sensor streams from power-up,
//!    and values on the line would mix with the replies (see the protocol's `IldLink`).
//! 2. `ECHO OFF`, so replies are short (the host tells an echo apart either way).
//! 3. `GETINFO`: name, serial, article, version and the measuring range (the span: the
//!    manual's `Measuring range: 100.00mm`), which must match the expected span.
//! 4. `MEASRATE <expected>` (the manual's word: `49` for 49.14 kHz), then `MEASRATE` to read it
//!    back; both must give the expected rate. A refused set is reported with the rate the
//!    sensor reports instead.
//! 5. `OUTDIST_RS422 DIST1`, `OUTADD_RS422 <the rig's extra values, or NONE>`, `LASERPOW FULL`
//!    (laser on; the command name is unchecked), then `BAUDRATE` read back, which must be the
//!    rig's when the sensor answers with a rate (the host does not change the baud rate: that
//!    would need reopening the port at the new rate).
//! 6. `GETOUTINFO_RS422`: the values of a cycle in the order they go out (A 6.5.2.1); it must
//!    hold the distance and exactly the rig's extra values, and the link decodes the stream by
//!    it (the distance and the counter wherever the sensor puts them).
//! 7. `OUTPUT RS422`: the stream starts.
//!
//! The start of the measuring range is not in `GETINFO` (it follows from the model: 70 mm for
//! the ILD 2300-100, unchecked); the report carries the expected one, marked as such.

use std::path::Path;
use std::time::Duration;

use crate::rig::RigSensor;
use scanhil_protocol::ild::command::{
    IldCommand, IldInfo, IldOutputInfo, IldReply, MeasuringRate, OUTPUT_NONE, OUTPUT_RS422,
};
use scanhil_protocol::link::ild::IldLink;
use scanhil_protocol::link::{LinkError, LinkUri};

use super::LinkPlan;
use super::scenario::NodeLink;
use super::sensor_link::{SampleLayout, SensorLink};

/// How long each command may take to be answered.
pub const COMMAND_TIMEOUT: Duration = Duration::from_secs(1);
/// The line counts as quiet (the stream stopped) after this long without a cycle.
pub const QUIET: Duration = Duration::from_millis(20);
/// How long the stream may take to stop after `OUTPUT NONE`.
pub const STOP_WAIT: Duration = Duration::from_secs(1);
/// How far a reported measuring range may differ from the expected one, mm (`GETINFO` gives
/// two decimals).
const RANGE_TOLERANCE_MM: f64 = 0.005;

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
    /// The values of a cycle in the order they go out (`GETOUTINFO_RS422`).
    pub output_values: Vec<String>,
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
         (MEASRATE {} kHz)",
        MeasuringRate::words()
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
    /// The sensor's line runs at another baud rate.
    #[error("sensor reports baud rate {reported}, the rig expects {expected}")]
    BaudMismatch {
        /// `BAUDRATE` read back.
        reported: u32,
        /// The rig's.
        expected: u32,
    },
    /// The values of a cycle are not the expected ones.
    #[error(
        "sensor sends {reported} per cycle (GETOUTINFO_RS422), the rig expects the distance \
         and {expected}"
    )]
    OutputMismatch {
        /// The values `GETOUTINFO_RS422` lists.
        reported: String,
        /// The rig's extra values (`NONE`: the distance alone).
        expected: String,
    },
    /// Values kept coming after `OUTPUT NONE`.
    #[error("sensor still streams {waited:?} after `OUTPUT NONE`")]
    StillStreaming {
        /// How long we waited.
        waited: Duration,
    },
}

/// Checks, before anything opens, that the sensor's line runs at the rig's baud rate (the
/// rate the rig's values per cycle were checked against when it loaded): an `ild:PATH@BAUD`
/// at another rate is refused naming both. An emulated line (`pty`) runs at the rig's.
///
/// # Errors
/// A mismatch, naming the link, its baud, the rig and its baud; a URI that does not parse.
pub fn check_line(sensor: &RigSensor, link: &NodeLink, rig: &Path) -> anyhow::Result<()> {
    if let NodeLink::Uri(uri) = link
        && let Ok(LinkUri::Ild { baud, .. }) = uri.parse::<LinkUri>()
        && baud != sensor.baud
    {
        anyhow::bail!(
            "the sensor's line {uri} runs at {baud} baud, the sensor of rig {} at {} \
             (`sensor.baud`): give the line's rate as `ild:PATH@{}` or change the rig",
            rig.display(),
            sensor.baud,
            sensor.baud
        );
    }
    Ok(())
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
            let (configured, layout) = configure(link, expected).await?;
            sensor.set_layout(layout);
            return Ok(Some(SensorSetupReport::Configured(configured)));
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
/// leaves the stream running with the distance and the expected extra values per cycle, the
/// link set to the cycle's length. Returns the report and where the values are in a cycle.
///
/// # Errors
/// [`SensorSetupError`]: a refused command, a mismatch (naming both values), an unreadable
/// reply, a link failure.
pub async fn configure(
    link: &mut IldLink,
    expected: &RigSensor,
) -> Result<(ConfiguredSensor, SampleLayout), SensorSetupError> {
    let rate = MeasuringRate::from_hz(expected.measuring_rate_hz).ok_or(
        SensorSetupError::UnknownRate {
            expected_hz: expected.measuring_rate_hz,
        },
    )?;
    let mut session = Session {
        link,
        commands: Vec::new(),
    };
    stop_output(session.link).await?;
    session.commands.push(output(OUTPUT_NONE).line());
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
    let set = IldCommand::MeasRate(Some(rate));
    let set_reply = session.send(&set).await?;
    let read_back = session.measuring_rate().await?;
    if let Some(error) = &set_reply.error {
        let refusal = format!(
            " (it refused `{}`: E{:02} {})",
            set.line(),
            error.code,
            error.text
        );
        return Err(SensorSetupError::RateMismatch {
            reported_hz: read_back.hz(),
            expected_hz: expected.measuring_rate_hz,
            refusal,
        });
    }
    if read_back != rate {
        return Err(SensorSetupError::RateMismatch {
            reported_hz: read_back.hz(),
            expected_hz: expected.measuring_rate_hz,
            refusal: String::new(),
        });
    }
    session.must(&IldCommand::OutDistRs422(Some(true))).await?;
    session
        .must(&IldCommand::OutAddRs422(Some(expected.extra_values)))
        .await?;
    session.must(&IldCommand::LaserPower(Some(true))).await?;
    let baud_reply = session.send(&IldCommand::Baudrate(None)).await?;
    let baud_read_back = match baud_reply.queried("BAUDRATE") {
        Some(IldCommand::Baudrate(baud)) => baud,
        _ => None,
    };
    if let Some(reported) = baud_read_back.filter(|&baud| baud != expected.baud) {
        return Err(SensorSetupError::BaudMismatch {
            reported,
            expected: expected.baud,
        });
    }
    let output_info = session.output_info().await?;
    let layout = SampleLayout::of(&output_info)
        .filter(|_| output_info.extras() == expected.extra_values)
        .ok_or_else(|| SensorSetupError::OutputMismatch {
            reported: output_info.words(),
            expected: expected.extra_values.to_string(),
        })?;
    // Set before the stream starts: its first cycles may come with the reply.
    session.link.set_values_per_cycle(output_info.values.len());
    session.must(&output(OUTPUT_RS422)).await?;
    let configured = ConfiguredSensor {
        device_name: info.name,
        serial: info.serial,
        article: info.article,
        version: info.version,
        range_span_mm: info.measuring_range_mm,
        range_start_mm_expected: expected.range_start_mm,
        measuring_rate_set_hz: expected.measuring_rate_hz,
        measuring_rate_read_back_hz: read_back.hz(),
        extra_values: expected
            .extra_values
            .iter()
            .map(|v| v.word().to_owned())
            .collect(),
        output_values: output_info.reply_lines(),
        laser_on: true,
        baud_read_back,
        commands: session.commands,
    };
    Ok((configured, layout))
}

/// `OUTPUT <word>`.
fn output(word: &str) -> IldCommand {
    IldCommand::Output(Some(word.to_owned()))
}

/// Reads what a cycle holds (`GETOUTINFO_RS422`) with the output stopped, and restarts it:
/// for a sensor taken as it is (conformance).
///
/// # Errors
/// As [`stop_output`]; an unreadable or refused `GETOUTINFO_RS422`; a refused restart.
pub async fn read_output(link: &mut IldLink) -> Result<IldOutputInfo, SensorSetupError> {
    stop_output(link).await?;
    let mut session = Session {
        link,
        commands: Vec::new(),
    };
    let info = session.output_info().await?;
    session.must(&output(OUTPUT_RS422)).await?;
    Ok(info)
}

/// Stops the sensor's output (`OUTPUT NONE`) and reads until the line is quiet for
/// [`QUIET`], dropping the values that were in flight.
///
/// # Errors
/// A refusal, [`SensorSetupError::StillStreaming`] after [`STOP_WAIT`], a link failure.
pub async fn stop_output(link: &mut IldLink) -> Result<(), SensorSetupError> {
    let command = output(OUTPUT_NONE);
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
            command: command.line(),
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
        self.commands.push(command.line());
        Ok(self.link.command(command, COMMAND_TIMEOUT).await?)
    }

    /// Sends `command`; a refusal is an error.
    async fn must(&mut self, command: &IldCommand) -> Result<IldReply, SensorSetupError> {
        let reply = self.send(command).await?;
        refused(command, &reply)?;
        Ok(reply)
    }

    /// Reads the measuring rate back (`MEASRATE`).
    async fn measuring_rate(&mut self) -> Result<MeasuringRate, SensorSetupError> {
        let query = IldCommand::MeasRate(None);
        let reply = self.must(&query).await?;
        match reply.queried(query.name()) {
            Some(IldCommand::MeasRate(Some(rate))) => Ok(rate),
            _ => Err(SensorSetupError::Unreadable {
                command: query.name().to_owned(),
                detail: format!(
                    "no `MEASRATE {}` line in {:?}",
                    MeasuringRate::words(),
                    reply.lines
                ),
            }),
        }
    }

    /// The values of a cycle in their order (`GETOUTINFO_RS422`).
    async fn output_info(&mut self) -> Result<IldOutputInfo, SensorSetupError> {
        let command = IldCommand::GetOutInfoRs422;
        let reply = self.must(&command).await?;
        IldOutputInfo::from_reply(&reply).map_err(|e| SensorSetupError::Unreadable {
            command: command.line(),
            detail: e.to_string(),
        })
    }
}
