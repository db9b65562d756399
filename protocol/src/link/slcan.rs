//! SLCAN over a serial line, both ends: the host opens and drives an adapter (a CANable on
//! `/dev/ttyACM0`, or the emulator on a pty); the device end answers like such an adapter.
//!
//! Host, on open: `C` (a BEL reply is accepted: the channel was already closed), `Sn` for the
//! bit rate, `O`; each must be answered CR within [`REPLY_TIMEOUT`]. Frames that arrive before
//! the `O` is answered are stale and dropped. On close: `C`. Transmit acknowledgements (`z`,
//! `Z`, bare CR) are swallowed; an unsolicited BEL means the adapter refused a frame and is
//! returned as an error by the next receive.
//!
//! Device: `O` opens the channel (BEL if already open), `L` opens it listen-only (host frames
//! are then refused with BEL), `C` closes it, `Sn` sets the bit rate and `Yn` the FD data bit
//! rate (both BEL while open, as Lawicel adapters do), `V`/`N` answer [`DEVICE_VERSION`] /
//! [`DEVICE_SERIAL`], an empty line (clients send a few CRs to flush the adapter) gets CR. Frames from the host are delivered while the channel is open and answered
//! BEL while it is closed; malformed lines are answered BEL. Frames the device sends while the
//! channel is closed are dropped, as an adapter does with bus traffic nobody asked for. The
//! device does not acknowledge frames (no `z`): the wire stays lean at 20 kHz.
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
        self.command(SlcanMessage::Close, true).await?;
        self.frames.clear();
        self.command(SlcanMessage::Bitrate(bitrate), false).await?;
        self.bitrate = bitrate;
        self.command(SlcanMessage::Open, false).await?;
        self.frames.clear();
        self.channel_open = true;
        Ok(())
    }

    /// Host: closes the channel (`C`). Device: nothing to do.
    ///
    /// # Errors
    /// As [`SlcanPort::start`].
    pub async fn close_channel(&mut self) -> LinkResult<()> {
        if self.role == Role::Host {
            self.channel_open = false;
            self.command(SlcanMessage::Close, true).await?;
        }
        Ok(())
    }

    /// Host: asks the adapter for its version (`V`) and returns the text after the `V`.
    ///
    /// # Errors
    /// As [`SlcanPort::start`], and [`LinkError::Protocol`] for an answer that is no version.
    pub async fn version(&mut self) -> LinkResult<String> {
        match self.command(SlcanMessage::VersionRequest, false).await? {
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
        if !self.channel_open {
            if self.role == Role::Device {
                self.counters.dropped_while_closed += 1;
                self.line.flush_pending(&mut self.pending_tx).await?;
                return Ok(false);
            }
            return Err(LinkError::Protocol {
                link: self.name().to_owned(),
                detail: "cannot send: the SLCAN channel is closed".to_owned(),
            });
        }
        self.pending_tx
            .extend_from_slice(encode_frame(frame).as_bytes());
        self.line.flush_pending(&mut self.pending_tx).await?;
        Ok(true)
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

    /// Host: sends `message` and waits for its reply; BEL is an error unless `bel_ok`.
    async fn command(&mut self, message: SlcanMessage, bel_ok: bool) -> LinkResult<SlcanMessage> {
        let text = message.encode();
        let command = text.trim_end_matches('\r').to_owned();
        self.replies.clear();
        self.awaiting_reply = true;
        self.pending_tx.extend_from_slice(text.as_bytes());
        let exchange = async {
            loop {
                if let Some(reply) = self.replies.pop_front() {
                    return Ok(reply);
                }
                self.fill().await?;
            }
        };
        let outcome = tokio::time::timeout(REPLY_TIMEOUT, exchange).await;
        self.awaiting_reply = false;
        match outcome {
            Err(_elapsed) => Err(LinkError::NoReply {
                link: self.name().to_owned(),
                command,
                waited: REPLY_TIMEOUT,
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
