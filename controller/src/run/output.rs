//! The output folder of a scan:
//!
//! | file | what |
//! |------|------|
//! | `report.json` | scenario, active plant parts, timing, tracking error, resolution and frame rate, feature height, reconstruction error against scan time, counters |
//! | `points.ply` | the reconstructed point cloud (binary little-endian PLY with t, angles, z_meas) |
//! | `height_map.png`, `height_map.csv` | the gridded heights (missing cells magenta / empty) |
//! | `tracking.svg` | reference and measured angles, and the tracking error, over time |
//! | `progressive.svg` | reconstruction error and coverage against scan time (when the truth is known) |
//! | `fsm.log` | every frame on the mirror link, candump `-L` format, loop-time stamps |
//! | `sensor.ild` | every byte of the ILD stream, raw (`scanhil decode --format ild`) |

use std::path::Path;

use anyhow::Context;
use scanhil_emulator::scene::Scene;
use scanhil_geometry::Scanner;
use scanhil_protocol::ild::{IldValue, MeasuringRange};
use scanhil_report::{Axis, Chart, Series, draw_charts};

use super::ScanEnd;
use super::lockstep::LoopRecord;
use super::mirror_link::{MirrorLinkCounters, NodeEvent};
use super::pairing::{CounterUnwrapper, SensorClock};
use super::scenario::Scenario;
use super::sensor_link::{CountedSample, ILD_COUNTER_MODULUS, SensorCounters};
use crate::imaging::feature::feature_height;
use crate::imaging::grid::{GridMethod, GridSpec, HeightMap, grid_points};
use crate::imaging::ply::{PlyEncoding, write_ply_file};
use crate::imaging::reconstruct::{ScanSample, reconstruct};

/// The mirror link's candump log.
pub const FSM_LOG: &str = "fsm.log";
/// The interface name in the candump log, the same on every transport so recordings compare.
pub const FSM_INTERFACE: &str = "fsm";
/// The ILD stream's raw capture.
pub const SENSOR_CAPTURE: &str = "sensor.ild";
/// The run report.
pub const REPORT: &str = "report.json";

/// Everything the loop produced, before imaging.
#[derive(Debug)]
pub struct RunData {
    /// The loop's record.
    pub record: LoopRecord,
    /// Distance frames that came on the mirror's CAN link, with their arrival.
    pub can_distances: Vec<(u32, IldValue, tokio::time::Instant)>,
    /// The mirror link's counters.
    pub mirror_counters: MirrorLinkCounters,
    /// Status and fault frames of the mirror node.
    pub node_events: Vec<NodeEvent>,
    /// The ILD stream's samples and counters.
    pub sensor: (Vec<CountedSample>, SensorCounters),
    /// What the sensor set-up before the run did.
    pub sensor_setup: Option<super::sensor_setup::SensorSetupReport>,
    /// The emulator's exit status and summary line, when it was started by this run.
    pub emulator_summary: Option<serde_json::Value>,
}

/// Images the run and writes every output file; returns how the run ended.
///
/// # Errors
/// A file that cannot be written.
pub fn write(
    scenario: &Scenario,
    scene: &Scene,
    run: &RunData,
    clock: Option<SensorClock>,
    measuring_rate_hz: f64,
    out_dir: &Path,
) -> anyhow::Result<ScanEnd> {
    let record = &run.record;
    let range = MeasuringRange::ILD2300_100;
    let (mut counted, sensor_counters) = run.sensor.clone();
    let mut can_counter = CounterUnwrapper::new(ILD_COUNTER_MODULUS);
    counted.extend(
        run.can_distances
            .iter()
            .map(|&(counter, value, arrived)| CountedSample {
                counter: can_counter.unwrap(u64::from(counter)),
                value,
                arrived,
            }),
    );
    let clock = match (clock, record.loop_epoch) {
        (Some(declared), _) => declared,
        (None, Some(epoch)) => estimate_sensor_clock(&counted, epoch, measuring_rate_hz),
        (None, None) => SensorClock {
            measuring_rate_hz,
            counter_zero_s: 0.0,
        },
    };
    let mut unpaired = 0u64;
    let samples: Vec<ScanSample> = counted
        .iter()
        .filter_map(|sample| {
            let t_s = clock.instant_s(sample.counter);
            let Some(angles) = record.angles.at(t_s) else {
                unpaired += 1;
                return None;
            };
            let z_meas_mm = match sample.value {
                IldValue::Distance(digital) => range.digital_to_mm(digital),
                IldValue::Error(_) => None,
            };
            Some(ScanSample {
                t_s,
                d_alpha_rad: angles.alpha,
                d_beta_rad: angles.beta,
                z_meas_mm,
            })
        })
        .collect();
    let scanner = Scanner::paper(scenario.imaging.reconstruction);
    let reconstruction = reconstruct(&samples, &scanner);
    let points = &reconstruction.cloud.points;
    if !points.is_empty() {
        write_ply_file(
            &out_dir.join("points.ply"),
            &reconstruction.cloud,
            PlyEncoding::BinaryLittleEndian,
        )
        .context("writing points.ply")?;
    }
    let xyz: Vec<[f64; 3]> = points.iter().map(|p| [p.x_mm, p.y_mm, p.z_mm]).collect();
    let spec = GridSpec::covering(xyz.iter().map(|p| (p[0], p[1])), scenario.imaging.pitch_mm).ok();
    let height_map = spec.map(|spec| {
        grid_points(
            xyz.iter().map(|p| (p[0], p[1], p[2])),
            spec,
            GridMethod::default(),
        )
    });
    if let Some(map) = &height_map {
        // Cells drawn 4 pixels wide: a 0.1 mm grid over a 12 mm field is a readable 480 px.
        map.write_png(&out_dir.join("height_map.png"), 4)
            .context("writing height_map.png")?;
        let csv = std::fs::File::create(out_dir.join("height_map.csv"))
            .context("writing height_map.csv")?;
        map.write_csv(std::io::BufWriter::new(csv))
            .context("writing height_map.csv")?;
    }
    let feature = scenario
        .imaging
        .feature
        .map(|params| feature_height(&xyz, &params).map_err(|error| error.to_string()));
    let truth = super::truth::TrueSurface::from_scene(scene)
        .map_err(|error| anyhow::anyhow!("scene {}: surface: {error}", scene.name))?;
    let progressive = progressive_error(
        points,
        spec,
        record.periods_done as f64 * record.angles.period_s(),
        scenario.imaging.progressive_steps,
        truth.as_ref(),
    );
    write_plots(record, &progressive, out_dir)?;
    let end = match &record.stopped_by {
        None => ScanEnd::Complete,
        Some(error) => ScanEnd::Stopped(error.to_string()),
    };
    let figures = scenario.trajectory.figures(height_map.as_ref().map(|m| {
        (
            m.spec.nx as f64 * m.spec.pitch_mm,
            m.spec.ny as f64 * m.spec.pitch_mm,
        )
    }));
    let report = serde_json::json!({
        "scenario": {
            "name": scenario.name,
            "file": scenario.path.display().to_string(),
            "scene": scenario.scene.display().to_string(),
            "controller": scenario.controller.display().to_string(),
            "seed": scenario.seed,
            "duration_s": scenario.duration_s,
            "timing": scenario.timing,
            "links": scenario.links,
            "reconstruction": scenario.imaging.reconstruction.name(),
        },
        "outcome": match &end {
            ScanEnd::Complete => serde_json::json!({"complete": true}),
            ScanEnd::Stopped(why) => serde_json::json!({"complete": false, "stopped_by": why}),
        },
        "active_plant_parts": scene.parts,
        "periods": {
            "planned": record.periods_planned,
            "done": record.periods_done,
            "period_s": record.angles.period_s(),
            "saturated": record.saturated_periods,
        },
        "timing": {
            "mode": scenario.timing.mode,
            "controller": record.controller_timing,
            "emulator": run.emulator_summary.as_ref().map(|e| e["summary"]["timing"].clone()),
        },
        "tracking_error": record.tracking.summary(),
        "sensor_setup": run.sensor_setup,
        "trajectory": figures,
        "samples": {
            "sensor_samples": counted.len(),
            "paired": samples.len(),
            "outside_the_angle_record": unpaired,
            "points": points.len(),
            "missing_distances": reconstruction.missing_samples,
            "sensor_clock": clock,
        },
        "height_map": height_map.as_ref().map(|m| serde_json::json!({
            "nx": m.spec.nx, "ny": m.spec.ny, "pitch_mm": m.spec.pitch_mm,
            "coverage": m.coverage_fraction(),
        })),
        "feature": feature.map(|f| match f {
            Ok(f) => serde_json::json!({
                "height_mm": f.height_mm, "std_mm": f.std_mm, "median_mm": f.median_mm,
                "points": f.points,
            }),
            Err(error) => serde_json::json!({ "error": error }),
        }),
        "reconstruction_error_vs_scan_time": progressive,
        "links": {
            "mirror": run.mirror_counters,
            "sensor": sensor_counters,
            "node_events": run.node_events,
        },
        "emulator": run.emulator_summary,
    });
    let text = serde_json::to_string_pretty(&report).context("formatting report.json")?;
    std::fs::write(out_dir.join(REPORT), text + "\n").context("writing report.json")?;
    Ok(end)
}

/// A sensor's clock estimated from arrival times (real time, a real sensor): a sample arrives
/// after it was measured, so the earliest `arrival - counter / rate` on the loop's time axis
/// (whose epoch the angle readings fixed the same way) bounds counter 0's instant from above,
/// within the line's transmission time.
fn estimate_sensor_clock(
    samples: &[CountedSample],
    loop_epoch: tokio::time::Instant,
    measuring_rate_hz: f64,
) -> SensorClock {
    let counter_zero_s = samples
        .iter()
        .map(|s| {
            s.arrived
                .saturating_duration_since(loop_epoch)
                .as_secs_f64()
                - s.counter as f64 / measuring_rate_hz
        })
        .fold(f64::INFINITY, f64::min);
    SensorClock {
        measuring_rate_hz,
        counter_zero_s: if counter_zero_s.is_finite() {
            counter_zero_s
        } else {
            0.0
        },
    }
}

/// One point of the reconstruction error against scan time.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ProgressivePoint {
    /// Scan time, s.
    pub scan_time_s: f64,
    /// Fraction of the grid's cells measured by then.
    pub coverage: f64,
    /// RMS of (measured - true) surface height over the measured cells, mm (dominated by the
    /// cells that straddle an edge).
    pub rms_error_mm: Option<f64>,
    /// Median of |measured - true| over the measured cells, mm (the typical cell).
    pub median_abs_error_mm: Option<f64>,
}

fn progressive_error(
    points: &[crate::imaging::reconstruct::ScanPoint],
    spec: Option<GridSpec>,
    scan_time_s: f64,
    steps: usize,
    truth: Option<&super::truth::TrueSurface>,
) -> Vec<ProgressivePoint> {
    let Some(spec) = spec else {
        return Vec::new();
    };
    (1..=steps)
        .map(|i| {
            let until = scan_time_s * i as f64 / steps as f64;
            let map = grid_points(
                points
                    .iter()
                    .filter(|p| p.t_s <= until)
                    .map(|p| (p.x_mm, p.y_mm, p.z_mm)),
                spec,
                GridMethod::default(),
            );
            let errors = truth
                .map(|t| errors_against_truth(&map, t))
                .unwrap_or_default();
            ProgressivePoint {
                scan_time_s: until,
                coverage: map.coverage_fraction(),
                rms_error_mm: rms(&errors),
                median_abs_error_mm: median_abs(errors),
            }
        })
        .collect()
}

/// (measured - true) height of every measured cell where the truth is known, mm.
fn errors_against_truth(map: &HeightMap, truth: &super::truth::TrueSurface) -> Vec<f64> {
    let mut errors = Vec::new();
    for iy in 0..map.spec.ny {
        for ix in 0..map.spec.nx {
            let Some(h) = map.heights_mm[map.spec.index(ix, iy)] else {
                continue;
            };
            let (x, y) = map.spec.centre_mm(ix, iy);
            if let Some(z) = truth.z_mm(x, y) {
                errors.push(h - z);
            }
        }
    }
    errors
}

fn rms(errors: &[f64]) -> Option<f64> {
    (!errors.is_empty())
        .then(|| (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt())
}

fn median_abs(errors: Vec<f64>) -> Option<f64> {
    let mut magnitudes: Vec<f64> = errors.into_iter().map(f64::abs).collect();
    magnitudes.sort_by(f64::total_cmp);
    magnitudes.get(magnitudes.len() / 2).copied()
}

fn write_plots(
    record: &LoopRecord,
    progressive: &[ProgressivePoint],
    out_dir: &Path,
) -> anyhow::Result<()> {
    let period_s = record.angles.period_s();
    let readings = record.angles.readings_rad();
    let errors = record.tracking.errors_rad();
    let stride = (readings.len() / 4000).max(1);
    let series = |label: &str, f: &dyn Fn(usize) -> f64| Series {
        label: label.into(),
        points: (0..readings.len())
            .step_by(stride)
            .map(|k| ((k + 1) as f64 * period_s, f(k)))
            .collect(),
        markers: false,
    };
    if !readings.is_empty() {
        let charts = [
            Chart {
                title: "Measured mirror angles".into(),
                x_label: "loop time (s)".into(),
                y_label: "angle (mrad)".into(),
                x_axis: Axis::Linear,
                y_axis: Axis::Linear,
                series: vec![
                    series("alpha", &|k| readings[k].alpha * 1e3),
                    series("beta", &|k| readings[k].beta * 1e3),
                ],
            },
            Chart {
                title: "Tracking error (measured - reference)".into(),
                x_label: "loop time (s)".into(),
                y_label: "error (urad)".into(),
                x_axis: Axis::Linear,
                y_axis: Axis::Linear,
                series: vec![
                    series("alpha", &|k| errors[k].alpha * 1e6),
                    series("beta", &|k| errors[k].beta * 1e6),
                ],
            },
        ];
        draw_charts(&out_dir.join("tracking.svg"), &charts).context("writing tracking.svg")?;
    }
    let error_series = |label: &str, pick: fn(&ProgressivePoint) -> Option<f64>| Series {
        label: label.into(),
        points: progressive
            .iter()
            .filter_map(|p| pick(p).map(|e| (p.scan_time_s, e)))
            .collect(),
        markers: true,
    };
    let rms_series = error_series("RMS", |p| p.rms_error_mm);
    let median_series = error_series("median |error|", |p| p.median_abs_error_mm);
    if !progressive.is_empty() {
        let mut charts = vec![Chart {
            title: "Coverage against scan time".into(),
            x_label: "scan time (s)".into(),
            y_label: "measured cells (fraction)".into(),
            x_axis: Axis::Linear,
            y_axis: Axis::Linear,
            series: vec![Series {
                label: "coverage".into(),
                points: progressive
                    .iter()
                    .map(|p| (p.scan_time_s, p.coverage))
                    .collect(),
                markers: true,
            }],
        }];
        if !rms_series.points.is_empty() {
            charts.push(Chart {
                title: "Reconstruction error against scan time".into(),
                x_label: "scan time (s)".into(),
                y_label: "height error (mm)".into(),
                x_axis: Axis::Linear,
                y_axis: Axis::Log,
                series: vec![rms_series, median_series],
            });
        }
        draw_charts(&out_dir.join("progressive.svg"), &charts)
            .context("writing progressive.svg")?;
    }
    Ok(())
}
