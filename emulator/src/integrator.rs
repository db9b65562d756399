//! Integrators for the linear drive model over one control period, with optional sub-steps,
//! and the stability check that runs before any of them is used.
//!
//! The input (the coil current command) is held constant over a period, so every method is a
//! linear map per sub-step of length `h`: `x <- Phi x + Gamma u`.
//! - `exact_zoh`: `[Phi Gamma; 0 I] = exp([A B; 0 0] h)` (the matrix exponential): exact for a
//!   held input, to rounding. The default.
//! - `trapezoid` (implicit, A-stable): `Phi = (I - hA/2)^-1 (I + hA/2)`,
//!   `Gamma = (I - hA/2)^-1 h B`, factored once; stepping costs the same as `exact_zoh`.
//! - `rk4` (classical Runge-Kutta) and `explicit_euler` evaluate `f(x) = A x + B u` at run time
//!   (4 and 1 evaluations per sub-step).
//!
//! Stability: the per-sub-step state map (`Phi`, or the stability polynomial `R(hA)` of the
//! explicit methods) must have spectral radius `rho` with `rho^substeps <= 1 + 1e-12`: no
//! mode may grow by more than rounding over one control period (a marginally stable mode,
//! as in an undamped mirror under the exact map, passes). Otherwise [`Stepper::new`] refuses
//! with the method, the step and the offending eigenvalue.

use std::fmt;

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::drive_model::{DriveModel, INPUTS};

/// How far above 1 the growth per control period may lie (rounding of a marginally stable map).
const GROWTH_TOLERANCE: f64 = 1e-12;
/// The most sub-steps [`StabilityError::stable_substeps`] searches for.
const MAX_SUGGESTED_SUBSTEPS: u32 = 1 << 20;

/// An integration method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Exact zero-order-hold discretisation via the matrix exponential.
    ExactZoh,
    /// Classical fourth-order Runge-Kutta.
    Rk4,
    /// The implicit trapezoid rule (Tustin).
    Trapezoid,
    /// Explicit (forward) Euler, for contrast.
    ExplicitEuler,
}

impl Method {
    /// All methods, the default first.
    pub const ALL: [Method; 4] = [
        Method::ExactZoh,
        Method::Rk4,
        Method::Trapezoid,
        Method::ExplicitEuler,
    ];

    /// The name used in scene files, output and errors.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Method::ExactZoh => "exact_zoh",
            Method::Rk4 => "rk4",
            Method::Trapezoid => "trapezoid",
            Method::ExplicitEuler => "explicit_euler",
        }
    }

    /// The per-sub-step maps `(Phi, Gamma)` of this method for step `h_s`.
    #[must_use]
    pub fn step_maps(self, model: &DriveModel, h_s: f64) -> (DMatrix<f64>, DMatrix<f64>) {
        let n = model.states();
        let eye = DMatrix::<f64>::identity(n, n);
        let ha = &model.a * h_s;
        let hb = &model.b * h_s;
        match self {
            Method::ExactZoh => {
                let mut aug = DMatrix::<f64>::zeros(n + INPUTS, n + INPUTS);
                aug.view_mut((0, 0), (n, n)).copy_from(&ha);
                aug.view_mut((0, n), (n, INPUTS)).copy_from(&hb);
                let e = aug.exp();
                (
                    e.view((0, 0), (n, n)).into_owned(),
                    e.view((0, n), (n, INPUTS)).into_owned(),
                )
            }
            Method::Trapezoid => {
                let left = &eye - &ha * 0.5;
                let inv = left
                    .try_inverse()
                    .expect("I - hA/2 is invertible: A has no eigenvalue with positive real part");
                (&inv * (&eye + &ha * 0.5), inv * hb)
            }
            Method::Rk4 => {
                // R(hA) = I + hA + (hA)^2/2 + (hA)^3/6 + (hA)^4/24, Gamma = (I + hA/2 + ...)hB.
                let ha2 = &ha * &ha;
                let ha3 = &ha2 * &ha;
                let phi = &eye + &ha + &ha2 * 0.5 + &ha3 * (1.0 / 6.0) + &ha3 * &ha * (1.0 / 24.0);
                let series = &eye + &ha * 0.5 + &ha2 * (1.0 / 6.0) + &ha3 * (1.0 / 24.0);
                (phi, series * hb)
            }
            Method::ExplicitEuler => (eye + ha, hb),
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The scene's choice of integrator.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IntegratorConfig {
    /// The method.
    pub method: Method,
    /// Sub-steps per control period (>= 1).
    pub substeps: u32,
}

impl Default for IntegratorConfig {
    fn default() -> Self {
        IntegratorConfig {
            method: Method::ExactZoh,
            substeps: 1,
        }
    }
}

/// An integrator/step combination that would blow up on this plant.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "integrator {method} with step {step_s:e} s ({substeps} sub-step(s) per period) is unstable \
     on this plant: the sub-step map has eigenvalue {re:+.6e}{im:+.6e}i of magnitude {radius:.15}, \
     a growth of {growth:.15} per control period (> 1); use exact_zoh or trapezoid{suggestion}",
    growth = radius.powf(f64::from(*substeps)),
    re = eigenvalue.0,
    im = eigenvalue.1,
    suggestion = match stable_substeps {
        Some(n) => format!(", or at least {n} sub-steps"),
        None => String::new(),
    }
)]
pub struct StabilityError {
    /// The method refused.
    pub method: Method,
    /// The sub-step length, in s.
    pub step_s: f64,
    /// Sub-steps per period asked for.
    pub substeps: u32,
    /// The offending eigenvalue of the per-sub-step map, (re, im); the one of largest
    /// magnitude.
    pub eigenvalue: (f64, f64),
    /// Its magnitude (the spectral radius).
    pub radius: f64,
    /// The smallest power-of-two sub-step count that is stable, if one up to 2^20 is.
    pub stable_substeps: Option<u32>,
}

/// The largest-magnitude eigenvalue of a square matrix, as (re, im, |.|); (0, 0, 0) if empty.
#[must_use]
pub fn spectral_radius(map: &DMatrix<f64>) -> (f64, f64, f64) {
    if map.is_empty() {
        return (0.0, 0.0, 0.0);
    }
    map.complex_eigenvalues()
        .iter()
        .map(|z| (z.re, z.im, z.norm()))
        .fold(
            (0.0, 0.0, -1.0),
            |best, z| if z.2 > best.2 { z } else { best },
        )
}

/// [`spectral_radius`] of a map near the identity (a short sub-step's), computed as
/// `1 + eig(Phi - I)`: the eigenvalue solver's rounding is relative to the spread of the
/// eigenvalues it is given, and `Phi`'s cluster within 1e-4 of 1 at sub-steps of 0.1 us, where
/// the solver's rounding on `Phi` itself posed as growth (an explicit Euler map with every
/// continuous mode damped reported 1.00009); `Phi - I` holds them spread out.
fn shifted_spectral_radius(map: &DMatrix<f64>) -> (f64, f64, f64) {
    if map.is_empty() {
        return (0.0, 0.0, 0.0);
    }
    let shifted = map - DMatrix::identity(map.nrows(), map.ncols());
    shifted
        .complex_eigenvalues()
        .iter()
        .map(|z| (1.0 + z.re, z.im, (1.0 + z.re).hypot(z.im)))
        .fold(
            (0.0, 0.0, -1.0),
            |best, z| if z.2 > best.2 { z } else { best },
        )
}

/// A ready-to-run integrator for one drive model and control period.
#[derive(Debug, Clone)]
pub struct Stepper {
    method: Method,
    substeps: u32,
    h_s: f64,
    n: usize,
    /// Row-major `Phi` (exact_zoh, trapezoid) or `A` (rk4, explicit_euler).
    state_map: Vec<f64>,
    /// Row-major `Gamma` (exact_zoh, trapezoid) or `B` (rk4, explicit_euler).
    input_map: Vec<f64>,
    scratch: [Vec<f64>; 5],
}

impl Stepper {
    /// Checks stability and prepares the maps. `substeps` 0 is treated as 1.
    pub fn new(
        model: &DriveModel,
        period_s: f64,
        config: IntegratorConfig,
    ) -> Result<Stepper, StabilityError> {
        let substeps = config.substeps.max(1);
        let h_s = period_s / f64::from(substeps);
        check_stability(model, period_s, substeps, config.method).map_err(|(re, im, radius)| {
            StabilityError {
                method: config.method,
                step_s: h_s,
                substeps,
                eigenvalue: (re, im),
                radius,
                stable_substeps: smallest_stable_substeps(model, period_s, config.method),
            }
        })?;
        let (state_map, input_map) = match config.method {
            Method::ExactZoh | Method::Trapezoid => config.method.step_maps(model, h_s),
            Method::Rk4 | Method::ExplicitEuler => (model.a.clone(), model.b.clone()),
        };
        let n = model.states();
        Ok(Stepper {
            method: config.method,
            substeps,
            h_s,
            n,
            state_map: row_major(&state_map),
            input_map: row_major(&input_map),
            scratch: std::array::from_fn(|_| vec![0.0; n]),
        })
    }

    /// The method.
    #[must_use]
    pub fn method(&self) -> Method {
        self.method
    }

    /// Sub-steps per period.
    #[must_use]
    pub fn substeps(&self) -> u32 {
        self.substeps
    }

    /// Advances `x` by one control period with the coil commands `u` held (the constant
    /// input of [`DriveModel`] is 1).
    pub fn step(&mut self, x: &mut [f64], u: [f64; 2]) {
        let u = [u[0], u[1], 1.0];
        for _ in 0..self.substeps {
            match self.method {
                Method::ExactZoh | Method::Trapezoid => self.linear_map(x, u),
                Method::Rk4 => self.rk4(x, u),
                Method::ExplicitEuler => self.euler(x, u),
            }
        }
    }

    fn linear_map(&mut self, x: &mut [f64], u: [f64; INPUTS]) {
        let [next, ..] = &mut self.scratch;
        derivative(&self.state_map, &self.input_map, self.n, x, u, next);
        x.copy_from_slice(next);
    }

    fn euler(&mut self, x: &mut [f64], u: [f64; INPUTS]) {
        let [k, ..] = &mut self.scratch;
        derivative(&self.state_map, &self.input_map, self.n, x, u, k);
        for (xi, ki) in x.iter_mut().zip(k.iter()) {
            *xi += self.h_s * ki;
        }
    }

    fn rk4(&mut self, x: &mut [f64], u: [f64; INPUTS]) {
        let h = self.h_s;
        let (a, b, n) = (&self.state_map, &self.input_map, self.n);
        let [k1, k2, k3, k4, probe] = &mut self.scratch;
        derivative(a, b, n, x, u, k1);
        axpy_into(probe, x, 0.5 * h, k1);
        derivative(a, b, n, probe, u, k2);
        axpy_into(probe, x, 0.5 * h, k2);
        derivative(a, b, n, probe, u, k3);
        axpy_into(probe, x, h, k3);
        derivative(a, b, n, probe, u, k4);
        for i in 0..n {
            x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
}

/// `out = M x + N u` with row-major `M` (n x n) and `N` (n x [`INPUTS`]).
fn derivative(m: &[f64], nmat: &[f64], n: usize, x: &[f64], u: [f64; INPUTS], out: &mut [f64]) {
    for (r, o) in out.iter_mut().enumerate() {
        let row = &m[r * n..(r + 1) * n];
        let inputs = &nmat[r * INPUTS..(r + 1) * INPUTS];
        let mut acc: f64 = inputs.iter().zip(u).map(|(b, u)| b * u).sum();
        for (mi, xi) in row.iter().zip(x) {
            acc += mi * xi;
        }
        *o = acc;
    }
}

/// `out = x + s k`.
fn axpy_into(out: &mut [f64], x: &[f64], s: f64, k: &[f64]) {
    for ((o, xi), ki) in out.iter_mut().zip(x).zip(k) {
        *o = xi + s * ki;
    }
}

fn row_major(m: &DMatrix<f64>) -> Vec<f64> {
    m.transpose().as_slice().to_vec()
}

/// `Err((re, im, radius))` (the per-sub-step map's dominant eigenvalue) when `method` with
/// `substeps` sub-steps per `period_s` lets a mode grow over one period.
pub fn check_stability(
    model: &DriveModel,
    period_s: f64,
    substeps: u32,
    method: Method,
) -> Result<(), (f64, f64, f64)> {
    let (phi, _) = method.step_maps(model, period_s / f64::from(substeps));
    // A state whose derivative is zero (a saturated amplifier's frozen PI integral) is held
    // exactly: the map is block triangular with a 1 for it, which cannot grow; leaving it out
    // keeps the eigenvalue solver's rounding on that 1 (1e-12 on a stiff map) from posing
    // as growth.
    let moving: Vec<usize> = (0..model.states())
        .filter(|&r| model.a.row(r).iter().any(|&a| a != 0.0))
        .collect();
    let phi = phi.select_rows(&moving).select_columns(&moving);
    let (re, im, radius) = shifted_spectral_radius(&phi);
    let growth = radius.powf(f64::from(substeps));
    if growth.is_finite() && growth <= 1.0 + GROWTH_TOLERANCE {
        Ok(())
    } else {
        Err((re, im, radius))
    }
}

fn smallest_stable_substeps(model: &DriveModel, period_s: f64, method: Method) -> Option<u32> {
    let mut n = 1u32;
    while n <= MAX_SUGGESTED_SUBSTEPS {
        if check_stability(model, period_s, n, method).is_ok() {
            return Some(n);
        }
        n *= 2;
    }
    None
}
