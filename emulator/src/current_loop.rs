//! The amplifier's inner current loop (part `current_loop`): the OPA544 stage as the paper's
//! Fig. 7 draws it, an analog current controller `C_I(s)` driving the coil through the power
//! op-amp `A(s)`, with the coil's resistance and inductance, the back-EMF of the moving
//! magnets and the supply's voltage limit.
//!
//! Per actuator axis (coil pair), with the command `c` and the coil current `i`:
//!
//! ```text
//! e = c - i,   v = kp e + q,   dq/dt = kp wi e            (PI controller, q its integral, V)
//! L di/dt = sat(v) - R i - e_emf                           (coil; sat: +-v_max)
//! ```
//!
//! `A(s)` is unity: the OPA544's 1.4 MHz gain-bandwidth puts its pole two decades above the
//! loop. The controller is the textbook design for the paper's stated 10 kHz
//! (`amplifier.bandwidth_hz`): `kp = 2 pi 10 kHz L` and the PI zero on the coil's pole,
//! `wi = R / L`, so unsaturated and without back-EMF the loop is exactly first order at
//! `kp / L`; the bandwidth then follows from the loop, and moves when `proportional_v_per_a`
//! or `integral_corner_hz` are set apart from the design or when the back-EMF acts. Over
//! `v_max = supply_v - headroom_v` the op-amp saturates: the voltage is held at the rail and
//! the PI integral stops (clamping anti-windup), so a large step is slew-limited at
//! `di/dt = (v_max - R i) / L` long before the current limit is reached.
//!
//! The back-EMF of coil `k` is `sum over axes of k_t coupling[axis][k] omega_axis` (the
//! transpose of the path its current takes to the torques, so the coils absorb exactly the
//! mechanical power): `k_t = J ws^2 K RAD_PER_OUTPUT_UNIT` N m per input unit, `J` the
//! mirror's moment of inertia, `omega` the first mode's angular rate.

use serde::{Deserialize, Serialize};

/// The current loop's parameters (both coil pairs alike).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CurrentLoopConfig {
    /// Coil resistance per actuator axis (sense resistor included), in ohm; absent: the
    /// resistance the power limit uses (derived from the paper's 30 W at 52 Hz).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coil_resistance_ohm: Option<f64>,
    /// Coil inductance per actuator axis, in H.
    pub coil_inductance_h: f64,
    /// The controller's proportional gain, in V/A; absent: `2 pi amplifier.bandwidth_hz L`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub proportional_v_per_a: Option<f64>,
    /// The PI zero, in Hz; absent: `R / (2 pi L)` (on the coil's pole).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub integral_corner_hz: Option<f64>,
    /// The supply rails, +-V.
    pub supply_v: f64,
    /// How far below each rail the output saturates at the currents in use, in V.
    pub headroom_v: f64,
    /// The mirror's moment of inertia about each tilt axis, in kg m^2 (the back-EMF scales
    /// with it); 0 leaves the back-EMF out.
    pub inertia_kg_m2: f64,
}

impl Default for CurrentLoopConfig {
    /// The values of `docs/bench-scene.md`: a 1 mH coil, a +-24 V supply with 5 V headroom,
    /// 2e-5 kg m^2.
    fn default() -> Self {
        CurrentLoopConfig {
            coil_resistance_ohm: None,
            coil_inductance_h: 1.0e-3,
            proportional_v_per_a: None,
            integral_corner_hz: None,
            supply_v: 24.0,
            headroom_v: 5.0,
            inertia_kg_m2: 2.0e-5,
        }
    }
}

impl CurrentLoopConfig {
    /// Checks the parameters; on failure, the field name and why.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let field = |name: &str| format!("current_loop.{name}");
        for (name, value) in [
            ("coil_resistance_ohm", self.coil_resistance_ohm),
            ("coil_inductance_h", Some(self.coil_inductance_h)),
            ("proportional_v_per_a", self.proportional_v_per_a),
            ("integral_corner_hz", self.integral_corner_hz),
            ("supply_v", Some(self.supply_v)),
        ] {
            if let Some(v) = value
                && !(v.is_finite() && v > 0.0)
            {
                return Err((field(name), format!("must be finite and > 0, got {v}")));
            }
        }
        if !(self.headroom_v.is_finite()
            && self.headroom_v >= 0.0
            && self.headroom_v < self.supply_v)
        {
            return Err((
                field("headroom_v"),
                format!(
                    "must be finite, >= 0 and below supply_v ({}), got {}",
                    self.supply_v, self.headroom_v
                ),
            ));
        }
        if !(self.inertia_kg_m2.is_finite() && self.inertia_kg_m2 >= 0.0) {
            return Err((
                field("inertia_kg_m2"),
                format!("must be finite and >= 0, got {}", self.inertia_kg_m2),
            ));
        }
        Ok(())
    }

    /// The loop's values for a designed bandwidth of `bandwidth_hz` and a coil resistance
    /// `default_resistance_ohm` (used when the scene leaves `coil_resistance_ohm` out).
    #[must_use]
    pub fn resolve(&self, bandwidth_hz: f64, default_resistance_ohm: f64) -> CurrentLoop {
        let r = self.coil_resistance_ohm.unwrap_or(default_resistance_ohm);
        let l = self.coil_inductance_h;
        let kp = self
            .proportional_v_per_a
            .unwrap_or(std::f64::consts::TAU * bandwidth_hz * l);
        let wi = self
            .integral_corner_hz
            .map_or(r / l, |hz| std::f64::consts::TAU * hz);
        CurrentLoop {
            resistance_ohm: r,
            inductance_h: l,
            kp_v_per_a: kp,
            ki_v_per_a_s: kp * wi,
            max_voltage_v: self.supply_v - self.headroom_v,
            inertia_kg_m2: self.inertia_kg_m2,
        }
    }
}

/// The current loop's resolved values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CurrentLoop {
    /// R, in ohm.
    pub resistance_ohm: f64,
    /// L, in H.
    pub inductance_h: f64,
    /// The PI's proportional gain, V/A.
    pub kp_v_per_a: f64,
    /// The PI's integral gain `kp wi`, V/(A s).
    pub ki_v_per_a_s: f64,
    /// The largest output voltage magnitude, in V.
    pub max_voltage_v: f64,
    /// J, in kg m^2.
    pub inertia_kg_m2: f64,
}

impl CurrentLoop {
    /// The closed loop's current response `i / c` at `omega` as (re, im), unsaturated and
    /// without back-EMF: `(kp s + ki) / (L s^2 + (R + kp) s + ki)`.
    #[must_use]
    pub fn response_at(&self, omega_rad_s: f64) -> (f64, f64) {
        let (l, r, kp, ki) = (
            self.inductance_h,
            self.resistance_ohm,
            self.kp_v_per_a,
            self.ki_v_per_a_s,
        );
        let num = (ki, kp * omega_rad_s);
        let den = (ki - l * omega_rad_s * omega_rad_s, (r + kp) * omega_rad_s);
        let d2 = den.0 * den.0 + den.1 * den.1;
        (
            (num.0 * den.0 + num.1 * den.1) / d2,
            (num.1 * den.0 - num.0 * den.1) / d2,
        )
    }

    /// The voltage the controller asks for with command `command_a`, current `current_a` and
    /// integral `integral_v`, in V.
    #[must_use]
    pub fn demand_v(&self, command_a: f64, current_a: f64, integral_v: f64) -> f64 {
        self.kp_v_per_a * (command_a - current_a) + integral_v
    }
}
