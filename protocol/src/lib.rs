#![forbid(unsafe_code)]
//! scanhil wire format, shared by the emulator and the controller.
//!
//! # Layout
//! - [`plant_units`]: the mirror node's device contract: units, scalings, axis rotation.
//! - [`ild`]: the ILD 2300 sensor's RS422 values and (to come) its byte stream and commands.

pub mod ild;
pub mod plant_units;
