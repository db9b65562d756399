//! SLCAN over a serial line, both ends: the host opens and drives an adapter (a CANable on
//! `/dev/ttyACM0`, or the emulator on a pty); the device end answers like such an adapter.
//!
//! Host, on open: `C` (a BEL reply is accepted: the channel was already closed), `Sn` for the
//! bit rate, `O`; each must be answered CR within [`REPLY_TIMEOUT`]. Frames that arrive before
//! the `O` is answered are stale and dropped. Transmit acknowledgements (`z`, `Z`, bare CR) are
//! swallowed; an unsolicited BEL means the adapter refused a frame and is returned as an error
//! by the next receive.
//!
//! Closing: a host whose channel is open always sends `C` at the end, so a real adapter is not
//! left open on the bus. [`SlcanPort::close`] sends it and waits (at most
//! [`CLOSE_REPLY_TIMEOUT`]) for the CR; dropping a port whose channel is still open writes `C`
//! once, without waiting, as a fallback (see the `Drop` impl for its limits).
//!
//! Device: `O` opens the channel (BEL if already open), `L` opens it listen-only (host frames
//! are then refused with BEL), `C` closes it, `Sn` sets the bit rate and `Yn` the FD data bit
//! rate (both BEL while open, as Lawicel adapters do), `V`/`N` answer [`DEVICE_VERSION`] /
//! [`DEVICE_SERIAL`], an empty line (clients send a few CRs to flush the adapter) gets CR. Frames from the host are delivered while the channel is open and answered
//! BEL while it is closed; malformed lines are answered BEL. Frames the device sends while the
//! channel is closed are dropped, as an adapter does with bus traffic nobody asked for. The
//! device does not acknowledge frames (no `z`): the wire stays lean at 20 kHz.
//!
//! A device asked to ([`SlcanPort::end_run_on_close`]) reports the host's `C` on an open channel
//! as [`LinkError::ChannelClosed`] from its next receive: the emulator ends its run there, as on
//! a hang-up.
//!
//! Malformed lines (garbage) cost one line: the protocol's decoder resynchronises at the next
//! CR; they are counted in [`SlcanCounters`].

use std::collections::VecDeque;
use std::time::Duration;

use super::error::{LinkError, LinkResult};
use super::line::SerialLine;
use super::role::Role;
use crate::can::CanFrame;
use crate::slcan::{SlcanBitrate, SlcanDecoder, SlcanEvent, SlcanMessage, encode_frame};

/// How long the host waits for the adapter's answer to a command.
pub const REPLY_TIMEOUT: Duration = Duration::from_secs(1);
/// How long [`SlcanPort::close`] waits for the adapter's CR to `C`: bounded, so an end of run
/// (or an error path) never hangs on a frozen adapter.
pub const CLOSE_REPLY_TIMEOUT: Duration = Duration::from_millis(500);
/// How long [`SlcanPort::send_raw_line`] waits for the device's answer to a raw line.
pub const RAW_LINE_REPLY_TIMEOUT: Duration = Duration::from_millis(200);
/// The longest raw line [`SlcanPort::send_raw_line`] sends (a few times the longest SLCAN
/// line, enough to test a device's line-length cap).
pub const MAX_RAW_LINE_LEN: usize = 4 * crate::slcan::MAX_LINE_LEN;
/// What the device end answers to `V` (Lawicel style: hardware 1.0, software 1.3).
pub const DEVICE_VERSION: &str = "1013";
/// What the device end answers to `N`.
pub const DEVICE_SERIAL: &str = "SHIL";
/// Bytes read from the line at a time.
const READ_CHUNK: usize = 4096;

/// Counts of what went wrong on an SLCAN line, for reports and conformance checks.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
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
}

/// One end of an SLCAN line.
#[derive(Debug)]
pub struct SlcanPort {
    line: SerialLine,
    role: Role,
    decoder: SlcanDecoder,
    frames: VecDeque<CanFrame>,
    /// Replies to the host's pending command (host role).
    replies: VecDeque<SlcanMessage>,
    awaiting_reply: bool,
    /// Bytes to write before anything else (replies of the device role, frames being sent).
    pending_tx: Vec<u8>,
    /// An error to report on the next receive (host: an unsolicited BEL).
    pending_error: Option<LinkError>,
    channel_open: bool,
    /// Device: the host opened the channel with `L` (listen-only): its frames are refused.
    listen_only: bool,
    /// Device: report the host's `C` on an open channel as the end of the run.
    end_run_on_close: bool,
    bitrate: SlcanBitrate,
    counters: SlcanCounters,
}

impl SlcanPort {
    /// Starts SLCAN on `line`. A host opens the adapter at `bitrate`; a device waits for the
    /// host (its bit rate is whatever the host sets, `bitrate` until then).
    ///
    /// # Errors
    /// Host: [`LinkError::AdapterRefused`] / [`LinkError::NoReply`] naming the command, or a
    /// line error.
    pub async fn start(line: SerialLine, role: Role, bitrate: SlcanBitrate) -> LinkResult<Self> {
        let mut port = SlcanPort {
            line,
            role,
            decoder: SlcanDecoder::new(),
            frames: VecDeque::new(),
            replies: VecDeque::new(),
            awaiting_reply: false,
            pending_tx: Vec::new(),
            pending_error: None,
            channel_open: false,
            listen_only: false,
            end_run_on_close: false,
            bitrate,
            counters: SlcanCounters::default(),
        };
        if role == Role::Host {
            port.open_channel(bitrate).await?;
        }
        Ok(port)
    }

    /// The line's name (the link URI).
    #[must_use]
    pub fn name(&self) -> &str {
        self.line.name()
    }

    /// Whether the channel is open (host: we opened it; device: the host opened it).
    #[must_use]
    pub fn channel_open(&self) -> bool {
        self.channel_open
    }

    /// The bit rate set on the channel (device: the one the host last set).
    #[must_use]
    pub fn bitrate(&self) -> SlcanBitrate {
        self.bitrate
    }

    /// What went wrong so far.
    #[must_use]
    pub fn counters(&self) -> &SlcanCounters {
        &self.counters
    }

    /// Host: closes the channel (`C`), sets the bit rate (`Sn`) and opens it (`O`).
    ///
    /// # Errors
    /// As [`SlcanPort::start`].
    pub async fn open_channel(&mut self, bitrate: SlcanBitrate) -> LinkResult<()> {
        self.channel_open = false;
        // BEL to `C` only says the channel was closed already.
        self.command(SlcanMessage::Close, true, REPLY_TIMEOUT)
            .await?;
        self.frames.clear();
        self.command(SlcanMessage::Bitrate(bitrate), false, REPLY_TIMEOUT)
            .await?;
        self.bitrate = bitrate;
        self.command(SlcanMessage::Open, false, REPLY_TIMEOUT)
            .await?;
        self.frames.clear();
        self.channel_open = true;
        Ok(())
    }

    /// Host: closes the channel (`C`), whether or not it is open (to reopen it later).
    /// Device: nothing to do.
    ///
    /// # Errors
    /// As [`SlcanPort::start`].
    pub async fn close_channel(&mut self) -> LinkResult<()> {
        if self.role == Role::Host {
            self.channel_open = false;
            self.command(SlcanMessage::Close, true, REPLY_TIMEOUT)
                .await?;
        }
        Ok(())
    }

    /// Host, at the end of a session: if the channel is open, sends `C` and waits at most
    /// [`CLOSE_REPLY_TIMEOUT`] for the adapter's CR (a BEL is accepted: the adapter is closed
    /// either way). The channel counts as closed afterwards even when this fails, so a later
    /// drop does not send `C` again. Device, or a closed channel: nothing to do.
    ///
    /// # Errors
    /// [`LinkError::NoReply`] when the adapter did not answer in time; line errors (a peer
    /// that hung up: nothing is left to close then).
    pub async fn close(&mut self) -> LinkResult<()> {
        if self.role != Role::Host || !self.channel_open {
            return Ok(());
        }
        self.channel_open = false;
        self.command(SlcanMessage::Close, true, CLOSE_REPLY_TIMEOUT)
            .await
            .map(drop)
    }

    /// Device: from now on, report the host's `C` on an open channel as
    /// [`LinkError::ChannelClosed`] from the next receive (after the frames received before
    /// it). The `C` is still answered with CR. Host: no effect.
    pub fn end_run_on_close(&mut self) {
        self.end_run_on_close = true;
    }

    /// Host, for conformance testing only: sends `line` and a CR exactly as given, bypassing
    /// the codec (garbage, a truncated frame, an overlong line), and waits up to
    /// [`RAW_LINE_REPLY_TIMEOUT`] for the device's answer. Returns that answer (an adapter
    /// answers a bad line with BEL, [`SlcanMessage::Nack`]) or `None` when none came. The
    /// answer is consumed here, so a BEL does not fail the next receive.
    ///
    /// # Errors
    /// [`LinkError::Protocol`] for a line with a CR in it or longer than
    /// [`MAX_RAW_LINE_LEN`], or on a device end; line errors.
    pub async fn send_raw_line(&mut self, line: &[u8]) -> LinkResult<Option<SlcanMessage>> {
        let refuse = |detail: String| LinkError::Protocol {
            link: self.name().to_owned(),
            detail,
        };
        if self.role != Role::Host {
            return Err(refuse("raw lines are sent by the host end only".to_owned()));
        }
        if line.contains(&b'\r') || line.len() > MAX_RAW_LINE_LEN {
            return Err(refuse(format!(
                "a raw line must hold no CR and at most {MAX_RAW_LINE_LEN} bytes (got {})",
                line.len()
            )));
        }
        let mut text = line.to_vec();
        text.push(b'\r');
        let label = String::from_utf8_lossy(line).into_owned();
        match self
            .exchange(text, label, true, RAW_LINE_REPLY_TIMEOUT)
            .await
        {
            Ok(reply) => Ok(Some(reply)),
            Err(LinkError::NoReply { .. }) => Ok(None),
            Err(error) => Err(error),
        }
    }

    /// Host: asks the adapter for its version (`V`) and returns the text after the `V`.
    ///
    /// # Errors
    /// As [`SlcanPort::start`], and [`LinkError::Protocol`] for an answer that is no version.
    pub async fn version(&mut self) -> LinkResult<String> {
        match self
            .command(SlcanMessage::VersionRequest, false, REPLY_TIMEOUT)
            .await?
        {
            SlcanMessage::Version(text) => Ok(text),
            other => Err(LinkError::Protocol {
                link: self.name().to_owned(),
                detail: format!("answer to `V` is {other:?}, not a version"),
            }),
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
    /// go out; the rules are [`SlcanPort::send`]'s.
    ///
    /// # Errors
    /// [`LinkError::Protocol`] (host, channel closed).
    pub fn queue(&mut self, frame: &CanFrame) -> LinkResult<bool> {
        if !self.channel_open {
            if self.role == Role::Device {
                self.counters.dropped_while_closed += 1;
                return Ok(false);
            }
            return Err(LinkError::Protocol {
                link: self.name().to_owned(),
                detail: "cannot send: the SLCAN channel is closed".to_owned(),
            });
        }
        self.pending_tx
            .extend_from_slice(encode_frame(frame).as_bytes());
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

    /// Whether a frame (or a pending refusal) is there for the next receive without reading.
    #[must_use]
    pub fn has_ready(&self) -> bool {
        !self.frames.is_empty() || self.pending_error.is_some()
    }

    /// Waits for the next frame. Cancel-safe.
    ///
    /// # Errors
    /// A line error, or (host) [`LinkError::AdapterRefused`] after an unsolicited BEL.
    pub async fn recv(&mut self) -> LinkResult<CanFrame> {
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
    pub fn try_recv(&mut self) -> LinkResult<Option<CanFrame>> {
        if let Some(frame) = self.take_ready()? {
            return Ok(Some(frame));
        }
        let mut buf = [0; READ_CHUNK];
        while let Some(n) = self.line.try_read(&mut buf)? {
            let events = self.decoder.push(&buf[..n]);
            self.absorb(events);
        }
        // Device replies to what was just read (the rest goes out with the next call).
        self.line.try_flush_pending(&mut self.pending_tx)?;
        self.take_ready()
    }

    /// The next queued frame; once none is left, a pending refusal.
    fn take_ready(&mut self) -> LinkResult<Option<CanFrame>> {
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
        let events = self.decoder.push(&buf[..n]);
        self.absorb(events);
        self.line.flush_pending(&mut self.pending_tx).await
    }

    /// Host: sends `message` and waits up to `timeout` for its reply; BEL is an error unless
    /// `bel_ok`.
    async fn command(
        &mut self,
        message: SlcanMessage,
        bel_ok: bool,
        timeout: Duration,
    ) -> LinkResult<SlcanMessage> {
        let text = message.encode();
        let command = text.trim_end_matches('\r').to_owned();
        self.exchange(text.into_bytes(), command, bel_ok, timeout)
            .await
    }

    /// Host: sends `bytes` (one line) and waits up to `timeout` for the reply; `command` names
    /// the line in errors.
    async fn exchange(
        &mut self,
        bytes: Vec<u8>,
        command: String,
        bel_ok: bool,
        timeout: Duration,
    ) -> LinkResult<SlcanMessage> {
        self.replies.clear();
        self.awaiting_reply = true;
        self.pending_tx.extend_from_slice(&bytes);
        let exchange = async {
            loop {
                if let Some(reply) = self.replies.pop_front() {
                    return Ok(reply);
                }
                self.fill().await?;
            }
        };
        let outcome = tokio::time::timeout(timeout, exchange).await;
        self.awaiting_reply = false;
        match outcome {
            Err(_elapsed) => Err(LinkError::NoReply {
                link: self.name().to_owned(),
                command,
                waited: timeout,
            }),
            Ok(Err(error)) => Err(error),
            Ok(Ok(SlcanMessage::Nack)) if !bel_ok => Err(LinkError::AdapterRefused {
                link: self.name().to_owned(),
                command,
            }),
            Ok(Ok(reply)) => Ok(reply),
        }
    }

    fn absorb(&mut self, events: Vec<SlcanEvent>) {
        for event in events {
            match event {
                Ok(message) => match self.role {
                    Role::Host => self.absorb_as_host(message),
                    Role::Device => self.absorb_as_device(message),
                },
                Err(error) => {
                    self.malformed(error.to_string());
                    if self.role == Role::Device {
                        self.reply(&SlcanMessage::Nack);
                    }
                }
            }
        }
    }

    fn absorb_as_host(&mut self, message: SlcanMessage) {
        match message {
            SlcanMessage::Frame(frame) => {
                if self.channel_open {
                    self.frames.push_back(frame);
                }
            }
            SlcanMessage::Ack
            | SlcanMessage::Nack
            | SlcanMessage::Version(_)
            | SlcanMessage::Serial(_)
                if self.awaiting_reply =>
            {
                self.replies.push_back(message);
            }
            SlcanMessage::Nack => {
                self.counters.refused_frames += 1;
                self.pending_error = Some(LinkError::AdapterRefused {
                    link: self.name().to_owned(),
                    command: "a transmitted frame".to_owned(),
                });
            }
            // Transmit acknowledgements: `z`, `Z`, or a bare CR from adapters that answer
            // every line.
            SlcanMessage::Ack | SlcanMessage::TransmitAck { .. } => {}
            other => self.malformed(format!("unexpected {other:?} from the adapter")),
        }
    }

    fn absorb_as_device(&mut self, message: SlcanMessage) {
        let answer = match message {
            SlcanMessage::Frame(frame) if self.channel_open && !self.listen_only => {
                self.frames.push_back(frame);
                return;
            }
            SlcanMessage::Frame(_) => {
                self.counters.refused_frames += 1;
                SlcanMessage::Nack
            }
            SlcanMessage::Open | SlcanMessage::ListenOnly if self.channel_open => {
                SlcanMessage::Nack
            }
            SlcanMessage::Open | SlcanMessage::ListenOnly => {
                self.channel_open = true;
                self.listen_only = message == SlcanMessage::ListenOnly;
                SlcanMessage::Ack
            }
            SlcanMessage::Close => {
                if self.channel_open && self.end_run_on_close {
                    self.pending_error = Some(LinkError::ChannelClosed {
                        link: self.name().to_owned(),
                    });
                }
                self.channel_open = false;
                SlcanMessage::Ack
            }
            SlcanMessage::Bitrate(_) | SlcanMessage::DataBitrate(_) if self.channel_open => {
                SlcanMessage::Nack
            }
            // The emulated bus has no data-phase timing: accepted as an adapter would.
            SlcanMessage::DataBitrate(_) => SlcanMessage::Ack,
            SlcanMessage::Bitrate(rate) => {
                self.bitrate = rate;
                SlcanMessage::Ack
            }
            SlcanMessage::VersionRequest => SlcanMessage::Version(DEVICE_VERSION.to_owned()),
            SlcanMessage::SerialRequest => SlcanMessage::Serial(DEVICE_SERIAL.to_owned()),
            // An empty line: clients (python-can) send a few CRs to flush the adapter's input.
            SlcanMessage::Ack => SlcanMessage::Ack,
            other => {
                self.malformed(format!("unexpected {other:?} from the host"));
                SlcanMessage::Nack
            }
        };
        self.reply(&answer);
    }

    fn reply(&mut self, answer: &SlcanMessage) {
        self.pending_tx
            .extend_from_slice(answer.encode().as_bytes());
    }

    fn malformed(&mut self, description: String) {
        self.counters.malformed_lines += 1;
        self.counters.last_malformed = Some(description);
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
        if self.role != Role::Host || !self.channel_open {
            return;
        }
        self.channel_open = false;
        let mut bytes = if self.pending_tx.is_empty() {
            Vec::new()
        } else {
            b"\r".to_vec()
        };
        bytes.extend_from_slice(SlcanMessage::Close.encode().as_bytes());
        let _ = self.line.try_flush_pending(&mut bytes);
    }
}
