//! The emulator's end of a CAN link, in the device role: on a serial line or pty it behaves
//! as an SLCAN adapter with the emulated node behind it (answers `O`, `C`, `Sn`, `V`, `N`
//! with CR, refuses malformed lines with BEL, carries frames only while open); on SocketCAN it
//! is one more node on the bus.

use std::collections::VecDeque;

use scanhil_protocol::can::CanFrame;
use scanhil_protocol::link::{LinkError, LinkResult, LinkUri, PtyPair, SerialLine};
use scanhil_protocol::link::socketcan::SocketCanPort;
use scanhil_protocol::slcan::{SlcanDecoder, SlcanMessage, encode_frame};

/// Version reply to `V` (hardware 01, software 01).
const SLCAN_VERSION: &str = "0101";
/// Serial number reply to `N`.
const SLCAN_SERIAL: &str = "SHIL";

/// A device-side CAN port.
#[derive(Debug)]
pub enum DevicePort {
    /// SLCAN over a serial line or pty, this end acting as the adapter.
    Slcan(SlcanDevice),
    /// A SocketCAN interface.
    SocketCan(SocketCanPort),
}

/// The adapter side of an SLCAN line.
#[derive(Debug)]
pub struct SlcanDevice {
    line: SerialLine,
    decoder: SlcanDecoder,
    received: VecDeque<CanFrame>,
    open: bool,
    malformed_lines: u64,
}

/// Counts of what the port saw that was not a frame for the node.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct PortCounters {
    /// Malformed SLCAN lines (each answered with BEL).
    pub malformed_lines: u64,
}

impl DevicePort {
    /// Opens the port a URI names (`slcan:PATH`, `socketcan:IFACE`).
    ///
    /// # Errors
    /// [`LinkError`] naming the link; an `ild:` URI is refused as not a CAN link.
    pub fn open(uri: &LinkUri) -> LinkResult<DevicePort> {
        let name = uri.to_string();
        match uri {
            LinkUri::Slcan { path, .. } => {
                let line = SerialLine::open(path, scanhil_protocol::link::uri::SLCAN_SERIAL_BAUD, &name)?;
                Ok(DevicePort::Slcan(SlcanDevice::new(line)))
            }
            LinkUri::SocketCan { iface, .. } => {
                Ok(DevicePort::SocketCan(SocketCanPort::open(iface, &name)?))
            }
            LinkUri::Ild { .. } => Err(LinkError::Protocol {
                link: name,
                detail: "the mirror node needs a CAN link (slcan: or socketcan:)".into(),
            }),
        }
    }

    /// An SLCAN port on the master end of a fresh pty pair (for an outside client).
    ///
    /// # Errors
    /// [`LinkError::Open`] if the master cannot be registered.
    pub fn slcan_on_pty(pair: PtyPair, name: &str) -> LinkResult<DevicePort> {
        Ok(DevicePort::Slcan(SlcanDevice::new(SerialLine::from_pty(
            pair, name,
        )?)))
    }

    /// Waits for the next frame for the node. Cancel-safe.
    ///
    /// # Errors
    /// [`LinkError::HangUp`] when the host closed the line; other link errors.
    pub async fn recv(&mut self) -> LinkResult<CanFrame> {
        match self {
            DevicePort::Slcan(device) => device.recv().await,
            DevicePort::SocketCan(port) => port.recv().await,
        }
    }

    /// Sends a frame from the node (dropped on a closed SLCAN channel, as an adapter would).
    ///
    /// # Errors
    /// Link errors.
    pub async fn send(&mut self, frame: &CanFrame) -> LinkResult<()> {
        match self {
            DevicePort::Slcan(device) => device.send(frame).await,
            DevicePort::SocketCan(port) => port.send(frame).await,
        }
    }

    /// What the port saw that was not a frame.
    #[must_use]
    pub fn counters(&self) -> PortCounters {
        match self {
            DevicePort::Slcan(device) => PortCounters {
                malformed_lines: device.malformed_lines,
            },
            DevicePort::SocketCan(_) => PortCounters::default(),
        }
    }
}

impl SlcanDevice {
    fn new(line: SerialLine) -> SlcanDevice {
        SlcanDevice {
            line,
            decoder: SlcanDecoder::new(),
            received: VecDeque::new(),
            open: false,
            malformed_lines: 0,
        }
    }

    async fn recv(&mut self) -> LinkResult<CanFrame> {
        let mut buf = [0u8; 4096];
        loop {
            if let Some(frame) = self.received.pop_front() {
                return Ok(frame);
            }
            let n = self.line.read(&mut buf).await?;
            let mut replies = String::new();
            for event in self.decoder.push(&buf[..n]) {
                match event {
                    Ok(SlcanMessage::Frame(frame)) if self.open => self.received.push_back(frame),
                    Ok(SlcanMessage::Open) => {
                        self.open = true;
                        replies.push('\r');
                    }
                    Ok(SlcanMessage::Close) => {
                        self.open = false;
                        replies.push('\r');
                    }
                    Ok(SlcanMessage::Bitrate(_)) => replies.push('\r'),
                    Ok(SlcanMessage::VersionRequest) => {
                        replies += &SlcanMessage::Version(SLCAN_VERSION.into()).encode();
                    }
                    Ok(SlcanMessage::SerialRequest) => {
                        replies += &SlcanMessage::Serial(SLCAN_SERIAL.into()).encode();
                    }
                    // Frames on a closed channel, replies sent to a device, and garbage.
                    Ok(_) | Err(_) => {
                        self.malformed_lines += 1;
                        replies += &SlcanMessage::Nack.encode();
                    }
                }
            }
            if !replies.is_empty() {
                self.line.write_all(replies.as_bytes()).await?;
            }
        }
    }

    async fn send(&mut self, frame: &CanFrame) -> LinkResult<()> {
        if self.open {
            self.line.write_all(encode_frame(frame).as_bytes()).await
        } else {
            Ok(())
        }
    }
}
