//! A mirror node that stops reading its line (a hung adapter, a frozen node behind a buffer),
//! played on a real pty: it answers the SLCAN set-up, then only writes AngleReadings (counter
//! 0, 1, ...) as fast as the line takes them, never reading the host's commands again, so the
//! host's writes fill the line. A plain thread on the pty's master end: it answers at once,
//! however loaded the machine (a node on an async runtime answered too late for a 1 ms
//! watchdog under CI load).

use std::io::{Read, Write};
use std::os::fd::OwnedFd;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use nix::fcntl::OFlag;
use scanhil_protocol::message::{AngleReading, Message};
use scanhil_protocol::plant_units::SensingPair;

/// The node: the pty's slave path for the host, and how many readings it has written.
pub struct DeafNode {
    slave_path: String,
    /// Held so the line stays up while the host opens it.
    _slave: OwnedFd,
    readings_sent: Arc<AtomicU64>,
}

impl DeafNode {
    /// Opens a pty and starts the node on its master end.
    pub fn start() -> DeafNode {
        let master = nix::pty::posix_openpt(OFlag::O_RDWR | OFlag::O_NOCTTY).expect("a pty");
        nix::pty::grantpt(&master).expect("grantpt");
        nix::pty::unlockpt(&master).expect("unlockpt");
        let slave_path = nix::pty::ptsname_r(&master).expect("the slave's path");
        let slave: OwnedFd = nix::fcntl::open(
            slave_path.as_str(),
            OFlag::O_RDWR | OFlag::O_NOCTTY,
            nix::sys::stat::Mode::empty(),
        )
        .expect("opening the slave");
        let mut settings = nix::sys::termios::tcgetattr(&slave).expect("termios");
        nix::sys::termios::cfmakeraw(&mut settings);
        nix::sys::termios::tcsetattr(&slave, nix::sys::termios::SetArg::TCSANOW, &settings)
            .expect("raw mode");
        let mut line = std::fs::File::from(OwnedFd::from(master));
        let readings_sent = Arc::new(AtomicU64::new(0));
        let counter = Arc::clone(&readings_sent);
        std::thread::spawn(move || {
            // Answer every SLCAN command with CR until the channel is opened (`O`).
            let mut buf = [0u8; 256];
            let mut pending = Vec::new();
            'setup: while let Ok(n) = line.read(&mut buf) {
                if n == 0 {
                    return;
                }
                pending.extend_from_slice(&buf[..n]);
                while let Some(end) = pending.iter().position(|&b| b == b'\r') {
                    let command: Vec<u8> = pending.drain(..=end).collect();
                    if line.write_all(b"\r").is_err() {
                        return;
                    }
                    if command.first() == Some(&b'O') {
                        break 'setup;
                    }
                }
            }
            // Then only talk, and never read the host's answers (its writes fill the line).
            for k in 0u64.. {
                let reading =
                    Message::AngleReading(AngleReading::from_rad(k as u16, SensingPair::default()));
                let frame = reading.encode().expect("encodable");
                let text = scanhil_protocol::slcan::encode_frame(&frame);
                if line.write_all(text.as_bytes()).is_err() {
                    return;
                }
                counter.fetch_add(1, Ordering::Relaxed);
            }
        });
        DeafNode {
            slave_path,
            _slave: slave,
            readings_sent,
        }
    }

    /// The host's URI of the node's line (`slcan:/dev/pts/N`).
    pub fn fsm_uri(&self) -> String {
        format!("slcan:{}", self.slave_path)
    }

    /// AngleReadings written so far.
    pub fn readings_sent(&self) -> u64 {
        self.readings_sent.load(Ordering::Relaxed)
    }
}
