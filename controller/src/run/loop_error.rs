//! Why a host loop stopped early: one error for the pure loop, its links and its shells.

use std::time::Duration;

use scanhil_protocol::link::LinkError;
use scanhil_protocol::message::{FaultKind, NodeId};

/// Why the loop stopped early.
#[derive(Debug, thiserror::Error)]
pub enum LoopError {
    /// No answer within the watchdog's allowance.
    #[error(
        "link timeout on {link}: no angle reading for period {period} within {waited:?} (watchdog: {periods} periods)"
    )]
    LinkTimeout {
        /// The link.
        link: String,
        /// The period waited for.
        period: u64,
        /// The watchdog's periods.
        periods: u32,
        /// The wall-clock time waited.
        waited: Duration,
    },
    /// The node stopped taking frames: a send did not go out within the watchdog's allowance
    /// (a node that no longer reads its line fills it, and the write would wait forever).
    #[error(
        "link timeout on {link}: the frames of period {period} could not be sent within {waited:?} (the node stopped reading)"
    )]
    SendTimeout {
        /// The link.
        link: String,
        /// The period whose frames were being sent.
        period: u64,
        /// The wall-clock time waited.
        waited: Duration,
    },
    /// A node reported a fault that ends the run (its own link timeout).
    #[error("{link}: the {node:?} node reported {kind:?} at step {step} (mod 2^16)")]
    NodeFault {
        /// The link.
        link: String,
        /// The node.
        node: NodeId,
        /// The fault.
        kind: FaultKind,
        /// Its step counter.
        step: u16,
    },
    /// A message could not be encoded.
    #[error("cannot encode a frame: {0}")]
    Encode(String),
    /// A signal (Ctrl-C, SIGTERM, SIGHUP) stopped the scan.
    #[error("interrupted by {signal}")]
    Interrupted {
        /// The signal's name.
        signal: &'static str,
    },
    /// The transport failed (hang-up: the emulator or adapter went away).
    #[error(transparent)]
    Link(#[from] LinkError),
}
