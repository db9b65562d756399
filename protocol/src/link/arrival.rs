//! When a received frame arrived: the time this program read it, and the best estimate of
//! when it was on the bus (the kernel's receive timestamp on SocketCAN, the adapter's on an
//! SLCAN adapter with timestamps on, else the read time).

use std::time::{Duration, SystemTime};

use tokio::time::Instant;

/// Where [`Arrival::on_bus_at`] comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ArrivalSource {
    /// The time this program read the frame (no better time was given).
    Read,
    /// The kernel's receive timestamp (`SO_TIMESTAMPNS`), taken when the frame entered the
    /// socket layer.
    Kernel,
    /// The SLCAN adapter's receive timestamp (Lawicel `Z1`, millisecond resolution), placed
    /// on the host's clock ([`crate::slcan::adapter_clock::AdapterClock`]).
    Adapter,
}

/// When a received frame arrived.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Arrival {
    /// When this program read it from the link.
    pub read_at: Instant,
    /// When it was on the bus, at the latest `read_at`.
    pub on_bus_at: Instant,
    /// Where `on_bus_at` comes from.
    pub source: ArrivalSource,
}

impl Arrival {
    /// A frame read at `read_at` with no better time.
    #[must_use]
    pub fn read(read_at: Instant) -> Arrival {
        Arrival {
            read_at,
            on_bus_at: read_at,
            source: ArrivalSource::Read,
        }
    }

    /// A frame read at `read_at` (when the wall clock read `wall_now`) that the kernel
    /// stamped `kernel` on the wall clock: the stamp moved onto the monotonic clock, never
    /// after the read (a wall clock stepped backwards gives the read time).
    #[must_use]
    pub fn kernel(read_at: Instant, wall_now: SystemTime, kernel: SystemTime) -> Arrival {
        let age = wall_now.duration_since(kernel).unwrap_or(Duration::ZERO);
        Arrival {
            read_at,
            on_bus_at: read_at.checked_sub(age).unwrap_or(read_at),
            source: ArrivalSource::Kernel,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_kernel_stamp_is_moved_onto_the_monotonic_clock_and_never_after_the_read() {
        let read_at = Instant::now();
        let wall_now = SystemTime::UNIX_EPOCH + Duration::from_secs(1_700_000_000);
        let stamped = Arrival::kernel(read_at, wall_now, wall_now - Duration::from_micros(250));
        assert_eq!(stamped.on_bus_at, read_at - Duration::from_micros(250));
        assert_eq!(stamped.source, ArrivalSource::Kernel);
        let future = Arrival::kernel(read_at, wall_now, wall_now + Duration::from_secs(1));
        assert_eq!(future.on_bus_at, read_at);
        let plain = Arrival::read(read_at);
        assert_eq!(
            (plain.on_bus_at, plain.source),
            (read_at, ArrivalSource::Read)
        );
    }
}
