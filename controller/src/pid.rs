//! The PID position controller of Table II with a filtered derivative, in the series
//! (alpha-tuning) and the parallel form, run as discrete paths with conditional-integration
//! anti-windup.
//!
//! - parallel: `C(s) = kp + ki/s + kd s / (1 + s/wt)`
//! - series:   `C(s) = kp (1 + wi/s) (1 + s/wd) / (1 + s/wt)`, `wi = ki/kp`, `wd = kp/kd`
//!
//! Both are run as `u = direct(v) + integral(v)` with `v = pre(e)`: series `pre` is the lead
//! `(1 + s/wd)/(1 + s/wt)`, `direct = kp`, `integral = kp wi / s`; parallel `pre = 1`,
//! `direct = kp + kd s/(1 + s/wt)`, `integral = ki / s`. Each path is discretised on its own.

use crate::continuous::{ContinuousSection, FactoredTf, Quadratic};
use crate::discretise::{Method, discretise};
use crate::sos::{Cascade, Section, SectionState};

/// Which reading of the lost PID equation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PidForm {
    /// `kp (1 + wi/s)(1 + s/wd)/(1 + s/wt)` (alpha tuning).
    Series,
    /// `kp + ki/s + kd s/(1 + s/wt)`.
    Parallel,
}

/// Table II's coefficients and the form they are read in.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PidParams {
    /// Series or parallel reading.
    pub form: PidForm,
    /// Proportional gain kp (input units per output unit).
    pub kp: f64,
    /// Derivative gain kd (s).
    pub kd: f64,
    /// Integral gain ki (1/s).
    pub ki: f64,
    /// Derivative filter corner wt, rad/s.
    pub wt_rad_s: f64,
}

impl PidParams {
    /// The continuous paths `(pre, direct, integral)`.
    fn paths(&self) -> [ContinuousSection; 3] {
        let integrator = Quadratic::integrator();
        let wt = self.wt_rad_s;
        match self.form {
            PidForm::Series => {
                let (wi, wd) = (self.ki / self.kp, self.kp / self.kd);
                [
                    ContinuousSection {
                        num: Quadratic {
                            s2: 0.0,
                            s1: wt / wd,
                            s0: wt,
                        },
                        den: Quadratic::first_order(wt),
                    },
                    ContinuousSection {
                        num: Quadratic::constant(self.kp),
                        den: Quadratic::constant(1.0),
                    },
                    ContinuousSection {
                        num: Quadratic::constant(self.kp * wi),
                        den: integrator,
                    },
                ]
            }
            PidForm::Parallel => [
                ContinuousSection {
                    num: Quadratic::constant(1.0),
                    den: Quadratic::constant(1.0),
                },
                ContinuousSection {
                    num: Quadratic {
                        s2: 0.0,
                        s1: self.kp + self.kd * wt,
                        s0: self.kp * wt,
                    },
                    den: Quadratic::first_order(wt),
                },
                ContinuousSection {
                    num: Quadratic::constant(self.ki),
                    den: integrator,
                },
            ],
        }
    }

    /// The continuous controller as factors (for reports and continuous analysis).
    #[must_use]
    pub fn continuous(&self) -> FactoredTf {
        let wt = self.wt_rad_s;
        match self.form {
            PidForm::Series => {
                let (wi, wd) = (self.ki / self.kp, self.kp / self.kd);
                FactoredTf {
                    gain: self.kp * wt / wd,
                    zeros: vec![Quadratic::first_order(wi), Quadratic::first_order(wd)],
                    poles: vec![Quadratic::integrator(), Quadratic::first_order(wt)],
                }
            }
            PidForm::Parallel => FactoredTf {
                gain: 1.0,
                zeros: vec![Quadratic {
                    s2: self.kp + self.kd * wt,
                    s1: self.kp * wt + self.ki,
                    s0: self.ki * wt,
                }],
                poles: vec![Quadratic::integrator(), Quadratic::first_order(wt)],
            },
        }
    }
}

/// A discrete PID with output limit and conditional-integration anti-windup.
#[derive(Debug, Clone, PartialEq)]
pub struct Pid {
    pre: Section,
    direct: Section,
    integral: Section,
    states: [SectionState; 3],
    output_limit: f64,
}

impl Pid {
    /// Discretises the paths of `params` with `method` at `period_s`; the output is clamped to
    /// `+-output_limit` (input units).
    #[must_use]
    pub fn new(params: &PidParams, method: &Method, period_s: f64, output_limit: f64) -> Self {
        let [pre, direct, integral] = params.paths().map(|p| discretise(&p, method, period_s));
        Self {
            pre,
            direct,
            integral,
            states: [SectionState::default(); 3],
            output_limit,
        }
    }

    /// The linear discrete controller (no limit) as one cascade: `pre * (direct + integral)`.
    #[must_use]
    pub fn linear(&self) -> Cascade {
        Cascade::new(
            1.0,
            vec![self.pre, self.direct.parallel_sum(&self.integral)],
        )
    }

    /// One period: error (output units) in, command (input units) out, clamped. While the
    /// output is clamped, the integrator does not integrate further into the limit.
    pub fn step(&mut self, error: f64) -> f64 {
        let v = self.pre.step(&mut self.states[0], error);
        let d = self.direct.step(&mut self.states[1], v);
        let before = self.states[2];
        let i = self.integral.step(&mut self.states[2], v);
        let u = d + i;
        let limited = u.clamp(-self.output_limit, self.output_limit);
        if limited != u && (u - limited).signum() == v.signum() {
            self.states[2] = before;
        }
        limited
    }

    /// All states to zero.
    pub fn reset(&mut self) {
        self.states = [SectionState::default(); 3];
    }
}
