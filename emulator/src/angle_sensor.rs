//! The mirror's internal angle sensor: offset, white noise and quantisation on each sensing
//! axis. Without the `angle_sensor_noise` part the plant reports the true angles exactly.
//!
//! `measured = step * round((true + offset + noise) / step)`, noise Gaussian with the given
//! rms, drawn from a ChaCha8 stream seeded by the scene seed.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use scanhil_protocol::plant_units::SensingPair;

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
}

impl Default for AngleSensorConfig {
    fn default() -> Self {
        AngleSensorConfig {
            resolution_urad: 0.8,
            noise_rms_urad: 2.0,
            offset_urad: SensingPair::default(),
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
        Ok(())
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
