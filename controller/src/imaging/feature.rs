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

use std::collections::{HashMap, HashSet};

use super::point::Point3;
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
    /// Checks that the region is a real area: finite bounds, a rectangle's minimum at or
    /// below its maximum, a disc's radius positive.
    ///
    /// # Errors
    /// What is wrong, naming the bound.
    pub fn check(&self) -> Result<(), String> {
        let finite = |name: &str, value: f64| {
            if value.is_finite() {
                Ok(())
            } else {
                Err(format!("{name} {value} is not finite"))
            }
        };
        match *self {
            Region::All => Ok(()),
            Region::Disc {
                x_mm,
                y_mm,
                radius_mm,
            } => {
                finite("x_mm", x_mm)?;
                finite("y_mm", y_mm)?;
                if radius_mm.is_finite() && radius_mm > 0.0 {
                    Ok(())
                } else {
                    Err(format!("radius_mm {radius_mm} must be positive and finite"))
                }
            }
            Region::Rect {
                x_min_mm,
                x_max_mm,
                y_min_mm,
                y_max_mm,
            } => {
                for (name, value) in [
                    ("x_min_mm", x_min_mm),
                    ("x_max_mm", x_max_mm),
                    ("y_min_mm", y_min_mm),
                    ("y_max_mm", y_max_mm),
                ] {
                    finite(name, value)?;
                }
                if x_min_mm > x_max_mm {
                    Err(format!("x_min_mm {x_min_mm} is above x_max_mm {x_max_mm}"))
                } else if y_min_mm > y_max_mm {
                    Err(format!("y_min_mm {y_min_mm} is above y_max_mm {y_max_mm}"))
                } else {
                    Ok(())
                }
            }
        }
    }

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

impl FeatureParams {
    /// Checks every setting before any point is measured: both regions real areas, the
    /// threshold finite, the edge margin finite and not negative, the RANSAC settings usable.
    ///
    /// # Errors
    /// The setting (`plane_region`, `selection.region`, `selection.min_height_mm`,
    /// `selection.edge_margin_mm`, `ransac`) and what is wrong with it.
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        self.plane_region
            .check()
            .map_err(|reason| ("plane_region", reason))?;
        match self.selection {
            FeatureSelection::Inside { region } => region
                .check()
                .map_err(|reason| ("selection.region", reason))?,
            FeatureSelection::AboveThreshold {
                min_height_mm,
                edge_margin_mm,
            } => {
                if !min_height_mm.is_finite() {
                    return Err((
                        "selection.min_height_mm",
                        format!("{min_height_mm} mm is not finite"),
                    ));
                }
                if !(edge_margin_mm.is_finite() && edge_margin_mm >= 0.0) {
                    return Err((
                        "selection.edge_margin_mm",
                        format!("{edge_margin_mm} mm must be finite and not negative"),
                    ));
                }
            }
        }
        self.ransac
            .check()
            .map_err(|error| ("ransac", error.to_string()))
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

/// Measures the feature in `points` (x, y, z in mm), read in place: heights above the
/// plane are computed as they are needed, and only the feature's heights are kept.
pub fn feature_height<P: Point3 + Clone>(
    points: &[P],
    params: &FeatureParams,
) -> Result<FeatureHeight, FeatureError> {
    let explicit = match params.selection {
        FeatureSelection::Inside { region } => Some(region),
        FeatureSelection::AboveThreshold { .. } => None,
    };
    // The plane is fitted to every point unless a region says otherwise (then to a copy of
    // those points' coordinates only): a frame's points are not copied for nothing.
    let plane = if params.plane_region == Region::All && explicit.is_none() {
        fit_plane(points, &params.ransac)?
    } else {
        let plane_points: Vec<[f64; 3]> = points
            .iter()
            .map(Point3::xyz_mm)
            .filter(|p| params.plane_region.contains(p[0], p[1]))
            .filter(|p| explicit.is_none_or(|r| !r.contains(p[0], p[1])))
            .collect();
        fit_plane(&plane_points, &params.ransac)?
    };
    let heights = points.iter().filter(|p| p.is_finite()).map(|p| {
        let p = p.xyz_mm();
        (p, plane.plane.height_mm(p))
    });
    let feature = match params.selection {
        FeatureSelection::Inside { region } => {
            FeaturePoints::of(heights.filter(|(p, _)| region.contains(p[0], p[1])))
        }
        FeatureSelection::AboveThreshold {
            min_height_mm,
            edge_margin_mm,
        } => top_points(heights, min_height_mm, edge_margin_mm),
    };
    let mut selected = feature.heights_mm;
    if selected.len() < 2 {
        return Err(FeatureError::TooFewFeaturePoints {
            points: selected.len(),
        });
    }
    let n = selected.len() as f64;
    let centre_mm = [feature.x_sum_mm / n, feature.y_sum_mm / n];
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

/// The selected feature points, kept as their heights and the sums of their x and y (for
/// the centre), in point order.
struct FeaturePoints {
    heights_mm: Vec<f64>,
    x_sum_mm: f64,
    y_sum_mm: f64,
}

impl FeaturePoints {
    /// The points `(point, height)` given, in order.
    fn of(points: impl IntoIterator<Item = ([f64; 3], f64)>) -> FeaturePoints {
        // The sums start at -0.0, as `Iterator::sum` of f64 does (exactly its result).
        let mut feature = FeaturePoints {
            heights_mm: Vec::new(),
            x_sum_mm: -0.0,
            y_sum_mm: -0.0,
        };
        for (p, h) in points {
            feature.heights_mm.push(h);
            feature.x_sum_mm += p[0];
            feature.y_sum_mm += p[1];
        }
        feature
    }
}

/// The points (with heights) above `threshold` that lie farther than `margin` from every
/// lower point, found with a bucket grid of side `margin`. `heights` is walked three times:
/// for the buckets of the points above, for the lower points in and next to those buckets
/// (the only ones that can be within `margin` of a point above), and for the selection.
fn top_points<I>(heights: I, threshold: f64, margin: f64) -> FeaturePoints
where
    I: Iterator<Item = ([f64; 3], f64)> + Clone,
{
    let above = heights.clone().filter(|(_, h)| *h > threshold);
    if margin.is_nan() || margin <= 0.0 {
        return FeaturePoints::of(above);
    }
    let key = |x: f64, y: f64| ((x / margin).floor() as i64, (y / margin).floor() as i64);
    let neighbours = |(kx, ky): (i64, i64)| {
        (-1..=1).flat_map(move |dx| (-1..=1).map(move |dy| (kx + dx, ky + dy)))
    };
    let near_above: HashSet<(i64, i64)> = above
        .clone()
        .map(|(p, _)| key(p[0], p[1]))
        .collect::<HashSet<_>>()
        .into_iter()
        .flat_map(neighbours)
        .collect();
    let mut low: HashMap<(i64, i64), Vec<(f64, f64)>> = HashMap::new();
    for (p, _) in heights.filter(|(_, h)| *h <= threshold) {
        let bucket = key(p[0], p[1]);
        if near_above.contains(&bucket) {
            low.entry(bucket).or_default().push((p[0], p[1]));
        }
    }
    FeaturePoints::of(above.filter(|(p, _)| {
        !neighbours(key(p[0], p[1])).any(|bucket| {
            low.get(&bucket).is_some_and(|cell| {
                cell.iter()
                    .any(|&(x, y)| (x - p[0]).hypot(y - p[1]) <= margin)
            })
        })
    }))
}
