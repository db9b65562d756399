#![warn(missing_docs)]
#![forbid(unsafe_code)]
//! scanhil wire format, shared by the emulator and the controller.
//!
//! # Layout
//! - [`can`]: CAN identifiers and frames (classical, remote, FD), validated at construction.
//! - [`slcan`]: the SLCAN (Lawicel) line protocol: incremental decoder and encoder.
//! - [`message`]: the CAN message set: ids, typed messages, the signal table (single source
//!   of the layout).
//! - [`plant_units`]: the mirror node's device contract: units, scalings, the sensing axes,
//!   axis rotation (cargo feature `clap`: the axis as a command-line value).
//! - [`bus_load`]: worst-case bits per frame and the load a message budget puts on a bus.
//! - [`candump`]: candump `-L` log lines, reader and writer (classical and FD).
//! - [`fault_injection`]: injected faults on a frame stream (drop, delay, duplicate, reorder,
//!   bit flip), seeded and deterministic, with a ledger of every frame.
//! - [`dbc`]: the DBC file rendered from the message table (`protocol/scanhil.dbc`).
//! - [`ild`]: the ILD 2300 sensor: RS422 values, the L/M/H byte stream, ASCII commands.
//! - [`interface_name`]: Linux network interface names, as the kernel accepts them.
//! - [`error_text`]: an error and its causes on one line, each said once (the programs'
//!   error line).
//! - [`loop_timing`]: period jitter and overruns of a real-time loop, as both ends report them.
//! - [`loop_limits`]: the timing limits both ends hold a run to (duration, answer allowance,
//!   watchdog, probe, heartbeat).
//! - [`socketcan`]: what the SocketCAN link decides, pure: retries on a full transmit queue,
//!   the interface's bit rate and state checked, the socket's dropped frames counted.
//! - [`validation`]: how every program says a value cannot run: the field or flag, the file,
//!   the value and the allowed range.
//! - [`whole_file`]: output files written under a temporary name and renamed once whole.
//! - [`stdout`]: printing whose failure (`> /dev/full`) is an error, never a panic.
//! - `link` (cargo feature `links`): the real transports: SocketCAN, SLCAN over a serial port or
//!   pty, the ILD stream over a serial port or pty; link URIs, pty pairs, capture, watchdog.

pub mod bus_load;
pub mod can;
pub mod candump;
pub mod dbc;
pub mod error_text;
pub mod fault_injection;
pub mod ild;
pub mod interface_name;
#[cfg(feature = "links")]
pub mod link;
pub mod loop_limits;
pub mod loop_timing;
pub mod message;
pub mod plant_units;
#[cfg(feature = "links")]
pub mod scheduling;
pub mod slcan;
pub mod socketcan;
pub mod stdout;
pub mod validation;
pub mod whole_file;
