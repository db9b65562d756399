//! The output folder of a scan:
//!
//! | file | what |
//! |------|------|
//! | `report.json` | scenario, rig, outcome, periods, timing, tracking error, trajectory figures, sample pairing, `imaging` (the same [`ImagingReport`] `scanhil reconstruct` writes: feature height, coverage, error against the truth over scan time), link counters, the emulator's summary |
//! | `points.ply` | the reconstructed point cloud (binary little-endian PLY with t, angles, z_meas) |
//! | `height_map.png`, `height_map.csv` | the gridded heights: a picture in mm with a colour bar (missing cells grey) / the cells (missing empty) |
//! | `tracking.svg` | reference and measured angles, and the tracking error, over time |
//! | `progressive.svg` | coverage, and the error against the true surface when one is known, against scan time |
//! | `snapshots.png`, `profiles.svg`, `profiles.csv` | the map after 10/25/50/100 % of the frame (Fig. 6); sections along x and y through the feature against the truth (Fig. 10) |
//! | `fsm.log` | every frame on the mirror link, candump `-L` format, loop-time stamps |
//! | `sensor.ild` | every byte of the ILD stream, raw (`scanhil decode --format ild`) |
//!
//! A file that cannot be written does not stop the others ([`super::output_failures`]):
//! report.json lists it with why in `outputs.failed` (report.json itself, when it is the one
//! that fails, is named by `scanhil scan` on stderr).

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Context;
use scanhil_protocol::ild::IldValue;
use scanhil_report::{Axis, Chart, Series, draw_charts};
use scanhil_scene::truth::TrueScene;

use super::chunked::Chunked;
use super::host_loop::LoopRecord;
use super::link_faults::InjectedFrameFaults;
use super::mirror_link::{MirrorLinkCounters, NodeEvent};
use super::output_failures::OutputFailures;
use super::pairing::{ArrivalBound, FramePairing, SensorClock};
use super::plan::PlanSummary;
use super::sample_log::CountedSample;
use super::scenario::{OutputsConfig, Scenario};
use super::sensor_link::SensorCounters;
use super::tracking::{PlotPoint, TrackingSummary};
use super::verdict::{PlantDeclares, RunFigures, SensorFigures, Status, judge};
use super::{ScanEnd, ScanResult};
use crate::imaging::grid::GridMethod;
use crate::imaging::pipeline::{
    Figures, HEIGHT_MAP_PNG, IMAGING_OUTPUTS, ImagingOptions, ImagingReport, PROFILES_SVG,
    PROGRESSIVE_SVG, SNAPSHOTS_PNG, image_points, reconstruct_samples, write_outputs,
};
use crate::imaging::ply::PlyEncoding;
use crate::imaging::progressive::ScanFrame;
use crate::steady_state::PredictedTracking;

/// The mirror link's candump log.
pub const FSM_LOG: &str = "fsm.log";
/// The interface name in the candump log, the same on every transport so recordings compare.
pub const FSM_INTERFACE: &str = "fsm";
/// The ILD stream's raw capture.
pub const SENSOR_CAPTURE: &str = "sensor.ild";
/// The run report.
pub const REPORT: &str = "report.json";
/// The tracking plot.
pub const TRACKING_SVG: &str = "tracking.svg";

/// The recordings [`OutputsConfig::recordings`] switches.
pub const RECORDING_FILES: [&str; 2] = [FSM_LOG, SENSOR_CAPTURE];

/// The figures [`OutputsConfig::figures`] switches.
pub const FIGURE_FILES: [&str; 5] = [
    TRACKING_SVG,
    HEIGHT_MAP_PNG,
    PROGRESSIVE_SVG,
    SNAPSHOTS_PNG,
    PROFILES_SVG,
];

/// The files `outputs` leaves out, recordings first.
#[must_use]
pub fn left_out(outputs: OutputsConfig) -> Vec<&'static str> {
    let recordings = (!outputs.recordings).then_some(RECORDING_FILES);
    let figures = (!outputs.figures).then_some(FIGURE_FILES);
    recordings
        .into_iter()
        .flatten()
        .chain(figures.into_iter().flatten())
        .collect()
}

/// The imaging's files `outputs` writes ([`IMAGING_OUTPUTS`] but those it leaves out).
#[must_use]
pub fn imaging_outputs(outputs: OutputsConfig) -> Vec<&'static str> {
    let left_out = left_out(outputs);
    IMAGING_OUTPUTS
        .into_iter()
        .filter(|file| !left_out.contains(file))
        .collect()
}

/// Everything the loop produced, before imaging.
#[derive(Debug)]
pub struct RunData {
    /// The loop's record.
    pub record: LoopRecord,
    /// Distance frames that came on the mirror's CAN link (a sensor on CAN), counters
    /// unwrapped.
    pub can_distances: Chunked<CountedSample>,
    /// The bound the Distance frames' arrivals give on the sensor's clock, when asked for.
    pub can_arrivals: Option<ArrivalBound>,
    /// The mirror link's counters.
    pub mirror_counters: MirrorLinkCounters,
    /// The mirror's CAN link itself: transport, adapter, what crossed it (`None`: no link, the
    /// in-process loop).
    pub mirror_link: Option<scanhil_protocol::link::LinkReport>,
    /// The mirror node's faults and changes of state ([`NodeEvent`]).
    pub node_events: Vec<NodeEvent>,
    /// The ILD stream's samples and counters.
    pub sensor: (Chunked<CountedSample>, SensorCounters),
    /// The bound the ILD stream's arrivals give on the sensor's clock, when asked for.
    pub sensor_arrivals: Option<ArrivalBound>,
    /// What the sensor set-up before the run did.
    pub sensor_setup: Option<super::sensor_setup::SensorSetupReport>,
    /// What the emulated plant declares of itself (nothing for real devices).
    pub plant: PlantDeclares,
    /// The emulator's exit status and summary line, when it was started by this run.
    pub emulator_summary: Option<serde_json::Value>,
    /// What the injected frame faults did (`None`: none declared).
    pub frame_faults: Option<InjectedFrameFaults>,
    /// Wall-clock time from opening the links (or starting the in-process loop) to the end
    /// of the loop, s.
    pub run_time_s: f64,
    /// Recordings that could not be created or written.
    pub failed_recordings: OutputFailures,
    /// The recorded session the devices replayed (`None`: no replay).
    pub replay: Option<super::replay_check::ReplayRun>,
}

/// Images the run with the one imaging pipeline (the rig's geometry and calibration) and
/// writes every output file; returns how the run ended and the files that could not be
/// written (each failed alone; report.json lists the others' failures in `outputs.failed`).
/// The sensor's samples and the angle record are taken out of `run` and consumed as they are
/// paired and reconstructed: a long frame is never held as samples and points at once.
///
/// # Errors
/// A truth scene that cannot be read, samples that cannot be imaged.
pub fn write(
    scenario: &Scenario,
    plan: &PlanSummary,
    run: &mut RunData,
    clock: Option<SensorClock>,
    out_dir: &Path,
) -> anyhow::Result<ScanResult> {
    let mut failed = run.failed_recordings.clone();
    let rig = &scenario.rig;
    let measuring_rate_hz = rig.sensor.map_or(0.0, |sensor| sensor.measuring_rate_hz);
    let range = rig.sensor.map(|sensor| sensor.range());
    let ild_samples = std::mem::take(&mut run.sensor.0);
    let can_samples = std::mem::take(&mut run.can_distances);
    let sensor_counters = run.sensor.1;
    let clock = clock.unwrap_or_else(|| {
        estimate_sensor_clock(
            [run.sensor_arrivals.as_ref(), run.can_arrivals.as_ref()],
            run.record.wall_clock_epoch,
            measuring_rate_hz,
        )
    });
    let sensor_samples = ild_samples.len() + can_samples.len();
    let sensor_errors = sensor_error_counts(
        ild_samples
            .iter()
            .chain(can_samples.iter())
            .map(|sample| sample.value),
    );
    let record = &run.record;
    let period_s = record.period_s;
    // The recorded frame: after the lead-in, to the last period done.
    let frame = ScanFrame {
        start_s: record.lead_in_periods as f64 * period_s,
        length_s: record.periods_done.saturating_sub(record.lead_in_periods) as f64 * period_s,
    };
    // A rig's sensor is on one of the two: its samples come in the order they were measured.
    let samples = can_samples.into_iter().chain(ild_samples);
    let mut pairing = FramePairing::new(clock, frame.start_s, run.record.angles.take(), range);
    let record = &run.record;
    let options = ImagingOptions {
        model: scenario.imaging.reconstruction,
        setup: rig.scanner.setup,
        calibration: rig.scanner.calibration,
        pitch_mm: scenario.imaging.pitch_mm,
        grid: GridMethod::default(),
        feature: scenario.imaging.feature,
        progressive_steps: scenario.imaging.progressive_steps,
        ..ImagingOptions::default()
    };
    // Paired as they are reconstructed (the filter keeps the samples' count as the bound the
    // point cloud reserves). An imaging that fails is the verdict's reason, not the end of
    // the report.
    let reconstruction = reconstruct_samples(
        samples.filter_map(|sample| pairing.pair(sample.counter, sample.value)),
        &options,
    );
    let tracking = record.tracking.summary();
    if scenario.outputs.figures {
        failed.attempt(
            TRACKING_SVG,
            write_tracking_plot(record, &tracking, plan, out_dir),
        );
    }
    let end = ScanEnd::of(record);
    // No prediction is compared where none applies: a scene without dynamics.
    let predicted = match run.plant.dynamics {
        Some(false) => None,
        _ => Some(plan.predicted_tracking),
    };
    let unpredicted = PredictedTracking {
        alpha_rms_relative: None,
        beta_rms_relative: None,
    };
    let [alpha, beta] =
        RunFigures::axes(&tracking.frame, predicted.as_ref().unwrap_or(&unpredicted));
    // Real time: the emulator's list of missed deadlines becomes their attribution.
    let mut emulator = run.emulator_summary.clone();
    let verdicts = match (&record.controller_timing, emulator.as_mut()) {
        (Some(controller), Some(emulator)) => super::controller_timing::verdicts(
            controller,
            &mut emulator["summary"]["timing"],
            period_s,
        ),
        _ => serde_json::Value::Null,
    };
    let replay = run.replay.as_ref().map(|replay| {
        replay.judged(
            run.emulator_summary
                .as_ref()
                .map(|emulator| &emulator["summary"]),
        )
    });
    // The report and its verdict for an imaging (or its error) and the outputs not written.
    let report_with = |imaging: Option<&ImagingReport>,
                       imaging_error: Option<String>,
                       failed: &OutputFailures| {
        let verdict = judge(&RunFigures {
            stopped_by: record.stopped_by.as_ref().map(ToString::to_string),
            frame_periods: tracking.frame.periods,
            alpha,
            beta,
            plant: run.plant,
            sensor: rig.sensor.map(|_| SensorFigures {
                samples: sensor_samples as u64,
                paired_with_distance: pairing.with_distance as u64,
            }),
            imaging_error: imaging_error.clone(),
            replay: replay.as_ref().map(|(_, figures)| *figures),
        });
        let figures = scenario.trajectory.figures(imaging.map(|m| {
            (
                m.grid.nx as f64 * m.grid.pitch_mm,
                m.grid.ny as f64 * m.grid.pitch_mm,
            )
        }));
        let report = serde_json::json!({
            "scenario": {
                "name": scenario.name,
                "file": scenario.path.display().to_string(),
                "scene": scenario.scene.as_ref().map(|p| p.display().to_string()),
                "truth": scenario.truth_scene().map(|p| p.display().to_string()),
                "controller": scenario.controller.display().to_string(),
                "seed": scenario.seed,
                "duration_s": scenario.duration_s,
                "timing": scenario.timing,
                "links": scenario.links,
                "recording": scenario.recording,
            },
            "rig": rig.to_json(),
            "outcome": {
                "complete": verdict.status == Status::Complete,
                "verdict": verdict.status,
                "stopped_by": record.stopped_by.as_ref().map(ToString::to_string),
                "reasons": verdict.reasons,
                "notes": verdict.notes,
                "tracking_limits": verdict.tracking_limits,
            },
            "coils_at_end": coils_at_end(record, run.emulator_summary.as_ref()),
            "run_time_s": run.run_time_s,
            "periods": {
                "planned": record.periods_planned,
                "done": record.periods_done,
                "period_s": record.period_s,
                "saturated": record.saturated_periods,
                "saturated_in_frame": record.saturated_in_frame(),
                "planned_saturated_share": plan.planned_saturated_share,
            },
            "timing": {
                "mode": scenario.timing.mode,
                "controller": record.controller_timing,
                "emulator": emulator.as_ref().map(|e| e["summary"]["timing"].clone()),
                "deadline_misses": verdicts["deadline_misses"],
                "jitter_against_probe": verdicts["jitter_against_probe"],
            },
            "frame": {
                "start_s": frame.start_s,
                "duration_s": frame.length_s,
                "lead_in": plan.lead_in,
            },
            "tracking_error": tracking,
            "predicted_tracking_error": predicted,
            "sensor_setup": run.sensor_setup,
            "power": { "check": plan.power, "backoff": record.power_backoff },
            "trajectory": figures,
            "samples": {
                "sensor_samples": sensor_samples,
                "paired": pairing.paired,
                "in_the_lead_in": pairing.in_lead_in,
                "outside_the_angle_record": pairing.unpaired,
                "sensor_clock": clock,
            },
            "imaging": imaging,
            "imaging_error": imaging_error,
            "links": {
                "mirror": run.mirror_counters,
                "mirror_link": run.mirror_link,
                "sensor": sensor_counters,
                "node_events": run.node_events,
            },
            "faults": scenario.faults.is_active().then(|| fault_report(scenario, run, &sensor_counters, &sensor_errors)),
            "emulator": emulator,
            "replay": replay.as_ref().map(|(section, _)| section),
            "outputs": { "failed": &failed, "left_out": left_out(scenario.outputs) },
        });
        (report, verdict)
    };
    // Imaging takes seconds to minutes: a report is written before it, saying it did not
    // finish, so a signal or a crash meanwhile (the loop's handlers are gone by now) still
    // leaves one; the report after it replaces this one.
    if pairing.with_distance > 0 {
        let unfinished = "the run ended while its points were imaged";
        let mut not_written = failed.clone();
        for file in imaging_outputs(scenario.outputs) {
            not_written.add(file, unfinished.to_owned());
        }
        let (report, _) = report_with(None, Some(unfinished.to_owned()), &not_written);
        // A failure here is the final report's to say.
        let _ = write_report(&report, out_dir);
    }
    let imaging = if pairing.with_distance > 0 {
        image_and_write(
            scenario,
            reconstruction,
            &options,
            frame,
            out_dir,
            &pairing.missing_by_reason,
        )
        .map(Some)
    } else {
        Ok(None)
    };
    let (imaging, imaging_error) = match imaging {
        Ok(imaging) => (imaging, None),
        Err(error) => (
            None,
            Some(scanhil_protocol::error_text::chain_text(&*error)),
        ),
    };
    if let Some(report) = &imaging {
        for (file, why) in &report.failed_files {
            failed.add(file, why.clone());
        }
    }
    let (report, verdict) = report_with(imaging.as_ref(), imaging_error, &failed);
    failed.attempt(REPORT, write_report(&report, out_dir));
    Ok(ScanResult {
        end,
        verdict,
        failed_outputs: failed,
    })
}

/// Writes `report` as `out_dir`'s report.json, whole or not at all.
///
/// # Errors
/// The formatting or the write, naming the file.
fn write_report(report: &serde_json::Value, out_dir: &Path) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(report).context("formatting report.json")?;
    let path = out_dir.join(REPORT);
    scanhil_protocol::whole_file::write_file(&path, text + "\n")
        .with_context(|| format!("writing {}", path.display()))
}

/// `report.json` `coils_at_end`: the zero command the run ended with and whether the node
/// acknowledged it ([`super::host_loop::CoilsAtEnd`]), and, when an emulator served the mirror,
/// the node's own word on it: its final state and the coil currents it holds (`null` for a
/// real node, which reports none).
fn coils_at_end(
    record: &super::host_loop::LoopRecord,
    emulator: Option<&serde_json::Value>,
) -> serde_json::Value {
    let summary = emulator.map(|emulator| &emulator["summary"]);
    serde_json::json!({
        "zero_commanded": record.coils_at_end.zero_commanded,
        "acknowledged": record.coils_at_end.acknowledged,
        "node_final_state": summary.map(|summary| &summary["final_state"]),
        "node_held_coil_currents_a": summary.map(|summary| &summary["held_coil_currents_a"]),
    })
}

/// Images the frame's reconstruction (scored against the scenario's truth, when it has one)
/// and writes the imaging outputs into `out_dir`.
///
/// # Errors
/// A truth scene that cannot be read, points that cannot be imaged, outputs that cannot be
/// written (each failed file is listed in the report instead).
fn image_and_write(
    scenario: &Scenario,
    reconstruction: Result<
        crate::imaging::reconstruct::Reconstruction,
        crate::imaging::pipeline::ImagingError,
    >,
    options: &ImagingOptions,
    frame: ScanFrame,
    out_dir: &Path,
    missing_by_reason: &BTreeMap<String, usize>,
) -> anyhow::Result<crate::imaging::pipeline::ImagingReport> {
    let truth = scenario
        .truth_scene()
        .map(TrueScene::from_scene_file)
        .transpose()
        .or_else(|error| match error {
            // An emulated scene without a surface (a control-only run) has nothing to score.
            scanhil_scene::truth::TruthError::NoSurface { .. } if scenario.truth.is_none() => {
                Ok(None)
            }
            error => Err(error),
        })
        .context("reading the true surface")?;
    let reconstruction = reconstruction.context("imaging the scan")?;
    let mut imaging = image_points(reconstruction, options).context("imaging the scan")?;
    imaging.score_progressive(truth.as_ref(), frame);
    write_outputs(
        &imaging,
        out_dir,
        PlyEncoding::BinaryLittleEndian,
        missing_by_reason,
        if scenario.outputs.figures {
            Figures::Drawn
        } else {
            Figures::LeftOut
        },
    )
    .context("writing the imaging outputs")
}

/// The sensor's error values by name.
fn sensor_error_counts(values: impl Iterator<Item = IldValue>) -> BTreeMap<&'static str, u64> {
    let mut errors = BTreeMap::new();
    for value in values {
        if let IldValue::Error(error) = value {
            *errors.entry(error.name()).or_default() += 1;
        }
    }
    errors
}

/// `report.json` `faults`: what was declared, what was injected (frames on each direction of
/// the mirror's link, samples of the sensor), and what each side detected.
fn fault_report(
    scenario: &Scenario,
    run: &RunData,
    sensor_counters: &SensorCounters,
    sensor_errors: &BTreeMap<&'static str, u64>,
) -> serde_json::Value {
    let summary = run
        .emulator_summary
        .as_ref()
        .map(|emulator| &emulator["summary"]);
    let node = summary.map(|summary| &summary["node"]);
    let node_detected = node.map(|node| {
        serde_json::json!({
            "command_gaps": node["command_gaps"],
            "late_commands": node["late_commands"],
            "repeated_commands": node["repeated_commands"],
            "repeated_steps": node["repeated_steps"],
            "out_of_order_steps": node["out_of_order_steps"],
            "stale_periods": node["stale_periods"],
            "malformed_frames": node["malformed_frames"],
            "final_state": summary.map(|summary| &summary["final_state"]),
            "held_coil_currents_a": summary.map(|summary| &summary["held_coil_currents_a"]),
        })
    });
    let mirror = run.mirror_counters;
    serde_json::json!({
        "declared": scenario.faults,
        "injected": {
            "frames": run.frame_faults,
            "sensor_samples": summary.map(|summary| &summary["sensor_faults"]),
        },
        "host_detected": {
            "angle_sequence_gaps": mirror.angle_sequence_gaps,
            "late_readings": mirror.late_readings,
            "implausible_readings": mirror.implausible_readings,
            "malformed_frames": mirror.malformed_frames,
            "foreign_frames": mirror.foreign_frames,
            "repeated_steps": run.record.repeated_steps,
            "sensor_error_values": sensor_errors,
            "sensor_counter_gaps": sensor_counters.counter_gaps,
            "stopped_by": run.record.stopped_by.as_ref().map(ToString::to_string),
            "stopped_in_period": run.record.stopped_by.as_ref().map(|_| run.record.periods_done),
        },
        "node_detected": node_detected,
    })
}

/// A sensor's clock estimated from arrival times (a real sensor, which declares none): a
/// sample arrives after it was measured, so the earliest `arrival - counter / rate` on the
/// loop's time axis bounds counter 0's instant from above: within the line's transmission
/// time in real time, within one control period in lockstep (loop time is known there only
/// to the period the sample arrived in). The samples were bounded as they came, on the ILD
/// line and as Distance frames on the mirror's link ([`ArrivalBound`]); a wall-clock bound is
/// placed on the loop's axis by `epoch` (real time). Counter 0 at loop time 0 when nothing
/// bounds it.
fn estimate_sensor_clock<'a>(
    bounds: impl IntoIterator<Item = Option<&'a ArrivalBound>>,
    epoch: Option<tokio::time::Instant>,
    measuring_rate_hz: f64,
) -> SensorClock {
    let counter_zero_s = bounds
        .into_iter()
        .flatten()
        .filter_map(|bound| bound.counter_zero_s(epoch))
        .fold(f64::INFINITY, f64::min);
    SensorClock::new(
        measuring_rate_hz,
        if counter_zero_s.is_finite() {
            counter_zero_s
        } else {
            0.0
        },
    )
}

/// `tracking.svg`: the measured angles, the tracking error, and the relative error per window
/// (log scale, with the nominal loop's steady-state prediction) against loop time; the
/// recorded frame's start is marked in each panel.
fn write_tracking_plot(
    record: &LoopRecord,
    tracking: &TrackingSummary,
    plan: &PlanSummary,
    out_dir: &Path,
) -> anyhow::Result<()> {
    let period_s = record.period_s;
    let points = record.tracking.plot_points();
    if points.is_empty() {
        return Ok(());
    }
    let series = |label: &str, f: &dyn Fn(&PlotPoint) -> f64| Series {
        label: label.into(),
        points: points.iter().map(|point| (point.t_s, f(point))).collect(),
        markers: false,
    };
    let frame_start_s = record.lead_in_periods as f64 * period_s;
    // A vertical line at the frame's start spanning `values`, when there is a lead-in.
    let frame_marker = |values: &mut dyn Iterator<Item = f64>| {
        let (low, high) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        (record.lead_in_periods > 0 && low < high).then(|| Series {
            label: "frame start".into(),
            points: vec![(frame_start_s, low), (frame_start_s, high)],
            markers: false,
        })
    };
    let angles = vec![
        series("alpha", &|p| p.measured_rad.alpha * 1e3),
        series("beta", &|p| p.measured_rad.beta * 1e3),
    ];
    let error_series = vec![
        series("alpha", &|p| p.error_rad.alpha * 1e6),
        series("beta", &|p| p.error_rad.beta * 1e6),
    ];
    let window = |label: &str, pick: fn(&super::tracking::WindowError) -> f64| Series {
        label: label.into(),
        points: tracking
            .windows
            .iter()
            .map(|w| (w.start_s, pick(w)))
            .filter(|(_, v)| *v > 0.0)
            .collect(),
        markers: true,
    };
    let mut windows = vec![
        window("alpha", |w| w.alpha_rms_relative),
        window("beta", |w| w.beta_rms_relative),
    ];
    let end_s = record.tracking.periods() as f64 * period_s;
    let predicted = plan.predicted_tracking;
    for (label, value) in [
        ("alpha predicted", predicted.alpha_rms_relative),
        ("beta predicted", predicted.beta_rms_relative),
    ] {
        if let Some(value) = value.filter(|v| *v > 0.0) {
            windows.push(Series {
                label: label.into(),
                points: vec![(0.0, value), (end_s, value)],
                markers: false,
            });
        }
    }
    let with_marker = |mut lines: Vec<Series>| {
        let mut values = lines.iter().flat_map(|s| s.points.iter().map(|p| p.1));
        if let Some(marker) = frame_marker(&mut values) {
            lines.push(marker);
        }
        lines
    };
    let mut charts = vec![
        Chart {
            title: "Measured mirror angles".into(),
            x_label: "loop time (s)".into(),
            y_label: "angle (mrad)".into(),
            x_axis: Axis::Linear,
            y_axis: Axis::Linear,
            series: with_marker(angles),
        },
        Chart {
            title: "Tracking error (measured - reference)".into(),
            x_label: "loop time (s)".into(),
            y_label: "error (urad)".into(),
            x_axis: Axis::Linear,
            y_axis: Axis::Linear,
            series: with_marker(error_series),
        },
    ];
    if windows.iter().any(|s| !s.points.is_empty()) {
        charts.push(Chart {
            title: format!(
                "Relative rms error per {} ms window",
                super::tracking::WINDOW_S * 1e3
            ),
            x_label: "loop time (s)".into(),
            y_label: "rms error / reference peak".into(),
            x_axis: Axis::Linear,
            y_axis: Axis::Log,
            series: with_marker(windows),
        });
    }
    scanhil_protocol::whole_file::write_whole(
        &out_dir.join(TRACKING_SVG),
        |path| draw_charts(path, &charts).map_err(anyhow::Error::from),
        anyhow::Error::from,
    )
    .context("writing tracking.svg")
}

#[cfg(test)]
mod left_out_tests {
    use super::{OutputsConfig, imaging_outputs, left_out};

    #[test]
    fn what_is_left_out_is_each_switched_off_group_in_order() {
        let outputs = |recordings, figures| OutputsConfig {
            recordings,
            figures,
        };
        assert!(left_out(outputs(true, true)).is_empty());
        assert_eq!(left_out(outputs(false, true)), ["fsm.log", "sensor.ild"]);
        assert_eq!(
            left_out(outputs(true, false)),
            [
                "tracking.svg",
                "height_map.png",
                "progressive.svg",
                "snapshots.png",
                "profiles.svg"
            ]
        );
        assert_eq!(left_out(outputs(false, false)).len(), 7);
    }

    #[test]
    fn the_imaging_writes_its_files_but_the_pictures_left_out() {
        let outputs = |figures| OutputsConfig {
            recordings: false,
            figures,
        };
        assert_eq!(imaging_outputs(outputs(true)), super::IMAGING_OUTPUTS);
        assert_eq!(
            imaging_outputs(outputs(false)),
            ["points.ply", "height_map.csv", "profiles.csv"]
        );
    }
}

#[cfg(test)]
mod tests {
    //! The real sensor's clock estimate (`estimate_sensor_clock`) from known counter/arrival
    //! pairs: each sample arrives a transmission time plus a random queueing delay after it
    //! was measured, so the estimate must lie within the transmission time (and the smallest
    //! queueing delay) after the true `counter_zero_s`, never before it.

    use std::time::Duration;

    use super::estimate_sensor_clock;
    use crate::run::pairing::ArrivalBound;

    const RATE_HZ: f64 = 20_000.0;
    /// One ILD cycle (3 bytes of 10 bits) at 691 200 Bd.
    const TRANSMISSION_S: f64 = 30.0 / 691_200.0;

    /// `(counter, arrival)` of samples with counters `first..first + n` measured from
    /// `zero_s` on the loop's time axis; each arrives `TRANSMISSION_S` plus a queueing delay
    /// (up to `jitter_s`, zero for every 50th sample: the line drains in bursts) after its
    /// instant, in shuffled order.
    fn samples(
        epoch: tokio::time::Instant,
        zero_s: f64,
        first: u64,
        n: u64,
        jitter_s: f64,
    ) -> Vec<(u64, tokio::time::Instant)> {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut out: Vec<(u64, tokio::time::Instant)> = (first..first + n)
            .map(|counter| {
                let queued = if counter % 50 == 0 {
                    0.0
                } else {
                    uniform() * jitter_s
                };
                let measured = zero_s + counter as f64 / RATE_HZ;
                let arrived = epoch + Duration::from_secs_f64(measured + TRANSMISSION_S + queued);
                (counter, arrived)
            })
            .collect();
        // Arrival order never matters: hand them over last first.
        out.reverse();
        out
    }

    /// The estimate from `samples` both ways they come: all on the ILD line, and split
    /// between the line and Distance frames on the mirror's link (each bounded as they
    /// arrive); both must agree.
    fn estimate(epoch: tokio::time::Instant, samples: &[(u64, tokio::time::Instant)]) -> f64 {
        let bound = |samples: &mut dyn Iterator<Item = &(u64, tokio::time::Instant)>| {
            let mut bound = ArrivalBound::wall_clock(RATE_HZ);
            for &(counter, arrived) in samples {
                bound.note(arrived, counter);
            }
            bound
        };
        let all = bound(&mut samples.iter());
        let on_the_line = estimate_sensor_clock([Some(&all), None], Some(epoch), RATE_HZ);
        let (line, can) = (
            bound(&mut samples.iter().step_by(2)),
            bound(&mut samples.iter().skip(1).step_by(2)),
        );
        let split = estimate_sensor_clock([Some(&line), Some(&can)], Some(epoch), RATE_HZ);
        assert_eq!(on_the_line.measuring_rate_hz, RATE_HZ);
        assert!(
            (on_the_line.counter_zero_s - split.counter_zero_s).abs() < 1e-9,
            "ILD line {} s, split with CAN {} s",
            on_the_line.counter_zero_s,
            split.counter_zero_s
        );
        on_the_line.counter_zero_s
    }

    #[test]
    fn the_estimate_is_within_the_transmission_time_of_the_true_clock() {
        let epoch = tokio::time::Instant::now();
        for (zero_s, first, jitter_s) in [
            (0.0123, 0, 2e-3),
            (0.5, 262_144 + 17, 5e-3), // past one wrap of the 18-bit counter
            (0.0, 0, 0.0),
        ] {
            let estimate_s = estimate(epoch, &samples(epoch, zero_s, first, 4000, jitter_s));
            let error = estimate_s - zero_s;
            assert!(
                (-1e-9..=TRANSMISSION_S + 1e-9).contains(&error),
                "estimate {estimate_s} for a true {zero_s}: {error} s off (transmission \
                 {TRANSMISSION_S} s)"
            );
        }
    }

    #[test]
    fn a_late_burst_does_not_pull_the_estimate() {
        // Every sample delayed by at least 1 ms except one prompt one: the prompt one decides.
        let epoch = tokio::time::Instant::now();
        let mut all = samples(epoch, 0.02, 0, 1000, 3e-3);
        for (counter, arrived) in &mut all {
            if *counter != 500 {
                *arrived += Duration::from_millis(1);
            }
        }
        let error = estimate(epoch, &all) - 0.02;
        assert!((-1e-9..=TRANSMISSION_S + 1e-9).contains(&error), "{error}");
    }

    #[test]
    fn no_samples_give_counter_zero_at_the_epoch() {
        assert_eq!(estimate(tokio::time::Instant::now(), &[]), 0.0);
    }
}
