//! RANSAC base plane and feature height on synthetic scenes with known answers, and the
//! feature's selection against its definition.

use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use scanhil_controller::imaging::feature::{
    FeatureError, FeatureParams, FeatureSelection, Region, feature_height,
};
use scanhil_controller::imaging::ransac::{Plane, RansacError, RansacParams, fit_plane};
use scanhil_controller::imaging::reconstruct::ScanPoint;

/// A plane tilted by a few degrees (normal (0.05, -0.03, 1) normalised) through z = -130.
fn tilted_z(x: f64, y: f64) -> f64 {
    -130.0 - 0.05 * x + 0.03 * y
}

#[test]
fn recovers_a_tilted_plane_among_40_percent_outliers() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let noise = Normal::new(0.0, 0.02).unwrap();
    let mut points = Vec::new();
    for i in 0..3000 {
        let (x, y) = (rng.random_range(-6.0..6.0), rng.random_range(-9.0..9.0));
        let z = if i % 5 < 2 {
            tilted_z(x, y) + rng.random_range(-5.0..20.0) // outlier
        } else {
            tilted_z(x, y) + noise.sample(&mut rng)
        };
        points.push([x, y, z]);
    }
    let params = RansacParams::default();
    let fit = fit_plane(&points, &params).unwrap();
    let truth = Plane::through(
        [0.0, 0.0, tilted_z(0.0, 0.0)],
        [1.0, 0.0, tilted_z(1.0, 0.0)],
        [0.0, 1.0, tilted_z(0.0, 1.0)],
    )
    .unwrap();
    let dn: f64 = (0..3)
        .map(|k| (fit.plane.normal[k] - truth.normal[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(
        dn < 1e-3,
        "normal {:?} vs {:?}",
        fit.plane.normal,
        truth.normal
    );
    assert!((fit.plane.z_at_mm(0.0, 0.0).unwrap() + 130.0).abs() < 0.01);
    assert!((fit.plane.tilt_rad() - truth.tilt_rad()).abs() < 1e-3);
    // About 60 % inliers (plus the few outliers that land inside the band).
    assert!(fit.inliers >= 1750 && fit.inliers < 1900, "{}", fit.inliers);
    // Noise 0.02 mm, plus ~30 outliers uniform inside the +-0.3 mm band (rms 0.17 mm).
    assert!(
        fit.inlier_rms_mm > 0.02 && fit.inlier_rms_mm < 0.035,
        "{}",
        fit.inlier_rms_mm
    );
    assert!(fit.iterations >= params.min_iterations && fit.iterations < params.max_iterations);
    // Seeded: the same seed gives the same fit, bit for bit.
    assert_eq!(fit_plane(&points, &params).unwrap(), fit);
}

#[test]
fn keeps_the_candidate_with_the_most_inliers_not_the_first() {
    // Two parallel planes 10 mm apart: 60 % of the points on the lower, 40 % on the upper,
    // interleaved. A draw on the upper plane refines to the upper plane (its band holds none
    // of the lower), so only keeping the best candidate finds the lower plane for every seed
    // (issue 20: keeping the first candidate was caught by no test of this file).
    let points: Vec<[f64; 3]> = (0..1000)
        .map(|i| {
            let (x, y) = ((i % 40) as f64 * 0.25, (i / 40) as f64 * 0.4);
            [x, y, if i % 5 < 3 { -130.0 } else { -120.0 }]
        })
        .collect();
    for seed in 0..20 {
        let params = RansacParams {
            seed,
            ..RansacParams::default()
        };
        let fit = fit_plane(&points, &params).unwrap();
        assert_eq!(fit.inliers, 600, "seed {seed}: {fit:?}");
        let z = fit.plane.z_at_mm(1.0, 1.0).unwrap();
        assert!((z + 130.0).abs() < 1e-9, "seed {seed}: z {z}");
    }
}

#[test]
fn refuses_what_it_cannot_fit() {
    let p = RansacParams::default();
    assert_eq!(
        fit_plane(&[[0.0, 0.0, 0.0], [1.0, 0.0, f64::NAN]], &p),
        Err(RansacError::TooFewPoints { found: 1 })
    );
    let line: Vec<[f64; 3]> = (0..10).map(|i| [i as f64, 2.0 * i as f64, 0.0]).collect();
    assert!(matches!(
        fit_plane(&line, &p),
        Err(RansacError::Degenerate { .. })
    ));
    let bad = RansacParams {
        inlier_threshold_mm: -1.0,
        ..p
    };
    let err = fit_plane(&line, &bad).unwrap_err().to_string();
    assert!(err.contains("inlier_threshold_mm = -1"), "{err}");
}

/// A Duplo-like scene on the tilted plane: a hollow stud (outer radius 4.7 mm, inner 3.4 mm,
/// height 4.663 mm) at the origin, sampled on a 0.1 mm lattice with N(0, sigma) noise.
fn stud_scene(sigma_mm: f64, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, sigma_mm).unwrap();
    let mut points = Vec::new();
    for i in -70..=70 {
        for j in -90..=90 {
            let (x, y) = (i as f64 * 0.1, j as f64 * 0.1);
            let r = x.hypot(y);
            let top = if (3.4..=4.7).contains(&r) { 4.663 } else { 0.0 };
            // The stud's height is along the plane's normal; over a 3 deg tilt the vertical
            // offset differs from it by cos(tilt), which the perpendicular height undoes.
            let n = [0.05, -0.03, 1.0];
            let norm = (n[0] * n[0] + n[1] * n[1] + 1.0f64).sqrt();
            let base = [x, y, tilted_z(x, y)];
            let p = [
                base[0] + top * n[0] / norm,
                base[1] + top * n[1] / norm,
                base[2] + top / norm + noise.sample(&mut rng),
            ];
            points.push(p);
        }
    }
    points
}

#[test]
fn stud_height_above_threshold_matches_the_truth() {
    let points = stud_scene(0.18, 11);
    let m = feature_height(&points, &FeatureParams::default()).unwrap();
    // The mean of n noisy samples: standard error 0.18 / sqrt(n) (noise is vertical, the
    // height perpendicular, a 0.2 % difference).
    let stderr = 0.18 / (m.points as f64).sqrt();
    assert!(m.points > 1000, "{}", m.points);
    assert!((m.height_mm - 4.663).abs() < 5.0 * stderr + 0.005, "{m:?}");
    // The threshold cuts the low tail of the noise only 2.6 mm below the mean: no effect.
    assert!((m.std_mm - 0.18).abs() < 0.02, "{}", m.std_mm);
    assert!((m.median_mm - 4.663).abs() < 0.03);
}

#[test]
fn stud_height_inside_an_explicit_region_matches_the_truth() {
    let points = stud_scene(0.05, 12);
    let params = FeatureParams {
        selection: FeatureSelection::Inside {
            region: Region::Rect {
                x_min_mm: -0.5,
                x_max_mm: 0.5,
                y_min_mm: 3.7,
                y_max_mm: 4.4,
            },
        },
        ..FeatureParams::default()
    };
    let m = feature_height(&points, &params).unwrap();
    assert!((m.height_mm - 4.663).abs() < 0.01, "{m:?}");
    assert!((m.std_mm - 0.05).abs() < 0.02, "{}", m.std_mm);
    // A region with nothing in it.
    let empty = FeatureParams {
        selection: FeatureSelection::Inside {
            region: Region::Disc {
                x_mm: 100.0,
                y_mm: 0.0,
                radius_mm: 1.0,
            },
        },
        ..FeatureParams::default()
    };
    assert_eq!(
        feature_height(&points, &empty),
        Err(FeatureError::TooFewFeaturePoints { points: 0 })
    );
}

/// `[x, y, z]` as a reconstructed point (the other fields made up).
fn scan_point(p: [f64; 3], i: usize) -> ScanPoint {
    ScanPoint {
        x_mm: p[0],
        y_mm: p[1],
        z_mm: p[2],
        t_s: i as f64 * 5e-5,
        d_alpha_rad: 0.0,
        d_beta_rad: 0.0,
        z_meas_mm: 130.0,
    }
}

/// The feature's points by [`FeatureSelection::AboveThreshold`]'s definition, compared pair
/// by pair: above `threshold` over `plane`, farther than `margin` from every point at or
/// below it. Their count and mean height (summed in point order).
fn above_threshold_by_definition(
    points: &[[f64; 3]],
    plane: &Plane,
    threshold: f64,
    margin: f64,
) -> (usize, f64) {
    let finite: Vec<([f64; 3], f64)> = points
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .map(|&p| (p, plane.height_mm(p)))
        .collect();
    let low: Vec<[f64; 3]> = finite
        .iter()
        .filter(|(_, h)| *h <= threshold)
        .map(|&(p, _)| p)
        .collect();
    let selected: Vec<f64> = finite
        .iter()
        .filter(|(p, h)| {
            *h > threshold
                && low
                    .iter()
                    .all(|q| (q[0] - p[0]).hypot(q[1] - p[1]) > margin)
        })
        .map(|&(_, h)| h)
        .collect();
    let mean = selected.iter().sum::<f64>() / selected.len() as f64;
    (selected.len(), mean)
}

#[test]
fn the_top_of_the_stud_is_the_definitions_and_scan_points_measure_as_coordinates_do() {
    let mut points = stud_scene(0.18, 11);
    // A point that is not finite: left out by the plane fit (copying the rest) and the
    // selection alike.
    points.insert(100, [f64::NAN, 0.0, 0.0]);
    let params = FeatureParams::default();
    let m = feature_height(&points, &params).unwrap();
    let FeatureSelection::AboveThreshold {
        min_height_mm,
        edge_margin_mm,
    } = params.selection
    else {
        unreachable!("the default selects above a threshold")
    };
    let (count, mean) =
        above_threshold_by_definition(&points, &m.plane.plane, min_height_mm, edge_margin_mm);
    assert_eq!((m.points, m.height_mm), (count, mean));
    let scan_points: Vec<ScanPoint> = points
        .iter()
        .enumerate()
        .map(|(i, &p)| scan_point(p, i))
        .collect();
    assert_eq!(feature_height(&scan_points, &params).unwrap(), m);
    let finite: Vec<[f64; 3]> = points
        .iter()
        .copied()
        .filter(|p| p[0].is_finite())
        .collect();
    let fit = fit_plane(&finite, &params.ransac).unwrap();
    assert_eq!(fit_plane(&points, &params.ransac).unwrap(), fit);
    assert_eq!(fit_plane(&scan_points, &params.ransac).unwrap(), fit);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Bumps on a flat base, any margin: the bucketed selection keeps exactly the points the
    /// definition keeps (points on bucket borders and at negative coordinates included).
    #[test]
    fn the_selection_above_a_threshold_is_the_definitions(
        bumps in proptest::collection::vec((-3.0..3.0f64, -3.0..3.0f64, 0.0..2.0f64), 1..200),
        margin_steps in 1..40u32,
        seed in any::<u64>(),
    ) {
        let margin = f64::from(margin_steps) * 0.05;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        // A base of 0.05 mm lattice points (on bucket borders for many margins) at z = 0,
        // more of them than bumps, so the base is the dominant plane.
        let mut points: Vec<[f64; 3]> = (0..600)
            .map(|_| [
                f64::from(rng.random_range(-60..60i32)) * 0.05,
                f64::from(rng.random_range(-60..60i32)) * 0.05,
                0.0,
            ])
            .collect();
        points.extend(bumps.iter().map(|&(x, y, z)| [x, y, z]));
        let params = FeatureParams {
            selection: FeatureSelection::AboveThreshold {
                min_height_mm: 1.0,
                edge_margin_mm: margin,
            },
            ..FeatureParams::default()
        };
        let fit = fit_plane(&points, &params.ransac).unwrap();
        let (count, mean) = above_threshold_by_definition(&points, &fit.plane, 1.0, margin);
        match feature_height(&points, &params) {
            Ok(m) => prop_assert_eq!((m.points, m.height_mm), (count, mean)),
            Err(e) => prop_assert_eq!(e, FeatureError::TooFewFeaturePoints { points: count }),
        }
    }
}
