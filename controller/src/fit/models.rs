//! The models a measured open-loop response is fitted with, and their response as the loop
//! samples it.
//!
//! - `eq4`: eq. 4, `K ws^2 / (s^2 + 2 zeta ws s + ws^2)` with its input delay `Ta`;
//! - `eq4_lag`: eq. 4 behind a first-order lag `wl / (s + wl)` (the amplifier's current loop,
//!   or an angle sensor's bandwidth);
//! - `eq4_mode`: eq. 4 plus a second mechanical mode `r K w2^2 / (s^2 + 2 z2 w2 s + w2^2)`
//!   (modal superposition; `r` may be negative);
//! - `eq4_mode_lag`: both.
//!
//! The response is the one the loop measures: the command held over a period (zero-order
//! hold), acting `delay_s` after its period starts (the emulator: one period), sampled at the
//! period ends. In partial fractions `G(s) = sum_i r_i / (s - p_i)` each pole samples to
//! `r_i (g1 + g0 z^-1) / (z - e^(p_i T))`, `g1 = (e^(p (T - d)) - 1) / p` the command's own
//! share over the last `T - d` of the period and `g0 = e^(p (T - d)) (e^(p d) - 1) / p` the
//! previous command's over its first `d`, for `delay_s = m T + d` times `z^-m` (the modified
//! z-transform, in closed form: scalar arithmetic only, so a fit evaluates thousands of
//! parameter sets quickly, and a model and the emulator agree to rounding). Poles are simple:
//! a critically damped mode (zeta exactly 1) or a lag on a mode's pole has no partial
//! fractions and is out of the fit's reach (a measure-zero set).

use nalgebra::{Complex, DVector};

/// Which model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ModelKind {
    /// Eq. 4 with its delay.
    Eq4,
    /// Eq. 4 behind a first-order lag.
    Eq4Lag,
    /// Eq. 4 plus a second mode.
    Eq4Mode,
    /// Eq. 4 plus a second mode, behind a first-order lag.
    Eq4ModeLag,
}

impl ModelKind {
    /// Every model, simplest first.
    pub const ALL: [ModelKind; 4] = [
        ModelKind::Eq4,
        ModelKind::Eq4Lag,
        ModelKind::Eq4Mode,
        ModelKind::Eq4ModeLag,
    ];

    /// The number of free parameters.
    #[must_use]
    pub fn parameter_count(self) -> usize {
        match self {
            ModelKind::Eq4 => 4,
            ModelKind::Eq4Lag => 5,
            ModelKind::Eq4Mode => 7,
            ModelKind::Eq4ModeLag => 8,
        }
    }

    /// Whether the model has the first-order lag.
    #[must_use]
    pub fn has_lag(self) -> bool {
        matches!(self, ModelKind::Eq4Lag | ModelKind::Eq4ModeLag)
    }

    /// Whether the model has the second mode.
    #[must_use]
    pub fn has_mode(self) -> bool {
        matches!(self, ModelKind::Eq4Mode | ModelKind::Eq4ModeLag)
    }
}

/// A second mechanical mode.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SecondMode {
    /// Its DC gain over eq. 4's `K` (negative: out of phase).
    pub gain_ratio: f64,
    /// Its natural frequency, rad/s.
    pub natural_freq_rad_s: f64,
    /// Its damping ratio.
    pub damping_ratio: f64,
}

/// A model's parameters.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ModelParams {
    /// Eq. 4's `K` (output units per input unit; negative for a reversed axis).
    pub dc_gain: f64,
    /// Eq. 4's `ws`, rad/s.
    pub natural_freq_rad_s: f64,
    /// Eq. 4's `zeta`.
    pub damping_ratio: f64,
    /// Eq. 4's `Ta`: the command acts this long after its period starts, s (the emulator and
    /// the paper: one period).
    pub delay_s: f64,
    /// The first-order lag's pole, rad/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lag_rad_s: Option<f64>,
    /// The second mode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mode: Option<SecondMode>,
}

impl ModelParams {
    /// Eq. 4 as printed, with the delay of one period at `period_s`.
    #[must_use]
    pub fn paper(period_s: f64) -> ModelParams {
        ModelParams {
            dc_gain: 11.4,
            natural_freq_rad_s: 140.68,
            damping_ratio: 3.21e-2,
            delay_s: period_s,
            lag_rad_s: None,
            mode: None,
        }
    }

    /// The model these parameters are of.
    #[must_use]
    pub fn kind(&self) -> ModelKind {
        match (self.mode.is_some(), self.lag_rad_s.is_some()) {
            (false, false) => ModelKind::Eq4,
            (false, true) => ModelKind::Eq4Lag,
            (true, false) => ModelKind::Eq4Mode,
            (true, true) => ModelKind::Eq4ModeLag,
        }
    }

    /// The fit's parameter vector: logarithms of the positive ones, the delay in periods
    /// (the sign of `K` is kept apart, fixed during a fit).
    #[must_use]
    pub fn to_vector(&self, period_s: f64) -> DVector<f64> {
        let mut v = vec![
            self.dc_gain.abs().ln(),
            self.natural_freq_rad_s.ln(),
            self.damping_ratio.ln(),
            self.delay_s / period_s,
        ];
        if let Some(lag) = self.lag_rad_s {
            v.push(lag.ln());
        }
        if let Some(mode) = self.mode {
            v.extend([
                mode.gain_ratio,
                mode.natural_freq_rad_s.ln(),
                mode.damping_ratio.ln(),
            ]);
        }
        DVector::from_vec(v)
    }

    /// The parameters of a vector of `kind` (as [`Self::to_vector`]) with the sign of `K`.
    #[must_use]
    pub fn from_vector(kind: ModelKind, v: &DVector<f64>, sign: f64, period_s: f64) -> ModelParams {
        let lag_at = 4;
        let mode_at = if kind.has_lag() { 5 } else { 4 };
        ModelParams {
            dc_gain: sign * v[0].exp(),
            natural_freq_rad_s: v[1].exp(),
            damping_ratio: v[2].exp(),
            delay_s: v[3] * period_s,
            lag_rad_s: kind.has_lag().then(|| v[lag_at].exp()),
            mode: kind.has_mode().then(|| SecondMode {
                gain_ratio: v[mode_at],
                natural_freq_rad_s: v[mode_at + 1].exp(),
                damping_ratio: v[mode_at + 2].exp(),
            }),
        }
    }

    /// The names and units of the vector's entries, as reported (each converted back to its
    /// own unit: `K`, rad/s, 1, s, rad/s, 1, rad/s, 1).
    #[must_use]
    pub fn names(kind: ModelKind) -> Vec<(&'static str, &'static str)> {
        let mut names = vec![
            ("dc_gain", ""),
            ("natural_freq_rad_s", "rad/s"),
            ("damping_ratio", ""),
            ("delay_s", "s"),
        ];
        if kind.has_lag() {
            names.push(("lag_rad_s", "rad/s"));
        }
        if kind.has_mode() {
            names.extend([
                ("mode_gain_ratio", ""),
                ("mode_natural_freq_rad_s", "rad/s"),
                ("mode_damping_ratio", ""),
            ]);
        }
        names
    }

    /// The continuous poles and their residues: `G(s) = sum_i r_i / (s - p_i)` (eq. 4's pair,
    /// the second mode's, the lag's pole).
    fn partial_fractions(&self) -> Vec<(Complex<f64>, Complex<f64>)> {
        let lag = |s: Complex<f64>| {
            self.lag_rad_s
                .map_or(Complex::new(1.0, 0.0), |wl| wl / (s + wl))
        };
        let modes: Vec<(f64, f64, f64)> =
            std::iter::once((self.dc_gain, self.natural_freq_rad_s, self.damping_ratio))
                .chain(self.mode.map(|m| {
                    (
                        m.gain_ratio * self.dc_gain,
                        m.natural_freq_rad_s,
                        m.damping_ratio,
                    )
                }))
                .collect();
        let second = |s: Complex<f64>, &(k, w, z): &(f64, f64, f64)| {
            k * w * w / (s * s + s * (2.0 * z * w) + w * w)
        };
        let mut out = Vec::with_capacity(5);
        for mode in &modes {
            let (k, w, z) = *mode;
            // s^2 + 2 z w s + w^2 = (s - p1)(s - p2); residue of k w^2 / ((s - p1)(s - p2)) at
            // p1 is k w^2 / (p1 - p2), times the lag (and the other mode is regular there).
            let root = Complex::new(z * z - 1.0, 0.0).sqrt() * w;
            let (p1, p2) = (-z * w + root, -z * w - root);
            for (p, q) in [(p1, p2), (p2, p1)] {
                out.push((p, k * w * w / (p - q) * lag(p)));
            }
        }
        if let Some(wl) = self.lag_rad_s {
            let p = Complex::new(-wl, 0.0);
            let sum: Complex<f64> = modes.iter().map(|m| second(p, m)).sum();
            out.push((p, sum * wl));
        }
        out
    }

    /// The model as the loop samples it at `period_s`.
    #[must_use]
    pub fn sampled(&self, period_s: f64) -> SampledModel {
        let delay = self.delay_s.max(0.0);
        let whole = (delay / period_s).floor();
        let fraction = (delay - whole * period_s).clamp(0.0, period_s);
        // y' = p y + r u over a period whose input is the previous command for `d`, then this
        // one: y[k+1] = e^(pT) y[k] + r g1 u[k] + r g0 u[k-1].
        let terms = self
            .partial_fractions()
            .into_iter()
            .map(|(p, r)| {
                let late = expm1_over(p, period_s - fraction);
                let early = (p * (period_s - fraction)).exp() * expm1_over(p, fraction);
                PoleTerm {
                    pole: (p * period_s).exp(),
                    late: r * late,
                    early: r * early,
                }
            })
            .collect();
        SampledModel {
            whole_periods: whole as i32,
            terms,
            period_s,
        }
    }
}

/// `(e^(p tau) - 1) / p`, accurate for small `p tau` (and `tau` at `p = 0`).
fn expm1_over(p: Complex<f64>, tau: f64) -> Complex<f64> {
    if p.norm() * tau < 1e-300 || p.norm() == 0.0 {
        return Complex::new(tau, 0.0);
    }
    let half = p * (tau / 2.0);
    // e^x - 1 = 2 sinh(x/2) e^(x/2), without the cancellation of e^x - 1 near 0.
    half.sinh() * half.exp() * 2.0 / p
}

/// One pole of a sampled model: `(late + early z^-1) / (z - pole)`.
#[derive(Debug, Clone, Copy)]
struct PoleTerm {
    pole: Complex<f64>,
    late: Complex<f64>,
    early: Complex<f64>,
}

/// A model sampled at the control period, ready to be evaluated at any frequency.
#[derive(Debug, Clone)]
pub struct SampledModel {
    whole_periods: i32,
    terms: Vec<PoleTerm>,
    period_s: f64,
}

impl SampledModel {
    /// The response at `f_hz` (output units per input unit).
    #[must_use]
    pub fn response(&self, f_hz: f64) -> Complex<f64> {
        let z = Complex::from_polar(1.0, std::f64::consts::TAU * f_hz * self.period_s);
        let zi = z.inv();
        let sum: Complex<f64> = self
            .terms
            .iter()
            .map(|t| (t.late + t.early * zi) / (z - t.pole))
            .sum();
        sum * zi.powi(self.whole_periods)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant_model::PlantModel;

    #[test]
    fn eq4_with_one_period_of_delay_is_the_emulators_plant() {
        for period_s in [50e-6, 1.0 / 2736.0] {
            let model = ModelParams::paper(period_s).sampled(period_s);
            let nominal = PlantModel::default().discrete(period_s);
            for f in [0.5, 22.39, 100.0, 1000.0, 0.45 / period_s] {
                let (got, want) = (model.response(f), nominal.response(f, period_s));
                assert!(
                    (got - want).norm() < 1e-9 * want.norm(),
                    "{f} Hz: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn a_fractional_delay_matches_the_plant_models_extra_delay() {
        let period_s = 1.0 / 2736.0;
        let extra = 0.37 * period_s;
        let params = ModelParams {
            delay_s: period_s + extra,
            ..ModelParams::paper(period_s)
        };
        let plant = PlantModel {
            extra_delay_s: extra,
            ..PlantModel::default()
        };
        let (model, nominal) = (params.sampled(period_s), plant.discrete(period_s));
        for f in [1.0, 22.0, 300.0] {
            let (got, want) = (model.response(f), nominal.response(f, period_s));
            assert!(
                (got - want).norm() < 1e-9 * want.norm(),
                "{f} Hz: {got} vs {want}"
            );
        }
    }

    #[test]
    fn the_lag_and_the_mode_add_their_continuous_responses_at_low_frequency() {
        // Far below Nyquist the sampled response is the continuous one with the delay and the
        // hold's half period.
        let period_s = 50e-6;
        let params = ModelParams {
            lag_rad_s: Some(2.0 * std::f64::consts::PI * 3000.0),
            mode: Some(SecondMode {
                gain_ratio: -0.02,
                natural_freq_rad_s: 2.0 * std::f64::consts::PI * 400.0,
                damping_ratio: 0.05,
            }),
            ..ModelParams::paper(period_s)
        };
        let model = params.sampled(period_s);
        for f in [5.0, 50.0, 400.0] {
            let s = Complex::new(0.0, std::f64::consts::TAU * f);
            let mode = params.mode.unwrap();
            let second = |k: f64, w: f64, z: f64| k * w * w / (s * s + s * (2.0 * z * w) + w * w);
            let continuous = (second(11.4, 140.68, 3.21e-2)
                + second(
                    mode.gain_ratio * 11.4,
                    mode.natural_freq_rad_s,
                    mode.damping_ratio,
                ))
                * (params.lag_rad_s.unwrap() / (s + params.lag_rad_s.unwrap()))
                * (-s * 1.5 * period_s).exp();
            let got = model.response(f);
            assert!(
                (got - continuous).norm() < 2e-3 * continuous.norm(),
                "{f} Hz: {got} vs {continuous}"
            );
        }
    }

    #[test]
    fn vectors_round_trip() {
        let params = ModelParams {
            dc_gain: -9.0,
            lag_rad_s: Some(5e4),
            mode: Some(SecondMode {
                gain_ratio: 0.1,
                natural_freq_rad_s: 3000.0,
                damping_ratio: 0.02,
            }),
            ..ModelParams::paper(1e-4)
        };
        let back = ModelParams::from_vector(params.kind(), &params.to_vector(1e-4), -1.0, 1e-4);
        for (a, b) in [
            (back.dc_gain, params.dc_gain),
            (back.natural_freq_rad_s, params.natural_freq_rad_s),
            (back.delay_s, params.delay_s),
            (back.lag_rad_s.unwrap(), 5e4),
            (back.mode.unwrap().natural_freq_rad_s, 3000.0),
        ] {
            assert!((a - b).abs() < 1e-9 * b.abs(), "{a} vs {b}");
        }
        assert_eq!(
            ModelParams::names(params.kind()).len(),
            params.kind().parameter_count()
        );
    }
}
