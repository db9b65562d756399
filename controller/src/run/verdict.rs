//! The run's verdict: whether it did what it was asked, decided from its figures alone (no
//! I/O, no clock), for `report.json` `outcome` and the exit status.
//!
//! - `complete` (exit 0): every planned period ran and the result is valid;
//! - `stopped` (exit 3): the loop stopped early ([`RunFigures::stopped_by`]); the figures of a
//!   partial run are not judged further;
//! - `failed` (exit 4): the run completed but its result is not valid, each reason said:
//!   no period in the recorded frame, a reference that does not move (the power check scaled
//!   it to nothing), a mirror that never moved, a tracking error above its limit, a sensor
//!   that sent nothing or whose samples paired with no angle, samples that could not be
//!   imaged.
//!
//! The tracking limit per axis is [`TRACKING_MULTIPLE`] times the nominal loop's prediction,
//! never below [`TRACKING_FLOOR`] of the reference's peak and never above
//! [`TRACKING_CEILING`]. The floor: the prediction is the steady state's, while a frame
//! without a lead-in holds the loop's start-up transient too (`vcan-small.json`, 0.05 s from
//! rest, tracks beta at 5.12 % against a predicted 0.83 %). The ceiling: an error of half the
//! reference is no tracking at all, whatever was predicted. An axis without a prediction (a
//! reference that is not periodic) is held to the ceiling. The limit is coarse on purpose: it
//! tells a loop that failed from one that works (a plant far from the host's model tracks at
//! 894-1784 % against a predicted 0.7 %, a mirror that stands still scores 71 % on a sine),
//! while the shipped scans' finer bands around the prediction are the steady-state tests'
//! (`lab/tests/steady_state.rs`).
//!
//! Where a rule does not apply the verdict says so in its notes instead of judging: an
//! emulated scene without dynamics (part `axes` off: the mirror cannot move, so neither
//! motion nor tracking is judged and no prediction is compared), a rig without a sensor
//! (nothing is imaged).

use scanhil_protocol::plant_units::SensingAxis;
use serde::Serialize;

use super::tracking::TrackingError;
use crate::steady_state::PredictedTracking;

/// The tracking limit as a multiple of the predicted error.
pub const TRACKING_MULTIPLE: f64 = 5.0;

/// The lowest tracking limit, as a share of the reference's peak (rms error over peak).
pub const TRACKING_FLOOR: f64 = 0.2;

/// The highest tracking limit, as a share of the reference's peak: an error this large is
/// no tracking at all (a mirror standing still scores 0.71 on a sine).
pub const TRACKING_CEILING: f64 = 0.5;

/// The share of the reference's span the measured angle must span on an axis for the mirror
/// to count as having moved there.
pub const MOVED_SHARE: f64 = 0.01;

/// How a run ended, judged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// It did what it was asked.
    Complete,
    /// The loop stopped early.
    Stopped,
    /// It completed, but its result is not valid.
    Failed,
}

impl Status {
    /// The name reports use: `complete`, `stopped`, `failed`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Status::Complete => "complete",
            Status::Stopped => "stopped",
            Status::Failed => "failed",
        }
    }

    /// The exit status of `scanhil scan` for a run judged so (outputs that could not be
    /// written are exit 3 as well, decided by the caller).
    #[must_use]
    pub fn exit_code(self) -> u8 {
        match self {
            Status::Complete => 0,
            Status::Stopped => 3,
            Status::Failed => 4,
        }
    }
}

/// What the emulated plant declares of itself; a real device declares nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct PlantDeclares {
    /// `Some(false)`: the emulated scene has no dynamics (part `axes` off), the mirror cannot
    /// move; `Some(true)`: it has; `None`: not declared (real devices).
    pub dynamics: Option<bool>,
}

/// One axis's figures over the recorded frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AxisFigures {
    /// The reference's peak magnitude, rad.
    pub reference_peak_rad: f64,
    /// The reference's span (largest minus smallest), rad.
    pub reference_span_rad: f64,
    /// The measured angle's span, rad.
    pub measured_span_rad: f64,
    /// The rms tracking error over the reference's peak.
    pub rms_relative: f64,
    /// The nominal loop's prediction of it (`None`: not periodic, or at rest).
    pub predicted_rms_relative: Option<f64>,
}

/// The sensor's side of a run with a sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SensorFigures {
    /// Samples the sensor sent.
    pub samples: u64,
    /// Samples of the frame paired with an angle, with a distance.
    pub paired_with_distance: u64,
}

/// A scan against a recorded session: its coil commands compared with the recorded ones
/// ([`super::replay_check`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ReplayFigures {
    /// `--replay-must-match`: a divergence fails the run.
    pub must_match: bool,
    /// Commands compared with a recorded one.
    pub compared: u64,
    /// The first period whose command differs (`None`: none did).
    pub first_divergence: Option<u64>,
}

/// Everything the verdict is decided from.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RunFigures {
    /// Why the loop stopped early, if it did.
    pub stopped_by: Option<String>,
    /// Periods of the recorded frame that ran.
    pub frame_periods: u64,
    /// The frame's figures per axis.
    pub alpha: AxisFigures,
    /// Beta's.
    pub beta: AxisFigures,
    /// What the plant declares of itself.
    pub plant: PlantDeclares,
    /// The sensor's figures (`None`: the rig has no sensor).
    pub sensor: Option<SensorFigures>,
    /// Why the samples could not be imaged, if they could not.
    pub imaging_error: Option<String>,
    /// A replayed session's comparison (`None`: no replay).
    pub replay: Option<ReplayFigures>,
}

impl RunFigures {
    /// The axis figures of a frame's tracking error and its prediction.
    #[must_use]
    pub fn axes(frame: &TrackingError, predicted: &PredictedTracking) -> [AxisFigures; 2] {
        [
            (SensingAxis::Alpha, predicted.alpha_rms_relative),
            (SensingAxis::Beta, predicted.beta_rms_relative),
        ]
        .map(|(axis, predicted_rms_relative)| {
            let figures = frame.axis(axis);
            AxisFigures {
                reference_peak_rad: figures.reference_peak_urad * 1e-6,
                reference_span_rad: figures.reference_span_urad * 1e-6,
                measured_span_rad: figures.measured_span_urad * 1e-6,
                rms_relative: figures.rms_relative,
                predicted_rms_relative,
            }
        })
    }
}

/// A tracking limit that was applied, per axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TrackingLimit {
    /// The axis.
    pub axis: &'static str,
    /// The measured rms error over the reference's peak.
    pub measured: f64,
    /// The limit it was held to.
    pub limit: f64,
}

/// The verdict.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Verdict {
    /// Complete, stopped or failed.
    pub status: Status,
    /// Why it is not complete (empty when it is).
    pub reasons: Vec<String>,
    /// What was not judged, and why.
    pub notes: Vec<String>,
    /// The tracking limits applied.
    pub tracking_limits: Vec<TrackingLimit>,
}

/// The tracking limit for an axis with prediction `predicted` (see the module doc).
#[must_use]
pub fn tracking_limit(predicted: Option<f64>) -> f64 {
    predicted.map_or(TRACKING_CEILING, |predicted| {
        (TRACKING_MULTIPLE * predicted).clamp(TRACKING_FLOOR, TRACKING_CEILING)
    })
}

/// Judges a run by its figures (see the module doc for the rules).
#[must_use]
pub fn judge(run: &RunFigures) -> Verdict {
    let mut verdict = Verdict {
        status: Status::Complete,
        reasons: Vec::new(),
        notes: Vec::new(),
        tracking_limits: Vec::new(),
    };
    if let Some(why) = &run.stopped_by {
        verdict.status = Status::Stopped;
        verdict.reasons.push(format!("stopped early: {why}"));
        return verdict;
    }
    let fail = |verdict: &mut Verdict, reason: String| {
        verdict.status = Status::Failed;
        verdict.reasons.push(reason);
    };
    if run.frame_periods == 0 {
        fail(
            &mut verdict,
            "the recorded frame has no period: its duration is shorter than one control \
             period"
                .into(),
        );
        return verdict;
    }
    let axes = [("alpha", run.alpha), ("beta", run.beta)];
    if axes.iter().all(|(_, axis)| axis.reference_peak_rad == 0.0) {
        fail(
            &mut verdict,
            "the reference does not move the mirror: its amplitudes are 0 (after the power \
             check)"
                .into(),
        );
    } else if run.plant.dynamics == Some(false) {
        verdict.notes.push(
            "the emulated scene has no dynamics (part `axes` off): the mirror cannot move, so \
             neither its motion nor its tracking is judged, and no prediction applies"
                .into(),
        );
    } else {
        for (name, axis) in axes {
            if axis.reference_peak_rad == 0.0 {
                continue;
            }
            if axis.measured_span_rad < MOVED_SHARE * axis.reference_span_rad {
                fail(
                    &mut verdict,
                    format!(
                        "the mirror never moved on {name}: its angle spanned {:.3} urad for a \
                         reference spanning {:.1} urad",
                        axis.measured_span_rad * 1e6,
                        axis.reference_span_rad * 1e6
                    ),
                );
                continue;
            }
            let limit = tracking_limit(axis.predicted_rms_relative);
            verdict.tracking_limits.push(TrackingLimit {
                axis: name,
                measured: axis.rms_relative,
                limit,
            });
            // A NaN error is within no limit.
            let within = axis.rms_relative <= limit;
            if !within {
                let against = axis.predicted_rms_relative.map_or_else(
                    || "no prediction applies".to_owned(),
                    |p| format!("predicted {:.2} %", 100.0 * p),
                );
                fail(
                    &mut verdict,
                    format!(
                        "the loop does not track on {name}: rms error {:.2} % of the \
                         reference's peak, above its limit of {:.2} % ({against}; the limit is \
                         {TRACKING_MULTIPLE} x the prediction, within {:.0} % and {:.0} %)",
                        100.0 * axis.rms_relative,
                        100.0 * limit,
                        100.0 * TRACKING_FLOOR,
                        100.0 * TRACKING_CEILING,
                    ),
                );
            }
        }
    }
    match run.sensor {
        None => verdict
            .notes
            .push("the rig has no sensor: nothing is imaged".into()),
        Some(sensor) if sensor.samples == 0 => {
            fail(&mut verdict, "the sensor sent no sample".into());
        }
        Some(sensor) if sensor.paired_with_distance == 0 => fail(
            &mut verdict,
            format!(
                "none of the sensor's {} samples paired with an angle of the frame with a \
                 distance: nothing is imaged",
                sensor.samples
            ),
        ),
        Some(_) => {}
    }
    if let Some(error) = &run.imaging_error {
        fail(
            &mut verdict,
            format!("the samples could not be imaged: {error}"),
        );
    }
    if let Some(replay) = run.replay {
        let mismatch = match replay.first_divergence {
            Some(period) => Some(format!(
                "the host's coil commands differ from the recording's from period {period}"
            )),
            None if replay.compared == 0 => {
                Some("no coil command was compared with the recording".to_owned())
            }
            None => None,
        };
        match mismatch {
            Some(why) if replay.must_match => {
                fail(&mut verdict, format!("{why} (--replay-must-match)"))
            }
            Some(why) => verdict.notes.push(format!(
                "{why} (see `replay`; --replay-must-match makes this a failed run)"
            )),
            None => {}
        }
    }
    verdict
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A good run: tracking at its prediction, a sensor whose samples pair.
    fn good() -> RunFigures {
        let axis = AxisFigures {
            reference_peak_rad: 0.01,
            reference_span_rad: 0.02,
            measured_span_rad: 0.0199,
            rms_relative: 0.0072,
            predicted_rms_relative: Some(0.0070),
        };
        RunFigures {
            stopped_by: None,
            frame_periods: 20_000,
            alpha: axis,
            beta: axis,
            plant: PlantDeclares {
                dynamics: Some(true),
            },
            sensor: Some(SensorFigures {
                samples: 20_000,
                paired_with_distance: 18_725,
            }),
            imaging_error: None,
            replay: None,
        }
    }

    #[test]
    fn a_good_run_is_complete_with_its_limits_stated() {
        let verdict = judge(&good());
        assert_eq!(verdict.status, Status::Complete, "{verdict:?}");
        assert!(verdict.reasons.is_empty() && verdict.notes.is_empty());
        assert_eq!(verdict.tracking_limits.len(), 2);
        assert_eq!(verdict.tracking_limits[0].axis, "alpha");
        assert_eq!(verdict.tracking_limits[0].limit, TRACKING_FLOOR);
        assert_eq!(verdict.status.exit_code(), 0);
    }

    #[test]
    fn a_stopped_run_is_stopped_and_not_judged_further() {
        let run = RunFigures {
            stopped_by: Some("interrupted by SIGINT".into()),
            frame_periods: 0,
            sensor: Some(SensorFigures::default()),
            ..good()
        };
        let verdict = judge(&run);
        assert_eq!(verdict.status, Status::Stopped);
        assert_eq!(verdict.reasons, ["stopped early: interrupted by SIGINT"]);
        assert_eq!(verdict.status.exit_code(), 3);
    }

    #[test]
    fn no_period_in_the_frame_fails() {
        let verdict = judge(&RunFigures {
            frame_periods: 0,
            ..good()
        });
        assert_eq!(verdict.status, Status::Failed);
        assert_eq!(verdict.status.exit_code(), 4);
        assert!(verdict.reasons[0].contains("no period"), "{verdict:?}");
        assert_eq!(verdict.reasons.len(), 1);
    }

    #[test]
    fn a_reference_scaled_to_nothing_fails() {
        let still = AxisFigures {
            reference_peak_rad: 0.0,
            reference_span_rad: 0.0,
            measured_span_rad: 0.0,
            rms_relative: 0.0,
            predicted_rms_relative: None,
        };
        let verdict = judge(&RunFigures {
            alpha: still,
            beta: still,
            ..good()
        });
        assert_eq!(verdict.status, Status::Failed);
        assert!(verdict.reasons[0].contains("does not move"), "{verdict:?}");
        // One axis at rest is a sine on the other: judged on the moving axis alone.
        let verdict = judge(&RunFigures {
            beta: still,
            ..good()
        });
        assert_eq!(verdict.status, Status::Complete, "{verdict:?}");
        assert_eq!(verdict.tracking_limits.len(), 1);
    }

    #[test]
    fn a_mirror_that_never_moved_fails_unless_its_scene_declares_no_dynamics() {
        let frozen = AxisFigures {
            measured_span_rad: 0.0,
            rms_relative: 0.707,
            ..good().alpha
        };
        let run = RunFigures {
            alpha: frozen,
            beta: frozen,
            ..good()
        };
        let verdict = judge(&run);
        assert_eq!(verdict.status, Status::Failed);
        assert_eq!(verdict.reasons.len(), 2, "{verdict:?}");
        assert!(verdict.reasons[0].contains("never moved on alpha"));
        assert!(verdict.reasons[1].contains("never moved on beta"));
        // Just under the share still fails; at it, the motion counts.
        let barely = AxisFigures {
            measured_span_rad: MOVED_SHARE * 0.02 * 0.999,
            ..good().alpha
        };
        assert_eq!(
            judge(&RunFigures {
                alpha: barely,
                ..good()
            })
            .status,
            Status::Failed
        );
        let moved = AxisFigures {
            measured_span_rad: MOVED_SHARE * 0.02,
            ..good().alpha
        };
        assert_eq!(
            judge(&RunFigures {
                alpha: moved,
                ..good()
            })
            .status,
            Status::Complete
        );
        let declared = judge(&RunFigures {
            plant: PlantDeclares {
                dynamics: Some(false),
            },
            ..run
        });
        assert_eq!(declared.status, Status::Complete, "{declared:?}");
        assert!(declared.notes[0].contains("no dynamics"));
        assert!(declared.tracking_limits.is_empty());
    }

    #[test]
    fn tracking_beyond_its_limit_fails_naming_the_axis_and_the_limit() {
        let far = AxisFigures {
            rms_relative: 8.94,
            ..good().beta
        };
        let verdict = judge(&RunFigures {
            beta: far,
            ..good()
        });
        assert_eq!(verdict.status, Status::Failed);
        assert_eq!(verdict.reasons.len(), 1);
        assert!(
            verdict.reasons[0].contains("does not track on beta")
                && verdict.reasons[0].contains("894.00 %")
                && verdict.reasons[0].contains("predicted 0.70 %"),
            "{verdict:?}"
        );
        // At the limit passes, just above fails.
        for (rms, status) in [
            (TRACKING_FLOOR, Status::Complete),
            (TRACKING_FLOOR * 1.000_001, Status::Failed),
        ] {
            let axis = AxisFigures {
                rms_relative: rms,
                ..good().beta
            };
            assert_eq!(
                judge(&RunFigures {
                    beta: axis,
                    ..good()
                })
                .status,
                status
            );
        }
        // A NaN error is not within any limit.
        let nan = AxisFigures {
            rms_relative: f64::NAN,
            ..good().beta
        };
        assert_eq!(
            judge(&RunFigures {
                beta: nan,
                ..good()
            })
            .status,
            Status::Failed
        );
    }

    #[test]
    fn the_limit_is_a_multiple_of_the_prediction_between_floor_and_ceiling() {
        assert_eq!(tracking_limit(Some(0.007)), TRACKING_FLOOR);
        assert!((tracking_limit(Some(0.0592)) - 0.296).abs() < 1e-12);
        assert_eq!(tracking_limit(Some(0.2)), TRACKING_CEILING);
        assert_eq!(tracking_limit(None), TRACKING_CEILING);
        // Without a prediction the axis is held to the ceiling.
        let unpredicted = AxisFigures {
            rms_relative: 0.49,
            predicted_rms_relative: None,
            ..good().alpha
        };
        let verdict = judge(&RunFigures {
            alpha: unpredicted,
            ..good()
        });
        assert_eq!(verdict.status, Status::Complete);
        let verdict = judge(&RunFigures {
            alpha: AxisFigures {
                rms_relative: 0.51,
                ..unpredicted
            },
            ..good()
        });
        assert!(
            verdict.reasons[0].contains("no prediction applies"),
            "{verdict:?}"
        );
    }

    #[test]
    fn a_sensor_that_sent_nothing_or_paired_nothing_fails_and_no_sensor_is_noted() {
        let verdict = judge(&RunFigures {
            sensor: Some(SensorFigures {
                samples: 0,
                paired_with_distance: 0,
            }),
            ..good()
        });
        assert_eq!(verdict.reasons, ["the sensor sent no sample"]);
        let verdict = judge(&RunFigures {
            sensor: Some(SensorFigures {
                samples: 5000,
                paired_with_distance: 0,
            }),
            ..good()
        });
        assert_eq!(verdict.status, Status::Failed);
        assert!(verdict.reasons[0].contains("5000 samples"), "{verdict:?}");
        let verdict = judge(&RunFigures {
            sensor: None,
            ..good()
        });
        assert_eq!(verdict.status, Status::Complete);
        assert_eq!(verdict.notes, ["the rig has no sensor: nothing is imaged"]);
        let verdict = judge(&RunFigures {
            imaging_error: Some("grid too large".into()),
            ..good()
        });
        assert_eq!(
            verdict.reasons,
            ["the samples could not be imaged: grid too large"]
        );
    }

    #[test]
    fn a_replay_that_diverges_is_noted_or_fails_when_it_must_match() {
        let replay = |must_match, compared, first_divergence| {
            judge(&RunFigures {
                replay: Some(ReplayFigures {
                    must_match,
                    compared,
                    first_divergence,
                }),
                ..good()
            })
        };
        for must_match in [false, true] {
            let same = replay(must_match, 301, None);
            assert_eq!(same.status, Status::Complete);
            assert!(same.notes.is_empty() && same.reasons.is_empty(), "{same:?}");
        }
        let noted = replay(false, 301, Some(17));
        assert_eq!(noted.status, Status::Complete);
        assert_eq!(
            noted.notes,
            [
                "the host's coil commands differ from the recording's from period 17 (see \
              `replay`; --replay-must-match makes this a failed run)"
            ]
        );
        let failed = replay(true, 301, Some(17));
        assert_eq!(failed.status, Status::Failed);
        assert_eq!(
            failed.reasons,
            [
                "the host's coil commands differ from the recording's from period 17 \
              (--replay-must-match)"
            ]
        );
        // Nothing compared (the emulator's summary lost) is no match either.
        assert_eq!(replay(true, 0, None).status, Status::Failed);
        assert_eq!(
            replay(false, 0, None).notes,
            [
                "no coil command was compared with the recording (see `replay`; \
              --replay-must-match makes this a failed run)"
            ]
        );
    }
}
