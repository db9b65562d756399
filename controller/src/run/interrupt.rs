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

    /// Gives the signals back their default action (end the process) once the loop has
    /// stopped: tokio keeps its handlers installed for the process' life, so without this a
    /// signal during the wrap-up (closing links, waiting for the emulator, writing outputs)
    /// would be caught and ignored.
    pub fn restore_default(self) {
        use nix::sys::signal::{SigHandler, Signal, signal};
        for stop in [Signal::SIGINT, Signal::SIGTERM, Signal::SIGHUP] {
            // SAFETY: the default disposition installs no handler code; tokio's handler,
            // which only records the signal, is simply no longer called.
            let _ = unsafe { signal(stop, SigHandler::SigDfl) };
        }
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
