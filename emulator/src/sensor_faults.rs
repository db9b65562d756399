//! The sensor losing its peak, as declared in a scenario's `faults.sensor`
//! ([`SensorFaults`]): the emulated ILD sends the error value a real one sends in place of the
//! distance. Laser off sends `laser_off`, a target beyond the range `peak_after_range`, a burst
//! of occlusion `no_peak`; where windows overlap the first in that order wins. Pure and seeded:
//! the same seed shades the same samples.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use scanhil_protocol::fault_injection::SensorFaults;
use scanhil_protocol::ild::{IldError, IldValue};

use crate::sensor::IldSample;

/// The generator stream of the occlusion bursts (apart from the plant's noise streams).
const OCCLUSION_STREAM: u64 = 0x0cc1;

/// How many samples each sensor fault replaced.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct SensorFaultCounts {
    /// Samples sent as `laser_off`.
    pub laser_off: u64,
    /// Samples sent as `peak_after_range`.
    pub out_of_range: u64,
    /// Samples sent as `no_peak` inside an occlusion burst.
    pub occluded: u64,
    /// Occlusion bursts started.
    pub occlusion_bursts: u64,
}

/// The declared sensor faults applied to the emulated sensor's samples.
#[derive(Debug, Clone)]
pub struct SensorFaultModel {
    faults: SensorFaults,
    rng: ChaCha8Rng,
    /// A burst's start probability per sample.
    burst_probability: f64,
    occluded_until_s: f64,
    counts: SensorFaultCounts,
}

impl SensorFaultModel {
    /// The model of `faults` (checked) for a sensor sampling at `measuring_rate_hz`, seeded
    /// with `seed`.
    #[must_use]
    pub fn new(faults: SensorFaults, seed: u64, measuring_rate_hz: f64) -> SensorFaultModel {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(OCCLUSION_STREAM);
        let burst_probability = faults.occlusion.map_or(0.0, |bursts| {
            (bursts.bursts_per_s / measuring_rate_hz).min(1.0)
        });
        SensorFaultModel {
            faults,
            rng,
            burst_probability,
            occluded_until_s: f64::NEG_INFINITY,
            counts: SensorFaultCounts::default(),
        }
    }

    /// Replaces the sample's value with the error its fault gives, if one is active at its
    /// time.
    pub fn apply(&mut self, sample: &mut IldSample) {
        let t_s = sample.t_s;
        if let Some(bursts) = self.faults.occlusion
            && t_s >= self.occluded_until_s
            && self.rng.random::<f64>() < self.burst_probability
        {
            self.occluded_until_s = t_s + bursts.burst_s;
            self.counts.occlusion_bursts += 1;
        }
        let error = if self.faults.laser_off.iter().any(|w| w.contains(t_s)) {
            self.counts.laser_off += 1;
            IldError::LaserOff
        } else if self.faults.out_of_range.iter().any(|w| w.contains(t_s)) {
            self.counts.out_of_range += 1;
            IldError::PeakAfterRange
        } else if t_s < self.occluded_until_s {
            self.counts.occluded += 1;
            IldError::NoPeak
        } else {
            return;
        };
        sample.value = IldValue::Error(error);
        sample.true_distance_mm = None;
    }

    /// How many samples each fault replaced so far.
    #[must_use]
    pub fn counts(&self) -> SensorFaultCounts {
        self.counts
    }
}

#[cfg(test)]
mod tests {
    use scanhil_protocol::fault_injection::{OcclusionBursts, TimeWindow};

    use super::*;

    fn samples(rate_hz: f64, n: u32) -> Vec<IldSample> {
        (0..n)
            .map(|counter| IldSample {
                t_s: f64::from(counter) / rate_hz,
                counter,
                value: IldValue::Distance(1000),
                true_distance_mm: Some(120.0),
            })
            .collect()
    }

    #[test]
    fn windows_and_bursts_send_the_ild_error_values() {
        let faults = SensorFaults {
            laser_off: vec![TimeWindow {
                from_s: 0.1,
                to_s: 0.2,
            }],
            out_of_range: vec![TimeWindow {
                from_s: 0.15,
                to_s: 0.3,
            }],
            occlusion: Some(OcclusionBursts {
                bursts_per_s: 20.0,
                burst_s: 0.005,
            }),
        };
        faults.check().unwrap();
        let mut model = SensorFaultModel::new(faults, 7, 10_000.0);
        let mut all = samples(10_000.0, 10_000);
        for sample in &mut all {
            model.apply(sample);
        }
        let value_at = |t_s: f64| all[(t_s * 10_000.0).round() as usize].value;
        assert_eq!(value_at(0.12), IldValue::Error(IldError::LaserOff));
        assert_eq!(value_at(0.25), IldValue::Error(IldError::PeakAfterRange));
        let counts = model.counts();
        assert_eq!(counts.laser_off, 1000);
        assert_eq!(counts.out_of_range, 1000);
        // About 20 bursts of 50 samples in the 0.8 s outside the windows.
        assert!((8..40).contains(&counts.occlusion_bursts), "{counts:?}");
        let no_peak = all
            .iter()
            .filter(|s| s.value == IldValue::Error(IldError::NoPeak))
            .count() as u64;
        assert_eq!(no_peak, counts.occluded);
        assert!(no_peak >= counts.occlusion_bursts * 25, "{counts:?}");
        assert!(
            all.iter().filter(|s| s.true_distance_mm.is_none()).count() as u64
                == counts.laser_off + counts.out_of_range + counts.occluded
        );
    }
}
