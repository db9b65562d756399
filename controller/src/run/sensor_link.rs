//! The controller's end of the sensor: the ILD 2300's RS422 stream (the protocol's
//! [`IldLink`], host end), recorded raw byte for byte, decoded into (counter, value) samples.
//! Each output cycle holds the values `GETOUTINFO_RS422` lists, in that order
//! ([`SampleLayout`]): the distance, and the 18-bit measured-value counter when the sensor sends
//! it (`OUTADD_RS422 COUNTER`); a sensor without the counter gets the running count of cycles,
//! so its samples are placed by their arrival alone. A sensor on the mirror's CAN link sends
//! Distance frames instead; [`super::mirror_link`] collects those. [`IldSampleDecoder`] is the
//! same decoding fed with bytes directly, for a loop run in one process.

use std::collections::VecDeque;
use std::time::Duration;

use scanhil_protocol::ild::IldValue;
use scanhil_protocol::ild::command::{AddValue, IldOutputInfo, OutputValue};
use scanhil_protocol::ild::stream::encode_cycle;
use scanhil_protocol::ild::value::RAW_MAX;
use scanhil_protocol::link::ild::{IldCounters, IldCycle, IldCycleAssembler, IldLink};
use scanhil_protocol::link::role::Role;
use scanhil_protocol::link::{ByteCapture, LinkError, LinkUri, PtyPair};

use super::chunked::Chunked;
use super::loop_error::LoopError;
use super::pairing::ArrivalBound;
use super::sample_log::{CountedSample, SampleLog};

/// Where a cycle's values are: how many, the distance's place and the counter's (when the
/// sensor sends one), as `GETOUTINFO_RS422` lists them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleLayout {
    /// Values per cycle.
    pub values: usize,
    /// The distance's place (0: the cycle's first value).
    pub distance: usize,
    /// The counter's place, if the cycle has one.
    pub counter: Option<usize>,
}

impl SampleLayout {
    /// A cycle of the distance alone (a sensor taken as it is, before its output is known).
    pub const DISTANCE_ONLY: SampleLayout = SampleLayout {
        values: 1,
        distance: 0,
        counter: None,
    };

    /// The layout of cycles holding `info`'s values; `None` without a distance (`DIST1`).
    #[must_use]
    pub fn of(info: &IldOutputInfo) -> Option<SampleLayout> {
        Some(SampleLayout {
            values: info.values.len(),
            distance: info.position(OutputValue::Dist1)?,
            counter: info.position(OutputValue::Add(AddValue::Counter)),
        })
    }

    /// The sample a cycle carries: its counter (`None` when the layout has none) and its
    /// distance; `None` when the cycle lost one of them (counted as incomplete by the link).
    #[must_use]
    pub fn sample(&self, cycle: &IldCycle) -> Option<(Option<u32>, IldValue)> {
        let raw = |index: usize| match index {
            0 => Some(cycle.distance.raw()),
            i => cycle.extras.get(i - 1).copied(),
        };
        let distance = IldValue::from_raw(raw(self.distance)?);
        match self.counter {
            None => Some((None, distance)),
            Some(index) => Some((Some(raw(index)?), distance)),
        }
    }
}

/// What the sensor link saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct SensorCounters {
    /// Samples decoded.
    pub samples: u64,
    /// Counter values missing between received samples (0 on a healthy link).
    pub counter_gaps: u64,
    /// Bytes skipped to resynchronise.
    pub resync_bytes: u64,
    /// Cycles that arrived without their counter.
    pub incomplete_cycles: u64,
}

/// The sensor's link.
#[derive(Debug)]
pub enum SensorLink {
    /// No sensor, or its distances arrive on the mirror's CAN link.
    Elsewhere,
    /// The ILD stream.
    Ild(Box<IldStream>),
}

/// The host end of an ILD stream and what it delivered.
#[derive(Debug)]
pub struct IldStream {
    link: IldLink,
    layout: SampleLayout,
    log: SampleLog,
}

/// The ILD stream's bytes decoded into samples without I/O: what the host end of an
/// [`IldLink`] does with the bytes it reads, for bytes handed over in memory.
#[derive(Debug)]
pub struct IldSampleDecoder {
    assembler: IldCycleAssembler,
    layout: SampleLayout,
    cycles: VecDeque<IldCycle>,
    log: SampleLog,
}

impl SensorLink {
    /// Opens an `ild:` link.
    ///
    /// # Errors
    /// [`LinkError`] naming the link; a CAN URI is refused.
    pub fn open(uri: &LinkUri) -> Result<SensorLink, LinkError> {
        Ok(Self::on(IldLink::open(uri, Role::Host)?))
    }

    /// The ILD stream on the master end of a pty pair whose slave the emulator opens, standing
    /// for a line at `baud`.
    ///
    /// # Errors
    /// [`LinkError`] if the line cannot be set up.
    pub fn on_pty(pair: PtyPair, baud: u32) -> Result<SensorLink, LinkError> {
        Ok(Self::on(IldLink::open_pty(pair, baud, Role::Host)?))
    }

    fn on(link: IldLink) -> SensorLink {
        let mut stream = IldStream {
            link,
            layout: SampleLayout::DISTANCE_ONLY,
            log: SampleLog::new(),
        };
        stream.set_layout(SampleLayout::DISTANCE_ONLY);
        SensorLink::Ild(Box::new(stream))
    }

    /// Decodes the cycles by `layout` from now on (the sensor's `GETOUTINFO_RS422`; the
    /// distance alone until told). Nothing when the sensor is elsewhere.
    pub fn set_layout(&mut self, layout: SampleLayout) {
        if let SensorLink::Ild(stream) = self {
            stream.set_layout(layout);
        }
    }

    /// The host end of the ILD line, for commands (`None`: the sensor is elsewhere).
    pub fn ild_link_mut(&mut self) -> Option<&mut IldLink> {
        match self {
            SensorLink::Elsewhere => None,
            SensorLink::Ild(stream) => Some(&mut stream.link),
        }
    }

    /// Bounds the sensor's clock from the arrivals of the samples from now on (see
    /// [`ArrivalBound`]; nothing when the sensor is elsewhere).
    pub fn bound_clock_by_arrivals(&mut self, bound: ArrivalBound) {
        if let SensorLink::Ild(stream) = self {
            stream.log.bound_clock_by_arrivals(bound);
        }
    }

    /// Lockstep: the next period's frames started going out at `at` (for the arrival bound).
    pub fn period_started(&mut self, at: tokio::time::Instant) {
        if let SensorLink::Ild(stream) = self {
            stream.log.period_started(at);
        }
    }

    /// The arrival bound on the sensor's clock, taken out (`None` if none was asked for).
    pub fn take_arrival_bound(&mut self) -> Option<ArrivalBound> {
        match self {
            SensorLink::Elsewhere => None,
            SensorLink::Ild(stream) => stream.log.take_arrival_bound(),
        }
    }

    /// Records every received byte into `out` (a raw capture `scanhil decode --format ild`
    /// reads); nothing when the sensor is elsewhere.
    pub fn record_to(&mut self, out: impl std::io::Write + Send + 'static) {
        if let SensorLink::Ild(stream) = self {
            stream.link.set_capture(ByteCapture::new(out));
        }
    }

    /// Reads and decodes until the link fails; never returns otherwise (a link that is
    /// elsewhere never returns). Cancel-safe: meant to run beside the mirror exchange.
    pub async fn pump(&mut self) -> LoopError {
        match self {
            SensorLink::Elsewhere => std::future::pending().await,
            SensorLink::Ild(stream) => loop {
                match stream.link.recv_cycle().await {
                    Ok(cycle) => add_cycle(&mut stream.log, stream.layout, &cycle),
                    Err(error) => return error.into(),
                }
            },
        }
    }

    /// Busy-polling: decodes what the link has now, without waiting.
    ///
    /// # Errors
    /// The link's failure (as [`Self::pump`] returns it).
    pub fn try_pump(&mut self) -> Result<(), LoopError> {
        if let SensorLink::Ild(stream) = self {
            while let Some(cycle) = stream.link.try_recv_cycle()? {
                add_cycle(&mut stream.log, stream.layout, &cycle);
            }
        }
        Ok(())
    }

    /// Reads what is still in flight: until the peer hangs up or nothing arrives for `quiet`;
    /// then writes the rest of the recording.
    ///
    /// # Errors
    /// A link error other than the hang-up; the recording's.
    pub async fn drain(&mut self, quiet: Duration) -> Result<(), LinkError> {
        let SensorLink::Ild(stream) = self else {
            return Ok(());
        };
        loop {
            match stream.link.recv_cycle_timeout(quiet).await {
                Ok(None) | Err(LinkError::HangUp { .. }) => return stream.link.flush_capture(),
                Err(error) => return Err(error),
                Ok(Some(cycle)) => add_cycle(&mut stream.log, stream.layout, &cycle),
            }
        }
    }

    /// The samples and counters so far (the link stays open).
    #[must_use]
    pub fn snapshot(&self) -> (Vec<CountedSample>, SensorCounters) {
        match self {
            SensorLink::Elsewhere => (Vec::new(), SensorCounters::default()),
            SensorLink::Ild(stream) => (
                stream.log.samples().iter().copied().collect(),
                counters(&stream.log, stream.link.counters()),
            ),
        }
    }

    /// The samples and counters, handed over without a copy; the link's log is empty
    /// afterwards.
    pub fn take_samples(&mut self) -> (Chunked<CountedSample>, SensorCounters) {
        match self {
            SensorLink::Elsewhere => (Chunked::new(), SensorCounters::default()),
            SensorLink::Ild(stream) => {
                let counters = counters(&stream.log, stream.link.counters());
                (stream.log.take_samples(), counters)
            }
        }
    }
}

impl IldStream {
    fn set_layout(&mut self, layout: SampleLayout) {
        self.layout = layout;
        self.link.set_values_per_cycle(layout.values);
    }
}

impl IldSampleDecoder {
    /// A decoder of cycles laid out as `layout`.
    #[must_use]
    pub fn new(layout: SampleLayout) -> IldSampleDecoder {
        IldSampleDecoder {
            assembler: IldCycleAssembler::new(layout.values),
            layout,
            cycles: VecDeque::new(),
            log: SampleLog::new(),
        }
    }

    /// Decodes bytes of the stream, received at `arrived`.
    pub fn push(&mut self, bytes: &[u8], arrived: tokio::time::Instant) {
        self.assembler.push(bytes, arrived, &mut self.cycles);
        for cycle in self.cycles.drain(..) {
            add_cycle(&mut self.log, self.layout, &cycle);
        }
    }

    /// One output cycle of `values` handed over in memory (no bytes between the two ends),
    /// taken as [`Self::push`] takes its bytes (a property test below holds the two to the
    /// same samples and counters): a whole cycle of the layout, with no other half assembled,
    /// goes straight to the log, each value kept to the stream's 18 bits; any other goes
    /// through its bytes, so it is counted as the line would count it.
    pub fn push_cycle(&mut self, values: &[u32], arrived: tokio::time::Instant) {
        match values.split_first() {
            Some((&first, extras))
                if values.len() == self.layout.values && self.assembler.is_between_cycles() =>
            {
                let cycle = IldCycle {
                    distance: IldValue::from_raw(first & RAW_MAX),
                    extras: extras.iter().map(|value| value & RAW_MAX).collect(),
                    arrived,
                    offset: 0,
                };
                add_cycle(&mut self.log, self.layout, &cycle);
            }
            _ => self.push(&encode_cycle(values), arrived),
        }
    }

    /// The samples and counters, handed over without a copy.
    #[must_use]
    pub fn finish(mut self) -> (Chunked<CountedSample>, SensorCounters) {
        let counters = counters(&self.log, self.assembler.counters());
        (self.log.take_samples(), counters)
    }
}

/// Adds a decoded cycle: its distance, with its counter when the sensor sends one (a cycle
/// that lost either is left out: it cannot be placed).
fn add_cycle(log: &mut SampleLog, layout: SampleLayout, cycle: &IldCycle) {
    if let Some((counter, distance)) = layout.sample(cycle) {
        log.add(counter, distance, cycle.arrived);
    }
}

/// The log's counters, with the line's.
fn counters(log: &SampleLog, line: &IldCounters) -> SensorCounters {
    SensorCounters {
        samples: log.samples().len() as u64,
        counter_gaps: log.counter_gaps(),
        resync_bytes: line.skipped_bytes,
        incomplete_cycles: line.incomplete_cycles,
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    fn decoded(
        layout: SampleLayout,
        cycles: &[Vec<u32>],
        hand_over: impl Fn(&mut IldSampleDecoder, &[u32], tokio::time::Instant),
    ) -> (Vec<CountedSample>, SensorCounters) {
        let mut decoder = IldSampleDecoder::new(layout);
        let arrived = tokio::time::Instant::now();
        for cycle in cycles {
            hand_over(&mut decoder, cycle, arrived);
        }
        let (samples, counters) = decoder.finish();
        (samples.into_iter().collect(), counters)
    }

    proptest! {
        /// Cycles handed over in memory give the samples and counters their bytes give,
        /// whole cycles of the layout and others alike, values beyond 18 bits included.
        #[test]
        fn cycles_handed_over_decode_as_their_bytes(
            cycles in prop::collection::vec(
                prop::collection::vec(any::<u32>(), 0..4),
                0..20,
            ),
            with_counter in any::<bool>(),
        ) {
            let layout = SampleLayout {
                values: 2,
                distance: 0,
                counter: with_counter.then_some(1),
            };
            let through_bytes = decoded(layout, &cycles, |decoder, values, arrived| {
                decoder.push(&encode_cycle(values), arrived);
            });
            let handed_over = decoded(layout, &cycles, IldSampleDecoder::push_cycle);
            prop_assert_eq!(handed_over, through_bytes);
        }
    }
}
