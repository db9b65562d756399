//! Peak heap of the imaging once a frame's points exist, per point: two synthetic frames
//! (the simulated stud, Lissajous at 20 kHz) are reconstructed, then each step after that is
//! measured by the allocator's count ([`peak_alloc`]) as the most bytes it held at once
//! beyond what was live when it began. A step's `bytes_per_added_point` (its peak's growth from the shorter frame
//! to the longer, per point added) is what it holds per point: a copy of the points' x, y, z
//! shows as 24 B or more, a grid or a figure as nothing. The floor is the point itself
//! (56 B): `added_point_ratio_to_the_point` says how much of a second frame the step holds.
//! Prints JSON; fails (exit 1, naming the steps) when a step holds more than
//! [`BUDGET_BYTES_PER_ADDED_POINT`] per point added.
//!
//! `cargo bench -p scanhil-controller --bench imaging_memory [-- SHORT_S LONG_S]` (default
//! 10 and 20 s: 200 000 and 400 000 samples)

#[path = "../tests/imaging_support/mod.rs"]
mod imaging_support;

use std::collections::BTreeMap;

use anyhow::Context;
use peak_alloc::PeakAlloc;

use imaging_support::{lissajous, stud_scene};
use scanhil_controller::imaging::feature::FeatureParams;
use scanhil_controller::imaging::pipeline::{Figures, ImagingOptions, image_points, write_outputs};
use scanhil_controller::imaging::ply::PlyEncoding;
use scanhil_controller::imaging::progressive::{ScanFrame, simulate_samples};
use scanhil_controller::imaging::reconstruct::{Reconstruction, ScanPoint, reconstruct};
use scanhil_geometry::{GeometryModel, Scanner};

#[global_allocator]
static HEAP: PeakAlloc = PeakAlloc;

/// Runs `step` and returns its value with the most bytes it held at once beyond those live
/// when it began.
fn measure<T>(step: impl FnOnce() -> T) -> (T, usize) {
    let before = HEAP.current_usage();
    HEAP.reset_peak_usage();
    let value = step();
    (value, HEAP.peak_usage().saturating_sub(before))
}

/// The most a step may hold per point added before the bench fails: below a copy of the
/// points' x, y, z (24 B); the imaging holds 1-4 B (flags while the plane is refined, the
/// feature's heights).
const BUDGET_BYTES_PER_ADDED_POINT: f64 = 16.0;

/// The steps measured, by name, with their peaks in bytes.
type Peaks = BTreeMap<&'static str, usize>;

/// The steps after reconstruction on `reconstruction` with `options`: each one's peak.
fn measure_imaging(
    reconstruction: Reconstruction,
    options: &ImagingOptions,
    length_s: f64,
) -> anyhow::Result<Peaks> {
    let (imaging, image_peak) = measure(|| image_points(reconstruction, options));
    let mut imaging = imaging?;
    let frame = ScanFrame::from_first_sample(
        imaging.reconstruction.cloud.points.iter().map(|p| p.t_s),
        length_s,
    );
    let ((), score_peak) = measure(|| imaging.score_progressive(None, frame));
    let dir = tempfile::tempdir()?;
    let (report, write_peak) = measure(|| {
        write_outputs(
            &imaging,
            dir.path(),
            PlyEncoding::BinaryLittleEndian,
            &BTreeMap::new(),
            Figures::Drawn,
        )
    });
    anyhow::ensure!(
        report?.failed_files.is_empty(),
        "an output could not be written"
    );
    Ok(BTreeMap::from([
        ("image_points", image_peak),
        ("score_progressive", score_peak),
        ("write_outputs", write_peak),
    ]))
}

/// One frame of `length_s`: its points and each case's peaks.
fn measure_frame(
    length_s: f64,
    cases: &[(&'static str, ImagingOptions)],
) -> anyhow::Result<(usize, BTreeMap<&'static str, Peaks>)> {
    let samples = simulate_samples(
        lissajous,
        &stud_scene(GeometryModel::ExactReflection),
        20_000.0,
        length_s,
    );
    let (_, first) = cases.first().context("no case to measure")?;
    let scanner = Scanner::new(first.setup, first.model)?;
    let reconstruction = reconstruct(&samples, &scanner);
    drop(samples);
    let points = reconstruction.cloud.points.len();
    let mut peaks = BTreeMap::new();
    for (name, options) in cases {
        peaks.insert(
            *name,
            measure_imaging(reconstruction.clone(), options, length_s)?,
        );
    }
    Ok((points, peaks))
}

fn main() -> anyhow::Result<()> {
    // `cargo bench` passes `--bench`; two numbers are the frames' lengths.
    let lengths_s: Vec<f64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let [short_s, long_s] = lengths_s[..] else {
        return main_with(10.0, 20.0);
    };
    main_with(short_s, long_s)
}

/// Measures frames of `short_s` and `long_s` and prints each step's peak per point of the
/// longer frame and per point the longer frame adds.
fn main_with(short_s: f64, long_s: f64) -> anyhow::Result<()> {
    let cases = [
        (
            "feature_z_map",
            ImagingOptions {
                feature: Some(FeatureParams::default()),
                ..ImagingOptions::default()
            },
        ),
        (
            "plane_subtracted_map",
            ImagingOptions {
                subtract_plane: true,
                ..ImagingOptions::default()
            },
        ),
    ];
    let (short_points, short) = measure_frame(short_s, &cases)?;
    let (long_points, long) = measure_frame(long_s, &cases)?;
    anyhow::ensure!(
        long_points > short_points,
        "the longer frame has no more points"
    );
    let point_bytes = std::mem::size_of::<ScanPoint>() as f64;
    let mut steps = serde_json::Map::new();
    let mut over_budget = Vec::new();
    for (case, long_peaks) in &long {
        for (step, &long_peak) in long_peaks {
            let short_peak = short[case][step];
            let added =
                (long_peak as f64 - short_peak as f64) / (long_points - short_points) as f64;
            if added > BUDGET_BYTES_PER_ADDED_POINT {
                over_budget.push(format!("{case}/{step}: {added:.1} B"));
            }
            steps.insert(
                format!("{case}/{step}"),
                serde_json::json!({
                    "peak_bytes": [short_peak, long_peak],
                    "bytes_per_point": long_peak as f64 / long_points as f64,
                    "bytes_per_added_point": added,
                    "added_point_ratio_to_the_point": added / point_bytes,
                }),
            );
        }
    }
    let results = serde_json::json!({
        "frames_s": [short_s, long_s],
        "points": [short_points, long_points],
        "point_bytes": point_bytes,
        "budget_bytes_per_added_point": BUDGET_BYTES_PER_ADDED_POINT,
        "steps": steps,
    });
    println!("{}", serde_json::to_string_pretty(&results)?);
    anyhow::ensure!(
        over_budget.is_empty(),
        "over the budget of {BUDGET_BYTES_PER_ADDED_POINT} B per point added (a copy of the \
         points?): {}",
        over_budget.join(", ")
    );
    Ok(())
}
