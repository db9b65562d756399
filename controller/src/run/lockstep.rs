//! The lockstep loop, controller side: per period k, compute the coil command from the newest
//! angle reading, send CoilCommand(k) and Step(k), and wait for AngleReading(k). Time is
//! virtual (`k * period`), so the run is deterministic for a seed. After the last period,
//! [`MirrorLink::end_lockstep`] ends the run with the node (on every transport the same way,
//! a bus included).

use scanhil_protocol::plant_units::SensingPair;

use super::mirror_link::{LoopError, MirrorLink};
use super::pairing::AngleTrack;
use super::progress::Progress;
use super::realtime::ControllerTiming;
use super::sensor_link::SensorLink;
use super::tracking::TrackingRecorder;
use crate::scan_controller::ScanController;
use crate::trajectory::Trajectory;

/// What a lockstep run produced.
#[derive(Debug)]
pub struct LoopRecord {
    /// The angle readings, reading k at loop time `(k + 1) * period`.
    pub angles: AngleTrack,
    /// Reference against measurement.
    pub tracking: TrackingRecorder,
    /// Periods completed.
    pub periods_done: u64,
    /// Periods asked for.
    pub periods_planned: u64,
    /// Periods in which the coil command was clipped.
    pub saturated_periods: u64,
    /// Why the run stopped early, if it did.
    pub stopped_by: Option<LoopError>,
    /// Real time only: the controller's side of the timing.
    pub controller_timing: Option<ControllerTiming>,
    /// Real time only: the instant of loop time 0 as seen here (the earliest reading's
    /// arrival minus its loop time), to place a real sensor's samples on the loop's time axis.
    pub loop_epoch: Option<tokio::time::Instant>,
}

impl LoopRecord {
    /// An empty record for a loop of `periods` periods of `period_s`.
    #[must_use]
    pub fn new(period_s: f64, periods: u64) -> LoopRecord {
        LoopRecord {
            angles: AngleTrack::new(period_s),
            tracking: TrackingRecorder::default(),
            periods_done: 0,
            periods_planned: periods,
            saturated_periods: 0,
            stopped_by: None,
            controller_timing: None,
            loop_epoch: None,
        }
    }

    /// Records reading `k` (the angles at loop time `(k + 1) * period`) against the reference
    /// at that instant.
    pub fn push_reading(&mut self, trajectory: &Trajectory, k: u64, angles: SensingPair) {
        let t_s = (k + 1) as f64 * self.angles.period_s();
        self.angles.push(angles);
        self.tracking.record(trajectory.reference_rad(t_s), angles);
        self.periods_done = k + 1;
    }
}

/// Runs `periods` lockstep periods. A link error stops the loop (after commanding zero where
/// the link still allows it) and is returned inside the record, so what was recorded stays.
pub async fn run(
    mirror: &mut MirrorLink,
    sensor: &mut SensorLink,
    controller: &mut ScanController,
    trajectory: &Trajectory,
    periods: u64,
    progress: &Progress,
) -> LoopRecord {
    let period_s = controller.period_s();
    let mut record = LoopRecord::new(period_s, periods);
    let mut measured = SensingPair::default();
    for k in 0..periods {
        let reference = trajectory.reference_rad(k as f64 * period_s);
        let command = controller.step(reference, measured);
        let reading = tokio::select! {
            reading = mirror.exchange_lockstep(k, command) => reading,
            error = sensor.pump() => Err(error),
        };
        match reading {
            Ok(angles) => {
                measured = angles;
                record.push_reading(trajectory, k, angles);
            }
            Err(error) => {
                mirror.command_zero(k).await;
                record.stopped_by = Some(error);
                break;
            }
        }
        if k % 256 == 0 {
            progress.set(k);
        }
    }
    if record.stopped_by.is_none()
        && let Err(error) = mirror.end_lockstep(record.periods_done).await
    {
        record.stopped_by = Some(error);
    }
    progress.set(record.periods_done);
    record.saturated_periods = controller.saturated_periods();
    record
}
