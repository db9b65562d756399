//! Reference trajectories for the two sensing axes (mechanical mirror angles in rad) and the
//! figures derived from their definition alone: frame rate and line spacing.
//!
//! Axes: `alpha` moves the spot along y (the paper's 52 Hz Lissajous axis), `beta` along x
//! (27 Hz). Spacings are fractions of the image side along that axis; with a scan range in mm
//! they are also given in mm.

use nalgebra::Complex;
pub use scanhil_protocol::plant_units::SensingAxis;
use scanhil_protocol::plant_units::{FULL_RANGE_DEG, SensingPair};
use std::f64::consts::{PI, TAU};

fn full_range_rad() -> f64 {
    FULL_RANGE_DEG.to_radians()
}

fn default_alpha() -> SensingAxis {
    SensingAxis::Alpha
}

/// A reference trajectory (`"kind": "lissajous"`, ...); amplitudes default to the mirror's
/// full +-1.5 deg range.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Trajectory {
    /// `alpha = A_a sin(2 pi f_a t)`, `beta = A_b sin(2 pi f_b t + phase)`.
    Lissajous {
        /// Frequency on alpha (y), Hz (52 in the paper).
        alpha_hz: f64,
        /// Frequency on beta (x), Hz (27 in the paper).
        beta_hz: f64,
        /// Amplitude on alpha, rad.
        #[serde(default = "full_range_rad")]
        alpha_amplitude_rad: f64,
        /// Amplitude on beta, rad.
        #[serde(default = "full_range_rad")]
        beta_amplitude_rad: f64,
        /// Phase of beta against alpha, rad.
        #[serde(default)]
        relative_phase_rad: f64,
    },
    /// Slow and fast triangles (each starts at -amplitude); every half period of the fast one
    /// is one line.
    Raster {
        /// The slow triangle's frequency, Hz (2 in the paper).
        slow_hz: f64,
        /// The fast triangle's frequency, Hz (34 in the paper).
        fast_hz: f64,
        /// The axis that carries the slow triangle.
        slow_axis: SensingAxis,
        /// Amplitude on alpha, rad.
        #[serde(default = "full_range_rad")]
        alpha_amplitude_rad: f64,
        /// Amplitude on beta, rad.
        #[serde(default = "full_range_rad")]
        beta_amplitude_rad: f64,
        /// The fast triangle made of its odd harmonics up to this order only, scaled so its
        /// peaks stay at the amplitude (`None`: the ideal triangle). The paper: a triangle
        /// needs its first seven harmonics inside the loop's bandwidth (7 x 34 Hz = 238 Hz);
        /// the ideal triangle's higher harmonics only drive the coils into their limit at the
        /// corners.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        fast_max_harmonic: Option<u32>,
    },
    /// A step of `amplitude_rad` on one axis at `at_s`.
    Step {
        /// The stepped axis.
        #[serde(default = "default_alpha")]
        axis: SensingAxis,
        /// Step height, rad.
        amplitude_rad: f64,
        /// When the step happens, s.
        #[serde(default)]
        at_s: f64,
    },
    /// A sine on one axis.
    Sine {
        /// The driven axis.
        #[serde(default = "default_alpha")]
        axis: SensingAxis,
        /// Frequency, Hz.
        frequency_hz: f64,
        /// Amplitude, rad.
        amplitude_rad: f64,
    },
    /// A logarithmic sine sweep on one axis from `start_hz` to `stop_hz` over `duration_s`,
    /// then zero.
    SweptSine {
        /// The driven axis.
        #[serde(default = "default_alpha")]
        axis: SensingAxis,
        /// Start frequency, Hz.
        start_hz: f64,
        /// Stop frequency, Hz.
        stop_hz: f64,
        /// Sweep duration, s.
        duration_s: f64,
        /// Amplitude, rad.
        amplitude_rad: f64,
    },
}

/// The phase (rad) at `t_s` of a logarithmic sweep from `start_hz` to `stop_hz` over
/// `duration_s` (instantaneous frequency `start_hz (stop_hz/start_hz)^(t/duration)`).
#[must_use]
pub fn swept_sine_phase(start_hz: f64, stop_hz: f64, duration_s: f64, t_s: f64) -> f64 {
    let ratio_ln = (stop_hz / start_hz).ln();
    if ratio_ln == 0.0 {
        return TAU * start_hz * t_s;
    }
    TAU * start_hz * duration_s / ratio_ln * ((ratio_ln * t_s / duration_s).exp() - 1.0)
}

/// A triangle of period `1/f_hz` between -1 and 1, starting at -1.
fn triangle(f_hz: f64, t_s: f64) -> f64 {
    let phase = (f_hz * t_s).rem_euclid(1.0);
    if phase < 0.5 {
        4.0 * phase - 1.0
    } else {
        3.0 - 4.0 * phase
    }
}

/// A triangle of period `1/f_hz` between -1 and 1 starting at -1, made of its odd harmonics up
/// to order `max_order` and scaled so its peaks are exactly -1 and 1.
fn band_limited_triangle(f_hz: f64, max_order: u32, t_s: f64) -> f64 {
    let (sum, norm) = odd_orders(max_order).fold((0.0, 0.0), |(sum, norm), n| {
        let weight = 1.0 / (n * n);
        (sum + weight * (TAU * n * f_hz * t_s).cos(), norm + weight)
    });
    -sum / norm
}

/// The odd harmonic orders 1, 3, ... up to `max_order`.
fn odd_orders(max_order: u32) -> impl Iterator<Item = f64> {
    (1..=max_order).step_by(2).map(f64::from)
}

/// One frequency of a reference: `Re(phasor e^(j 2 pi f t))` per sensing axis, rad (for
/// `f_hz = 0` the phasor is the constant value).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tone {
    /// Frequency, Hz (0 for the constant part).
    pub f_hz: f64,
    /// The alpha axis' phasor, rad.
    pub alpha_rad: Complex<f64>,
    /// The beta axis' phasor, rad.
    pub beta_rad: Complex<f64>,
}

impl Tone {
    /// A sine `amplitude sin(2 pi f t + phase)` as a tone on `axis`.
    #[must_use]
    pub fn sine(axis: SensingAxis, f_hz: f64, amplitude_rad: f64, phase_rad: f64) -> Tone {
        // sin(x) = Re(-j e^(jx))
        let phasor = Complex::from_polar(amplitude_rad, phase_rad) * Complex::new(0.0, -1.0);
        on_axis(axis, f_hz, phasor)
    }
}

fn on_axis(axis: SensingAxis, f_hz: f64, phasor: Complex<f64>) -> Tone {
    let zero = Complex::new(0.0, 0.0);
    match axis {
        SensingAxis::Alpha => Tone {
            f_hz,
            alpha_rad: phasor,
            beta_rad: zero,
        },
        SensingAxis::Beta => Tone {
            f_hz,
            alpha_rad: zero,
            beta_rad: phasor,
        },
    }
}

/// The odd harmonics below `nyquist_hz` of a triangle between `-amplitude` and `amplitude`
/// starting at `-amplitude` (the raster's): `-8 A / (pi^2 n^2)` at `n f`, or, made of its
/// harmonics up to `max_order` only, `-A / (n^2 sum_k 1/k^2)` (peaks kept at `A`).
fn triangle_tones(
    axis: SensingAxis,
    f_hz: f64,
    amplitude_rad: f64,
    nyquist_hz: f64,
    max_order: Option<u32>,
) -> Vec<Tone> {
    let scale = match max_order {
        Some(order) => 1.0 / odd_orders(order).map(|n| 1.0 / (n * n)).sum::<f64>(),
        None => 8.0 / (PI * PI),
    };
    (1u64..)
        .step_by(2)
        .map(|n| (n as f64, n as f64 * f_hz))
        .take_while(|(n, f)| *f < nyquist_hz && max_order.is_none_or(|m| *n <= f64::from(m)))
        .map(|(n, f)| {
            let c = -scale * amplitude_rad / (n * n);
            on_axis(axis, f, Complex::new(c, 0.0))
        })
        .collect()
}

/// Adds tones of the same frequency together (they add coherently).
fn merged(mut tones: Vec<Tone>) -> Vec<Tone> {
    tones.sort_by(|a, b| a.f_hz.total_cmp(&b.f_hz));
    let mut out: Vec<Tone> = Vec::with_capacity(tones.len());
    for tone in tones {
        match out.last_mut() {
            Some(last) if (last.f_hz - tone.f_hz).abs() <= 1e-9 * tone.f_hz.max(1.0) => {
                last.alpha_rad += tone.alpha_rad;
                last.beta_rad += tone.beta_rad;
            }
            _ => out.push(tone),
        }
    }
    out
}

impl Trajectory {
    /// The Fourier content of the reference below `nyquist_hz` at steady state, one tone per
    /// frequency: a sine is one tone; a triangle (raster) its odd harmonics
    /// `-8 A / (pi^2 n^2) cos(2 pi n f t)`; a step its DC value; a swept sine its start
    /// frequency (its band: [`crate::power_budget::estimate`]).
    #[must_use]
    pub fn tones(&self, nyquist_hz: f64) -> Vec<Tone> {
        let tones = match *self {
            Trajectory::Lissajous {
                alpha_hz,
                beta_hz,
                alpha_amplitude_rad,
                beta_amplitude_rad,
                relative_phase_rad,
            } => vec![
                Tone::sine(SensingAxis::Alpha, alpha_hz, alpha_amplitude_rad, 0.0),
                Tone::sine(
                    SensingAxis::Beta,
                    beta_hz,
                    beta_amplitude_rad,
                    relative_phase_rad,
                ),
            ],
            Trajectory::Raster {
                slow_hz,
                fast_hz,
                slow_axis,
                alpha_amplitude_rad,
                beta_amplitude_rad,
                fast_max_harmonic,
            } => {
                let amplitude = |axis: SensingAxis| match axis {
                    SensingAxis::Alpha => alpha_amplitude_rad,
                    SensingAxis::Beta => beta_amplitude_rad,
                };
                let fast_axis = slow_axis.other();
                let mut tones =
                    triangle_tones(slow_axis, slow_hz, amplitude(slow_axis), nyquist_hz, None);
                tones.extend(triangle_tones(
                    fast_axis,
                    fast_hz,
                    amplitude(fast_axis),
                    nyquist_hz,
                    fast_max_harmonic,
                ));
                tones
            }
            Trajectory::Step {
                axis,
                amplitude_rad,
                ..
            } => vec![on_axis(axis, 0.0, Complex::new(amplitude_rad, 0.0))],
            Trajectory::Sine {
                axis,
                frequency_hz,
                amplitude_rad,
            } => vec![Tone::sine(axis, frequency_hz, amplitude_rad, 0.0)],
            Trajectory::SweptSine {
                axis,
                start_hz,
                amplitude_rad,
                ..
            } => vec![Tone::sine(axis, start_hz, amplitude_rad, 0.0)],
        };
        merged(tones)
    }
}

/// Figures derived from a trajectory's definition.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TrajectoryFigures {
    /// The trajectory kind.
    pub kind: &'static str,
    /// Time for one complete image, s (Lissajous: the pattern's period `1/gcd`; raster: one
    /// slow sweep). None for single-axis references.
    pub frame_time_s: Option<f64>,
    /// Complete images per second.
    pub frame_rate_hz: Option<f64>,
    /// Raster: lines per slow sweep (`fast_hz / slow_hz`).
    pub lines_per_frame: Option<f64>,
    /// Line spacing along y (the alpha axis) at the image centre, fraction of the image side.
    pub spacing_alpha_fraction: Option<f64>,
    /// Line spacing along x (the beta axis) at the image centre, fraction of the image side.
    pub spacing_beta_fraction: Option<f64>,
    /// The coarser of the two spacings (the paper's "resolution").
    pub resolution_fraction: Option<f64>,
    /// Scan range (x along beta, y along alpha) the mm figures use, mm.
    pub scan_range_mm: Option<(f64, f64)>,
    /// Spacing along y in mm.
    pub spacing_alpha_mm: Option<f64>,
    /// Spacing along x in mm.
    pub spacing_beta_mm: Option<f64>,
    /// The coarser spacing in mm.
    pub resolution_mm: Option<f64>,
}

/// The common period of two frequencies, s, when both are multiples of 1 mHz.
fn common_period_s(f1_hz: f64, f2_hz: f64) -> Option<f64> {
    let to_mhz = |f: f64| {
        let m = (f * 1000.0).round();
        ((f * 1000.0 - m).abs() < 1e-6 && m > 0.0).then_some(m as u64)
    };
    let (a, b) = (to_mhz(f1_hz)?, to_mhz(f2_hz)?);
    let gcd = (1..).try_fold(
        (a, b),
        |(x, y), _: u32| if y == 0 { Err(x) } else { Ok((y, x % y)) },
    );
    let g = gcd.err()?;
    Some(1000.0 / g as f64)
}

/// The spacing, at the image centre, of the values `other(t)` takes where `driven(t)` crosses
/// zero: `driven = sin(2 pi f t + phase)` over `period_s`. Returned as a fraction of the image
/// side (values are normalised to [-1, 1]).
fn centre_spacing(f_hz: f64, phase_rad: f64, period_s: f64, other: impl Fn(f64) -> f64) -> f64 {
    let crossings = (2.0 * f_hz * period_s).round() as i64;
    let mut values: Vec<f64> = (0..crossings)
        .map(|k| (k as f64 * PI - phase_rad).rem_euclid(TAU * f_hz * period_s) / (TAU * f_hz))
        .map(other)
        .collect();
    values.sort_by(f64::total_cmp);
    values.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    let above = values
        .iter()
        .position(|v| *v > 1e-9)
        .unwrap_or(values.len());
    let at_zero = above > 0 && values[above - 1].abs() <= 1e-9;
    let gap = |i: usize, j: usize| values.get(j).zip(values.get(i)).map(|(b, a)| b - a);
    let spacing = if at_zero {
        let i = above - 1;
        gap(i, i + 1)
            .into_iter()
            .chain(i.checked_sub(1).and_then(|h| gap(h, i)))
            .fold(0.0, f64::max)
    } else {
        above
            .checked_sub(1)
            .and_then(|i| gap(i, above))
            .unwrap_or(2.0)
    };
    spacing / 2.0
}

impl Trajectory {
    /// Checks the frequencies against a loop of Nyquist frequency `nyquist_hz` (half the
    /// control rate): each positive, finite and below Nyquist (a reference at or above it
    /// aliases: sampled at the control rate, 1e7 Hz on a 20 kHz loop is a constant). On
    /// failure the field (as in the scenario file, `trajectory.alpha_hz`) and why, with the
    /// value and the limit. (Amplitudes too large for the mirror are the power check's and the
    /// planned saturation's: [`crate::run::plan`].)
    ///
    /// # Errors
    /// The first frequency out of range.
    pub fn check(&self, nyquist_hz: f64) -> Result<(), (&'static str, String)> {
        let frequencies = match *self {
            Trajectory::Lissajous {
                alpha_hz, beta_hz, ..
            } => vec![
                ("trajectory.alpha_hz", alpha_hz),
                ("trajectory.beta_hz", beta_hz),
            ],
            Trajectory::Raster {
                slow_hz, fast_hz, ..
            } => vec![
                ("trajectory.slow_hz", slow_hz),
                ("trajectory.fast_hz", fast_hz),
            ],
            Trajectory::Step { .. } => vec![],
            Trajectory::Sine { frequency_hz, .. } => {
                vec![("trajectory.frequency_hz", frequency_hz)]
            }
            Trajectory::SweptSine {
                start_hz, stop_hz, ..
            } => vec![
                ("trajectory.start_hz", start_hz),
                ("trajectory.stop_hz", stop_hz),
            ],
        };
        for (field, f_hz) in frequencies {
            if !(f_hz.is_finite() && f_hz > 0.0) {
                return Err((field, format!("{f_hz} Hz must be positive and finite")));
            }
            if f_hz >= nyquist_hz {
                return Err((
                    field,
                    format!(
                        "{f_hz} Hz is at or above {nyquist_hz} Hz, the Nyquist frequency of the \
                         {} Hz control rate: sampled by the loop it aliases to another \
                         frequency (or a constant)",
                        2.0 * nyquist_hz
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The same trajectory with every amplitude multiplied by `factor` (frequencies, phases
    /// and timing unchanged): what the power budget's `shrink` runs.
    #[must_use]
    pub fn scaled(&self, factor: f64) -> Trajectory {
        let mut scaled = self.clone();
        match &mut scaled {
            Trajectory::Lissajous {
                alpha_amplitude_rad,
                beta_amplitude_rad,
                ..
            }
            | Trajectory::Raster {
                alpha_amplitude_rad,
                beta_amplitude_rad,
                ..
            } => {
                *alpha_amplitude_rad *= factor;
                *beta_amplitude_rad *= factor;
            }
            Trajectory::Step { amplitude_rad, .. }
            | Trajectory::Sine { amplitude_rad, .. }
            | Trajectory::SweptSine { amplitude_rad, .. } => *amplitude_rad *= factor,
        }
        scaled
    }

    /// The reference mirror angles at `t_s`, rad.
    #[must_use]
    pub fn reference_rad(&self, t_s: f64) -> SensingPair {
        match *self {
            Trajectory::Lissajous {
                alpha_hz,
                beta_hz,
                alpha_amplitude_rad,
                beta_amplitude_rad,
                relative_phase_rad,
            } => SensingPair {
                alpha: alpha_amplitude_rad * (TAU * alpha_hz * t_s).sin(),
                beta: beta_amplitude_rad * (TAU * beta_hz * t_s + relative_phase_rad).sin(),
            },
            Trajectory::Raster {
                slow_hz,
                fast_hz,
                slow_axis,
                alpha_amplitude_rad,
                beta_amplitude_rad,
                fast_max_harmonic,
            } => {
                let fast = match fast_max_harmonic {
                    Some(order) => band_limited_triangle(fast_hz, order, t_s),
                    None => triangle(fast_hz, t_s),
                };
                let (slow, fast) = (triangle(slow_hz, t_s), fast);
                let (alpha, beta) = match slow_axis {
                    SensingAxis::Alpha => (slow, fast),
                    SensingAxis::Beta => (fast, slow),
                };
                SensingPair {
                    alpha: alpha * alpha_amplitude_rad,
                    beta: beta * beta_amplitude_rad,
                }
            }
            Trajectory::Step {
                axis,
                amplitude_rad,
                at_s,
            } => axis.pair(if t_s >= at_s { amplitude_rad } else { 0.0 }),
            Trajectory::Sine {
                axis,
                frequency_hz,
                amplitude_rad,
            } => axis.pair(amplitude_rad * (TAU * frequency_hz * t_s).sin()),
            Trajectory::SweptSine {
                axis,
                start_hz,
                stop_hz,
                duration_s,
                amplitude_rad,
            } => {
                if !(0.0..duration_s).contains(&t_s) {
                    return SensingPair::default();
                }
                axis.pair(
                    amplitude_rad * swept_sine_phase(start_hz, stop_hz, duration_s, t_s).sin(),
                )
            }
        }
    }

    /// Whether the reference is periodic (a steady state exists): Lissajous, raster, sine.
    #[must_use]
    pub fn is_periodic(&self) -> bool {
        matches!(
            self,
            Trajectory::Lissajous { .. } | Trajectory::Raster { .. } | Trajectory::Sine { .. }
        )
    }

    /// The largest |reference| on `axis`, rad.
    #[must_use]
    pub fn peak_rad(&self, axis: SensingAxis) -> f64 {
        let pick = |alpha: f64, beta: f64| match axis {
            SensingAxis::Alpha => alpha.abs(),
            SensingAxis::Beta => beta.abs(),
        };
        match *self {
            Trajectory::Lissajous {
                alpha_amplitude_rad,
                beta_amplitude_rad,
                ..
            }
            | Trajectory::Raster {
                alpha_amplitude_rad,
                beta_amplitude_rad,
                ..
            } => pick(alpha_amplitude_rad, beta_amplitude_rad),
            Trajectory::Step {
                axis: driven,
                amplitude_rad,
                ..
            }
            | Trajectory::Sine {
                axis: driven,
                amplitude_rad,
                ..
            }
            | Trajectory::SweptSine {
                axis: driven,
                amplitude_rad,
                ..
            } => {
                if driven == axis {
                    amplitude_rad.abs()
                } else {
                    0.0
                }
            }
        }
    }

    /// Frame rate and line spacing from the definition; `scan_range_mm` = (x along beta,
    /// y along alpha) adds the spacings in mm.
    #[must_use]
    pub fn figures(&self, scan_range_mm: Option<(f64, f64)>) -> TrajectoryFigures {
        let mut fig = TrajectoryFigures {
            kind: "",
            frame_time_s: None,
            frame_rate_hz: None,
            lines_per_frame: None,
            spacing_alpha_fraction: None,
            spacing_beta_fraction: None,
            resolution_fraction: None,
            scan_range_mm,
            spacing_alpha_mm: None,
            spacing_beta_mm: None,
            resolution_mm: None,
        };
        match *self {
            Trajectory::Lissajous {
                alpha_hz,
                beta_hz,
                relative_phase_rad,
                ..
            } => {
                fig.kind = "lissajous";
                if let Some(period) = common_period_s(alpha_hz, beta_hz) {
                    fig.frame_time_s = Some(period);
                    fig.frame_rate_hz = Some(1.0 / period);
                    // Along y: alpha values where beta crosses zero (the centre column).
                    fig.spacing_alpha_fraction =
                        Some(centre_spacing(beta_hz, relative_phase_rad, period, |t| {
                            (TAU * alpha_hz * t).sin()
                        }));
                    // Along x: beta values where alpha crosses zero (the centre row).
                    fig.spacing_beta_fraction = Some(centre_spacing(alpha_hz, 0.0, period, |t| {
                        (TAU * beta_hz * t + relative_phase_rad).sin()
                    }));
                }
            }
            Trajectory::Raster {
                slow_hz,
                fast_hz,
                slow_axis,
                ..
            } => {
                fig.kind = "raster";
                let sweep = 0.5 / slow_hz;
                let lines = fast_hz / slow_hz;
                fig.frame_time_s = Some(sweep);
                fig.frame_rate_hz = Some(1.0 / sweep);
                fig.lines_per_frame = Some(lines);
                let spacing = Some(1.0 / lines);
                match slow_axis {
                    SensingAxis::Alpha => fig.spacing_alpha_fraction = spacing,
                    SensingAxis::Beta => fig.spacing_beta_fraction = spacing,
                }
            }
            Trajectory::Step { .. } => fig.kind = "step",
            Trajectory::Sine { .. } => fig.kind = "sine",
            Trajectory::SweptSine { .. } => fig.kind = "swept_sine",
        }
        fig.resolution_fraction = match (fig.spacing_alpha_fraction, fig.spacing_beta_fraction) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        };
        if let Some((x_mm, y_mm)) = scan_range_mm {
            fig.spacing_alpha_mm = fig.spacing_alpha_fraction.map(|s| s * y_mm);
            fig.spacing_beta_mm = fig.spacing_beta_fraction.map(|s| s * x_mm);
            fig.resolution_mm = match (fig.spacing_alpha_mm, fig.spacing_beta_mm) {
                (Some(a), Some(b)) => Some(a.max(b)),
                (a, b) => a.or(b),
            };
        }
        fig
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_multiplies_every_amplitude_and_nothing_else() {
        let raster = Trajectory::Raster {
            slow_hz: 2.0,
            fast_hz: 34.0,
            slow_axis: SensingAxis::Beta,
            alpha_amplitude_rad: 0.02,
            beta_amplitude_rad: 0.01,
            fast_max_harmonic: None,
        };
        let half = raster.scaled(0.5);
        for t_s in [0.0, 0.013, 0.2, 0.377] {
            let (a, b) = (raster.reference_rad(t_s), half.reference_rad(t_s));
            assert!((b.alpha - 0.5 * a.alpha).abs() < 1e-15);
            assert!((b.beta - 0.5 * a.beta).abs() < 1e-15);
        }
        let sine = Trajectory::Sine {
            axis: SensingAxis::Beta,
            frequency_hz: 60.0,
            amplitude_rad: 0.02,
        };
        assert_eq!(
            sine.scaled(0.25),
            Trajectory::Sine {
                axis: SensingAxis::Beta,
                frequency_hz: 60.0,
                amplitude_rad: 0.005,
            }
        );
    }
}
