//! The real transports between the controller, the mirror node and the sensor node, named by
//! URIs on the command line: `socketcan:IFACE[@BITRATE]`, `slcan:PATH[@BITRATE][?family=F]`,
//! `ild:PATH[@BAUD]`.
//!
//! # Layout
//! - [`uri`]: link URIs from the command line.
//! - [`role`]: which end of a link this program is (host or device).
//! - [`arrival`]: when a received frame arrived (read time, and the kernel's or the adapter's
//!   receive time).
//! - [`error`]: [`LinkError`], naming the link and the OS error.
//! - [`pty`]: pty pairs, a serial line between two programs on one machine.
//! - [`line`](mod@line): an async byte line over a serial port or pty (what SLCAN and ILD run on).
//! - [`socketcan`]: a kernel SocketCAN interface.
//! - [`slcan`]: SLCAN over a line, host (drives an adapter) and device (acts as one).
//! - [`can`]: [`CanLink`], one CAN link over either transport: send, receive, timeouts.
//! - [`ild`]: [`IldLink`], the ILD 2300's value stream and ASCII commands, both ends.
//! - [`capture`]: recording what crosses a link (candump `-L` lines, raw ILD bytes).
//! - [`watchdog`]: declares a link timeout after N silent periods.

pub mod arrival;
pub mod can;
pub mod capture;
pub mod error;
pub mod ild;
pub mod line;
pub mod pty;
pub mod role;
pub mod slcan;
pub mod socketcan;
pub mod uri;
pub mod watchdog;

pub use arrival::{Arrival, ArrivalSource};
pub use can::{CanLink, LinkReport, LinkStats, RecvError, SlcanReport};
pub use capture::{ByteCapture, CAPTURE_FLUSH_BYTES, CanCapture, CaptureClock, VirtualClock};
pub use error::{LinkError, LinkResult};
pub use ild::{IldCycle, IldCycleAssembler, IldLink, IldRequest};
pub use line::SerialLine;
pub use pty::PtyPair;
pub use role::Role;
pub use socketcan::SocketCanReport;
pub use uri::{LinkUri, UriError};
pub use watchdog::{LinkTimeout, Watchdog};
