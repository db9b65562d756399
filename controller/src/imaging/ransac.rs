//! RANSAC fit of a plane to 3D points (the base plane under a feature), seeded and
//! deterministic, and the height of points above it.
//!
//! 1. Draw three distinct points with a ChaCha8 generator seeded from
//!    [`RansacParams::seed`]; skip degenerate (near-collinear) triples.
//! 2. Count the points within [`RansacParams::inlier_threshold_mm`] (perpendicular distance)
//!    of their plane; keep the best (most inliers; ties keep the earlier draw).
//! 3. Stop after [`RansacParams::max_iterations`] draws, or earlier once the best inlier
//!    fraction `w` makes `1 - (1 - w^3)^k >= confidence` after `k` draws (the standard
//!    adaptive count), but never before [`RansacParams::min_iterations`].
//! 4. Refine: total least squares (the smallest eigenvector of the inliers' covariance), then
//!    recount the inliers against the refined plane and repeat until the inlier set no longer
//!    changes (at most [`REFINE_ROUNDS`] rounds).
//!
//! The plane's normal points to +z (towards the sensor, which looks down at negative z), so
//! [`Plane::height_mm`] is positive above the plane. Heights are perpendicular distances: on
//! a tilted object they are the object's own heights, not vertical differences.

use std::borrow::Cow;

use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::point::Point3;

/// How many least-squares refinement rounds follow the random search at most.
pub const REFINE_ROUNDS: usize = 10;

/// The RANSAC settings.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RansacParams {
    /// A point within this perpendicular distance of the plane is an inlier, in mm.
    pub inlier_threshold_mm: f64,
    /// The most random draws.
    pub max_iterations: usize,
    /// The fewest random draws, even when the adaptive count says fewer suffice.
    pub min_iterations: usize,
    /// The probability of having drawn at least one all-inlier triple before stopping early.
    pub confidence: f64,
    /// The seed of the ChaCha8 generator.
    pub seed: u64,
}

impl Default for RansacParams {
    /// 0.3 mm threshold (above the ILD noise, well below a 4.6 mm stud), 2000 draws at most,
    /// 50 at least, 0.999 confidence, seed 1.
    fn default() -> Self {
        RansacParams {
            inlier_threshold_mm: 0.3,
            max_iterations: 2000,
            min_iterations: 50,
            confidence: 0.999,
            seed: 1,
        }
    }
}

impl RansacParams {
    /// Checks that the settings can run: a positive finite threshold, at least one draw, a
    /// confidence strictly between 0 and 1.
    ///
    /// # Errors
    /// [`RansacError::BadParameter`] naming the setting.
    pub fn check(&self) -> Result<(), RansacError> {
        let bad = |name, value: f64, expected| {
            Err(RansacError::BadParameter {
                name,
                value,
                expected,
            })
        };
        if !(self.inlier_threshold_mm.is_finite() && self.inlier_threshold_mm > 0.0) {
            return bad(
                "inlier_threshold_mm",
                self.inlier_threshold_mm,
                "positive, finite",
            );
        }
        if self.max_iterations == 0 {
            return bad("max_iterations", 0.0, "at least 1");
        }
        if !(self.confidence > 0.0 && self.confidence < 1.0) {
            return bad("confidence", self.confidence, "between 0 and 1, exclusive");
        }
        Ok(())
    }
}

/// A plane `normal . p = offset_mm` with a unit normal pointing to +z.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Plane {
    /// Unit normal, `z >= 0`.
    pub normal: [f64; 3],
    /// Distance term in mm.
    pub offset_mm: f64,
}

impl Plane {
    /// The plane through three points, or `None` if they are (nearly) collinear.
    #[must_use]
    pub fn through(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> Option<Plane> {
        let (a, b, c) = (Vector3::from(a), Vector3::from(b), Vector3::from(c));
        let n = (b - a).cross(&(c - a));
        let scale = (b - a).norm() * (c - a).norm();
        if n.norm().is_nan() || n.norm() <= 1e-9 * scale {
            return None;
        }
        Some(Plane::from_normal(n.normalize(), &a))
    }

    fn from_normal(n: Vector3<f64>, on: &Vector3<f64>) -> Plane {
        let n = if n.z < 0.0 { -n } else { n };
        Plane {
            normal: n.into(),
            offset_mm: n.dot(on),
        }
    }

    /// Signed perpendicular distance of `p` from the plane, positive on the +z side, in mm.
    /// (Inlined across crates: the fit's inner loop, instantiated where its points' type is.)
    #[must_use]
    #[inline]
    pub fn height_mm(&self, p: [f64; 3]) -> f64 {
        Vector3::from(self.normal).dot(&Vector3::from(p)) - self.offset_mm
    }

    /// The plane's z at `(x, y)`, or `None` for a vertical plane.
    #[must_use]
    pub fn z_at_mm(&self, x_mm: f64, y_mm: f64) -> Option<f64> {
        let [nx, ny, nz] = self.normal;
        (nz.abs() > 1e-12).then(|| (self.offset_mm - nx * x_mm - ny * y_mm) / nz)
    }

    /// The angle between the plane and the x-y plane, in rad.
    #[must_use]
    pub fn tilt_rad(&self) -> f64 {
        self.normal[2].clamp(-1.0, 1.0).acos()
    }
}

/// The outcome of a RANSAC plane fit.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PlaneFit {
    /// The refined plane.
    pub plane: Plane,
    /// Points within the threshold of the refined plane.
    pub inliers: usize,
    /// Points offered to the fit.
    pub candidates: usize,
    /// Random draws made.
    pub iterations: usize,
    /// RMS perpendicular distance of the inliers from the plane, in mm.
    pub inlier_rms_mm: f64,
    /// The settings used.
    pub params: RansacParams,
}

/// Why no plane could be fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RansacError {
    /// Fewer than three finite points.
    #[error("a plane needs at least 3 finite points, got {found}")]
    TooFewPoints {
        /// Finite points offered.
        found: usize,
    },
    /// A setting is out of range.
    #[error("RANSAC setting {name} = {value} is out of range ({expected})")]
    BadParameter {
        /// The setting.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
    /// Every triple drawn was collinear.
    #[error("no non-degenerate point triple found in {iterations} draws (points collinear?)")]
    Degenerate {
        /// Draws made.
        iterations: usize,
    },
}

/// Fits the dominant plane of `points` (non-finite points are ignored). The points are read
/// in place when all are finite (the usual case); only otherwise are the finite ones copied.
pub fn fit_plane<P: Point3 + Clone>(
    points: &[P],
    params: &RansacParams,
) -> Result<PlaneFit, RansacError> {
    params.check()?;
    let pts: Cow<'_, [P]> = if points.iter().all(Point3::is_finite) {
        Cow::Borrowed(points)
    } else {
        points.iter().filter(|p| p.is_finite()).cloned().collect()
    };
    if pts.len() < 3 {
        return Err(RansacError::TooFewPoints { found: pts.len() });
    }
    let count = |plane: &Plane| {
        pts.iter()
            .filter(|p| plane.height_mm(p.xyz_mm()).abs() <= params.inlier_threshold_mm)
            .count()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let mut best: Option<(Plane, usize)> = None;
    let mut needed = params.max_iterations;
    let mut iterations = 0;
    while iterations < needed.max(params.min_iterations).min(params.max_iterations) {
        iterations += 1;
        let i = rng.random_range(0..pts.len());
        let j = rng.random_range(0..pts.len());
        let k = rng.random_range(0..pts.len());
        if i == j || j == k || i == k {
            continue;
        }
        let Some(plane) = Plane::through(pts[i].xyz_mm(), pts[j].xyz_mm(), pts[k].xyz_mm()) else {
            continue;
        };
        let n = count(&plane);
        if best.is_none_or(|(_, m)| n > m) {
            best = Some((plane, n));
            let w = n as f64 / pts.len() as f64;
            needed = adaptive_iterations(w, params.confidence).min(params.max_iterations);
        }
    }
    let (mut plane, _) = best.ok_or(RansacError::Degenerate { iterations })?;
    let mut inliers = Inliers::of(&pts, &plane, params.inlier_threshold_mm);
    for _ in 0..REFINE_ROUNDS {
        let Some(refined) = least_squares_plane(&pts, &inliers) else {
            break;
        };
        let next = Inliers::of(&pts, &refined, params.inlier_threshold_mm);
        if next.count < 3 {
            break;
        }
        plane = refined;
        if next == inliers {
            break;
        }
        inliers = next;
    }
    let inlier_rms_mm = (inliers
        .points(&pts)
        .map(|p| plane.height_mm(p).powi(2))
        .sum::<f64>()
        / inliers.count.max(1) as f64)
        .sqrt();
    Ok(PlaneFit {
        plane,
        inliers: inliers.count,
        candidates: pts.len(),
        iterations,
        inlier_rms_mm,
        params: *params,
    })
}

/// The draws needed to see one all-inlier triple with probability `confidence` when a
/// fraction `w` of the points are inliers.
fn adaptive_iterations(w: f64, confidence: f64) -> usize {
    let p_good = w.powi(3);
    if p_good >= 1.0 {
        return 1;
    }
    if p_good <= 0.0 {
        return usize::MAX;
    }
    ((1.0 - confidence).ln() / (1.0 - p_good).ln()).ceil() as usize
}

/// Which points lie within a threshold of a plane: one flag a point (a frame's inliers
/// are most of its points, so flags hold a byte where indices would hold eight).
#[derive(PartialEq)]
struct Inliers {
    /// Whether each point is an inlier.
    is_inlier: Vec<bool>,
    /// How many are.
    count: usize,
}

impl Inliers {
    /// The points of `pts` within `threshold` of `plane`.
    fn of(pts: &[impl Point3], plane: &Plane, threshold: f64) -> Inliers {
        let is_inlier: Vec<bool> = pts
            .iter()
            .map(|p| plane.height_mm(p.xyz_mm()).abs() <= threshold)
            .collect();
        let count = is_inlier.iter().filter(|&&inlier| inlier).count();
        Inliers { is_inlier, count }
    }

    /// The inliers of `pts`, in order.
    fn points<'a>(&'a self, pts: &'a [impl Point3]) -> impl Iterator<Item = [f64; 3]> + 'a {
        pts.iter()
            .zip(&self.is_inlier)
            .filter(|(_, inlier)| **inlier)
            .map(|(p, _)| p.xyz_mm())
    }
}

/// The total-least-squares plane of the `inliers` of `pts`.
fn least_squares_plane(pts: &[impl Point3], inliers: &Inliers) -> Option<Plane> {
    if inliers.count < 3 {
        return None;
    }
    let n = inliers.count as f64;
    let centroid = inliers
        .points(pts)
        .fold(Vector3::zeros(), |acc, p| acc + Vector3::from(p))
        / n;
    let covariance = inliers.points(pts).fold(Matrix3::zeros(), |acc, p| {
        let d = Vector3::from(p) - centroid;
        acc + d * d.transpose()
    });
    let eigen = SymmetricEigen::new(covariance);
    let smallest = eigen.eigenvalues.imin();
    let normal: Vector3<f64> = eigen.eigenvectors.column(smallest).into();
    (normal.norm() > 0.0).then(|| Plane::from_normal(normal.normalize(), &centroid))
}
