//! An axis's delay beyond one control period: its measured angle lags the mechanical one.
//!
//! Eq. 4's `e^(-s Ta)` is one control period in the plant's command path (see
//! [`crate::plant`]). A scene may give an axis a longer delay (`mirror.delay_s`, e.g. a fitted
//! 62 us at 20 kHz); the rest, `D = m Ta + g` with `0 <= g < Ta`, delays what that axis
//! reports, so from the command to the measured angle the axis is exactly `G(s) e^(-s delay_s)`
//! while the optics see the mirror where it is. The value at `(k+1) Ta - D` lies in period
//! `k - m` at `tau = Ta - g` after its start, where the input was held, so it is exact:
//! `y = c Phi(tau) x_start + (c Gamma(tau) + d) u` for the measured output `c x + d u`, with the
//! matrix exponential over `tau` (whatever integrator steps the period itself), kept for `m`
//! periods.

use std::collections::VecDeque;

use crate::drive_model::{DriveModel, INPUTS, OutputRow};
use crate::integrator::Method;

/// The delayed value of one axis's measured output.
#[derive(Debug, Clone)]
pub struct OutputLatency {
    /// The output delayed, `c x + d u`.
    output: OutputRow,
    /// `(c Phi(tau), c Gamma(tau) + d)`, or `None` when `g = 0` and the value is the period
    /// end's.
    interpolation: Option<OutputRow>,
    /// The values still to be reported, oldest first (`m` of them between steps).
    pending: VecDeque<f64>,
}

impl OutputLatency {
    /// The latency of `output` of `model` by `extra_delay_s` (> 0) at periods of `period_s`,
    /// starting from the value `initial`.
    #[must_use]
    pub fn new(
        model: &DriveModel,
        output: &OutputRow,
        extra_delay_s: f64,
        period_s: f64,
        initial: f64,
    ) -> OutputLatency {
        let periods = extra_delay_s / period_s;
        // A fraction within rounding of a whole period counts as whole.
        let mut whole = periods.floor();
        let mut fraction = periods - whole;
        if fraction > 1.0 - 1e-9 {
            whole += 1.0;
            fraction = 0.0;
        }
        let interpolation = (fraction > 1e-9).then(|| {
            let (phi, gamma) = Method::ExactZoh.step_maps(model, (1.0 - fraction) * period_s);
            let c = (0..model.states())
                .map(|j| {
                    output
                        .c
                        .iter()
                        .enumerate()
                        .map(|(i, ci)| ci * phi[(i, j)])
                        .sum()
                })
                .collect();
            let mut d = output.d;
            for (k, dk) in d.iter_mut().enumerate() {
                *dk += output
                    .c
                    .iter()
                    .enumerate()
                    .map(|(i, ci)| ci * gamma[(i, k)])
                    .sum::<f64>();
            }
            OutputRow { c, d }
        });
        OutputLatency {
            output: output.clone(),
            interpolation,
            pending: std::iter::repeat_n(initial, whole as usize).collect(),
        }
    }

    /// Records one period that started in state `start` with the inputs `u` held and ended
    /// in `end`; returns the delayed value at the period's end.
    pub fn step(&mut self, start: &[f64], u: [f64; INPUTS], end: &[f64]) -> f64 {
        let value = match &self.interpolation {
            None => self.output.value(end, u),
            Some(row) => row.value(start, u),
        };
        self.pending.push_back(value);
        self.pending.pop_front().unwrap_or(value)
    }
}
