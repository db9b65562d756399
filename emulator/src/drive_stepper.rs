//! Steps the drive model over one control period, with the current loop's voltage limit.
//!
//! Without part `current_loop` the drive is linear and one [`Stepper`] steps it. With it, an
//! amplifier whose controller asks for more than its voltage limit saturates: its coil then
//! sees the rail and its PI integral stops ([`DriveModel::saturated`]), a model of its own for
//! each of the nine combinations of the two coils (linear, at the upper rail, at the lower).
//! A period is first stepped linearly; when the voltage demanded at its start or end lies
//! beyond the limit on either coil, it is stepped again from its start in
//! [`FINE_STEPS`] equal parts, each with the model the demand at its start selects, so a
//! saturation begins and ends within 1/[`FINE_STEPS`] of a period of its true instant (the
//! demand of a first-order loop is monotonic over a period of held command, so a period
//! whose two ends are within the limit never saturates inside). Every model of every
//! combination passes the stability check before a run.

use crate::drive_model::{DriveModel, INPUTS};
use crate::integrator::{IntegratorConfig, StabilityError, Stepper};

/// Parts of a period stepped one by one while a coil is (or may be) saturated.
pub const FINE_STEPS: u32 = 32;

/// The saturation state of one coil's amplifier.
const MODES: [Option<f64>; 3] = [None, Some(1.0), Some(-1.0)];

/// The drive's stepper over whole control periods.
#[derive(Debug, Clone)]
pub struct DriveStepper {
    linear: Stepper,
    /// With a current loop: the fine steppers of the nine combinations (index `3 m_a + m_b`),
    /// the loop's states, and a copy of the period's start.
    saturating: Option<Saturating>,
}

#[derive(Debug, Clone)]
struct Saturating {
    fine: Vec<Stepper>,
    model: DriveModel,
    start: Vec<f64>,
}

impl DriveStepper {
    /// Checks stability of every model and prepares the maps.
    ///
    /// # Errors
    /// The first model an integrator/step combination is unstable on.
    pub fn new(
        model: &DriveModel,
        period_s: f64,
        config: IntegratorConfig,
    ) -> Result<DriveStepper, StabilityError> {
        let linear = Stepper::new(model, period_s, config)?;
        let saturating = match model.current_loop {
            None => None,
            Some(_) => {
                let fine_period_s = period_s / f64::from(FINE_STEPS);
                let mut fine = Vec::with_capacity(9);
                for mode_a in MODES {
                    for mode_b in MODES {
                        let variant = model.saturated([mode_a, mode_b]);
                        fine.push(Stepper::new(&variant, fine_period_s, config)?);
                    }
                }
                Some(Saturating {
                    fine,
                    model: model.clone(),
                    start: vec![0.0; model.states()],
                })
            }
        };
        Ok(DriveStepper { linear, saturating })
    }

    /// The linear stepper (the method and sub-steps in use).
    #[must_use]
    pub fn linear(&self) -> &Stepper {
        &self.linear
    }

    /// Advances `x` by one control period with the commands `u` held; returns which coils'
    /// amplifiers saturated at some time in the period.
    pub fn step(&mut self, x: &mut [f64], u: [f64; 2]) -> [bool; 2] {
        let Some(sat) = &mut self.saturating else {
            self.linear.step(x, u);
            return [false, false];
        };
        let Some(cl) = sat.model.current_loop else {
            self.linear.step(x, u);
            return [false, false];
        };
        let limit = cl.values.max_voltage_v;
        let within = |demand: [f64; 2]| demand.iter().all(|v| v.abs() <= limit);
        if within(cl.demand_v(x, u)) {
            sat.start.copy_from_slice(x);
            self.linear.step(x, u);
            if within(cl.demand_v(x, u)) {
                return [false, false];
            }
            x.copy_from_slice(&sat.start);
        }
        let mut saturated = [false, false];
        for _ in 0..FINE_STEPS {
            let demand = cl.demand_v(x, u);
            let mode = demand.map(|v| {
                if v > limit {
                    1
                } else if v < -limit {
                    2
                } else {
                    0
                }
            });
            for (flag, m) in saturated.iter_mut().zip(mode) {
                *flag |= m != 0;
            }
            sat.fine[3 * mode[0] + mode[1]].step(x, u);
        }
        saturated
    }
}

/// The input vector of a period: the commands and the constant 1.
#[must_use]
pub fn inputs(u: [f64; 2]) -> [f64; INPUTS] {
    [u[0], u[1], 1.0]
}
