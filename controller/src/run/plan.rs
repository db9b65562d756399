//! What a scan runs, worked out once before any link opens, by `scanhil scan` and the
//! in-process loop alike: the controller built from its file and checked against the rig, the
//! trajectory after the coil power check ([`super::power_guard`]), the lead-in before the
//! recorded frame ([`super::lead_in`]), and the steady-state tracking error the nominal loop
//! predicts for the frame ([`crate::steady_state`]).

use super::budget::{ScanArea, check_grid};
use super::lead_in::LeadInPlan;
use super::power_backoff::PowerBackoff;
use super::power_guard::{PowerCheck, describe, guard};
use super::scenario::{Scenario, ScenarioError};
use crate::power_budget::{DriveLimits, loop_effort, saturated_share};
use crate::scan_controller::ScanController;
use crate::settings::ControllerSettings;
use crate::steady_state::{PredictedTracking, predict};
use crate::trajectory::Trajectory;
use scanhil_protocol::plant_units::SensingAxis;
use scanhil_protocol::validation::Invalid;

/// A scan's plan.
#[derive(Debug)]
pub struct ScanPlan {
    /// The controller, discretised, checked stable, at the rig's rate.
    pub controller: ScanController,
    /// The trajectory that runs (amplitudes shrunk by the power check where it had to).
    pub trajectory: Trajectory,
    /// The host's back-off on the node's power limit.
    pub backoff: PowerBackoff,
    /// The frame's periods: the scenario's duration.
    pub frame_periods: u64,
    /// The height map's cells over the area the scan can cover (0 without a sensor).
    pub grid_cells: f64,
    /// For the report.
    pub summary: PlanSummary,
}

/// The plan's figures, for `report.json`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PlanSummary {
    /// The lead-in before the recorded frame.
    pub lead_in: LeadInPlan,
    /// The coil power check (`None`: the rig states no mirror).
    pub power: Option<PowerCheck>,
    /// The frame's steady-state tracking error as the nominal loop predicts it.
    pub predicted_tracking: PredictedTracking,
    /// The share of the frame's periods in which the trajectory's planned steady-state drive
    /// is beyond the controller's command limits ([`saturated_share`]); from
    /// [`SATURATION_WARNING_SHARE`] on, said on stderr before the run.
    pub planned_saturated_share: f64,
}

/// The planned saturation from which a scan is warned about before it runs: a tenth of the
/// frame. A loop saturated that often does not track its reference (1 rad amplitudes under
/// power policy `off`: 1995 of 2000 periods); the scan still runs, as asked.
pub const SATURATION_WARNING_SHARE: f64 = 0.1;

impl ScanPlan {
    /// Plans `scenario`: loads and builds its controller (at the rig's rate), checks the coil
    /// power, works out the lead-in and the prediction.
    ///
    /// # Errors
    /// A controller file that does not load or discretise stably, a rate other than the
    /// rig's (both named), a trajectory the power policy refuses.
    pub fn new(scenario: &Scenario) -> anyhow::Result<ScanPlan> {
        let settings = ControllerSettings::load(&scenario.controller)?;
        let controller = settings.build()?;
        let period_s = controller.period_s();
        let rig = &scenario.rig;
        if (rig.period_s() - period_s).abs() > 1e-12 * period_s {
            anyhow::bail!(
                "{}: the controller {} runs at {:.1} Hz but rig {} at {:.1} Hz",
                scenario.path.display(),
                scenario.controller.display(),
                1.0 / period_s,
                rig.path.display(),
                rig.control_rate_hz
            );
        }
        let nominal = settings.nominal_loop(controller.axis());
        let guarded = guard(scenario, &settings, &controller, &nominal)?;
        let lead_in = scenario.lead_in.plan(&nominal, &guarded.trajectory);
        if lead_in.capped {
            eprintln!(
                "lead-in: the loop settles in {:.2} s, capped at {:.2} s by `lead_in.max_s`: \
                 the recorded frame may hold some of the transient",
                lead_in.settle_s.unwrap_or(f64::NAN),
                lead_in.duration_s
            );
        }
        let grid_cells = match rig.sensor {
            Some(sensor) => {
                let scanner = scanhil_geometry::Scanner::new(
                    rig.scanner.setup,
                    scenario.imaging.reconstruction,
                )?;
                let peaks_rad = (
                    guarded.trajectory.peak_rad(SensingAxis::Alpha),
                    guarded.trajectory.peak_rad(SensingAxis::Beta),
                );
                let area = ScanArea::of_rig(
                    &scanner,
                    &rig.scanner.calibration,
                    peaks_rad,
                    sensor.range(),
                );
                check_grid(
                    &area,
                    scenario.imaging.pitch_mm,
                    super::machine::available_memory_bytes(),
                )
                .map_err(|invalid| ScenarioError::from(invalid.in_file(&scenario.path)))?
            }
            None => 0.0,
        };
        let frame_periods = (scenario.duration_s / period_s).round() as u64;
        scenario
            .faults
            .check_reachable(lead_in.periods + frame_periods, rig.sensor.is_some())
            .map_err(|error| {
                ScenarioError::from(Invalid::new(error.field, error.reason).in_file(&scenario.path))
            })?;
        let predicted_tracking = predict(&nominal, &guarded.trajectory);
        let planned_saturated_share = saturated_share(
            &guarded.trajectory,
            &rig.mirror
                .map(|mirror| mirror.cross_talk)
                .unwrap_or_default(),
            &loop_effort(&nominal),
            DriveLimits {
                axis_a: settings.axis_limit_a(),
                coil_a: settings.coil_current_limit_a,
            },
            period_s,
            scenario.duration_s,
        );
        if planned_saturated_share >= SATURATION_WARNING_SHARE {
            eprintln!(
                "warning: trajectory {} drives the controller past its command limits ({:.2} A \
                 per axis, {:.2} A per coil) in an estimated {:.1} % of the frame's periods at \
                 steady state: the loop saturates there and does not follow the reference; \
                 lower the amplitudes or frequencies (power policy `shrink` scales them to the \
                 rig's limits)",
                describe(&guarded.trajectory),
                settings.axis_limit_a(),
                settings.coil_current_limit_a,
                100.0 * planned_saturated_share
            );
        }
        Ok(ScanPlan {
            controller,
            trajectory: guarded.trajectory,
            backoff: guarded.backoff,
            frame_periods,
            grid_cells,
            summary: PlanSummary {
                lead_in,
                power: guarded.check,
                predicted_tracking,
                planned_saturated_share,
            },
        })
    }

    /// Every period the loop runs: the lead-in's and the frame's.
    #[must_use]
    pub fn periods(&self) -> u64 {
        self.summary.lead_in.periods + self.frame_periods
    }
}
