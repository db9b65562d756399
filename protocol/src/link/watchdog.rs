//! The link watchdog, used on both sides: when no frame arrives for a configured number of
//! loop periods, the link has timed out (the emulator then drops its coil currents to zero,
//! the controller commands zero and stops).
//!
//! Time is tokio's clock ([`tokio::time::Instant`]), so tests can pause it. In lockstep the
//! loop feeds the watchdog on every awaited answer and gives it a wall-clock allowance per
//! period (the guest of a software-emulated VM is slow), see [`Watchdog::new`].

use std::time::Duration;

use tokio::time::Instant;

/// A link that went quiet for too long.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("link timeout on {link}: nothing received for {periods} periods ({silent_for:?})")]
pub struct LinkTimeout {
    /// The link's name (its URI).
    pub link: String,
    /// The number of periods the watchdog allowed.
    pub periods: u32,
    /// How long the link had been silent when the timeout was declared.
    pub silent_for: Duration,
}

/// Counts silent periods on one link.
#[derive(Debug, Clone)]
pub struct Watchdog {
    link: String,
    period: Duration,
    periods: u32,
    last_fed: Instant,
}

impl Watchdog {
    /// A watchdog on `link` that fires after `periods` periods of `period` without a frame
    /// (`periods` is at least 1). It starts fed.
    #[must_use]
    pub fn new(link: &str, period: Duration, periods: u32) -> Self {
        Watchdog {
            link: link.to_owned(),
            period,
            periods: periods.max(1),
            last_fed: Instant::now(),
        }
    }

    /// Records that a frame arrived now.
    pub fn feed(&mut self) {
        self.last_fed = Instant::now();
    }

    /// The total silence allowed: `periods * period`.
    #[must_use]
    pub fn allowance(&self) -> Duration {
        self.period.saturating_mul(self.periods)
    }

    /// How long the link may still stay silent before it times out (zero once expired).
    #[must_use]
    pub fn remaining(&self) -> Duration {
        self.allowance().saturating_sub(self.last_fed.elapsed())
    }

    /// `Err` once the link has been silent for the whole allowance.
    ///
    /// # Errors
    /// [`LinkTimeout`] naming the link, the periods and the silence.
    pub fn check(&self) -> Result<(), LinkTimeout> {
        let silent_for = self.last_fed.elapsed();
        if silent_for >= self.allowance() {
            Err(LinkTimeout {
                link: self.link.clone(),
                periods: self.periods,
                silent_for,
            })
        } else {
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test(start_paused = true)]
    async fn fires_after_the_allowed_periods_and_feeding_resets_it() {
        let mut dog = Watchdog::new("slcan:/dev/null", Duration::from_micros(50), 4);
        assert_eq!(dog.allowance(), Duration::from_micros(200));
        tokio::time::advance(Duration::from_micros(150)).await;
        assert!(dog.check().is_ok());
        dog.feed();
        tokio::time::advance(Duration::from_micros(150)).await;
        assert!(dog.check().is_ok());
        assert_eq!(dog.remaining(), Duration::from_micros(50));
        tokio::time::advance(Duration::from_micros(60)).await;
        let timeout = dog.check().unwrap_err();
        assert_eq!(timeout.periods, 4);
        assert!(timeout.to_string().contains("slcan:/dev/null"), "{timeout}");
        assert_eq!(dog.remaining(), Duration::ZERO);
    }
}
