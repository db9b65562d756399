#![warn(missing_docs)]
//! The scanhil lab: the host's and the emulator's libraries linked into one process. The
//! `scanhil` binary never links the emulator (a technician's host stands alone); this crate
//! does, for what needs both sides at once without processes or links in between.
//!
//! The host's lockstep state machine ([`scanhil_controller::run::host_loop`]) and the mirror
//! node's ([`scanhil_emulator::serve::lockstep_node`]) exchange frames over an in-memory
//! transport, with no ptys, no second program and no wall clock, and the run is recorded and
//! imaged as `scanhil scan` records and images it: the same seed gives the same `fsm.log`,
//! `sensor.ild` and `points.ply` bit for bit.
//!
//! # Layout
//! - [`in_process`]: one scenario run in process, with its output folder.
//! - [`emulated_imaging`]: ideal-tracking scans through the emulator's optics and sensor model
//!   (scene files), imaged by the host's pipeline.
//! - [`study`]: many variants of a scenario (seeds, noise, distance, controller,
//!   discretisation) run across the cores, or written out for a batch system, and tabulated;
//!   the binary `scanhil-study`.

pub mod emulated_imaging;
pub mod in_process;
pub mod study;
