//! The timing limits both ends of the loop hold a run to, checked before anything opens: the
//! host checks a scenario's `timing` and its command-line overrides against them, the
//! emulator its `serve` flags, conformance its own; so a value one end would take is never one
//! the other end cannot (an allowance of `1e300` s passed the host's check and made the
//! emulator panic converting it to a `Duration`).

use crate::validation::{Allowed, Invalid, check_count};

/// The longest run, s: an hour of 20 kHz loop (72 million periods).
pub const DURATION_S: Allowed = Allowed::above(0.0, 3600.0, "s");

/// A lockstep answer allowance, s: a debug build on a busy machine needs up to about a
/// second; a minute per period is a hung peer, not a slow one.
pub const ANSWER_ALLOWANCE_S: Allowed = Allowed::above(0.0, 60.0, "s");

/// A loop's control rate, Hz: ten times the paper's 20 kHz. Beyond it the buffers sized in
/// periods (a power limit's window, a delay line) grow past any memory (a scene at 2e25 Hz
/// once asked for a 1.6e14-byte window).
pub const CONTROL_RATE_HZ: Allowed = Allowed::above(0.0, 200_000.0, "Hz");

/// The real-time wake-up probe before the loop, s (0: none).
pub const PROBE_S: Allowed = Allowed::closed(0.0, 60.0, "s");

/// The most missed periods a watchdog may allow.
pub const MAX_WATCHDOG_PERIODS: u64 = 100_000_000;

/// The longest a watchdog may wait in all (its periods times each one's allowance), s: a day.
/// Beyond it there is no watchdog at all, only a run that cannot end by itself.
pub const MAX_WATCHDOG_S: f64 = 86_400.0;

/// Checks a watchdog of `periods` missed periods of `allowance_s` each (the lockstep answer
/// allowance, or the control period in real time); `field` names the periods.
///
/// # Errors
/// No period allowed, more than [`MAX_WATCHDOG_PERIODS`], or a whole wait above
/// [`MAX_WATCHDOG_S`].
pub fn check_watchdog(field: &str, periods: u32, allowance_s: f64) -> Result<(), Invalid> {
    check_count(
        field,
        u64::from(periods),
        1,
        MAX_WATCHDOG_PERIODS,
        "periods",
    )?;
    let whole_s = f64::from(periods) * allowance_s;
    if whole_s > MAX_WATCHDOG_S {
        return Err(Invalid::new(
            field,
            format!(
                "{periods} periods of {allowance_s} s wait {whole_s:.0} s in all, more than \
                 {MAX_WATCHDOG_S} s (a day)"
            ),
        ));
    }
    Ok(())
}

/// The node's status frames per second of loop time at a control rate of `control_rate_hz`:
/// above 0, at most one per period.
#[must_use]
pub fn heartbeat_hz(control_rate_hz: f64) -> Allowed {
    Allowed::above(0.0, control_rate_hz, "Hz")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_watchdog_is_one_period_to_a_day() {
        assert!(check_watchdog("w", 1, 0.01).is_ok());
        assert!(check_watchdog("w", 100_000, 0.05).is_ok());
        assert!(check_watchdog("w", 8_640_000, 0.01).is_ok());
        assert_eq!(
            check_watchdog("w", 0, 0.01).unwrap_err().reason,
            "0 periods is not within [1, 100000000] periods"
        );
        let error = check_watchdog("timing.watchdog_periods", 8_640_001, 0.01).unwrap_err();
        assert_eq!(error.field, "timing.watchdog_periods");
        assert!(error.reason.contains("more than 86400 s"), "{error}");
        assert!(check_watchdog("w", u32::MAX, 5e-5).is_err());
    }

    #[test]
    fn the_shared_ranges() {
        assert!(ANSWER_ALLOWANCE_S.contains(60.0) && !ANSWER_ALLOWANCE_S.contains(1e300));
        assert!(DURATION_S.contains(3600.0) && !DURATION_S.contains(0.0));
        assert!(PROBE_S.contains(0.0) && !PROBE_S.contains(-1.0));
        assert!(heartbeat_hz(20_000.0).contains(20_000.0));
        assert!(!heartbeat_hz(20_000.0).contains(20_001.0));
        assert!(!heartbeat_hz(20_000.0).contains(0.0));
    }
}
