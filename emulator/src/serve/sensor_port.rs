//! Where the emulated sensor's samples go: the ILD 2300's own RS422 byte stream on a serial
//! line or pty (one output cycle per sample: the distance value, then the 18-bit measured-value
//! counter, as a sensor configured with `OUTADD_RS422 COUNTER` sends them), or Distance frames
//! on the mirror's CAN link.
//!
//! The summary line declares the sensor's clock (measuring rate, and the loop time its counter
//! 0 stands for) so the host can place each distance in time; for a real sensor the host
//! estimates it instead.
//!
//! On the ILD line the port also answers the host's ASCII commands
//! ([`super::sensor_commands`]): before the run and between periods (the timing loops wait on
//! [`SensorPort::answer_commands`] beside the mirror's link) and, in real time, between
//! streamed cycles ([`SensorPort::emit`] first answers what has arrived). Answering never
//! blocks the mirror loop: replies are written as far as the line takes them now, the rest
//! goes out with the next cycle. What the commands set (output on/off, the counter, the laser) shapes the cycles
//! sent. Distance frames on CAN have no command line.
//!
//! In real time the ILD stream never waits for its reader, as a real RS422 sensor streams
//! whether anyone listens: a cycle the line cannot take now (the host is not reading, or not
//! keeping up) is dropped whole and counted (`dropped_cycles` in the summary; the
//! measured-value counter still advances, so the host sees the gap). So a sensor line nobody
//! reads never stalls the mirror, and at most one cycle and
//! [`MAX_QUEUED_REPLY_BYTES`](scanhil_protocol::link::ild::MAX_QUEUED_REPLY_BYTES) of replies
//! wait in memory.
//!
//! In lockstep ([`SensorPort::lossless`]) time is the host's to give, so nothing is dropped:
//! each period's cycles are written whole, waiting while the host has not read the line yet
//! (a loaded host may leave it unread for a while). The lockstep loop bounds that wait by the
//! watchdog's allowance: a host that stops reading the sensor's line then ends the run as one
//! that stops reading the mirror's does (coils zeroed, `ended_by: host_stopped_reading`).

use scanhil_protocol::link::ild::{IldLink, IldRequest};
use scanhil_protocol::link::role::Role;
use scanhil_protocol::link::{CanLink, LinkError, LinkUri, PtyPair};

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
    /// Distance frames on the mirror's CAN link.
    Can(SensorClockTrack),
}

/// The ILD line's device end with the emulated sensor's settings.
#[derive(Debug)]
pub struct IldPort {
    link: IldLink,
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
}

/// What the sensor has sent and when its counter started.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct SensorClockTrack {
    /// Samples sent.
    pub samples: u64,
    /// ILD line: samples whose output cycle the line could not take (dropped, not sent).
    pub dropped_cycles: u64,
    /// The loop time counter value 0 stands for, s (`None` before the first sample).
    pub counter_zero_s: Option<f64>,
    /// The sensor's measuring rate, Hz.
    pub measuring_rate_hz: f64,
}

impl SensorPort {
    /// Opens the sensor's link: `None` (no sensor served), `ild:pty` (a new pty pair),
    /// `ild:PATH[@BAUD]`, or `fsm` (Distance frames on the mirror's link). Returns the port
    /// and the link's name for the ready line.
    ///
    /// # Errors
    /// A link that does not open, a CAN URI given for the sensor, or a sensor link for a
    /// scene without a sensor.
    pub fn open(uri: Option<&str>, scene: &Scene) -> anyhow::Result<(SensorPort, String)> {
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
            return Ok((SensorPort::Can(clock), "fsm".into()));
        }
        let settings = IldSettings::new(config.measuring_rate_hz, config.range.span_mm);
        let link = if uri == "ild:pty" {
            IldLink::open_pty(PtyPair::open()?, Role::Device)?
        } else {
            match uri.parse::<LinkUri>()? {
                parsed @ LinkUri::Ild { .. } => IldLink::open(&parsed, Role::Device)?,
                other => anyhow::bail!(
                    "--sensor {other}: the sensor speaks the ILD stream (`ild:PATH`) or Distance \
                     frames on the mirror's link (`fsm`)"
                ),
            }
        };
        let name = link.name().to_owned();
        let port = IldPort {
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
            SensorPort::Off | SensorPort::Can(_) => "",
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
}

impl SensorPort {
    /// Sends the samples of one period, in order, with one write: first answers the command
    /// lines that have arrived ([`SensorPort::poll_commands`]), then [`SensorPort::queue`] and
    /// [`SensorPort::flush`]. For a loop that does not wait on [`SensorPort::answer_commands`]
    /// between periods (real time).
    ///
    /// # Errors
    /// Link errors.
    pub async fn emit(&mut self, samples: &[IldSample], fsm: &mut CanLink) -> anyhow::Result<()> {
        self.poll_commands()?;
        self.queue(samples, fsm).await?;
        self.flush(fsm).await
    }

    /// Counts the samples of a period as dropped without queueing them: the period's send
    /// allowance ran out on the mirror's link before the sensor's turn (real time), so every
    /// sample is still counted once, sent or dropped.
    pub fn count_unsent(&mut self, samples: &[IldSample]) {
        match self {
            SensorPort::Off => {}
            SensorPort::Ild(port) => {
                for sample in samples {
                    if port.settings.cycle(sample).is_some() {
                        port.clock.count(sample, false);
                    }
                }
            }
            SensorPort::Can(clock) => {
                for sample in samples {
                    clock.count(sample, false);
                }
            }
        }
    }

    /// Queues the samples of one period, in order, without writing them and without looking
    /// for commands (a loop that waits on [`SensorPort::answer_commands`] between periods
    /// answers them there; lockstep does, and saves a read per period). On the ILD line each
    /// sample's output cycle is queued as the settings make it (none while the output is
    /// off), never waiting: unless [`lossless`](SensorPort::lossless), while the host has not
    /// read the previous period's bytes, this period's cycles are dropped whole (counted). On
    /// CAN the Distance frames are queued on `fsm` behind the frames queued before them.
    ///
    /// # Errors
    /// Link errors.
    pub async fn queue(&mut self, samples: &[IldSample], fsm: &mut CanLink) -> anyhow::Result<()> {
        match self {
            SensorPort::Off => {}
            SensorPort::Ild(port) => {
                let line_free = port.lossless || port.link.try_flush()?;
                for sample in samples {
                    if let Some(values) = port.settings.cycle(sample) {
                        if line_free {
                            port.link.queue_cycle(&values)?;
                        }
                        port.clock.count(sample, line_free);
                    }
                }
            }
            SensorPort::Can(clock) => {
                for sample in samples {
                    clock.count(sample, true);
                    let counter = sample.counter;
                    let sensor_time_us =
                        ((sample.t_s * 1e6).round() as u64 & u64::from(U24_MAX)) as u32;
                    let distance = Distance {
                        value: sample.value,
                        counter,
                        sensor_time_us,
                    };
                    fsm.queue(&Message::Distance(distance).encode()?).await?;
                }
            }
        }
        Ok(())
    }

    /// Writes what [`SensorPort::queue`] queued: on the ILD line as far as the line takes it
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
            SensorPort::Can(_) => fsm.flush().await?,
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
            }),
            SensorPort::Can(clock) => Some(SensorSummary {
                clock: *clock,
                commands: CommandCounts::default(),
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
            counter_zero_s: None,
            measuring_rate_hz,
        }
    }

    /// Counts one sample, `sent` or dropped; the first one fixes the loop time of counter 0.
    pub fn count(&mut self, sample: &IldSample, sent: bool) {
        if self.counter_zero_s.is_none() {
            self.counter_zero_s =
                Some(sample.t_s - f64::from(sample.counter) / self.measuring_rate_hz);
        }
        if sent {
            self.samples += 1;
        } else {
            self.dropped_cycles += 1;
        }
    }
}
