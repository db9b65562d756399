//! The host end of SLCAN: opening, commanding and closing a real adapter whatever its
//! firmware answers (see the module above for the rules), and filing what it sends.

use std::collections::VecDeque;
use std::time::Duration;

use tokio::time::Instant;

use super::{
    CLOSE_REPLY_TIMEOUT, End, RAW_LINE_REPLY_TIMEOUT, REPLY_TIMEOUT, REPLY_WINDOW, SlcanPort,
};
use crate::link::error::{LinkError, LinkResult};
use crate::slcan::SlcanMessage;
use crate::slcan::adapter_clock::AdapterClock;
use crate::slcan::bus_status::StatusFlags;
use crate::slcan::family::AdapterFamily;

/// The host end's state.
#[derive(Debug)]
pub(super) struct HostState {
    /// The family whose `Sn` table the link uses.
    pub(super) family: AdapterFamily,
    /// The bit rate this link set with `Sn` (`None`: the adapter's own setting).
    pub(super) bitrate: Option<u32>,
    /// Whether we opened the channel (frames are taken only then).
    pub(super) channel_open: bool,
    /// Whether the adapter answers commands with CR or BEL: `None` until one was waited for.
    pub(super) answers: Option<bool>,
    /// The adapter's receive stamps on the host's clock.
    pub(super) clock: AdapterClock,
    /// Replies to the command in flight.
    replies: VecDeque<SlcanMessage>,
    awaiting_reply: bool,
}

impl HostState {
    pub(super) fn new(family: AdapterFamily) -> HostState {
        HostState {
            family,
            bitrate: None,
            channel_open: false,
            answers: None,
            clock: AdapterClock::new(),
            replies: VecDeque::new(),
            awaiting_reply: false,
        }
    }

    /// How long to wait for an answer: briefly from an adapter not known to answer.
    fn reply_wait(&self, answering: Duration) -> Duration {
        if self.answers == Some(true) {
            answering
        } else {
            REPLY_WINDOW
        }
    }
}

impl SlcanPort {
    /// Host: closes the channel (`C`), sets the bit rate (`Sn`, only when `bitrate` is given:
    /// otherwise the adapter keeps its own) and opens it (`O`); on a Lawicel adapter then
    /// reads its status flags (`F`).
    ///
    /// # Errors
    /// [`LinkError::Unsupported`] for a bit rate the family cannot set (naming the ones it
    /// can); [`LinkError::AdapterRefused`] for a BEL to `Sn` or `O`; [`LinkError::NoReply`]
    /// from an adapter that answers but fell silent; line errors; on a device end,
    /// [`LinkError::Protocol`].
    pub async fn open_channel(&mut self, bitrate: Option<u32>) -> LinkResult<()> {
        let family = self.host_mut("open the channel")?.family;
        let code = bitrate
            .map(|bits| {
                family.code_for(bits).ok_or_else(|| LinkError::Unsupported {
                    link: self.name().to_owned(),
                    detail: format!(
                        "bit rate {bits} on a {family} adapter (it sets {})",
                        family.table_text()
                    ),
                })
            })
            .transpose()?;
        self.host_mut("open the channel")?.channel_open = false;
        // BEL to `C` only says the channel was closed already.
        self.command(SlcanMessage::Close, true).await?;
        self.frames.clear();
        if let Some(code) = code {
            self.command(SlcanMessage::Bitrate(code), false).await?;
            self.host_mut("open the channel")?.bitrate = bitrate;
        }
        // Frames the adapter forwards once it has the `O` are the session's.
        self.host_mut("open the channel")?.channel_open = true;
        if let Err(error) = self.command(SlcanMessage::Open, false).await {
            self.host_mut("open the channel")?.channel_open = false;
            return Err(error);
        }
        if family == AdapterFamily::Lawicel {
            self.poll_status().await?;
        }
        Ok(())
    }

    /// Host: closes the channel (`C`), whether or not it is open (to reopen it later).
    /// Device: nothing to do.
    ///
    /// # Errors
    /// As [`SlcanPort::open_channel`].
    pub async fn close_channel(&mut self) -> LinkResult<()> {
        let End::Host(host) = &mut self.end else {
            return Ok(());
        };
        host.channel_open = false;
        self.command(SlcanMessage::Close, true).await.map(drop)
    }

    /// Host, at the end of a session: if the channel is open, reads a Lawicel adapter's
    /// status flags (`F`, for the report), then sends `C` and waits briefly for an answer
    /// (an adapter that answers: at most [`CLOSE_REPLY_TIMEOUT`]; a BEL is accepted: the
    /// adapter is closed either way). The channel counts as closed afterwards even when this
    /// fails, so a later drop does not send `C` again. Device, or a closed channel: nothing
    /// to do.
    ///
    /// # Errors
    /// [`LinkError::NoReply`] when an adapter that answers did not; line errors (a peer that
    /// hung up: nothing is left to close then).
    pub async fn close(&mut self) -> LinkResult<()> {
        let End::Host(host) = &mut self.end else {
            return Ok(());
        };
        if !host.channel_open {
            return Ok(());
        }
        let polled = if host.family == AdapterFamily::Lawicel {
            self.poll_status().await.map(drop)
        } else {
            Ok(())
        };
        if let End::Host(host) = &mut self.end {
            host.channel_open = false;
        }
        let closed = self
            .command_within(SlcanMessage::Close, true, CLOSE_REPLY_TIMEOUT)
            .await
            .map(drop);
        closed.and(polled)
    }

    /// Host: asks for the adapter's status flags (`F`); `None` when it refused or stayed
    /// silent. The flags also go into [`super::SlcanCounters::bus`].
    ///
    /// # Errors
    /// [`LinkError::NoReply`] from an adapter that answers but fell silent, line errors;
    /// [`LinkError::Protocol`] on a device end.
    pub async fn poll_status(&mut self) -> LinkResult<Option<StatusFlags>> {
        self.host_mut("read the status flags")?;
        Ok(
            match self.command(SlcanMessage::StatusRequest, true).await? {
                Some(SlcanMessage::StatusFlags(flags)) => Some(flags),
                _ => None,
            },
        )
    }

    /// Host: asks the adapter for its version (`V`): the text after a Lawicel adapter's `V`,
    /// or a CANable's free-text line; `None` when it refused or stayed silent.
    ///
    /// # Errors
    /// [`LinkError::Protocol`] for an answer that is no version, or on a device end; line
    /// errors.
    pub async fn version(&mut self) -> LinkResult<Option<String>> {
        let wait = self
            .host_mut("ask for the version")?
            .reply_wait(REPLY_TIMEOUT);
        let request = SlcanMessage::VersionRequest.encode().into_bytes();
        match self.exchange(request, "V".to_owned(), true, wait).await? {
            Some(SlcanMessage::Version(text) | SlcanMessage::Text(text)) => Ok(Some(text)),
            None | Some(SlcanMessage::Nack) => Ok(None),
            Some(other) => Err(LinkError::Protocol {
                link: self.name().to_owned(),
                detail: format!("answer to `V` is {other:?}, not a version"),
            }),
        }
    }

    /// Host, for conformance testing only: sends `line` and a CR exactly as given, bypassing
    /// the codec (garbage, a truncated frame, an overlong line), and waits up to
    /// [`RAW_LINE_REPLY_TIMEOUT`] for the device's answer. Returns that answer (an adapter
    /// that answers takes a bad line with BEL, [`SlcanMessage::Nack`]) or `None` when none
    /// came. An adapter that answered none of the commands (a CANable) is not waited for:
    /// the line goes out and `None` comes back at once, so a series of raw lines does not
    /// keep the node's watchdog waiting. The answer is consumed here, so a BEL does not fail
    /// the next receive.
    ///
    /// # Errors
    /// [`LinkError::Protocol`] for a line with a CR in it or longer than
    /// [`super::MAX_RAW_LINE_LEN`], or on a device end; line errors.
    pub async fn send_raw_line(&mut self, line: &[u8]) -> LinkResult<Option<SlcanMessage>> {
        self.host_mut("send raw lines")?;
        if line.contains(&b'\r') || line.len() > super::MAX_RAW_LINE_LEN {
            return Err(LinkError::Protocol {
                link: self.name().to_owned(),
                detail: format!(
                    "a raw line must hold no CR and at most {} bytes (got {})",
                    super::MAX_RAW_LINE_LEN,
                    line.len()
                ),
            });
        }
        let mut text = line.to_vec();
        text.push(b'\r');
        let label = String::from_utf8_lossy(line).into_owned();
        let wait = match self.host_mut("send raw lines")?.answers {
            Some(false) => Duration::ZERO,
            _ => RAW_LINE_REPLY_TIMEOUT,
        };
        // What a zero wait leaves unwritten goes out with the next write.
        self.exchange(text, label, true, wait).await
    }

    /// The host's state, or a protocol error saying a device end cannot `what`.
    fn host_mut(&mut self, what: &str) -> LinkResult<&mut HostState> {
        match &mut self.end {
            End::Host(host) => Ok(host),
            End::Device(_) => Err(LinkError::Protocol {
                link: self.line.name().to_owned(),
                detail: format!("a device end cannot {what} (host end only)"),
            }),
        }
    }

    /// Host: sends `message` and waits for its answer: briefly from an adapter not known to
    /// answer, [`REPLY_TIMEOUT`] from one that has. BEL is an error unless `bel_ok`.
    async fn command(
        &mut self,
        message: SlcanMessage,
        bel_ok: bool,
    ) -> LinkResult<Option<SlcanMessage>> {
        self.command_within(message, bel_ok, REPLY_TIMEOUT).await
    }

    /// [`Self::command`], waiting at most `answering` for an adapter that answers.
    /// Silence from an adapter not known to answer is success (counted); from one that has
    /// answered before, [`LinkError::NoReply`].
    async fn command_within(
        &mut self,
        message: SlcanMessage,
        bel_ok: bool,
        answering: Duration,
    ) -> LinkResult<Option<SlcanMessage>> {
        let text = message.encode();
        let label = text.trim_end_matches('\r').to_owned();
        let wait = self.host_mut("send commands")?.reply_wait(answering);
        let reply = self
            .exchange(text.into_bytes(), label.clone(), bel_ok, wait)
            .await?;
        if reply.is_some() {
            return Ok(reply);
        }
        let host = self.host_mut("send commands")?;
        if host.answers == Some(true) {
            return Err(LinkError::NoReply {
                link: self.name().to_owned(),
                command: label,
                waited: wait,
            });
        }
        host.answers = Some(false);
        self.counters.unanswered_commands += 1;
        Ok(None)
    }

    /// Host: sends `bytes` (one line) and waits up to `wait` for the reply (`None`: none
    /// came); `command` names the line in errors. A BEL is
    /// [`LinkError::AdapterRefused`] unless `bel_ok`.
    async fn exchange(
        &mut self,
        bytes: Vec<u8>,
        command: String,
        bel_ok: bool,
        wait: Duration,
    ) -> LinkResult<Option<SlcanMessage>> {
        let host = self.host_mut("send commands")?;
        host.replies.clear();
        host.awaiting_reply = true;
        self.pending_tx.extend_from_slice(&bytes);
        let exchange = async {
            loop {
                if let End::Host(host) = &mut self.end
                    && let Some(reply) = host.replies.pop_front()
                {
                    return Ok::<_, LinkError>(reply);
                }
                self.fill().await?;
            }
        };
        let outcome = tokio::time::timeout(wait, exchange).await;
        let host = self.host_mut("send commands")?;
        host.awaiting_reply = false;
        let reply = match outcome {
            Err(_elapsed) => return Ok(None),
            Ok(result) => result?,
        };
        // A CR or BEL shows the adapter answers commands; a version text alone does not (a
        // CANable answers `V` and nothing else).
        if matches!(reply, SlcanMessage::Ack | SlcanMessage::Nack) {
            host.answers = Some(true);
        }
        if reply == SlcanMessage::Nack && !bel_ok {
            return Err(LinkError::AdapterRefused {
                link: self.name().to_owned(),
                command,
            });
        }
        Ok(Some(reply))
    }

    /// Host: files one message from the adapter, read at `read_at`.
    pub(super) fn absorb_as_host(&mut self, message: SlcanMessage, read_at: Instant) {
        let End::Host(host) = &mut self.end else {
            return;
        };
        let awaiting = host.awaiting_reply;
        match message {
            SlcanMessage::Frame(frame) => self.receive_frame(frame, None, read_at),
            SlcanMessage::StampedFrame {
                frame,
                timestamp_ms,
            } => self.receive_frame(frame, Some(timestamp_ms), read_at),
            SlcanMessage::StatusFlags(flags) => {
                self.counters.bus.on_flags(flags);
                if awaiting {
                    host.replies.push_back(message);
                }
            }
            SlcanMessage::BusState(report) => {
                if let Some(detail) = self.counters.bus.on_state(report) {
                    self.pending_error = Some(LinkError::BusOff {
                        link: self.line.name().to_owned(),
                        detail,
                    });
                }
            }
            SlcanMessage::BusErrors(errors) => self.counters.bus.on_errors(&errors),
            SlcanMessage::Text(text) => {
                self.counters.text_lines += 1;
                self.counters.last_text = Some(text.clone());
                if awaiting {
                    host.replies.push_back(SlcanMessage::Text(text));
                }
            }
            SlcanMessage::Ack
            | SlcanMessage::Nack
            | SlcanMessage::Version(_)
            | SlcanMessage::Serial(_)
                if awaiting =>
            {
                host.replies.push_back(message);
            }
            SlcanMessage::Nack => {
                self.counters.refused_frames += 1;
                self.pending_error = Some(LinkError::AdapterRefused {
                    link: self.line.name().to_owned(),
                    command: "a transmitted frame".to_owned(),
                });
            }
            // Transmit acknowledgements: `z`, `Z`, or a bare CR from adapters that answer
            // every line.
            SlcanMessage::Ack | SlcanMessage::TransmitAck { .. } => {
                self.counters.transmit_acks += 1;
            }
            other => self
                .counters
                .malformed(format!("unexpected {other:?} from the adapter")),
        }
    }
}
