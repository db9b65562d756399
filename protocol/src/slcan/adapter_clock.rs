//! An adapter's receive timestamps (Lawicel `Z1`: 4 hex digits of milliseconds, 0 to EA5F,
//! wrapping every minute) placed on the host's clock.
//!
//! A frame reaches the host some time after the adapter stamped it (USB or UART transfer,
//! the FTDI latency timer, the host's wake-up), and the adapter's clock runs on its own
//! crystal. [`AdapterClock`] keeps the smallest offset between the host's read time and the
//! adapter's time seen so far (the transfer with the least delay), relaxing it by
//! [`DRIFT_ALLOWANCE`] (two crystals' worst disagreement) so a slow adapter clock is followed.
//! A frame then left the bus within the stamp's millisecond after `adapter time + offset`: the
//! estimate is the host's read time where that agrees, else the end of that millisecond (a
//! frame held back by the transfer is placed where its stamp says). Estimates never come
//! after the read time and never go backwards.

use std::time::Duration;

/// The adapter's stamps wrap at this many milliseconds (stamps run 0 to 0xEA5F).
pub const STAMP_MODULUS_MS: u16 = 60_000;

/// How fast the offset may grow, s per s: 200 ppm, two ordinary crystals' worst
/// disagreement (an adapter clock running slow makes the observed offset grow).
pub const DRIFT_ALLOWANCE: f64 = 200e-6;

/// One stamp's resolution, s.
const STAMP_RESOLUTION_S: f64 = 1e-3;

/// The last stamped frame and the estimates made for it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct LastStamp {
    stamp_ms: u16,
    read_at_s: f64,
    /// The adapter's time of the stamp, unwrapped, s.
    adapter_s: f64,
    /// Host time minus adapter time, the smallest seen (relaxed by the drift allowance), s.
    offset_s: f64,
    /// The estimate made for it, s.
    on_bus_s: f64,
}

/// Places an adapter's millisecond stamps on the host's clock (times as durations since an
/// origin of the caller's choosing). No I/O, no clock of its own.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AdapterClock {
    last: Option<LastStamp>,
    stamps: u64,
}

impl AdapterClock {
    /// A clock that has seen no stamp.
    #[must_use]
    pub fn new() -> AdapterClock {
        AdapterClock::default()
    }

    /// Stamps placed so far.
    #[must_use]
    pub fn stamps(&self) -> u64 {
        self.stamps
    }

    /// A frame stamped `stamp_ms` (taken modulo [`STAMP_MODULUS_MS`]) was read at `read_at`:
    /// when it left the bus, on the same clock as `read_at`.
    pub fn on_bus_at(&mut self, stamp_ms: u16, read_at: Duration) -> Duration {
        let stamp_ms = stamp_ms % STAMP_MODULUS_MS;
        let read_at_s = read_at.as_secs_f64();
        let (adapter_s, offset_s, floor_s) = match self.last {
            None => {
                let adapter_s = f64::from(stamp_ms) * STAMP_RESOLUTION_S;
                (adapter_s, read_at_s - adapter_s, 0.0)
            }
            Some(last) => {
                let adapter_s = last.adapter_s + adapter_step_s(last, stamp_ms, read_at_s);
                let relaxed = last.offset_s + DRIFT_ALLOWANCE * (read_at_s - last.read_at_s);
                (adapter_s, relaxed.min(read_at_s - adapter_s), last.on_bus_s)
            }
        };
        let latest_s = adapter_s + offset_s + STAMP_RESOLUTION_S;
        let on_bus_s = read_at_s.min(latest_s).max(floor_s);
        self.last = Some(LastStamp {
            stamp_ms,
            read_at_s,
            adapter_s,
            offset_s,
            on_bus_s,
        });
        self.stamps += 1;
        Duration::from_secs_f64(on_bus_s.max(0.0))
    }
}

/// The adapter time between `last` and a stamp `stamp_ms` read at `read_at_s`, s: the step
/// of the stamps plus as many whole minutes (wraps) as the host's clock says went by.
fn adapter_step_s(last: LastStamp, stamp_ms: u16, read_at_s: f64) -> f64 {
    let modulus = f64::from(STAMP_MODULUS_MS);
    let wrap = u32::from(STAMP_MODULUS_MS);
    let step_ms = f64::from((u32::from(stamp_ms) + wrap - u32::from(last.stamp_ms)) % wrap);
    let host_ms = (read_at_s - last.read_at_s) / STAMP_RESOLUTION_S;
    let wraps = ((host_ms - step_ms) / modulus).round().max(0.0);
    (step_ms + wraps * modulus) * STAMP_RESOLUTION_S
}

/// The stamp a device sends for a frame `elapsed` after its clock started.
#[must_use]
pub fn stamp_at(elapsed: Duration) -> u16 {
    (elapsed.as_millis() % u128::from(STAMP_MODULUS_MS)) as u16
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(value: f64) -> Duration {
        Duration::from_secs_f64(value * 1e-3)
    }

    fn in_ms(time: Duration) -> f64 {
        time.as_secs_f64() * 1e3
    }

    #[test]
    fn a_delayed_frame_is_placed_where_its_stamp_says() {
        let mut clock = AdapterClock::new();
        // Stamp 100 read at host 1000.2 ms: offset 900.2 ms.
        assert!((in_ms(clock.on_bus_at(100, ms(1000.2))) - 1000.2).abs() < 1e-9);
        // Stamp 110 read promptly (0.4 ms after its millisecond began): the read time.
        assert!((in_ms(clock.on_bus_at(110, ms(1010.4))) - 1010.4).abs() < 1e-6);
        // Stamp 120 read 7 ms late (a USB burst): placed at the end of its millisecond.
        let placed = in_ms(clock.on_bus_at(120, ms(1027.0)));
        assert!((placed - 1021.2).abs() < 0.01, "{placed}");
        assert_eq!(clock.stamps(), 3);
    }

    #[test]
    fn stamps_wrap_each_minute_and_long_gaps_count_their_wraps() {
        let mut clock = AdapterClock::new();
        clock.on_bus_at(59_990, ms(10.0));
        // 20 ms later the stamp has wrapped to 10.
        let placed = in_ms(clock.on_bus_at(10, ms(30.0)));
        assert!((placed - 30.0).abs() < 1e-6, "{placed}");
        // Two minutes and 5 ms of silence: the same stamp step plus two wraps.
        let placed = in_ms(clock.on_bus_at(15, ms(120_035.0)));
        assert!((placed - 120_035.0).abs() < 0.03, "{placed}");
        assert_eq!(stamp_at(Duration::from_millis(60_001)), 1);
        assert_eq!(stamp_at(Duration::from_millis(59_999)), 59_999);
        // Out-of-range stamps are taken modulo the wrap.
        let mut other = AdapterClock::new();
        let placed = in_ms(other.on_bus_at(60_005, ms(7.0)));
        assert!((placed - 7.0).abs() < 1e-9, "{placed}");
    }

    #[test]
    fn estimates_never_pass_the_read_time_nor_go_backwards_and_follow_a_slow_adapter() {
        let mut clock = AdapterClock::new();
        let mut previous = Duration::ZERO;
        // An adapter whose clock runs 100 ppm slow, frames every 10 ms for 10 minutes, read
        // 0.2 to 3 ms after they left the bus.
        for k in 0..60_000u64 {
            let host_ms = 10.0 * k as f64;
            let adapter_ms = (host_ms * (1.0 - 100e-6)).floor();
            let delay_ms = 0.2 + 2.8 * ((k * 7919) % 13) as f64 / 12.0;
            let read = ms(host_ms + delay_ms);
            let stamp = (adapter_ms as u64 % 60_000) as u16;
            let placed = clock.on_bus_at(stamp, read);
            assert!(
                placed <= read,
                "frame {k}: {placed:?} after its read at {read:?}"
            );
            assert!(placed >= previous, "frame {k} went backwards");
            // Within the stamp's millisecond plus the drift the allowance lets through.
            assert!(
                (in_ms(placed) - host_ms).abs() < 1.5,
                "frame {k}: placed at {} ms, left at {host_ms} ms",
                in_ms(placed)
            );
            previous = placed;
        }
    }
}
