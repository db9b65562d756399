//! The plant emulator: fast steering mirror, coil drive, optics, ILD 2300 sensor, scenes.
//!
//! # Layout (being written)
//! - [`surface`]: what is in front of the sensor, and its ground truth.
//! - [`optics`]: from mirror angles to the laser spot on the surface, with shading.
//! - [`sensor`]: the ILD 2300-100 triangulation sensor on its own clock.
//! - [`mirror`]: eq. 4 per sensing axis.
//! - [`amplifier`], [`cross_talk`], [`power`], [`angle_sensor`]: the drive and the angle
//!   sensor.
//! - [`drive_model`]: the composed linear dynamics of the active parts.
//! - [`integrator`]: exact ZOH, RK4, trapezoid, Euler, and the stability check.

pub mod amplifier;
pub mod angle_sensor;
pub mod cross_talk;
pub mod drive_model;
pub mod integrator;
pub mod mirror;
pub mod optics;
pub mod power;
pub mod sensor;
pub mod surface;
