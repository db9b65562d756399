//! The plant emulator: fast steering mirror, coil drive, optics, ILD 2300 sensor, scenes.
//!
//! # Layout (being written)
//! - [`surface`]: what is in front of the sensor, and its ground truth.
//! - [`optics`]: from mirror angles to the laser spot on the surface, with shading.
//! - [`sensor`]: the ILD 2300-100 triangulation sensor on its own clock.

pub mod optics;
pub mod sensor;
pub mod surface;
