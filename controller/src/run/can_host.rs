//! The controller's end of a CAN link, in the host role, with its recording: on a serial line
//! or pty it speaks SLCAN to an adapter (or the emulator acting as one): `C`, `Sn`, `O` on
//! open, frames both ways; on SocketCAN it is a node on the bus. Every frame sent and received
//! is written to a candump `-L` log as it passes, flushed line by line so a run that dies keeps
//! everything recorded so far.

use std::collections::VecDeque;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use scanhil_protocol::can::{CanFrame, FrameFormat, hex_upper};
use scanhil_protocol::link::socketcan::SocketCanPort;
use scanhil_protocol::link::uri::{SLCAN_DEFAULT_BITRATE, SLCAN_SERIAL_BAUD};
use scanhil_protocol::link::{LinkError, LinkResult, LinkUri, PtyPair, SerialLine};
use scanhil_protocol::slcan::{SlcanBitrate, SlcanDecoder, SlcanMessage, encode_frame};

/// A host-side CAN port with its candump recording.
#[derive(Debug)]
pub struct HostCanPort {
    transport: Transport,
    capture: Option<CandumpCapture>,
    name: String,
}

#[derive(Debug)]
enum Transport {
    Slcan {
        line: SerialLine,
        decoder: SlcanDecoder,
        received: VecDeque<CanFrame>,
        refusals: u64,
    },
    SocketCan(SocketCanPort),
}

/// A candump `-L` log being written: `(seconds.micro) IFACE ID#DATA`, one frame per line.
#[derive(Debug)]
struct CandumpCapture {
    out: BufWriter<File>,
    iface: String,
    path: String,
}

impl HostCanPort {
    /// Opens a `slcan:` or `socketcan:` link.
    ///
    /// # Errors
    /// [`LinkError`] naming the link.
    pub async fn open(uri: &LinkUri) -> LinkResult<HostCanPort> {
        let name = uri.to_string();
        let transport = match uri {
            LinkUri::Slcan { path, .. } => {
                let line = SerialLine::open(path, SLCAN_SERIAL_BAUD, &name)?;
                Transport::slcan(line)
            }
            LinkUri::SocketCan { iface, .. } => {
                Transport::SocketCan(SocketCanPort::open(iface, &name)?)
            }
            LinkUri::Ild { .. } => {
                return Err(LinkError::Protocol {
                    link: name,
                    detail: "the mirror node needs a CAN link (slcan: or socketcan:)".into(),
                });
            }
        };
        let mut port = HostCanPort {
            transport,
            capture: None,
            name,
        };
        port.start(uri.bus_bitrate().unwrap_or(SLCAN_DEFAULT_BITRATE))
            .await?;
        Ok(port)
    }

    /// SLCAN on the master end of a pty pair whose slave the emulator opens.
    ///
    /// # Errors
    /// [`LinkError`] if the line cannot be set up.
    pub async fn on_pty(pair: PtyPair, name: &str) -> LinkResult<HostCanPort> {
        let mut port = HostCanPort {
            transport: Transport::slcan(SerialLine::from_pty(pair, name)?),
            capture: None,
            name: name.to_owned(),
        };
        port.start(SLCAN_DEFAULT_BITRATE).await?;
        Ok(port)
    }

    /// Records every frame from now on into a candump `-L` log at `path`, interface name
    /// `iface`.
    ///
    /// # Errors
    /// The file cannot be created.
    pub fn record_to(&mut self, path: &Path, iface: &str) -> std::io::Result<()> {
        self.capture = Some(CandumpCapture {
            out: BufWriter::new(File::create(path)?),
            iface: iface.to_owned(),
            path: path.display().to_string(),
        });
        Ok(())
    }

    /// The link's name.
    #[must_use]
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Lines the adapter refused with BEL so far.
    #[must_use]
    pub fn refusals(&self) -> u64 {
        match &self.transport {
            Transport::Slcan { refusals, .. } => *refusals,
            Transport::SocketCan(_) => 0,
        }
    }

    async fn start(&mut self, bitrate: u32) -> LinkResult<()> {
        if let Transport::Slcan { line, .. } = &self.transport {
            let rate = SlcanBitrate::from_bits_per_s(bitrate).unwrap_or(SlcanBitrate::from_bits_per_s(SLCAN_DEFAULT_BITRATE).expect("1 Mbit/s is an SLCAN rate"));
            let open = SlcanMessage::Close.encode()
                + &SlcanMessage::Bitrate(rate).encode()
                + &SlcanMessage::Open.encode();
            line.write_all(open.as_bytes()).await?;
        }
        Ok(())
    }

    /// Sends a frame, recording it at loop time `t_s`.
    ///
    /// # Errors
    /// Link errors, or a failed write of the recording.
    pub async fn send(&mut self, frame: &CanFrame, t_s: f64) -> LinkResult<()> {
        match &self.transport {
            Transport::Slcan { line, .. } => line.write_all(encode_frame(frame).as_bytes()).await?,
            Transport::SocketCan(port) => port.send(frame).await?,
        }
        self.record(frame, t_s)
    }

    /// On SLCAN, writes a line no adapter understands (`X?!` CR) and returns true; on
    /// SocketCAN there is no such thing, and it returns false.
    ///
    /// # Errors
    /// Link errors.
    pub async fn send_garbage_line(&mut self) -> LinkResult<bool> {
        match &self.transport {
            Transport::Slcan { line, .. } => {
                line.write_all(b"X?!\r").await?;
                Ok(true)
            }
            Transport::SocketCan(_) => Ok(false),
        }
    }

    /// Waits for the next frame and records it at loop time `t_s`. Cancel-safe.
    ///
    /// # Errors
    /// Link errors ([`LinkError::HangUp`] when the device end closed).
    pub async fn recv(&mut self, t_s: f64) -> LinkResult<CanFrame> {
        let frame = match &mut self.transport {
            Transport::Slcan {
                line,
                decoder,
                received,
                refusals,
            } => loop {
                if let Some(frame) = received.pop_front() {
                    break frame;
                }
                let mut buf = [0u8; 4096];
                let n = line.read(&mut buf).await?;
                for event in decoder.push(&buf[..n]) {
                    match event {
                        Ok(SlcanMessage::Frame(frame)) => received.push_back(frame),
                        Ok(SlcanMessage::Nack) => *refusals += 1,
                        _ => {}
                    }
                }
            },
            Transport::SocketCan(port) => port.recv().await?,
        };
        self.record(&frame, t_s)?;
        Ok(frame)
    }

    fn record(&mut self, frame: &CanFrame, t_s: f64) -> LinkResult<()> {
        let Some(capture) = &mut self.capture else {
            return Ok(());
        };
        let separator = match frame.format() {
            FrameFormat::Fd { brs, esi } => {
                format!("##{:X}", u8::from(brs) | (u8::from(esi) << 1))
            }
            FrameFormat::Remote => "#R".to_owned(),
            FrameFormat::Classical => "#".to_owned(),
        };
        let data = if frame.is_remote() {
            String::new()
        } else {
            hex_upper(frame.data())
        };
        writeln!(
            capture.out,
            "({t_s:.6}) {} {}{separator}{data}",
            capture.iface,
            frame.id()
        )
        .and_then(|()| capture.out.flush())
        .map_err(|source| LinkError::Capture {
            link: capture.path.clone(),
            source,
        })
    }
}

impl Transport {
    fn slcan(line: SerialLine) -> Transport {
        Transport::Slcan {
            line,
            decoder: SlcanDecoder::new(),
            received: VecDeque::new(),
            refusals: 0,
        }
    }
}
