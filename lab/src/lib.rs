#![warn(missing_docs)]
//! The scanhil lab: where the whole loop runs in one process, for tests and studies. The
//! host's lockstep state machine ([`scanhil_controller::run::host_loop`]) and the mirror
//! node's ([`scanhil_emulator::serve::lockstep_node`]) exchange frames over an in-memory
//! transport, with no ptys, no second program and no wall clock, and the run is recorded and
//! imaged as `scanhil scan` records and images it: the same seed gives the same `fsm.log`,
//! `sensor.ild` and `points.ply` bit for bit.
//!
//! # Layout
//! - [`in_process`]: one scenario run in process, with its output folder.

pub mod in_process;
