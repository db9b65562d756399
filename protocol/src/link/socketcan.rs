//! SocketCAN: a kernel CAN interface (`vcan0`, a real `can0`) through the `socketcan` crate
//! under tokio. The socket is opened in CAN FD mode, so it carries classical and FD frames
//! (FD frames need an FD-capable interface: `ip link set can0 type can bitrate 1000000
//! dbitrate 5000000 fd on`).
//!
//! The socket subscribes to the kernel's error frames (`CAN_ERR_FLAG`): each is classified
//! ([`classify_error_frame`]); bus-off ends the link's receive with [`LinkError::BusOff`]
//! (the controller has left the bus, the run cannot go on), any other error condition
//! (error-passive, no ACK, a protocol violation, a lost arbitration) is counted
//! ([`SocketCanPort::error_frames`]) and receiving goes on.

use std::io;

use socketcan::id::FdFlags;
use socketcan::{
    CanAnyFrame, CanErrorFrame, EmbeddedFrame, ErrorCause, Id, SocketOptions, tokio::CanFdSocket,
};

use super::arrival::Arrival;
use super::error::{LinkError, LinkResult};
use crate::can::{CanFrame, CanId, FrameFormat};

/// An open SocketCAN interface.
#[derive(Debug)]
pub struct SocketCanPort {
    name: String,
    socket: CanFdSocket,
    error_frames: u64,
}

/// What an error frame from the kernel means for the loop.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BusEvent {
    /// The controller went bus-off: it takes no part in the bus any more (the kernel's
    /// description).
    BusOff(String),
    /// Any other error condition: counted, the bus goes on (the kernel's description).
    Error(String),
}

/// Classifies an error frame: bus-off, or another error condition.
#[must_use]
pub fn classify_error_frame(frame: &CanErrorFrame) -> BusEvent {
    let error = frame.into_error();
    let description = error.to_string();
    if error.causes().any(|cause| *cause == ErrorCause::BusOff) {
        BusEvent::BusOff(description)
    } else {
        BusEvent::Error(description)
    }
}

impl SocketCanPort {
    /// Opens `iface` (`name` is the link's URI, for errors).
    ///
    /// # Errors
    /// [`LinkError::Open`] naming the link, the OS error and what to do about it (no such
    /// interface; no CAN in this kernel).
    pub fn open(iface: &str, name: &str) -> LinkResult<Self> {
        let socket = CanFdSocket::open(iface).map_err(|source| LinkError::Open {
            link: name.to_owned(),
            hint: open_hint(iface, &source),
            source,
        })?;
        socket
            .set_error_filter_accept_all()
            .map_err(|source| LinkError::Open {
                link: name.to_owned(),
                hint: "; subscribing to the bus's error frames".to_owned(),
                source,
            })?;
        Ok(SocketCanPort {
            name: name.to_owned(),
            socket,
            error_frames: 0,
        })
    }

    /// Error frames received so far (bus-off included).
    #[must_use]
    pub fn error_frames(&self) -> u64 {
        self.error_frames
    }

    /// Sends one frame, waiting while the socket's queue is full.
    ///
    /// # Errors
    /// [`LinkError::Io`] (e.g. an FD frame on a classical-only interface: "Invalid argument").
    pub async fn send(&self, frame: &CanFrame) -> LinkResult<()> {
        let frame = to_socketcan(frame).ok_or_else(|| LinkError::Unsupported {
            link: self.name.clone(),
            detail: format!("{frame:?}: the socketcan crate rejects it"),
        })?;
        self.socket
            .write_frame(&frame)
            .await
            .map_err(|source| self.io("write", source))
    }

    /// Waits for the next data, remote or FD frame; error frames are counted. Cancel-safe.
    ///
    /// # Errors
    /// [`LinkError::Io`] when the socket fails (interface gone: "Network is down");
    /// [`LinkError::BusOff`] when the controller went bus-off.
    pub async fn recv(&mut self) -> LinkResult<(CanFrame, Arrival)> {
        loop {
            let frame = self
                .socket
                .read_frame()
                .await
                .map_err(|source| self.io("read", source))?;
            if let Some(frame) = self.accept(&frame)? {
                return Ok((frame, Arrival::read(tokio::time::Instant::now())));
            }
        }
    }

    /// A data, remote or FD frame as ours; an error frame counted (bus-off: the error).
    fn accept(&mut self, frame: &CanAnyFrame) -> LinkResult<Option<CanFrame>> {
        if let CanAnyFrame::Error(error) = frame {
            self.error_frames += 1;
            if let BusEvent::BusOff(detail) = classify_error_frame(error) {
                return Err(LinkError::BusOff {
                    link: self.name.clone(),
                    detail,
                });
            }
            return Ok(None);
        }
        Ok(from_socketcan(frame))
    }

    /// The next frame if one is already there, without waiting.
    ///
    /// # Errors
    /// As [`SocketCanPort::recv`].
    pub fn try_recv(&mut self) -> LinkResult<Option<(CanFrame, Arrival)>> {
        loop {
            match self.socket.try_read_frame() {
                Ok(frame) => {
                    if let Some(frame) = self.accept(&frame)? {
                        return Ok(Some((frame, Arrival::read(tokio::time::Instant::now()))));
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return Ok(None),
                Err(e) => return Err(self.io("read", e)),
            }
        }
    }

    fn io(&self, op: &'static str, source: io::Error) -> LinkError {
        LinkError::Io {
            link: self.name.clone(),
            op,
            source,
        }
    }
}

/// What the operator can do about a failed open.
fn open_hint(iface: &str, error: &io::Error) -> String {
    match error.raw_os_error() {
        Some(nix::libc::ENODEV) if iface.starts_with("vcan") => format!(
            "; no network interface `{iface}` (create it: `modprobe vcan; ip link add dev \
             {iface} type vcan; ip link set up {iface}`; on a kernel without CAN run inside \
             ci/vcan-vm.sh)"
        ),
        Some(nix::libc::ENODEV) => format!(
            "; no network interface `{iface}` (a real bus: plug the adapter in, then `ip link \
             set {iface} type can bitrate 1000000; ip link set up {iface}`; a virtual one: \
             `modprobe vcan; ip link add dev {iface} type vcan; ip link set up {iface}`)"
        ),
        Some(nix::libc::EAFNOSUPPORT) => "; this kernel has no CAN support (`modprobe can-raw`); \
             without it use `slcan:` over a pty, or run inside ci/vcan-vm.sh"
            .to_owned(),
        Some(nix::libc::ENETDOWN) => format!("; bring it up: `ip link set up {iface}`"),
        _ => String::new(),
    }
}

/// Our frame as the `socketcan` crate's frame. Our frames are valid by construction, so this
/// is `None` only if the two crates ever disagree on what is valid.
fn to_socketcan(frame: &CanFrame) -> Option<CanAnyFrame> {
    let id = match frame.id() {
        CanId::Standard(id) => Id::Standard(socketcan::StandardId::new(id.as_raw())?),
        CanId::Extended(id) => Id::Extended(socketcan::ExtendedId::new(id.as_raw())?),
    };
    match frame.format() {
        FrameFormat::Classical => socketcan::CanDataFrame::new(id, frame.data()).map(Into::into),
        FrameFormat::Remote => {
            socketcan::CanRemoteFrame::new_remote(id, usize::from(frame.dlc())).map(Into::into)
        }
        FrameFormat::Fd { brs, esi } => {
            let mut flags = FdFlags::empty();
            flags.set(FdFlags::BRS, brs);
            flags.set(FdFlags::ESI, esi);
            socketcan::CanFdFrame::with_flags(id, frame.data(), flags).map(CanAnyFrame::Fd)
        }
    }
}

/// The `socketcan` crate's frame as ours; `None` for error frames.
fn from_socketcan(frame: &CanAnyFrame) -> Option<CanFrame> {
    let id = match frame.id() {
        Id::Standard(id) => CanId::standard(id.as_raw())?,
        Id::Extended(id) => CanId::extended(id.as_raw())?,
    };
    match frame {
        CanAnyFrame::Normal(f) => CanFrame::new(id, f.data()).ok(),
        CanAnyFrame::Remote(f) => CanFrame::new_remote(id, u8::try_from(f.dlc()).ok()?).ok(),
        CanAnyFrame::Fd(f) => CanFrame::new_fd(id, f.data(), f.is_brs(), f.is_esi()).ok(),
        CanAnyFrame::Error(_) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_convert_both_ways() {
        let std_id = CanId::standard(0x123).unwrap();
        let ext_id = CanId::extended(0x1ABC_DEF0).unwrap();
        let frames = [
            CanFrame::new(std_id, &[1, 2, 3]).unwrap(),
            CanFrame::new(ext_id, &[]).unwrap(),
            CanFrame::new_remote(std_id, 4).unwrap(),
            CanFrame::new_fd(ext_id, &[7; 12], true, false).unwrap(),
            CanFrame::new_fd(std_id, &[9; 64], false, true).unwrap(),
        ];
        for frame in frames {
            assert_eq!(from_socketcan(&to_socketcan(&frame).unwrap()), Some(frame));
        }
    }

    /// `CAN_ERR_BUSOFF` in an error frame's id (linux/can/error.h).
    const CAN_ERR_BUSOFF: u32 = 0x40;
    /// `CAN_ERR_CRTL`: controller problems, detailed in data byte 1.
    const CAN_ERR_CRTL: u32 = 0x04;
    /// `CAN_ERR_CRTL_RX_PASSIVE` in data byte 1.
    const CAN_ERR_CRTL_RX_PASSIVE: u8 = 0x10;
    /// `CAN_ERR_ACK`: no acknowledgement on transmission.
    const CAN_ERR_ACK: u32 = 0x20;

    #[test]
    fn bus_off_is_told_apart_from_the_other_error_frames() {
        let bus_off = CanErrorFrame::new_error(CAN_ERR_BUSOFF, &[]).unwrap();
        assert!(matches!(
            classify_error_frame(&bus_off),
            BusEvent::BusOff(text) if text.contains("bus off")
        ));
        let passive =
            CanErrorFrame::new_error(CAN_ERR_CRTL, &[0, CAN_ERR_CRTL_RX_PASSIVE]).unwrap();
        let no_ack = CanErrorFrame::new_error(CAN_ERR_ACK, &[]).unwrap();
        for frame in [passive, no_ack] {
            assert!(
                matches!(classify_error_frame(&frame), BusEvent::Error(_)),
                "{frame:?}"
            );
        }
        // Several causes at once: bus-off wins.
        let both = CanErrorFrame::new_error(CAN_ERR_ACK | CAN_ERR_BUSOFF, &[]).unwrap();
        assert!(matches!(classify_error_frame(&both), BusEvent::BusOff(_)));
    }

    #[test]
    fn error_frames_are_never_taken_for_data() {
        let frame = CanAnyFrame::Error(CanErrorFrame::new_error(CAN_ERR_ACK, &[]).unwrap());
        assert_eq!(from_socketcan(&frame), None);
    }
}
