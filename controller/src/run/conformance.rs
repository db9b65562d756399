//! Conformance checks of a mirror node and a sensor node, real or emulated, against the loop
//! protocol. Each check is independent of the others' verdicts and says what it saw.
//!
//! Mirror node (lockstep exchanges over its CAN link):
//! - `answers_in_time`: every Step is answered by its AngleReading within the allowance.
//! - `angle_sequence_gapless`: AngleReading sequence counters follow the Step counter.
//! - `angles_in_range`: angles finite and within the mirror's range (+-1.5 deg, with margin).
//! - `status_frames`: Status frames arrive with a valid state.
//! - `over_current_fault`: a coil command beyond any amplifier's limit raises an OverCurrent
//!   fault frame.
//! - `survives_malformed_frames`: malformed loop frames (short payloads) leave the node
//!   answering.
//! - `survives_garbage_slcan_lines` (SLCAN links only): garbage lines (unknown commands,
//!   truncated frames, bytes outside ASCII, an overlong line) leave the node answering.
//! - `link_timeout_fault`: silence for the watchdog's periods raises a LinkTimeout fault
//!   (run last: the node leaves the session).
//!
//! Sensor node (ILD stream, while the mirror node is stepped):
//! - `sensor_values_decode`: the stream decodes with no resynchronisation.
//! - `sensor_counter_gapless`: measured-value counters without gaps.
//! - `sensor_values_in_range`: every value a distance or a known error code.
//! - `sensor_survives_bad_commands` (ILD line only): unknown commands, wrong parameters and an
//!   overlong line are each refused with an `Exx` error, and `GETINFO` is still answered with
//!   a measuring range. The stream is stopped (`OUTPUT NONE`) around the check and restarted
//!   after it.

use std::fmt::Write as _;
use std::time::{Duration, Instant};

use scanhil_protocol::ild::command::{IldCommand, IldInfo};
use scanhil_protocol::ild::{IldError, IldValue};
use scanhil_protocol::link::{IldLink, LinkError};
use scanhil_protocol::message::FaultKind;
use scanhil_protocol::plant_units::ActuatorPair;
use scanhil_protocol::slcan::SlcanMessage;

use super::host_inbox::{plausible_angle_limit_rad, plausible_angles};
use super::mirror_link::MirrorLink;
use super::sensor_link::SensorLink;
use super::sensor_setup::{COMMAND_TIMEOUT, stop_output};

/// Garbage SLCAN lines for `survives_garbage_slcan_lines`, with what each is.
const GARBAGE_SLCAN_LINES: [(&[u8], &str); 5] = [
    (b"xyz", "unknown command `xyz`"),
    (b"t12", "truncated frame `t12`"),
    (b"t1008010203", "frame shorter than its DLC"),
    (b"\xff\xfe\x00\x80", "bytes outside ASCII"),
    (&[b'A'; 200], "a 200-byte line"),
];
/// Bad ASCII command lines for `sensor_survives_bad_commands`, with what each is.
const BAD_ILD_COMMANDS: [(&str, &str); 4] = [
    ("FROB 1", "unknown command"),
    ("MEASRATE 7", "a measuring rate the sensor does not have"),
    ("OUTPUT SIDEWAYS", "an unknown OUTPUT word"),
    ("GETINFO EXTRA", "a parameter GETINFO does not take"),
];
/// Length of the overlong command line (longer than a device's line buffer).
const OVERLONG_COMMAND_LEN: usize = 300;

/// Exchanges used by the timing and range checks.
const EXCHANGES: u64 = 2_500;
/// A coil current no amplifier accepts, A.
const OVER_CURRENT_A: f64 = 8.0;

/// One check's verdict.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CheckResult {
    /// The check's name.
    pub name: &'static str,
    /// Which node it checked.
    pub node: &'static str,
    /// Passed?
    pub passed: bool,
    /// What was seen.
    pub detail: String,
    /// How long it took, s.
    pub time_s: f64,
}

/// Runs the mirror node's checks and, when given, the sensor's.
pub async fn run_checks(
    mirror: &mut MirrorLink,
    mut sensor: Option<&mut SensorLink>,
) -> Vec<CheckResult> {
    let mut results = Vec::new();
    let mut k = 0u64;
    // Timing, sequence, range, status (and the sensor stream alongside).
    let start = Instant::now();
    let mut late: Option<String> = None;
    let mut slowest = Duration::ZERO;
    let mut out_of_range: Option<String> = None;
    let limit_rad = plausible_angle_limit_rad();
    while k < EXCHANGES {
        let t0 = Instant::now();
        let exchange = match sensor.as_deref_mut() {
            Some(sensor) => tokio::select! {
                r = mirror.exchange_lockstep(k, ActuatorPair::default()) => r,
                e = sensor.pump() => Err(e),
            },
            None => mirror.exchange_lockstep(k, ActuatorPair::default()).await,
        };
        slowest = slowest.max(t0.elapsed());
        match exchange {
            Ok(angles) => {
                if out_of_range.is_none() && !plausible_angles(angles) {
                    out_of_range = Some(format!(
                        "period {k}: alpha {} rad, beta {} rad",
                        angles.alpha, angles.beta
                    ));
                }
            }
            Err(error) => {
                late = Some(format!("period {k}: {error}"));
                break;
            }
        }
        k += 1;
    }
    let elapsed = start.elapsed().as_secs_f64();
    results.push(CheckResult {
        name: "answers_in_time",
        node: "fsm",
        passed: late.is_none(),
        detail: late.unwrap_or_else(|| format!("{k} steps answered, slowest {slowest:?}")),
        time_s: elapsed,
    });
    let counters = mirror.counters();
    results.push(CheckResult {
        name: "angle_sequence_gapless",
        node: "fsm",
        passed: counters.angle_sequence_gaps + counters.late_readings == 0
            && counters.angle_readings >= k,
        detail: format!(
            "{} readings, {} out of sequence",
            counters.angle_readings,
            counters.angle_sequence_gaps + counters.late_readings
        ),
        time_s: 0.0,
    });
    results.push(CheckResult {
        name: "angles_in_range",
        node: "fsm",
        passed: out_of_range.is_none() && k > 0,
        detail: out_of_range.unwrap_or_else(|| format!("all within +-{:.3} mrad", limit_rad * 1e3)),
        time_s: 0.0,
    });
    let statuses = mirror
        .events()
        .iter()
        .filter(|e| e.status.is_some())
        .count();
    results.push(CheckResult {
        name: "status_frames",
        node: "fsm",
        passed: statuses > 0,
        detail: format!("{statuses} status frames in {k} periods"),
        time_s: 0.0,
    });
    // Over-current fault.
    let t0 = Instant::now();
    let faults_before = fault_count(mirror, FaultKind::OverCurrent);
    let big = ActuatorPair {
        a: OVER_CURRENT_A,
        b: -OVER_CURRENT_A,
    };
    let mut over_current_error = None;
    for _ in 0..3 {
        if let Err(error) = mirror.exchange_lockstep(k, big).await {
            over_current_error = Some(error.to_string());
            break;
        }
        k += 1;
    }
    for _ in 0..3 {
        if mirror
            .exchange_lockstep(k, ActuatorPair::default())
            .await
            .is_ok()
        {
            k += 1;
        }
    }
    let raised = fault_count(mirror, FaultKind::OverCurrent) > faults_before;
    results.push(CheckResult {
        name: "over_current_fault",
        node: "fsm",
        passed: raised && over_current_error.is_none(),
        detail: over_current_error.unwrap_or_else(|| {
            if raised {
                format!("OverCurrent fault frame after a {OVER_CURRENT_A} A command")
            } else {
                format!("no OverCurrent fault after a {OVER_CURRENT_A} A command")
            }
        }),
        time_s: t0.elapsed().as_secs_f64(),
    });
    // Malformed input.
    let t0 = Instant::now();
    let survived = match mirror.send_malformed(k).await {
        Err(error) => Err(format!("sending malformed input: {error}")),
        Ok(sent) => match mirror.exchange_lockstep(k, ActuatorPair::default()).await {
            Ok(_) => Ok(format!("{sent}; still answering")),
            Err(error) => Err(format!("{sent}; then: {error}")),
        },
    };
    results.push(CheckResult {
        name: "survives_malformed_frames",
        node: "fsm",
        passed: survived.is_ok(),
        detail: survived.unwrap_or_else(|e| e),
        time_s: t0.elapsed().as_secs_f64(),
    });
    // The malformed check's exchange used period k.
    if results.last().is_some_and(|r| r.passed) {
        k += 1;
    }
    // Garbage SLCAN lines (SLCAN only).
    let t0 = Instant::now();
    if let Some(survived) = survive_garbage_lines(mirror, k).await {
        results.push(CheckResult {
            name: "survives_garbage_slcan_lines",
            node: "fsm",
            passed: survived.is_ok(),
            detail: survived.unwrap_or_else(|e| e),
            time_s: t0.elapsed().as_secs_f64(),
        });
    }
    // Sensor stream.
    if let Some(sensor) = sensor {
        let _ = sensor.drain(Duration::from_millis(100)).await;
        results.extend(sensor_checks(sensor));
        if let Some(link) = sensor.ild_link_mut() {
            let t0 = Instant::now();
            let survived = survive_bad_commands(link).await;
            results.push(CheckResult {
                name: "sensor_survives_bad_commands",
                node: "sensor",
                passed: survived.is_ok(),
                detail: survived.unwrap_or_else(|e| e),
                time_s: t0.elapsed().as_secs_f64(),
            });
        }
    }
    // Link timeout (last).
    let t0 = Instant::now();
    let timeout = mirror.await_link_timeout_fault().await;
    results.push(CheckResult {
        name: "link_timeout_fault",
        node: "fsm",
        passed: timeout.is_ok(),
        detail: timeout.unwrap_or_else(|e| {
            format!("no LinkTimeout fault from the node after the host fell silent: {e}")
        }),
        time_s: t0.elapsed().as_secs_f64(),
    });
    results
}

/// Sends the garbage lines, then one lockstep exchange (period `k`) that must be answered.
/// `None` on a link without SLCAN lines (SocketCAN).
async fn survive_garbage_lines(mirror: &mut MirrorLink, k: u64) -> Option<Result<String, String>> {
    let mut answers = Vec::new();
    for (line, what) in GARBAGE_SLCAN_LINES {
        let answer = match mirror.can_link_mut().send_raw_line(line).await {
            Err(LinkError::Unsupported { .. }) => return None,
            Err(error) => return Some(Err(format!("sending {what}: {error}"))),
            Ok(Some(SlcanMessage::Nack)) => "BEL".to_owned(),
            Ok(Some(other)) => format!("{other:?}"),
            Ok(None) => "no answer".to_owned(),
        };
        answers.push(format!("{what}: {answer}"));
    }
    let sent = answers.join(", ");
    Some(
        match mirror.exchange_lockstep(k, ActuatorPair::default()).await {
            Ok(_) => Ok(format!("{sent}; still answering")),
            Err(error) => Err(format!("{sent}; then the next exchange failed: {error}")),
        },
    )
}

/// Sends the bad command lines (each must be refused with an `Exx` error), then `GETINFO`
/// (must be answered with a measuring range), with the sensor's output stopped meanwhile.
async fn survive_bad_commands(link: &mut IldLink) -> Result<String, String> {
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

fn fault_count(mirror: &MirrorLink, kind: FaultKind) -> usize {
    mirror
        .events()
        .iter()
        .filter(|e| e.fault == Some(kind))
        .count()
}

fn sensor_checks(sensor: &SensorLink) -> Vec<CheckResult> {
    let (samples, counters) = sensor.snapshot();
    let bad = samples
        .iter()
        .find(|s| matches!(s.value, IldValue::Error(IldError::Unknown(_))));
    vec![
        CheckResult {
            name: "sensor_values_decode",
            node: "sensor",
            passed: counters.samples > 0
                && counters.resync_bytes == 0
                && counters.incomplete_cycles == 0,
            detail: format!(
                "{} samples, {} bytes skipped, {} incomplete cycles",
                counters.samples, counters.resync_bytes, counters.incomplete_cycles
            ),
            time_s: 0.0,
        },
        CheckResult {
            name: "sensor_counter_gapless",
            node: "sensor",
            passed: counters.samples > 0 && counters.counter_gaps == 0,
            detail: format!("{} counter values missing", counters.counter_gaps),
            time_s: 0.0,
        },
        CheckResult {
            name: "sensor_values_in_range",
            node: "sensor",
            passed: bad.is_none() && counters.samples > 0,
            detail: bad.map_or_else(
                || "every value a distance or a known error code".to_owned(),
                |s| format!("unknown error code {}", s.value.raw()),
            ),
            time_s: 0.0,
        },
    ]
}

/// The pass/fail table.
#[must_use]
pub fn table(results: &[CheckResult]) -> String {
    let mut text = format!("{:<6} {:<28} {:<6} detail\n", "node", "check", "result");
    for r in results {
        let _ = writeln!(
            text,
            "{:<6} {:<28} {:<6} {}",
            r.node,
            r.name,
            if r.passed { "PASS" } else { "FAIL" },
            r.detail
        );
    }
    let failed = results.iter().filter(|r| !r.passed).count();
    let _ = write!(
        text,
        "{} checks, {} passed, {failed} failed",
        results.len(),
        results.len() - failed
    );
    text
}

/// The results as JUnit XML (one test suite, one test case per check).
#[must_use]
pub fn junit_xml(results: &[CheckResult]) -> String {
    let failures = results.iter().filter(|r| !r.passed).count();
    let total: f64 = results.iter().map(|r| r.time_s).sum();
    let mut xml = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites>\n  <testsuite name=\"scanhil-conformance\" tests=\"{}\" failures=\"{failures}\" errors=\"0\" time=\"{total:.6}\">\n",
        results.len()
    );
    for r in results {
        let _ = write!(
            xml,
            "    <testcase classname=\"{}\" name=\"{}\" time=\"{:.6}\"",
            r.node, r.name, r.time_s
        );
        if r.passed {
            let _ = writeln!(
                xml,
                "><system-out>{}</system-out></testcase>",
                escape(&r.detail)
            );
        } else {
            let _ = writeln!(
                xml,
                "><failure message=\"{}\"/></testcase>",
                escape(&r.detail)
            );
        }
    }
    xml + "  </testsuite>\n</testsuites>\n"
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}
