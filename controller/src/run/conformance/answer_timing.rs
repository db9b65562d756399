//! The lockstep timing check's bookkeeping: how long each Step took to be answered, the late
//! answers and a lost one.

use std::time::Duration;

/// How long the timing check waits for an answer, in watchdog allowances: an answer after
/// one allowance is late, one after this many is lost (and ends the check).
pub(super) const LATE_WAIT_ALLOWANCES: u32 = 2;

/// How the timing check's answers came: the late ones (after the allowance, but within
/// [`LATE_WAIT_ALLOWANCES`] of it) and a lost one (never, which ends the check).
#[derive(Debug, Default)]
pub(super) struct AnswerTiming {
    slowest: Duration,
    late: u64,
    first_late: Option<String>,
    pub(super) lost: Option<String>,
}

impl AnswerTiming {
    pub(super) fn answered(&mut self, k: u64, took: Duration, allowance: Duration) {
        self.slowest = self.slowest.max(took);
        if took > allowance {
            self.late += 1;
            self.first_late.get_or_insert_with(|| {
                format!(
                    "period {k}: AngleReading {took:.3?} after its Step, beyond the watchdog's {allowance:?} allowance"
                )
            });
        }
    }

    pub(super) fn passed(&self) -> bool {
        self.late == 0 && self.lost.is_none()
    }

    pub(super) fn detail(&self, answered: u64) -> String {
        let late = self
            .first_late
            .as_ref()
            .map(|first| format!("{} of {answered} answers late; first: {first}", self.late));
        match (&self.lost, late) {
            (Some(lost), Some(late)) => format!("{lost}; {late}"),
            (Some(lost), None) => lost.clone(),
            (None, Some(late)) => late,
            (None, None) => format!("{answered} steps answered, slowest {:?}", self.slowest),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_late_answer_is_counted_and_named_and_fails_the_timing() {
        let allowance = Duration::from_millis(500);
        let mut timing = AnswerTiming::default();
        timing.answered(0, Duration::from_millis(3), allowance);
        assert!(timing.passed());
        timing.answered(1, Duration::from_millis(750), allowance);
        timing.answered(2, Duration::from_millis(600), allowance);
        assert!(!timing.passed());
        let detail = timing.detail(3);
        assert!(
            detail.starts_with("2 of 3 answers late; first: period 1: AngleReading 750.000ms"),
            "{detail}"
        );
    }

    #[test]
    fn an_answer_taking_exactly_the_allowance_is_in_time() {
        let allowance = Duration::from_millis(500);
        let mut timing = AnswerTiming::default();
        timing.answered(0, allowance, allowance);
        assert!(timing.passed(), "{}", timing.detail(1));
    }
}
