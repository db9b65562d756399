//! Recording what crosses a link: CAN frames as candump `-L` lines (the protocol's
//! [`LogEntry`] writer), ILD bytes raw. Lines are flushed one by one, so a run that stops on
//! a fault or a link timeout loses nothing already recorded.
//!
//! Timestamps come from a [`CaptureClock`]: the wall clock in real time, or a
//! [`VirtualClock`] the loop sets to `k * Ta` every period in lockstep, so the same seed gives
//! bit-identical recordings on every transport.

use std::io::{self, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use crate::can::CanFrame;
use crate::candump::{LogEntry, Timestamp};

/// A clock the loop sets: the current virtual time, shared by cheap clones.
#[derive(Debug, Clone, Default)]
pub struct VirtualClock(Arc<AtomicU64>);

impl VirtualClock {
    /// Sets the current virtual time (saturates at about 584 years).
    pub fn set(&self, time: Duration) {
        let nanos = u64::try_from(time.as_nanos()).unwrap_or(u64::MAX);
        self.0.store(nanos, Ordering::Relaxed);
    }

    /// The current virtual time.
    #[must_use]
    pub fn now(&self) -> Duration {
        Duration::from_nanos(self.0.load(Ordering::Relaxed))
    }
}

/// Where capture timestamps come from.
#[derive(Debug, Clone)]
pub enum CaptureClock {
    /// Seconds since the Unix epoch, as candump writes them.
    Wall,
    /// The loop's virtual time.
    Virtual(VirtualClock),
}

impl CaptureClock {
    fn timestamp(&self) -> Timestamp {
        let since_epoch = match self {
            CaptureClock::Wall => SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .unwrap_or_default(),
            CaptureClock::Virtual(clock) => clock.now(),
        };
        Timestamp {
            secs: since_epoch.as_secs(),
            nanos: since_epoch.subsec_nanos(),
        }
    }
}

/// Records every CAN frame sent or received on a link as a candump `-L` line.
pub struct CanCapture {
    out: Box<dyn Write + Send>,
    interface: String,
    clock: CaptureClock,
}

impl std::fmt::Debug for CanCapture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CanCapture")
            .field("interface", &self.interface)
            .field("clock", &self.clock)
            .finish_non_exhaustive()
    }
}

impl CanCapture {
    /// Writes lines `(<time>) <interface> <frame>` to `out`. Choose the same `interface` name
    /// on every transport (e.g. `fsm`) when recordings are to be compared.
    pub fn new(out: impl Write + Send + 'static, interface: &str, clock: CaptureClock) -> Self {
        CanCapture {
            out: Box::new(out),
            interface: interface.to_owned(),
            clock,
        }
    }

    /// Appends one frame's line and flushes it.
    ///
    /// # Errors
    /// The writer's error.
    pub fn record(&mut self, frame: &CanFrame) -> io::Result<()> {
        let entry = LogEntry {
            timestamp: self.clock.timestamp(),
            interface: self.interface.clone(),
            frame: *frame,
        };
        writeln!(self.out, "{entry}")?;
        self.out.flush()
    }
}

/// Records the raw bytes of a byte link (the ILD stream): those received, and optionally
/// those sent, each to its own writer, unchanged.
pub struct ByteCapture {
    received: Box<dyn Write + Send>,
    sent: Option<Box<dyn Write + Send>>,
}

impl std::fmt::Debug for ByteCapture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ByteCapture")
            .field("records_sent", &self.sent.is_some())
            .finish_non_exhaustive()
    }
}

impl ByteCapture {
    /// Records the bytes received to `received`.
    pub fn new(received: impl Write + Send + 'static) -> Self {
        ByteCapture {
            received: Box::new(received),
            sent: None,
        }
    }

    /// Also records the bytes sent, to `sent`.
    #[must_use]
    pub fn with_sent(mut self, sent: impl Write + Send + 'static) -> Self {
        self.sent = Some(Box::new(sent));
        self
    }

    /// Records bytes received.
    ///
    /// # Errors
    /// The writer's error.
    pub fn record_received(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.received.write_all(bytes)?;
        self.received.flush()
    }

    /// Records bytes sent (if a writer for them was given).
    ///
    /// # Errors
    /// The writer's error.
    pub fn record_sent(&mut self, bytes: &[u8]) -> io::Result<()> {
        match &mut self.sent {
            Some(out) => {
                out.write_all(bytes)?;
                out.flush()
            }
            None => Ok(()),
        }
    }
}
