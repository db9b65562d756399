//! Recording what crosses a link: CAN frames as candump `-L` lines (the protocol's
//! [`crate::candump::push_line`]), ILD bytes raw.
//!
//! A capture collects what it records in memory and writes it with one `write` when flushed:
//! the links flush their capture before they wait for input ([`CanLink`](super::CanLink),
//! [`IldLink`](super::IldLink)), so in a loop the recording reaches the file once per period
//! (not once per line or per piece of a line), and a process killed outright loses at most
//! what it recorded since it last waited: the period in flight. What a capture holds is
//! bounded: past [`CAPTURE_FLUSH_BYTES`] it writes on its own, and dropping it writes the
//! rest (best effort; call `flush` to see the error).
//!
//! Timestamps come from a [`CaptureClock`]: the wall clock in real time, or a
//! [`VirtualClock`] the loop sets to `k * Ta` every period in lockstep, so the same seed gives
//! bit-identical recordings on every transport; or, for tools that want Unix times
//! (`log2asc`, `canplayer`), that virtual time added to the wall clock's reading when the run
//! started ([`CaptureClock::VirtualSinceEpoch`]): epoch stamps, still `Ta` apart.

use std::io::{self, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use crate::can::CanFrame;
use crate::candump::{Timestamp, push_line};

/// A capture writes on its own once it holds this many bytes (a run that never waits for
/// input, like the in-process loop, still streams its recording).
pub const CAPTURE_FLUSH_BYTES: usize = 64 * 1024;

/// Bytes recorded and not yet written, with the writer they go to.
struct Pending {
    out: Box<dyn Write + Send>,
    bytes: Vec<u8>,
}

impl Pending {
    fn new(out: impl Write + Send + 'static) -> Pending {
        Pending {
            out: Box::new(out),
            bytes: Vec::with_capacity(CAPTURE_FLUSH_BYTES),
        }
    }

    /// Writes on its own past [`CAPTURE_FLUSH_BYTES`].
    fn recorded(&mut self) -> io::Result<()> {
        if self.bytes.len() >= CAPTURE_FLUSH_BYTES {
            self.flush()
        } else {
            Ok(())
        }
    }

    /// Writes what is held with one `write_all` and flushes the writer; nothing when empty.
    fn flush(&mut self) -> io::Result<()> {
        if self.bytes.is_empty() {
            return Ok(());
        }
        let written = self
            .out
            .write_all(&self.bytes)
            .and_then(|()| self.out.flush());
        self.bytes.clear();
        written
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        let _ = self.flush();
    }
}

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
    /// The loop's virtual time after `start`, a time since the Unix epoch (the wall clock
    /// when the run started, [`CaptureClock::since_now`]).
    VirtualSinceEpoch {
        /// The Unix time virtual time zero stands for.
        start: Duration,
        /// The loop's virtual time.
        clock: VirtualClock,
    },
}

impl CaptureClock {
    /// The loop's virtual time `clock` stamped as Unix times from now on: virtual time zero is
    /// the wall clock's present reading.
    #[must_use]
    pub fn since_now(clock: VirtualClock) -> CaptureClock {
        CaptureClock::VirtualSinceEpoch {
            start: wall_since_epoch(),
            clock,
        }
    }

    fn timestamp(&self) -> Timestamp {
        let since_epoch = match self {
            CaptureClock::Wall => wall_since_epoch(),
            CaptureClock::Virtual(clock) => clock.now(),
            CaptureClock::VirtualSinceEpoch { start, clock } => start.saturating_add(clock.now()),
        };
        Timestamp {
            secs: since_epoch.as_secs(),
            nanos: since_epoch.subsec_nanos(),
        }
    }
}

/// The wall clock's time since the Unix epoch (zero for a clock set before 1970).
fn wall_since_epoch() -> Duration {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap_or_default()
}

/// Records every CAN frame sent or received on a link as a candump `-L` line.
pub struct CanCapture {
    out: Pending,
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
            out: Pending::new(out),
            interface: interface.to_owned(),
            clock,
        }
    }

    /// Appends one frame's line (written at the next [`CanCapture::flush`], or once
    /// [`CAPTURE_FLUSH_BYTES`] are held).
    ///
    /// # Errors
    /// The writer's error, when this record made the capture write.
    pub fn record(&mut self, frame: &CanFrame) -> io::Result<()> {
        push_line(
            &mut self.out.bytes,
            self.clock.timestamp(),
            &self.interface,
            frame,
        );
        self.out.bytes.push(b'\n');
        self.out.recorded()
    }

    /// Writes the lines recorded so far, with one `write`.
    ///
    /// # Errors
    /// The writer's error.
    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
}

/// Records the raw bytes of a byte link (the ILD stream): those received, and optionally
/// those sent, each to its own writer, unchanged.
pub struct ByteCapture {
    received: Pending,
    sent: Option<Pending>,
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
            received: Pending::new(received),
            sent: None,
        }
    }

    /// Also records the bytes sent, to `sent`.
    #[must_use]
    pub fn with_sent(mut self, sent: impl Write + Send + 'static) -> Self {
        self.sent = Some(Pending::new(sent));
        self
    }

    /// Records bytes received (written at the next [`ByteCapture::flush`], or once
    /// [`CAPTURE_FLUSH_BYTES`] are held).
    ///
    /// # Errors
    /// The writer's error, when this record made the capture write.
    pub fn record_received(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.received.bytes.extend_from_slice(bytes);
        self.received.recorded()
    }

    /// Records bytes sent (if a writer for them was given), as
    /// [`ByteCapture::record_received`].
    ///
    /// # Errors
    /// The writer's error, when this record made the capture write.
    pub fn record_sent(&mut self, bytes: &[u8]) -> io::Result<()> {
        match &mut self.sent {
            Some(out) => {
                out.bytes.extend_from_slice(bytes);
                out.recorded()
            }
            None => Ok(()),
        }
    }

    /// Writes the bytes recorded so far, one `write` per writer.
    ///
    /// # Errors
    /// The writers' error (both are flushed either way).
    pub fn flush(&mut self) -> io::Result<()> {
        let received = self.received.flush();
        let sent = self.sent.as_mut().map_or(Ok(()), Pending::flush);
        received.and(sent)
    }
}
