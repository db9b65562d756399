//! What the conformance drive does to the mirror: the coil currents of each period (a sine on
//! each coil), and the verdict on the angles it moves (in range, and both axes swinging).

use scanhil_protocol::plant_units::{ActuatorPair, SensingPair};

use crate::run::host_inbox::{plausible_angle_limit_rad, plausible_angles};
/// The least peak-to-peak swing each axis must show under [`EXCITATION`], rad.
const MIN_SWING_RAD: f64 = 1e-3;

/// The drive during the timing and range checks: a sine on each coil.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Excitation {
    /// Amplitude of both sines, A.
    pub amplitude_a: f64,
    /// Frequency of coil A's sine, Hz.
    pub a_hz: f64,
    /// Frequency of coil B's sine, Hz (different from A's, so both axes move).
    pub b_hz: f64,
}

/// The conformance drive: well below the current and power limits, away from the mirror's
/// resonance, both sines starting at zero.
pub const EXCITATION: Excitation = Excitation {
    amplitude_a: 0.3,
    a_hz: 40.0,
    b_hz: 80.0,
};

/// The drive in real time: [`EXCITATION`] at a third of its amplitude. A node on its own
/// clock holds its last command through a stall of the host and takes the drive's value again
/// after it: each such jump of up to twice the amplitude rings the lightly damped mirror, and
/// at 0.3 A a few of them on a loaded host swing it past its range. At 0.1 A both axes still
/// swing several mrad.
pub const REALTIME_EXCITATION: Excitation = Excitation {
    amplitude_a: 0.1,
    ..EXCITATION
};

impl Excitation {
    /// The coil currents of period `k` at a period of `period_s`.
    #[must_use]
    pub fn at(&self, k: u64, period_s: f64) -> ActuatorPair {
        let t_s = k as f64 * period_s;
        let sine = |hz: f64| self.amplitude_a * (std::f64::consts::TAU * hz * t_s).sin();
        ActuatorPair {
            a: sine(self.a_hz),
            b: sine(self.b_hz),
        }
    }
}

impl std::fmt::Display for Excitation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} A sines at {} Hz (coil A) and {} Hz (coil B)",
            self.amplitude_a, self.a_hz, self.b_hz
        )
    }
}

/// The angles the timing check saw: the first out of the mirror's range, and each axis's
/// extremes (the drive must move both).
#[derive(Debug)]
pub(super) struct AngleRange {
    excitation: Excitation,
    out_of_range: Option<String>,
    min_rad: SensingPair,
    max_rad: SensingPair,
}

impl AngleRange {
    /// Nothing seen yet under `excitation`.
    pub(super) fn new(excitation: Excitation) -> Self {
        AngleRange {
            excitation,
            out_of_range: None,
            min_rad: SensingPair {
                alpha: f64::INFINITY,
                beta: f64::INFINITY,
            },
            max_rad: SensingPair {
                alpha: f64::NEG_INFINITY,
                beta: f64::NEG_INFINITY,
            },
        }
    }

    /// Reading `k`: out of range when not finite or beyond the mirror's range with margin
    /// (the host's own plausibility bound, [`plausible_angles`]).
    pub(super) fn add(&mut self, k: u64, angles: SensingPair) {
        if self.out_of_range.is_none() && !plausible_angles(angles) {
            self.out_of_range = Some(format!(
                "period {k}: alpha {:.3} mrad, beta {:.3} mrad, beyond the mirror's +-{:.3} mrad",
                angles.alpha * 1e3,
                angles.beta * 1e3,
                plausible_angle_limit_rad() * 1e3
            ));
        }
        self.min_rad.alpha = self.min_rad.alpha.min(angles.alpha);
        self.min_rad.beta = self.min_rad.beta.min(angles.beta);
        self.max_rad.alpha = self.max_rad.alpha.max(angles.alpha);
        self.max_rad.beta = self.max_rad.beta.max(angles.beta);
    }

    /// `Ok` (what was seen) when every reading was in range and both axes swung by at least
    /// [`MIN_SWING_RAD`] over `readings` readings; `Err` says what was expected and seen.
    pub(super) fn verdict(&self, readings: u64) -> Result<String, String> {
        if let Some(out) = &self.out_of_range {
            return Err(out.clone());
        }
        if readings == 0 {
            return Err("no angle reading to check".to_owned());
        }
        let alpha = self.max_rad.alpha - self.min_rad.alpha;
        let beta = self.max_rad.beta - self.min_rad.beta;
        let swing = format!(
            "alpha swung {:.3} mrad, beta {:.3} mrad peak to peak under {}",
            alpha * 1e3,
            beta * 1e3,
            self.excitation
        );
        if alpha < MIN_SWING_RAD || beta < MIN_SWING_RAD {
            return Err(format!(
                "{swing}: at least {:.3} mrad each expected (frozen or unresponsive angles)",
                MIN_SWING_RAD * 1e3
            ));
        }
        Ok(format!(
            "all within +-{:.3} mrad; {swing}",
            plausible_angle_limit_rad() * 1e3
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PERIOD_S: f64 = 5e-5;

    #[test]
    fn the_drive_starts_at_zero_and_stays_within_its_amplitude() {
        assert_eq!(EXCITATION.at(0, PERIOD_S), ActuatorPair::default());
        let peak = (0..2_500)
            .map(|k| EXCITATION.at(k, PERIOD_S))
            .map(|c| c.a.abs().max(c.b.abs()))
            .fold(0.0, f64::max);
        assert!(peak <= EXCITATION.amplitude_a && peak > 0.99 * EXCITATION.amplitude_a);
    }

    fn verdict(angles: impl Fn(u64) -> SensingPair) -> Result<String, String> {
        let mut range = AngleRange::new(EXCITATION);
        for k in 0..100 {
            range.add(k, angles(k));
        }
        range.verdict(100)
    }

    #[test]
    fn angles_pass_only_in_range_and_moving_on_both_axes() {
        let swing = |k: u64| (k as f64 * 0.1).sin() * 5e-3;
        let moving = verdict(|k| SensingPair {
            alpha: swing(k),
            beta: -swing(k),
        });
        assert!(moving.is_ok_and(|seen| seen.contains("alpha swung")));
        let frozen = verdict(|_| SensingPair {
            alpha: 1e-3,
            beta: 1e-3,
        });
        assert!(frozen.is_err_and(|why| why.contains("alpha swung 0.000 mrad, beta 0.000 mrad")));
        let one_axis = verdict(|k| SensingPair {
            alpha: swing(k),
            beta: 0.0,
        });
        assert!(one_axis.is_err_and(|why| why.contains("beta 0.000 mrad")));
        let alpha_frozen = verdict(|k| SensingPair {
            alpha: 0.0,
            beta: swing(k),
        });
        assert!(alpha_frozen.is_err_and(|why| why.contains("alpha swung 0.000 mrad")));
        // A swing of exactly the least one passes.
        let least = verdict(|k| SensingPair {
            alpha: if k == 0 { MIN_SWING_RAD } else { 0.0 },
            beta: if k == 1 { MIN_SWING_RAD } else { 0.0 },
        });
        assert!(least.is_ok(), "{least:?}");
        let beyond = verdict(|k| SensingPair {
            alpha: if k == 42 { 0.05 } else { swing(k) },
            beta: swing(k),
        });
        assert!(beyond.is_err_and(|why| why.starts_with("period 42: alpha 50.000 mrad")));
        let not_finite = verdict(|k| SensingPair {
            alpha: swing(k),
            beta: if k == 7 { f64::NAN } else { swing(k) },
        });
        assert!(not_finite.is_err_and(|why| why.starts_with("period 7:")));
    }

    #[test]
    fn the_real_time_drive_is_a_third_of_lockstep_at_the_same_frequencies() {
        assert_eq!(REALTIME_EXCITATION.amplitude_a, 0.1);
        assert_eq!(
            (REALTIME_EXCITATION.a_hz, REALTIME_EXCITATION.b_hz),
            (EXCITATION.a_hz, EXCITATION.b_hz)
        );
        assert_eq!(
            REALTIME_EXCITATION.to_string(),
            "0.1 A sines at 40 Hz (coil A) and 80 Hz (coil B)"
        );
    }
}
