//! The power check before a run, shared by `scanhil scan` and the in-process loop: the
//! trajectory's steady-state coil power is estimated from the rig's mirror and the controller's
//! nominal loop ([`crate::power_budget`]) and the scenario's `power` policy decides:
//!
//! - `shrink` (default): amplitudes scaled so the estimate is `margin x limit` (the paper:
//!   above 52 Hz the range shrinks), said on stderr and in report.json;
//! - `refuse`: an estimate over `margin x limit` stops the run before any link is opened,
//!   naming the trajectory, the estimate and the limit;
//! - `off`: the trajectory runs as written (over the limit the node's clamp acts).
//!
//! It also sets up the host's [`PowerBackoff`] for the run (`"backoff": false` turns it off),
//! with the trajectory's estimate and its current cap (the controller's command limit).

use anyhow::bail;
use scanhil_protocol::plant_units::AMPS_PER_INPUT_UNIT;
use serde::Serialize;

use super::power_backoff::PowerBackoff;
use super::scenario::{PowerPolicy, Scenario};
use crate::loop_analysis::NominalLoop;
use crate::power_budget::{PowerEstimate, estimate, loop_effort, shrink_factor};
use crate::scan_controller::ScanController;
use crate::settings::ControllerSettings;
use crate::trajectory::Trajectory;

/// The check's figures (report.json's `power.check`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PowerCheck {
    /// The policy applied.
    pub policy: PowerPolicy,
    /// The rig's coil resistance per actuator axis, ohm.
    pub coil_resistance_ohm: f64,
    /// The rig's power limit, W.
    pub limit_w: f64,
    /// `margin x limit`, W.
    pub budget_w: f64,
    /// `margin x` the rig's amplifier current limit, A (the peak coil current allowed).
    pub current_budget_a: Option<f64>,
    /// The trajectory as written.
    pub before: PowerEstimate,
    /// The amplitude factor applied (1: unchanged).
    pub factor: f64,
    /// The trajectory that runs.
    pub after: PowerEstimate,
}

/// The trajectory to run, the check's figures and the back-off for the loop.
#[derive(Debug, Clone)]
pub struct Guarded {
    /// The trajectory the loop follows (scaled under `shrink`).
    pub trajectory: Trajectory,
    /// The figures, or None when the rig has no `mirror` section.
    pub check: Option<PowerCheck>,
    /// The host's back-off for this run.
    pub backoff: PowerBackoff,
}

/// Estimates `scenario`'s trajectory under `controller` and applies its power policy.
///
/// # Errors
/// Under `refuse`, an estimate over `margin x limit` (trajectory, estimate and limit named).
pub fn guard(
    scenario: &Scenario,
    settings: &ControllerSettings,
    controller: &ScanController,
    nominal: &NominalLoop,
) -> anyhow::Result<Guarded> {
    let config = scenario.power;
    let trajectory = scenario.trajectory.clone();
    let period_s = controller.period_s();
    let resonance_hz = settings.plant.natural_freq_rad_s / std::f64::consts::TAU;
    let ramp_periods = PowerBackoff::ramp_periods_for(resonance_hz, period_s);
    let Some(mirror) = scenario.rig.mirror else {
        eprintln!(
            "power: rig {} has no `mirror` section: the coil power of the trajectory is not \
             estimated",
            scenario.rig.path.display()
        );
        let backoff = if config.backoff {
            PowerBackoff::new(None, 1.0, config.margin, ramp_periods)
        } else {
            PowerBackoff::inactive()
        };
        return Ok(Guarded {
            trajectory,
            check: None,
            backoff,
        });
    };
    let effort = loop_effort(nominal);
    let nyquist_hz = 0.5 / period_s;
    let before = estimate(&trajectory, &mirror, &effort, nyquist_hz);
    let budget_w = config.margin * mirror.power_limit_w;
    let current_budget_a = mirror
        .amplifier_current_limit_a
        .map(|limit| config.margin * limit);
    let over = before.mean_power_w > budget_w;
    let peak_a = before.peak_coil_current_bound_a;
    let over_current = current_budget_a.is_some_and(|budget| peak_a > budget);
    let described = describe(&trajectory);
    let factor = match config.policy {
        PowerPolicy::Refuse if over => bail!(
            "{}: trajectory {described} needs an estimated {:.2} W of coil power at steady \
             state, over {:.2} W ({} x the {} W limit of rig {}); policy `refuse`",
            scenario.path.display(),
            before.mean_power_w,
            budget_w,
            config.margin,
            mirror.power_limit_w,
            scenario.rig.path.display()
        ),
        PowerPolicy::Refuse if over_current => bail!(
            "{}: trajectory {described} needs up to an estimated {peak_a:.2} A of coil current \
             at steady state, over {:.2} A ({} x the amplifiers' limit of rig {}); policy \
             `refuse`",
            scenario.path.display(),
            current_budget_a.unwrap_or(f64::NAN),
            config.margin,
            scenario.rig.path.display()
        ),
        // Power goes with the amplitude squared, the peak current with the amplitude.
        PowerPolicy::Shrink => shrink_factor(before.mean_power_w, budget_w)
            .min(current_budget_a.map_or(1.0, |budget| (budget / peak_a).min(1.0))),
        PowerPolicy::Refuse | PowerPolicy::Off => 1.0,
    };
    let trajectory = if factor < 1.0 {
        trajectory.scaled(factor)
    } else {
        trajectory
    };
    let after = estimate(&trajectory, &mirror, &effort, nyquist_hz);
    if factor < 1.0 {
        eprintln!(
            "power: trajectory {described} needs an estimated {:.2} W (budget {budget_w:.2} W) \
             and up to {peak_a:.2} A per coil (budget {}): amplitudes scaled by {factor:.4} to \
             {:.2} W and {:.2} A",
            before.mean_power_w,
            current_budget_a.map_or_else(|| "none".to_owned(), |a| format!("{a:.2} A")),
            after.mean_power_w,
            after.peak_coil_current_bound_a,
        );
    } else if over || over_current {
        eprintln!(
            "power: trajectory {described} needs an estimated {:.2} W > {:.2} W ({} x {} W); \
             policy `off`: it runs as written",
            before.mean_power_w, budget_w, config.margin, mirror.power_limit_w
        );
    }
    let backoff = if config.backoff {
        let axis_limit_a = controller.axis().output_limit() * AMPS_PER_INPUT_UNIT;
        let peak_a = after.alpha_peak_bound_a.max(after.beta_peak_bound_a);
        PowerBackoff::new(
            Some(after.mean_power_w),
            mirror.power_limit_w,
            config.margin,
            ramp_periods,
        )
        .with_current_cap(config.margin * axis_limit_a / peak_a)
    } else {
        PowerBackoff::inactive()
    };
    Ok(Guarded {
        trajectory,
        check: Some(PowerCheck {
            policy: config.policy,
            coil_resistance_ohm: mirror.coil_resistance_ohm,
            limit_w: mirror.power_limit_w,
            budget_w,
            current_budget_a,
            before,
            factor,
            after,
        }),
        backoff,
    })
}

/// The trajectory as its JSON (kind, frequencies, amplitudes).
pub(crate) fn describe(trajectory: &Trajectory) -> String {
    serde_json::to_string(trajectory).unwrap_or_else(|_| format!("{trajectory:?}"))
}
