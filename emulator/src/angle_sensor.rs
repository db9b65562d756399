//! The mirror's internal angle sensor: its bandwidth (part `angle_sensor_bandwidth`, a
//! first-order low-pass in the drive model), a small nonlinearity (part
//! `angle_sensor_nonlinearity`), and offset, white noise and quantisation (part
//! `angle_sensor_noise`) on each sensing axis. Without these parts the plant reports the true
//! angles exactly.
//!
//! `measured = step * round((nl(filtered) + offset + noise) / step)`, noise Gaussian with the
//! given rms, drawn from a ChaCha8 stream seeded by the scene seed, and
//! `nl(x) = x (1 + p/100 (x / x_fs)^2)`: an odd (S-shaped) error, as a position-sensing
//! detector has, of `p` % of full scale at full scale (`x_fs` = 1.5 deg mechanical).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use scanhil_protocol::plant_units::{OUTPUT_UNITS_AT_FULL_RANGE, RAD_PER_OUTPUT_UNIT, SensingPair};

/// The RNG stream of the angle sensor (each random part of the plant has its own stream).
pub const RNG_STREAM: u64 = 1;

/// The angle sensor's imperfections.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AngleSensorConfig {
    /// Quantisation step in urad (default 0.8 urad: 16 bits over +-1.5 deg); 0 = none.
    pub resolution_urad: f64,
    /// Rms of the white noise per sample, in urad.
    pub noise_rms_urad: f64,
    /// Constant offset added on each axis, in urad.
    pub offset_urad: SensingPair,
    /// The -3 dB bandwidth of the sensor's first-order response, in Hz (part
    /// `angle_sensor_bandwidth`; default 10 kHz).
    pub bandwidth_hz: f64,
    /// The nonlinearity at full scale, in % of full scale (part `angle_sensor_nonlinearity`;
    /// default 1 %).
    pub nonlinearity_percent: f64,
}

impl Default for AngleSensorConfig {
    fn default() -> Self {
        AngleSensorConfig {
            resolution_urad: 0.8,
            noise_rms_urad: 2.0,
            offset_urad: SensingPair::default(),
            bandwidth_hz: 10_000.0,
            nonlinearity_percent: 1.0,
        }
    }
}

impl AngleSensorConfig {
    /// Checks the parameters; on failure, the field name and why.
    pub fn validate(&self) -> Result<(), (String, String)> {
        for (name, v) in [
            ("resolution_urad", self.resolution_urad),
            ("noise_rms_urad", self.noise_rms_urad),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err((
                    format!("angle_sensor.{name}"),
                    format!("must be finite and >= 0, got {v}"),
                ));
            }
        }
        let o = self.offset_urad;
        if !(o.alpha.is_finite() && o.beta.is_finite()) {
            return Err(("angle_sensor.offset_urad".into(), "must be finite".into()));
        }
        if !(self.bandwidth_hz.is_finite() && self.bandwidth_hz > 0.0) {
            return Err((
                "angle_sensor.bandwidth_hz".into(),
                format!("must be finite and > 0, got {}", self.bandwidth_hz),
            ));
        }
        // Beyond 30 % the cubic is no longer monotonic-looking small error; 100 % would fold.
        if !(self.nonlinearity_percent.is_finite() && self.nonlinearity_percent.abs() <= 30.0) {
            return Err((
                "angle_sensor.nonlinearity_percent".into(),
                format!(
                    "must be finite and within +-30 (a small nonlinearity), got {}",
                    self.nonlinearity_percent
                ),
            ));
        }
        Ok(())
    }
}

/// The angle sensor's static nonlinearity: `x (1 + p/100 (x / x_fs)^2)` on each axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nonlinearity {
    /// `p / 100 / x_fs^2`, per rad^2.
    cubic_per_rad2: f64,
}

impl Nonlinearity {
    /// The nonlinearity of `percent` % at full scale (1.5 deg mechanical).
    #[must_use]
    pub fn new(percent: f64) -> Nonlinearity {
        let full_scale_rad = OUTPUT_UNITS_AT_FULL_RANGE * RAD_PER_OUTPUT_UNIT;
        Nonlinearity {
            cubic_per_rad2: percent / 100.0 / (full_scale_rad * full_scale_rad),
        }
    }

    /// What the sensor reports for the angles `rad`.
    #[must_use]
    pub fn apply(&self, rad: SensingPair) -> SensingPair {
        let one = |x: f64| x * (1.0 + self.cubic_per_rad2 * x * x);
        SensingPair {
            alpha: one(rad.alpha),
            beta: one(rad.beta),
        }
    }
}

/// A running angle sensor.
#[derive(Debug, Clone)]
pub struct AngleSensor {
    step_rad: f64,
    offset_rad: SensingPair,
    noise: Normal<f64>,
    rng: ChaCha8Rng,
}

impl AngleSensor {
    /// A sensor with its own RNG stream derived from `seed`.
    #[must_use]
    pub fn new(config: &AngleSensorConfig, seed: u64) -> AngleSensor {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(RNG_STREAM);
        AngleSensor {
            step_rad: config.resolution_urad * 1e-6,
            offset_rad: SensingPair {
                alpha: config.offset_urad.alpha * 1e-6,
                beta: config.offset_urad.beta * 1e-6,
            },
            // validate() keeps the rms finite and >= 0, which Normal accepts.
            noise: Normal::new(0.0, config.noise_rms_urad * 1e-6)
                .unwrap_or_else(|_| Normal::new(0.0, 0.0).expect("zero rms is valid")),
            rng,
        }
    }

    /// One reading of the true angles.
    pub fn measure(&mut self, true_rad: SensingPair) -> SensingPair {
        SensingPair {
            alpha: self.one(true_rad.alpha + self.offset_rad.alpha),
            beta: self.one(true_rad.beta + self.offset_rad.beta),
        }
    }

    fn one(&mut self, value_rad: f64) -> f64 {
        let noisy = value_rad + self.noise.sample(&mut self.rng);
        if self.step_rad > 0.0 {
            (noisy / self.step_rad).round() * self.step_rad
        } else {
            noisy
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantises_offsets_and_adds_noise_of_the_given_rms() {
        let config = AngleSensorConfig {
            resolution_urad: 1.0,
            noise_rms_urad: 5.0,
            offset_urad: SensingPair {
                alpha: 10.0,
                beta: -20.0,
            },
            ..AngleSensorConfig::default()
        };
        let mut sensor = AngleSensor::new(&config, 3);
        let n = 20_000;
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..n {
            let m = sensor.measure(SensingPair::default());
            let steps = m.alpha / 1e-6;
            assert!(
                (steps - steps.round()).abs() < 1e-6,
                "not quantised: {}",
                m.alpha
            );
            sum += m.beta;
            sum2 += (m.beta + 20e-6).powi(2);
        }
        let mean_urad = sum / f64::from(n) * 1e6;
        let rms_urad = (sum2 / f64::from(n)).sqrt() * 1e6;
        assert!((mean_urad + 20.0).abs() < 0.2, "{mean_urad}");
        assert!((rms_urad - 5.0).abs() < 0.2, "{rms_urad}");
    }

    #[test]
    fn the_nonlinearity_is_its_percentage_at_full_scale_and_odd() {
        let nl = Nonlinearity::new(1.0);
        let fs = OUTPUT_UNITS_AT_FULL_RANGE * RAD_PER_OUTPUT_UNIT;
        let out = nl.apply(SensingPair {
            alpha: fs,
            beta: -0.5 * fs,
        });
        assert!((out.alpha / fs - 1.01).abs() < 1e-12, "{}", out.alpha);
        assert!((out.beta / fs + 0.5 * (1.0 + 0.01 * 0.25)).abs() < 1e-12);
        assert_eq!(nl.apply(SensingPair::default()), SensingPair::default());
    }

    #[test]
    fn same_seed_same_readings() {
        let config = AngleSensorConfig::default();
        let mut a = AngleSensor::new(&config, 9);
        let mut b = AngleSensor::new(&config, 9);
        for _ in 0..10 {
            let t = SensingPair {
                alpha: 1e-3,
                beta: -2e-3,
            };
            assert_eq!(a.measure(t), b.measure(t));
        }
    }
}
