//! Conformance checks of a mirror node and a sensor node, real or emulated, against the loop
//! protocol. Each check is independent of the others' verdicts and says what it saw.
//!
//! Mirror node (lockstep exchanges over its CAN link):
//! - `answers_in_time`: every Step is answered by an AngleReading within the watchdog's
//!   allowance (a later answer is waited for up to twice that, and counted late).
//! - `angle_sequence_gapless`: AngleReading sequence counters follow the Step counter.
//! - `angles_in_range`: under [`EXCITATION`] (sines on both coils), angles finite and within
//!   the mirror's range (+-1.5 deg, with margin), and each axis swinging at least
//!   1 mrad peak to peak (frozen angles fail).
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
//! Which checks run is the caller's [`Selection`] ([`super::check_selection`]): on a real
//! link `over_current_fault` and `survives_garbage_slcan_lines` run only with `--destructive`
//! and are listed as skipped otherwise. A run without `link_timeout_fault` ends its session
//! with the zero command the node acknowledges ([`MirrorLink::end_session`]), so the coils are
//! at zero at its end either way.
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
use scanhil_protocol::plant_units::{ActuatorPair, FULL_RANGE_DEG, SensingPair};
use scanhil_protocol::slcan::SlcanMessage;

use super::check_selection::{Decision, Selection, spec};
use super::loop_error::LoopError;
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
/// Periods commanded at [`OVER_CURRENT_A`], then at zero, in the over-current check.
const OVER_CURRENT_PERIODS: u32 = 3;
/// Margin on the mirror's range for the range check.
const RANGE_MARGIN: f64 = 1.2;
/// The least peak-to-peak swing each axis must show under [`EXCITATION`], rad.
const MIN_SWING_RAD: f64 = 1e-3;
/// How long the timing check waits for an answer, in watchdog allowances: an answer after
/// one allowance is late, one after this many is lost (and ends the check).
const LATE_WAIT_ALLOWANCES: u32 = 2;

/// One check's verdict.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CheckResult {
    /// The check's name.
    pub name: &'static str,
    /// Which node it checked.
    pub node: &'static str,
    /// Passed, failed, or not run.
    pub outcome: Outcome,
    /// What was seen (skipped: why it did not run).
    pub detail: String,
    /// How long it took, s.
    pub time_s: f64,
}

/// A check's outcome.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// It ran and passed.
    Passed,
    /// It ran and failed.
    Failed,
    /// It did not run (a destructive check on a real link without `--destructive`).
    Skipped,
}

impl CheckResult {
    /// Whether the check ran and passed.
    #[must_use]
    pub fn passed(&self) -> bool {
        self.outcome == Outcome::Passed
    }

    /// Whether the check ran and failed.
    #[must_use]
    pub fn failed(&self) -> bool {
        self.outcome == Outcome::Failed
    }
}

/// The verdicts of a run as the checks come: only the selected checks', and the ones left
/// out for the bench's safety as skipped.
struct Verdicts<'a> {
    selection: &'a Selection,
    results: &'a mut Vec<CheckResult>,
    /// Told of the results after each one (the caller writes them as they come).
    on_result: &'a mut dyn FnMut(&[CheckResult]),
}

impl Verdicts<'_> {
    /// Whether check `name` is to run now; one left out for the bench's safety is listed as
    /// skipped with the reason.
    fn start(&mut self, name: &'static str) -> bool {
        match self.selection.decide(name) {
            Decision::Run => true,
            Decision::Deselected => false,
            Decision::Skipped(why) => {
                self.push(name, Outcome::Skipped, why, 0.0);
                false
            }
        }
    }

    /// The verdict of check `name`, which ran.
    fn add(&mut self, name: &'static str, passed: bool, detail: String, time_s: f64) {
        let outcome = if passed {
            Outcome::Passed
        } else {
            Outcome::Failed
        };
        self.push(name, outcome, detail, time_s);
    }

    /// The verdict of a check of the timing phase, which always runs: kept when selected.
    fn add_if_selected(&mut self, name: &'static str, passed: bool, detail: String) {
        if self.selection.runs(name) {
            self.add(name, passed, detail, 0.0);
        }
    }

    fn push(&mut self, name: &'static str, outcome: Outcome, detail: String, time_s: f64) {
        self.results.push(CheckResult {
            name,
            node: spec(name).map_or("fsm", |check| check.node),
            outcome,
            detail,
            time_s,
        });
        (self.on_result)(self.results);
    }
}

/// The drive during the timing and range checks: a sine on each coil.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Excitation {
    /// Amplitude of both sines, A.
    pub amplitude_a: f64,
    /// Frequency of coil A's sine, Hz.
    pub a_hz: f64,
    /// Frequency of coil B's sine, Hz (different from A's, so both axes move).
    pub b_hz: f64,
}

/// The conformance drive: well below the current and power limits, away from the mirror's
/// resonance, both sines starting at zero.
pub const EXCITATION: Excitation = Excitation {
    amplitude_a: 0.3,
    a_hz: 40.0,
    b_hz: 80.0,
};

impl Excitation {
    /// The coil currents of period `k` at a period of `period_s`.
    #[must_use]
    pub fn at(&self, k: u64, period_s: f64) -> ActuatorPair {
        let t_s = k as f64 * period_s;
        let sine = |hz: f64| self.amplitude_a * (std::f64::consts::TAU * hz * t_s).sin();
        ActuatorPair {
            a: sine(self.a_hz),
            b: sine(self.b_hz),
        }
    }
}

impl std::fmt::Display for Excitation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} A sines at {} Hz (coil A) and {} Hz (coil B)",
            self.amplitude_a, self.a_hz, self.b_hz
        )
    }
}

/// The row of a run stopped by `signal` before its checks were done: failed, so a run cut
/// short never passes.
#[must_use]
pub fn ended_early(signal: &str) -> CheckResult {
    CheckResult {
        name: RUN_ENDED_EARLY,
        node: "-",
        outcome: Outcome::Failed,
        detail: format!("interrupted by {signal}: the checks after the rows above did not run"),
        time_s: 0.0,
    }
}

/// The name of [`ended_early`]'s row.
pub const RUN_ENDED_EARLY: &str = "run_ended_early";

/// Runs the mirror node's checks and, when given, the sensor's, as `selection` says. Each
/// result is pushed onto `results` as it is known, and `on_result` told of them all then (the
/// caller writes them as they come: a run cut short keeps what it found).
pub async fn run_checks(
    mirror: &mut MirrorLink,
    mut sensor: Option<&mut SensorLink>,
    selection: &Selection,
    results: &mut Vec<CheckResult>,
    on_result: &mut dyn FnMut(&[CheckResult]),
) {
    let mut verdicts = Verdicts {
        selection,
        results,
        on_result,
    };
    let mut k = 0u64;
    // Timing, sequence, range, status (and the sensor stream alongside), under the drive.
    let start = Instant::now();
    let allowance = mirror.total_allowance();
    let period_s = mirror.period_s();
    let mut timing = AnswerTiming::default();
    let mut first_gap: Option<String> = None;
    let mut angles_seen = AngleRange::default();
    while k < EXCHANGES {
        let t0 = Instant::now();
        let command = EXCITATION.at(k, period_s);
        let wait = allowance.saturating_mul(LATE_WAIT_ALLOWANCES);
        let exchange = match sensor.as_deref_mut() {
            Some(sensor) => tokio::select! {
                r = mirror.exchange_lockstep_any_counter(k, command, wait) => r,
                e = sensor.pump() => Err(e),
            },
            None => mirror.exchange_lockstep_any_counter(k, command, wait).await,
        };
        match exchange {
            Ok((offset, angles)) => {
                timing.answered(k, t0.elapsed(), allowance);
                if offset != 0 && first_gap.is_none() {
                    first_gap = Some(format!(
                        "period {k}: AngleReading counter {}, expected {}",
                        (k as u16).wrapping_add(offset),
                        k as u16
                    ));
                }
                angles_seen.add(k, angles);
            }
            Err(error) => {
                timing.lost = Some(format!("period {k}: {error}"));
                break;
            }
        }
        k += 1;
    }
    if selection.runs("answers_in_time") {
        verdicts.add(
            "answers_in_time",
            timing.passed(),
            timing.detail(k),
            start.elapsed().as_secs_f64(),
        );
    }
    let counters = mirror.counters();
    // A reading behind the one awaited is as much out of sequence as one ahead of it.
    let out_of_sequence = counters.angle_sequence_gaps + counters.late_readings;
    let in_sequence = out_of_sequence == 0 && counters.angle_readings >= k;
    verdicts.add_if_selected(
        "angle_sequence_gapless",
        in_sequence,
        match first_gap {
            Some(first) if !in_sequence => format!(
                "{out_of_sequence} of {} readings out of sequence; first: {first}",
                counters.angle_readings
            ),
            _ => format!(
                "{} readings, {out_of_sequence} out of sequence",
                counters.angle_readings
            ),
        },
    );
    let in_range = angles_seen.verdict(k);
    verdicts.add_if_selected(
        "angles_in_range",
        in_range.is_ok(),
        in_range.unwrap_or_else(|e| e),
    );
    let statuses = mirror.counters().status_frames;
    verdicts.add_if_selected(
        "status_frames",
        statuses > 0,
        if statuses > 0 {
            format!("{statuses} status frames in {k} periods")
        } else {
            format!("no Status frame from the node in {k} periods (a heartbeat expected)")
        },
    );
    if verdicts.start("over_current_fault") {
        k = over_current_fault(mirror, k, &mut verdicts).await;
    }
    if verdicts.start("survives_malformed_frames") {
        k = survives_malformed_frames(mirror, k, &mut verdicts).await;
    }
    // Garbage SLCAN lines (SLCAN only: a line of bytes).
    let slcan = mirror.can_link_mut().bytes_written().is_some();
    if slcan && verdicts.start("survives_garbage_slcan_lines") {
        let t0 = Instant::now();
        if let Some(survived) = survive_garbage_lines(mirror, k).await {
            verdicts.add(
                "survives_garbage_slcan_lines",
                survived.is_ok(),
                survived.unwrap_or_else(|e| e),
                t0.elapsed().as_secs_f64(),
            );
        }
    }
    // Sensor stream.
    if let Some(sensor) = sensor {
        let _ = sensor.drain(Duration::from_millis(100)).await;
        for (name, passed, detail) in sensor_checks(sensor) {
            verdicts.add_if_selected(name, passed, detail);
        }
        if let Some(link) = sensor.ild_link_mut()
            && verdicts.start("sensor_survives_bad_commands")
        {
            let t0 = Instant::now();
            let survived = survive_bad_commands(link).await;
            verdicts.add(
                "sensor_survives_bad_commands",
                survived.is_ok(),
                survived.unwrap_or_else(|e| e),
                t0.elapsed().as_secs_f64(),
            );
        }
    }
    if verdicts.start("link_timeout_fault") {
        link_timeout_fault(mirror, &mut verdicts).await;
    } else {
        // The node is still in its session: the zero command it acknowledges ends it.
        let _ = mirror.end_session(k).await;
    }
}

/// `over_current_fault` from period `k`: [`OVER_CURRENT_PERIODS`] periods at
/// [`OVER_CURRENT_A`], as many at zero; returns the next period.
async fn over_current_fault(
    mirror: &mut MirrorLink,
    mut k: u64,
    verdicts: &mut Verdicts<'_>,
) -> u64 {
    let t0 = Instant::now();
    let faults_before = fault_count(mirror, FaultKind::OverCurrent);
    let big = ActuatorPair {
        a: OVER_CURRENT_A,
        b: -OVER_CURRENT_A,
    };
    let mut over_current_error = None;
    for _ in 0..OVER_CURRENT_PERIODS {
        if let Err(error) = exchange(mirror, k, big).await {
            over_current_error = Some(error.to_string());
            break;
        }
        k += 1;
    }
    for _ in 0..OVER_CURRENT_PERIODS {
        if exchange(mirror, k, ActuatorPair::default()).await.is_ok() {
            k += 1;
        }
    }
    let raised = fault_count(mirror, FaultKind::OverCurrent) > faults_before;
    verdicts.add(
        "over_current_fault",
        raised && over_current_error.is_none(),
        over_current_error.unwrap_or_else(|| {
            if raised {
                format!("OverCurrent fault frame after a {OVER_CURRENT_A} A command")
            } else {
                format!(
                    "no OverCurrent fault frame after {OVER_CURRENT_PERIODS} periods at {OVER_CURRENT_A} A and {OVER_CURRENT_PERIODS} at zero (one expected)"
                )
            }
        }),
        t0.elapsed().as_secs_f64(),
    );
    k
}

/// `survives_malformed_frames` at period `k`; returns the next period.
async fn survives_malformed_frames(
    mirror: &mut MirrorLink,
    k: u64,
    verdicts: &mut Verdicts<'_>,
) -> u64 {
    let t0 = Instant::now();
    let survived = match mirror.send_malformed(k).await {
        Err(error) => Err(format!("sending malformed input: {error}")),
        Ok(sent) => match exchange(mirror, k, ActuatorPair::default()).await {
            Ok(()) => Ok(format!("{sent}; still answering")),
            Err(error) => Err(format!("{sent}; then: {error}")),
        },
    };
    // The malformed check's exchange used period k.
    let next = if survived.is_ok() { k + 1 } else { k };
    verdicts.add(
        "survives_malformed_frames",
        survived.is_ok(),
        survived.unwrap_or_else(|e| e),
        t0.elapsed().as_secs_f64(),
    );
    next
}

/// `link_timeout_fault`, last: the host falls silent and waits for the node's fault.
async fn link_timeout_fault(mirror: &mut MirrorLink, verdicts: &mut Verdicts<'_>) {
    let t0 = Instant::now();
    let timeout = mirror.await_link_timeout_fault().await;
    let allowance = mirror.total_allowance();
    verdicts.add(
        "link_timeout_fault",
        timeout.is_ok(),
        timeout.unwrap_or_else(|error| match error {
            LoopError::LinkTimeout { waited, .. } => format!(
                "no LinkTimeout fault from the node within {waited:?} of the host falling silent (twice the watchdog's {allowance:?})"
            ),
            other => format!("no LinkTimeout fault from the node after the host fell silent: {other}"),
        }),
        t0.elapsed().as_secs_f64(),
    );
}

/// One lockstep exchange of the checks after the timing check: period `k` with `command`, any
/// counter accepted (the sequence check has its verdict), within the watchdog's allowance.
async fn exchange(mirror: &mut MirrorLink, k: u64, command: ActuatorPair) -> Result<(), LoopError> {
    let wait = mirror.total_allowance();
    mirror
        .exchange_lockstep_any_counter(k, command, wait)
        .await
        .map(drop)
}

/// How the timing check's answers came: the late ones (after the allowance, but within
/// [`LATE_WAIT_ALLOWANCES`] of it) and a lost one (never, which ends the check).
#[derive(Debug, Default)]
struct AnswerTiming {
    slowest: Duration,
    late: u64,
    first_late: Option<String>,
    lost: Option<String>,
}

impl AnswerTiming {
    fn answered(&mut self, k: u64, took: Duration, allowance: Duration) {
        self.slowest = self.slowest.max(took);
        if took > allowance {
            self.late += 1;
            self.first_late.get_or_insert_with(|| {
                format!(
                    "period {k}: AngleReading {took:.3?} after its Step, beyond the watchdog's {allowance:?} allowance"
                )
            });
        }
    }

    fn passed(&self) -> bool {
        self.late == 0 && self.lost.is_none()
    }

    fn detail(&self, answered: u64) -> String {
        let late = self
            .first_late
            .as_ref()
            .map(|first| format!("{} of {answered} answers late; first: {first}", self.late));
        match (&self.lost, late) {
            (Some(lost), Some(late)) => format!("{lost}; {late}"),
            (Some(lost), None) => lost.clone(),
            (None, Some(late)) => late,
            (None, None) => format!("{answered} steps answered, slowest {:?}", self.slowest),
        }
    }
}

/// The angles the timing check saw: the first out of the mirror's range, and each axis's
/// extremes (the drive must move both).
#[derive(Debug)]
struct AngleRange {
    out_of_range: Option<String>,
    min_rad: SensingPair,
    max_rad: SensingPair,
}

impl Default for AngleRange {
    fn default() -> Self {
        AngleRange {
            out_of_range: None,
            min_rad: SensingPair {
                alpha: f64::INFINITY,
                beta: f64::INFINITY,
            },
            max_rad: SensingPair {
                alpha: f64::NEG_INFINITY,
                beta: f64::NEG_INFINITY,
            },
        }
    }
}

impl AngleRange {
    fn limit_rad() -> f64 {
        FULL_RANGE_DEG.to_radians() * RANGE_MARGIN
    }

    fn add(&mut self, k: u64, angles: SensingPair) {
        let limit_rad = Self::limit_rad();
        let inside = |angle: f64| angle.is_finite() && angle.abs() <= limit_rad;
        if self.out_of_range.is_none() && !(inside(angles.alpha) && inside(angles.beta)) {
            self.out_of_range = Some(format!(
                "period {k}: alpha {:.3} mrad, beta {:.3} mrad, beyond the mirror's +-{:.3} mrad",
                angles.alpha * 1e3,
                angles.beta * 1e3,
                limit_rad * 1e3
            ));
        }
        self.min_rad.alpha = self.min_rad.alpha.min(angles.alpha);
        self.min_rad.beta = self.min_rad.beta.min(angles.beta);
        self.max_rad.alpha = self.max_rad.alpha.max(angles.alpha);
        self.max_rad.beta = self.max_rad.beta.max(angles.beta);
    }

    /// `Ok` (what was seen) when every reading was in range and both axes swung by at least
    /// [`MIN_SWING_RAD`] over `readings` readings; `Err` says what was expected and seen.
    fn verdict(&self, readings: u64) -> Result<String, String> {
        if let Some(out) = &self.out_of_range {
            return Err(out.clone());
        }
        if readings == 0 {
            return Err("no angle reading to check".to_owned());
        }
        let alpha = self.max_rad.alpha - self.min_rad.alpha;
        let beta = self.max_rad.beta - self.min_rad.beta;
        let swing = format!(
            "alpha swung {:.3} mrad, beta {:.3} mrad peak to peak under {EXCITATION}",
            alpha * 1e3,
            beta * 1e3
        );
        if alpha < MIN_SWING_RAD || beta < MIN_SWING_RAD {
            return Err(format!(
                "{swing}: at least {:.3} mrad each expected (frozen or unresponsive angles)",
                MIN_SWING_RAD * 1e3
            ));
        }
        Ok(format!(
            "all within +-{:.3} mrad; {swing}",
            Self::limit_rad() * 1e3
        ))
    }
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
    Some(match exchange(mirror, k, ActuatorPair::default()).await {
        Ok(()) => Ok(format!("{sent}; still answering")),
        Err(error) => Err(format!("{sent}; then the next exchange failed: {error}")),
    })
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

/// The sensor stream's checks: (name, passed, what was seen).
fn sensor_checks(sensor: &SensorLink) -> [(&'static str, bool, String); 3] {
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

/// The pass/fail table, then one line per failed check on what to look at on the bench.
#[must_use]
pub fn table(results: &[CheckResult]) -> String {
    let mut text = format!("{:<6} {:<28} {:<6} detail\n", "node", "check", "result");
    for r in results {
        let result = match r.outcome {
            Outcome::Passed => "PASS",
            Outcome::Failed => "FAIL",
            Outcome::Skipped => "SKIP",
        };
        let _ = writeln!(
            text,
            "{:<6} {:<28} {:<6} {}",
            r.node, r.name, result, r.detail
        );
    }
    let count = |outcome| results.iter().filter(|r| r.outcome == outcome).count();
    let _ = write!(
        text,
        "{} checks, {} passed, {} failed, {} skipped",
        results.len(),
        count(Outcome::Passed),
        count(Outcome::Failed),
        count(Outcome::Skipped)
    );
    for r in results.iter().filter(|r| r.failed()) {
        if let Some(check) = spec(r.name) {
            let _ = write!(
                text,
                "\non the bench, {}: look at {}",
                r.name, check.bench_hint
            );
        }
    }
    text
}

/// The results as JUnit XML (one test suite, one test case per check).
#[must_use]
pub fn junit_xml(results: &[CheckResult]) -> String {
    let failures = results.iter().filter(|r| r.failed()).count();
    let skipped = results
        .iter()
        .filter(|r| r.outcome == Outcome::Skipped)
        .count();
    let total: f64 = results.iter().map(|r| r.time_s).sum();
    let mut xml = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites>\n  <testsuite name=\"scanhil-conformance\" tests=\"{}\" failures=\"{failures}\" errors=\"0\" skipped=\"{skipped}\" time=\"{total:.6}\">\n",
        results.len()
    );
    for r in results {
        let _ = write!(
            xml,
            "    <testcase classname=\"{}\" name=\"{}\" time=\"{:.6}\"",
            r.node, r.name, r.time_s
        );
        let detail = escape(&r.detail);
        let _ = match r.outcome {
            Outcome::Passed => writeln!(xml, "><system-out>{detail}</system-out></testcase>"),
            Outcome::Failed => writeln!(xml, "><failure message=\"{detail}\"/></testcase>"),
            Outcome::Skipped => writeln!(xml, "><skipped message=\"{detail}\"/></testcase>"),
        };
    }
    xml + "  </testsuite>\n</testsuites>\n"
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    const PERIOD_S: f64 = 5e-5;

    #[test]
    fn the_drive_starts_at_zero_and_stays_within_its_amplitude() {
        assert_eq!(EXCITATION.at(0, PERIOD_S), ActuatorPair::default());
        let peak = (0..EXCHANGES)
            .map(|k| EXCITATION.at(k, PERIOD_S))
            .map(|c| c.a.abs().max(c.b.abs()))
            .fold(0.0, f64::max);
        assert!(peak <= EXCITATION.amplitude_a && peak > 0.99 * EXCITATION.amplitude_a);
    }

    fn verdict(angles: impl Fn(u64) -> SensingPair) -> Result<String, String> {
        let mut range = AngleRange::default();
        for k in 0..100 {
            range.add(k, angles(k));
        }
        range.verdict(100)
    }

    #[test]
    fn angles_pass_only_in_range_and_moving_on_both_axes() {
        let swing = |k: u64| (k as f64 * 0.1).sin() * 5e-3;
        let moving = verdict(|k| SensingPair {
            alpha: swing(k),
            beta: -swing(k),
        });
        assert!(moving.is_ok_and(|seen| seen.contains("alpha swung")));
        let frozen = verdict(|_| SensingPair {
            alpha: 1e-3,
            beta: 1e-3,
        });
        assert!(frozen.is_err_and(|why| why.contains("alpha swung 0.000 mrad, beta 0.000 mrad")));
        let one_axis = verdict(|k| SensingPair {
            alpha: swing(k),
            beta: 0.0,
        });
        assert!(one_axis.is_err_and(|why| why.contains("beta 0.000 mrad")));
        let beyond = verdict(|k| SensingPair {
            alpha: if k == 42 { 0.05 } else { swing(k) },
            beta: swing(k),
        });
        assert!(beyond.is_err_and(|why| why.starts_with("period 42: alpha 50.000 mrad")));
        let not_finite = verdict(|k| SensingPair {
            alpha: swing(k),
            beta: if k == 7 { f64::NAN } else { swing(k) },
        });
        assert!(not_finite.is_err_and(|why| why.starts_with("period 7:")));
    }

    #[test]
    fn a_late_answer_is_counted_and_named_and_fails_the_timing() {
        let allowance = Duration::from_millis(500);
        let mut timing = AnswerTiming::default();
        timing.answered(0, Duration::from_millis(3), allowance);
        assert!(timing.passed());
        timing.answered(1, Duration::from_millis(750), allowance);
        timing.answered(2, Duration::from_millis(600), allowance);
        assert!(!timing.passed());
        let detail = timing.detail(3);
        assert!(
            detail.starts_with("2 of 3 answers late; first: period 1: AngleReading 750.000ms"),
            "{detail}"
        );
    }
}
