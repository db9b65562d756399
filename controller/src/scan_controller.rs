//! The per-period controller the loop calls: one control law per sensing axis in the paper's
//! units, the scalings to rad and A, the 45 degree rotation onto the coil axes and the coil
//! current limit. Pure and deterministic: no clock, no I/O.

use scanhil_protocol::plant_units::{
    AMPS_PER_INPUT_UNIT, ActuatorPair, RAD_PER_OUTPUT_UNIT, SensingPair, actuator_from_sensing,
};

use crate::pid::Pid;
use crate::sos::Cascade;

/// The control law of one sensing axis (error in output units, command in input units).
#[derive(Debug, Clone, PartialEq)]
pub enum AxisLaw {
    /// PID paths with anti-windup.
    Pid(Pid),
    /// A cascade of sections (the dual-tone controller), output clamped.
    Cascade(Cascade),
}

/// One sensing axis' controller with its output limit.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisController {
    law: AxisLaw,
    output_limit: f64,
}

impl AxisController {
    /// `law` with its command clamped to `+-output_limit` input units.
    #[must_use]
    pub fn new(law: AxisLaw, output_limit: f64) -> Self {
        Self { law, output_limit }
    }

    /// One period: error (output units) to command (input units).
    pub fn step(&mut self, error: f64) -> f64 {
        match &mut self.law {
            AxisLaw::Pid(pid) => pid.step(error),
            AxisLaw::Cascade(c) => c.step(error).clamp(-self.output_limit, self.output_limit),
        }
    }

    /// The command limit, input units.
    #[must_use]
    pub fn output_limit(&self) -> f64 {
        self.output_limit
    }

    /// The linear discrete controller (limits ignored), for analysis.
    #[must_use]
    pub fn linear(&self) -> Cascade {
        match &self.law {
            AxisLaw::Pid(pid) => pid.linear(),
            AxisLaw::Cascade(c) => c.clone(),
        }
    }

    /// All states to zero.
    pub fn reset(&mut self) {
        match &mut self.law {
            AxisLaw::Pid(pid) => pid.reset(),
            AxisLaw::Cascade(c) => c.reset(),
        }
    }
}

/// Both axes' controllers, the rotation onto the coils and the coil current limit.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanController {
    alpha: AxisController,
    beta: AxisController,
    coil_current_limit_a: f64,
    period_s: f64,
    saturated_periods: u64,
}

impl ScanController {
    /// Two axis controllers (identical axes share one design), the coil limit and the period.
    #[must_use]
    pub fn new(axis: AxisController, coil_current_limit_a: f64, period_s: f64) -> Self {
        Self {
            alpha: axis.clone(),
            beta: axis,
            coil_current_limit_a,
            period_s,
            saturated_periods: 0,
        }
    }

    /// The control period, s.
    #[must_use]
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// One axis' controller (both are the same design).
    #[must_use]
    pub fn axis(&self) -> &AxisController {
        &self.alpha
    }

    /// One control period: reference and measured mirror angles (rad, sensing axes) in, coil
    /// currents (A, actuator axes) out, each clamped to the coil current limit.
    pub fn step(
        &mut self,
        reference_rad: SensingPair,
        measured_angles_rad: SensingPair,
    ) -> ActuatorPair {
        let error = |r: f64, y: f64| (r - y) / RAD_PER_OUTPUT_UNIT;
        let alpha = self
            .alpha
            .step(error(reference_rad.alpha, measured_angles_rad.alpha));
        let beta = self
            .beta
            .step(error(reference_rad.beta, measured_angles_rad.beta));
        let at_axis_limit =
            alpha.abs() >= self.alpha.output_limit() || beta.abs() >= self.beta.output_limit();
        let command_a = SensingPair {
            alpha: alpha * AMPS_PER_INPUT_UNIT,
            beta: beta * AMPS_PER_INPUT_UNIT,
        };
        let coils = actuator_from_sensing(command_a);
        let limit = self.coil_current_limit_a;
        let clamped = ActuatorPair {
            a: coils.a.clamp(-limit, limit),
            b: coils.b.clamp(-limit, limit),
        };
        if at_axis_limit || clamped != coils {
            self.saturated_periods += 1;
        }
        clamped
    }

    /// All states to zero (and the saturation count).
    pub fn reset(&mut self) {
        self.alpha.reset();
        self.beta.reset();
        self.saturated_periods = 0;
    }

    /// Periods since the last reset in which an axis command sat at its limit or a coil
    /// command was clipped.
    #[must_use]
    pub fn saturated_periods(&self) -> u64 {
        self.saturated_periods
    }
}
