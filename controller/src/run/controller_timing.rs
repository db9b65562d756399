//! The host's side of a real-time run's timing and the report's verdicts on it: the real-time
//! settings as granted and the wake-up probe ([`HostScheduling`]), reading intervals, answer
//! latencies and missed readings ([`ControllerTiming`]), and who missed each of the node's
//! deadlines and how the loop's jitter compares with the probe ([`verdicts`]).

use std::time::Duration;

use scanhil_protocol::loop_timing::{
    MissAttribution, MissedDeadline, PeriodStats, attribute_misses,
};
use scanhil_protocol::scheduling::{self, InEffect};

use super::scenario::TimingConfig;

/// The host's real-time settings as granted, and its wake-up probe.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct HostScheduling {
    /// What the OS granted (warnings for what it refused).
    pub in_effect: InEffect,
    /// The wake-up latency at the control period, measured before the loop.
    pub wakeup_probe: Option<PeriodStats>,
    /// Why the probe could not run, if it could not.
    pub probe_error: Option<String>,
}

impl HostScheduling {
    /// Applies the scenario's host settings to the calling thread (a warning on stderr for each
    /// refusal), then runs the wake-up probe for `timing.probe_s`.
    #[must_use]
    pub fn set_up(timing: &TimingConfig, period_s: f64) -> HostScheduling {
        let in_effect = scheduling::apply(&timing.host_options());
        for warning in &in_effect.warnings {
            eprintln!("scanhil: {warning}");
        }
        let probe = scheduling::wakeup_probe(
            Duration::from_secs_f64(period_s),
            Duration::from_secs_f64(timing.probe_s),
        );
        HostScheduling {
            in_effect,
            wakeup_probe: probe.unwrap_or_default(),
            probe_error: probe
                .err()
                .map(|errno| format!("wake-up probe failed: {errno}")),
        }
    }
}

/// The controller's timing in a real-time run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ControllerTiming {
    /// Interval between consecutive angle readings.
    pub reading_interval: Option<PeriodStats>,
    /// From a reading's arrival to the command sent; overruns: latency above one period.
    pub answer_latency: Option<PeriodStats>,
    /// Readings skipped by the master's sequence counter (the controller was too slow).
    pub missed_readings: u64,
    /// This end's real-time settings and wake-up probe.
    pub scheduling: HostScheduling,
    /// The answer latency of each reading, by period, s (NaN: not answered).
    #[serde(skip)]
    pub latency_by_reading_s: Vec<f64>,
}

impl ControllerTiming {
    /// Blames each of the node's missed deadlines on the node, this host or the link
    /// ([`attribute_misses`] with this host's answer latencies).
    #[must_use]
    pub fn attribute(&self, misses: &[MissedDeadline], period_s: f64) -> MissAttribution {
        attribute_misses(misses, period_s, |reading| {
            usize::try_from(reading)
                .ok()
                .and_then(|index| self.latency_by_reading_s.get(index))
                .copied()
                .filter(|latency_s| latency_s.is_finite())
        })
    }
}

/// Takes the emulator's list of missed deadlines out of its summary's `timing` (it is long;
/// the report keeps their attribution instead). Empty when there is none or it does not parse.
pub fn take_missed_deadlines(emulator_timing: &mut serde_json::Value) -> Vec<MissedDeadline> {
    emulator_timing
        .as_object_mut()
        .and_then(|timing| timing.remove("missed_deadlines"))
        .and_then(|list| serde_json::from_value(list).ok())
        .unwrap_or_default()
}

/// The target of the loop's jitter: its p99 within this factor of the wake-up probe's p99.
pub const JITTER_TARGET_P99_RATIO: f64 = 2.0;

/// The report's real-time verdicts from both ends' timing (`emulator_timing` is the emulator
/// summary's `timing`; its list of missed deadlines is taken out): `deadline_misses`, who
/// missed and by how much ([`ControllerTiming::attribute`]), and `jitter_against_probe`, the
/// clock master's tick lateness (how late each period started, as cyclictest measures a
/// wake-up) beside its wake-up probe, with the p99 ratio and whether it is within
/// [`JITTER_TARGET_P99_RATIO`]. Null where a side's figures are missing (a real node reports
/// none).
pub fn verdicts(
    controller: &ControllerTiming,
    emulator_timing: &mut serde_json::Value,
    period_s: f64,
) -> serde_json::Value {
    let misses = take_missed_deadlines(emulator_timing);
    let deadline_misses = emulator_timing
        .get("stale_command_periods")
        .map(|_| controller.attribute(&misses, period_s));
    let lateness: Option<PeriodStats> =
        serde_json::from_value(emulator_timing["tick_lateness"].clone()).ok();
    let probe: Option<PeriodStats> =
        serde_json::from_value(emulator_timing["scheduling"]["wakeup_probe"].clone()).ok();
    let jitter_against_probe = lateness.zip(probe).map(|(loop_s, probe_s)| {
        let ratio = loop_s.p99_s / probe_s.p99_s;
        serde_json::json!({
            "loop_tick_lateness": { "median_s": loop_s.median_s, "p99_s": loop_s.p99_s, "max_s": loop_s.max_s },
            "wakeup_probe": { "median_s": probe_s.median_s, "p99_s": probe_s.p99_s, "max_s": probe_s.max_s },
            "p99_ratio": ratio.is_finite().then_some(ratio),
            "target_p99_ratio": JITTER_TARGET_P99_RATIO,
            "within_target": ratio <= JITTER_TARGET_P99_RATIO,
        })
    });
    serde_json::json!({
        "deadline_misses": deadline_misses,
        "jitter_against_probe": jitter_against_probe,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(median_s: f64, p99_s: f64) -> serde_json::Value {
        serde_json::json!({
            "periods": 100, "nominal_s": 50e-6, "min_s": 0.0, "median_s": median_s,
            "p99_s": p99_s, "max_s": p99_s, "overruns": 0, "above_nominal": 0,
        })
    }

    #[test]
    fn verdicts_attribute_the_emulators_misses_and_take_its_list_out() {
        let controller = ControllerTiming {
            reading_interval: None,
            answer_latency: None,
            missed_readings: 0,
            scheduling: HostScheduling::default(),
            latency_by_reading_s: vec![10e-6, 60e-6, f64::NAN],
        };
        let mut emulator = serde_json::json!({
            "stale_command_periods": 4,
            "missed_deadlines": [
                { "period": 0, "reading_late_s": null },
                { "period": 1, "reading_late_s": 45e-6 },
                { "period": 2, "reading_late_s": 1e-6 },
                { "period": 3, "reading_late_s": 2e-6 },
            ],
            "tick_lateness": stats(1e-6, 30e-6),
            "scheduling": { "wakeup_probe": stats(5e-6, 10e-6) },
        });
        let verdicts = verdicts(&controller, &mut emulator, 50e-6);
        assert!(emulator.get("missed_deadlines").is_none());
        let misses = &verdicts["deadline_misses"];
        assert_eq!(misses["total"], 3);
        assert_eq!(misses["node"]["count"], 1, "{misses}");
        assert_eq!(
            misses["host"]["count"], 2,
            "60 us, and one never answered: {misses}"
        );
        let jitter = &verdicts["jitter_against_probe"];
        assert!((jitter["p99_ratio"].as_f64().unwrap() - 3.0).abs() < 1e-9);
        assert_eq!(jitter["within_target"], false);
    }
}
