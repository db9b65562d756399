//! Progressive imaging: error against scan time, Lissajous and raster side by side.

mod imaging_support;

use imaging_support::{lissajous, raster, stud_scene};
use scanhil_controller::imaging::fill::FillMethod;
use scanhil_controller::imaging::grid::{GridMethod, GridSpec};
use scanhil_controller::imaging::progressive::{
    ProgressiveComparison, ProgressivePoint, ProgressiveRun, ScanScene, progressive_errors,
    progressive_maps, simulate_samples,
};
use scanhil_controller::imaging::reconstruct::{ScanPoint, reconstruct};
use scanhil_geometry::{GeometryModel, Scanner};

const CHECKPOINTS_S: [f64; 6] = [0.05, 0.1, 0.2, 0.4, 0.7, 1.0];

/// The points of a 1 s scan of the stud at `rate_hz` (the scene and reconstruction share the
/// paper's model).
fn stud_points(angles: imaging_support::Angles, rate_hz: f64) -> Vec<ScanPoint> {
    let scene = stud_scene(GeometryModel::SmallAngle);
    let samples = simulate_samples(angles, &scene, rate_hz, 1.0);
    reconstruct(&samples, &Scanner::paper(GeometryModel::SmallAngle))
        .cloud
        .points
}

fn run(
    angles: imaging_support::Angles,
    spec: Option<GridSpec>,
) -> (GridSpec, Vec<ProgressivePoint>) {
    let scene = stud_scene(GeometryModel::SmallAngle);
    let points = stud_points(angles, 10_000.0);
    let spec = spec.unwrap_or_else(|| {
        GridSpec::covering(points.iter().map(|p| (p.x_mm, p.y_mm)), 0.25).unwrap()
    });
    let errors = progressive_errors(
        &points,
        spec,
        GridMethod::default(),
        FillMethod::Nearest,
        &CHECKPOINTS_S,
        |x, y| scene.true_z_mm(x, y),
    );
    (spec, errors)
}

#[test]
fn lissajous_previews_the_whole_field_early_and_both_improve_with_time() {
    let (spec, liss) = run(lissajous, None);
    let (_, rast) = run(raster, Some(spec));
    let image = |p: &ProgressivePoint| p.image_rms_mm.unwrap();
    // More scan time, a better image (never worse between checkpoints, strictly better over
    // the frame).
    for series in [&liss, &rast] {
        for w in series.windows(2) {
            assert!(w[1].coverage_fraction >= w[0].coverage_fraction);
            assert!(image(&w[1]) <= image(&w[0]) * 1.05, "{w:?}");
        }
        assert!(
            image(series.last().unwrap()) < 0.6 * image(&series[0]),
            "{series:?}"
        );
    }
    // After 0.05 s the raster has swept a fifth of the field; the Lissajous preview spans it
    // all, so its whole-image error is lower.
    assert!(
        image(&liss[0]) < image(&rast[0]),
        "{:?} vs {:?}",
        liss[0],
        rast[0]
    );
    // Measured cells are right wherever they are: errors only where a cell straddles the
    // stud's edges, so the median is exact (same model for scene and reconstruction).
    assert!(liss.iter().all(|p| p.covered_rms_mm.unwrap() < 1.0));
    assert!(liss.iter().all(|p| p.covered_median_abs_mm.unwrap() < 1e-9));
}

#[test]
fn maps_grow_with_the_checkpoints_and_the_comparison_plots() {
    let points = stud_points(lissajous, 2_000.0);
    let spec = GridSpec::covering(points.iter().map(|p| (p.x_mm, p.y_mm)), 0.5).unwrap();
    let maps = progressive_maps(&points, spec, GridMethod::CellMean, &[0.0, 0.5, 1.0]);
    let counts: Vec<u32> = maps.iter().map(|(_, m)| m.samples.iter().sum()).collect();
    // t = 0 holds the first sample only; t = 1 every point.
    assert_eq!(counts, [1, 1001, points.len() as u32]);

    let (spec, liss) = run(lissajous, Some(spec));
    let mut comparison = ProgressiveComparison::new(
        GeometryModel::SmallAngle,
        Some(GeometryModel::SmallAngle),
        spec,
        GridMethod::default(),
        FillMethod::Nearest,
    );
    comparison.runs.push(ProgressiveRun {
        name: "lissajous".into(),
        samples: 10_000,
        missing_samples: 0,
        points: liss,
    });
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("progressive.svg");
    comparison.draw(&svg).unwrap();
    assert!(std::fs::read_to_string(&svg).unwrap().contains("lissajous"));
    let json = serde_json::to_string(&comparison).unwrap();
    let back: ProgressiveComparison = serde_json::from_str(&json).unwrap();
    assert_eq!(back.runs[0].points.len(), CHECKPOINTS_S.len());
    // serde_json parses floats to within an ulp or so (no float_roundtrip feature).
    let (a, b) = (&back.runs[0].points[0], &comparison.runs[0].points[0]);
    assert!((a.covered_rms_mm.unwrap() - b.covered_rms_mm.unwrap()).abs() < 1e-12);
    assert_eq!(
        (back.grid.nx, back.fill),
        (comparison.grid.nx, comparison.fill)
    );
}

#[test]
fn points_out_of_time_order_score_as_the_ordered_points_do() {
    // A recording need not be in time order: each checkpoint still holds the points taken
    // up to then.
    let scene = stud_scene(GeometryModel::SmallAngle);
    let points = stud_points(lissajous, 2_000.0);
    let spec = GridSpec::covering(points.iter().map(|p| (p.x_mm, p.y_mm)), 0.25).unwrap();
    let score = |points: &[ScanPoint]| {
        progressive_errors(
            points,
            spec,
            GridMethod::default(),
            FillMethod::Nearest,
            &CHECKPOINTS_S,
            |x, y| scene.true_z_mm(x, y),
        )
    };
    let ordered = score(&points);
    assert!(ordered[0].coverage_fraction > 0.0);
    let mut mixed = points.clone();
    mixed.rotate_left(points.len() / 3);
    assert_eq!(score(&mixed), ordered);
}
