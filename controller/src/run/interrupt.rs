//! Stopping a scan by signal: SIGINT (Ctrl-C), SIGTERM and SIGHUP are caught while the loop
//! runs, so an interrupted scan stops like any other early stop: the loop commands zero
//! current, the links close properly (SLCAN `C`), everything recorded up to then is written,
//! and `scanhil scan` says why and exits 3.
//!
//! The handler is installed when the loop starts; a signal before that (while the emulator
//! starts) ends the process as usual. The emulator runs in its own process group
//! ([`super::emulator_process`]), so a Ctrl-C on the terminal reaches the host alone, which
//! then ends the emulator's run through the link.

use tokio::signal::unix::{Signal, SignalKind, signal};

/// The installed signal handlers.
#[derive(Debug)]
pub struct Interrupt {
    interrupt: Signal,
    terminate: Signal,
    hangup: Signal,
}

impl Interrupt {
    /// Installs the handlers (inside a tokio runtime with I/O enabled).
    ///
    /// # Errors
    /// The OS error of installing a handler.
    pub fn install() -> std::io::Result<Interrupt> {
        Ok(Interrupt {
            interrupt: signal(SignalKind::interrupt())?,
            terminate: signal(SignalKind::terminate())?,
            hangup: signal(SignalKind::hangup())?,
        })
    }

    /// Waits for the first stopping signal and returns its name.
    pub async fn recv(&mut self) -> &'static str {
        tokio::select! {
            _ = self.interrupt.recv() => "SIGINT",
            _ = self.terminate.recv() => "SIGTERM",
            _ = self.hangup.recv() => "SIGHUP",
        }
    }
}
