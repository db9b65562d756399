//! Pseudo-terminal pairs: a serial line between two programs on one machine, with no
//! hardware and no kernel CAN.
//!
//! The creating program keeps the master end (it has no path of its own: `/dev/ptmx` opens a
//! new pair) and hands the slave's path (`/dev/pts/N`) to the other program, which opens it
//! like any serial port (`slcan:/dev/pts/N`, `ild:/dev/pts/N`). Either end can play either
//! role: the controller usually keeps the master as host and starts the emulator on the slave
//! path; a device can also create the pair and print the slave path for an outside client
//! (python-can's `slcan` interface).

use std::fs::File;
use std::os::fd::OwnedFd;
use std::path::{Path, PathBuf};

use nix::fcntl::OFlag;
use nix::sys::termios::{self, SetArg};

use super::error::{LinkError, LinkResult};

/// A freshly created pty pair: the master end held here, the slave's path for the peer.
#[derive(Debug)]
pub struct PtyPair {
    master: File,
    /// Held open (in raw mode) until the peer has opened its end and spoken.
    slave: OwnedFd,
    slave_path: PathBuf,
}

impl PtyPair {
    /// Creates a pty pair with its slave in raw mode (no echo, no line editing, 8 bits).
    ///
    /// # Errors
    /// [`LinkError::Open`] naming `/dev/ptmx` (or the slave path) and the OS error.
    pub fn open() -> LinkResult<Self> {
        let fail = |link: &str, e: nix::Error| LinkError::Open {
            link: link.to_owned(),
            source: e.into(),
            hint: String::new(),
        };
        let master = nix::pty::posix_openpt(OFlag::O_RDWR | OFlag::O_NOCTTY | OFlag::O_CLOEXEC)
            .map_err(|e| fail("/dev/ptmx", e))?;
        nix::pty::grantpt(&master).map_err(|e| fail("/dev/ptmx", e))?;
        nix::pty::unlockpt(&master).map_err(|e| fail("/dev/ptmx", e))?;
        let slave_path =
            PathBuf::from(nix::pty::ptsname_r(&master).map_err(|e| fail("/dev/ptmx", e))?);
        let slave_name = slave_path.display().to_string();
        let slave: OwnedFd = nix::fcntl::open(
            &slave_path,
            OFlag::O_RDWR | OFlag::O_NOCTTY | OFlag::O_CLOEXEC,
            nix::sys::stat::Mode::empty(),
        )
        .map_err(|e| fail(&slave_name, e))?;
        let mut settings = termios::tcgetattr(&slave).map_err(|e| fail(&slave_name, e))?;
        termios::cfmakeraw(&mut settings);
        termios::tcsetattr(&slave, SetArg::TCSANOW, &settings).map_err(|e| fail(&slave_name, e))?;
        Ok(PtyPair {
            master: File::from(OwnedFd::from(master)),
            slave,
            slave_path,
        })
    }

    /// The slave end's path (`/dev/pts/N`), to give to the peer program.
    #[must_use]
    pub fn slave_path(&self) -> &Path {
        &self.slave_path
    }

    /// The master file and the slave keep-alive handle.
    pub(crate) fn into_parts(self) -> (File, OwnedFd) {
        (self.master, self.slave)
    }
}
