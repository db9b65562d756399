#![warn(missing_docs)]
//! The laboratory: the host's and the emulator's libraries linked into one process. The
//! `scanhil` binary never links the emulator (a technician's host stands alone); this crate
//! does, for what needs both sides at once without processes or links in between.
//!
//! # Layout
//! - [`emulated_imaging`]: ideal-tracking scans through the emulator's optics and sensor model
//!   (scene files), imaged by the host's pipeline.

pub mod emulated_imaging;
