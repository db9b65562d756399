//! SocketCAN: a kernel CAN interface (`vcan0`, a real `can0`) through the `socketcan` crate
//! under tokio: the crate's blocking socket, non-blocking in an [`AsyncFd`]. The socket is
//! opened in CAN FD mode, so it carries classical and FD frames (FD frames need an FD-capable
//! interface: `ip link set can0 type can bitrate 1000000 dbitrate 5000000 fd on`).
//!
//! The socket subscribes to the kernel's error frames (`CAN_ERR_FLAG`): each is classified
//! ([`classify_error_frame`]); bus-off ends the link's receive with [`LinkError::BusOff`]
//! (the controller has left the bus, the run cannot go on), any other error condition
//! (error-passive, no ACK, a protocol violation, a lost arbitration) is counted
//! ([`SocketCanPort::error_frames`]) and receiving goes on.
//!
//! What the link does beyond frames (the decisions are pure, in [`crate::socketcan`]):
//! - at open, reads the interface through netlink (the crate's `CanInterface`: up, bit rate,
//!   sample point, controller state, error counters) and refuses one that cannot carry the run
//!   ([`interface_state::check`]: another bit rate than the URI's `@BITRATE`, down, bus-off);
//! - stamps each received frame with the kernel's receive time (`SO_TIMESTAMPNS`), its
//!   [`Arrival`];
//! - retries a send the kernel refused with `ENOBUFS` (a full transmit queue), bounded
//!   ([`ENOBUFS_RETRY`]), and counts the retries;
//! - reports the frames the kernel dropped because the socket's receive queue was full (its
//!   `sk_drops`, read with `SO_MEMINFO`: [`drop_count`]).

use std::io;
use std::time::SystemTime;

use socketcan::id::FdFlags;
use socketcan::nl::{CanInterface, CanState};
use socketcan::{CanAnyFrame, CanErrorFrame, EmbeddedFrame, ErrorCause, Id, Socket, SocketOptions};
use tokio::io::Interest;
use tokio::io::unix::AsyncFd;
use tokio::time::Instant;

use super::arrival::Arrival;
use super::error::{LinkError, LinkResult};
use super::line::register;
use crate::can::{CanFrame, CanId, FrameFormat};
use crate::socketcan::drop_count::{self, DropCount};
use crate::socketcan::interface_state::{
    self, ControllerState, ErrorCounters, ExpectedBitrate, InterfaceReading,
};
use crate::socketcan::send_retry::{ENOBUFS_RETRY, NextStep, RetryCounts};

/// An open SocketCAN interface.
#[derive(Debug)]
pub struct SocketCanPort {
    name: String,
    socket: AsyncFd<socketcan::CanFdSocket>,
    error_frames: u64,
    send_retries: RetryCounts,
    interface: Option<InterfaceReading>,
    notes: Vec<String>,
    drops: Option<DropCount>,
}

/// What a SocketCAN link found and did beyond its frames, for a run's report.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct SocketCanReport {
    /// The interface as netlink reported it at open (`None`: netlink could not be read, see
    /// `notes`).
    pub interface: Option<InterfaceReading>,
    /// What could not be checked, or deserves a look (a vcan's missing bit rate, an
    /// error-passive controller, an unreadable counter).
    pub notes: Vec<String>,
    /// Sends the kernel refused with `ENOBUFS` (a full transmit queue) and their retries.
    pub send_retries: RetryCounts,
    /// Frames the kernel dropped since the socket opened because its receive queue was full
    /// (`None`: the counter could not be read, see `notes`).
    pub dropped_frames: Option<u32>,
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
    /// Opens `iface` (`name` is the link's URI, for errors), expecting the bus at `bitrate`
    /// when the URI gave one.
    ///
    /// # Errors
    /// [`LinkError::Open`] naming the link, the OS error and what to do about it (no such
    /// interface; no CAN in this kernel); [`LinkError::Interface`] for an interface that
    /// cannot carry the run ([`interface_state::check`]).
    pub fn open(iface: &str, name: &str, bitrate: Option<u32>) -> LinkResult<Self> {
        let open_error = |hint: String| {
            let link = name.to_owned();
            move |source: io::Error| LinkError::Open { link, source, hint }
        };
        let socket = socketcan::CanFdSocket::open(iface)
            .map_err(|source| open_error(open_hint(iface, &source))(source))?;
        socket.set_error_filter_accept_all().map_err(open_error(
            "; subscribing to the bus's error frames".to_owned(),
        ))?;
        socket.set_recv_timestamp(true).map_err(open_error(
            "; asking for receive timestamps (SO_TIMESTAMPNS)".to_owned(),
        ))?;
        socket
            .set_nonblocking(true)
            .map_err(open_error("; making the socket non-blocking".to_owned()))?;
        let mut notes = Vec::new();
        let interface = match read_interface(iface) {
            Ok(reading) => {
                let expected = bitrate.map(|bitrate| ExpectedBitrate {
                    bitrate,
                    source: "the URI's @BITRATE",
                });
                notes = interface_state::check(iface, &reading, expected).map_err(|detail| {
                    LinkError::Interface {
                        link: name.to_owned(),
                        detail,
                    }
                })?;
                Some(reading)
            }
            Err(error) => {
                notes.push(format!(
                    "interface {iface} could not be read through netlink ({error}): its bit \
                     rate and state are not checked"
                ));
                None
            }
        };
        let drops = match dropped_so_far(&socket) {
            Ok(counter) => Some(DropCount::starting_at(counter)),
            Err(error) => {
                notes.push(format!(
                    "the socket's dropped-frame counter could not be read (SO_MEMINFO: {error})"
                ));
                None
            }
        };
        let socket = register(socket).map_err(open_error(
            "; registering the socket with the I/O runtime".to_owned(),
        ))?;
        Ok(SocketCanPort {
            name: name.to_owned(),
            socket,
            error_frames: 0,
            send_retries: RetryCounts::default(),
            interface,
            notes,
            drops,
        })
    }

    /// Error frames received so far (bus-off included).
    #[must_use]
    pub fn error_frames(&self) -> u64 {
        self.error_frames
    }

    /// The interface as read at open, what was noted, the send retries and the frames the
    /// kernel dropped so far.
    #[must_use]
    pub fn report(&self) -> SocketCanReport {
        let dropped_frames = self.drops.and_then(|mut drops| {
            drops.observe(dropped_so_far(self.socket.get_ref()).ok()?);
            Some(drops.dropped())
        });
        SocketCanReport {
            interface: self.interface,
            notes: self.notes.clone(),
            send_retries: self.send_retries,
            dropped_frames,
        }
    }

    /// Sends one frame, waiting while the socket's buffer is full; a full transmit queue
    /// (`ENOBUFS`) is retried as [`ENOBUFS_RETRY`] says.
    ///
    /// # Errors
    /// [`LinkError::QueueFull`] when the queue stayed full; [`LinkError::Io`] (e.g. an FD
    /// frame on a classical-only interface: "Invalid argument").
    pub async fn send(&mut self, frame: &CanFrame) -> LinkResult<()> {
        let frame = to_socketcan(frame).ok_or_else(|| LinkError::Unsupported {
            link: self.name.clone(),
            detail: format!("{frame:?}: the socketcan crate rejects it"),
        })?;
        let mut retries = 0;
        loop {
            let sent = self
                .socket
                .async_io(Interest::WRITABLE, |socket| socket.write_frame(&frame))
                .await;
            let queue_full =
                matches!(&sent, Err(e) if e.raw_os_error() == Some(nix::libc::ENOBUFS));
            match ENOBUFS_RETRY.next_step(queue_full, retries) {
                NextStep::Done => {
                    if retries > 0 {
                        self.send_retries.count(retries, sent.is_ok());
                    }
                    return sent.map_err(|source| self.io("write", source));
                }
                NextStep::RetryAfter(wait) => {
                    tokio::time::sleep(wait).await;
                    retries += 1;
                }
                NextStep::GiveUp => {
                    self.send_retries.count(retries, false);
                    return Err(LinkError::QueueFull {
                        link: self.name.clone(),
                        retries,
                        waited: ENOBUFS_RETRY.total_wait(),
                    });
                }
            }
        }
    }

    /// Waits for the next data, remote or FD frame; error frames are counted. Cancel-safe.
    ///
    /// # Errors
    /// [`LinkError::Io`] when the socket fails (interface gone: "Network is down");
    /// [`LinkError::BusOff`] when the controller went bus-off.
    pub async fn recv(&mut self) -> LinkResult<(CanFrame, Arrival)> {
        loop {
            let (frame, stamp) = self
                .socket
                .async_io(Interest::READABLE, Socket::read_frame_with_timestamp)
                .await
                .map_err(|source| self.io("read", source))?;
            if let Some(frame) = self.accept(&frame)? {
                return Ok((frame, kernel_arrival(stamp)));
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

    /// The next frame if one is already there, without waiting (straight to the socket,
    /// whatever the runtime last saw of its readiness).
    ///
    /// # Errors
    /// As [`SocketCanPort::recv`].
    pub fn try_recv(&mut self) -> LinkResult<Option<(CanFrame, Arrival)>> {
        loop {
            match self.socket.get_ref().read_frame_with_timestamp() {
                Ok((frame, stamp)) => {
                    if let Some(frame) = self.accept(&frame)? {
                        return Ok(Some((frame, kernel_arrival(stamp))));
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

/// A frame read now that the kernel stamped `stamp` (wall clock) on receipt.
fn kernel_arrival(stamp: SystemTime) -> Arrival {
    Arrival::kernel(Instant::now(), SystemTime::now(), stamp)
}

/// The interface as netlink reports it.
fn read_interface(iface: &str) -> Result<InterfaceReading, socketcan::Error> {
    let details = CanInterface::open(iface)?.details()?;
    let can = details.can;
    Ok(InterfaceReading {
        is_up: details.is_up,
        bitrate: can.bit_timing.map(|timing| timing.bitrate),
        sample_point_permille: can.bit_timing.map(|timing| timing.sample_point),
        state: can.state.map(|state| match state {
            CanState::ErrorActive => ControllerState::ErrorActive,
            CanState::ErrorWarning => ControllerState::ErrorWarning,
            CanState::ErrorPassive => ControllerState::ErrorPassive,
            CanState::BusOff => ControllerState::BusOff,
            CanState::Stopped => ControllerState::Stopped,
            CanState::Sleeping => ControllerState::Sleeping,
        }),
        error_counters: can.berr_counter.map(|counter| ErrorCounters {
            tx: counter.txerr,
            rx: counter.rxerr,
        }),
    })
}

/// The socket's drop counter (`sk_drops`), through `SO_MEMINFO`.
fn dropped_so_far(socket: &socketcan::CanFdSocket) -> io::Result<u32> {
    let mut meminfo = [0u8; drop_count::SK_MEMINFO_VARS * 4];
    let len = socket.get_socket_option_bytes(
        nix::libc::SOL_SOCKET,
        nix::libc::SO_MEMINFO,
        &mut meminfo,
    )?;
    drop_count::drops_in_meminfo(&meminfo[..len]).ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{len} bytes, too few for the drop counter"),
        )
    })
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
