//! [`CanLink`]: one CAN link whatever the transport (SocketCAN or SLCAN over a serial line or
//! pty), with the loop's receive calls, a watchdog-guarded receive and a candump capture.
//! Frames are delivered in the order they arrived, one link at a time.

use std::time::Duration;

use super::capture::CanCapture;
use super::error::{LinkError, LinkResult};
use super::line::SerialLine;
use super::pty::PtyPair;
use super::role::Role;
use super::slcan::{SlcanCounters, SlcanPort};
use super::socketcan::SocketCanPort;
use super::uri::{LinkUri, SLCAN_DEFAULT_BITRATE, SLCAN_SERIAL_BAUD};
use super::watchdog::{LinkTimeout, Watchdog};
use crate::can::CanFrame;
use crate::slcan::SlcanBitrate;

/// Traffic and trouble on a CAN link so far.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Frames sent.
    pub frames_sent: u64,
    /// Frames received.
    pub frames_received: u64,
    /// SLCAN only: malformed lines, refused and dropped frames.
    pub slcan: SlcanCounters,
    /// SocketCAN only: error frames from the kernel (bus-off included).
    pub bus_error_frames: u64,
}

/// Why a watched receive ended without a frame.
#[derive(Debug, thiserror::Error)]
pub enum RecvError {
    /// The watchdog's allowance ran out.
    #[error(transparent)]
    Timeout(#[from] LinkTimeout),
    /// The link failed.
    #[error(transparent)]
    Link(#[from] LinkError),
}

#[derive(Debug)]
enum Transport {
    SocketCan(SocketCanPort),
    Slcan(Box<SlcanPort>),
}

/// An open CAN link.
#[derive(Debug)]
pub struct CanLink {
    name: String,
    bus_bitrate: Option<u32>,
    transport: Transport,
    capture: Option<CanCapture>,
    stats: LinkStats,
}

impl CanLink {
    /// Opens the link `uri` names, as `role`. An SLCAN host opens the adapter (`C`, `Sn`,
    /// `O`) before this returns.
    ///
    /// # Errors
    /// [`LinkError::Unsupported`] for an `ild:` URI; otherwise the transport's open errors
    /// (naming the URI and the OS error) or the SLCAN handshake's.
    pub async fn open(uri: &LinkUri, role: Role) -> LinkResult<CanLink> {
        let name = uri.to_string();
        let transport = match uri {
            LinkUri::SocketCan { iface, .. } => {
                Transport::SocketCan(SocketCanPort::open(iface, &name)?)
            }
            LinkUri::Slcan { path, bitrate } => {
                let line = SerialLine::open(path, SLCAN_SERIAL_BAUD, &name)?;
                Transport::Slcan(Box::new(
                    SlcanPort::start(line, role, slcan_bitrate(*bitrate)).await?,
                ))
            }
            LinkUri::Ild { .. } => {
                return Err(LinkError::Unsupported {
                    link: name,
                    detail: "CAN frames over an ILD link (use socketcan: or slcan:)".to_owned(),
                });
            }
        };
        Ok(Self::with_transport(name, uri.bus_bitrate(), transport))
    }

    /// Runs SLCAN as `role` on the master end of `pair` (the peer opens the slave path).
    /// `bitrate` is the CAN bit rate the bus-load check uses and the host sets (`None`: 1 Mbit/s
    /// set, no bus-load check). The link is named `slcan:<slave path>[@bitrate]`.
    ///
    /// # Errors
    /// [`LinkError::Uri`] for a bit rate SLCAN cannot set; the handshake's errors (host).
    pub async fn open_pty(pair: PtyPair, bitrate: Option<u32>, role: Role) -> LinkResult<CanLink> {
        let uri = LinkUri::Slcan {
            path: pair.slave_path().to_owned(),
            bitrate,
        };
        let name = uri.to_string();
        // Re-parse so a bad bit rate gets the same message as on the command line.
        name.parse::<LinkUri>()?;
        let line = SerialLine::from_pty(pair, &name)?;
        let port = SlcanPort::start(line, role, slcan_bitrate(bitrate)).await?;
        Ok(Self::with_transport(
            name,
            bitrate,
            Transport::Slcan(Box::new(port)),
        ))
    }

    fn with_transport(name: String, bus_bitrate: Option<u32>, transport: Transport) -> CanLink {
        CanLink {
            name,
            bus_bitrate,
            transport,
            capture: None,
            stats: LinkStats::default(),
        }
    }

    /// The link's name (its URI), as every error names it.
    #[must_use]
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The bus bit rate to check the loop's bus load against, when the URI gave one.
    #[must_use]
    pub fn bus_bitrate(&self) -> Option<u32> {
        self.bus_bitrate
    }

    /// Records every frame sent or received from now on.
    pub fn set_capture(&mut self, capture: CanCapture) {
        self.capture = Some(capture);
    }

    /// Traffic and trouble so far.
    #[must_use]
    pub fn stats(&self) -> LinkStats {
        let mut stats = self.stats.clone();
        match &self.transport {
            Transport::Slcan(port) => stats.slcan = port.counters().clone(),
            Transport::SocketCan(port) => stats.bus_error_frames = port.error_frames(),
        }
        stats
    }

    /// Whether the channel is open: always for SocketCAN; SLCAN: the host has sent `O` (and
    /// not `C` since).
    #[must_use]
    pub fn channel_open(&self) -> bool {
        match &self.transport {
            Transport::SocketCan(_) => true,
            Transport::Slcan(port) => port.channel_open(),
        }
    }

    /// SLCAN: the bit rate set on the channel (device: the one the host last set with `Sn`).
    #[must_use]
    pub fn slcan_bitrate(&self) -> Option<u32> {
        match &self.transport {
            Transport::SocketCan(_) => None,
            Transport::Slcan(port) => Some(port.bitrate().bits_per_s()),
        }
    }

    /// Sends one frame. On an SLCAN device end whose channel the host has not opened, the
    /// frame is dropped (and counted) as an adapter would; it is not recorded.
    ///
    /// # Errors
    /// The transport's errors, naming the link.
    pub async fn send(&mut self, frame: &CanFrame) -> LinkResult<()> {
        self.queue(frame).await?;
        self.flush().await
    }

    /// Queues one frame behind those queued before, recording it now: SLCAN writes the queued
    /// frames' lines with one `write` at [`CanLink::flush`] (or the next send or receive);
    /// SocketCAN, one frame per `write`, sends it at once. A loop queues a period's frames and
    /// flushes once. The rules are [`CanLink::send`]'s.
    ///
    /// # Errors
    /// The transport's errors, naming the link.
    pub async fn queue(&mut self, frame: &CanFrame) -> LinkResult<()> {
        let delivered = match &mut self.transport {
            Transport::SocketCan(port) => port.send(frame).await.map(|()| true)?,
            Transport::Slcan(port) => port.queue(frame)?,
        };
        if delivered {
            self.stats.frames_sent += 1;
            self.record(frame)?;
        }
        Ok(())
    }

    /// SLCAN: the bytes the line has taken so far, which grow while the peer reads (a peer
    /// that stops reading stops them); SocketCAN: `None` (the kernel takes whole frames).
    #[must_use]
    pub fn bytes_written(&self) -> Option<u64> {
        match &self.transport {
            Transport::SocketCan(_) => None,
            Transport::Slcan(port) => Some(port.bytes_written()),
        }
    }

    /// Writes the frames queued so far and the bytes a cut-short send left waiting, waiting
    /// while the line is full (SocketCAN: nothing waits, the kernel queues whole frames). Cancel-safe. A node that
    /// must never block flushes under a deadline before it queues more, so what waits for a
    /// peer that is not reading stays bounded.
    ///
    /// # Errors
    /// The transport's errors ([`LinkError::HangUp`] when the other end went away).
    pub async fn flush(&mut self) -> LinkResult<()> {
        match &mut self.transport {
            Transport::SocketCan(_) => Ok(()),
            Transport::Slcan(port) => port.flush().await,
        }
    }

    /// Writes the capture's recorded lines now (the link does so itself before it waits for
    /// a frame, see [`super::capture`]).
    ///
    /// # Errors
    /// [`LinkError::Capture`] naming the link.
    pub fn flush_capture(&mut self) -> LinkResult<()> {
        match &mut self.capture {
            Some(capture) => capture.flush().map_err(|source| LinkError::Capture {
                link: self.name.clone(),
                source,
            }),
            None => Ok(()),
        }
    }

    /// Waits for the next frame. Cancel-safe: a frame is never lost to a dropped future.
    /// Before waiting, the capture writes what it holds.
    ///
    /// # Errors
    /// The transport's errors ([`LinkError::HangUp`] when the other end went away).
    pub async fn recv(&mut self) -> LinkResult<CanFrame> {
        let must_wait = match &self.transport {
            Transport::SocketCan(_) => true,
            Transport::Slcan(port) => !port.has_ready(),
        };
        if must_wait {
            self.flush_capture()?;
        }
        let frame = match &mut self.transport {
            Transport::SocketCan(port) => port.recv().await?,
            Transport::Slcan(port) => port.recv().await?,
        };
        self.received(frame)
    }

    /// Waits up to `timeout` for the next frame; `None` when none came.
    ///
    /// # Errors
    /// As [`CanLink::recv`].
    pub async fn recv_timeout(&mut self, timeout: Duration) -> LinkResult<Option<CanFrame>> {
        match tokio::time::timeout(timeout, self.recv()).await {
            Ok(result) => result.map(Some),
            Err(_elapsed) => Ok(None),
        }
    }

    /// The next frame if one is already there, without waiting.
    ///
    /// # Errors
    /// As [`CanLink::recv`].
    pub fn try_recv(&mut self) -> LinkResult<Option<CanFrame>> {
        let frame = match &mut self.transport {
            Transport::SocketCan(port) => port.try_recv()?,
            Transport::Slcan(port) => port.try_recv()?,
        };
        frame.map(|f| self.received(f)).transpose()
    }

    /// Waits for the next frame for as long as `watchdog` allows, and feeds it on arrival.
    ///
    /// # Errors
    /// [`RecvError::Timeout`] when the link stayed silent for the watchdog's allowance;
    /// [`RecvError::Link`] when it failed.
    pub async fn recv_watched(&mut self, watchdog: &mut Watchdog) -> Result<CanFrame, RecvError> {
        loop {
            if let Some(frame) = self.recv_timeout(watchdog.remaining()).await? {
                watchdog.feed();
                return Ok(frame);
            }
            watchdog.check()?;
        }
    }

    /// Host: closes the SLCAN channel (`C`), keeping the line; SocketCAN: nothing.
    ///
    /// # Errors
    /// The adapter's refusal or silence.
    pub async fn close_channel(&mut self) -> LinkResult<()> {
        match &mut self.transport {
            Transport::SocketCan(_) => Ok(()),
            Transport::Slcan(port) => port.close_channel().await,
        }
    }

    /// Host, at the end of a session (normal end or error path): closes the SLCAN channel if
    /// it is open (`C`, waiting at most
    /// [`CLOSE_REPLY_TIMEOUT`](super::slcan::CLOSE_REPLY_TIMEOUT) for the CR), so a real
    /// adapter is not left open on the bus. SocketCAN, a device end, a closed channel:
    /// nothing. Dropping an open SLCAN host link writes `C` as a best-effort fallback.
    ///
    /// # Errors
    /// The adapter's silence, or a line error (the peer is gone: nothing is left open).
    pub async fn close(&mut self) -> LinkResult<()> {
        match &mut self.transport {
            Transport::SocketCan(_) => Ok(()),
            Transport::Slcan(port) => port.close().await,
        }
    }

    /// Device end of SLCAN: the host's `C` on an open channel ends the session: the next
    /// [`CanLink::recv`] returns [`LinkError::ChannelClosed`] (the emulator treats it like a
    /// hang-up). SocketCAN, or a host end: no effect.
    pub fn end_run_on_close(&mut self) {
        if let Transport::Slcan(port) = &mut self.transport {
            port.end_run_on_close();
        }
    }

    /// Host, for conformance testing only: sends a raw SLCAN line (garbage, a truncated
    /// frame), see [`SlcanPort::send_raw_line`]; returns the device's answer (BEL expected) or
    /// `None` when none came within its wait. Not recorded in the capture (it is no frame).
    ///
    /// # Errors
    /// [`LinkError::Unsupported`] on SocketCAN (no lines there); the SLCAN port's errors.
    pub async fn send_raw_line(
        &mut self,
        line: &[u8],
    ) -> LinkResult<Option<crate::slcan::SlcanMessage>> {
        match &mut self.transport {
            Transport::SocketCan(_) => Err(LinkError::Unsupported {
                link: self.name.clone(),
                detail: "raw SLCAN lines on a SocketCAN interface".to_owned(),
            }),
            Transport::Slcan(port) => port.send_raw_line(line).await,
        }
    }

    /// Host: (re)opens the SLCAN channel at `bitrate` (`C`, `Sn`, `O`); SocketCAN: nothing.
    ///
    /// # Errors
    /// [`LinkError::Unsupported`] for a bit rate SLCAN cannot set; the adapter's refusal or
    /// silence.
    pub async fn open_channel(&mut self, bitrate: u32) -> LinkResult<()> {
        match &mut self.transport {
            Transport::SocketCan(_) => Ok(()),
            Transport::Slcan(port) => {
                let rate = SlcanBitrate::from_bits_per_s(bitrate).ok_or_else(|| {
                    LinkError::Unsupported {
                        link: self.name.clone(),
                        detail: format!("bit rate {bitrate}: SLCAN sets only S0..S8"),
                    }
                })?;
                port.open_channel(rate).await
            }
        }
    }

    /// Host: the SLCAN adapter's version (`V`); `None` on SocketCAN.
    ///
    /// # Errors
    /// The adapter's refusal or silence.
    pub async fn adapter_version(&mut self) -> LinkResult<Option<String>> {
        match &mut self.transport {
            Transport::SocketCan(_) => Ok(None),
            Transport::Slcan(port) => port.version().await.map(Some),
        }
    }

    fn received(&mut self, frame: CanFrame) -> LinkResult<CanFrame> {
        self.stats.frames_received += 1;
        self.record(&frame)?;
        Ok(frame)
    }

    fn record(&mut self, frame: &CanFrame) -> LinkResult<()> {
        match &mut self.capture {
            Some(capture) => capture.record(frame).map_err(|source| LinkError::Capture {
                link: self.name.clone(),
                source,
            }),
            None => Ok(()),
        }
    }
}

/// The `Sn` setting for a URI's bit rate (validated when the URI was parsed); 1 Mbit/s when
/// none was given.
fn slcan_bitrate(bitrate: Option<u32>) -> SlcanBitrate {
    bitrate
        .and_then(SlcanBitrate::from_bits_per_s)
        .unwrap_or(SLCAN_DEFAULT_BITRATE)
}
