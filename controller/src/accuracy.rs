//! What a discretisation costs in accuracy: where the controller's lightly damped (tone) poles
//! land after discretisation, and the tracking error of a simulated scan with the nominal
//! plant, for each method. `scanhil analyze --compare-methods` reports it; the
//! `control_discretisation` bench adds the run time per period.

use scanhil_protocol::plant_units::SensingPair;

use crate::discretise::Method;
use crate::link::{NominalPlantLink, PlantLink};
use crate::loop_analysis::ZPoint;
use crate::scan_controller::ScanController;
use crate::settings::ControllerSettings;
use crate::trajectory::Trajectory;

/// Continuous poles with a damping ratio below this are tones.
const TONE_DAMPING: f64 = 0.01;

/// Where one lightly damped continuous pole pair lands after discretisation.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TonePlacement {
    /// The continuous pole's frequency `Im(s) / 2 pi`, Hz.
    pub continuous_hz: f64,
    /// The discrete pole's frequency `arg(z) / (2 pi T)`, Hz.
    pub discrete_hz: f64,
    /// `discrete - continuous`, mHz.
    pub error_mhz: f64,
    /// The continuous pole's damping ratio.
    pub continuous_damping: f64,
    /// The discrete pole's damping ratio (of `ln(z)/T`).
    pub discrete_damping: f64,
    /// The discrete pole's |z|.
    pub discrete_abs: f64,
}

/// The tone placements of `settings`' controller, lowest frequency first.
#[must_use]
pub fn tone_placements(
    settings: &ControllerSettings,
    discrete_poles: &[nalgebra::Complex<f64>],
) -> Vec<TonePlacement> {
    let t = settings.period_s();
    let mut out: Vec<TonePlacement> = settings
        .continuous()
        .poles
        .iter()
        .flat_map(|q| q.roots())
        .filter(|s| s.im > 0.0 && -s.re / s.norm() < TONE_DAMPING)
        .map(|s| {
            let continuous_hz = s.im / std::f64::consts::TAU;
            let nearest = discrete_poles
                .iter()
                .filter(|z| z.im > 0.0)
                .map(|&z| ZPoint::new(z, t))
                .min_by(|a, b| {
                    (a.f_hz - continuous_hz)
                        .abs()
                        .total_cmp(&(b.f_hz - continuous_hz).abs())
                });
            let z = nearest.unwrap_or(ZPoint::new(nalgebra::Complex::new(0.0, 0.0), t));
            TonePlacement {
                continuous_hz,
                discrete_hz: z.f_hz,
                error_mhz: (z.f_hz - continuous_hz) * 1e3,
                continuous_damping: -s.re / s.norm(),
                discrete_damping: z.damping,
                discrete_abs: z.abs,
            }
        })
        .collect();
    out.sort_by(|a, b| a.continuous_hz.total_cmp(&b.continuous_hz));
    out
}

/// Tracking error of a simulated scan, measured over the last `measure_s` seconds.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TrackingError {
    /// Simulated time, s.
    pub duration_s: f64,
    /// Measured over the final this many seconds, s.
    pub measured_over_s: f64,
    /// RMS error on alpha, urad.
    pub rms_alpha_urad: f64,
    /// RMS error on beta, urad.
    pub rms_beta_urad: f64,
    /// Largest |error| on either axis, urad.
    pub max_urad: f64,
    /// Periods with a clipped coil command.
    pub saturated_periods: u64,
}

/// Runs `controller` against the nominal plant of `settings` following `trajectory` for
/// `duration_s` and measures the error (reference minus true angle) over the last `measure_s`.
#[must_use]
pub fn simulate_tracking(
    settings: &ControllerSettings,
    controller: &mut ScanController,
    trajectory: &Trajectory,
    duration_s: f64,
    measure_s: f64,
) -> TrackingError {
    let t = controller.period_s();
    let mut plant = NominalPlantLink::new(&settings.plant, t, 0.0, 0);
    controller.reset();
    let steps = (duration_s / t).round() as u64;
    let first_measured = steps.saturating_sub((measure_s / t).round() as u64);
    let mut measured = SensingPair::default();
    let (mut sum_a, mut sum_b, mut max, mut n) = (0.0, 0.0, 0.0f64, 0u64);
    for k in 0..steps {
        let reference = trajectory.reference_rad(k as f64 * t);
        if k >= first_measured {
            let (ea, eb) = (
                reference.alpha - measured.alpha,
                reference.beta - measured.beta,
            );
            sum_a += ea * ea;
            sum_b += eb * eb;
            max = max.max(ea.abs()).max(eb.abs());
            n += 1;
        }
        let command = controller.step(reference, measured);
        measured = plant
            .exchange(command)
            .expect("the nominal plant accepts every finite command");
    }
    let rms = |s: f64| (s / n.max(1) as f64).sqrt() * 1e6;
    TrackingError {
        duration_s,
        measured_over_s: measure_s,
        rms_alpha_urad: rms(sum_a),
        rms_beta_urad: rms(sum_b),
        max_urad: max * 1e6,
        saturated_periods: controller.saturated_periods(),
    }
}

/// One method's result in a comparison.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MethodComparison {
    /// The method's name.
    pub method: String,
    /// Whether the stability check accepted it.
    pub accepted: bool,
    /// The refusal message (with the poles) when it was refused.
    pub refusal: Option<String>,
    /// Where the tone poles land.
    pub tones: Vec<TonePlacement>,
    /// Tracking error of the simulated scan (accepted methods only).
    pub tracking: Option<TrackingError>,
}

/// Every method of [`Method::all`] (prewarped at `prewarp_hz`) applied to `settings`' law.
#[must_use]
pub fn compare_methods(
    settings: &ControllerSettings,
    prewarp_hz: &[f64],
    trajectory: &Trajectory,
    duration_s: f64,
    measure_s: f64,
) -> Vec<MethodComparison> {
    Method::all(prewarp_hz)
        .into_iter()
        .map(|method| {
            let variant = ControllerSettings {
                discretisation: method.clone(),
                ..settings.clone()
            };
            let tones = variant
                .axis_controller()
                .map(|axis| tone_placements(&variant, &axis.linear().poles()))
                .unwrap_or_default();
            match variant.build() {
                Ok(mut controller) => MethodComparison {
                    method: method.name(),
                    accepted: true,
                    refusal: None,
                    tones,
                    tracking: Some(simulate_tracking(
                        &variant,
                        &mut controller,
                        trajectory,
                        duration_s,
                        measure_s,
                    )),
                },
                Err(e) => MethodComparison {
                    method: method.name(),
                    accepted: false,
                    refusal: Some(e.to_string()),
                    tones,
                    tracking: None,
                },
            }
        })
        .collect()
}
