//! The link to a plant, one control period per exchange, and the in-process nominal plant
//! behind it (eq. 4 on both axes, the 45 degree rotation, optional seeded sensor noise).
//! The loop work implements [`PlantLink`] over CAN/SLCAN (emulator process or real mirror).

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use scanhil_protocol::plant_units::{
    AMPS_PER_INPUT_UNIT, ActuatorPair, RAD_PER_OUTPUT_UNIT, SensingPair, sensing_from_actuator,
};

use crate::plant_model::PlantModel;
use crate::sos::Cascade;

/// Why an exchange with the plant failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("plant link: {message}")]
pub struct LinkError {
    /// What failed, and where.
    pub message: String,
}

/// How a run left the mirror's coils: the zero command the host sent at its end (after the
/// last period, or on the way out of an early stop), and whether the node acknowledged it
/// (its Status(ready) answering the controller's, which it sends after it took the zero
/// command: the zero is in force). An early stop commands zero best effort and awaits no
/// answer: the link may be gone, and the node's own watchdog zeroes the coils then.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct CoilsAtEnd {
    /// The host sent CoilCommand(0) at the end.
    pub zero_commanded: bool,
    /// The node answered the end of the run after taking it.
    pub acknowledged: bool,
}

/// One control period with a plant.
pub trait PlantLink {
    /// Delivers the coil command of this period (A, actuator axes) and returns the mirror
    /// angles sampled at the end of the period (rad, sensing axes). The command acts over the
    /// next period (the emulator's timing convention).
    fn exchange(&mut self, coil_currents_a: ActuatorPair) -> Result<SensingPair, LinkError>;

    /// The control period, s.
    fn period_s(&self) -> f64;

    /// Ends the session with the coils commanded to zero, and says how that went (`None`: a
    /// plant with no node to leave driven, such as the nominal model in process).
    fn end(&mut self) -> Option<CoilsAtEnd> {
        None
    }
}

/// The nominal model as a plant: `ZOH(eq. 4)` per sensing axis with the command acting one
/// period late (plus the model's extra delay), and optional white Gaussian angle noise (seeded).
#[derive(Debug, Clone)]
pub struct NominalPlantLink {
    axes: [Cascade; 2],
    period_s: f64,
    noise_rms_rad: f64,
    rng: ChaCha8Rng,
}

impl NominalPlantLink {
    /// The plant `model` at `period_s`, with angle noise of `noise_rms_rad` drawn from `seed`.
    #[must_use]
    pub fn new(model: &PlantModel, period_s: f64, noise_rms_rad: f64, seed: u64) -> Self {
        Self {
            axes: [model.sampled(period_s), model.sampled(period_s)],
            period_s,
            noise_rms_rad,
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// A standard normal sample (Box-Muller).
    fn gaussian(&mut self) -> f64 {
        let u1: f64 = 1.0 - self.rng.random::<f64>();
        let u2: f64 = self.rng.random::<f64>();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

impl PlantLink for NominalPlantLink {
    fn exchange(&mut self, coil_currents_a: ActuatorPair) -> Result<SensingPair, LinkError> {
        if !(coil_currents_a.a.is_finite() && coil_currents_a.b.is_finite()) {
            return Err(LinkError {
                message: format!("non-finite coil command {coil_currents_a:?}"),
            });
        }
        let input = sensing_from_actuator(coil_currents_a);
        let alpha = self.axes[0].step(input.alpha / AMPS_PER_INPUT_UNIT);
        let beta = self.axes[1].step(input.beta / AMPS_PER_INPUT_UNIT);
        let mut out = SensingPair {
            alpha: alpha * RAD_PER_OUTPUT_UNIT,
            beta: beta * RAD_PER_OUTPUT_UNIT,
        };
        if self.noise_rms_rad > 0.0 {
            out.alpha += self.noise_rms_rad * self.gaussian();
            out.beta += self.noise_rms_rad * self.gaussian();
        }
        Ok(out)
    }

    fn period_s(&self) -> f64 {
        self.period_s
    }
}
