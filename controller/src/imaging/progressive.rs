//! Progressive imaging: the height map a scan has built after any part of its frame (the
//! paper's Fig. 6), and, when the true surface is known, its error against scan time.
//!
//! At each checkpoint time `t` the map holds every sample taken up to `t`, gridded with the
//! chosen [`GridMethod`] (incrementally: one pass over the samples for all checkpoints).
//! Against the truth it is scored two ways:
//! - **covered cells**: RMS, max and median absolute value of `map - truth` over the cells
//!   some sample reached, with the fraction of cells covered; this is what the scan has
//!   measured so far;
//! - **whole image**: the same over every cell after filling the missing ones with the
//!   chosen [`FillMethod`]; this is the preview a user sees (a Lissajous scan covers the whole
//!   field coarsely early, a raster scan line by line).
//!
//! The truth is compared at cell centres. [`simulate_samples`] makes the samples of an ideal
//! scan (perfect tracking, no noise) of a [`ScanScene`]; a recorded scan's samples go straight
//! into [`progressive_errors`] instead.

use std::borrow::Cow;
use std::path::Path;

use scanhil_geometry::{GeometryModel, Scanner};
use scanhil_report::{Axis, Chart, ReportError, Series, draw_charts};

use super::fill::{FillMethod, fill_missing};
use super::grid::{GridAccumulator, GridMethod, GridSpec, HeightMap};
use super::reconstruct::{ScanPoint, ScanSample};

/// What a simulated scan sees.
pub trait ScanScene {
    /// The sensor's distance for the mirror deflections (rad), or `None` where the sensor
    /// reports an error (shading, out of range).
    fn z_meas_mm(&self, d_alpha_rad: f64, d_beta_rad: f64) -> Option<f64>;
    /// The true surface z at `(x, y)`, mm, or `None` where the scene has no surface.
    fn true_z_mm(&self, x_mm: f64, y_mm: f64) -> Option<f64>;
}

/// An ideal scene: a height field `z = f(x, y)` seen along the scanner's beam, with no
/// shading and no noise; the distance is the first crossing of the beam with the surface
/// inside the sensor's range.
#[derive(Debug, Clone, Copy)]
pub struct HeightFieldScene<F> {
    /// The beam geometry (its model is the "physical truth" of the simulation).
    pub scanner: Scanner,
    /// The surface, z in mm at (x, y) in mm.
    pub surface: F,
    /// The sensor's measuring range, (start, end) z_meas in mm.
    pub range_mm: (f64, f64),
}

/// The march step along the beam when looking for the surface, mm (then bisection); a
/// surface part thinner than this along the beam can be missed.
const MARCH_STEP_MM: f64 = 0.25;

impl<F: Fn(f64, f64) -> f64> ScanScene for HeightFieldScene<F> {
    fn z_meas_mm(&self, d_alpha_rad: f64, d_beta_rad: f64) -> Option<f64> {
        let ray = self.scanner.beam(d_alpha_rad, d_beta_rad);
        // Above the surface: positive.
        let gap = |z_meas: f64| {
            let p = ray.point_at(z_meas);
            p.z - (self.surface)(p.x, p.y)
        };
        let (start, end) = self.range_mm;
        let mut lo = start;
        // Already at or below the surface at the start of the range (or NaN): no reading.
        if gap(lo).is_nan() || gap(lo) <= 0.0 {
            return None;
        }
        while lo < end {
            let hi = (lo + MARCH_STEP_MM).min(end);
            if gap(hi) <= 0.0 {
                let (mut a, mut b) = (lo, hi);
                for _ in 0..60 {
                    let m = 0.5 * (a + b);
                    if gap(m) > 0.0 { a = m } else { b = m }
                }
                return Some(0.5 * (a + b));
            }
            lo = hi;
        }
        None
    }

    fn true_z_mm(&self, x_mm: f64, y_mm: f64) -> Option<f64> {
        Some((self.surface)(x_mm, y_mm))
    }
}

/// The samples of an ideal scan: the mirror follows `angles_rad(t) = (d_alpha, d_beta)`
/// exactly, the sensor samples at `sample_rate_hz` from `t = 0` for `duration_s`.
pub fn simulate_samples(
    angles_rad: impl Fn(f64) -> (f64, f64),
    scene: &impl ScanScene,
    sample_rate_hz: f64,
    duration_s: f64,
) -> Vec<ScanSample> {
    let n = (duration_s * sample_rate_hz).round().max(0.0) as usize;
    (0..n)
        .map(|k| {
            let t_s = k as f64 / sample_rate_hz;
            let (d_alpha_rad, d_beta_rad) = angles_rad(t_s);
            ScanSample {
                t_s,
                d_alpha_rad,
                d_beta_rad,
                z_meas_mm: scene.z_meas_mm(d_alpha_rad, d_beta_rad),
            }
        })
        .collect()
}

/// The part of the sample clock a scan images: from `start_s` (the first sample's time) for
/// `length_s` (the scan's frame). Fractions of the scan are fractions of this span.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ScanFrame {
    /// The frame's first instant on the samples' clock, s.
    pub start_s: f64,
    /// The frame's length, s.
    pub length_s: f64,
}

impl ScanFrame {
    /// The frame of `length_s` that starts at the earliest finite time of `times_s` (0
    /// without one): a scan's frame from its samples' times.
    #[must_use]
    pub fn from_first_sample(times_s: impl IntoIterator<Item = f64>, length_s: f64) -> ScanFrame {
        let start_s = times_s
            .into_iter()
            .filter(|t| t.is_finite())
            .fold(None, |acc: Option<f64>, t| {
                Some(acc.map_or(t, |a| a.min(t)))
            });
        ScanFrame {
            start_s: start_s.unwrap_or(0.0),
            length_s,
        }
    }

    /// The frame from the earliest to the latest finite time of `times_s` (a recording's
    /// span; 0 s at 0 without one).
    #[must_use]
    pub fn spanning(times_s: impl IntoIterator<Item = f64>) -> ScanFrame {
        let (first, last) = times_s
            .into_iter()
            .filter(|t| t.is_finite())
            .fold(None, |acc: Option<(f64, f64)>, t| {
                Some(acc.map_or((t, t), |(a, b)| (a.min(t), b.max(t))))
            })
            .unwrap_or((0.0, 0.0));
        ScanFrame {
            start_s: first,
            length_s: last - first,
        }
    }

    /// The sample time after `fraction` of the frame, s.
    #[must_use]
    pub fn time_at(&self, fraction: f64) -> f64 {
        self.start_s + fraction * self.length_s
    }
}

/// The map after every checkpoint time (ascending): each holds the points taken up to then.
#[must_use]
pub fn progressive_maps(
    points: &[ScanPoint],
    spec: GridSpec,
    grid: GridMethod,
    checkpoints_s: &[f64],
) -> Vec<(f64, HeightMap)> {
    progressive_maps_with(points, spec, grid, checkpoints_s, |p| p.z_mm)
}

/// [`progressive_maps`] of each point's `height_mm(point)` instead of its z_s (such as its
/// height above a plane), computed as the point is added. Points in time order (a scan's)
/// are read in place; others (a recording or a PLY from elsewhere) are copied and sorted by
/// time first (stable: points of one time keep their order).
#[must_use]
pub fn progressive_maps_with(
    points: &[ScanPoint],
    spec: GridSpec,
    grid: GridMethod,
    checkpoints_s: &[f64],
    height_mm: impl Fn(&ScanPoint) -> f64,
) -> Vec<(f64, HeightMap)> {
    let by_time = |a: &ScanPoint, b: &ScanPoint| a.t_s.total_cmp(&b.t_s);
    let points: Cow<'_, [ScanPoint]> = if points.is_sorted_by(|a, b| by_time(a, b).is_le()) {
        Cow::Borrowed(points)
    } else {
        let mut sorted = points.to_vec();
        sorted.sort_by(by_time);
        Cow::Owned(sorted)
    };
    let mut acc = GridAccumulator::new(spec, grid);
    let mut next = 0;
    let mut out = Vec::with_capacity(checkpoints_s.len());
    for &t in checkpoints_s {
        while next < points.len() && points[next].t_s <= t {
            let p = &points[next];
            acc.add(p.x_mm, p.y_mm, height_mm(p));
            next += 1;
        }
        out.push((t, acc.height_map()));
    }
    out
}

/// The error of the map at one checkpoint.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ProgressivePoint {
    /// Scan time, s.
    pub t_s: f64,
    /// Fraction of cells measured.
    pub coverage_fraction: f64,
    /// RMS error over the measured cells, mm (`None` before the first).
    pub covered_rms_mm: Option<f64>,
    /// Largest error over the measured cells, mm.
    pub covered_max_mm: Option<f64>,
    /// Median absolute error over the measured cells, mm: the flat areas' accuracy, which
    /// the RMS hides behind the few cells that straddle a step.
    pub covered_median_abs_mm: Option<f64>,
    /// RMS error over all cells after the fill, mm.
    pub image_rms_mm: Option<f64>,
    /// Largest error over all cells after the fill, mm.
    pub image_max_mm: Option<f64>,
    /// Median absolute error over all cells after the fill, mm.
    pub image_median_abs_mm: Option<f64>,
}

/// Scores the map after each checkpoint against `truth` (see the module doc).
pub fn progressive_errors(
    points: &[ScanPoint],
    spec: GridSpec,
    grid: GridMethod,
    fill: FillMethod,
    checkpoints_s: &[f64],
    truth: impl Fn(f64, f64) -> Option<f64>,
) -> Vec<ProgressivePoint> {
    let truth_at: Vec<Option<f64>> = (0..spec.len())
        .map(|i| {
            let (x, y) = spec.centre_mm(i % spec.nx, i / spec.nx);
            truth(x, y)
        })
        .collect();
    let score = |map: &HeightMap, only_measured: bool| {
        let errors: Vec<f64> = (0..spec.len())
            .filter(|&i| !only_measured || map.samples[i] > 0)
            .filter_map(|i| Some(map.heights_mm[i]? - truth_at[i]?))
            .collect();
        if errors.is_empty() {
            return ErrorFigures::default();
        }
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        let mut abs: Vec<f64> = errors.iter().map(|e| e.abs()).collect();
        abs.sort_by(f64::total_cmp);
        ErrorFigures {
            rms: Some(rms),
            max: abs.last().copied(),
            median_abs: Some(abs[abs.len() / 2]),
        }
    };
    progressive_maps(points, spec, grid, checkpoints_s)
        .into_iter()
        .map(|(t_s, mut map)| {
            let covered = score(&map, true);
            let coverage_fraction = map.coverage_fraction();
            fill_missing(&mut map, fill);
            let image = score(&map, false);
            ProgressivePoint {
                t_s,
                coverage_fraction,
                covered_rms_mm: covered.rms,
                covered_max_mm: covered.max,
                covered_median_abs_mm: covered.median_abs,
                image_rms_mm: image.rms,
                image_max_mm: image.max,
                image_median_abs_mm: image.median_abs,
            }
        })
        .collect()
}

/// RMS, max and median absolute error of a set of cells.
#[derive(Debug, Clone, Copy, Default)]
struct ErrorFigures {
    rms: Option<f64>,
    max: Option<f64>,
    median_abs: Option<f64>,
}

/// One trajectory's error against scan time.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ProgressiveRun {
    /// The trajectory's name.
    pub name: String,
    /// Its samples.
    pub samples: usize,
    /// Samples without a distance.
    pub missing_samples: usize,
    /// The error at each checkpoint.
    pub points: Vec<ProgressivePoint>,
}

/// Trajectories side by side on one grid and truth.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ProgressiveComparison {
    /// The reconstruction model's name.
    pub reconstruction_model: String,
    /// The model of the simulated beam (the truth), if simulated.
    pub simulation_model: Option<String>,
    /// The grid.
    pub grid: GridSpec,
    /// The gridding.
    pub grid_method: GridMethod,
    /// The fill of the whole-image score.
    pub fill: FillMethod,
    /// One run per trajectory.
    pub runs: Vec<ProgressiveRun>,
}

impl ProgressiveComparison {
    /// The comparison's name for a reconstruction model and optional simulation model.
    #[must_use]
    pub fn new(
        reconstruction: GeometryModel,
        simulation: Option<GeometryModel>,
        grid: GridSpec,
        grid_method: GridMethod,
        fill: FillMethod,
    ) -> ProgressiveComparison {
        ProgressiveComparison {
            reconstruction_model: reconstruction.name().into(),
            simulation_model: simulation.map(|m| m.name().into()),
            grid,
            grid_method,
            fill,
            runs: Vec::new(),
        }
    }

    /// Draws up to four panels against scan time: whole-image RMS error, covered-cell RMS and
    /// median absolute error (log scale, mm, when a truth gave errors) and coverage; one line
    /// per run.
    pub fn draw(&self, path: &Path) -> Result<(), ReportError> {
        let series = |pick: &dyn Fn(&ProgressivePoint) -> Option<f64>| -> Vec<Series> {
            self.runs
                .iter()
                .map(|r| Series {
                    label: r.name.clone(),
                    points: r
                        .points
                        .iter()
                        .filter_map(|p| Some((p.t_s, pick(p)?)))
                        .collect(),
                    markers: false,
                })
                .collect()
        };
        let chart = |title: &str, y_label: &str, y_axis, s| Chart {
            title: title.into(),
            x_label: "scan time (s)".into(),
            y_label: y_label.into(),
            x_axis: Axis::Linear,
            y_axis,
            series: s,
        };
        let charts = [
            chart(
                &format!(
                    "whole image (missing cells: {:?} fill): RMS error",
                    self.fill
                ),
                "RMS error (mm)",
                Axis::Log,
                series(&|p| p.image_rms_mm),
            ),
            chart(
                "measured cells: RMS error",
                "RMS error (mm)",
                Axis::Log,
                series(&|p| p.covered_rms_mm),
            ),
            chart(
                "measured cells: median absolute error",
                "median |error| (mm)",
                Axis::Log,
                series(&|p| p.covered_median_abs_mm),
            ),
            chart(
                "coverage",
                "measured cells (fraction)",
                Axis::Linear,
                series(&|p| Some(p.coverage_fraction)),
            ),
        ];
        // Without a truth only the coverage has points: the error panels are left out.
        let drawable: Vec<Chart> = charts
            .into_iter()
            .filter(|chart| chart.series.iter().any(|s| !s.points.is_empty()))
            .collect();
        draw_charts(path, &drawable)
    }
}
