//! SLCAN over a serial line, both ends: the host opens and drives an adapter (a CANable on
//! `/dev/ttyACM0`, a Lawicel CANUSB, or the emulator on a pty); the device end behaves as one
//! of those adapters ([`device::EmulatedAdapter`]).
//!
//! Host ([`host`]): real adapters differ in what they answer. A CANable 2.x answers no command
//! at all, a Lawicel adapter answers CR or BEL and acknowledges each frame with `z`, may stamp
//! every received frame with 4 hex digits of milliseconds, and Linux-driver-style adapters
//! report their bus state in `s` and `e` lines. The host therefore requires no reply: it waits
//! briefly ([`REPLY_WINDOW`]) after each command and takes a CR or silence as done and a BEL as
//! a refusal; an adapter that has answered once is waited for longer ([`REPLY_TIMEOUT`]) and
//! its silence is an error. On open it sends `C`, then `Sn` only when the link names a bit rate
//! (otherwise the adapter's own setting is kept), then `O`; on a Lawicel adapter also `F` once
//! open. Stamped frames are placed on the host's clock ([`crate::slcan::adapter_clock`]);
//! `Fxx`, `s` and `e` lines go into the link's bus status, and an adapter's bus-off ends the
//! next receive with [`LinkError::BusOff`], as on SocketCAN. Free-text lines (a CANable's
//! version) are counted and kept, transmit acknowledgements swallowed; an unsolicited BEL
//! means the adapter refused a frame and is returned as an error by the next receive.
//!
//! Closing: a host whose channel is open always sends `C` at the end, so a real adapter is not
//! left open on the bus. [`SlcanPort::close`] sends it and waits briefly for an answer;
//! dropping a port whose channel is still open writes `C` once, without waiting, as a
//! fallback (see the `Drop` impl for its limits).
//!
//! Device ([`device`]): answers as the adapter it plays. A device asked to
//! ([`SlcanPort::end_run_on_close`]) reports the host's `C` on an open channel as
//! [`LinkError::ChannelClosed`] from its next receive: the emulator ends its run there, as on a
//! hang-up.
//!
//! Malformed lines (garbage) cost one line: the protocol's decoder resynchronises at the next
//! CR; they are counted in [`SlcanCounters`].

pub mod device;
pub mod host;

use std::collections::VecDeque;
use std::time::Duration;

use tokio::time::Instant;

use super::arrival::{Arrival, ArrivalSource};
use super::error::{LinkError, LinkResult};
use super::line::SerialLine;
use crate::can::CanFrame;
use crate::slcan::adapter_clock::stamp_at;
use crate::slcan::bus_status::AdapterBusStatus;
use crate::slcan::family::AdapterFamily;
use crate::slcan::{SlcanDecoder, SlcanEvent, SlcanMessage, encode_frame, encode_stamped_frame};
use device::{DeviceState, EmulatedAdapter};
use host::HostState;

/// How long the host waits for the answer to a command from an adapter not known to answer
/// (a CANable answers none): a CR or silence within it is success, a BEL a refusal.
pub const REPLY_WINDOW: Duration = Duration::from_millis(100);
/// How long the host waits for the answer of an adapter that has answered before; silence
/// then is an error ([`LinkError::NoReply`]).
pub const REPLY_TIMEOUT: Duration = Duration::from_secs(1);
/// How long [`SlcanPort::close`] waits for the CR to `C` from an adapter that answers:
/// bounded, so an end of run (or an error path) never hangs on a frozen adapter.
pub const CLOSE_REPLY_TIMEOUT: Duration = Duration::from_millis(500);
/// How long [`SlcanPort::send_raw_line`] waits for the device's answer to a raw line.
pub const RAW_LINE_REPLY_TIMEOUT: Duration = Duration::from_millis(200);
/// The longest raw line [`SlcanPort::send_raw_line`] sends (a few times the longest SLCAN
/// line, enough to test a device's line-length cap).
pub const MAX_RAW_LINE_LEN: usize = 4 * crate::slcan::MAX_LINE_LEN;
/// Bytes read from the line at a time.
const READ_CHUNK: usize = 4096;

pub use device::{DEVICE_SERIAL, DEVICE_VERSION};

/// Counts of what crossed and what went wrong on an SLCAN line, for reports and conformance
/// checks.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct SlcanCounters {
    /// Lines that did not parse, or messages the other end should not have sent.
    pub malformed_lines: u64,
    /// The last of those, described.
    pub last_malformed: Option<String>,
    /// Frames the adapter refused with BEL (host), or frames the host sent while the channel
    /// was closed (device).
    pub refused_frames: u64,
    /// Frames the device dropped because the host had not opened the channel.
    pub dropped_while_closed: u64,
    /// Host: commands the adapter did not answer within [`REPLY_WINDOW`] (all of them on a
    /// CANable).
    pub unanswered_commands: u64,
    /// Host: transmit acknowledgements received (`z`, `Z`, or a bare CR).
    pub transmit_acks: u64,
    /// Host: frames that carried the adapter's receive timestamp.
    pub stamped_frames: u64,
    /// Host: free-text lines received (a CANable's version reply).
    pub text_lines: u64,
    /// The last of those.
    pub last_text: Option<String>,
    /// Host: what the adapter said about its bus (`Fxx`, `s` and `e` lines).
    pub bus: AdapterBusStatus,
}

impl SlcanCounters {
    fn malformed(&mut self, description: String) {
        self.malformed_lines += 1;
        self.last_malformed = Some(description);
    }
}

/// Which end this port is, with that end's state.
#[derive(Debug)]
enum End {
    Host(HostState),
    Device(DeviceState),
}

/// One end of an SLCAN line.
#[derive(Debug)]
pub struct SlcanPort {
    line: SerialLine,
    end: End,
    decoder: SlcanDecoder,
    frames: VecDeque<(CanFrame, Arrival)>,
    /// Bytes to write before anything else (replies of the device role, frames being sent).
    pending_tx: Vec<u8>,
    /// An error to report on the next receive (host: an unsolicited BEL, a bus-off; device:
    /// the host's `C`).
    pending_error: Option<LinkError>,
    /// Where the adapter clock's times start (host: the stamps' mapping; device: its stamps).
    origin: Instant,
    counters: SlcanCounters,
}

impl SlcanPort {
    /// The host end on `line`: opens the adapter of `family` (`C`, `Sn` when `bitrate` is
    /// given, `O`).
    ///
    /// # Errors
    /// [`LinkError::AdapterRefused`] naming the command an adapter answered with BEL,
    /// [`LinkError::NoReply`] when an adapter that answers fell silent, [`LinkError::Uri`]-like
    /// [`LinkError::Unsupported`] for a bit rate the family cannot set, or a line error.
    pub async fn host(
        line: SerialLine,
        family: AdapterFamily,
        bitrate: Option<u32>,
    ) -> LinkResult<Self> {
        let mut port = Self::on_line(line, End::Host(HostState::new(family)));
        port.open_channel(bitrate).await?;
        Ok(port)
    }

    /// The device end on `line`, playing `adapter`; it waits for the host.
    #[must_use]
    pub fn device(line: SerialLine, adapter: EmulatedAdapter) -> Self {
        Self::on_line(line, End::Device(DeviceState::new(adapter)))
    }

    fn on_line(line: SerialLine, end: End) -> Self {
        SlcanPort {
            line,
            end,
            decoder: SlcanDecoder::new(),
            frames: VecDeque::new(),
            pending_tx: Vec::new(),
            pending_error: None,
            origin: Instant::now(),
            counters: SlcanCounters::default(),
        }
    }

    /// The line's name (the link URI).
    #[must_use]
    pub fn name(&self) -> &str {
        self.line.name()
    }

    /// Whether the channel is open (host: we opened it; device: the host opened it).
    #[must_use]
    pub fn channel_open(&self) -> bool {
        match &self.end {
            End::Host(host) => host.channel_open,
            End::Device(device) => device.channel_open(),
        }
    }

    /// The CAN bit rate set on the channel, bit/s: host, the rate this link set with `Sn`
    /// (`None`: the adapter's own setting was kept); device, the rate the host last set.
    #[must_use]
    pub fn bitrate(&self) -> Option<u32> {
        match &self.end {
            End::Host(host) => host.bitrate,
            End::Device(device) => device.bitrate(),
        }
    }

    /// The adapter family whose bit-rate table the link uses.
    #[must_use]
    pub fn family(&self) -> AdapterFamily {
        match &self.end {
            End::Host(host) => host.family,
            End::Device(device) => device.adapter().family(),
        }
    }

    /// Host: whether the adapter has answered a command (`None`: no command was waited for
    /// yet; `Some(false)`: it stayed silent, as a CANable does).
    #[must_use]
    pub fn adapter_answers(&self) -> Option<bool> {
        match &self.end {
            End::Host(host) => host.answers,
            End::Device(_) => None,
        }
    }

    /// What went wrong so far.
    #[must_use]
    pub fn counters(&self) -> &SlcanCounters {
        &self.counters
    }

    /// Device: from now on, report the host's `C` on an open channel as
    /// [`LinkError::ChannelClosed`] from the next receive (after the frames received before
    /// it). Host: no effect.
    pub fn end_run_on_close(&mut self) {
        if let End::Device(device) = &mut self.end {
            device.end_run_on_close();
        }
    }

    /// Device: plays `adapter` from now on (before the host has sent anything). Host: no
    /// effect.
    pub fn play_adapter(&mut self, adapter: EmulatedAdapter) {
        if let End::Device(device) = &mut self.end {
            let mut state = DeviceState::new(adapter);
            if device.ends_run_on_close() {
                state.end_run_on_close();
            }
            *device = state;
        }
    }

    /// Sends one frame. Host: refused while the channel is closed. Device: dropped (and
    /// counted) while the host has not opened the channel.
    ///
    /// # Errors
    /// [`LinkError::Protocol`] (host, channel closed), or a line error.
    pub async fn send(&mut self, frame: &CanFrame) -> LinkResult<bool> {
        let delivered = self.queue(frame)?;
        self.flush().await?;
        Ok(delivered)
    }

    /// Queues one frame's line behind what is pending, without writing: [`SlcanPort::flush`]
    /// (or the next send or receive) writes them all at once. Returns whether the frame will
    /// go out; the rules are [`SlcanPort::send`]'s. A device playing an adapter with
    /// timestamps on stamps it with the time since the device started.
    ///
    /// # Errors
    /// [`LinkError::Protocol`] (host, channel closed).
    pub fn queue(&mut self, frame: &CanFrame) -> LinkResult<bool> {
        let line = match &self.end {
            End::Host(host) if host.channel_open => encode_frame(frame),
            End::Host(_) => {
                return Err(LinkError::Protocol {
                    link: self.name().to_owned(),
                    detail: "cannot send: the SLCAN channel is closed".to_owned(),
                });
            }
            End::Device(device) if !device.channel_open() => {
                self.counters.dropped_while_closed += 1;
                return Ok(false);
            }
            End::Device(device) if device.timestamps() => {
                encode_stamped_frame(frame, stamp_at(self.origin.elapsed()))
            }
            End::Device(_) => encode_frame(frame),
        };
        self.pending_tx.extend_from_slice(line.as_bytes());
        Ok(true)
    }

    /// Bytes the line has taken so far (see [`SerialLine::bytes_written`]).
    #[must_use]
    pub fn bytes_written(&self) -> u64 {
        self.line.bytes_written()
    }

    /// Writes every queued line and the bytes still waiting (frames whose send was cut short,
    /// replies), waiting while the line is full: one `write` when the line takes them all.
    /// Cancel-safe: what is not written stays waiting.
    ///
    /// # Errors
    /// A line error ([`LinkError::HangUp`] when the peer is gone).
    pub async fn flush(&mut self) -> LinkResult<()> {
        self.line.flush_pending(&mut self.pending_tx).await
    }

    /// Whether a frame (or a pending error) is there for the next receive without reading.
    #[must_use]
    pub fn has_ready(&self) -> bool {
        !self.frames.is_empty() || self.pending_error.is_some()
    }

    /// Waits for the next frame and its arrival. Cancel-safe.
    ///
    /// # Errors
    /// A line error; host: [`LinkError::AdapterRefused`] after an unsolicited BEL,
    /// [`LinkError::BusOff`] after the adapter reported bus-off; device:
    /// [`LinkError::ChannelClosed`] (see [`SlcanPort::end_run_on_close`]).
    pub async fn recv(&mut self) -> LinkResult<(CanFrame, Arrival)> {
        loop {
            if let Some(frame) = self.take_ready()? {
                return Ok(frame);
            }
            self.fill().await?;
        }
    }

    /// The next frame if one has arrived, without waiting.
    ///
    /// # Errors
    /// As [`SlcanPort::recv`].
    pub fn try_recv(&mut self) -> LinkResult<Option<(CanFrame, Arrival)>> {
        if let Some(frame) = self.take_ready()? {
            return Ok(Some(frame));
        }
        let mut buf = [0; READ_CHUNK];
        while let Some(n) = self.line.try_read(&mut buf)? {
            let read_at = Instant::now();
            let events = self.decoder.push(&buf[..n]);
            self.absorb(events, read_at);
        }
        // Device replies to what was just read (the rest goes out with the next call).
        self.line.try_flush_pending(&mut self.pending_tx)?;
        self.take_ready()
    }

    /// The next queued frame; once none is left, a pending error.
    fn take_ready(&mut self) -> LinkResult<Option<(CanFrame, Arrival)>> {
        match self.frames.pop_front() {
            Some(frame) => Ok(Some(frame)),
            None => self.pending_error.take().map_or(Ok(None), Err),
        }
    }

    /// Writes what is pending, then reads one chunk and absorbs it.
    async fn fill(&mut self) -> LinkResult<()> {
        self.line.flush_pending(&mut self.pending_tx).await?;
        let mut buf = [0; READ_CHUNK];
        let n = self.line.read(&mut buf).await?;
        let read_at = Instant::now();
        let events = self.decoder.push(&buf[..n]);
        self.absorb(events, read_at);
        self.line.flush_pending(&mut self.pending_tx).await
    }

    /// Takes the messages of one read, made at `read_at`.
    fn absorb(&mut self, events: Vec<SlcanEvent>, read_at: Instant) {
        for event in events {
            match event {
                Ok(message) => match &mut self.end {
                    End::Host(_) => self.absorb_as_host(message, read_at),
                    End::Device(device) => {
                        let reaction = device.on_message(message, &mut self.counters);
                        if let Some(frame) = reaction.deliver {
                            self.frames.push_back((frame, Arrival::read(read_at)));
                        }
                        if reaction.ends_run {
                            self.pending_error = Some(LinkError::ChannelClosed {
                                link: self.line.name().to_owned(),
                            });
                        }
                        if let Some(answer) = reaction.answer {
                            self.reply(&answer);
                        }
                    }
                },
                Err(error) => {
                    self.counters.malformed(error.to_string());
                    if let End::Device(device) = &self.end
                        && let Some(answer) = device.on_malformed()
                    {
                        self.reply(&answer);
                    }
                }
            }
        }
    }

    /// Host: files a received frame (stamped or not) while the channel is open.
    fn receive_frame(&mut self, frame: CanFrame, stamp_ms: Option<u16>, read_at: Instant) {
        let End::Host(host) = &mut self.end else {
            return;
        };
        let arrival = match stamp_ms {
            None => Arrival::read(read_at),
            Some(stamp_ms) => {
                self.counters.stamped_frames += 1;
                let since = read_at.saturating_duration_since(self.origin);
                let on_bus = host.clock.on_bus_at(stamp_ms, since);
                Arrival {
                    read_at,
                    on_bus_at: self.origin + on_bus,
                    source: ArrivalSource::Adapter,
                }
            }
        };
        if host.channel_open {
            self.frames.push_back((frame, arrival));
        }
    }

    fn reply(&mut self, answer: &SlcanMessage) {
        self.pending_tx
            .extend_from_slice(answer.encode().as_bytes());
    }
}

/// The fallback close: a host whose channel is still open writes `C` once, without waiting
/// and ignoring every error, so an adapter is closed even when the session ended by an error
/// or a panic that skipped [`SlcanPort::close`]. When a frame was left half written (a
/// cancelled send), a CR first ends that line so the `C` stands on its own.
///
/// Limits (why [`SlcanPort::close`] is the normal path): the write is one non-blocking attempt,
/// so a full output buffer loses the `C`; and on a pty master the kernel discards what the
/// slave end has not read yet when the master closes, so a peer program may never see it (a
/// real adapter, opened by path, gets it).
impl Drop for SlcanPort {
    fn drop(&mut self) {
        let End::Host(host) = &mut self.end else {
            return;
        };
        if !host.channel_open {
            return;
        }
        host.channel_open = false;
        let mut bytes = if self.pending_tx.is_empty() {
            Vec::new()
        } else {
            b"\r".to_vec()
        };
        bytes.extend_from_slice(SlcanMessage::Close.encode().as_bytes());
        let _ = self.line.try_flush_pending(&mut bytes);
    }
}
