//! A sensor's samples as they arrive, on whichever link carries them (the ILD line, or
//! Distance frames on the mirror's CAN link): counters unwrapped, samples kept in chunks, and,
//! when the loop asks for it, the bound their arrivals give on the sensor's clock
//! ([`ArrivalBound`]). Nothing is kept per sample but its counter and value.

use scanhil_protocol::ild::IldValue;

use super::chunked::Chunked;
use super::pairing::{ArrivalBound, CounterUnwrapper};

/// The ILD counter's modulus (18 bits).
pub const ILD_COUNTER_MODULUS: u64 = 1 << 18;

/// One decoded sensor sample: unwrapped counter and value (16 bytes: a long run keeps one a
/// sample; their arrivals go into an [`ArrivalBound`] instead of being kept).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CountedSample {
    /// The measured-value counter, unwrapped (monotonic).
    pub counter: u64,
    /// The distance or error.
    pub value: IldValue,
}

/// A sensor's samples in the order they arrived, with their counters unwrapped.
#[derive(Debug, Clone)]
pub struct SampleLog {
    unwrapper: CounterUnwrapper,
    samples: Chunked<CountedSample>,
    arrivals: Option<ArrivalBound>,
}

impl SampleLog {
    /// An empty log that bounds no clock.
    #[must_use]
    pub fn new() -> SampleLog {
        SampleLog {
            unwrapper: CounterUnwrapper::new(ILD_COUNTER_MODULUS),
            samples: Chunked::new(),
            arrivals: None,
        }
    }

    /// Bounds the sensor's clock from the arrivals of the samples from now on.
    pub fn bound_clock_by_arrivals(&mut self, bound: ArrivalBound) {
        self.arrivals = Some(bound);
    }

    /// Lockstep: the next period's frames started going out at `at` (for the arrival bound).
    pub fn period_started(&mut self, at: tokio::time::Instant) {
        if let Some(arrivals) = &mut self.arrivals {
            arrivals.period_started(at);
        }
    }

    /// Adds a sample that arrived at `arrived` with its raw 18-bit counter (`None`: a sensor
    /// that sends none gets the running count of samples).
    pub fn add(
        &mut self,
        raw_counter: Option<u32>,
        value: IldValue,
        arrived: tokio::time::Instant,
    ) {
        let counter = match raw_counter {
            Some(raw) => self.unwrapper.unwrap(u64::from(raw)),
            None => self.samples.len() as u64,
        };
        if let Some(arrivals) = &mut self.arrivals {
            arrivals.note(arrived, counter);
        }
        self.samples.push(CountedSample { counter, value });
    }

    /// The samples held, in order.
    #[must_use]
    pub fn samples(&self) -> &Chunked<CountedSample> {
        &self.samples
    }

    /// Counter values missing between the samples (0 on a healthy link).
    #[must_use]
    pub fn counter_gaps(&self) -> u64 {
        self.unwrapper.missing()
    }

    /// The samples, handed over without a copy; the log holds none afterwards.
    pub fn take_samples(&mut self) -> Chunked<CountedSample> {
        std::mem::take(&mut self.samples)
    }

    /// The arrival bound on the sensor's clock, taken out (`None` if none was asked for).
    pub fn take_arrival_bound(&mut self) -> Option<ArrivalBound> {
        self.arrivals.take()
    }
}

impl Default for SampleLog {
    fn default() -> Self {
        SampleLog::new()
    }
}
