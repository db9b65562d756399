//! The real-time loop, controller side: the emulator (or a real mirror node) is the clock
//! master and sends AngleReading(j) every period; the controller answers at once with the
//! command for the next period, CoilCommand(j + 1), which must arrive before that period
//! starts. Measured here: the interval between readings (the master's period as seen after the
//! link) and the answer latency (reading in to command out), as min / median / p99 / max, and
//! overruns (answers slower than one period) and readings that never came.
//!
//! Before the loop this thread gets the scenario's real-time settings (CPU, `SCHED_FIFO`,
//! locked memory: [`HostScheduling`]) and measures the machine's wake-up latency with them.
//! With busy-polling the wait for a reading spins on non-blocking reads of both links instead
//! of waiting on readiness (yielding to the runtime every [`SPINS_PER_YIELD`] spins, so a
//! Ctrl-C is still seen). After the run, each period the emulator stepped without a fresh
//! command is blamed on the side with the larger delay ([`ControllerTiming::attribute`]).

use std::time::{Duration, Instant};

use scanhil_protocol::loop_timing::{
    MissAttribution, MissedDeadline, PeriodRecorder, PeriodStats, attribute_misses,
};
use scanhil_protocol::plant_units::SensingPair;
use scanhil_protocol::scheduling::{self, InEffect};

use super::host_loop::{LoopError, coil_command_frame};
use super::interrupt::Interrupt;
use super::lockstep::LoopRecord;
use super::mirror_link::MirrorLink;
use super::pairing::ArrivalClock;
use super::progress::Progress;
use super::scenario::TimingConfig;
use super::sensor_link::SensorLink;
use crate::scan_controller::ScanController;
use crate::trajectory::Trajectory;

/// Busy-polling: non-blocking reads between two yields to the runtime (its signals and timers).
pub const SPINS_PER_YIELD: u32 = 32;

/// The host's real-time settings as granted, and its wake-up probe.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct HostScheduling {
    /// What the OS granted (warnings for what it refused).
    pub in_effect: InEffect,
    /// The wake-up latency at the control period, measured before the loop.
    pub wakeup_probe: Option<PeriodStats>,
    /// Why the probe could not run, if it could not.
    pub probe_error: Option<String>,
}

impl HostScheduling {
    /// Applies the scenario's host settings to the calling thread (a warning on stderr for each
    /// refusal), then runs the wake-up probe for `timing.probe_s`.
    #[must_use]
    pub fn set_up(timing: &TimingConfig, period_s: f64) -> HostScheduling {
        let in_effect = scheduling::apply(&timing.host_options());
        for warning in &in_effect.warnings {
            eprintln!("scanhil: {warning}");
        }
        let probe = scheduling::wakeup_probe(
            Duration::from_secs_f64(period_s),
            Duration::from_secs_f64(timing.probe_s),
        );
        HostScheduling {
            in_effect,
            wakeup_probe: probe.unwrap_or_default(),
            probe_error: probe
                .err()
                .map(|errno| format!("wake-up probe failed: {errno}")),
        }
    }
}

/// The real-time arguments of `scanhil-emulator serve` for `timing`, running `duration_s`.
#[must_use]
pub fn emulator_args(timing: &TimingConfig, duration_s: f64) -> Vec<String> {
    let options = timing.emulator_options();
    let mut args = vec![
        "--duration-s".into(),
        duration_s.to_string(),
        "--probe-s".into(),
        timing.probe_s.to_string(),
    ];
    if options.busy_poll {
        args.push("--busy-poll".into());
    }
    if let Some(cpu) = options.cpu {
        args.extend(["--cpu".into(), cpu.to_string()]);
    }
    if let Some(priority) = options.sched_fifo_priority {
        args.extend(["--sched-fifo-priority".into(), priority.to_string()]);
    }
    args
}

/// Takes the emulator's list of missed deadlines out of its summary's `timing` (it is long;
/// the report keeps their attribution instead). Empty when there is none or it does not parse.
pub fn take_missed_deadlines(emulator_timing: &mut serde_json::Value) -> Vec<MissedDeadline> {
    emulator_timing
        .as_object_mut()
        .and_then(|timing| timing.remove("missed_deadlines"))
        .and_then(|list| serde_json::from_value(list).ok())
        .unwrap_or_default()
}

/// The target of the loop's jitter: its p99 within this factor of the wake-up probe's p99.
pub const JITTER_TARGET_P99_RATIO: f64 = 2.0;

/// The report's real-time verdicts from both ends' timing (`emulator_timing` is the emulator
/// summary's `timing`; its list of missed deadlines is taken out): `deadline_misses`, who
/// missed and by how much ([`ControllerTiming::attribute`]), and `jitter_against_probe`, the
/// clock master's tick lateness (how late each period started, as cyclictest measures a
/// wake-up) beside its wake-up probe, with the p99 ratio and whether it is within
/// [`JITTER_TARGET_P99_RATIO`]. Null where a side's figures are missing (a real node reports
/// none).
pub fn verdicts(
    controller: &ControllerTiming,
    emulator_timing: &mut serde_json::Value,
    period_s: f64,
) -> serde_json::Value {
    let misses = take_missed_deadlines(emulator_timing);
    let deadline_misses = emulator_timing
        .get("stale_command_periods")
        .map(|_| controller.attribute(&misses, period_s));
    let lateness: Option<PeriodStats> =
        serde_json::from_value(emulator_timing["tick_lateness"].clone()).ok();
    let probe: Option<PeriodStats> =
        serde_json::from_value(emulator_timing["scheduling"]["wakeup_probe"].clone()).ok();
    let jitter_against_probe = lateness.zip(probe).map(|(loop_s, probe_s)| {
        let ratio = loop_s.p99_s / probe_s.p99_s;
        serde_json::json!({
            "loop_tick_lateness": { "median_s": loop_s.median_s, "p99_s": loop_s.p99_s, "max_s": loop_s.max_s },
            "wakeup_probe": { "median_s": probe_s.median_s, "p99_s": probe_s.p99_s, "max_s": probe_s.max_s },
            "p99_ratio": ratio.is_finite().then_some(ratio),
            "target_p99_ratio": JITTER_TARGET_P99_RATIO,
            "within_target": ratio <= JITTER_TARGET_P99_RATIO,
        })
    });
    serde_json::json!({
        "deadline_misses": deadline_misses,
        "jitter_against_probe": jitter_against_probe,
    })
}

/// The controller's timing in a real-time run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ControllerTiming {
    /// Interval between consecutive angle readings.
    pub reading_interval: Option<PeriodStats>,
    /// From a reading's arrival to the command sent; overruns: latency above one period.
    pub answer_latency: Option<PeriodStats>,
    /// Readings skipped by the master's sequence counter (the controller was too slow).
    pub missed_readings: u64,
    /// This end's real-time settings and wake-up probe.
    pub scheduling: HostScheduling,
    /// The answer latency of each reading, by period, s (NaN: not answered).
    #[serde(skip)]
    pub latency_by_reading_s: Vec<f64>,
}

impl ControllerTiming {
    /// Blames each of the node's missed deadlines on the node, this host or the link
    /// ([`attribute_misses`] with this host's answer latencies).
    #[must_use]
    pub fn attribute(&self, misses: &[MissedDeadline], period_s: f64) -> MissAttribution {
        attribute_misses(misses, period_s, |reading| {
            usize::try_from(reading)
                .ok()
                .and_then(|index| self.latency_by_reading_s.get(index))
                .copied()
                .filter(|latency_s| latency_s.is_finite())
        })
    }
}

/// Runs until the periods `record` plans have been answered or the link fails; returns the
/// record filled in.
#[allow(clippy::too_many_arguments)]
pub async fn run(
    mirror: &mut MirrorLink,
    sensor: &mut SensorLink,
    controller: &mut ScanController,
    trajectory: &Trajectory,
    mut record: LoopRecord,
    progress: &Progress,
    interrupt: &mut Interrupt,
    scheduling: HostScheduling,
) -> LoopRecord {
    let busy_poll = scheduling.in_effect.busy_poll;
    let period_s = controller.period_s();
    let periods = record.periods_planned;
    let mut intervals = PeriodRecorder::new(period_s);
    let mut latencies = PeriodRecorder::new(period_s);
    let mut latency_by_reading_s = vec![f64::NAN; periods as usize];
    let mut missed_readings = 0u64;
    let mut last_arrival: Option<Instant> = None;
    let mut expected = 0u64;
    let mut last_angles = SensingPair::default();
    while expected < periods {
        let reading = if busy_poll {
            spin_for_reading(mirror, sensor, interrupt, expected).await
        } else {
            tokio::select! {
                reading = mirror.next_reading(expected) => reading,
                error = sensor.pump() => Err(error),
                signal = interrupt.recv() => Err(LoopError::Interrupted { signal }),
            }
        };
        let (j, angles) = match reading {
            Ok(reading) => reading,
            Err(error) => {
                mirror.command_zero(expected).await;
                record.stopped_by = Some(error);
                break;
            }
        };
        let arrival = Instant::now();
        let epoch = tokio::time::Instant::from_std(arrival)
            .checked_sub(Duration::from_secs_f64((j + 1) as f64 * period_s));
        if let Some(candidate) = epoch {
            record.arrival_clock = Some(match record.arrival_clock {
                Some(ArrivalClock::Epoch(current)) => ArrivalClock::Epoch(current.min(candidate)),
                _ => ArrivalClock::Epoch(candidate),
            });
        }
        if let Some(previous) = last_arrival {
            intervals.record((arrival - previous).as_secs_f64());
        }
        last_arrival = Some(arrival);
        // Readings the master sent while we were late: hold the last angles in their place.
        while expected < j && expected < periods {
            missed_readings += 1;
            record.push_reading(trajectory, expected, last_angles);
            expected += 1;
        }
        if j >= periods {
            break;
        }
        record.push_reading(trajectory, j, angles);
        last_angles = angles;
        let next = j + 1;
        let command = controller.step(trajectory.reference_rad(next as f64 * period_s), angles);
        let send_deadline = tokio::time::Instant::now() + mirror.total_allowance();
        let frame = coil_command_frame(next, command, (next + 1) as f64 * period_s);
        let sent = match frame {
            Ok(frame) => {
                mirror
                    .send_within(next, &[frame], send_deadline, interrupt)
                    .await
            }
            Err(error) => Err(error),
        };
        if let Err(error) = sent {
            mirror.command_zero(next).await;
            record.stopped_by = Some(error);
            break;
        }
        let latency = arrival.elapsed().as_secs_f64();
        latencies.record(latency);
        if let Some(slot) = latency_by_reading_s.get_mut(j as usize) {
            *slot = latency;
        }
        if latency > period_s {
            latencies.overrun();
        }
        expected = next;
        if j % 256 == 0 {
            progress.set(j);
        }
    }
    record.saturated_periods = controller.saturated_periods();
    record.controller_timing = Some(ControllerTiming {
        reading_interval: intervals.stats(),
        answer_latency: latencies.stats(),
        missed_readings,
        scheduling,
        latency_by_reading_s,
    });
    record
}

/// Busy-polling: spins on non-blocking reads of the mirror and sensor links until the next
/// reading, the watchdog's allowance, a link error or a stopping signal.
async fn spin_for_reading(
    mirror: &mut MirrorLink,
    sensor: &mut SensorLink,
    interrupt: &mut Interrupt,
    expected: u64,
) -> Result<(u64, SensingPair), LoopError> {
    let allowance = mirror.total_allowance();
    let deadline = Instant::now() + allowance;
    let mut spins = 0u32;
    loop {
        if let Some(reading) = mirror.try_reading(expected)? {
            return Ok(reading);
        }
        sensor.try_pump()?;
        spins += 1;
        if spins.is_multiple_of(SPINS_PER_YIELD) {
            if Instant::now() >= deadline {
                return Err(mirror.timeout(expected, allowance));
            }
            tokio::select! {
                biased;
                signal = interrupt.recv() => return Err(LoopError::Interrupted { signal }),
                () = tokio::task::yield_now() => {}
            }
        } else {
            std::hint::spin_loop();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(median_s: f64, p99_s: f64) -> serde_json::Value {
        serde_json::json!({
            "periods": 100, "nominal_s": 50e-6, "min_s": 0.0, "median_s": median_s,
            "p99_s": p99_s, "max_s": p99_s, "overruns": 0, "above_nominal": 0,
        })
    }

    #[test]
    fn verdicts_attribute_the_emulators_misses_and_take_its_list_out() {
        let controller = ControllerTiming {
            reading_interval: None,
            answer_latency: None,
            missed_readings: 0,
            scheduling: HostScheduling::default(),
            latency_by_reading_s: vec![10e-6, 60e-6, f64::NAN],
        };
        let mut emulator = serde_json::json!({
            "stale_command_periods": 4,
            "missed_deadlines": [
                { "period": 0, "reading_late_s": null },
                { "period": 1, "reading_late_s": 45e-6 },
                { "period": 2, "reading_late_s": 1e-6 },
                { "period": 3, "reading_late_s": 2e-6 },
            ],
            "tick_lateness": stats(1e-6, 30e-6),
            "scheduling": { "wakeup_probe": stats(5e-6, 10e-6) },
        });
        let verdicts = verdicts(&controller, &mut emulator, 50e-6);
        assert!(emulator.get("missed_deadlines").is_none());
        let misses = &verdicts["deadline_misses"];
        assert_eq!(misses["total"], 3);
        assert_eq!(misses["node"]["count"], 1, "{misses}");
        assert_eq!(
            misses["host"]["count"], 2,
            "60 us, and one never answered: {misses}"
        );
        let jitter = &verdicts["jitter_against_probe"];
        assert!((jitter["p99_ratio"].as_f64().unwrap() - 3.0).abs() < 1e-9);
        assert_eq!(jitter["within_target"], false);
    }
}
