//! The controller's end of the sensor: the ILD 2300's RS422 stream on a serial line or pty,
//! recorded raw byte for byte, decoded into (counter, value) samples. Each output cycle is a
//! distance value, then (when the sensor sends it, `OUTADD_RS422 COUNTER`) its 18-bit
//! measured-value counter; a sensor without the counter gets the running count of cycles.
//! A sensor on the mirror's CAN link sends Distance frames instead; [`super::mirror_link`]
//! collects those.

use std::fs::File;
use std::io::Write;
use std::path::Path;
use std::time::Duration;

use scanhil_protocol::ild::IldValue;
use scanhil_protocol::ild::stream::IldDecoder;
use scanhil_protocol::link::{LinkError, LinkUri, PtyPair, SerialLine};

use super::mirror_link::LoopError;
use super::pairing::CounterUnwrapper;

/// The ILD counter's modulus (18 bits).
pub const ILD_COUNTER_MODULUS: u64 = 1 << 18;

/// One decoded sensor sample: unwrapped counter and value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CountedSample {
    /// The measured-value counter, unwrapped (monotonic).
    pub counter: u64,
    /// The distance or error.
    pub value: IldValue,
}

/// What the sensor link saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct SensorCounters {
    /// Bytes received.
    pub bytes: u64,
    /// Samples decoded.
    pub samples: u64,
    /// Counter values missing between received samples (0 on a healthy link).
    pub counter_gaps: u64,
    /// Bytes skipped to resynchronise.
    pub resync_bytes: u64,
}

/// The sensor's link.
#[derive(Debug)]
pub enum SensorLink {
    /// No sensor, or its distances arrive on the mirror's CAN link.
    Elsewhere,
    /// The ILD stream.
    Ild(IldStream),
}

/// The host end of an ILD stream.
#[derive(Debug)]
pub struct IldStream {
    line: SerialLine,
    capture: Option<File>,
    decoder: IldDecoder,
    cycle: Vec<u32>,
    unwrapper: CounterUnwrapper,
    samples: Vec<CountedSample>,
    counters: SensorCounters,
}

impl SensorLink {
    /// Opens an `ild:` link.
    ///
    /// # Errors
    /// [`LinkError`] naming the link; a CAN URI is refused.
    pub fn open(uri: &LinkUri) -> Result<SensorLink, LinkError> {
        match uri {
            LinkUri::Ild { path, baud } => Ok(SensorLink::Ild(IldStream::new(SerialLine::open(
                path,
                *baud,
                &uri.to_string(),
            )?))),
            other => Err(LinkError::Protocol {
                link: other.to_string(),
                detail: "the sensor link must be `ild:PATH[@BAUD]` (Distance frames on CAN \
                         arrive on the mirror's link)"
                    .into(),
            }),
        }
    }

    /// The ILD stream on the master end of a pty pair whose slave the emulator opens.
    ///
    /// # Errors
    /// [`LinkError`] if the line cannot be set up.
    pub fn on_pty(pair: PtyPair, name: &str) -> Result<SensorLink, LinkError> {
        Ok(SensorLink::Ild(IldStream::new(SerialLine::from_pty(
            pair, name,
        )?)))
    }

    /// Records every received byte into `path` (a raw capture `scanhil decode --format ild`
    /// reads).
    ///
    /// # Errors
    /// The file cannot be created.
    pub fn record_to(&mut self, path: &Path) -> std::io::Result<()> {
        if let SensorLink::Ild(stream) = self {
            stream.capture = Some(File::create(path)?);
        }
        Ok(())
    }

    /// Reads and decodes until the link fails; never returns otherwise (a link that is
    /// elsewhere never returns). Cancel-safe: meant to run beside the mirror exchange.
    pub async fn pump(&mut self) -> LoopError {
        match self {
            SensorLink::Elsewhere => std::future::pending().await,
            SensorLink::Ild(stream) => loop {
                if let Err(error) = stream.read_once().await {
                    return error.into();
                }
            },
        }
    }

    /// Reads what is still in flight: until the peer hangs up or nothing arrives for `quiet`.
    ///
    /// # Errors
    /// A link error other than the hang-up.
    pub async fn drain(&mut self, quiet: Duration) -> Result<(), LinkError> {
        let SensorLink::Ild(stream) = self else {
            return Ok(());
        };
        loop {
            match tokio::time::timeout(quiet, stream.read_once()).await {
                Err(_) | Ok(Err(LinkError::HangUp { .. })) => return Ok(()),
                Ok(Err(error)) => return Err(error),
                Ok(Ok(())) => {}
            }
        }
    }

    /// The samples and counters so far (the link stays open).
    #[must_use]
    pub fn snapshot(&self) -> (Vec<CountedSample>, SensorCounters) {
        match self {
            SensorLink::Elsewhere => (Vec::new(), SensorCounters::default()),
            SensorLink::Ild(stream) => {
                let mut counters = stream.counters;
                counters.counter_gaps = stream.unwrapper.missing();
                (stream.samples.clone(), counters)
            }
        }
    }

    /// The decoded samples and counters.
    #[must_use]
    pub fn into_samples(self) -> (Vec<CountedSample>, SensorCounters) {
        match self {
            SensorLink::Elsewhere => (Vec::new(), SensorCounters::default()),
            SensorLink::Ild(mut stream) => {
                stream.end_cycle();
                stream.counters.counter_gaps = stream.unwrapper.missing();
                (stream.samples, stream.counters)
            }
        }
    }
}

impl IldStream {
    fn new(line: SerialLine) -> IldStream {
        IldStream {
            line,
            capture: None,
            decoder: IldDecoder::new(),
            cycle: Vec::new(),
            unwrapper: CounterUnwrapper::new(ILD_COUNTER_MODULUS),
            samples: Vec::new(),
            counters: SensorCounters::default(),
        }
    }

    async fn read_once(&mut self) -> Result<(), LinkError> {
        let mut buf = [0u8; 4096];
        let n = self.line.read(&mut buf).await?;
        let bytes = &buf[..n];
        self.counters.bytes += n as u64;
        if let Some(capture) = &mut self.capture {
            capture
                .write_all(bytes)
                .map_err(|source| LinkError::Capture {
                    link: self.line.name().to_owned(),
                    source,
                })?;
        }
        for event in self.decoder.push(bytes) {
            match event {
                Ok(word) => {
                    if word.first_in_cycle {
                        self.end_cycle();
                    }
                    self.cycle.push(word.raw);
                }
                Err(gap) => {
                    self.counters.resync_bytes += gap.len;
                    self.cycle.clear();
                }
            }
        }
        Ok(())
    }

    /// Turns the collected cycle (value, then optionally the counter) into a sample.
    fn end_cycle(&mut self) {
        let Some(&raw) = self.cycle.first() else {
            return;
        };
        let counter = match self.cycle.get(1) {
            Some(&counter) => self.unwrapper.unwrap(u64::from(counter)),
            None => self.counters.samples,
        };
        self.samples.push(CountedSample {
            counter,
            value: IldValue::from_raw(raw),
        });
        self.counters.samples += 1;
        self.cycle.clear();
    }
}
