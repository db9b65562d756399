//! The device end of SLCAN: the adapter the emulator plays, as one of the real firmwares
//! behaves (docs/decisions.md, "SLCAN adapters", has the sources). What it answers to each
//! line is decided here, free of I/O ([`DeviceState::on_message`]).
//!
//! | adapter | answers commands | transmit acks | `V` | frames it sends | bit rates |
//! |---------|------------------|---------------|-----|-----------------|-----------|
//! | `scanhil` (default) | CR / BEL | none | `V1013` | plain | Linux table |
//! | `canable` (CANable 1.x/2.x slcan firmware) | nothing, not even to errors | none | free text `<git version> <remote>` | plain | CANable table |
//! | `silent` (an adapter that answers nothing at all) | nothing | none | nothing | plain | CANable table |
//! | `lawicel` (CANUSB/CAN232) | CR / BEL | `z` / `Z` | `V1013` | plain | Lawicel table |
//! | `lawicel-timestamps` (the same with `Z1` stored) | CR / BEL | `z` / `Z` | `V1013` | with 4 hex digits of ms | Lawicel table |
//!
//! Lawicel rules followed by the Lawicel adapters: `O` and `L` only on a closed channel, `C`
//! only on an open one, `Sn` and `Zn` only while closed, `F` only while open, no CAN FD
//! frames. The `scanhil` device refuses a second `O` and `Sn` while open, answers `C` always,
//! carries FD frames and is the lean default: no acks, so the wire stays light at 20 kHz.

use std::fmt;
use std::str::FromStr;

use super::SlcanCounters;
use crate::can::CanFrame;
use crate::slcan::SlcanMessage;
use crate::slcan::bus_status::StatusFlags;
use crate::slcan::family::AdapterFamily;

/// What the device end answers to `V` (Lawicel style: hardware 1.0, software 1.3).
pub const DEVICE_VERSION: &str = "1013";
/// What the device end answers to `N`.
pub const DEVICE_SERIAL: &str = "SHIL";
/// What the emulated CANable answers to `V`: free text, as its firmware's
/// `GIT_VERSION " " GIT_REMOTE`.
pub const CANABLE_VERSION: &str = "b158aa7 scanhil-emulator/canable2-fw";

/// Which real adapter the device end behaves as.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum EmulatedAdapter {
    /// The harness's own lean adapter: CR/BEL answers, no transmit acks, FD frames.
    #[default]
    Scanhil,
    /// CANable 1.x/2.x slcan firmware: answers nothing but `V` (free text).
    Canable,
    /// An adapter that answers nothing at all, not even `V`.
    Silent,
    /// A Lawicel CANUSB/CAN232: CR/BEL answers, `z`/`Z` transmit acks, timestamps off.
    Lawicel,
    /// The same with receive timestamps stored on (`Z1`).
    LawicelTimestamps,
}

impl EmulatedAdapter {
    /// Every adapter the device end plays.
    pub const ALL: [EmulatedAdapter; 5] = [
        EmulatedAdapter::Scanhil,
        EmulatedAdapter::Canable,
        EmulatedAdapter::Silent,
        EmulatedAdapter::Lawicel,
        EmulatedAdapter::LawicelTimestamps,
    ];

    /// Its name on the command line (`--slcan-adapter NAME`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            EmulatedAdapter::Scanhil => "scanhil",
            EmulatedAdapter::Canable => "canable",
            EmulatedAdapter::Silent => "silent",
            EmulatedAdapter::Lawicel => "lawicel",
            EmulatedAdapter::LawicelTimestamps => "lawicel-timestamps",
        }
    }

    /// The family whose `Sn` table it follows.
    #[must_use]
    pub fn family(self) -> AdapterFamily {
        match self {
            EmulatedAdapter::Scanhil => AdapterFamily::Linux,
            EmulatedAdapter::Canable | EmulatedAdapter::Silent => AdapterFamily::Canable,
            EmulatedAdapter::Lawicel | EmulatedAdapter::LawicelTimestamps => AdapterFamily::Lawicel,
        }
    }

    /// Whether it answers commands with CR and BEL (and `N`, `F` with their replies).
    #[must_use]
    pub fn answers(self) -> bool {
        !matches!(self, EmulatedAdapter::Canable | EmulatedAdapter::Silent)
    }

    fn is_lawicel(self) -> bool {
        matches!(
            self,
            EmulatedAdapter::Lawicel | EmulatedAdapter::LawicelTimestamps
        )
    }
}

impl fmt::Display for EmulatedAdapter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for EmulatedAdapter {
    type Err = String;

    fn from_str(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|adapter| adapter.name() == name)
            .ok_or_else(|| {
                let names: Vec<&str> = Self::ALL.iter().map(|a| a.name()).collect();
                format!(
                    "unknown SLCAN adapter `{name}` (expected {})",
                    names.join(", ")
                )
            })
    }
}

/// What the device does with one line from the host.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct DeviceReaction {
    /// A frame to deliver to the node.
    pub deliver: Option<CanFrame>,
    /// What to answer on the line.
    pub answer: Option<SlcanMessage>,
    /// The host closed the open channel and the run is to end there.
    pub ends_run: bool,
}

/// The device end's state: which adapter it plays and what the host has set.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceState {
    adapter: EmulatedAdapter,
    channel_open: bool,
    listen_only: bool,
    timestamps: bool,
    bitrate_code: Option<u8>,
    end_run_on_close: bool,
}

impl DeviceState {
    /// A closed adapter, as it powers up.
    #[must_use]
    pub fn new(adapter: EmulatedAdapter) -> DeviceState {
        DeviceState {
            adapter,
            channel_open: false,
            listen_only: false,
            timestamps: adapter == EmulatedAdapter::LawicelTimestamps,
            bitrate_code: None,
            end_run_on_close: false,
        }
    }

    /// The adapter it plays.
    #[must_use]
    pub fn adapter(&self) -> EmulatedAdapter {
        self.adapter
    }

    /// Whether the host has opened the channel.
    #[must_use]
    pub fn channel_open(&self) -> bool {
        self.channel_open
    }

    /// Whether frames it sends carry receive timestamps.
    #[must_use]
    pub fn timestamps(&self) -> bool {
        self.timestamps
    }

    /// The bit rate the host last set, bit/s (`None`: never set).
    #[must_use]
    pub fn bitrate(&self) -> Option<u32> {
        self.bitrate_code
            .and_then(|code| self.adapter.family().bits_per_s(code))
    }

    /// From now on, the host's `C` on an open channel ends the run.
    pub fn end_run_on_close(&mut self) {
        self.end_run_on_close = true;
    }

    /// Whether the host's `C` on an open channel ends the run.
    #[must_use]
    pub fn ends_run_on_close(&self) -> bool {
        self.end_run_on_close
    }

    /// Reacts to one message from the host, counting what it refuses in `counters`.
    pub fn on_message(
        &mut self,
        message: SlcanMessage,
        counters: &mut SlcanCounters,
    ) -> DeviceReaction {
        let adapter = self.adapter;
        let mut reaction = DeviceReaction::default();
        let outcome = match message {
            SlcanMessage::Frame(frame) => self.transmit(frame, &mut reaction, counters),
            SlcanMessage::Open | SlcanMessage::ListenOnly => {
                if self.channel_open {
                    Outcome::Refused
                } else {
                    self.channel_open = true;
                    self.listen_only = message == SlcanMessage::ListenOnly;
                    Outcome::Done
                }
            }
            SlcanMessage::Close => {
                let was_open = self.channel_open;
                self.channel_open = false;
                reaction.ends_run = was_open && self.end_run_on_close;
                if !was_open && adapter.is_lawicel() {
                    Outcome::Refused
                } else {
                    Outcome::Done
                }
            }
            SlcanMessage::Bitrate(_) | SlcanMessage::Timestamps(_) if self.channel_open => {
                Outcome::Refused
            }
            SlcanMessage::Bitrate(code) => match adapter.family().bits_per_s(code) {
                Some(_) => {
                    self.bitrate_code = Some(code);
                    Outcome::Done
                }
                None => Outcome::Refused,
            },
            SlcanMessage::Timestamps(on) if adapter.is_lawicel() => {
                self.timestamps = on;
                Outcome::Done
            }
            SlcanMessage::DataBitrate(_) if self.channel_open || adapter.is_lawicel() => {
                Outcome::Refused
            }
            // The emulated bus has no data-phase timing: accepted as a CANable 2.0 would.
            SlcanMessage::DataBitrate(_) => Outcome::Done,
            SlcanMessage::VersionRequest => match adapter {
                EmulatedAdapter::Silent => Outcome::Silent,
                EmulatedAdapter::Canable => {
                    Outcome::Reply(SlcanMessage::Text(CANABLE_VERSION.to_owned()))
                }
                _ => Outcome::Reply(SlcanMessage::Version(DEVICE_VERSION.to_owned())),
            },
            SlcanMessage::SerialRequest if adapter.answers() => {
                Outcome::Reply(SlcanMessage::Serial(DEVICE_SERIAL.to_owned()))
            }
            SlcanMessage::StatusRequest if adapter.is_lawicel() && !self.channel_open => {
                Outcome::Refused
            }
            SlcanMessage::StatusRequest if adapter.answers() => {
                Outcome::Reply(SlcanMessage::StatusFlags(StatusFlags::default()))
            }
            // An empty line: clients (python-can) send a few CRs to flush the adapter's input.
            SlcanMessage::Ack => Outcome::Done,
            other => {
                counters.malformed(format!("unexpected {other:?} from the host"));
                Outcome::Refused
            }
        };
        reaction.answer = match outcome {
            _ if !adapter.answers() && !matches!(outcome, Outcome::Reply(_)) => None,
            Outcome::Done => Some(SlcanMessage::Ack),
            Outcome::Refused => Some(SlcanMessage::Nack),
            Outcome::Reply(reply) => Some(reply),
            Outcome::Ack(ack) => Some(ack),
            Outcome::Silent => None,
        };
        reaction
    }

    /// A malformed line from the host: counted by the caller; BEL unless the adapter is
    /// silent.
    #[must_use]
    pub fn on_malformed(&self) -> Option<SlcanMessage> {
        self.adapter.answers().then_some(SlcanMessage::Nack)
    }

    /// The host asks to transmit `frame`.
    fn transmit(
        &mut self,
        frame: CanFrame,
        reaction: &mut DeviceReaction,
        counters: &mut SlcanCounters,
    ) -> Outcome {
        let lawicel = self.adapter.is_lawicel();
        if !self.channel_open || self.listen_only || (lawicel && frame.is_fd()) {
            counters.refused_frames += 1;
            return Outcome::Refused;
        }
        reaction.deliver = Some(frame);
        if lawicel {
            Outcome::Ack(SlcanMessage::TransmitAck {
                extended: frame.id().is_extended(),
            })
        } else {
            Outcome::Silent
        }
    }
}

/// How a line was taken, before the adapter's manner of answering is applied.
enum Outcome {
    /// Done: CR from an answering adapter.
    Done,
    /// Refused: BEL from an answering adapter.
    Refused,
    /// A reply proper (a version, a serial, flags): every adapter sends its own.
    Reply(SlcanMessage),
    /// A transmit acknowledgement.
    Ack(SlcanMessage),
    /// Nothing to answer (a frame on an adapter without acks).
    Silent,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::can::CanId;

    fn frame(id: u16) -> CanFrame {
        CanFrame::new(CanId::standard(id).unwrap(), &[1, 2]).unwrap()
    }

    /// Feeds `lines` to a fresh device playing `adapter`; returns each answer and what was
    /// delivered.
    fn play(adapter: EmulatedAdapter, lines: &[SlcanMessage]) -> (Vec<Option<String>>, usize) {
        let mut device = DeviceState::new(adapter);
        let mut counters = SlcanCounters::default();
        let mut delivered = 0;
        let answers = lines
            .iter()
            .map(|line| {
                let reaction = device.on_message(line.clone(), &mut counters);
                delivered += usize::from(reaction.deliver.is_some());
                reaction.answer.map(|a| a.encode())
            })
            .collect();
        (answers, delivered)
    }

    fn session() -> Vec<SlcanMessage> {
        vec![
            SlcanMessage::Close,
            SlcanMessage::Bitrate(7),
            SlcanMessage::Open,
            SlcanMessage::Frame(frame(0x100)),
            SlcanMessage::VersionRequest,
            SlcanMessage::StatusRequest,
            SlcanMessage::Bitrate(8),
            SlcanMessage::Open,
            SlcanMessage::Close,
        ]
    }

    #[test]
    fn each_adapter_answers_a_session_as_its_firmware_does() {
        let some = |text: &str| Some(text.to_owned());
        let (scanhil, delivered) = play(EmulatedAdapter::Scanhil, &session());
        assert_eq!(delivered, 1);
        assert_eq!(
            scanhil,
            [
                some("\r"),
                some("\r"),
                some("\r"),
                None,
                some("V1013\r"),
                some("F00\r"),
                some("\x07"),
                some("\x07"),
                some("\r")
            ]
        );
        let (lawicel, _) = play(EmulatedAdapter::Lawicel, &session());
        assert_eq!(
            lawicel,
            [
                some("\x07"),
                some("\r"),
                some("\r"),
                some("z\r"),
                some("V1013\r"),
                some("F00\r"),
                some("\x07"),
                some("\x07"),
                some("\r")
            ]
        );
        let (canable, delivered) = play(EmulatedAdapter::Canable, &session());
        assert_eq!(delivered, 1);
        let mut expected = vec![None; 9];
        expected[4] = Some(format!("{CANABLE_VERSION}\r"));
        assert_eq!(canable, expected);
        let (silent, delivered) = play(EmulatedAdapter::Silent, &session());
        assert_eq!(delivered, 1);
        assert_eq!(silent, vec![None; 9]);
    }

    #[test]
    fn lawicel_refuses_fd_frames_and_status_while_closed_and_keeps_timestamps_settable() {
        let fd = CanFrame::new_fd(CanId::standard(0x140).unwrap(), &[0; 12], false, false).unwrap();
        let lines = [
            SlcanMessage::StatusRequest,
            SlcanMessage::Timestamps(true),
            SlcanMessage::Open,
            SlcanMessage::Frame(fd),
            SlcanMessage::Timestamps(false),
            SlcanMessage::DataBitrate(2),
        ];
        let (answers, delivered) = play(EmulatedAdapter::Lawicel, &lines);
        assert_eq!(delivered, 0);
        let bel = Some("\x07".to_owned());
        let cr = Some("\r".to_owned());
        assert_eq!(
            answers,
            [bel.clone(), cr.clone(), cr, bel.clone(), bel.clone(), bel]
        );
        let mut device = DeviceState::new(EmulatedAdapter::Lawicel);
        let mut counters = SlcanCounters::default();
        assert!(!device.timestamps());
        device.on_message(SlcanMessage::Timestamps(true), &mut counters);
        assert!(device.timestamps());
        assert!(DeviceState::new(EmulatedAdapter::LawicelTimestamps).timestamps());
        // The emulated bus carries FD on the others.
        let (_, delivered) = play(
            EmulatedAdapter::Canable,
            &[SlcanMessage::Open, SlcanMessage::Frame(fd)],
        );
        assert_eq!(delivered, 1);
    }

    #[test]
    fn bit_rates_follow_the_family_and_frames_need_an_open_talking_channel() {
        let mut canable = DeviceState::new(EmulatedAdapter::Canable);
        let mut counters = SlcanCounters::default();
        canable.on_message(SlcanMessage::Bitrate(7), &mut counters);
        assert_eq!(canable.bitrate(), Some(750_000));
        let mut lawicel = DeviceState::new(EmulatedAdapter::Lawicel);
        lawicel.on_message(SlcanMessage::Bitrate(7), &mut counters);
        assert_eq!(lawicel.bitrate(), Some(800_000));
        let refused = lawicel.on_message(SlcanMessage::Bitrate(9), &mut counters);
        assert_eq!(refused.answer, Some(SlcanMessage::Nack));
        assert_eq!(lawicel.bitrate(), Some(800_000));
        let closed = lawicel.on_message(SlcanMessage::Frame(frame(1)), &mut counters);
        assert_eq!(
            (closed.deliver, closed.answer),
            (None, Some(SlcanMessage::Nack))
        );
        lawicel.on_message(SlcanMessage::ListenOnly, &mut counters);
        let listening = lawicel.on_message(SlcanMessage::Frame(frame(1)), &mut counters);
        assert_eq!(listening.deliver, None);
        assert_eq!(counters.refused_frames, 2);
        let flush = lawicel.on_message(SlcanMessage::Ack, &mut counters);
        assert_eq!(flush.answer, Some(SlcanMessage::Ack));
        let reply = lawicel.on_message(SlcanMessage::Version("x".into()), &mut counters);
        assert_eq!(reply.answer, Some(SlcanMessage::Nack));
        assert_eq!(counters.malformed_lines, 1);
    }

    #[test]
    fn closing_an_open_channel_ends_the_run_only_when_asked() {
        let mut device = DeviceState::new(EmulatedAdapter::Canable);
        let mut counters = SlcanCounters::default();
        device.on_message(SlcanMessage::Open, &mut counters);
        assert!(
            !device
                .on_message(SlcanMessage::Close, &mut counters)
                .ends_run
        );
        device.end_run_on_close();
        assert!(
            !device
                .on_message(SlcanMessage::Close, &mut counters)
                .ends_run
        );
        device.on_message(SlcanMessage::Open, &mut counters);
        assert!(device.channel_open());
        assert!(
            device
                .on_message(SlcanMessage::Close, &mut counters)
                .ends_run
        );
        assert_eq!(device.on_malformed(), None);
        assert_eq!(
            DeviceState::new(EmulatedAdapter::Scanhil).on_malformed(),
            Some(SlcanMessage::Nack)
        );
        for adapter in EmulatedAdapter::ALL {
            assert_eq!(adapter.name().parse::<EmulatedAdapter>(), Ok(adapter));
        }
        assert!(
            "peak"
                .parse::<EmulatedAdapter>()
                .unwrap_err()
                .contains("lawicel-timestamps")
        );
    }
}
