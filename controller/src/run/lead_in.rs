//! The lead-in: how long the mirror runs the trajectory before the recorded frame. A bench
//! mirror runs continuously and a frame is taken once the loop has settled; the loop starts
//! from rest, so without a lead-in the frame holds the start-up transient (the dual-tone's
//! slowest closed-loop pole, |z| = 0.999917 at 20 kHz, decays with a 0.6 s time constant).
//!
//! A scenario's `lead_in` is one of
//! - `{"mode": "none"}` (the default): the frame starts with the loop;
//! - `{"mode": "fixed", "duration_s": 3.0}`;
//! - `{"mode": "settle", "residual": 0.001, "max_s": 10.0}`: until the nominal closed loop's
//!   slowest pole has decayed to `residual` of its start (`ln(residual) / ln|z|` periods), at
//!   most `max_s` (a capped lead-in is said on stderr and in the report).
//!
//! Either way the lead-in is rounded up to a whole number of the trajectory's frames (when it
//! has a frame time), so the recorded frame starts where the trajectory's frame starts.

use serde::{Deserialize, Serialize};

use crate::loop_analysis::NominalLoop;
use crate::trajectory::Trajectory;

/// The longest lead-in a scenario may ask for, s.
pub const MAX_LEAD_IN_S: f64 = 600.0;

/// A scenario's `lead_in` section.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "snake_case", deny_unknown_fields)]
pub enum LeadIn {
    /// No lead-in: the recorded frame starts with the loop, transient included.
    #[default]
    None,
    /// A fixed lead-in.
    Fixed {
        /// Its length, s.
        duration_s: f64,
    },
    /// Until the nominal loop's slowest pole has decayed to `residual`, at most `max_s`.
    Settle {
        /// The slowest mode's remaining fraction, in (0, 1).
        residual: f64,
        /// The cap, s.
        max_s: f64,
    },
}

/// The lead-in worked out for one scan.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LeadInPlan {
    /// What the scenario asked for.
    pub requested: LeadIn,
    /// The settle rule's time before the cap and the rounding, s.
    pub settle_s: Option<f64>,
    /// The settle rule hit its cap.
    pub capped: bool,
    /// Control periods of lead-in.
    pub periods: u64,
    /// The lead-in, s (`periods` x the control period): the recorded frame's start.
    pub duration_s: f64,
}

impl LeadIn {
    /// Checks the numbers; on failure the field and why.
    ///
    /// # Errors
    /// A duration or cap that is not finite, negative, or over [`MAX_LEAD_IN_S`]; a residual
    /// outside (0, 1).
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        let seconds = |field: &'static str, value: f64| {
            if value.is_finite() && (0.0..=MAX_LEAD_IN_S).contains(&value) {
                Ok(())
            } else {
                Err((
                    field,
                    format!("{value} s must be between 0 and {MAX_LEAD_IN_S} s"),
                ))
            }
        };
        match *self {
            LeadIn::None => Ok(()),
            LeadIn::Fixed { duration_s } => seconds("lead_in.duration_s", duration_s),
            LeadIn::Settle { residual, max_s } => {
                if !(residual > 0.0 && residual < 1.0) {
                    return Err((
                        "lead_in.residual",
                        format!("{residual} must be between 0 and 1 (exclusive)"),
                    ));
                }
                seconds("lead_in.max_s", max_s)
            }
        }
    }

    /// The lead-in for `trajectory` under `nominal` (its slowest closed-loop pole), in whole
    /// control periods and whole trajectory frames.
    #[must_use]
    pub fn plan(&self, nominal: &NominalLoop, trajectory: &Trajectory) -> LeadInPlan {
        let period_s = nominal.period_s();
        let (wanted_s, settle_s, capped) = match *self {
            LeadIn::None => (0.0, None, false),
            LeadIn::Fixed { duration_s } => (duration_s, None, false),
            LeadIn::Settle { residual, max_s } => {
                let slowest = nominal
                    .closed_loop_poles()
                    .iter()
                    .map(|z| z.norm())
                    .fold(0.0, f64::max);
                // A stable loop has |z| < 1; the build refuses any other.
                let settle_s = residual.ln() / slowest.ln() * period_s;
                let settle_s = if settle_s.is_finite() {
                    settle_s
                } else {
                    max_s
                };
                (settle_s.min(max_s), Some(settle_s), settle_s > max_s)
            }
        };
        let frame_s = trajectory.figures(None).frame_time_s.filter(|t| *t > 0.0);
        let rounded_s = match frame_s {
            Some(frame_s) if wanted_s > 0.0 => (wanted_s / frame_s - 1e-9).ceil() * frame_s,
            _ => wanted_s,
        };
        let periods = (rounded_s / period_s).round() as u64;
        LeadInPlan {
            requested: *self,
            settle_s,
            capped,
            periods,
            duration_s: periods as f64 * period_s,
        }
    }
}
