//! The loop's figures read off a measured complementary sensitivity `T` on a frequency grid:
//! the gain crossover of `L = T / (1 - T)` and its phase margin, the -3 dB bandwidth of `T`
//! and its peak. What a system analyser gives on the bench (the paper's 240 Hz crossover,
//! 45 deg, 422 Hz bandwidth, 2.8 dB at 155 Hz), to set beside the nominal loop's figures. The
//! crossings are interpolated linearly in log frequency between neighbouring points, so the
//! grid's density bounds their accuracy.

use nalgebra::Complex;

/// The figures of a closed loop measured at a set of frequencies.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ClosedLoopFigures {
    /// Where |L| first falls through 1, Hz (`None`: not within the grid).
    pub crossover_hz: Option<f64>,
    /// `180 + arg L` there, degrees.
    pub phase_margin_deg: Option<f64>,
    /// Where |T| first falls below -3 dB after its peak, Hz (`None`: not within the grid).
    pub bandwidth_hz: Option<f64>,
    /// The largest |T|, dB.
    pub peak_db: f64,
    /// Its frequency, Hz.
    pub peak_hz: f64,
}

/// The figures of `t` (`(f_hz, T)` in ascending frequency; at least one point).
#[must_use]
pub fn closed_loop_figures(t: &[(f64, Complex<f64>)]) -> ClosedLoopFigures {
    let db = |z: Complex<f64>| 20.0 * z.norm().log10();
    let (peak_i, peak) = t
        .iter()
        .enumerate()
        .fold((0, f64::NEG_INFINITY), |best, (i, (_, z))| {
            if db(*z) > best.1 { (i, db(*z)) } else { best }
        });
    let loop_gain: Vec<(f64, Complex<f64>)> = t
        .iter()
        .map(|&(f, z)| (f, z / (Complex::new(1.0, 0.0) - z)))
        .collect();
    let crossing = |values: &[(f64, f64)], level: f64| {
        values.windows(2).find_map(|w| {
            let ((f0, v0), (f1, v1)) = (w[0], w[1]);
            (v0 >= level && v1 < level).then(|| {
                let x = (v0 - level) / (v0 - v1);
                (f0.ln() + x * (f1.ln() - f0.ln())).exp()
            })
        })
    };
    let l_db: Vec<(f64, f64)> = loop_gain.iter().map(|&(f, l)| (f, db(l))).collect();
    let crossover_hz = crossing(&l_db, 0.0);
    let phase_margin_deg = crossover_hz.map(|fc| {
        let i = loop_gain
            .iter()
            .position(|&(f, _)| f >= fc)
            .unwrap_or(loop_gain.len() - 1)
            .max(1);
        let ((f0, l0), (f1, l1)) = (loop_gain[i - 1], loop_gain[i]);
        let x = (fc.ln() - f0.ln()) / (f1.ln() - f0.ln());
        // Interpolate the phase along the shorter way round.
        let (p0, mut p1) = (l0.arg(), l1.arg());
        if p1 - p0 > std::f64::consts::PI {
            p1 -= std::f64::consts::TAU;
        } else if p0 - p1 > std::f64::consts::PI {
            p1 += std::f64::consts::TAU;
        }
        let phase = p0 + x * (p1 - p0);
        (180.0 + phase.to_degrees() + 180.0).rem_euclid(360.0) - 180.0
    });
    let t_db: Vec<(f64, f64)> = t[peak_i..].iter().map(|&(f, z)| (f, db(z))).collect();
    ClosedLoopFigures {
        crossover_hz,
        phase_margin_deg,
        bandwidth_hz: crossing(&t_db, -3.0),
        peak_db: peak,
        peak_hz: t[peak_i].0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `L = wc^2 (1 + s/w1) / (s^2 (1 + s/w2))`-like loops have closed forms; a plain
    /// `L = k / (s (s + a))` is enough: its crossover and margin are known.
    #[test]
    fn figures_of_a_known_loop() {
        let (k, a) = (1.0e6_f64, 500.0_f64);
        let grid: Vec<f64> = (0..4000)
            .map(|i| 1.0 * 10f64.powf(i as f64 / 1000.0))
            .collect();
        let t: Vec<(f64, Complex<f64>)> = grid
            .iter()
            .map(|&f| {
                let s = Complex::new(0.0, std::f64::consts::TAU * f);
                let l = Complex::new(k, 0.0) / (s * (s + a));
                (f, l / (Complex::new(1.0, 0.0) + l))
            })
            .collect();
        let fig = closed_loop_figures(&t);
        // |L| = 1: w^2 sqrt(w^2 + a^2) = k  =>  w^4 + a^2 w^2 - k^2 = 0.
        let wc = ((-a * a + (a.powi(4) + 4.0 * k * k).sqrt()) / 2.0).sqrt();
        let fc = wc / std::f64::consts::TAU;
        assert!(
            (fig.crossover_hz.unwrap() / fc - 1.0).abs() < 1e-4,
            "{fig:?} {fc}"
        );
        let pm = 90.0 - (wc / a).atan().to_degrees();
        assert!(
            (fig.phase_margin_deg.unwrap() - pm).abs() < 0.01,
            "{fig:?} {pm}"
        );
        // T = k / (s^2 + a s + k): wn = 1000 rad/s, zeta = 0.25.
        let (wn, zeta) = (k.sqrt(), a / (2.0 * k.sqrt()));
        let peak = -20.0 * (2.0 * zeta * (1.0 - zeta * zeta).sqrt()).log10();
        assert!((fig.peak_db - peak).abs() < 1e-3, "{fig:?} {peak}");
        let fr = wn * (1.0 - 2.0 * zeta * zeta).sqrt() / std::f64::consts::TAU;
        assert!((fig.peak_hz / fr - 1.0).abs() < 3e-3, "{fig:?} {fr}");
        let w3 = wn
            * (1.0 - 2.0 * zeta * zeta + ((1.0 - 2.0 * zeta * zeta).powi(2) + 1.0).sqrt()).sqrt();
        assert!(
            (fig.bandwidth_hz.unwrap() / (w3 / std::f64::consts::TAU) - 1.0).abs() < 1e-3,
            "{fig:?}"
        );
    }

    #[test]
    fn a_grid_that_ends_before_the_crossings_says_so() {
        let t = [
            (1.0, Complex::new(1.0, 0.0)),
            (2.0, Complex::new(1.01, 0.0)),
        ];
        let fig = closed_loop_figures(&t);
        assert_eq!((fig.crossover_hz, fig.bandwidth_hz), (None, None));
        assert_eq!(fig.peak_hz, 2.0);
    }
}
