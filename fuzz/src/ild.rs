//! The ILD 2300's ASCII commands: command lines at the device end (the emulated sensor) and
//! replies at the host end.

use scanhil_emulator::serve::sensor_commands::IldSettings;
use scanhil_protocol::ild::command::{
    ECHO_DONE_SUFFIX, IldCommandError, LASER_POWER_COMMAND_UNCHECKED, MeasuringRate,
};
use scanhil_protocol::ild::{IldCommand, IldInfo, IldReply, IldReplyParser};
use scanhil_protocol::link::IldRequest;
use scanhil_protocol::link::ild::MAX_COMMAND_LINE;

/// The name of every command of the subset, for reading query answers.
const COMMAND_NAMES: [&str; 8] = [
    "GETINFO",
    "MEASRATE",
    "ECHO",
    "OUTDIST_RS422",
    "OUTADD_RS422",
    "BAUDRATE",
    "OUTPUT",
    LASER_POWER_COMMAND_UNCHECKED,
];

/// Bytes a host sends the sensor, cut into lines at CR or LF as the device end reads them (a
/// line longer than [`MAX_COMMAND_LINE`] refused whole), each answered by the emulated sensor.
/// A command that parses encodes back to itself, and every answer reads back at the host as
/// it was sent (unless the echoed line holds the prompt `->`, which no reply parser can tell
/// from the end of the reply).
pub fn commands(data: &[u8]) {
    let mut sensor = IldSettings::new(MeasuringRate::Khz20, 100.0, 691_200);
    for raw in data.split(|&b| b == b'\r' || b == b'\n') {
        let line = String::from_utf8_lossy(raw).trim().to_owned();
        if line.is_empty() {
            continue;
        }
        let command = if raw.len() > MAX_COMMAND_LINE {
            Err(IldCommandError::UnknownCommand(format!(
                "line longer than {MAX_COMMAND_LINE} bytes"
            )))
        } else {
            IldCommand::parse(&line)
        };
        if let Ok(command) = &command {
            let encoded = command.encode();
            assert_eq!(
                IldCommand::parse(&encoded).as_ref(),
                Ok(command),
                "{line:?} parsed as {command:?}, which encodes as {encoded:?}"
            );
        }
        let reply = sensor.answer(&IldRequest {
            line: line.clone(),
            command,
        });
        if reply
            .echo
            .as_deref()
            .is_some_and(|echo| echo.contains("->"))
        {
            continue;
        }
        let read = IldReplyParser::new(&line).push(reply.encode().as_bytes());
        assert_eq!(read, vec![reply.clone()], "the host misreads {reply:?}");
    }
}

/// Bytes a sensor sends the host after a command (byte 0, bit 0: echo is on, so the host sent
/// the command the first line echoes, `<command>` or `<command> ok`; else a command no line
/// repeats): the same replies whole and byte by byte; a `GETINFO` reply read only with a
/// measuring range the host can compare; a query answer only as a set command of the name
/// asked for.
pub fn replies(data: &[u8]) {
    let Some((&first, bytes)) = data.split_first() else {
        return;
    };
    let sent = if first & 1 == 1 {
        echoed_command(bytes)
    } else {
        String::new()
    };
    let whole = IldReplyParser::new(&sent).push(bytes);
    let mut parser = IldReplyParser::new(&sent);
    let byte_by_byte: Vec<IldReply> = bytes.iter().flat_map(|&b| parser.push(&[b])).collect();
    assert_eq!(whole, byte_by_byte, "chunking changed the replies");
    for reply in &whole {
        if let Ok(info) = IldInfo::from_reply(reply) {
            assert!(
                info.measuring_range_mm.is_finite() && info.measuring_range_mm > 0.0,
                "GETINFO read a measuring range of {} mm from {reply:?}",
                info.measuring_range_mm
            );
        }
        for name in COMMAND_NAMES {
            if let Some(setting) = reply.queried(name) {
                assert_eq!(setting.name(), name);
                assert!(!setting.is_query(), "{setting:?} read as a setting");
            }
        }
    }
}

/// The command the first line of `bytes` echoes: the line without [`ECHO_DONE_SUFFIX`].
fn echoed_command(bytes: &[u8]) -> String {
    let first = bytes
        .split(|&b| b == b'\r' || b == b'\n')
        .next()
        .unwrap_or_default();
    let first = String::from_utf8_lossy(first);
    let first = first.trim();
    first
        .strip_suffix(ECHO_DONE_SUFFIX)
        .unwrap_or(first)
        .to_owned()
}
