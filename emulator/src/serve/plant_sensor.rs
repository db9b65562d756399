//! The sensor as the serve loop sees it: the samples a plant step produced and the sensor's
//! measuring rate. (Adapter: the plant does not carry the optics and sensor yet, so a step has
//! no samples; this is the one place to change when it does.)

use scanhil_protocol::ild::IldValue;

use crate::plant::PlantStep;
use crate::scene::Scene;

/// The ILD 2300's default measuring rate, Hz.
const DEFAULT_MEASURING_RATE_HZ: f64 = 20_000.0;

/// One sensor sample: when it was measured (loop time) and what the sensor output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorSample {
    /// Loop time of the measurement, s.
    pub t_s: f64,
    /// The raw value (distance or error).
    pub value: IldValue,
}

/// The samples whose instants fell in the stepped period.
#[must_use]
pub fn samples(_step: &PlantStep) -> Vec<SensorSample> {
    Vec::new()
}

/// The scene's sensor measuring rate, Hz.
#[must_use]
pub fn measuring_rate_hz(scene: &Scene) -> f64 {
    scene
        .sensor
        .as_ref()
        .and_then(|sensor| sensor["measuring_rate_hz"].as_f64())
        .unwrap_or(DEFAULT_MEASURING_RATE_HZ)
}
