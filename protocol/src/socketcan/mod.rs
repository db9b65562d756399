//! What the SocketCAN link decides, without the kernel: pure functions the link
//! (`link::socketcan`, cargo feature `links`) calls with what it read, tested here without a
//! CAN-capable kernel.
//!
//! - [`send_retry`]: how often, and after how long, a send the kernel refused with `ENOBUFS`
//!   (the interface's transmit queue is full) is tried again, and the count of such retries.
//! - [`interface_state`]: the interface's bit rate, controller state and error counters as
//!   netlink reports them, checked against the bit rate the run expects: accepted with notes,
//!   or refused naming both values.
//! - [`drop_count`]: the frames the kernel dropped because the socket's receive queue was
//!   full (`sk_drops`), counted from the socket's open.

pub mod drop_count;
pub mod interface_state;
pub mod send_retry;
