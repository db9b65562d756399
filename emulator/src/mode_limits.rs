//! The ranges a mechanical mode's parameters may take, for the mirror's first mode and its
//! second: generous beside any voice-coil mirror, and small enough that the exact
//! discretisation's matrix exponential of the plant finishes (a natural frequency of 1e40
//! rad/s once kept `scanhil-emulator step` spinning).

/// The highest natural frequency a mode may have, rad/s (16 MHz: four orders of magnitude
/// above any voice-coil mirror's).
pub const MAX_NATURAL_FREQ_RAD_S: f64 = 1e8;

/// The highest damping ratio a mode may have (its fast pole is then `2 zeta ws`).
pub const MAX_DAMPING_RATIO: f64 = 1e3;

/// The largest DC gain an axis may have, output units per input unit (the paper's is 11.4).
pub const MAX_DC_GAIN: f64 = 1e6;
