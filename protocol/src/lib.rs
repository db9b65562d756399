#![forbid(unsafe_code)]
//! scanhil wire format, shared by the emulator and the controller.
//!
//! # Layout
//! - [`plant_units`]: the mirror node's device contract: units, scalings, axis rotation.

pub mod plant_units;
