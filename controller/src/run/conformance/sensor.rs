//! The sensor's checks: its stream (decoding, counters, values) and its command line's
//! refusal of bad commands.

use scanhil_protocol::ild::command::{IldCommand, IldInfo};
use scanhil_protocol::ild::{IldError, IldValue};
use scanhil_protocol::link::IldLink;

use crate::run::sensor_link::SensorLink;
use crate::run::sensor_setup::{COMMAND_TIMEOUT, stop_output};

/// Bad ASCII command lines for `sensor_survives_bad_commands`, with what each is.
const BAD_ILD_COMMANDS: [(&str, &str); 4] = [
    ("FROB 1", "unknown command"),
    ("MEASRATE 7", "a measuring rate the sensor does not have"),
    ("OUTPUT SIDEWAYS", "an unknown OUTPUT word"),
    ("GETINFO EXTRA", "a parameter GETINFO does not take"),
];
/// Length of the overlong command line (longer than a device's line buffer).
const OVERLONG_COMMAND_LEN: usize = 300;

/// Sends the bad command lines (each must be refused with an `Exx` error), then `GETINFO`
/// (must be answered with a measuring range), with the sensor's output stopped meanwhile.
pub(super) async fn survive_bad_commands(link: &mut IldLink) -> Result<String, String> {
    stop_output(link)
        .await
        .map_err(|e| format!("stopping the output first: {e}"))?;
    let overlong = "X".repeat(OVERLONG_COMMAND_LEN);
    let lines = BAD_ILD_COMMANDS
        .iter()
        .map(|&(line, what)| (line.to_owned(), what.to_owned()))
        .chain([(overlong, format!("a {OVERLONG_COMMAND_LEN}-byte line"))]);
    let mut refusals = Vec::new();
    for (line, what) in lines {
        let reply = link
            .send_raw_command_line(&line, COMMAND_TIMEOUT)
            .await
            .map_err(|e| format!("{what}: {e}"))?;
        match reply.error {
            Some(error) => refusals.push(format!("{what}: E{:02}", error.code)),
            None => return Err(format!("{what} was not refused (reply {:?})", reply.lines)),
        }
    }
    let refusals = refusals.join(", ");
    let info = link
        .command(&IldCommand::GetInfo, COMMAND_TIMEOUT)
        .await
        .map_err(|e| format!("{refusals}; then GETINFO: {e}"))?;
    let info = IldInfo::from_reply(&info).map_err(|e| format!("{refusals}; then {e}"))?;
    let restart = IldCommand::Output(Some("RS422".to_owned()));
    match link.command(&restart, COMMAND_TIMEOUT).await {
        Ok(reply) if reply.is_ok() => {}
        Ok(reply) => return Err(format!("restarting the output: refused {:?}", reply.error)),
        Err(error) => return Err(format!("restarting the output: {error}")),
    }
    Ok(format!(
        "{refusals}; GETINFO still answered (measuring range {:.2} mm)",
        info.measuring_range_mm
    ))
}

/// The sensor stream's checks: (name, passed, what was seen).
pub(super) fn sensor_checks(sensor: &SensorLink) -> [(&'static str, bool, String); 3] {
    let (samples, counters) = sensor.snapshot();
    let bad = samples
        .iter()
        .find(|s| matches!(s.value, IldValue::Error(IldError::Unknown(_))));
    [
        (
            "sensor_values_decode",
            counters.samples > 0 && counters.resync_bytes == 0 && counters.incomplete_cycles == 0,
            format!(
                "{} samples, {} bytes skipped, {} incomplete cycles",
                counters.samples, counters.resync_bytes, counters.incomplete_cycles
            ),
        ),
        (
            "sensor_counter_gapless",
            counters.samples > 0 && counters.counter_gaps == 0,
            format!("{} counter values missing", counters.counter_gaps),
        ),
        (
            "sensor_values_in_range",
            bad.is_none() && counters.samples > 0,
            bad.map_or_else(
                || "every value a distance or a known error code".to_owned(),
                |s| format!("unknown error code {}", s.value.raw()),
            ),
        ),
    ]
}
