//! The real-time loop, controller side: the emulator (or a real mirror node) is the clock
//! master and sends AngleReading(j) every period; the controller answers at once with the
//! command for the next period, CoilCommand(j + 1), which must arrive before that period
//! starts. Measured here: the interval between readings (the master's period as seen after the
//! link) and the answer latency (reading in to command out), as min / median / p99 / max, and
//! overruns (answers slower than one period) and readings that never came.

use std::time::{Duration, Instant};

use scanhil_protocol::loop_timing::{PeriodRecorder, PeriodStats};
use scanhil_protocol::plant_units::SensingPair;

use super::host_loop::{LoopError, coil_command_frame};
use super::interrupt::Interrupt;
use super::lockstep::LoopRecord;
use super::mirror_link::MirrorLink;
use super::pairing::ArrivalClock;
use super::progress::Progress;
use super::sensor_link::SensorLink;
use crate::scan_controller::ScanController;
use crate::trajectory::Trajectory;

/// The controller's timing in a real-time run.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ControllerTiming {
    /// Interval between consecutive angle readings.
    pub reading_interval: Option<PeriodStats>,
    /// From a reading's arrival to the command sent; overruns: latency above one period.
    pub answer_latency: Option<PeriodStats>,
    /// Readings skipped by the master's sequence counter (the controller was too slow).
    pub missed_readings: u64,
}

/// Runs until `periods` readings have been answered or the link fails.
pub async fn run(
    mirror: &mut MirrorLink,
    sensor: &mut SensorLink,
    controller: &mut ScanController,
    trajectory: &Trajectory,
    periods: u64,
    progress: &Progress,
    interrupt: &mut Interrupt,
) -> LoopRecord {
    let period_s = controller.period_s();
    let mut record = LoopRecord::new(period_s, periods);
    let mut intervals = PeriodRecorder::with_capacity(periods as usize);
    let mut latencies = PeriodRecorder::with_capacity(periods as usize);
    let mut missed_readings = 0u64;
    let mut last_arrival: Option<Instant> = None;
    let mut expected = 0u64;
    let mut last_angles = SensingPair::default();
    while expected < periods {
        let reading = tokio::select! {
            reading = mirror.next_reading(expected) => reading,
            error = sensor.pump() => Err(error),
            signal = interrupt.recv() => Err(LoopError::Interrupted { signal }),
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
        reading_interval: intervals.stats(period_s),
        answer_latency: latencies.stats(period_s),
        missed_readings,
    });
    record
}
