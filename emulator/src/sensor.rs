//! The ILD 2300-100 triangulation sensor: turns the optics' distance into the 18-bit value it
//! sends, with its noise, its range limits and error values, on its own measuring clock, with
//! its measured-value counter.
//!
//! - Range: [`MeasuringRange::ILD2300_100`] (70-170 mm). Distances in the start/end reserves
//!   (69-70 mm, 170-171 mm) are sent as distances in the reserve codes; nearer than the start
//!   reserve is [`IldError::PeakBeforeRange`], farther than the end reserve
//!   [`IldError::PeakAfterRange`]; no surface or a shaded spot is [`IldError::NoPeak`].
//! - Noise: Gaussian, `noise_rms_um` (1.5 um by default: the resolution quoted for the
//!   ILD 2300-100 at 20 kHz; the raw step is 1.557 um), from a seeded ChaCha8 stream.
//! - Clock: sample k is taken at control time `clock_offset_s + k / (rate (1 + drift))`; the
//!   plant asks which instants fall in a control period ([`Ild2300::sample_instants`]).
//! - Counter: 18 bits, `(counter_start + k) mod 2^18`, as the sensor's `OUTADD_RS422` counter.
//! - Exposure (`exposure_us`): the optics looked at over the exposure, their distances averaged
//!   weighted by each look's intensity at the receiver (all alike unless the scene lists
//!   `receiver_intensity`).
//! - Receiver limits (part `receiver_intensity`): a spot darker than `intensity_dark_below`
//!   gives [`IldError::NoPeak`] (the manual's "no peak available"), one brighter than
//!   `intensity_saturated_above` [`IldError::PeakTooWide`] (a saturated line detector clips
//!   the peak, which widens it: our reading, the manual names no saturation code). Intensities
//!   are relative to a white matte surface facing the receiver at mid-range
//!   ([`crate::optics::receiver`]).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use scanhil_protocol::ild::value::{DIGITAL_MAX, RAW_MAX};
use scanhil_protocol::ild::{IldError, IldValue, MeasuringRange, MeasuringRate};
use serde::{Deserialize, Serialize};

use crate::optics::OpticalOutcome;

/// The sensor's default measuring rate, Hz.
pub const DEFAULT_MEASURING_RATE_HZ: f64 = 20_000.0;
/// Default distance noise (rms), um: the resolution quoted for the ILD 2300-100.
pub const DEFAULT_NOISE_RMS_UM: f64 = 1.5;
/// Modulus of the measured-value counter (18 bits).
pub const COUNTER_MODULUS: u64 = RAW_MAX as u64 + 1;
/// Points at which the optics are looked at during one exposure (`exposure_us` above 0).
pub const EXPOSURE_POINTS: usize = 5;
/// ChaCha stream of the sensor's noise, so it is independent of other parts seeded alike.
const NOISE_STREAM: u64 = 0x11D_2300;

fn default_rate() -> f64 {
    DEFAULT_MEASURING_RATE_HZ
}
fn default_noise() -> f64 {
    DEFAULT_NOISE_RMS_UM
}
fn default_range() -> MeasuringRange {
    MeasuringRange::ILD2300_100
}
fn default_wavelength_nm() -> f64 {
    DEFAULT_WAVELENGTH_NM
}
fn default_receiver_aperture_mm() -> f64 {
    DEFAULT_RECEIVER_APERTURE_MM
}
fn default_dark_below() -> f64 {
    DEFAULT_INTENSITY_DARK_BELOW
}
fn default_saturated_above() -> f64 {
    DEFAULT_INTENSITY_SATURATED_ABOVE
}

/// The ILD 2300's laser wavelength, nm (red; recalled from the data sheet, not re-read here:
/// docs/decisions.md).
pub const DEFAULT_WAVELENGTH_NM: f64 = 670.0;
/// The receiving lens's clear aperture, mm: assumed (not in the data sheet), a lens of this
/// size fits the ILD 2300's receiver window.
pub const DEFAULT_RECEIVER_APERTURE_MM: f64 = 12.0;
/// The darkest spot the receiver still evaluates, relative intensity: assumed, a black (5 %)
/// surface seen 60 deg off its normal at the far end of the range (0.0125) still measures.
pub const DEFAULT_INTENSITY_DARK_BELOW: f64 = 0.01;
/// The brightest spot the receiver evaluates unsaturated, relative intensity: assumed, ten
/// times a white surface at mid-range (only a glint of a glossy surface reaches it).
pub const DEFAULT_INTENSITY_SATURATED_ABOVE: f64 = 10.0;

/// The scene's `sensor` section.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorConfig {
    /// Measuring rate, Hz: one of the ILD 2300's ([`MeasuringRate`]).
    #[serde(default = "default_rate")]
    pub measuring_rate_hz: f64,
    /// Distance noise (rms), um; used when the scene lists `sensor_noise`.
    #[serde(default = "default_noise")]
    pub noise_rms_um: f64,
    /// Control time of the sensor's sample 0, s.
    #[serde(default)]
    pub clock_offset_s: f64,
    /// How much faster the sensor's clock runs than the control clock, ppm.
    #[serde(default)]
    pub clock_drift_ppm: f64,
    /// Counter value of sample 0 (below 2^18).
    #[serde(default)]
    pub counter_start: u32,
    /// Measuring range (ILD 2300-100 by default).
    #[serde(default = "default_range")]
    pub range: MeasuringRange,
    /// How long each measuring cycle exposes the receiver, us (0, the default: the distance
    /// at the cycle's instant alone). A spot that moves meanwhile is seen all along its path:
    /// the value is the average of the distances at [`EXPOSURE_POINTS`] instants spread over
    /// the exposure, which ends at the cycle's instant. At most one cycle.
    #[serde(default)]
    pub exposure_us: f64,
    /// The laser's wavelength, nm (for the speckle, part `speckle`).
    #[serde(default = "default_wavelength_nm")]
    pub wavelength_nm: f64,
    /// The receiving lens's clear aperture, mm (for the speckle, part `speckle`).
    #[serde(default = "default_receiver_aperture_mm")]
    pub receiver_aperture_mm: f64,
    /// Below this relative intensity the receiver finds no peak (part `receiver_intensity`).
    #[serde(default = "default_dark_below")]
    pub intensity_dark_below: f64,
    /// Above this relative intensity the receiver saturates (part `receiver_intensity`).
    #[serde(default = "default_saturated_above")]
    pub intensity_saturated_above: f64,
}

impl Default for SensorConfig {
    fn default() -> Self {
        SensorConfig {
            measuring_rate_hz: DEFAULT_MEASURING_RATE_HZ,
            noise_rms_um: DEFAULT_NOISE_RMS_UM,
            clock_offset_s: 0.0,
            clock_drift_ppm: 0.0,
            counter_start: 0,
            range: MeasuringRange::ILD2300_100,
            exposure_us: 0.0,
            wavelength_nm: DEFAULT_WAVELENGTH_NM,
            receiver_aperture_mm: DEFAULT_RECEIVER_APERTURE_MM,
            intensity_dark_below: DEFAULT_INTENSITY_DARK_BELOW,
            intensity_saturated_above: DEFAULT_INTENSITY_SATURATED_ABOVE,
        }
    }
}

/// A sensor configuration field out of its domain.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("sensor field `{field}` = {value} must be {requirement}")]
pub struct SensorError {
    /// The field's JSON name.
    pub field: &'static str,
    /// The value found.
    pub value: f64,
    /// What it must be.
    pub requirement: &'static str,
}

/// One of the sensor's sample instants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleInstant {
    /// Sample number since the sensor's clock started (sample 0 at `clock_offset_s`).
    pub index: u64,
    /// Control time of the sample, s.
    pub t_s: f64,
}

/// One measured value as the sensor outputs it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IldSample {
    /// Control time of the sample, s.
    pub t_s: f64,
    /// The 18-bit measured-value counter.
    pub counter: u32,
    /// The value sent: a raw distance or an error.
    pub value: IldValue,
    /// The noise-free distance the optics delivered, mm (`None`: no distance).
    pub true_distance_mm: Option<f64>,
}

/// The emulated ILD 2300.
#[derive(Debug, Clone)]
pub struct Ild2300 {
    config: SensorConfig,
    /// Samples per second of control time.
    effective_rate_hz: f64,
    noise: Option<Normal<f64>>,
    rng: ChaCha8Rng,
    /// Whether too dark and saturated spots are refused (part `receiver_intensity`).
    intensity_limits: bool,
}

impl Ild2300 {
    /// A sensor with a checked configuration; `seed` is the scene's seed, `noise` whether the
    /// scene lists `sensor_noise`.
    ///
    /// # Errors
    /// [`SensorError`] naming the bad field.
    pub fn new(config: &SensorConfig, seed: u64, noise: bool) -> Result<Ild2300, SensorError> {
        let bad = |field, value, requirement| {
            Err(SensorError {
                field,
                value,
                requirement,
            })
        };
        if MeasuringRate::from_hz(config.measuring_rate_hz).is_none() {
            return bad(
                "measuring_rate_hz",
                config.measuring_rate_hz,
                "one of 1500, 2500, 5000, 10000, 20000, 30000, 49140",
            );
        }
        if !(config.noise_rms_um.is_finite() && config.noise_rms_um >= 0.0) {
            return bad("noise_rms_um", config.noise_rms_um, "finite and >= 0");
        }
        if !config.clock_offset_s.is_finite() {
            return bad("clock_offset_s", config.clock_offset_s, "finite");
        }
        if !(config.clock_drift_ppm.is_finite() && config.clock_drift_ppm.abs() < 1e5) {
            return bad(
                "clock_drift_ppm",
                config.clock_drift_ppm,
                "finite, |drift| < 1e5 ppm",
            );
        }
        if u64::from(config.counter_start) >= COUNTER_MODULUS {
            return bad(
                "counter_start",
                f64::from(config.counter_start),
                "below 2^18",
            );
        }
        let cycle_us = 1e6 / config.measuring_rate_hz;
        if !(config.exposure_us.is_finite()
            && config.exposure_us >= 0.0
            && config.exposure_us <= cycle_us)
        {
            return bad(
                "exposure_us",
                config.exposure_us,
                "finite, from 0 to one measuring cycle (1e6 / measuring_rate_hz us)",
            );
        }
        if !(config.wavelength_nm.is_finite() && config.wavelength_nm > 0.0) {
            return bad("wavelength_nm", config.wavelength_nm, "finite and > 0");
        }
        if !(config.receiver_aperture_mm.is_finite() && config.receiver_aperture_mm > 0.0) {
            return bad(
                "receiver_aperture_mm",
                config.receiver_aperture_mm,
                "finite and > 0",
            );
        }
        if !(config.intensity_dark_below.is_finite() && config.intensity_dark_below >= 0.0) {
            return bad(
                "intensity_dark_below",
                config.intensity_dark_below,
                "finite and >= 0",
            );
        }
        if config.intensity_saturated_above.is_nan()
            || config.intensity_saturated_above <= config.intensity_dark_below
        {
            return bad(
                "intensity_saturated_above",
                config.intensity_saturated_above,
                "above intensity_dark_below",
            );
        }
        let span = config.range.span_mm;
        if !(span.is_finite() && span > 0.0 && config.range.start_mm.is_finite()) {
            return bad("range.span_mm", span, "finite and > 0 (start finite)");
        }
        let noise = (noise && config.noise_rms_um > 0.0)
            .then(|| Normal::new(0.0, config.noise_rms_um * 1e-3).ok())
            .flatten();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(NOISE_STREAM);
        Ok(Ild2300 {
            config: *config,
            effective_rate_hz: config.measuring_rate_hz * (1.0 + config.clock_drift_ppm * 1e-6),
            noise,
            rng,
            intensity_limits: false,
        })
    }

    /// The same sensor refusing too dark and saturated spots, or not (part
    /// `receiver_intensity`).
    #[must_use]
    pub fn with_intensity_limits(mut self, on: bool) -> Ild2300 {
        self.intensity_limits = on;
        self
    }

    /// The nominal measuring rate, Hz.
    #[must_use]
    pub fn measuring_rate_hz(&self) -> f64 {
        self.config.measuring_rate_hz
    }

    /// The measuring range.
    #[must_use]
    pub fn range(&self) -> MeasuringRange {
        self.config.range
    }

    /// The sensor's configuration.
    #[must_use]
    pub fn config(&self) -> &SensorConfig {
        &self.config
    }

    /// The sample instants in `(start_s, end_s]` of control time, in order. Consecutive
    /// periods computed with the same boundary value share no instant and miss none.
    pub fn sample_instants(
        &self,
        start_s: f64,
        end_s: f64,
    ) -> impl Iterator<Item = SampleInstant> + use<> {
        let (offset, rate) = (self.config.clock_offset_s, self.effective_rate_hz);
        let last_at_or_before = |t: f64| ((t - offset) * rate).floor();
        let first = (last_at_or_before(start_s) + 1.0).max(0.0);
        let last = last_at_or_before(end_s);
        let (first, last) = if first.is_finite() && last.is_finite() && last >= first {
            (first as u64, last as u64 + 1)
        } else {
            (0, 0)
        };
        (first..last).map(move |index| SampleInstant {
            index,
            t_s: offset + index as f64 / rate,
        })
    }

    /// The exposure of each cycle, s (0: one instant).
    #[must_use]
    pub fn exposure_s(&self) -> f64 {
        self.config.exposure_us * 1e-6
    }

    /// The instants, in order, at which the optics are looked at for a cycle at `t_s`: the
    /// middles of [`EXPOSURE_POINTS`] equal slices of the exposure ending at `t_s`; `t_s` alone
    /// without exposure.
    pub fn exposure_instants(&self, t_s: f64) -> impl Iterator<Item = f64> + use<> {
        let exposure_s = self.exposure_s();
        let (points, slice_s) = if exposure_s > 0.0 {
            (EXPOSURE_POINTS, exposure_s / EXPOSURE_POINTS as f64)
        } else {
            (1, 0.0)
        };
        (0..points).map(move |j| t_s - exposure_s + (j as f64 + 0.5) * slice_s)
    }

    /// What the receiver made of the optics over one exposure: the average of the distances
    /// seen, each weighted by its intensity (the part of the path the spot was shaded or off
    /// the surface adds no light), with the exposure's mean intensity; when none was seen, the
    /// outcome at the exposure's end.
    #[must_use]
    pub fn exposed(outcomes: impl IntoIterator<Item = OpticalOutcome>) -> OpticalOutcome {
        let (mut weighted_mm, mut plain_mm, mut sum_intensity) = (0.0, 0.0, 0.0);
        let (mut looks, mut seen, mut last) = (0u32, 0u32, OpticalOutcome::Miss);
        for outcome in outcomes {
            if let OpticalOutcome::Distance {
                z_meas_mm,
                intensity,
            } = outcome
            {
                weighted_mm += intensity * z_meas_mm;
                plain_mm += z_meas_mm;
                sum_intensity += intensity;
                seen += 1;
            }
            looks += 1;
            last = outcome;
        }
        if seen == 0 {
            return last;
        }
        // Looks that send no light still place the spot when none sends any.
        let z_meas_mm = if sum_intensity > 0.0 {
            weighted_mm / sum_intensity
        } else {
            plain_mm / f64::from(seen)
        };
        OpticalOutcome::Distance {
            z_meas_mm,
            intensity: sum_intensity / f64::from(looks),
        }
    }

    /// The sensor's output at `instant` for what the optics deliver.
    pub fn measure(&mut self, instant: SampleInstant, outcome: &OpticalOutcome) -> IldSample {
        let counter =
            ((u64::from(self.config.counter_start) + instant.index) % COUNTER_MODULUS) as u32;
        let true_distance_mm = match outcome {
            OpticalOutcome::Distance { z_meas_mm, .. } => Some(*z_meas_mm),
            OpticalOutcome::Miss | OpticalOutcome::Shaded(_) => None,
        };
        IldSample {
            t_s: instant.t_s,
            counter,
            value: self.value_for(outcome),
            true_distance_mm,
        }
    }

    /// The value the sensor sends for an optical outcome (noise drawn when enabled).
    pub fn value_for(&mut self, outcome: &OpticalOutcome) -> IldValue {
        let OpticalOutcome::Distance {
            z_meas_mm,
            intensity,
        } = *outcome
        else {
            return IldValue::Error(IldError::NoPeak);
        };
        if self.intensity_limits {
            if intensity < self.config.intensity_dark_below {
                return IldValue::Error(IldError::NoPeak);
            }
            if intensity > self.config.intensity_saturated_above {
                return IldValue::Error(IldError::PeakTooWide);
            }
        }
        let noisy = z_meas_mm + self.noise.map_or(0.0, |n| n.sample(&mut self.rng));
        let range = self.config.range;
        let nearest = range.digital_to_mm(0).unwrap_or(range.start_mm);
        let farthest = range
            .digital_to_mm(DIGITAL_MAX)
            .unwrap_or(range.start_mm + range.span_mm);
        match range.mm_to_digital(noisy) {
            None => IldValue::Error(IldError::CannotEvaluate),
            Some(_) if noisy < nearest => IldValue::Error(IldError::PeakBeforeRange),
            Some(_) if noisy > farthest => IldValue::Error(IldError::PeakAfterRange),
            Some(digital) => IldValue::Distance(digital),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::ShadeReason;

    fn sensor(config: SensorConfig, noise: bool) -> Ild2300 {
        Ild2300::new(&config, 7, noise).unwrap()
    }

    fn distance(z_meas_mm: f64) -> OpticalOutcome {
        OpticalOutcome::Distance {
            z_meas_mm,
            intensity: 1.0,
        }
    }

    /// Samples over one second, asked period by period as the plant does at 20 kHz.
    fn samples_per_second(s: &Ild2300) -> u64 {
        let period = 1.0 / 20_000.0;
        (0..20_000u32)
            .map(|k| {
                s.sample_instants(f64::from(k) * period, f64::from(k + 1) * period)
                    .count() as u64
            })
            .sum()
    }

    #[test]
    fn clock_gives_the_rate_per_second_at_20_and_49_14_khz() {
        for rate in [20_000.0, 49_140.0, 1_500.0] {
            let s = sensor(
                SensorConfig {
                    measuring_rate_hz: rate,
                    ..SensorConfig::default()
                },
                false,
            );
            assert_eq!(samples_per_second(&s), rate as u64, "{rate}");
        }
        let fast = sensor(
            SensorConfig {
                clock_drift_ppm: 100.0,
                ..SensorConfig::default()
            },
            false,
        );
        assert_eq!(samples_per_second(&fast), 20_002);
    }

    #[test]
    fn instants_follow_the_offset_and_partition_periods() {
        let s = sensor(
            SensorConfig {
                measuring_rate_hz: 49_140.0,
                clock_offset_s: 1e-5,
                ..SensorConfig::default()
            },
            false,
        );
        let first: Vec<_> = s.sample_instants(0.0, 50e-6).collect();
        assert_eq!(first.len(), 2);
        assert_eq!(first[0].index, 0);
        assert!((first[0].t_s - 1e-5).abs() < 1e-15);
        assert!((first[1].t_s - (1e-5 + 1.0 / 49_140.0)).abs() < 1e-15);
        let next: Vec<_> = s.sample_instants(50e-6, 100e-6).collect();
        assert_eq!(next[0].index, 2);
        // Nothing before the sensor's clock starts.
        assert_eq!(s.sample_instants(-1.0, 0.0).count(), 0);
    }

    #[test]
    fn counter_is_18_bit_and_wraps() {
        let mut s = sensor(
            SensorConfig {
                counter_start: 262_142,
                ..SensorConfig::default()
            },
            false,
        );
        let counters: Vec<u32> = s
            .sample_instants(0.0, 3.5 / 20_000.0)
            .collect::<Vec<_>>()
            .into_iter()
            .map(|i| s.measure(i, &distance(100.0)).counter)
            .collect();
        assert_eq!(counters, vec![262_143, 0, 1]);
        assert!(
            Ild2300::new(
                &SensorConfig {
                    counter_start: 1 << 18,
                    ..SensorConfig::default()
                },
                0,
                false
            )
            .is_err()
        );
    }

    #[test]
    fn error_values_out_of_range_and_when_shaded() {
        let mut s = sensor(SensorConfig::default(), false);
        assert_eq!(
            s.value_for(&distance(60.0)),
            IldValue::Error(IldError::PeakBeforeRange)
        );
        assert_eq!(
            s.value_for(&distance(180.0)),
            IldValue::Error(IldError::PeakAfterRange)
        );
        assert_eq!(
            s.value_for(&OpticalOutcome::Miss),
            IldValue::Error(IldError::NoPeak)
        );
        assert_eq!(
            s.value_for(&OpticalOutcome::Shaded(ShadeReason::ReflectionPathBlocked)),
            IldValue::Error(IldError::NoPeak)
        );
        // In the reserves: still a distance, in the reserve codes.
        let IldValue::Distance(near) = s.value_for(&distance(69.5)) else {
            panic!("reserve")
        };
        assert!(near < scanhil_protocol::ild::value::DIGITAL_RANGE_START);
        let IldValue::Distance(far) = s.value_for(&distance(170.5)) else {
            panic!("reserve")
        };
        assert!(far > scanhil_protocol::ild::value::DIGITAL_RANGE_END);
        // In range: the nearest raw step.
        let IldValue::Distance(mid) = s.value_for(&distance(130.0)) else {
            panic!("range")
        };
        let back = MeasuringRange::ILD2300_100.digital_to_mm(mid).unwrap();
        assert!((back - 130.0).abs() <= 0.5 * MeasuringRange::ILD2300_100.mm_per_digit() + 1e-12);
    }

    #[test]
    fn the_receiver_refuses_a_spot_too_dark_or_saturated_only_with_its_limits() {
        let lit = |intensity| OpticalOutcome::Distance {
            z_meas_mm: 130.0,
            intensity,
        };
        let config = SensorConfig {
            intensity_dark_below: 0.01,
            intensity_saturated_above: 10.0,
            ..SensorConfig::default()
        };
        let mut limited = sensor(config, false).with_intensity_limits(true);
        assert_eq!(
            limited.value_for(&lit(0.009)),
            IldValue::Error(IldError::NoPeak)
        );
        assert_eq!(
            limited.value_for(&lit(10.5)),
            IldValue::Error(IldError::PeakTooWide)
        );
        let measured = limited.value_for(&lit(0.01));
        assert!(matches!(measured, IldValue::Distance(_)), "{measured:?}");
        assert_eq!(limited.value_for(&lit(10.0)), measured);
        // Without the part the intensity is not looked at.
        let mut unlimited = sensor(config, false);
        assert_eq!(unlimited.value_for(&lit(0.0)), measured);
        assert_eq!(unlimited.value_for(&lit(1e6)), measured);
    }

    #[test]
    fn receiver_fields_out_of_their_domain_are_refused() {
        for (config, field) in [
            (
                SensorConfig {
                    wavelength_nm: 0.0,
                    ..SensorConfig::default()
                },
                "wavelength_nm",
            ),
            (
                SensorConfig {
                    receiver_aperture_mm: f64::INFINITY,
                    ..SensorConfig::default()
                },
                "receiver_aperture_mm",
            ),
            (
                SensorConfig {
                    intensity_dark_below: -0.1,
                    ..SensorConfig::default()
                },
                "intensity_dark_below",
            ),
            (
                SensorConfig {
                    intensity_dark_below: 2.0,
                    intensity_saturated_above: 2.0,
                    ..SensorConfig::default()
                },
                "intensity_saturated_above",
            ),
        ] {
            assert_eq!(Ild2300::new(&config, 1, false).unwrap_err().field, field);
        }
    }

    #[test]
    fn noise_has_its_rms_and_is_seeded() {
        let range = MeasuringRange::ILD2300_100;
        let draw = |seed: u64| {
            let mut s = Ild2300::new(
                &SensorConfig {
                    noise_rms_um: 5.0,
                    ..SensorConfig::default()
                },
                seed,
                true,
            )
            .unwrap();
            (0..20_000)
                .map(|_| match s.value_for(&distance(120.0)) {
                    IldValue::Distance(d) => range.digital_to_mm(d).unwrap() - 120.0,
                    other => panic!("{other:?}"),
                })
                .collect::<Vec<f64>>()
        };
        let a = draw(1);
        let rms_um = (a.iter().map(|e| e * e).sum::<f64>() / a.len() as f64).sqrt() * 1e3;
        // 5 um noise plus the 1.557 um quantisation step (uniform: 0.45 um rms).
        assert!((rms_um - 5.02).abs() < 0.15, "{rms_um}");
        assert_eq!(a, draw(1));
        assert_ne!(a, draw(2));
    }

    #[test]
    fn an_exposure_looks_at_the_middles_of_its_slices_and_averages_what_it_sees() {
        let instant = sensor(SensorConfig::default(), false);
        assert_eq!(instant.exposure_instants(1.0).collect::<Vec<_>>(), [1.0]);
        let exposed = sensor(
            SensorConfig {
                exposure_us: 40.0,
                ..SensorConfig::default()
            },
            false,
        );
        assert!((exposed.exposure_s() - 40e-6).abs() < 1e-18);
        let instants: Vec<f64> = exposed.exposure_instants(1e-3).collect();
        let expected_us = [964.0, 972.0, 980.0, 988.0, 996.0];
        assert_eq!(instants.len(), EXPOSURE_POINTS);
        for (t_s, expected) in instants.iter().zip(expected_us) {
            assert!((t_s * 1e6 - expected).abs() < 1e-9, "{instants:?}");
        }
        let shaded = OpticalOutcome::Shaded(ShadeReason::ReflectionPathBlocked);
        assert_eq!(
            Ild2300::exposed([
                distance(100.0),
                shaded,
                distance(103.0),
                OpticalOutcome::Miss
            ]),
            OpticalOutcome::Distance {
                z_meas_mm: 101.5,
                intensity: 0.5
            }
        );
        // Each look weighs as much as the light it sends: 100 mm at 3, 104 mm at 1.
        let lit = |z_meas_mm, intensity| OpticalOutcome::Distance {
            z_meas_mm,
            intensity,
        };
        assert_eq!(
            Ild2300::exposed([lit(100.0, 3.0), lit(104.0, 1.0)]),
            lit(101.0, 2.0)
        );
        // Looks that send no light still place the spot.
        assert_eq!(
            Ild2300::exposed([lit(100.0, 0.0), lit(104.0, 0.0), shaded]),
            lit(102.0, 0.0)
        );
        assert_eq!(
            Ild2300::exposed([distance(100.0), distance(101.0), distance(105.0)]),
            distance(102.0)
        );
        assert_eq!(Ild2300::exposed([OpticalOutcome::Miss, shaded]), shaded);
        assert_eq!(Ild2300::exposed([]), OpticalOutcome::Miss);
    }

    #[test]
    fn an_exposure_longer_than_a_cycle_or_negative_is_refused() {
        for exposure_us in [-1.0, 50.5, f64::NAN] {
            let err = Ild2300::new(
                &SensorConfig {
                    exposure_us,
                    ..SensorConfig::default()
                },
                0,
                false,
            )
            .unwrap_err();
            assert_eq!(err.field, "exposure_us");
        }
        let whole_cycle = SensorConfig {
            exposure_us: 50.0,
            ..SensorConfig::default()
        };
        assert!(Ild2300::new(&whole_cycle, 0, false).is_ok());
        let c: SensorConfig = serde_json::from_str(r#"{"exposure_us": 20.0}"#).unwrap();
        assert_eq!(
            c,
            SensorConfig {
                exposure_us: 20.0,
                ..SensorConfig::default()
            }
        );
        // The receiver's defaults: 670 nm, 12 mm, limits 0.01 and 10.
        assert_eq!(
            (
                c.wavelength_nm,
                c.receiver_aperture_mm,
                c.intensity_dark_below,
                c.intensity_saturated_above
            ),
            (670.0, 12.0, 0.01, 10.0)
        );
    }

    #[test]
    fn bad_config_is_named() {
        let err = Ild2300::new(
            &SensorConfig {
                measuring_rate_hz: 12_345.0,
                ..SensorConfig::default()
            },
            0,
            false,
        )
        .unwrap_err();
        assert_eq!(err.field, "measuring_rate_hz");
        let c: SensorConfig = serde_json::from_str(r#"{"measuring_rate_hz": 49140.0}"#).unwrap();
        assert_eq!(c.noise_rms_um, 1.5);
        assert!(serde_json::from_str::<SensorConfig>(r#"{"rate": 1.0}"#).is_err());
    }
}
