#![warn(missing_docs)]
//! Shared truths of the scanner's world, used by both programs: the surfaces that stand in
//! front of the scanner (the emulator traces its optics against them; the host scores its
//! reconstruction against them) and the true surface a scene file describes.
//!
//! The host needs no emulator to use this crate: a bench technician who knows the object on
//! the bench (a calibration plane, a Duplo brick) describes it in a scene file's `surface`
//! section and gets the error figures of a real scan against it.
//!
//! # Layout
//! - [`surface`]: plane, tilted plane, step, sphere, height maps, the Duplo brick; ray
//!   intersection and the true height at any (x, y).
//! - [`truth`]: a scene file's true surface, read without the emulator's plant sections.
//! - [`json_file`]: reading and parsing JSON files, errors naming file, line and column (the
//!   host's files use it too).

pub mod json_file;
pub mod surface;
pub mod truth;
