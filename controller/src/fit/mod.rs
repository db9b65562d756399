//! Fitting a measured open-loop response (`scanhil identify --fit`): per axis, the eq. 4
//! parameters (DC gain, natural frequency, damping, delay) and, where the data shows more, a
//! richer model ([`models`]); and the cross-talk between the axes.
//!
//! **Least squares on the complex response, weighted by coherence.** Each point's residual is
//! `(H_model - H) / sigma` in its real and imaginary parts, with
//! `sigma = |H| sqrt((1 - g2) / (2 B g2) + floor^2)`: the normalised random error of an H1
//! estimate averaged over `B` blocks with coherence `g2` (Bendat and Piersol, Random Data,
//! sec. 9.2.4), and a relative floor of [`RELATIVE_FLOOR`] (the analyser's resolution, so a
//! coherence of exactly 1 does not weigh a point infinitely). Relative errors weigh the
//! 80 dB of a response alike. Where the readings' resolution (an AngleReading counts 1 urad)
//! is coarse against the response, its quantisation is added as noise
//! ([`Measured::resolution_of`]): a stepped sine's quantisation repeats every block, so the
//! coherence does not show it. Levenberg-Marquardt ([`levenberg_marquardt`]) from a handful of
//! starts (resonance from the magnitude peak, damping and delay over a grid); the uncertainty
//! of each parameter from the Jacobian at the optimum, scaled by the residuals' scatter.
//!
//! **Model selection by BIC**: `chi^2 + p ln n` with `n` the real residuals (twice the points)
//! and `p` the parameters. A richer model is chosen only when it lowers `chi^2` by more than
//! `ln n` per added parameter (about 4.4 for 40 points): noise alone does not buy a second mode.
//!
//! **Cross-talk**: exciting one axis, the other's response over its own fitted model is the
//! coupling on its input (the emulator's `cross_talk`: `u_alpha + alpha_from_beta u_beta`);
//! its weighted mean over frequency is the coefficient, the per-frequency ratio says how
//! constant it is.

pub mod levenberg_marquardt;
pub mod models;
pub mod twin;

use nalgebra::{Complex, DVector};
use serde::Serialize;

use crate::trajectory::SensingAxis;
use levenberg_marquardt::{LeastSquares, minimise};
use models::{ModelKind, ModelParams, SampledModel, SecondMode};

/// Every point's uncertainty is at least this fraction of its magnitude.
pub const RELATIVE_FLOOR: f64 = 1e-3;

/// One measured frequency, as the fit reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    /// Frequency, Hz.
    pub f_hz: f64,
    /// The response (output units per input unit).
    pub response: Complex<f64>,
    /// Coherence, 0..1.
    pub coherence: f64,
    /// Blocks (or sweeps) averaged.
    pub blocks: u32,
    /// The uncertainty the readings' resolution leaves, output units per input unit (0: none).
    pub resolution: f64,
}

impl Measured {
    /// The standard uncertainty of the response's real and imaginary parts (`None`: unusable).
    #[must_use]
    pub fn sigma(&self) -> Option<f64> {
        let g2 = self.coherence;
        let magnitude = self.response.norm();
        if !(g2 > 0.0 && g2.is_finite() && magnitude > 0.0 && magnitude.is_finite()) {
            return None;
        }
        let random = (1.0 - g2.min(1.0)) / (2.0 * f64::from(self.blocks.max(1)) * g2);
        let relative = magnitude * magnitude * (random + RELATIVE_FLOOR * RELATIVE_FLOOR);
        Some((relative + self.resolution * self.resolution).sqrt())
    }

    /// The uncertainty a reading resolution of `step` (output units) leaves in a response
    /// estimated from blocks of `samples` with excitation coefficient `excitation_dft`:
    /// quantisation as white noise of `step / sqrt 12` per sample, `sqrt(samples)` of it in a
    /// block's coefficient. Not divided by the blocks: a stepped sine repeats its samples each
    /// block, and so its quantisation.
    #[must_use]
    pub fn resolution_of(step: f64, samples: usize, excitation_dft: f64) -> f64 {
        if excitation_dft > 0.0 {
            step / 12f64.sqrt() * (samples as f64).sqrt() / excitation_dft
        } else {
            0.0
        }
    }
}

/// A fitted parameter with its standard uncertainty.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Estimate {
    /// The parameter.
    pub name: &'static str,
    /// Its value.
    pub value: f64,
    /// Its standard uncertainty (one sigma).
    pub std: f64,
    /// Its unit.
    pub unit: &'static str,
}

/// One model fitted.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CandidateFit {
    /// The model.
    pub kind: ModelKind,
    /// Its parameters at the optimum.
    pub params: ModelParams,
    /// The same with uncertainties.
    pub estimates: Vec<Estimate>,
    /// `sum r^2` of the weighted residuals.
    pub chi_squared: f64,
    /// `chi^2 + p ln n`.
    pub bic: f64,
    /// rms of `|H_model / H - 1|` over the points.
    pub rms_relative: f64,
    /// Why the data does not resolve the model's added parts (`None`: it does; eq. 4 always).
    pub unresolved: Option<String>,
}

impl CandidateFit {
    /// Whether the added parts stand out of their uncertainty: a second mode's gain more than
    /// three standard uncertainties from zero, its frequency known to 10 % and its damping
    /// between 1e-4 and 1; a lag's pole known to a factor `e^(1/3)`.
    fn resolution(&self) -> Option<String> {
        let find = |name: &str| self.estimates.iter().find(|e| e.name == name);
        // A NaN uncertainty is not a resolution: each test is written to be false on it.
        if let Some(lag) = find("lag_rad_s")
            && lag.std.partial_cmp(&(lag.value / 3.0)) != Some(std::cmp::Ordering::Less)
        {
            return Some(format!(
                "the lag's pole {:.3e} +- {:.1e} rad/s is not resolved",
                lag.value, lag.std
            ));
        }
        if let (Some(ratio), Some(w), Some(zeta)) = (
            find("mode_gain_ratio"),
            find("mode_natural_freq_rad_s"),
            find("mode_damping_ratio"),
        ) && !(ratio.value.abs() > 3.0 * ratio.std
            && w.std < 0.1 * w.value
            && (1e-4..=1.0).contains(&zeta.value))
        {
            return Some(format!(
                "the second mode (gain ratio {:.2e} +- {:.1e}, {:.3e} +- {:.1e} rad/s, \
                 damping {:.2e}) is not resolved",
                ratio.value, ratio.std, w.value, w.std, zeta.value
            ));
        }
        None
    }
}

/// One point's residual against the chosen model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PointResidual {
    /// Frequency, Hz.
    pub f_hz: f64,
    /// Measured |H|, dB.
    pub measured_db: f64,
    /// Measured arg H, degrees.
    pub measured_deg: f64,
    /// The fit's |H|, dB.
    pub fit_db: f64,
    /// The fit's arg H, degrees.
    pub fit_deg: f64,
    /// Measured minus fit, dB.
    pub error_db: f64,
    /// Measured minus fit, degrees (wrapped to +-180).
    pub error_deg: f64,
    /// `|H - H_model| / sigma`.
    pub normalised: f64,
    /// The point's coherence.
    pub coherence: f64,
}

/// One axis' fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisFit {
    /// The excited (and fitted) axis.
    pub axis: SensingAxis,
    /// The model chosen.
    pub chosen: ModelKind,
    /// Why: each candidate's BIC, chi^2 and parameter count.
    pub selection: String,
    /// The chosen model's parameters.
    pub params: ModelParams,
    /// The same with uncertainties.
    pub estimates: Vec<Estimate>,
    /// Every model fitted.
    pub candidates: Vec<CandidateFit>,
    /// The chosen model's residual at each point.
    pub residuals: Vec<PointResidual>,
    /// The control period the data was sampled at, s.
    pub period_s: f64,
}

impl AxisFit {
    /// The standard uncertainty of the chosen model's parameter `name` (0 when it has none).
    #[must_use]
    pub fn std_of(&self, name: &str) -> f64 {
        self.estimates
            .iter()
            .find(|e| e.name == name)
            .map_or(0.0, |e| e.std)
    }
}

/// Why a response could not be fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// Too few usable points for even eq. 4.
    #[error(
        "{axis:?}: {usable} usable points (coherence above 0, a finite response): eq. 4 needs at least 3"
    )]
    TooFewPoints {
        /// The axis.
        axis: SensingAxis,
        /// How many there were.
        usable: usize,
    },
    /// No start converged.
    #[error("{axis:?}: no fit converged")]
    NoFit {
        /// The axis.
        axis: SensingAxis,
    },
}

/// A point the fit uses.
#[derive(Debug, Clone, Copy)]
struct Point {
    f_hz: f64,
    response: Complex<f64>,
    sigma: f64,
    coherence: f64,
}

/// Fits `points` (one axis' open-loop response, sampled at `period_s`) with every model and
/// keeps the one with the lowest BIC.
///
/// # Errors
/// [`FitError`] when too few points are usable or nothing converges.
pub fn fit_axis(
    axis: SensingAxis,
    points: &[Measured],
    period_s: f64,
) -> Result<AxisFit, FitError> {
    let mut usable: Vec<Point> = points
        .iter()
        .filter_map(|m| {
            Some(Point {
                f_hz: m.f_hz,
                response: m.response,
                sigma: m.sigma()?,
                coherence: m.coherence,
            })
        })
        .collect();
    usable.sort_by(|a, b| a.f_hz.total_cmp(&b.f_hz));
    if usable.len() < 3 {
        return Err(FitError::TooFewPoints {
            axis,
            usable: usable.len(),
        });
    }
    let problem = Problem {
        points: &usable,
        period_s,
        sign: if usable[0].response.re >= 0.0 {
            1.0
        } else {
            -1.0
        },
    };
    let eq4 = problem.fit_eq4().ok_or(FitError::NoFit { axis })?;
    let lag = problem.fit_from(ModelKind::Eq4Lag, &problem.lag_starts(&eq4.params));
    let mode = problem.fit_from(ModelKind::Eq4Mode, &problem.mode_starts(&eq4.params));
    let mode_lag = mode.as_ref().and_then(|mode| {
        problem.fit_from(ModelKind::Eq4ModeLag, &problem.lag_starts(&mode.params))
    });
    let candidates: Vec<CandidateFit> = [Some(eq4), lag, mode, mode_lag]
        .into_iter()
        .flatten()
        .filter(|c| 2 * usable.len() > c.kind.parameter_count())
        .map(|mut c| {
            c.unresolved = c.resolution();
            c
        })
        .collect();
    let best = candidates
        .iter()
        .filter(|c| c.unresolved.is_none())
        .min_by(|a, b| a.bic.total_cmp(&b.bic))
        .ok_or(FitError::NoFit { axis })?
        .clone();
    let selection = format!(
        "{:?}: the lowest BIC (chi^2 + p ln n, n = {} residuals) of the models whose added \
         parts the data resolves: {}",
        best.kind,
        2 * usable.len(),
        candidates
            .iter()
            .map(|c| format!(
                "{:?} BIC {:.1} (chi^2 {:.1}, p {}, rms {:.2e}{})",
                c.kind,
                c.bic,
                c.chi_squared,
                c.kind.parameter_count(),
                c.rms_relative,
                c.unresolved
                    .as_ref()
                    .map_or(String::new(), |why| format!("; {why}"))
            ))
            .collect::<Vec<_>>()
            .join("; ")
    );
    let sampled = best.params.sampled(period_s);
    let residuals = usable
        .iter()
        .map(|p| residual(p, sampled.response(p.f_hz)))
        .collect();
    Ok(AxisFit {
        axis,
        chosen: best.kind,
        selection,
        params: best.params,
        estimates: best.estimates.clone(),
        candidates,
        residuals,
        period_s,
    })
}

fn residual(point: &Point, model: Complex<f64>) -> PointResidual {
    let db = |h: Complex<f64>| 20.0 * h.norm().log10();
    let deg = |h: Complex<f64>| h.arg().to_degrees();
    let error_deg = (deg(point.response) - deg(model) + 180.0).rem_euclid(360.0) - 180.0;
    PointResidual {
        f_hz: point.f_hz,
        measured_db: db(point.response),
        measured_deg: deg(point.response),
        fit_db: db(model),
        fit_deg: deg(model),
        error_db: db(point.response) - db(model),
        error_deg,
        normalised: (point.response - model).norm() / point.sigma,
        coherence: point.coherence,
    }
}

/// One axis' data and what every fit of it shares.
struct Problem<'a> {
    points: &'a [Point],
    period_s: f64,
    sign: f64,
}

impl Problem<'_> {
    /// The weighted residuals of a model's parameter vector (`None`: unusable parameters).
    fn residuals(&self, kind: ModelKind, v: &DVector<f64>) -> Option<DVector<f64>> {
        let params = ModelParams::from_vector(kind, v, self.sign, self.period_s);
        // A second mode is only seen inside the measured band (an octave either side).
        let tau = std::f64::consts::TAU;
        let band = [
            tau * self.points[0].f_hz / 2.0,
            tau * 2.0 * self.points[self.points.len() - 1].f_hz,
        ];
        let usable = v.iter().all(|x| x.is_finite())
            && params.delay_s >= 0.0
            && params.damping_ratio < 10.0
            && params.mode.is_none_or(|m| {
                m.damping_ratio < 10.0 && (band[0]..=band[1]).contains(&m.natural_freq_rad_s)
            })
            && v.iter().all(|x| x.abs() < 700.0);
        if !usable {
            return None;
        }
        let sampled = params.sampled(self.period_s);
        let mut r = Vec::with_capacity(2 * self.points.len());
        for p in self.points {
            let e = (sampled.response(p.f_hz) - p.response) / p.sigma;
            if !(e.re.is_finite() && e.im.is_finite()) {
                return None;
            }
            r.extend([e.re, e.im]);
        }
        Some(DVector::from_vec(r))
    }

    /// The cost of a start (infinite when unusable).
    fn cost(&self, kind: ModelKind, start: &ModelParams) -> f64 {
        self.residuals(kind, &start.to_vector(self.period_s))
            .map_or(f64::INFINITY, |r| r.norm_squared())
    }

    /// Levenberg-Marquardt from the best few of `starts`; the best optimum.
    fn fit_from(&self, kind: ModelKind, starts: &[ModelParams]) -> Option<CandidateFit> {
        let mut ranked: Vec<(f64, &ModelParams)> =
            starts.iter().map(|s| (self.cost(kind, s), s)).collect();
        ranked.retain(|(c, _)| c.is_finite());
        ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
        let residuals = |v: &DVector<f64>| self.residuals(kind, v);
        ranked
            .iter()
            .take(4)
            .filter_map(|(_, start)| minimise(&residuals, start.to_vector(self.period_s)))
            .min_by(|a, b| a.cost.total_cmp(&b.cost))
            .map(|optimum| self.candidate(kind, &optimum))
    }

    fn candidate(&self, kind: ModelKind, optimum: &LeastSquares) -> CandidateFit {
        let params = ModelParams::from_vector(kind, &optimum.params, self.sign, self.period_s);
        let n = 2 * self.points.len();
        let sampled = params.sampled(self.period_s);
        let rms_relative = (self
            .points
            .iter()
            .map(|p| (sampled.response(p.f_hz) / p.response - 1.0).norm_sqr())
            .sum::<f64>()
            / self.points.len() as f64)
            .sqrt();
        CandidateFit {
            kind,
            params,
            estimates: estimates(kind, &params, optimum, self.period_s),
            chi_squared: optimum.cost,
            bic: optimum.cost + kind.parameter_count() as f64 * (n as f64).ln(),
            rms_relative,
            unresolved: None,
        }
    }

    /// Eq. 4 from a grid of starts around the magnitude peak.
    fn fit_eq4(&self) -> Option<CandidateFit> {
        let peak = self
            .points
            .iter()
            .max_by(|a, b| a.response.norm().total_cmp(&b.response.norm()))?;
        let low = self.points[0];
        let wp = std::f64::consts::TAU * peak.f_hz;
        let ratio = low.f_hz / peak.f_hz;
        let k = low.response.norm()
            * if ratio < 0.5 {
                1.0 - ratio * ratio
            } else {
                1.0
            };
        let mut starts = Vec::new();
        for scale in [0.8, 0.9, 1.0, 1.1, 1.25] {
            for zeta in [
                0.003,
                0.01,
                0.03,
                0.1,
                0.3,
                k / (2.0 * peak.response.norm()),
            ] {
                for periods in [0.5, 1.0, 2.0] {
                    starts.push(ModelParams {
                        dc_gain: self.sign * k,
                        natural_freq_rad_s: wp * scale,
                        damping_ratio: zeta.clamp(1e-4, 2.0),
                        delay_s: periods * self.period_s,
                        lag_rad_s: None,
                        mode: None,
                    });
                }
            }
        }
        self.fit_from(ModelKind::Eq4, &starts)
    }

    /// Starts with a lag added to `base`: poles from a quarter of Nyquist to eight times it,
    /// the delay lowered by the lag's own `1 / wl`.
    fn lag_starts(&self, base: &ModelParams) -> Vec<ModelParams> {
        let nyquist = std::f64::consts::PI / self.period_s;
        [0.25, 0.5, 1.0, 2.0, 4.0, 8.0]
            .iter()
            .map(|f| {
                let wl = f * nyquist;
                ModelParams {
                    lag_rad_s: Some(wl),
                    delay_s: (base.delay_s - 1.0 / wl).max(0.0),
                    ..*base
                }
            })
            .collect()
    }

    /// Starts with a second mode added to eq. 4's fit: at the points where its relative
    /// residual stands out most, each with its best gain ratio for a few dampings.
    fn mode_starts(&self, base: &ModelParams) -> Vec<ModelParams> {
        let sampled = base.sampled(self.period_s);
        let mut standing_out: Vec<(f64, &Point)> = self
            .points
            .iter()
            .map(|p| ((p.response - sampled.response(p.f_hz)).norm() / p.sigma, p))
            .collect();
        standing_out.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut starts = Vec::new();
        for (_, point) in standing_out.iter().take(3) {
            for zeta in [0.01, 0.05, 0.2] {
                let shape = ModelParams {
                    mode: Some(SecondMode {
                        gain_ratio: 1.0,
                        natural_freq_rad_s: std::f64::consts::TAU * point.f_hz,
                        damping_ratio: zeta,
                    }),
                    ..*base
                };
                let ratio = self.best_mode_ratio(base, &sampled, &shape.sampled(self.period_s));
                starts.push(ModelParams {
                    mode: shape.mode.map(|m| SecondMode {
                        gain_ratio: ratio,
                        ..m
                    }),
                    ..*base
                });
            }
        }
        starts
    }

    /// The mode's gain ratio that best explains eq. 4's residual (the mode enters linearly).
    fn best_mode_ratio(
        &self,
        _: &ModelParams,
        base: &SampledModel,
        with_unit_mode: &SampledModel,
    ) -> f64 {
        let (mut num, mut den) = (0.0, 0.0);
        for p in self.points {
            let b0 = base.response(p.f_hz);
            let shape = with_unit_mode.response(p.f_hz) - b0;
            let miss = p.response - b0;
            let w = 1.0 / (p.sigma * p.sigma);
            num += w * (shape.conj() * miss).re;
            den += w * shape.norm_sqr();
        }
        if den > 0.0 { num / den } else { 0.0 }
    }
}

/// Each parameter in its own unit, with its standard uncertainty from the covariance of the
/// fit's vector (logarithms: relative; the delay: in periods).
fn estimates(
    kind: ModelKind,
    params: &ModelParams,
    optimum: &LeastSquares,
    period_s: f64,
) -> Vec<Estimate> {
    let std = |i: usize| optimum.covariance[(i, i)].max(0.0).sqrt();
    let mut out = vec![
        (params.dc_gain, params.dc_gain.abs() * std(0)),
        (
            params.natural_freq_rad_s,
            params.natural_freq_rad_s * std(1),
        ),
        (params.damping_ratio, params.damping_ratio * std(2)),
        (params.delay_s, period_s * std(3)),
    ];
    let mut next = 4;
    if let Some(wl) = params.lag_rad_s {
        out.push((wl, wl * std(next)));
        next += 1;
    }
    if let Some(mode) = params.mode {
        out.extend([
            (mode.gain_ratio, std(next)),
            (
                mode.natural_freq_rad_s,
                mode.natural_freq_rad_s * std(next + 1),
            ),
            (mode.damping_ratio, mode.damping_ratio * std(next + 2)),
        ]);
    }
    ModelParams::names(kind)
        .into_iter()
        .zip(out)
        .map(|((name, unit), (value, std))| Estimate {
            name,
            value,
            std,
            unit,
        })
        .collect()
}

/// The cross-talk from one axis' excitation onto the other.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CrossTalkFit {
    /// The excited axis.
    pub from: SensingAxis,
    /// The responding axis.
    pub to: SensingAxis,
    /// The coupling on `to`'s input (the scene's `cross_talk.<to>_from_<from>`).
    pub coefficient: f64,
    /// Its standard uncertainty.
    pub std: f64,
    /// The coupling's quadrature part (0 for a static coupling).
    pub quadrature: f64,
    /// `20 log10 |coefficient|`, dB.
    pub level_db: f64,
    /// The ratio of the measured cross response to `to`'s model at each frequency:
    /// `(f_hz, dB, degrees, coherence)`.
    pub per_frequency: Vec<(f64, f64, f64, f64)>,
}

impl CrossTalkFit {
    /// Whether the coupling is there: more than three standard uncertainties from zero and
    /// above the analyser's floor ([`RELATIVE_FLOOR`] of the direct path: -60 dB), so the
    /// numerical dust of an uncoupled plant's ringing is not a coupling however sure its fit.
    #[must_use]
    pub fn stands_out(&self) -> bool {
        self.coefficient.abs() > 3.0 * self.std && self.coefficient.abs() > RELATIVE_FLOOR
    }
}

/// Fits the coupling of `cross` (the responding axis' response to the excitation of `from`)
/// over the responding axis' own fitted model. `None` without usable points.
#[must_use]
pub fn fit_cross_talk(
    from: SensingAxis,
    cross: &[Measured],
    to_model: &AxisFit,
) -> Option<CrossTalkFit> {
    let model = to_model.params.sampled(to_model.period_s);
    let mut terms = Vec::new();
    for m in cross {
        let Some(sigma) = m.sigma() else { continue };
        let g = model.response(m.f_hz);
        terms.push((m, g, 1.0 / (sigma * sigma)));
    }
    if terms.is_empty() {
        return None;
    }
    let (mut num, mut den) = (Complex::new(0.0, 0.0), 0.0);
    for (m, g, w) in &terms {
        num += g.conj() * m.response * *w;
        den += w * g.norm_sqr();
    }
    let c = num / den;
    let chi2: f64 = terms
        .iter()
        .map(|(m, g, w)| w * (m.response - c * g).norm_sqr())
        .sum();
    let dof = (2 * terms.len()).saturating_sub(2).max(1) as f64;
    Some(CrossTalkFit {
        from,
        to: to_model.axis,
        coefficient: c.re,
        std: (chi2 / dof / den).sqrt(),
        quadrature: c.im,
        level_db: 20.0 * c.norm().log10(),
        per_frequency: terms
            .iter()
            .map(|(m, g, _)| {
                let ratio = m.response / g;
                (
                    m.f_hz,
                    20.0 * ratio.norm().log10(),
                    ratio.arg().to_degrees(),
                    m.coherence,
                )
            })
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    const T: f64 = 50e-6;

    fn log_frequencies(n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| 2.0 * 1000f64.powf(i as f64 / (n - 1) as f64))
            .collect()
    }

    /// `truth` measured at 40 points with relative complex noise of `noise` (seeded), the
    /// coherence that noise gives over 4 blocks.
    fn measured(truth: &ModelParams, noise: f64, seed: u64) -> Vec<Measured> {
        let sampled = truth.sampled(T);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        log_frequencies(40)
            .into_iter()
            .map(|f| {
                let h = sampled.response(f);
                let mut gauss = || {
                    let (u1, u2): (f64, f64) = (1.0 - rng.random::<f64>(), rng.random());
                    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
                };
                let e = Complex::new(gauss(), gauss()) * (noise / std::f64::consts::SQRT_2);
                // eps^2 = (1 - g2) / (2 B g2) with B = 4: g2 = 1 / (1 + 8 eps^2).
                Measured {
                    f_hz: f,
                    response: h * (e + 1.0),
                    coherence: 1.0 / (1.0 + 8.0 * noise * noise),
                    blocks: 4,
                    resolution: 0.0,
                }
            })
            .collect()
    }

    fn differing() -> ModelParams {
        ModelParams {
            dc_gain: 8.7,
            natural_freq_rad_s: 2.0 * std::f64::consts::PI * 31.0,
            damping_ratio: 0.021,
            ..ModelParams::paper(T)
        }
    }

    #[test]
    fn noise_free_eq4_is_recovered_exactly_and_chosen() {
        let truth = differing();
        let fit = fit_axis(SensingAxis::Alpha, &measured(&truth, 0.0, 1), T).unwrap();
        assert_eq!(fit.chosen, ModelKind::Eq4, "{}", fit.selection);
        for (got, want) in [
            (fit.params.dc_gain, truth.dc_gain),
            (fit.params.natural_freq_rad_s, truth.natural_freq_rad_s),
            (fit.params.damping_ratio, truth.damping_ratio),
            (fit.params.delay_s, truth.delay_s),
        ] {
            assert!(
                (got / want - 1.0).abs() < 1e-6,
                "{got} vs {want}: {:?}",
                fit.params
            );
        }
    }

    #[test]
    fn with_noise_the_estimates_hold_the_truth_within_their_uncertainty() {
        let truth = differing();
        let fit = fit_axis(SensingAxis::Beta, &measured(&truth, 0.01, 7), T).unwrap();
        assert_eq!(fit.chosen, ModelKind::Eq4, "{}", fit.selection);
        let want = [
            truth.dc_gain,
            truth.natural_freq_rad_s,
            truth.damping_ratio,
            truth.delay_s,
        ];
        for (e, want) in fit.estimates.iter().zip(want) {
            assert!(e.std > 0.0, "{e:?}");
            assert!((e.value - want).abs() < 4.0 * e.std, "{e:?} against {want}");
        }
        // 1 % noise: K and ws to a fraction of a per cent, zeta to a few.
        assert!(
            fit.estimates[0].std / truth.dc_gain < 3e-3,
            "{:?}",
            fit.estimates[0]
        );
        assert!(
            fit.estimates[2].std / truth.damping_ratio < 0.05,
            "{:?}",
            fit.estimates[2]
        );
    }

    #[test]
    fn a_lag_is_found_and_chosen_where_the_data_shows_it() {
        let truth = ModelParams {
            lag_rad_s: Some(std::f64::consts::TAU * 10_000.0),
            ..differing()
        };
        let fit = fit_axis(SensingAxis::Alpha, &measured(&truth, 0.0, 1), T).unwrap();
        assert_eq!(fit.chosen, ModelKind::Eq4Lag, "{}", fit.selection);
        let wl = fit.params.lag_rad_s.unwrap();
        assert!(
            (wl / truth.lag_rad_s.unwrap() - 1.0).abs() < 0.05,
            "{:?}",
            fit.params
        );
    }

    #[test]
    fn a_second_mode_is_found_and_chosen_where_the_data_shows_it() {
        let truth = ModelParams {
            mode: Some(SecondMode {
                gain_ratio: 0.004,
                natural_freq_rad_s: std::f64::consts::TAU * 450.0,
                damping_ratio: 0.03,
            }),
            ..differing()
        };
        let fit = fit_axis(SensingAxis::Alpha, &measured(&truth, 0.002, 3), T).unwrap();
        assert_eq!(fit.chosen, ModelKind::Eq4Mode, "{}", fit.selection);
        let mode = fit.params.mode.unwrap();
        assert!(
            (mode.natural_freq_rad_s / (std::f64::consts::TAU * 450.0) - 1.0).abs() < 0.02,
            "{mode:?}"
        );
    }

    #[test]
    fn the_cross_talk_is_the_other_axis_response_over_its_model() {
        let truth = differing();
        let fit = fit_axis(SensingAxis::Beta, &measured(&truth, 0.0, 1), T).unwrap();
        let cross: Vec<Measured> = measured(&truth, 0.0, 1)
            .into_iter()
            .map(|m| Measured {
                response: m.response * -0.07,
                ..m
            })
            .collect();
        let c = fit_cross_talk(SensingAxis::Alpha, &cross, &fit).unwrap();
        assert!((c.coefficient + 0.07).abs() < 1e-9, "{c:?}");
        assert!(c.quadrature.abs() < 1e-9, "{c:?}");
        assert!((c.level_db - 20.0 * 0.07f64.log10()).abs() < 1e-6);
        assert_eq!(c.to, SensingAxis::Beta);
    }

    #[test]
    fn too_few_points_are_an_error() {
        let mut points = measured(&differing(), 0.0, 1);
        for p in points.iter_mut().skip(2) {
            p.coherence = 0.0;
        }
        assert_eq!(
            fit_axis(SensingAxis::Alpha, &points, T),
            Err(FitError::TooFewPoints {
                axis: SensingAxis::Alpha,
                usable: 2
            })
        );
    }
}
