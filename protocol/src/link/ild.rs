//! [`IldLink`]: the ILD 2300's RS422 line, both ends. The host (controller) receives the
//! measured-value stream as output cycles with their arrival times and exchanges ASCII
//! commands; the device end (the emulated sensor) sends cycles and answers commands.
//!
//! The host ends its command lines in CR LF ([`COMMAND_EOL`]); the device end takes CR, LF or
//! CR LF, or LF alone when told to ([`LineEnding`]). The host tells the device's echo of a
//! command apart whatever the device's echo setting ([`IldReplyParser`]).
//!
//! The stream and the command replies share the line. While the host waits for a reply, the
//! bytes go to the protocol's reply parser up to the `->` prompt (bytes with bit 7 set, which
//! ASCII never has, are left out); the rest go to the stream decoder. Value bytes that arrive
//! in the middle of a reply are lost to the stream, so hosts stop the output first
//! (`OUTPUT NONE`), as real hosts do. A valid stream never contains `->` (two L bytes in a
//! row), so values cannot end a reply early.

use std::collections::VecDeque;
use std::time::Duration;

use tokio::time::Instant;

use super::capture::ByteCapture;
use super::error::{LinkError, LinkResult};
use super::line::SerialLine;
use super::pty::PtyPair;
use super::role::Role;
use super::uri::LinkUri;
use crate::ild::IldValue;
use crate::ild::command::{
    COMMAND_EOL, IldCommand, IldCommandError, IldReply, IldReplyParser, LineEnding,
};
use crate::ild::stream::{IldDecoder, encode_cycle};

/// Bytes read from the line at a time.
const READ_CHUNK: usize = 4096;
/// The longest command line the device end accepts; longer lines are refused.
pub const MAX_COMMAND_LINE: usize = 256;
/// The longest raw line [`IldLink::send_raw_command_line`] sends (twice what a device accepts,
/// to test its cap).
pub const MAX_RAW_COMMAND_LINE: usize = 2 * MAX_COMMAND_LINE;

/// Device: the most reply bytes [`IldLink::reply_now`] keeps waiting for a host that does not
/// read them; further replies are dropped.
pub const MAX_QUEUED_REPLY_BYTES: usize = 4096;

/// One output cycle as received: the distance (or error) and the extra values
/// `OUTADD_RS422` enabled, in the sensor's order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IldCycle {
    /// The cycle's first value: a distance or an error code.
    pub distance: IldValue,
    /// The further raw 18-bit values of the cycle (counter, timestamp, ...). Fewer than
    /// configured when bytes were lost (the cycle is then counted as incomplete).
    pub extras: Vec<u32>,
    /// When the bytes that completed the cycle were read.
    pub arrived: Instant,
    /// Byte offset of the cycle's first byte in the received stream.
    pub offset: u64,
}

/// A command line the device end received, with its text (for the reply's echo).
#[derive(Debug, Clone, PartialEq)]
pub struct IldRequest {
    /// The line as received, without CR/LF.
    pub line: String,
    /// The parsed command, or why it is refused (answer with [`IldReply::refusal`]).
    pub command: Result<IldCommand, IldCommandError>,
}

/// What went wrong on an ILD line so far.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct IldCounters {
    /// Bytes the stream decoder skipped to resynchronise.
    pub skipped_bytes: u64,
    /// Times it lost sync.
    pub sync_losses: u64,
    /// Cycles delivered with fewer values than configured.
    pub incomplete_cycles: u64,
    /// Values dropped because the start of their cycle was lost, or because the cycle already
    /// had the configured number of values.
    pub orphan_values: u64,
}

/// One end of an ILD line.
#[derive(Debug)]
pub struct IldLink {
    line: SerialLine,
    role: Role,
    baud: u32,
    assembler: IldCycleAssembler,
    cycles: VecDeque<IldCycle>,
    line_ending: LineEnding,
    reply_parser: Option<IldReplyParser>,
    replies: VecDeque<IldReply>,
    command_line: Vec<u8>,
    requests: VecDeque<IldRequest>,
    pending_tx: Vec<u8>,
    capture: Option<ByteCapture>,
}

/// The host end's stream decoding without I/O: raw bytes in, complete output cycles out
/// (what [`IldLink`] does with the value bytes it reads; an in-memory host uses it directly).
#[derive(Debug)]
pub struct IldCycleAssembler {
    decoder: IldDecoder,
    values_per_cycle: usize,
    partial: Option<IldCycle>,
    counters: IldCounters,
}

impl IldCycleAssembler {
    /// An assembler of cycles of `values_per_cycle` values (1 + the `OUTADD_RS422` values).
    #[must_use]
    pub fn new(values_per_cycle: usize) -> IldCycleAssembler {
        IldCycleAssembler {
            decoder: IldDecoder::new(),
            values_per_cycle: values_per_cycle.max(1),
            partial: None,
            counters: IldCounters::default(),
        }
    }

    /// Values per output cycle; a cycle is delivered as soon as it is complete.
    pub fn set_values_per_cycle(&mut self, values: usize) {
        self.values_per_cycle = values.max(1);
    }

    /// What went wrong so far.
    #[must_use]
    pub fn counters(&self) -> &IldCounters {
        &self.counters
    }

    /// Whether no cycle is half assembled (the next value starts one).
    #[must_use]
    pub fn is_between_cycles(&self) -> bool {
        self.partial.is_none()
    }

    /// Decodes `bytes` (read at `arrived`) and appends the cycles they complete to `cycles`.
    pub fn push(&mut self, bytes: &[u8], arrived: Instant, cycles: &mut VecDeque<IldCycle>) {
        for event in self.decoder.push(bytes) {
            let word = match event {
                Ok(word) => word,
                Err(gap) => {
                    self.counters.sync_losses += 1;
                    self.counters.skipped_bytes += gap.len;
                    continue;
                }
            };
            if word.first_in_cycle {
                if let Some(unfinished) = self.partial.take() {
                    self.counters.incomplete_cycles += 1;
                    cycles.push_back(unfinished);
                }
                self.partial = Some(IldCycle {
                    distance: IldValue::from_raw(word.raw),
                    extras: Vec::new(),
                    arrived,
                    offset: word.offset,
                });
            } else if let (Some(cycle), Some(_)) = (&mut self.partial, word.index_in_cycle) {
                cycle.extras.push(word.raw);
                cycle.arrived = arrived;
            } else {
                self.counters.orphan_values += 1;
            }
            if self
                .partial
                .as_ref()
                .is_some_and(|c| 1 + c.extras.len() >= self.values_per_cycle)
            {
                cycles.extend(self.partial.take());
            }
        }
    }
}

impl IldLink {
    /// Opens the serial port an `ild:` URI names, as `role`.
    ///
    /// # Errors
    /// [`LinkError::Unsupported`] for a CAN URI; the port's open errors.
    pub fn open(uri: &LinkUri, role: Role) -> LinkResult<IldLink> {
        let name = uri.to_string();
        let LinkUri::Ild { path, baud } = uri else {
            return Err(LinkError::Unsupported {
                link: name,
                detail: "the ILD stream over a CAN link (use ild:PATH[@BAUD])".to_owned(),
            });
        };
        Ok(Self::on_line(
            SerialLine::open(path, *baud, &name)?,
            *baud,
            role,
        ))
    }

    /// Runs the ILD line as `role` on the master end of `pair` (the peer opens the slave path),
    /// standing for a line at `baud` (a pty carries any rate; the emulated sensor paces its
    /// bytes at this one). The link is named `ild:<slave path>@<baud>`.
    ///
    /// # Errors
    /// [`LinkError::Open`] when the master cannot be registered with tokio.
    pub fn open_pty(pair: PtyPair, baud: u32, role: Role) -> LinkResult<IldLink> {
        let name = LinkUri::Ild {
            path: pair.slave_path().to_owned(),
            baud,
        }
        .to_string();
        Ok(Self::on_line(
            SerialLine::from_pty(pair, &name)?,
            baud,
            role,
        ))
    }

    fn on_line(line: SerialLine, baud: u32, role: Role) -> IldLink {
        IldLink {
            line,
            role,
            baud,
            assembler: IldCycleAssembler::new(1),
            cycles: VecDeque::new(),
            line_ending: LineEnding::default(),
            reply_parser: None,
            replies: VecDeque::new(),
            command_line: Vec::new(),
            requests: VecDeque::new(),
            pending_tx: Vec::new(),
            capture: None,
        }
    }

    /// The link's name (its URI).
    #[must_use]
    pub fn name(&self) -> &str {
        self.line.name()
    }

    /// What went wrong so far.
    #[must_use]
    pub fn counters(&self) -> &IldCounters {
        self.assembler.counters()
    }

    /// Host: values per output cycle, 1 + the number of `OUTADD_RS422` values (default 1).
    /// A cycle is delivered as soon as it is complete.
    pub fn set_values_per_cycle(&mut self, values: usize) {
        self.assembler.set_values_per_cycle(values);
    }

    /// The line's baud rate (as its URI gives it; [`FACTORY_BAUD`](crate::ild::stream::FACTORY_BAUD)
    /// when the URI names none).
    #[must_use]
    pub fn baud(&self) -> u32 {
        self.baud
    }

    /// Device: how command lines end ([`LineEnding::CrOrLf`] unless told otherwise).
    pub fn set_line_ending(&mut self, ending: LineEnding) {
        self.line_ending = ending;
    }

    /// Records the raw bytes received (and sent, if the capture has a writer for them).
    pub fn set_capture(&mut self, capture: ByteCapture) {
        self.capture = Some(capture);
    }

    /// Host: waits for the next output cycle. Cancel-safe.
    ///
    /// # Errors
    /// Line errors ([`LinkError::HangUp`] when the sensor went away).
    pub async fn recv_cycle(&mut self) -> LinkResult<IldCycle> {
        loop {
            if let Some(cycle) = self.cycles.pop_front() {
                return Ok(cycle);
            }
            self.fill().await?;
        }
    }

    /// Host: waits up to `timeout` for the next output cycle; `None` when none came.
    ///
    /// # Errors
    /// As [`IldLink::recv_cycle`].
    pub async fn recv_cycle_timeout(&mut self, timeout: Duration) -> LinkResult<Option<IldCycle>> {
        match tokio::time::timeout(timeout, self.recv_cycle()).await {
            Ok(result) => result.map(Some),
            Err(_elapsed) => Ok(None),
        }
    }

    /// Host: the next output cycle if one is already there, without waiting.
    ///
    /// # Errors
    /// As [`IldLink::recv_cycle`].
    pub fn try_recv_cycle(&mut self) -> LinkResult<Option<IldCycle>> {
        if self.cycles.is_empty() {
            self.drain_now()?;
        }
        Ok(self.cycles.pop_front())
    }

    /// Host: sends `command` (ending in [`COMMAND_EOL`]) and waits up to `timeout` for its
    /// reply (up to the `->` prompt). A refused command is a reply with `error` set, not an
    /// `Err`.
    ///
    /// # Errors
    /// [`LinkError::NoReply`] naming the command; line errors.
    pub async fn command(
        &mut self,
        command: &IldCommand,
        timeout: Duration,
    ) -> LinkResult<IldReply> {
        self.exchange_line(command.line(), COMMAND_EOL, timeout)
            .await
    }

    /// Host, for conformance testing only: sends `line` and [`COMMAND_EOL`] as given (an
    /// unknown command, a bad parameter, an overlong line) and waits up to `timeout` for the
    /// reply, which should be a refusal. Use [`IldLink::command`] for real commands.
    ///
    /// # Errors
    /// [`LinkError::Protocol`] for a line holding CR or LF or longer than
    /// [`MAX_RAW_COMMAND_LINE`]; otherwise as [`IldLink::command`].
    pub async fn send_raw_command_line(
        &mut self,
        line: &str,
        timeout: Duration,
    ) -> LinkResult<IldReply> {
        if line.contains(['\r', '\n']) || line.len() > MAX_RAW_COMMAND_LINE {
            return Err(LinkError::Protocol {
                link: self.name().to_owned(),
                detail: format!(
                    "a raw command line must hold no CR/LF and at most {MAX_RAW_COMMAND_LINE} \
                     bytes (got {})",
                    line.len()
                ),
            });
        }
        self.exchange_line(line.to_owned(), COMMAND_EOL, timeout)
            .await
    }

    /// Host, for tests of a device's line ending: sends `command` ending in `eol` (`"\r"`,
    /// `"\n"`) instead of [`COMMAND_EOL`], and waits for its reply as [`IldLink::command`].
    ///
    /// # Errors
    /// As [`IldLink::command`].
    pub async fn command_ending_in(
        &mut self,
        command: &IldCommand,
        eol: &str,
        timeout: Duration,
    ) -> LinkResult<IldReply> {
        self.exchange_line(command.line(), eol, timeout).await
    }

    /// Host: sends one command line and its line end and waits for the reply.
    async fn exchange_line(
        &mut self,
        line: String,
        eol: &str,
        timeout: Duration,
    ) -> LinkResult<IldReply> {
        self.replies.clear();
        self.reply_parser = Some(IldReplyParser::new(&line));
        let text = line + eol;
        self.send_bytes(text.as_bytes()).await?;
        let exchange = async {
            loop {
                if let Some(reply) = self.replies.pop_front() {
                    return Ok::<_, LinkError>(reply);
                }
                self.fill().await?;
            }
        };
        let outcome = tokio::time::timeout(timeout, exchange).await;
        self.reply_parser = None;
        outcome.map_err(|_elapsed| LinkError::NoReply {
            link: self.name().to_owned(),
            command: text.trim_end().to_owned(),
            waited: timeout,
        })?
    }

    /// Device: sends one output cycle (raw 18-bit words, the distance first).
    ///
    /// # Errors
    /// Line errors ([`LinkError::HangUp`] when the host went away).
    pub async fn send_cycle(&mut self, raws: &[u32]) -> LinkResult<()> {
        self.queue_cycle(raws)?;
        self.flush().await
    }

    /// Device: queues one output cycle behind what is pending, without writing:
    /// [`IldLink::flush`] (or the next send or receive) writes them all at once.
    ///
    /// # Errors
    /// [`LinkError::Capture`] when recording it failed.
    pub fn queue_cycle(&mut self, raws: &[u32]) -> LinkResult<()> {
        self.queue(&encode_cycle(raws))
    }

    /// Writes everything queued, waiting while the line's buffer is full: one `write` when
    /// the line takes it all.
    ///
    /// # Errors
    /// Line errors ([`LinkError::HangUp`] when the other end went away).
    pub async fn flush(&mut self) -> LinkResult<()> {
        self.line.flush_pending(&mut self.pending_tx).await
    }

    /// Device: writes what is queued if the line takes it now, never waiting; `true` when
    /// nothing is left waiting (the host has read what was sent before). A node that must
    /// never block queues a period's cycles only after `true` and drops them whole otherwise,
    /// so at most one period's cycles (and the replies) are ever queued and a host that stops
    /// reading costs no memory: an RS422 sensor streams whether anyone reads or not.
    ///
    /// # Errors
    /// Line errors ([`LinkError::HangUp`] when the host went away).
    pub fn try_flush(&mut self) -> LinkResult<bool> {
        self.line.try_flush_pending(&mut self.pending_tx)?;
        Ok(self.pending_tx.is_empty())
    }

    /// Device: waits for the next command line. Cancel-safe.
    ///
    /// # Errors
    /// Line errors.
    pub async fn recv_command(&mut self) -> LinkResult<IldRequest> {
        loop {
            if let Some(request) = self.requests.pop_front() {
                return Ok(request);
            }
            self.fill().await?;
        }
    }

    /// Device: the next command line if one has arrived, without waiting.
    ///
    /// # Errors
    /// Line errors.
    pub fn try_recv_command(&mut self) -> LinkResult<Option<IldRequest>> {
        if self.requests.is_empty() {
            self.drain_now()?;
        }
        Ok(self.requests.pop_front())
    }

    /// Device: sends a reply (its lines, then the `->` prompt).
    ///
    /// # Errors
    /// Line errors.
    pub async fn reply(&mut self, reply: &IldReply) -> LinkResult<()> {
        self.send_bytes(reply.encode().as_bytes()).await
    }

    /// Device: queues a reply and writes what the line takes now, without waiting; the rest
    /// goes out ahead of the next cycle, reply, or command poll. For a node that must never
    /// block (the emulator's mirror loop). Returns `false` (the reply dropped, nothing
    /// queued) when [`MAX_QUEUED_REPLY_BYTES`] are already waiting: a host that sends
    /// commands but never reads their replies costs bounded memory.
    ///
    /// # Errors
    /// Line errors ([`LinkError::HangUp`] when the host went away).
    pub fn reply_now(&mut self, reply: &IldReply) -> LinkResult<bool> {
        self.line.try_flush_pending(&mut self.pending_tx)?;
        if self.pending_tx.len() >= MAX_QUEUED_REPLY_BYTES {
            return Ok(false);
        }
        self.queue(reply.encode().as_bytes())?;
        self.line.try_flush_pending(&mut self.pending_tx)?;
        Ok(true)
    }

    async fn send_bytes(&mut self, bytes: &[u8]) -> LinkResult<()> {
        self.queue(bytes)?;
        self.flush().await
    }

    /// Queues `bytes` for sending (behind anything pending) and records them.
    fn queue(&mut self, bytes: &[u8]) -> LinkResult<()> {
        self.pending_tx.extend_from_slice(bytes);
        if let Some(capture) = &mut self.capture {
            capture
                .record_sent(bytes)
                .map_err(|source| LinkError::Capture {
                    link: self.line.name().to_owned(),
                    source,
                })?;
        }
        Ok(())
    }

    /// Writes what is pending and the capture, then waits for input and absorbs it.
    async fn fill(&mut self) -> LinkResult<()> {
        self.line.flush_pending(&mut self.pending_tx).await?;
        self.flush_capture()?;
        let mut buf = [0; READ_CHUNK];
        let n = self.line.read(&mut buf).await?;
        self.absorb(&buf[..n])
    }

    fn drain_now(&mut self) -> LinkResult<()> {
        self.line.try_flush_pending(&mut self.pending_tx)?;
        let mut buf = [0; READ_CHUNK];
        while let Some(n) = self.line.try_read(&mut buf)? {
            self.absorb(&buf[..n])?;
        }
        Ok(())
    }

    /// Writes the capture's recorded bytes now (the link does so itself before it waits for
    /// input, see [`super::capture`]).
    ///
    /// # Errors
    /// [`LinkError::Capture`] naming the link.
    pub fn flush_capture(&mut self) -> LinkResult<()> {
        match &mut self.capture {
            Some(capture) => capture.flush().map_err(|source| LinkError::Capture {
                link: self.line.name().to_owned(),
                source,
            }),
            None => Ok(()),
        }
    }

    fn absorb(&mut self, bytes: &[u8]) -> LinkResult<()> {
        if let Some(capture) = &mut self.capture {
            capture
                .record_received(bytes)
                .map_err(|source| LinkError::Capture {
                    link: self.line.name().to_owned(),
                    source,
                })?;
        }
        match self.role {
            Role::Host => self.absorb_as_host(bytes),
            Role::Device => self.absorb_as_device(bytes),
        }
        Ok(())
    }

    fn absorb_as_host(&mut self, mut bytes: &[u8]) {
        let arrived = Instant::now();
        while let Some(parser) = &mut self.reply_parser {
            let Some((&byte, rest)) = bytes.split_first() else {
                return;
            };
            bytes = rest;
            if !byte.is_ascii() {
                continue;
            }
            if let Some(reply) = parser.push(&[byte]).pop() {
                self.replies.push_back(reply);
                self.reply_parser = None;
            }
        }
        self.assembler.push(bytes, arrived, &mut self.cycles);
    }

    fn absorb_as_device(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            let ends_line = match self.line_ending {
                LineEnding::CrOrLf => byte == b'\r' || byte == b'\n',
                LineEnding::Lf => byte == b'\n',
            };
            if byte == b'\r' && !ends_line {
                // An LF-only device ignores CR.
                continue;
            }
            if ends_line {
                let line = String::from_utf8_lossy(&self.command_line)
                    .trim()
                    .to_owned();
                let overlong = self.command_line.len() > MAX_COMMAND_LINE;
                self.command_line.clear();
                if line.is_empty() {
                    continue;
                }
                let command = if overlong {
                    Err(IldCommandError::UnknownCommand(format!(
                        "line longer than {MAX_COMMAND_LINE} bytes"
                    )))
                } else {
                    IldCommand::parse(&line)
                };
                self.requests.push_back(IldRequest { line, command });
            } else if self.command_line.len() <= MAX_COMMAND_LINE {
                self.command_line.push(byte);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_assembler_is_between_cycles_only_when_no_cycle_is_half_read() {
        let mut assembler = IldCycleAssembler::new(2);
        let mut cycles = VecDeque::new();
        let now = Instant::now();
        assert!(assembler.is_between_cycles());
        let bytes = encode_cycle(&[100, 7]);
        assembler.push(&bytes[..3], now, &mut cycles);
        assert!(
            !assembler.is_between_cycles(),
            "the distance alone is half a cycle"
        );
        assembler.push(&bytes[3..], now, &mut cycles);
        assert!(assembler.is_between_cycles());
        assert_eq!(cycles.len(), 1);
    }
}
