//! Where the emulated sensor's samples go: the ILD 2300's own RS422 byte stream on a serial
//! line or pty (one output cycle per sample, the values its settings select, paced at the
//! line's baud by [`super::ild_line`]), or Distance frames on the mirror's CAN link.
//!
//! The summary line declares the sensor's clock (measuring rate, the loop time its counter 0
//! stands for, and the measuring time of the first cycle it sent) so the host can place each
//! distance in time; for a real sensor the host estimates it instead.
//!
//! On the ILD line the port also answers the host's ASCII commands
//! ([`super::sensor_commands`]): before the run and between periods (the timing loops wait on
//! [`SensorPort::answer_commands`] beside the mirror's link) and, in real time, between
//! streamed cycles ([`SensorPort::emit`] first answers what has arrived). Answering never
//! blocks the mirror loop: replies are written as far as the line takes them now, the rest
//! goes out with the next cycle. What the commands set (output on/off, the extra values, the
//! laser) shapes the cycles sent. Distance frames on CAN have no command line.
//!
//! The line paces the cycles: each arrives its transmit time after it was measured, and one
//! the baud rate cannot carry is lost as the real sensor loses it (`lost_to_baud` in the
//! summary). Lockstep writes each cycle with the answer of the period in which its last byte
//! arrives; real time writes it at the first tick after that.
//!
//! In real time the ILD stream never waits for its reader, as a real RS422 sensor streams
//! whether anyone listens: a cycle the line cannot take now (the host is not reading, or not
//! keeping up) is dropped and counted (`dropped_cycles` in the summary; the measured-value
//! counter still advances, so the host sees the gap). So a sensor line nobody reads never
//! stalls the mirror, and at most one tick's cycles and
//! [`MAX_QUEUED_REPLY_BYTES`](scanhil_protocol::link::ild::MAX_QUEUED_REPLY_BYTES) of replies
//! wait in memory.
//!
//! In lockstep ([`SensorPort::lossless`]) time is the host's to give, so nothing is dropped:
//! each period's cycles are written whole, waiting while the host has not read the line yet
//! (a loaded host may leave it unread for a while). The lockstep loop bounds that wait by the
//! watchdog's allowance: a host that stops reading the sensor's line then ends the run as one
//! that stops reading the mirror's does (coils zeroed, `ended_by: host_stopped_reading`).

use scanhil_protocol::ild::command::{BAUD_RATES_UNCHECKED, LineEnding, MeasuringRate};
use scanhil_protocol::ild::stream::FACTORY_BAUD;
use scanhil_protocol::link::ild::{IldLink, IldRequest};
use scanhil_protocol::link::role::Role;
use scanhil_protocol::link::{CanLink, LinkError, LinkUri, PtyPair};

use super::ild_line::{IldLine, PacedCycle};
use super::sensor_commands::IldSettings;
use crate::scene::Scene;
use crate::sensor::IldSample;
use scanhil_protocol::message::{Distance, Message, U24_MAX};

/// The sensor's output.
#[derive(Debug)]
pub enum SensorPort {
    /// The scene has no sensor, or no sensor link was asked for: samples are dropped.
    Off,
    /// The ILD RS422 stream and command line (device end).
    Ild(Box<IldPort>),
    /// Distance frames on the mirror's CAN link: the samples offered, not yet queued.
    Can(SensorClockTrack, Vec<IldSample>),
}

/// The ILD line's device end with the emulated sensor's settings.
#[derive(Debug)]
pub struct IldPort {
    link: IldLink,
    line: IldLine,
    clock: SensorClockTrack,
    settings: IldSettings,
    commands: CommandCounts,
    /// The host hung up the line: no more commands to read (a cycle sent then still fails).
    host_gone: bool,
    /// Lockstep: every cycle is written, waiting for the line ([`SensorPort::lossless`]).
    lossless: bool,
}

/// The host's commands the sensor answered, for the summary line.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct CommandCounts {
    /// Command lines answered (refusals included).
    pub commands_answered: u64,
    /// Of those, refused with an `Exx` error.
    pub commands_refused: u64,
    /// Replies dropped because the host left earlier ones unread.
    pub replies_dropped: u64,
}

/// The sensor's part of the summary line.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct SensorSummary {
    /// Samples sent and the sensor's clock.
    #[serde(flatten)]
    pub clock: SensorClockTrack,
    /// Commands answered (ILD line only).
    #[serde(flatten)]
    pub commands: CommandCounts,
    /// ILD line: its baud rate (`None` on CAN).
    pub baud: Option<u32>,
}

/// What the sensor has sent and when its counter started.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct SensorClockTrack {
    /// Samples sent.
    pub samples: u64,
    /// ILD line, real time: cycles the line could not take when they were due (the host not
    /// reading): dropped, not sent.
    pub dropped_cycles: u64,
    /// ILD line: cycles lost because the line's baud rate could not carry them (a newer cycle
    /// replaced them while they waited for the line).
    pub lost_to_baud: u64,
    /// The loop time counter value 0 stands for, s (`None` before the first sample).
    pub counter_zero_s: Option<f64>,
    /// The measured-value counter of the first cycle sent (`None` before one was sent): where
    /// a host that counts cycles without the counter starts.
    pub first_sent_counter: Option<u32>,
    /// The sensor's measuring rate, Hz.
    pub measuring_rate_hz: f64,
}

impl SensorPort {
    /// Opens the sensor's link: `None` (no sensor served), `ild:pty[@BAUD]` (a new pty pair
    /// standing for a line at that baud, the factory 691 200 by default), `ild:PATH[@BAUD]`,
    /// or `fsm` (Distance frames on the mirror's link); command lines end as `line_ending`
    /// says. Returns the port and the link's name for the ready line.
    ///
    /// # Errors
    /// A link that does not open, a CAN URI given for the sensor, a sensor link for a scene
    /// without a sensor, a baud rate the sensor does not have.
    pub fn open(
        uri: Option<&str>,
        scene: &Scene,
        line_ending: LineEnding,
    ) -> anyhow::Result<(SensorPort, String)> {
        let Some(uri) = uri else {
            return Ok((SensorPort::Off, String::new()));
        };
        if !scene.has(crate::scene::Part::Sensor) {
            anyhow::bail!(
                "--sensor {uri}: scene `{}` has no `sensor` part to serve",
                scene.name
            );
        }
        let config = scene.sensor.unwrap_or_default();
        let clock = SensorClockTrack::new(config.measuring_rate_hz);
        if uri == "fsm" {
            return Ok((SensorPort::Can(clock, Vec::new()), "fsm".into()));
        }
        let mut link = match uri.strip_prefix("ild:pty") {
            Some(rest) => {
                let baud = match rest.strip_prefix('@') {
                    Some(_) => match format!("ild:x{rest}").parse::<LinkUri>()? {
                        LinkUri::Ild { baud, .. } => baud,
                        _ => unreachable!("an ild: URI parses as one"),
                    },
                    None if rest.is_empty() => FACTORY_BAUD,
                    None => anyhow::bail!("--sensor {uri}: expected `ild:pty` or `ild:pty@BAUD`"),
                };
                IldLink::open_pty(PtyPair::open()?, baud, Role::Device)?
            }
            None => match uri.parse::<LinkUri>()? {
                parsed @ LinkUri::Ild { .. } => IldLink::open(&parsed, Role::Device)?,
                other => anyhow::bail!(
                    "--sensor {other}: the sensor speaks the ILD stream (`ild:PATH`) or Distance \
                     frames on the mirror's link (`fsm`)"
                ),
            },
        };
        if !BAUD_RATES_UNCHECKED.contains(&link.baud()) {
            anyhow::bail!(
                "--sensor {uri}: the ILD 2300 has no baud rate {} (BAUDRATE takes {:?}; the \
                 list is the family's usual one, not confirmed for the 2300)",
                link.baud(),
                BAUD_RATES_UNCHECKED
            );
        }
        link.set_line_ending(line_ending);
        let rate = MeasuringRate::from_hz(config.measuring_rate_hz).ok_or_else(|| {
            anyhow::anyhow!(
                "scene `{}`: {} Hz is not an ILD 2300 measuring rate",
                scene.name,
                config.measuring_rate_hz
            )
        })?;
        let settings = IldSettings::new(rate, config.range.span_mm, link.baud());
        let name = link.name().to_owned();
        let port = IldPort {
            line: IldLine::new(link.baud()),
            link,
            clock,
            settings,
            commands: CommandCounts::default(),
            host_gone: false,
            lossless: false,
        };
        Ok((SensorPort::Ild(Box::new(port)), name))
    }

    /// The same port delivering every cycle, waiting for the line (lockstep), instead of
    /// dropping the cycles the line cannot take now (real time, as a real sensor streams).
    #[must_use]
    pub fn lossless(mut self) -> SensorPort {
        if let SensorPort::Ild(port) = &mut self {
            port.lossless = true;
        }
        self
    }

    /// The sensor line's name (empty when there is none; the mirror's link for CAN).
    #[must_use]
    pub fn name(&self) -> &str {
        match self {
            SensorPort::Ild(port) => port.link.name(),
            SensorPort::Off | SensorPort::Can(..) => "",
        }
    }

    /// Waits for the host's command lines and answers each; returns only on a link error
    /// other than the host's hang-up (after which, and on a port without a command line, it
    /// waits for ever). Cancel-safe: meant for a `select!` beside the mirror's link while the
    /// loop waits.
    pub async fn answer_commands(&mut self) -> anyhow::Error {
        if let SensorPort::Ild(port) = self {
            while !port.host_gone {
                let answered = match port.link.recv_command().await {
                    Ok(request) => port.answer(&request),
                    Err(error) => Err(error),
                };
                match answered {
                    Ok(()) => {}
                    Err(LinkError::HangUp { .. }) => port.host_gone = true,
                    Err(error) => return error.into(),
                }
            }
        }
        std::future::pending().await
    }

    /// Answers the command lines that have arrived, without waiting.
    ///
    /// # Errors
    /// Link errors other than the host's hang-up.
    pub fn poll_commands(&mut self) -> anyhow::Result<()> {
        let SensorPort::Ild(port) = self else {
            return Ok(());
        };
        while !port.host_gone {
            let answered = match port.link.try_recv_command() {
                Ok(Some(request)) => port.answer(&request),
                Ok(None) => return Ok(()),
                Err(error) => Err(error),
            };
            match answered {
                Ok(()) => {}
                Err(LinkError::HangUp { .. }) => port.host_gone = true,
                Err(error) => return Err(error.into()),
            }
        }
        Ok(())
    }
}

impl IldPort {
    /// Carries out one command line and sends its reply without waiting.
    fn answer(&mut self, request: &IldRequest) -> Result<(), LinkError> {
        let reply = self.settings.answer(request);
        self.commands.commands_answered += 1;
        if !reply.is_ok() {
            self.commands.commands_refused += 1;
        }
        if !self.link.reply_now(&reply)? {
            self.commands.replies_dropped += 1;
        }
        Ok(())
    }

    /// Queues `cycles` on the link: all of them (lossless), or only if the host has read what
    /// was written before (else they are dropped, counted).
    fn write(&mut self, cycles: &[PacedCycle]) -> Result<(), LinkError> {
        if cycles.is_empty() {
            return Ok(());
        }
        let line_free = self.lossless || self.link.try_flush()?;
        for cycle in cycles {
            if line_free {
                self.link.queue_cycle(&cycle.values)?;
                self.clock.sent(cycle.counter);
            } else {
                self.clock.dropped_cycles += 1;
            }
        }
        Ok(())
    }
}

impl SensorPort {
    /// Offers the samples of one period to the sensor's output, in order, without writing
    /// anything: on the ILD line each sample's output cycle (as the settings make it, none
    /// while the output is off) goes onto the line ([`IldLine`]), from which
    /// [`SensorPort::release`] writes it once it has arrived; on CAN the samples wait for
    /// [`SensorPort::release`] to queue their Distance frames.
    pub fn offer(&mut self, samples: &[IldSample]) {
        match self {
            SensorPort::Off => {}
            SensorPort::Ild(port) => {
                for sample in samples {
                    if let Some(values) = port.settings.cycle(sample) {
                        port.clock.measured(sample);
                        port.line.push(sample.t_s, sample.counter, values);
                    }
                }
                port.clock.lost_to_baud = port.line.lost();
            }
            SensorPort::Can(_, pending) => pending.extend_from_slice(samples),
        }
    }

    /// Queues, without writing, a recorded session's output cycles (raw values) on the ILD
    /// line as they are: no settings shape them and no line paces them (they are the bytes a
    /// host once received); [`SensorPort::flush`] writes them. Elsewhere they are dropped (a
    /// sensor on CAN was recorded as the mirror link's Distance frames).
    ///
    /// # Errors
    /// Link errors.
    pub fn write_cycles(&mut self, cycles: &[Vec<u32>]) -> Result<(), LinkError> {
        if let SensorPort::Ild(port) = self {
            for values in cycles {
                port.link.queue_cycle(values)?;
                port.clock.samples += 1;
            }
        }
        Ok(())
    }

    /// Queues, without writing, the ILD line's cycles that have arrived by loop time
    /// `until_s`, in order: unless [`lossless`](SensorPort::lossless), while the host has not
    /// read what was written before, they are dropped (counted). On CAN the offered samples'
    /// Distance frames are queued on `fsm` behind the frames queued before them.
    ///
    /// # Errors
    /// Link errors.
    pub async fn release(&mut self, until_s: f64, fsm: &mut CanLink) -> anyhow::Result<()> {
        match self {
            SensorPort::Off => {}
            SensorPort::Ild(port) => {
                let due = port.line.due(until_s);
                port.write(&due)?;
            }
            SensorPort::Can(clock, pending) => {
                // A sample leaves `pending` only once its frame is queued: a release cut short
                // (the send allowance ran out) leaves the rest for the next one.
                while let Some(&sample) = pending.first() {
                    let sensor_time_us =
                        ((sample.t_s * 1e6).round() as u64 & u64::from(U24_MAX)) as u32;
                    let distance = Distance {
                        value: sample.value,
                        counter: sample.counter,
                        sensor_time_us,
                    };
                    fsm.queue(&Message::Distance(distance).encode()?).await?;
                    pending.remove(0);
                    clock.measured(&sample);
                    clock.sent(sample.counter);
                }
            }
        }
        Ok(())
    }

    /// The end of the run: queues everything the sensor's output still holds (on the ILD line,
    /// what it would still deliver), as [`SensorPort::release`] does.
    ///
    /// # Errors
    /// Link errors.
    pub async fn release_all(&mut self, fsm: &mut CanLink) -> anyhow::Result<()> {
        if let SensorPort::Ild(port) = self {
            let rest = port.line.drain();
            port.write(&rest)?;
        }
        self.release(f64::INFINITY, fsm).await
    }

    /// Real time: the sensor's part of the tick that starts at loop time `now_s`: answers the
    /// command lines that have arrived ([`SensorPort::poll_commands`]), then
    /// [`SensorPort::release`] and [`SensorPort::flush`].
    ///
    /// # Errors
    /// Link errors.
    pub async fn emit(&mut self, now_s: f64, fsm: &mut CanLink) -> anyhow::Result<()> {
        self.poll_commands()?;
        self.release(now_s, fsm).await?;
        self.flush(fsm).await
    }

    /// Writes what [`SensorPort::release`] queued: on the ILD line as far as the line takes it
    /// now (never waiting) or, [`lossless`](SensorPort::lossless), all of it (waiting while
    /// the line is full: the caller bounds the wait); on CAN with the frames queued on `fsm`.
    ///
    /// # Errors
    /// Link errors.
    pub async fn flush(&mut self, fsm: &mut CanLink) -> anyhow::Result<()> {
        match self {
            SensorPort::Off => {}
            SensorPort::Ild(port) if port.lossless => port.link.flush().await?,
            SensorPort::Ild(port) => {
                port.link.try_flush()?;
            }
            SensorPort::Can(..) => fsm.flush().await?,
        }
        Ok(())
    }

    /// What the sensor sent and answered, for the summary line.
    #[must_use]
    pub fn summary(&self) -> Option<SensorSummary> {
        match self {
            SensorPort::Off => None,
            SensorPort::Ild(port) => Some(SensorSummary {
                clock: port.clock,
                commands: port.commands,
                baud: Some(port.link.baud()),
            }),
            SensorPort::Can(clock, _) => Some(SensorSummary {
                clock: *clock,
                commands: CommandCounts::default(),
                baud: None,
            }),
        }
    }
}

impl SensorClockTrack {
    /// Nothing sent yet, from a sensor measuring at `measuring_rate_hz`.
    #[must_use]
    pub fn new(measuring_rate_hz: f64) -> SensorClockTrack {
        SensorClockTrack {
            samples: 0,
            dropped_cycles: 0,
            lost_to_baud: 0,
            counter_zero_s: None,
            first_sent_counter: None,
            measuring_rate_hz,
        }
    }

    /// A sample was measured with an output cycle; the first one fixes the loop time of
    /// counter 0.
    pub fn measured(&mut self, sample: &IldSample) {
        if self.counter_zero_s.is_none() {
            self.counter_zero_s =
                Some(sample.t_s - f64::from(sample.counter) / self.measuring_rate_hz);
        }
    }

    /// The cycle of the sample with measured-value counter `counter` was sent.
    pub fn sent(&mut self, counter: u32) {
        self.samples += 1;
        self.first_sent_counter.get_or_insert(counter);
    }
}
