//! Conformance checks of a mirror node and a sensor node, real or emulated, against the loop
//! protocol. Each check is independent of the others' verdicts and says what it saw.
//!
//! Mirror node, over its CAN link, in lockstep (the host's Step frames advance the node) or in
//! real time (`--timing realtime`: the node runs on its own clock and sends a reading every
//! period, which the host answers with the next period's coil command; no Step frame):
//! - `answers_in_time` (lockstep): every Step is answered by an AngleReading within the
//!   watchdog's allowance (a later answer is waited for up to twice that, and counted late).
//! - `readings_on_time` (real time): no silence between two readings longer than the
//!   watchdog's allowance (a later reading is waited for up to twice that, and counted late);
//!   the intervals as min / median / p99 / max ([`reading_clock`]).
//! - `reading_rate` (real time): the node's own period, measured from the readings' counters
//!   and arrivals, within [`reading_clock::RATE_TOLERANCE`] of the declared rate.
//! - `angle_sequence_gapless`: AngleReading sequence counters follow the Step counter
//!   (lockstep), or follow each other with no reading missed (real time).
//! - `angles_in_range`: under the drive (sines on both coils), angles finite and within
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
//! The timing checks drive the mirror: [`EXCITATION`] for 2 500 exchanges in lockstep,
//! [`REALTIME_EXCITATION`] for at least [`REALTIME_DRIVE_S`] of readings in real time (the
//! rate needs a span).
//!
//! Sensor node (ILD stream, while the mirror node is driven):
//! - `sensor_values_decode`: the stream decodes with no resynchronisation.
//! - `sensor_counter_gapless`: measured-value counters without gaps.
//! - `sensor_values_in_range`: every value a distance or a known error code.
//! - `sensor_survives_bad_commands` (ILD line only): unknown commands, wrong parameters and an
//!   overlong line are each refused with an `Exx` error, and `GETINFO` is still answered with
//!   a measuring range. The stream is stopped (`OUTPUT NONE`) around the check and restarted
//!   after it.

use std::time::{Duration, Instant};

use scanhil_protocol::link::LinkError;
use scanhil_protocol::message::FaultKind;
use scanhil_protocol::plant_units::{ActuatorPair, SensingPair};
use scanhil_protocol::slcan::SlcanMessage;

use super::check_selection::{Decision, Selection, spec};
use super::host_loop::coil_command_frame;
use super::loop_error::LoopError;
use super::mirror_link::MirrorLink;
use super::scenario::TimingMode;
use super::sensor_link::SensorLink;

mod answer_timing;
mod excitation;
pub mod reading_clock;
mod results;
mod sensor;

use answer_timing::{AnswerTiming, LATE_WAIT_ALLOWANCES};
use excitation::AngleRange;
pub use excitation::{EXCITATION, Excitation, REALTIME_EXCITATION};
use reading_clock::ReadingClock;
pub use results::{CheckResult, Outcome, RUN_ENDED_EARLY, ended_early, junit_xml, table};

/// Garbage SLCAN lines for `survives_garbage_slcan_lines`, with what each is.
const GARBAGE_SLCAN_LINES: [(&[u8], &str); 5] = [
    (b"xyz", "unknown command `xyz`"),
    (b"t12", "truncated frame `t12`"),
    (b"t1008010203", "frame shorter than its DLC"),
    (b"\xff\xfe\x00\x80", "bytes outside ASCII"),
    (&[b'A'; 200], "a 200-byte line"),
];

/// Exchanges used by the timing and range checks (in real time, at least).
const EXCHANGES: u64 = 2_500;
/// Real time: the timing and range checks take at least this much of the node's readings, s.
pub const REALTIME_DRIVE_S: f64 = 1.0;
/// Real time: how long the node's first reading may take after the channel opened (its clock
/// starting), at least.
const FIRST_READING_WAIT: Duration = Duration::from_secs(1);
/// A coil current no amplifier accepts, A.
const OVER_CURRENT_A: f64 = 8.0;
/// Periods commanded at [`OVER_CURRENT_A`], then at zero, in the over-current check.
const OVER_CURRENT_PERIODS: u32 = 3;

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

    /// [`Self::add`] of a verdict given as `Ok(detail)` or `Err(detail)`.
    fn add_result(&mut self, name: &'static str, verdict: Result<String, String>, time_s: f64) {
        let passed = verdict.is_ok();
        self.add(name, passed, verdict.unwrap_or_else(|e| e), time_s);
    }

    /// The verdict of a check of the timing phase, which always runs: kept when selected.
    fn add_if_selected(&mut self, name: &'static str, passed: bool, detail: String) {
        if self.selection.runs(name) {
            self.add(name, passed, detail, 0.0);
        }
    }

    /// [`Self::add_if_selected`] of a verdict given as `Ok(detail)` or `Err(detail)`.
    fn add_verdict(&mut self, name: &'static str, verdict: Result<String, String>) {
        if self.selection.runs(name) {
            self.add_result(name, verdict, 0.0);
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

/// The checks' session with the mirror node: one exchange a period, as the node is clocked.
struct Session<'m> {
    mirror: &'m mut MirrorLink,
    timing: TimingMode,
    /// Lockstep: the period to step next. Real time: the reading awaited next.
    next: u64,
}

/// One exchange's reading.
struct Exchanged {
    /// The reading's period (real time: its counter, unwrapped).
    period: u64,
    /// Lockstep: how far its counter is ahead of the Step's (0: in sequence). Real time: the
    /// readings missed before it.
    offset: u64,
    angles: SensingPair,
    /// When it was on the bus as the link knows it.
    arrival: tokio::time::Instant,
}

impl Session<'_> {
    /// One period, waiting at most `wait` for the reading. Lockstep: CoilCommand(k) with
    /// `command(k)` and Step(k) for the next period k, then the first AngleReading not older
    /// than k. Real time: the next reading j (not older than the one awaited), answered with
    /// CoilCommand(j + 1) at `command(j + 1)`.
    async fn exchange(
        &mut self,
        command: impl Fn(u64) -> ActuatorPair,
        wait: Duration,
    ) -> Result<Exchanged, LoopError> {
        let k = self.next;
        match self.timing {
            TimingMode::Lockstep => {
                let (offset, angles) = self
                    .mirror
                    .exchange_lockstep_any_counter(k, command(k), wait)
                    .await?;
                self.next = k + 1;
                Ok(Exchanged {
                    period: k,
                    offset: u64::from(offset),
                    angles,
                    arrival: self.mirror.last_arrival(),
                })
            }
            TimingMode::Realtime => {
                let (j, angles) = self.mirror.next_reading_within(k, wait).await?;
                let arrival = self.mirror.last_arrival();
                let next = j + 1;
                let period_s = self.mirror.period_s();
                let frame = coil_command_frame(next, command(next), (next + 1) as f64 * period_s)?;
                self.mirror.send_period(next, &[frame]).await?;
                self.next = next;
                Ok(Exchanged {
                    period: j,
                    offset: j - k,
                    angles,
                    arrival,
                })
            }
        }
    }

    /// Runs `work` (checks of the sensor, on its own line) while, in real time, the node's
    /// readings go on being answered with zero current, so its watchdog stays fed; a lockstep
    /// node waits for its next Step meanwhile. A node that stops answering is left to the
    /// checks after.
    async fn while_fed<T>(&mut self, work: impl Future<Output = T>) -> T {
        if self.timing == TimingMode::Lockstep {
            return work.await;
        }
        tokio::pin!(work);
        loop {
            tokio::select! {
                biased;
                done = &mut work => return done,
                fed = self.exchange_at(ActuatorPair::default()) => {
                    if fed.is_err() {
                        return work.await;
                    }
                }
            }
        }
    }

    /// [`Self::exchange`] at a steady `command`, within the watchdog's allowance. In real time
    /// the readings that came while the host was busy elsewhere are passed over first: the
    /// command answers the newest, so the node applies it at its next period (a node on its
    /// own clock applies the newest command it has; a burst of answers to old readings would
    /// leave only the last).
    async fn exchange_at(&mut self, command: ActuatorPair) -> Result<(), LoopError> {
        if self.timing == TimingMode::Realtime {
            while let Some((j, _)) = self.mirror.try_reading(self.next)? {
                self.next = j + 1;
            }
        }
        let wait = self.mirror.total_allowance();
        self.exchange(|_| command, wait).await.map(drop)
    }
}

/// What the drive of the timing and range checks saw.
struct Drive {
    /// Exchanges done.
    exchanges: u64,
    /// How the readings came, as the node's timing measures it.
    timing: DriveTiming,
    angles: AngleRange,
}

/// How the drive's readings came.
enum DriveTiming {
    /// Lockstep: how each Step was answered, and the first reading out of sequence.
    Lockstep {
        answers: AnswerTiming,
        first_gap: Option<String>,
    },
    /// Real time: when each reading came.
    Realtime(ReadingClock),
}

/// Runs the mirror node's checks and, when given, the sensor's, as `selection` says (the
/// node's timing included). Each result is pushed onto `results` as it is known, and
/// `on_result` told of them all then (the caller writes them as they come: a run cut short
/// keeps what it found).
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
    let mut session = Session {
        mirror,
        timing: selection.timing,
        next: 0,
    };
    // Timing, sequence, range, status (and the sensor stream alongside), under the drive.
    let start = Instant::now();
    let drive = drive(&mut session, sensor.as_deref_mut()).await;
    let mirror = &mut *session.mirror;
    let counters = mirror.counters();
    match drive.timing {
        DriveTiming::Lockstep { answers, first_gap } => {
            if selection.runs("answers_in_time") {
                verdicts.add(
                    "answers_in_time",
                    answers.passed(),
                    answers.detail(drive.exchanges),
                    start.elapsed().as_secs_f64(),
                );
            }
            // A reading behind the one awaited is as much out of sequence as one ahead of it.
            let out_of_sequence = counters.angle_sequence_gaps + counters.late_readings;
            let in_sequence = out_of_sequence == 0 && counters.angle_readings >= drive.exchanges;
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
        }
        DriveTiming::Realtime(readings) => {
            if selection.runs("readings_on_time") {
                let on_time = readings.on_time();
                verdicts.add_result("readings_on_time", on_time, start.elapsed().as_secs_f64());
            }
            verdicts.add_verdict("reading_rate", readings.rate());
            verdicts.add_verdict(
                "angle_sequence_gapless",
                gapless_in_real_time(&readings, counters.late_readings),
            );
        }
    }
    verdicts.add_verdict("angles_in_range", drive.angles.verdict(drive.exchanges));
    let statuses = counters.status_frames;
    verdicts.add_if_selected(
        "status_frames",
        statuses > 0,
        if statuses > 0 {
            format!("{statuses} status frames in {} periods", drive.exchanges)
        } else {
            format!(
                "no Status frame from the node in {} periods (a heartbeat expected)",
                drive.exchanges
            )
        },
    );
    if verdicts.start("over_current_fault") {
        over_current_fault(&mut session, &mut verdicts).await;
    }
    if verdicts.start("survives_malformed_frames") {
        survives_malformed_frames(&mut session, &mut verdicts).await;
    }
    // Garbage SLCAN lines (SLCAN only: a line of bytes).
    let slcan = session.mirror.can_link_mut().bytes_written().is_some();
    if slcan && verdicts.start("survives_garbage_slcan_lines") {
        let t0 = Instant::now();
        if let Some(survived) = survive_garbage_lines(&mut session).await {
            verdicts.add_result(
                "survives_garbage_slcan_lines",
                survived,
                t0.elapsed().as_secs_f64(),
            );
        }
    }
    // Sensor stream.
    if let Some(sensor) = sensor {
        match session.timing {
            // What is still in flight after the drive.
            TimingMode::Lockstep => {
                let _ = sensor.drain(Duration::from_millis(100)).await;
            }
            // A node on its own clock keeps the sensor streaming: what a moment more brings.
            TimingMode::Realtime => {
                let more = tokio::time::timeout(Duration::from_millis(100), sensor.pump());
                let _ = session.while_fed(more).await;
            }
        }
        for (name, passed, detail) in sensor::sensor_checks(sensor) {
            verdicts.add_if_selected(name, passed, detail);
        }
        if let Some(link) = sensor.ild_link_mut()
            && verdicts.start("sensor_survives_bad_commands")
        {
            let t0 = Instant::now();
            let survived = session.while_fed(sensor::survive_bad_commands(link)).await;
            verdicts.add_result(
                "sensor_survives_bad_commands",
                survived,
                t0.elapsed().as_secs_f64(),
            );
        }
    }
    if verdicts.start("link_timeout_fault") {
        link_timeout_fault(session.mirror, &mut verdicts).await;
    } else {
        // The node is still in its session: the zero command it acknowledges ends it.
        let _ = session.mirror.end_session(session.next).await;
    }
}

/// The drive of the timing and range checks: [`EXCITATION`] for [`EXCHANGES`] exchanges (in
/// real time [`REALTIME_EXCITATION`] for at least [`REALTIME_DRIVE_S`] of readings), the
/// sensor's stream read alongside.
/// Stops at the first reading lost (none within twice the watchdog's allowance).
async fn drive(session: &mut Session<'_>, mut sensor: Option<&mut SensorLink>) -> Drive {
    let allowance = session.mirror.total_allowance();
    let period_s = session.mirror.period_s();
    let (exchanges, excitation) = match session.timing {
        TimingMode::Lockstep => (EXCHANGES, EXCITATION),
        TimingMode::Realtime => (
            EXCHANGES.max((REALTIME_DRIVE_S / period_s).ceil() as u64),
            REALTIME_EXCITATION,
        ),
    };
    let timing = match session.timing {
        TimingMode::Lockstep => DriveTiming::Lockstep {
            answers: AnswerTiming::default(),
            first_gap: None,
        },
        TimingMode::Realtime => {
            DriveTiming::Realtime(ReadingClock::new(period_s, allowance.as_secs_f64()))
        }
    };
    let mut drive = Drive {
        exchanges: 0,
        timing,
        angles: AngleRange::new(excitation),
    };
    let wait = allowance.saturating_mul(LATE_WAIT_ALLOWANCES);
    let mut first_arrival = None;
    while drive.exchanges < exchanges {
        let t0 = Instant::now();
        let expected = session.next;
        let command = |k: u64| excitation.at(k, period_s);
        let wait = match session.timing {
            TimingMode::Realtime if drive.exchanges == 0 => wait.max(FIRST_READING_WAIT),
            _ => wait,
        };
        let exchange = match sensor.as_deref_mut() {
            Some(sensor) => tokio::select! {
                r = session.exchange(command, wait) => r,
                e = sensor.pump() => Err(e),
            },
            None => session.exchange(command, wait).await,
        };
        let reading = match exchange {
            Ok(reading) => reading,
            Err(error) => {
                let lost = Some(format!("period {expected}: {error}"));
                match &mut drive.timing {
                    DriveTiming::Lockstep { answers, .. } => answers.lost = lost,
                    DriveTiming::Realtime(readings) => readings.lost = lost,
                }
                break;
            }
        };
        match &mut drive.timing {
            DriveTiming::Lockstep { answers, first_gap } => {
                answers.answered(expected, t0.elapsed(), allowance);
                if reading.offset != 0 && first_gap.is_none() {
                    *first_gap = Some(format!(
                        "period {expected}: AngleReading counter {}, expected {}",
                        (expected as u16).wrapping_add(reading.offset as u16),
                        expected as u16
                    ));
                }
            }
            DriveTiming::Realtime(readings) => {
                let first = *first_arrival.get_or_insert(reading.arrival);
                let arrival_s = reading.arrival.saturating_duration_since(first);
                readings.arrived(reading.period, expected, arrival_s.as_secs_f64());
            }
        }
        drive.angles.add(reading.period, reading.angles);
        drive.exchanges += 1;
    }
    drive
}

/// `angle_sequence_gapless` in real time: no reading missed, none behind the one awaited.
fn gapless_in_real_time(readings: &ReadingClock, behind: u64) -> Result<String, String> {
    let (missed, first) = readings.missed();
    let taken = readings.readings();
    if missed == 0 && behind == 0 && taken > 0 {
        return Ok(format!("{taken} readings, none missed or out of sequence"));
    }
    let mut seen = format!("{taken} readings, {missed} missed, {behind} behind the one awaited");
    if let Some(first) = first {
        seen += &format!("; first missed: {first}");
    }
    Err(seen)
}

/// `over_current_fault`: [`OVER_CURRENT_PERIODS`] periods at [`OVER_CURRENT_A`], as many at
/// zero.
async fn over_current_fault(session: &mut Session<'_>, verdicts: &mut Verdicts<'_>) {
    let t0 = Instant::now();
    let faults_before = fault_count(session.mirror, FaultKind::OverCurrent);
    let big = ActuatorPair {
        a: OVER_CURRENT_A,
        b: -OVER_CURRENT_A,
    };
    let mut over_current_error = None;
    for _ in 0..OVER_CURRENT_PERIODS {
        if let Err(error) = session.exchange_at(big).await {
            over_current_error = Some(error.to_string());
            break;
        }
    }
    for _ in 0..OVER_CURRENT_PERIODS {
        let _ = session.exchange_at(ActuatorPair::default()).await;
    }
    let raised = fault_count(session.mirror, FaultKind::OverCurrent) > faults_before;
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
}

/// `survives_malformed_frames`: a Step and a CoilCommand with short payloads, then one
/// exchange that must be answered.
async fn survives_malformed_frames(session: &mut Session<'_>, verdicts: &mut Verdicts<'_>) {
    let t0 = Instant::now();
    let survived = match session.mirror.send_malformed(session.next).await {
        Err(error) => Err(format!("sending malformed input: {error}")),
        Ok(sent) => match session.exchange_at(ActuatorPair::default()).await {
            Ok(()) => Ok(format!("{sent}; still answering")),
            Err(error) => Err(format!("{sent}; then: {error}")),
        },
    };
    verdicts.add_result(
        "survives_malformed_frames",
        survived,
        t0.elapsed().as_secs_f64(),
    );
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

/// Sends the garbage lines, each followed by one exchange (a node on its own clock keeps its
/// watchdog fed), then checks the node still answers. `None` on a link without SLCAN lines
/// (SocketCAN).
async fn survive_garbage_lines(session: &mut Session<'_>) -> Option<Result<String, String>> {
    let mut answers = Vec::new();
    for (line, what) in GARBAGE_SLCAN_LINES {
        let answer = match session.mirror.can_link_mut().send_raw_line(line).await {
            Err(LinkError::Unsupported { .. }) => return None,
            Err(error) => return Some(Err(format!("sending {what}: {error}"))),
            Ok(Some(SlcanMessage::Nack)) => "BEL".to_owned(),
            Ok(Some(other)) => format!("{other:?}"),
            Ok(None) => "no answer".to_owned(),
        };
        answers.push(format!("{what}: {answer}"));
        if session.timing == TimingMode::Realtime
            && let Err(error) = session.exchange_at(ActuatorPair::default()).await
        {
            let sent = answers.join(", ");
            return Some(Err(format!(
                "{sent}; then the next exchange failed: {error}"
            )));
        }
    }
    let sent = answers.join(", ");
    Some(match session.exchange_at(ActuatorPair::default()).await {
        Ok(()) => Ok(format!("{sent}; still answering")),
        Err(error) => Err(format!("{sent}; then the next exchange failed: {error}")),
    })
}

fn fault_count(mirror: &MirrorLink, kind: FaultKind) -> usize {
    mirror
        .events()
        .iter()
        .filter(|e| e.fault == Some(kind))
        .count()
}
