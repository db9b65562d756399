//! A SocketCAN send the kernel refused with `ENOBUFS`: the interface's transmit queue
//! (`txqueuelen` frames, 10 on a CAN interface unless raised) is full. A raw CAN socket does
//! not wait for room as a stream socket would; the frame is not sent, and the sender must try
//! again. The queue drains at the bus's pace (a classical 8-byte frame takes about 130 us at
//! 1 Mbit/s), or not at all when no node acknowledges.
//!
//! [`SendRetry`] bounds the waiting: up to [`SendRetry::max_retries`] retries, the wait
//! doubling from [`SendRetry::first_wait`]; after them the send fails, naming the full queue.
//! [`RetryCounts`] is what the report shows.

use std::time::Duration;

/// How a refused send is retried.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SendRetry {
    /// The wait before the first retry; each further one waits twice the one before.
    pub first_wait: Duration,
    /// Retries before the send fails.
    pub max_retries: u32,
}

/// The link's policy: 100 us, doubling, 7 retries (12.7 ms in all, about a hundred frames'
/// time at 1 Mbit/s: a queue that does not drain in that time does not drain).
pub const ENOBUFS_RETRY: SendRetry = SendRetry {
    first_wait: Duration::from_micros(100),
    max_retries: 7,
};

/// What to do after a send attempt.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NextStep {
    /// The frame went out (or failed for another reason than a full queue): no retry.
    Done,
    /// Wait this long, then send again.
    RetryAfter(Duration),
    /// The queue stayed full through every retry: the send fails.
    GiveUp,
}

impl SendRetry {
    /// After an attempt that found the queue full (`queue_full`) or not, with `retries_done`
    /// retries before it: the next step.
    #[must_use]
    pub fn next_step(&self, queue_full: bool, retries_done: u32) -> NextStep {
        if !queue_full {
            return NextStep::Done;
        }
        if retries_done >= self.max_retries {
            return NextStep::GiveUp;
        }
        NextStep::RetryAfter(self.first_wait.saturating_mul(1 << retries_done.min(31)))
    }

    /// The longest a send waits before it gives up: every retry's wait.
    #[must_use]
    pub fn total_wait(&self) -> Duration {
        (0..self.max_retries)
            .map(|retry| self.first_wait.saturating_mul(1 << retry.min(31)))
            .fold(Duration::ZERO, Duration::saturating_add)
    }
}

/// Sends that met a full queue, for the report.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct RetryCounts {
    /// Sends that found the queue full at least once (and went out on a retry, or failed).
    pub sends_delayed: u64,
    /// Retries in all.
    pub retries: u64,
    /// Sends that gave up (the queue stayed full).
    pub sends_failed: u64,
}

impl RetryCounts {
    /// Counts one send that took `retries` retries and went out (`sent`) or gave up.
    pub fn count(&mut self, retries: u32, sent: bool) {
        if retries > 0 || !sent {
            self.sends_delayed += 1;
        }
        self.retries += u64::from(retries);
        if !sent {
            self.sends_failed += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn us(micros: u64) -> Duration {
        Duration::from_micros(micros)
    }

    #[test]
    fn a_full_queue_is_retried_with_doubling_waits_then_given_up() {
        let steps: Vec<NextStep> = (0..=7)
            .map(|done| ENOBUFS_RETRY.next_step(true, done))
            .collect();
        assert_eq!(
            steps,
            [100, 200, 400, 800, 1600, 3200, 6400]
                .map(|wait| NextStep::RetryAfter(us(wait)))
                .into_iter()
                .chain([NextStep::GiveUp])
                .collect::<Vec<_>>()
        );
        assert_eq!(ENOBUFS_RETRY.next_step(true, 100), NextStep::GiveUp);
        assert_eq!(ENOBUFS_RETRY.total_wait(), us(12_700));
    }

    #[test]
    fn a_send_that_went_out_is_done_whatever_came_before() {
        for done in [0, 3, 7, 8] {
            assert_eq!(ENOBUFS_RETRY.next_step(false, done), NextStep::Done);
        }
    }

    #[test]
    fn waits_saturate_instead_of_overflowing() {
        let policy = SendRetry {
            first_wait: Duration::MAX,
            max_retries: 40,
        };
        assert_eq!(
            policy.next_step(true, 35),
            NextStep::RetryAfter(Duration::MAX)
        );
        assert_eq!(policy.total_wait(), Duration::MAX);
        let none = SendRetry {
            first_wait: us(100),
            max_retries: 0,
        };
        assert_eq!(none.next_step(true, 0), NextStep::GiveUp);
        assert_eq!(none.total_wait(), Duration::ZERO);
    }

    #[test]
    fn the_counts_tell_delayed_and_failed_sends_apart() {
        let mut counts = RetryCounts::default();
        counts.count(0, true);
        assert_eq!(counts, RetryCounts::default());
        counts.count(2, true);
        counts.count(7, false);
        assert_eq!(
            counts,
            RetryCounts {
                sends_delayed: 2,
                retries: 9,
                sends_failed: 1
            }
        );
        // Given up at once (a policy without retries) is delayed and failed.
        counts.count(0, false);
        assert_eq!(
            counts,
            RetryCounts {
                sends_delayed: 3,
                retries: 9,
                sends_failed: 2
            }
        );
    }
}
