//! The dual-tone design rule: resonant tones on an equalised plant (internal-model principle),
//! in the factored form of the paper's eq. 5.
//!
//! ```text
//! C(s) = E(s) sum_i R_i(s)
//! E(s)   = (s^2 + 2 zs ws s + ws^2) / (K ws^2) * wr^2 / (s^2 + 2 zr wr s + wr^2)
//! R_i(s) = k_i (s cos phi_i - w_i sin phi_i) / (s^2 + 2 zt w_i s + w_i^2)
//! ```
//!
//! - **Equaliser** `E`: a zero pair on the plant's resonance (eq. 4's `ws`, `zs`) and a
//!   well-damped roll-off pair at `wr`, scaled by `1/K`: the tones see `Q = P E`, close to a
//!   unit gain with the loop's delay. Table I has the same pair: zeros at 141 rad/s, damping
//!   0.0255, on eq. 4's 140.68 rad/s, and a roll-off pair at 1.13e4 rad/s, damping 0.667.
//! - **Tones** `R_i`: a pole pair at each drive frequency `w_i` (internal model of the
//!   reference: the loop gain there is `1 / (2 zt)` times the tone's, so the error at `w_i` is
//!   about `zt w_i / sigma_i`, zero for `zt = 0`). Near its pole the tone is
//!   `R_i ~ (k_i/2) e^(j phi_i) / (s - s_i)`; around the rest of the loop
//!   `G_i = Q / (1 + Q sum_{j != i} R_j)` the closed-loop pole moves from `s_i` by
//!   `delta = -(k_i/2) e^(j phi_i) G_i(j w_i)`. The rule picks `phi_i = -arg G_i(j w_i)`, so
//!   the pole moves straight into the left half plane by `sigma_i = k_i |G_i| / 2`, and
//!   `k_i = 2 sigma_i / |G_i|` for the asked width `sigma_i = 2 pi width_hz`: the error at `w_i`
//!   decays as `exp(-sigma_i t)`, the sensitivity has a notch of half-width `sigma_i` there,
//!   and `L` crosses 1 at `w_i -+ sigma_i` with the phase at `+-90 deg` (90 deg of phase
//!   margin, the paper's Fig. 8: T is 1 with 0 deg only at the tones).
//!
//! The phases and gains are computed on the discrete loop at the control rate: the plant with
//! its hold and delays (`z^-1 ZOH`, plus any extra delay), and the discretisation's own
//! distortion of the controller near each tone (its response against the continuous one at
//! `w_i + sigma_i`), iterated until they agree. `sum_i R_i` over a common denominator is
//! `N(s) / prod_i d_i(s)` with `N` of degree `2m - 1`; its roots are the zeros of eq. 5's
//! form (for two tones a real zero and a zero pair between the tones, as Table I's -7.87 and
//! 235 rad/s).

use std::f64::consts::TAU;

use nalgebra::{Complex, DMatrix};

use crate::discretise::{Method, discretise};
use crate::dual_tone::DualToneParams;
use crate::plant_model::PlantModel;
use crate::sos::Cascade;

/// Damping of the roll-off pole pair (Table I's 1.13e4 rad/s pair has 0.667).
pub const ROLLOFF_DAMPING: f64 = 0.7;
/// Iterations of the phase and gain fixed point (it settles in a handful).
const MAX_ITERATIONS: usize = 100;

/// The dual-tone rule's choices.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ToneRule {
    /// The drive frequencies the tones sit on, Hz.
    pub tones_hz: Vec<f64>,
    /// Each tone's width `sigma / 2 pi`, Hz: the error at the tone decays as
    /// `exp(-2 pi width t)`.
    pub width_hz: f64,
    /// The tones' damping `zt` (Table I: 1e-4; 0 is a pure internal model).
    pub damping: f64,
    /// The roll-off pair's frequency, Hz.
    pub rolloff_hz: f64,
}

impl ToneRule {
    /// The default roll-off for a control rate: a quarter of Nyquist (Table I's 1.8 kHz pair at
    /// 20 kHz is about a sixth).
    #[must_use]
    pub fn default_rolloff_hz(rate_hz: f64) -> f64 {
        rate_hz / 8.0
    }

    /// Checks the choices against the control rate; on failure the option and why.
    pub fn check(&self, rate_hz: f64) -> Result<(), (&'static str, String)> {
        let nyquist = rate_hz / 2.0;
        if self.tones_hz.is_empty() {
            return Err(("tones_hz", "a dual-tone needs at least one tone".into()));
        }
        for &f in &self.tones_hz {
            if !(f.is_finite() && f > 0.0 && f < nyquist) {
                return Err((
                    "tones_hz",
                    format!("{f} Hz must be above 0 and below Nyquist ({nyquist} Hz)"),
                ));
            }
        }
        if !(self.width_hz.is_finite() && self.width_hz > 0.0) {
            return Err(("width_hz", format!("{} Hz must be positive", self.width_hz)));
        }
        if !(self.damping.is_finite() && (0.0..1.0).contains(&self.damping)) {
            return Err(("damping", format!("{} must be in [0, 1)", self.damping)));
        }
        if !(self.rolloff_hz.is_finite() && self.rolloff_hz > 0.0 && self.rolloff_hz < nyquist) {
            return Err((
                "rolloff_hz",
                format!(
                    "{} Hz must be above 0 and below Nyquist ({nyquist} Hz)",
                    self.rolloff_hz
                ),
            ));
        }
        Ok(())
    }

    /// The dual-tone controller this rule gives for `plant` at `period_s`, discretised with
    /// `method` (eq. 5's form; the discretisation only enters through the tones' phases).
    #[must_use]
    pub fn design(&self, plant: &PlantModel, period_s: f64, method: &Method) -> DualToneParams {
        let discrete_plant = plant.discrete(period_s);
        let sigma = TAU * self.width_hz;
        let mut tones: Vec<Tone> = self
            .tones_hz
            .iter()
            .map(|&f| Tone {
                w: TAU * f,
                gain: 0.0,
                phase: 0.0,
            })
            .collect();
        let mut params = self.params(plant, &tones);
        for _ in 0..MAX_ITERATIONS {
            let controller = discrete_controller(&params, method, period_s);
            let mut change: f64 = 0.0;
            let previous = tones.clone();
            for (i, tone) in tones.iter_mut().enumerate() {
                let w = tone.w;
                let distortion = if previous.iter().all(|t| t.gain == 0.0) {
                    Complex::new(1.0, 0.0)
                } else {
                    let probe = w + sigma;
                    controller.response(probe / TAU, period_s)
                        / params.continuous().eval(Complex::new(0.0, probe))
                };
                let q = discrete_plant.response(w / TAU, period_s)
                    * self.equaliser(plant, Complex::new(0.0, w))
                    * distortion;
                let others: Complex<f64> = previous
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != i)
                    .map(|(_, t)| t.eval(Complex::new(0.0, w), self.damping))
                    .sum();
                let rest = q / (q * others + 1.0);
                let phase = -rest.arg();
                let gain = 2.0 * sigma / rest.norm();
                change = change
                    .max(wrapped(phase - tone.phase).abs())
                    .max(((gain - tone.gain) / gain).abs());
                *tone = Tone { w, gain, phase };
            }
            params = self.params(plant, &tones);
            if change < 1e-12 {
                break;
            }
        }
        params
    }

    /// `E(s)` at `s`.
    fn equaliser(&self, plant: &PlantModel, s: Complex<f64>) -> Complex<f64> {
        let (ws, zs) = (plant.natural_freq_rad_s, plant.damping_ratio);
        let wr = TAU * self.rolloff_hz;
        let notch = s * s + s * (2.0 * zs * ws) + ws * ws;
        let rolloff = s * s + s * (2.0 * ROLLOFF_DAMPING * wr) + wr * wr;
        notch / (plant.dc_gain * ws * ws) * (wr * wr) / rolloff
    }

    /// Eq. 5's factors of `E sum_i R_i`.
    fn params(&self, plant: &PlantModel, tones: &[Tone]) -> DualToneParams {
        let (ws, zs) = (plant.natural_freq_rad_s, plant.damping_ratio);
        let wr = TAU * self.rolloff_hz;
        // N(s) = sum_i n_i(s) prod_{j != i} d_j(s), in x = s / scale for conditioning.
        let scale = tones.iter().map(|t| t.w.ln()).sum::<f64>() / tones.len() as f64;
        let scale = scale.exp();
        let mut numerator = vec![0.0];
        for (i, tone) in tones.iter().enumerate() {
            let mut term = vec![
                -tone.gain * tone.w * tone.phase.sin() / scale,
                tone.gain * tone.phase.cos(),
            ];
            for (j, other) in tones.iter().enumerate() {
                if j != i {
                    let (w, z) = (other.w / scale, self.damping);
                    term = poly_mul(&term, &[w * w, 2.0 * z * w, 1.0]);
                }
            }
            numerator = poly_add(&numerator, &term);
        }
        let (lead, roots) = poly_roots(&numerator);
        // N(s) = lead scale^(2m-1) prod (x - x_r) = lead scale^(2m-1-deg) prod (s - s_r).
        let degree = roots.len() as i32;
        let n_gain = lead * scale.powi(2 * tones.len() as i32 - 1 - degree);
        let mut params = DualToneParams {
            k: n_gain * wr * wr / (plant.dc_gain * ws * ws),
            waz_rad_s: Vec::new(),
            wap_rad_s: Vec::new(),
            zeta_bz: vec![zs],
            wbz_rad_s: vec![ws],
            zeta_bp: tones.iter().map(|_| self.damping).collect(),
            wbp_rad_s: tones.iter().map(|t| t.w).collect(),
            tone_poles_at_hz: None,
        };
        params.zeta_bp.push(ROLLOFF_DAMPING);
        params.wbp_rad_s.push(wr);
        for root in roots.iter().map(|r| r * scale) {
            if root.im.abs() <= 1e-9 * root.norm().max(1e-300) {
                params.waz_rad_s.push(-root.re);
            } else if root.im > 0.0 {
                params.wbz_rad_s.push(root.norm());
                params.zeta_bz.push(-root.re / root.norm());
            }
        }
        params
    }
}

/// One tone's pole frequency, gain and phase.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Tone {
    w: f64,
    gain: f64,
    phase: f64,
}

impl Tone {
    /// `R(s)`.
    fn eval(&self, s: Complex<f64>, damping: f64) -> Complex<f64> {
        let num = (s * self.phase.cos() - self.w * self.phase.sin()) * self.gain;
        num / (s * s + s * (2.0 * damping * self.w) + self.w * self.w)
    }
}

/// The controller of `params` discretised section by section with `method`.
fn discrete_controller(params: &DualToneParams, method: &Method, period_s: f64) -> Cascade {
    let tf = params.continuous();
    let sections = tf
        .sections()
        .expect("eq. 5's form from the rule is proper: 2m + 1 zeros against 2m + 2 poles");
    Cascade::new(
        tf.gain,
        sections
            .iter()
            .map(|s| discretise(s, method, period_s))
            .collect(),
    )
}

fn wrapped(angle: f64) -> f64 {
    (angle + std::f64::consts::PI).rem_euclid(TAU) - std::f64::consts::PI
}

/// Polynomials, lowest power first.
fn poly_mul(p: &[f64], q: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; p.len() + q.len() - 1];
    for (i, a) in p.iter().enumerate() {
        for (j, b) in q.iter().enumerate() {
            out[i + j] += a * b;
        }
    }
    out
}

fn poly_add(p: &[f64], q: &[f64]) -> Vec<f64> {
    (0..p.len().max(q.len()))
        .map(|i| p.get(i).unwrap_or(&0.0) + q.get(i).unwrap_or(&0.0))
        .collect()
}

/// The leading coefficient and the roots of `p` (lowest power first), from the eigenvalues of
/// its companion matrix. Leading coefficients below 1e-12 of the largest are dropped.
fn poly_roots(p: &[f64]) -> (f64, Vec<Complex<f64>>) {
    let largest = p.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    let mut degree = p.len() - 1;
    while degree > 0 && p[degree].abs() <= 1e-12 * largest {
        degree -= 1;
    }
    let lead = p[degree];
    if degree == 0 {
        return (lead, Vec::new());
    }
    let mut companion = DMatrix::zeros(degree, degree);
    for i in 0..degree {
        companion[(0, i)] = -p[degree - 1 - i] / lead;
        if i + 1 < degree {
            companion[(i + 1, i)] = 1.0;
        }
    }
    let roots = crate::eigen::eigenvalues(companion);
    (lead, roots)
}

#[cfg(test)]
mod tests {
    use super::*;

    const RATE_HZ: f64 = 2740.0;

    fn rule() -> ToneRule {
        ToneRule {
            tones_hz: vec![27.0, 52.0],
            width_hz: 1.0,
            damping: 1e-4,
            rolloff_hz: ToneRule::default_rolloff_hz(RATE_HZ),
        }
    }

    #[test]
    fn roots_of_a_known_cubic() {
        // (x - 2)(x^2 + 2x + 5) = x^3 - x - 10... expanded: x^3 + 0 x^2 + x - 10.
        let (lead, mut roots) = poly_roots(&[-10.0, 1.0, 0.0, 1.0]);
        assert_eq!(lead, 1.0);
        roots.sort_by(|a, b| a.im.total_cmp(&b.im));
        assert!(
            (roots[0] - Complex::new(-1.0, -2.0)).norm() < 1e-12,
            "{roots:?}"
        );
        assert!(
            (roots[1] - Complex::new(2.0, 0.0)).norm() < 1e-12,
            "{roots:?}"
        );
        assert!(
            (roots[2] - Complex::new(-1.0, 2.0)).norm() < 1e-12,
            "{roots:?}"
        );
    }

    #[test]
    fn the_factors_are_the_sum_of_the_tones_times_the_equaliser() {
        let (plant, r) = (PlantModel::default(), rule());
        let tones = [
            Tone {
                w: TAU * 27.0,
                gain: 30.0,
                phase: 0.4,
            },
            Tone {
                w: TAU * 52.0,
                gain: 12.0,
                phase: 2.9,
            },
        ];
        let params = r.params(&plant, &tones);
        for f in [3.0, 22.0, 40.0, 300.0] {
            let s = Complex::new(0.0, TAU * f);
            let direct: Complex<f64> = tones
                .iter()
                .map(|t| t.eval(s, r.damping))
                .sum::<Complex<f64>>()
                * r.equaliser(&plant, s);
            let factored = params.continuous().eval(s);
            assert!(
                (direct - factored).norm() < 1e-9 * direct.norm(),
                "{f} Hz: {direct} vs {factored}"
            );
        }
    }

    #[test]
    fn each_tone_sits_at_its_width_with_ninety_degrees() {
        // The loop crosses |L| = 1 about a tone's width either side of it, with the phase
        // near +-90 degrees, and the closed-loop poles near the tones are damped by the width.
        let (plant, r) = (PlantModel::default(), rule());
        let t = 1.0 / RATE_HZ;
        let method = Method::TustinPrewarped {
            prewarp_hz: r.tones_hz.clone(),
        };
        let params = r.design(&plant, t, &method);
        let controller = discrete_controller(&params, &method, t);
        let plant_d = plant.discrete(t);
        let l = |f: f64| controller.response(f, t) * plant_d.response(f, t);
        for &f in &r.tones_hz {
            for side in [-1.0, 1.0] {
                let at = l(f + side * r.width_hz);
                // First order in the width: |L| is 1 to within 10 % (0.93-1.00 here).
                assert!(
                    (at.norm() - 1.0).abs() < 0.1,
                    "{f} Hz {side}: |L| = {}",
                    at.norm()
                );
                assert!(
                    (at.arg().to_degrees() + side * 90.0).abs() < 5.0,
                    "{f} Hz {side}: arg L = {}",
                    at.arg().to_degrees()
                );
            }
            // At the tone L is large, real and positive: T = 1 with 0 degrees.
            let at = l(f);
            assert!(
                at.re > 100.0 && at.im.abs() < 0.05 * at.re,
                "{f} Hz: L = {at}"
            );
        }
        let nominal = crate::loop_analysis::NominalLoop::new(controller, plant_d, t);
        let poles = nominal.closed_loop_poles();
        for &f in &r.tones_hz {
            let near = poles
                .iter()
                .map(|&z| crate::loop_analysis::ZPoint::new(z, t))
                .filter(|p| p.im > 0.0)
                .min_by(|a, b| (a.f_hz - f).abs().total_cmp(&(b.f_hz - f).abs()))
                .unwrap();
            let decay = -(near.abs.ln()) / t;
            eprintln!("{f}: {near} decay {decay}");
            assert!(
                (decay / (TAU * r.width_hz) - 1.0).abs() < 0.1,
                "{f} Hz: closed-loop pole {near} decays at {decay} 1/s"
            );
        }
    }
}
