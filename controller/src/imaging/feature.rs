//! The height of a feature above its base plane, as the paper reports for the Duplo stud.
//!
//! Definition (every choice is a parameter of [`FeatureParams`]):
//! 1. **Plane region.** The base plane is fitted by RANSAC ([`super::ransac`]) to the points
//!    inside [`FeatureParams::plane_region`] (default: all points), minus the points inside
//!    the feature region when that region is given explicitly ([`FeatureSelection::Inside`]).
//!    RANSAC keeps the dominant plane, so the base must hold more points than any other flat
//!    part of the region (true for a stud on a brick top).
//! 2. **Heights.** Every point's signed perpendicular distance from that plane, positive
//!    towards the sensor ([`super::ransac::Plane::height_mm`]).
//! 3. **Feature points.** Either the points inside a given region ([`FeatureSelection::Inside`]),
//!    or ([`FeatureSelection::AboveThreshold`]) the points higher than `min_height_mm` that
//!    lie more than `edge_margin_mm` (horizontally) from every point at or below that
//!    threshold: the flat top of the feature, without the shaded and blurred edge samples.
//! 4. **Result.** The mean height of the feature points, their sample standard deviation
//!    (`n - 1`), median and count.

use super::ransac::{PlaneFit, RansacError, RansacParams, fit_plane};

/// An area of the x-y plane.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "shape", rename_all = "snake_case")]
pub enum Region {
    /// Everywhere.
    All,
    /// A disc.
    Disc {
        /// Centre x, mm.
        x_mm: f64,
        /// Centre y, mm.
        y_mm: f64,
        /// Radius, mm.
        radius_mm: f64,
    },
    /// An axis-aligned rectangle.
    Rect {
        /// Lower x, mm.
        x_min_mm: f64,
        /// Upper x, mm.
        x_max_mm: f64,
        /// Lower y, mm.
        y_min_mm: f64,
        /// Upper y, mm.
        y_max_mm: f64,
    },
}

impl Region {
    /// Whether `(x, y)` lies inside (borders included).
    #[must_use]
    pub fn contains(&self, x_mm: f64, y_mm: f64) -> bool {
        match *self {
            Region::All => true,
            Region::Disc {
                x_mm: cx,
                y_mm: cy,
                radius_mm,
            } => (x_mm - cx).hypot(y_mm - cy) <= radius_mm,
            Region::Rect {
                x_min_mm,
                x_max_mm,
                y_min_mm,
                y_max_mm,
            } => (x_min_mm..=x_max_mm).contains(&x_mm) && (y_min_mm..=y_max_mm).contains(&y_mm),
        }
    }
}

/// How the feature's points are chosen once the plane is known.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "select", rename_all = "snake_case")]
pub enum FeatureSelection {
    /// Points above `min_height_mm` and farther than `edge_margin_mm` from any lower point.
    AboveThreshold {
        /// The height above the plane a feature point must exceed, mm.
        min_height_mm: f64,
        /// The horizontal distance a feature point keeps from every lower point, mm.
        edge_margin_mm: f64,
    },
    /// The points inside a region (also left out of the plane fit).
    Inside {
        /// The feature's region.
        region: Region,
    },
}

/// Everything that defines a feature-height measurement.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FeatureParams {
    /// Where the base plane is looked for.
    pub plane_region: Region,
    /// How the feature's points are chosen.
    pub selection: FeatureSelection,
    /// The plane fit's settings.
    pub ransac: RansacParams,
}

impl Default for FeatureParams {
    /// All points for the plane; feature points above 2 mm, 0.3 mm from any lower point
    /// (about two spot diameters); default RANSAC settings.
    fn default() -> Self {
        FeatureParams {
            plane_region: Region::All,
            selection: FeatureSelection::AboveThreshold {
                min_height_mm: 2.0,
                edge_margin_mm: 0.3,
            },
            ransac: RansacParams::default(),
        }
    }
}

/// A feature's height above the base plane.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FeatureHeight {
    /// Mean height of the feature points, mm.
    pub height_mm: f64,
    /// Sample standard deviation of their heights, mm.
    pub std_mm: f64,
    /// Median height, mm.
    pub median_mm: f64,
    /// Number of feature points.
    pub points: usize,
    /// The mean (x, y) of the feature points, mm: the feature's centre (of a ring-shaped
    /// hollow stud too).
    pub centre_mm: [f64; 2],
    /// The base plane.
    pub plane: PlaneFit,
    /// The settings used.
    pub params: FeatureParams,
}

/// Why a feature height could not be measured.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FeatureError {
    /// The base plane could not be fitted.
    #[error("base plane: {0}")]
    Plane(#[from] RansacError),
    /// Fewer than two points were selected as the feature.
    #[error("the feature selection kept {points} points; at least 2 are needed")]
    TooFewFeaturePoints {
        /// Points kept.
        points: usize,
    },
}

/// Measures the feature in `points` (x, y, z in mm).
pub fn feature_height(
    points: &[[f64; 3]],
    params: &FeatureParams,
) -> Result<FeatureHeight, FeatureError> {
    let explicit = match params.selection {
        FeatureSelection::Inside { region } => Some(region),
        FeatureSelection::AboveThreshold { .. } => None,
    };
    // The plane is fitted to every point unless a region says otherwise (then to a copy of
    // those points only): a frame's points are not copied for nothing.
    let plane_points: std::borrow::Cow<'_, [[f64; 3]]> =
        if params.plane_region == Region::All && explicit.is_none() {
            std::borrow::Cow::Borrowed(points)
        } else {
            points
                .iter()
                .copied()
                .filter(|p| params.plane_region.contains(p[0], p[1]))
                .filter(|p| explicit.is_none_or(|r| !r.contains(p[0], p[1])))
                .collect()
        };
    let plane = fit_plane(&plane_points, &params.ransac)?;
    let heights: Vec<([f64; 3], f64)> = points
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .map(|&p| (p, plane.plane.height_mm(p)))
        .collect();
    let feature: Vec<([f64; 3], f64)> = match params.selection {
        FeatureSelection::Inside { region } => heights
            .iter()
            .filter(|(p, _)| region.contains(p[0], p[1]))
            .copied()
            .collect(),
        FeatureSelection::AboveThreshold {
            min_height_mm,
            edge_margin_mm,
        } => top_points(&heights, min_height_mm, edge_margin_mm),
    };
    if feature.len() < 2 {
        return Err(FeatureError::TooFewFeaturePoints {
            points: feature.len(),
        });
    }
    let centre = |k: usize| feature.iter().map(|(p, _)| p[k]).sum::<f64>() / feature.len() as f64;
    let centre_mm = [centre(0), centre(1)];
    let mut selected: Vec<f64> = feature.iter().map(|&(_, h)| h).collect();
    let n = selected.len() as f64;
    let mean = selected.iter().sum::<f64>() / n;
    let var = selected.iter().map(|h| (h - mean).powi(2)).sum::<f64>() / (n - 1.0);
    selected.sort_by(f64::total_cmp);
    let mid = selected.len() / 2;
    let median = if selected.len().is_multiple_of(2) {
        0.5 * (selected[mid - 1] + selected[mid])
    } else {
        selected[mid]
    };
    Ok(FeatureHeight {
        height_mm: mean,
        std_mm: var.sqrt(),
        median_mm: median,
        points: selected.len(),
        centre_mm,
        plane,
        params: *params,
    })
}

/// The points (with heights) above `threshold` that lie farther than `margin` from every
/// lower point, found with a bucket grid of side `margin`.
fn top_points(heights: &[([f64; 3], f64)], threshold: f64, margin: f64) -> Vec<([f64; 3], f64)> {
    let above = heights.iter().filter(|(_, h)| *h > threshold).copied();
    if margin.is_nan() || margin <= 0.0 {
        return above.collect();
    }
    let key = |x: f64, y: f64| ((x / margin).floor() as i64, (y / margin).floor() as i64);
    let mut low: std::collections::HashMap<(i64, i64), Vec<(f64, f64)>> =
        std::collections::HashMap::new();
    for (p, _) in heights.iter().filter(|(_, h)| *h <= threshold) {
        low.entry(key(p[0], p[1])).or_default().push((p[0], p[1]));
    }
    above
        .filter(|(p, _)| {
            let (kx, ky) = key(p[0], p[1]);
            !(-1..=1).any(|dx| {
                (-1..=1).any(|dy| {
                    low.get(&(kx + dx, ky + dy)).is_some_and(|cell| {
                        cell.iter()
                            .any(|&(x, y)| (x - p[0]).hypot(y - p[1]) <= margin)
                    })
                })
            })
        })
        .collect()
}
