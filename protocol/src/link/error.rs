//! What can go wrong on a link, always naming the link (its URI or path) and the OS error.

use std::io;
use std::time::Duration;

use super::uri::UriError;

/// An error on a link. Every variant names the link it happened on.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LinkError {
    /// The link URI did not parse.
    #[error(transparent)]
    Uri(#[from] UriError),
    /// The transport could not be opened or configured.
    #[error("cannot open {link}: {source}{hint}")]
    Open {
        /// The link's URI (or path).
        link: String,
        /// The OS error.
        #[source]
        source: io::Error,
        /// A hint for the operator, empty or starting with "; ".
        hint: String,
    },
    /// Reading or writing failed with an OS error.
    #[error("{op} on {link} failed: {source}")]
    Io {
        /// The link's URI (or path).
        link: String,
        /// What was being done ("read", "write", ...).
        op: &'static str,
        /// The OS error.
        #[source]
        source: io::Error,
    },
    /// The other end closed the line (EOF, hang-up, adapter unplugged).
    #[error("{link}: the other end hung up")]
    HangUp {
        /// The link's URI (or path).
        link: String,
    },
    /// SocketCAN: the CAN controller went bus-off (too many transmit errors): it takes no
    /// part in the bus until restarted, so the run cannot go on.
    #[error("{link}: the CAN controller went bus-off ({detail})")]
    BusOff {
        /// The link's URI.
        link: String,
        /// The kernel's error frame, described.
        detail: String,
    },
    /// Device end of SLCAN, when asked to end its run on close
    /// ([`crate::link::CanLink::end_run_on_close`]): the host closed the open channel with `C`.
    /// Like a hang-up, the end of the session, but the line stays usable.
    #[error("{link}: the host closed the SLCAN channel (`C`)")]
    ChannelClosed {
        /// The link's URI (or path).
        link: String,
    },
    /// An SLCAN adapter (or device end) refused a command with BEL.
    #[error("{link}: the SLCAN adapter refused `{command}` (replied BEL)")]
    AdapterRefused {
        /// The link's URI (or path).
        link: String,
        /// The command it refused, without the CR.
        command: String,
    },
    /// SocketCAN: the interface cannot carry the run as netlink reports it (down, another
    /// bit rate than the URI's, a controller bus-off or stopped).
    #[error("cannot use {link}: {detail}")]
    Interface {
        /// The link's URI.
        link: String,
        /// What is wrong and what to do about it.
        detail: String,
    },
    /// SocketCAN: the interface's transmit queue stayed full (`ENOBUFS`) through every retry
    /// ([`crate::socketcan::send_retry`]).
    #[error(
        "{link}: the interface's transmit queue stayed full (ENOBUFS) through {retries} \
         retries over {waited:?}: nothing acknowledges the frames (no other node powered, no \
         termination), or the queue is short (`ip link set IFACE txqueuelen 1000`)"
    )]
    QueueFull {
        /// The link's URI.
        link: String,
        /// Retries made.
        retries: u32,
        /// How long they waited in all.
        waited: Duration,
    },
    /// A reply did not arrive in time.
    #[error("{link}: no reply to `{command}` within {waited:?}")]
    NoReply {
        /// The link's URI (or path).
        link: String,
        /// The command that went unanswered.
        command: String,
        /// How long we waited.
        waited: Duration,
    },
    /// The peer answered something this link cannot accept.
    #[error("{link}: {detail}")]
    Protocol {
        /// The link's URI (or path).
        link: String,
        /// What was wrong.
        detail: String,
    },
    /// A frame this transport cannot carry (e.g. CAN FD on a classical-only SLCAN line).
    #[error("{link}: cannot send {detail}")]
    Unsupported {
        /// The link's URI (or path).
        link: String,
        /// What could not be sent.
        detail: String,
    },
    /// Writing a capture (recording) failed.
    #[error("writing the capture of {link} failed: {source}")]
    Capture {
        /// The link's URI (or path).
        link: String,
        /// The OS error.
        #[source]
        source: io::Error,
    },
}

/// Result of a link operation.
pub type LinkResult<T> = Result<T, LinkError>;
