//! The real-time loop, controller side: the emulator (or a real mirror node) is the clock
//! master and sends AngleReading(j) every period; the controller answers at once with the
//! command for the next period, CoilCommand(j + 1), which must arrive before that period
//! starts. Measured here: the interval between readings (the master's period as seen after the
//! link) and the answer latency (reading in to command out), as min / median / p99 / max, and
//! overruns (answers slower than one period) and readings that never came. A reading's arrival
//! is when it was on the bus as the link knows it: the kernel's receive timestamp on SocketCAN,
//! an SLCAN adapter's stamp when it sends them, else when the loop takes it.
//!
//! Before the loop this thread gets the scenario's real-time settings (CPU, `SCHED_FIFO`,
//! locked memory) and measures the machine's wake-up latency with them ([`HostScheduling`]).
//! With busy-polling the wait for a reading spins on non-blocking reads of both links instead
//! of waiting on readiness (yielding to the runtime every [`SPINS_PER_YIELD`] spins, so a
//! Ctrl-C is still seen). After the run, each period the emulator stepped without a fresh
//! command is blamed on the side with the larger delay ([`ControllerTiming::attribute`]).

use std::time::{Duration, Instant};

use scanhil_protocol::loop_timing::PeriodRecorder;
use scanhil_protocol::plant_units::SensingPair;

use super::controller_timing::{ControllerTiming, HostScheduling};
use super::host_loop::{LoopRecord, coil_command_frame};
use super::interrupt::Interrupt;
use super::loop_error::LoopError;
use super::mirror_link::MirrorLink;
use super::progress::Progress;
use super::scenario::TimingConfig;
use super::sensor_link::SensorLink;
use crate::scan_controller::ScanController;
use crate::trajectory::Trajectory;

/// Busy-polling: non-blocking reads between two yields to the runtime (its signals and timers).
pub const SPINS_PER_YIELD: u32 = 32;

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
                record.coils_at_end.zero_commanded = mirror.command_zero(expected).await;
                record.stopped_by = Some(error);
                break;
            }
        };
        // On the bus as the kernel or the adapter stamped it, else now.
        let arrival = mirror.last_arrival().into_std();
        let epoch = tokio::time::Instant::from_std(arrival)
            .checked_sub(Duration::from_secs_f64((j + 1) as f64 * period_s));
        if let Some(candidate) = epoch {
            record.wall_clock_epoch = Some(
                record
                    .wall_clock_epoch
                    .map_or(candidate, |current| current.min(candidate)),
            );
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
        let sent = if next == periods {
            // The last reading is answered by the end: the zero command and the controller's
            // Status, which the node acknowledges below.
            let end = mirror.send_end(periods).await;
            record.coils_at_end.zero_commanded = end.is_ok();
            end
        } else {
            if next == record.lead_in_periods {
                record.saturated_in_lead_in = controller.saturated_periods();
            }
            let command = controller.step(trajectory.reference_rad(next as f64 * period_s), angles);
            let send_deadline = tokio::time::Instant::now() + mirror.total_allowance();
            match coil_command_frame(next, command, (next + 1) as f64 * period_s) {
                Ok(frame) => {
                    mirror
                        .send_within(next, &[frame], send_deadline, interrupt)
                        .await
                }
                Err(error) => Err(error),
            }
        };
        if let Err(error) = sent {
            record.coils_at_end.zero_commanded = mirror.command_zero(next).await;
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
    if record.stopped_by.is_none() {
        if !record.coils_at_end.zero_commanded {
            // The last readings never came (passed over): the end goes out now.
            record.coils_at_end.zero_commanded = mirror.send_end(periods).await.is_ok();
        }
        record.coils_at_end.acknowledged =
            record.coils_at_end.zero_commanded && mirror.await_end(periods).await;
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
