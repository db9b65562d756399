//! [`CanLink`]: one CAN link whatever the transport (SocketCAN or SLCAN over a serial line or
//! pty), with the loop's receive calls, a watchdog-guarded receive and a candump capture.
//! Frames are delivered in the order they arrived, one link at a time.

use std::time::Duration;

use super::arrival::Arrival;
use super::capture::CanCapture;
use super::error::{LinkError, LinkResult};
use super::line::SerialLine;
use super::pty::PtyPair;
use super::role::Role;
use super::slcan::device::EmulatedAdapter;
use super::slcan::{SlcanCounters, SlcanPort};
use super::socketcan::{SocketCanPort, SocketCanReport};
use super::uri::{LinkUri, SLCAN_SERIAL_BAUD};
use super::watchdog::{LinkTimeout, Watchdog};
use crate::can::CanFrame;
use crate::slcan::family::AdapterFamily;

/// Traffic and trouble on a CAN link so far.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct LinkStats {
    /// Frames sent.
    pub frames_sent: u64,
    /// Frames received.
    pub frames_received: u64,
    /// SLCAN only: malformed lines, refused and dropped frames, what the adapter said.
    pub slcan: SlcanCounters,
    /// Error reports from the bus: SocketCAN's error frames from the kernel, an SLCAN
    /// adapter's `e` lines (a bus-off included either way).
    pub bus_error_frames: u64,
}

/// What a CAN link is and what crossed it, for a run's report.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LinkReport {
    /// The link's URI.
    pub link: String,
    /// `slcan` or `socketcan`.
    pub transport: &'static str,
    /// The bus's bit rate the bus-load check used (the URI's), bit/s.
    pub bus_bitrate: Option<u32>,
    /// SLCAN: the adapter and what the link set on it.
    pub slcan: Option<SlcanReport>,
    /// SocketCAN: the interface as netlink reported it, notes, send retries on a full
    /// transmit queue, frames the kernel dropped.
    pub socketcan: Option<SocketCanReport>,
    /// Traffic and trouble.
    pub stats: LinkStats,
}

/// An SLCAN adapter as the link found and set it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct SlcanReport {
    /// The family whose `Sn` table the link used.
    pub family: AdapterFamily,
    /// The bit rate the link set with `Sn`, bit/s (`None`: the adapter kept its own setting,
    /// which the link cannot read).
    pub bitrate_set: Option<u32>,
    /// Whether the adapter answers commands with CR/BEL (`false`: it stayed silent, as a
    /// CANable does; `None`: no command was waited for).
    pub adapter_answers: Option<bool>,
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
    last_arrival: Option<Arrival>,
}

impl CanLink {
    /// Opens the link `uri` names, as `role`. An SLCAN host opens the adapter (`C`, `Sn` when
    /// the URI names a bit rate, `O`) before this returns; an SLCAN device end plays the
    /// default adapter until told otherwise ([`CanLink::play_slcan_adapter`]).
    ///
    /// # Errors
    /// [`LinkError::Unsupported`] for an `ild:` URI; otherwise the transport's open errors
    /// (naming the URI and the OS error) or the SLCAN handshake's.
    pub async fn open(uri: &LinkUri, role: Role) -> LinkResult<CanLink> {
        let name = uri.to_string();
        let transport = match uri {
            LinkUri::SocketCan { iface, bitrate } => {
                Transport::SocketCan(SocketCanPort::open(iface, &name, *bitrate)?)
            }
            LinkUri::Slcan {
                path,
                bitrate,
                family,
            } => {
                let line = SerialLine::open(path, SLCAN_SERIAL_BAUD, &name)?;
                Transport::Slcan(Box::new(start_slcan(line, role, *family, *bitrate).await?))
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

    /// Runs SLCAN as `role` on the master end of `pair` (the peer opens the slave path),
    /// with the default adapter family. `bitrate` is the CAN bit rate the bus-load check uses
    /// and the host sets (`None`: no `Sn` sent, the adapter keeps its own; no bus-load
    /// check). The link is named `slcan:<slave path>[@bitrate]`.
    ///
    /// # Errors
    /// [`LinkError::Uri`] for a bit rate the family cannot set; the handshake's errors (host).
    pub async fn open_pty(pair: PtyPair, bitrate: Option<u32>, role: Role) -> LinkResult<CanLink> {
        let family = AdapterFamily::default();
        let uri = LinkUri::Slcan {
            path: pair.slave_path().to_owned(),
            bitrate,
            family,
        };
        let name = uri.to_string();
        // Re-parse so a bad bit rate gets the same message as on the command line.
        name.parse::<LinkUri>()?;
        let line = SerialLine::from_pty(pair, &name)?;
        let port = start_slcan(line, role, family, bitrate).await?;
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
            last_arrival: None,
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
            Transport::Slcan(port) => {
                stats.slcan = port.counters().clone();
                stats.bus_error_frames = stats.slcan.bus.error_lines;
            }
            Transport::SocketCan(port) => stats.bus_error_frames = port.error_frames(),
        }
        stats
    }

    /// What the link is and what crossed it so far, for a report.
    #[must_use]
    pub fn report(&self) -> LinkReport {
        let (transport, slcan, socketcan) = match &self.transport {
            Transport::SocketCan(port) => ("socketcan", None, Some(port.report())),
            Transport::Slcan(port) => (
                "slcan",
                Some(SlcanReport {
                    family: port.family(),
                    bitrate_set: port.bitrate(),
                    adapter_answers: port.adapter_answers(),
                }),
                None,
            ),
        };
        LinkReport {
            link: self.name.clone(),
            transport,
            bus_bitrate: self.bus_bitrate,
            slcan,
            socketcan,
            stats: self.stats(),
        }
    }

    /// One line on how the link was opened, for the operator: the adapter's family, the bit
    /// rate set or kept, whether it answers commands.
    #[must_use]
    pub fn open_summary(&self) -> String {
        match &self.transport {
            Transport::SocketCan(port) => {
                let notes = port.report().notes;
                if notes.is_empty() {
                    format!("{}: SocketCAN interface", self.name)
                } else {
                    format!("{}: SocketCAN interface; {}", self.name, notes.join("; "))
                }
            }
            Transport::Slcan(port) => {
                let bitrate = match port.bitrate() {
                    Some(bits) => format!(
                        "bit rate {bits} set with S{}",
                        port.family().code_for(bits).unwrap_or(0)
                    ),
                    None => {
                        "no @BITRATE: the adapter keeps its own bit rate (no Sn sent)".to_owned()
                    }
                };
                let answers = match port.adapter_answers() {
                    Some(true) => "it answers commands",
                    Some(false) => "it answered no command (as a CANable does)",
                    None => "no command waited for",
                };
                format!(
                    "{}: {} SLCAN adapter, {bitrate}; {answers}",
                    self.name,
                    port.family()
                )
            }
        }
    }

    /// When the frame the last receive returned arrived (`None` before the first): its read
    /// time, and when it was on the bus as the kernel or the adapter stamped it.
    #[must_use]
    pub fn last_arrival(&self) -> Option<Arrival> {
        self.last_arrival
    }

    /// Whether the link runs SLCAN (over a serial line or pty).
    #[must_use]
    pub fn is_slcan(&self) -> bool {
        matches!(self.transport, Transport::Slcan(_))
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

    /// SLCAN: the bit rate set on the channel (host: the one this link set with `Sn`, `None`
    /// when it kept the adapter's own; device: the one the host last set). SocketCAN: `None`.
    #[must_use]
    pub fn slcan_bitrate(&self) -> Option<u32> {
        match &self.transport {
            Transport::SocketCan(_) => None,
            Transport::Slcan(port) => port.bitrate(),
        }
    }

    /// Device end of SLCAN: plays `adapter` (its answers, acks, timestamps, bit-rate table)
    /// from now on; call it before the host sends anything. SocketCAN, or a host end: no
    /// effect.
    pub fn play_slcan_adapter(&mut self, adapter: EmulatedAdapter) {
        if let Transport::Slcan(port) = &mut self.transport {
            port.play_adapter(adapter);
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
        let received = match &mut self.transport {
            Transport::SocketCan(port) => port.recv().await?,
            Transport::Slcan(port) => port.recv().await?,
        };
        self.received(received)
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
        let received = match &mut self.transport {
            Transport::SocketCan(port) => port.try_recv()?,
            Transport::Slcan(port) => port.try_recv()?,
        };
        received.map(|r| self.received(r)).transpose()
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

    /// Host: (re)opens the SLCAN channel (`C`, `Sn` when `bitrate` is given, `O`); SocketCAN:
    /// nothing.
    ///
    /// # Errors
    /// [`LinkError::Unsupported`] for a bit rate the adapter's family cannot set; the
    /// adapter's refusal, or the silence of an adapter that answers.
    pub async fn open_channel(&mut self, bitrate: Option<u32>) -> LinkResult<()> {
        match &mut self.transport {
            Transport::SocketCan(_) => Ok(()),
            Transport::Slcan(port) => port.open_channel(bitrate).await,
        }
    }

    /// Host: the SLCAN adapter's version (`V`: a Lawicel `Vhhss`'s text, a CANable's free
    /// text); `None` on SocketCAN or when the adapter answered none.
    ///
    /// # Errors
    /// An answer that is no version; line errors.
    pub async fn adapter_version(&mut self) -> LinkResult<Option<String>> {
        match &mut self.transport {
            Transport::SocketCan(_) => Ok(None),
            Transport::Slcan(port) => port.version().await,
        }
    }

    fn received(&mut self, (frame, arrival): (CanFrame, Arrival)) -> LinkResult<CanFrame> {
        self.stats.frames_received += 1;
        self.last_arrival = Some(arrival);
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

/// SLCAN on `line` as `role`: a host opens the adapter of `family` (at `bitrate` when given),
/// a device end waits for its host.
async fn start_slcan(
    line: SerialLine,
    role: Role,
    family: AdapterFamily,
    bitrate: Option<u32>,
) -> LinkResult<SlcanPort> {
    match role {
        Role::Host => SlcanPort::host(line, family, bitrate).await,
        Role::Device => Ok(SlcanPort::device(line, EmulatedAdapter::default())),
    }
}
