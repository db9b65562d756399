//! The nominal loop: discrete controller times the nominal plant model. Closed-loop poles from
//! the state-space realisation, margins, bandwidth and the complementary sensitivity T.

use nalgebra::{Complex, DMatrix};

use crate::sos::Cascade;

/// A complex pole or zero in the z-plane, with its s-plane reading.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ZPoint {
    /// Real part (z-plane).
    pub re: f64,
    /// Imaginary part (z-plane).
    pub im: f64,
    /// |z|; a pole with |z| >= 1 is unstable.
    pub abs: f64,
    /// The frequency it sits at, `arg(z) / (2 pi T)`, Hz.
    pub f_hz: f64,
    /// The damping ratio of `s = ln(z)/T`.
    pub damping: f64,
}

impl ZPoint {
    /// Describes `z` for sampling period `period_s`.
    #[must_use]
    pub fn new(z: Complex<f64>, period_s: f64) -> Self {
        let s = z.ln() / period_s;
        Self {
            re: z.re,
            im: z.im,
            abs: z.norm(),
            f_hz: z.arg().abs() / (std::f64::consts::TAU * period_s),
            damping: if s.norm() > 0.0 {
                -s.re / s.norm()
            } else {
                0.0
            },
        }
    }
}

impl std::fmt::Display for ZPoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Poles of an extreme gain reach 1e97: those in scientific notation, not 98 digits.
        if self.abs < 1e6 {
            write!(
                f,
                "{:.9}{:+.9}j (|z| = {:.9}, {:.4} Hz)",
                self.re, self.im, self.abs, self.f_hz
            )
        } else {
            write!(
                f,
                "{:.9e}{:+.9e}j (|z| = {:.9e}, {:.4} Hz)",
                self.re, self.im, self.abs, self.f_hz
            )
        }
    }
}

/// Poles as one line of text, for refusals.
#[must_use]
pub fn format_poles(poles: &[ZPoint]) -> String {
    poles
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// A gain crossover (|L| = 1) and its phase margin.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct GainCrossover {
    /// Frequency, Hz.
    pub f_hz: f64,
    /// `180 + arg L`, wrapped to (-180, 180], degrees.
    pub phase_margin_deg: f64,
}

/// A phase crossover (L real and negative) and its gain margin.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PhaseCrossover {
    /// Frequency, Hz.
    pub f_hz: f64,
    /// `-20 log10 |L|`, dB.
    pub gain_margin_db: f64,
}

/// |T| and its phase at one frequency.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FrequencyValue {
    /// Frequency, Hz.
    pub f_hz: f64,
    /// |T|, dB.
    pub magnitude_db: f64,
    /// arg T, degrees.
    pub phase_deg: f64,
}

/// Everything `scanhil analyze` reports about the nominal closed loop.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LoopReport {
    /// All closed-loop poles inside the unit circle.
    pub stable: bool,
    /// The largest closed-loop pole magnitude.
    pub spectral_radius: f64,
    /// Gain crossovers, lowest frequency first.
    pub gain_crossovers: Vec<GainCrossover>,
    /// Phase crossovers, lowest frequency first.
    pub phase_crossovers: Vec<PhaseCrossover>,
    /// The highest gain crossover, Hz (the loop's crossover frequency).
    pub crossover_hz: Option<f64>,
    /// The smallest phase margin over the gain crossovers, degrees.
    pub phase_margin_deg: Option<f64>,
    /// The smallest gain margin over the phase crossovers where |L| < 1 (how much more gain
    /// the loop takes), dB. Crossovers with |L| > 1 (conditional stability) are in the list.
    pub gain_margin_db: Option<f64>,
    /// The highest frequency where |T| falls through -3 dB, Hz.
    pub bandwidth_3db_hz: Option<f64>,
    /// max |T|, dB.
    pub peak_db: f64,
    /// Where max |T| is, Hz.
    pub peak_hz: f64,
    /// max |S| = 1 / (the smallest distance of L from -1), dB.
    pub sensitivity_peak_db: f64,
    /// Where max |S| is, Hz.
    pub sensitivity_peak_hz: f64,
    /// T at the frequencies asked for.
    pub at: Vec<FrequencyValue>,
    /// The closed-loop poles.
    pub closed_loop_poles: Vec<ZPoint>,
}

/// The nominal loop `L = C P` of one axis.
#[derive(Debug, Clone)]
pub struct NominalLoop {
    controller: Cascade,
    plant: Cascade,
    period_s: f64,
}

impl NominalLoop {
    /// The loop of `controller` (error to command) around `plant` (command to measurement).
    #[must_use]
    pub fn new(controller: Cascade, plant: Cascade, period_s: f64) -> Self {
        Self {
            controller,
            plant,
            period_s,
        }
    }

    /// The sampling period, s.
    #[must_use]
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// The loop gain `L = C P` at `f_hz`.
    #[must_use]
    pub fn loop_gain(&self, f_hz: f64) -> Complex<f64> {
        self.controller.response(f_hz, self.period_s) * self.plant.response(f_hz, self.period_s)
    }

    /// The control effort `C / (1 + L) = T / P` at `f_hz`: the plant input (input units) per
    /// output unit of reference, what the coils carry while the loop tracks.
    #[must_use]
    pub fn control_effort(&self, f_hz: f64) -> Complex<f64> {
        let c = self.controller.response(f_hz, self.period_s);
        c / (c * self.plant.response(f_hz, self.period_s) + 1.0)
    }

    /// The complementary sensitivity `T = L / (1 + L)` at `f_hz`.
    #[must_use]
    pub fn complementary(&self, f_hz: f64) -> Complex<f64> {
        let l = self.loop_gain(f_hz);
        l / (l + 1.0)
    }

    /// The closed-loop poles: eigenvalues of the loop's state matrix (the plant has no
    /// feed-through, so the loop is well posed).
    #[must_use]
    pub fn closed_loop_poles(&self) -> Vec<Complex<f64>> {
        crate::eigen::eigenvalues(self.closed_loop_matrix())
    }

    /// The closed loop's state matrix: plant states first, then the controller's.
    fn closed_loop_matrix(&self) -> DMatrix<f64> {
        let c = self.controller.state_space();
        let p = self.plant.state_space();
        let (nc, np) = (c.order(), p.order());
        let mut a = DMatrix::zeros(nc + np, nc + np);
        // u = Cc xc + Dc (r - Cp xp); xp' = Ap xp + Bp u; xc' = Ac xc + Bc (r - Cp xp)
        a.view_mut((0, 0), (np, np))
            .copy_from(&(&p.a - &p.b * &p.c * c.d));
        a.view_mut((0, np), (np, nc)).copy_from(&(&p.b * &c.c));
        a.view_mut((np, 0), (nc, np)).copy_from(&(-(&c.b * &p.c)));
        a.view_mut((np, np), (nc, nc)).copy_from(&c.a);
        a
    }

    /// The analysis frequency grid: log spaced from 0.1 Hz to just below Nyquist, plus fine
    /// linear grids around lightly damped controller poles (tones are millihertz wide).
    #[must_use]
    pub fn frequency_grid(&self) -> Vec<f64> {
        let nyquist = 0.5 / self.period_s;
        let n = 6000;
        let (lo, hi) = (0.1f64.log10(), (0.999 * nyquist).log10());
        let mut grid: Vec<f64> = (0..n)
            .map(|i| 10f64.powf(lo + (hi - lo) * i as f64 / (n - 1) as f64))
            .collect();
        for pole in self.controller.poles() {
            let zp = ZPoint::new(pole, self.period_s);
            if pole.im > 0.0 && zp.damping.abs() < 0.05 {
                let half_width = (zp.f_hz * 0.02).max(0.05);
                grid.extend(
                    (0..=2000)
                        .map(|i| zp.f_hz - half_width + 2.0 * half_width * f64::from(i) / 2000.0),
                );
            }
        }
        grid.retain(|f| *f > 0.0 && *f < nyquist);
        grid.sort_by(f64::total_cmp);
        grid.dedup();
        grid
    }

    /// Finds the root of `g` between `a` and `b` (a sign change) by bisection.
    fn bisect(g: impl Fn(f64) -> f64, mut a: f64, mut b: f64) -> f64 {
        let ga = g(a);
        for _ in 0..60 {
            let m = 0.5 * (a + b);
            if (g(m) > 0.0) == (ga > 0.0) {
                a = m;
            } else {
                b = m;
            }
        }
        0.5 * (a + b)
    }

    /// The full report, with T evaluated at `at_hz`.
    #[must_use]
    pub fn report(&self, at_hz: &[f64]) -> LoopReport {
        let grid = self.frequency_grid();
        let poles = self.closed_loop_poles();
        let spectral_radius = poles.iter().map(|p| p.norm()).fold(0.0, f64::max);
        let log_mag = |f: f64| self.loop_gain(f).norm().ln();
        let imag = |f: f64| self.loop_gain(f).im;
        let t_db = |f: f64| 20.0 * self.complementary(f).norm().log10() + 3.0103;
        let mut gain_crossovers = Vec::new();
        let mut phase_crossovers = Vec::new();
        let mut bandwidth = None;
        let (mut peak_db, mut peak_hz) = (f64::NEG_INFINITY, 0.0);
        let (mut sensitivity_peak, mut sensitivity_peak_hz) = (0.0f64, 0.0);
        // L once per grid point; each window compares its two ends.
        let values: Vec<(f64, Complex<f64>)> =
            grid.iter().map(|&f| (f, self.loop_gain(f))).collect();
        for w in values.windows(2) {
            let ((f0, l0), (f1, l1)) = (w[0], w[1]);
            if (l0.norm().ln() > 0.0) != (l1.norm().ln() > 0.0) {
                let f = Self::bisect(log_mag, f0, f1);
                let arg = self.loop_gain(f).arg().to_degrees();
                let pm = (180.0 + arg + 180.0).rem_euclid(360.0) - 180.0;
                gain_crossovers.push(GainCrossover {
                    f_hz: f,
                    phase_margin_deg: pm,
                });
            }
            if (l0.im > 0.0) != (l1.im > 0.0) {
                let f = Self::bisect(imag, f0, f1);
                let l = self.loop_gain(f);
                if l.re < 0.0 {
                    phase_crossovers.push(PhaseCrossover {
                        f_hz: f,
                        gain_margin_db: -20.0 * l.norm().log10(),
                    });
                }
            }
            let (t0, t1) = (l0 / (l0 + 1.0), l1 / (l1 + 1.0));
            let (t0_db, t1_db) = (20.0 * t0.norm().log10(), 20.0 * t1.norm().log10());
            if t0_db + 3.0103 > 0.0 && t1_db + 3.0103 <= 0.0 {
                bandwidth = Some(Self::bisect(t_db, f0, f1));
            }
            if t0_db > peak_db {
                (peak_db, peak_hz) = (t0_db, f0);
            }
            let s0 = (l0 + 1.0).inv().norm();
            if s0 > sensitivity_peak {
                (sensitivity_peak, sensitivity_peak_hz) = (s0, f0);
            }
        }
        let at = at_hz
            .iter()
            .map(|&f| {
                let t = self.complementary(f);
                FrequencyValue {
                    f_hz: f,
                    magnitude_db: 20.0 * t.norm().log10(),
                    phase_deg: t.arg().to_degrees(),
                }
            })
            .collect();
        LoopReport {
            stable: spectral_radius < 1.0,
            spectral_radius,
            crossover_hz: gain_crossovers.last().map(|c| c.f_hz),
            phase_margin_deg: gain_crossovers
                .iter()
                .map(|c| c.phase_margin_deg)
                .reduce(f64::min),
            gain_margin_db: phase_crossovers
                .iter()
                .map(|c| c.gain_margin_db)
                .filter(|gm| *gm > 0.0)
                .reduce(f64::min),
            gain_crossovers,
            phase_crossovers,
            bandwidth_3db_hz: bandwidth,
            peak_db,
            peak_hz,
            sensitivity_peak_db: 20.0 * sensitivity_peak.log10(),
            sensitivity_peak_hz,
            at,
            closed_loop_poles: poles
                .iter()
                .map(|&p| ZPoint::new(p, self.period_s))
                .collect(),
        }
    }

    /// Bode data of T on the analysis grid: (f Hz, |T| dB, unwrapped phase deg).
    #[must_use]
    pub fn bode(&self) -> Vec<(f64, f64, f64)> {
        let mut out = Vec::new();
        let mut previous = 0.0;
        let mut offset = 0.0;
        for f in self.frequency_grid() {
            let t = self.complementary(f);
            let raw = t.arg().to_degrees();
            if !out.is_empty() {
                let jump = raw + offset - previous;
                offset -= 360.0 * (jump / 360.0).round();
            }
            previous = raw + offset;
            out.push((f, 20.0 * t.norm().log10(), previous));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    //! The analysis against a loop whose figures have closed forms: `L(z) = k / (z (z - 1))`
    //! (a gain `k` around an integrator with one period of delay). With `theta = omega T`:
    //! `|L| = k / (2 sin(theta/2))`, `arg L = -(pi/2 + 3 theta/2)`, so the crossover is at
    //! `theta_c = 2 asin(k/2)` with phase margin `90 deg - 3 theta_c / 2`, the phase crossover
    //! at `theta = pi/3` with gain margin `-20 log10 k`; `T = k / (z^2 - z + k)`, whose poles
    //! have `|z| = sqrt k`, and `|z^2 - z + k|^2 = 4k c^2 - (2 + 2k) c + 2 - 2k + k^2` with
    //! `c = cos theta`: the peak at `c = (1 + k) / 4k`, the -3 dB point where it equals `2 k^2`.

    use std::f64::consts::PI;

    use super::*;
    use crate::sos::Section;

    const T: f64 = 5e-5;

    fn delayed_integrator_loop(k: f64) -> NominalLoop {
        let plant = Cascade::new(
            1.0,
            vec![Section {
                b: [0.0, 0.0, 1.0],
                a: [-1.0, 0.0],
            }],
        );
        NominalLoop::new(Cascade::new(k, vec![]), plant, T)
    }

    fn hz(theta: f64) -> f64 {
        theta / (2.0 * PI * T)
    }

    fn close(what: &str, got: f64, want: f64, tolerance: f64) {
        assert!(
            (got - want).abs() <= tolerance,
            "{what}: got {got}, the closed form gives {want} (tolerance {tolerance})"
        );
    }

    #[test]
    fn a_pid_with_an_extreme_gain_gets_the_asymptotic_poles() {
        // The paper's PID with kp = 1e200 on its nominal plant. For large z the controller is
        // its feed-through D and the plant (one period of delay: Cp Bp = 0) is
        // Cp Ap Bp / z^2, so 1 + L = 0 puts two poles at z^2 = -D Cp Ap Bp. Unbalanced, the QR
        // iteration found at most |z| = 2.0 (a refusal naming the wrong poles).
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../fixtures/controllers/pid-series.json");
        let text = std::fs::read_to_string(&path).expect("the fixture");
        let huge = text.replace(r#""kp": 2.567"#, r#""kp": 1e200"#);
        assert_ne!(huge, text, "the fixture's kp");
        let file = tempfile::NamedTempFile::new().expect("a temporary file");
        std::fs::write(file.path(), huge).expect("writing it");
        let settings = crate::settings::ControllerSettings::load(file.path())
            .expect("the controller loads (its stability is checked when built)");
        let axis = settings.axis_controller().expect("a PID discretises");
        let nominal = settings.nominal_loop(&axis);
        let (c, p) = (
            nominal.controller.state_space(),
            nominal.plant.state_space(),
        );
        assert_eq!((&p.c * &p.b)[(0, 0)], 0.0, "one period of delay");
        let asymptote = (c.d * (&p.c * &p.a * &p.b)[(0, 0)]).abs().sqrt();
        assert!(asymptote > 1e90, "{asymptote:e}");
        let mut magnitudes: Vec<f64> = nominal
            .closed_loop_poles()
            .iter()
            .map(|z| z.norm())
            .collect();
        magnitudes.sort_by(f64::total_cmp);
        for largest in &magnitudes[magnitudes.len() - 2..] {
            close("|z| / asymptote", largest / asymptote, 1.0, 1e-6);
        }
    }

    #[test]
    fn figures_of_a_delayed_integrator_match_their_closed_forms() {
        let k = 0.5;
        let r = delayed_integrator_loop(k).report(&[]);
        assert!(r.stable);
        close("spectral radius", r.spectral_radius, k.sqrt(), 1e-9);
        let theta_c = 2.0 * (k / 2.0).asin();
        assert_eq!(r.gain_crossovers.len(), 1, "{:?}", r.gain_crossovers);
        close("crossover Hz", r.crossover_hz.unwrap(), hz(theta_c), 1e-6);
        close(
            "phase margin deg",
            r.phase_margin_deg.unwrap(),
            90.0 - 1.5 * theta_c.to_degrees(),
            1e-6,
        );
        assert_eq!(r.phase_crossovers.len(), 1, "{:?}", r.phase_crossovers);
        close(
            "phase crossover Hz",
            r.phase_crossovers[0].f_hz,
            hz(PI / 3.0),
            1e-6,
        );
        close(
            "gain margin dB",
            r.gain_margin_db.unwrap(),
            -20.0 * k.log10(),
            1e-9,
        );
        // |T| from the denominator's closed form in c = cos(theta).
        let den2 = |c: f64| 4.0 * k * c * c - (2.0 + 2.0 * k) * c + 2.0 - 2.0 * k + k * k;
        let c_peak = (1.0 + k) / (4.0 * k);
        let peak_db = 20.0 * (k / den2(c_peak).sqrt()).log10();
        close("peak dB", r.peak_db, peak_db, 1e-3);
        let f_peak = hz(c_peak.acos());
        // The peak is read on the analysis grid (log spaced, 0.2 % apart there).
        close("peak Hz", r.peak_hz, f_peak, 0.005 * f_peak);
        // -3 dB: den2(c) = 2 k^2, the root with c in [-1, 1] and below the peak's c.
        let (qa, qb, qc) = (
            4.0 * k,
            -(2.0 + 2.0 * k),
            2.0 - 2.0 * k + k * k - 2.0 * k * k,
        );
        let c_bw = (-qb - (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa);
        // (The report's -3 dB is 3.0103 dB, 4e-8 dB off 10 log10 2: 1e-5 Hz here.)
        close(
            "bandwidth Hz",
            r.bandwidth_3db_hz.unwrap(),
            hz(c_bw.acos()),
            1e-3,
        );
    }

    #[test]
    fn a_loop_with_too_much_gain_is_unstable_and_has_no_gain_margin() {
        // k > 1: the poles leave the unit circle (|z| = sqrt k) and |L| > 1 where the phase
        // crosses -180 deg.
        let k = 1.2;
        let r = delayed_integrator_loop(k).report(&[]);
        assert!(!r.stable, "{r:?}");
        close("spectral radius", r.spectral_radius, k.sqrt(), 1e-9);
        assert_eq!(r.gain_margin_db, None, "{r:?}");
        close(
            "negative gain margin",
            r.phase_crossovers[0].gain_margin_db,
            -20.0 * k.log10(),
            1e-9,
        );
    }

    #[test]
    fn a_wrong_sign_controller_has_no_positive_margins() {
        // -k instead of k: at low frequency L is a large negative real (arg = -180 deg), the
        // phase margin at the crossover is 180 deg away from the right sign's.
        let k = 0.5;
        let good = delayed_integrator_loop(k).report(&[]);
        let bad = delayed_integrator_loop(-k).report(&[]);
        assert!(good.stable && !bad.stable, "{bad:?}");
        let theta_c = 2.0 * (k / 2.0).asin();
        close(
            "wrong-sign phase margin",
            bad.phase_margin_deg.unwrap(),
            -90.0 - 1.5 * theta_c.to_degrees(),
            1e-6,
        );
    }
}
