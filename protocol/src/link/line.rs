//! An async byte line over a serial port, a pty slave (opened by path) or a pty master (held
//! in this process): what SLCAN and the ILD stream run on.
//!
//! The line is non-blocking under tokio's [`AsyncFd`], so a timed-out read loses nothing.
//! EOF and `EIO` (the other end closed, the adapter was unplugged) are reported as
//! [`LinkError::HangUp`].

use std::fs::{File, OpenOptions};
use std::io::{self, Read, Write};
use std::os::fd::{AsRawFd, OwnedFd};
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

use nix::fcntl::{Flock, FlockArg, OFlag};
use tokio::io::unix::AsyncFd;

use super::error::{LinkError, LinkResult};
use super::pty::PtyPair;

/// What an open failure on a locked port most likely means.
const BUSY_HINT: &str = "; another program has this port open";

/// An open byte line, read and written asynchronously.
#[derive(Debug)]
pub struct SerialLine {
    /// The link's name in errors (its URI).
    name: String,
    fd: AsyncFd<File>,
    /// Exclusive lock on a real port, so a second program cannot share the adapter.
    _lock: Option<Flock<File>>,
    /// On a pty master: our own handle on the slave, held until the peer has spoken, so the
    /// master does not read `EIO` (= hang-up) before the peer has opened its end.
    slave_keepalive: Option<OwnedFd>,
    /// Bytes the line has taken so far (a peer that reads lets this grow).
    written: std::sync::atomic::AtomicU64,
}

impl SerialLine {
    /// Opens a serial device or pty slave by path, in raw 8N1 mode at `baud` (ignored by ptys
    /// and USB CDC adapters), locked against other programs.
    ///
    /// # Errors
    /// [`LinkError::Open`] naming `name` and the OS error (no such device, permission denied,
    /// in use by another program, not a tty).
    pub fn open(path: &Path, baud: u32, name: &str) -> LinkResult<Self> {
        let open_error = |source: io::Error, hint: &str| LinkError::Open {
            link: name.to_owned(),
            source,
            hint: hint.to_owned(),
        };
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags((OFlag::O_NOCTTY | OFlag::O_NONBLOCK).bits())
            .open(path)
            .map_err(|e| open_error(e, ""))?;
        if !nix::unistd::isatty(&file).unwrap_or(false) {
            return Err(open_error(
                io::Error::other(format!("{} is not a serial port or pty", path.display())),
                "",
            ));
        }
        // serialport configures raw 8N1 and any baud rate (termios2 on Linux); the settings
        // stay on the device while `file` holds it open.
        let path_text = path.to_string_lossy();
        serialport::new(path_text, baud)
            .exclusive(false)
            .open_native()
            .map_err(|e| {
                let hint = if e.kind() == serialport::ErrorKind::NoDevice {
                    BUSY_HINT
                } else {
                    ""
                };
                open_error(io::Error::other(e.to_string()), hint)
            })?;
        let lock = Flock::lock(
            file.try_clone().map_err(|e| open_error(e, ""))?,
            FlockArg::LockExclusiveNonblock,
        )
        .map_err(|(_, errno)| open_error(io::Error::from(errno), BUSY_HINT))?;
        Self::from_file(file, name, Some(lock), None)
    }

    /// Takes over the master end of a pty pair; the slave is held open until the peer speaks.
    ///
    /// # Errors
    /// [`LinkError::Open`] if the master cannot be registered with tokio (no runtime).
    pub fn from_pty(pair: PtyPair, name: &str) -> LinkResult<Self> {
        let (master, slave) = pair.into_parts();
        Self::from_file(master, name, None, Some(slave))
    }

    fn from_file(
        file: File,
        name: &str,
        lock: Option<Flock<File>>,
        slave_keepalive: Option<OwnedFd>,
    ) -> LinkResult<Self> {
        let open_error = |source: io::Error| LinkError::Open {
            link: name.to_owned(),
            source,
            hint: String::new(),
        };
        nix::fcntl::fcntl(&file, nix::fcntl::FcntlArg::F_SETFL(OFlag::O_NONBLOCK))
            .map_err(|e| open_error(e.into()))?;
        Ok(SerialLine {
            name: name.to_owned(),
            fd: register(file).map_err(open_error)?,
            _lock: lock,
            slave_keepalive,
            written: std::sync::atomic::AtomicU64::new(0),
        })
    }

    /// The link's name in errors.
    #[must_use]
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Bytes the line has taken so far: while a peer reads, this grows.
    #[must_use]
    pub fn bytes_written(&self) -> u64 {
        self.written.load(std::sync::atomic::Ordering::Relaxed)
    }

    fn took(&self, n: usize) {
        self.written
            .fetch_add(n as u64, std::sync::atomic::Ordering::Relaxed);
    }

    /// Reads what is available (at least one byte), waiting for it. Cancel-safe.
    ///
    /// # Errors
    /// [`LinkError::HangUp`] on EOF or `EIO`; [`LinkError::Io`] for other OS errors.
    pub async fn read(&mut self, buf: &mut [u8]) -> LinkResult<usize> {
        loop {
            let mut guard = self.fd.readable().await.map_err(|e| self.io("read", e))?;
            match guard.try_io(|inner| inner.get_ref().read(buf)) {
                Ok(Ok(0)) => return Err(self.hang_up()),
                Ok(Ok(n)) => {
                    // A short read took all there was: the next read waits for the next
                    // readiness event instead of trying once more for an EAGAIN (as tokio's
                    // own sockets do).
                    if n < buf.len() {
                        guard.clear_ready();
                    }
                    self.slave_keepalive = None;
                    return Ok(n);
                }
                Ok(Err(e)) if e.raw_os_error() == Some(nix::libc::EIO) => {
                    return Err(self.hang_up());
                }
                Ok(Err(e)) if e.kind() == io::ErrorKind::Interrupted => {}
                Ok(Err(e)) => return Err(self.io("read", e)),
                Err(_would_block) => {}
            }
        }
    }

    /// Reads what is available without waiting: `None` when nothing is.
    ///
    /// # Errors
    /// As [`SerialLine::read`].
    pub fn try_read(&mut self, buf: &mut [u8]) -> LinkResult<Option<usize>> {
        match self.fd.get_ref().read(buf) {
            Ok(0) => Err(self.hang_up()),
            Ok(n) => {
                self.slave_keepalive = None;
                Ok(Some(n))
            }
            Err(e) if e.raw_os_error() == Some(nix::libc::EIO) => Err(self.hang_up()),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
                ) =>
            {
                Ok(None)
            }
            Err(e) => Err(self.io("read", e)),
        }
    }

    /// Writes some of `bytes` (at least one), waiting while the line's buffer is full;
    /// returns how many were written. Cancel-safe: nothing is written unless it returns.
    ///
    /// # Errors
    /// [`LinkError::HangUp`] on `EIO`; [`LinkError::Io`] for other OS errors.
    pub async fn write_some(&self, bytes: &[u8]) -> LinkResult<usize> {
        loop {
            let mut guard = self.fd.writable().await.map_err(|e| self.io("write", e))?;
            // A pty whose other end is gone stays "writable" (hang-up) while its buffer is
            // full: without this the loop would spin on EAGAIN for ever.
            let peer_gone = guard.ready().is_write_closed();
            match guard.try_io(|inner| inner.get_ref().write(bytes)) {
                Ok(Ok(n)) => {
                    self.took(n);
                    return Ok(n);
                }
                Ok(Err(e)) if e.raw_os_error() == Some(nix::libc::EIO) => {
                    return Err(self.hang_up());
                }
                Ok(Err(e)) if e.kind() == io::ErrorKind::Interrupted => {}
                Ok(Err(e)) => return Err(self.io("write", e)),
                Err(_would_block) if peer_gone => return Err(self.hang_up()),
                Err(_would_block) => {}
            }
        }
    }

    /// Writes all of `bytes`, waiting while the line's buffer is full. Not cancel-safe (use
    /// [`SerialLine::flush_pending`] where a cancelled write must resume).
    ///
    /// # Errors
    /// As [`SerialLine::write_some`].
    pub async fn write_all(&self, bytes: &[u8]) -> LinkResult<()> {
        self.flush_pending(&mut bytes.to_vec()).await
    }

    /// Writes what of `pending` the line takes now, without waiting, and removes it from
    /// `pending`.
    ///
    /// # Errors
    /// As [`SerialLine::write_some`].
    pub fn try_flush_pending(&self, pending: &mut Vec<u8>) -> LinkResult<()> {
        while !pending.is_empty() {
            match self.fd.get_ref().write(pending) {
                Ok(n) => {
                    self.took(n);
                    pending.drain(..n);
                }
                Err(e) if e.raw_os_error() == Some(nix::libc::EIO) => {
                    return Err(self.hang_up());
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(e) => return Err(self.io("write", e)),
            }
        }
        Ok(())
    }

    /// Writes all of `pending` and empties it; cancel-safe (what was not yet written stays in
    /// `pending` for the next call).
    ///
    /// # Errors
    /// As [`SerialLine::write_some`].
    pub async fn flush_pending(&self, pending: &mut Vec<u8>) -> LinkResult<()> {
        while !pending.is_empty() {
            let n = self.write_some(pending).await?;
            pending.drain(..n);
        }
        Ok(())
    }

    fn io(&self, op: &'static str, source: io::Error) -> LinkError {
        LinkError::Io {
            link: self.name.clone(),
            op,
            source,
        }
    }

    fn hang_up(&self) -> LinkError {
        LinkError::HangUp {
            link: self.name.clone(),
        }
    }
}

/// Registers `owner` of a descriptor (a [`File`], the SocketCAN link's socket) with tokio's
/// reactor.
///
/// `AsyncFd::new` is deprecated because it cannot check, for an arbitrary `T`, that
/// `as_raw_fd()` stays the same open descriptor for the `AsyncFd`'s whole life; the unsafe
/// `AsyncFd::register` makes the caller promise it. A type that owns its descriptor, as a
/// [`File`] and a `socketcan` socket do, returns that same one until dropped, which is exactly
/// that promise, and this crate forbids unsafe code, so the safe (deprecated) constructor is
/// the right call here. Only ever pass such an owner.
#[allow(deprecated)]
pub(super) fn register<T: AsRawFd>(owner: T) -> io::Result<AsyncFd<T>> {
    AsyncFd::new(owner)
}
