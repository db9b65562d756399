//! From mirror angles and sensor distances to 3D points (paper eq. 1-3, or the exact
//! reflection), via `scanhil-geometry`'s [`Scanner`]. Every output carries the
//! [`GeometryModel`] it was made with; the paper's model is the default here.

pub use scanhil_geometry::GeometryModel;
use scanhil_geometry::Scanner;

/// One recorded sample: the mechanical mirror angles and the sensor's distance.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ScanSample {
    /// Sample time, s.
    pub t_s: f64,
    /// Mechanical mirror deflection about x (sensing axis alpha), rad.
    pub d_alpha_rad: f64,
    /// Mechanical mirror deflection about yz' (sensing axis beta), rad.
    pub d_beta_rad: f64,
    /// The measured distance z_meas, mm; `None` when the sensor reported an error (shading,
    /// out of range): a missing point, never a distance.
    pub z_meas_mm: Option<f64>,
}

/// A reconstructed surface point with the sample it came from.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ScanPoint {
    /// x_s, mm.
    pub x_mm: f64,
    /// y_s, mm.
    pub y_mm: f64,
    /// z_s, mm (negative: below the mirror).
    pub z_mm: f64,
    /// Sample time, s.
    pub t_s: f64,
    /// Mechanical mirror deflection about x, rad.
    pub d_alpha_rad: f64,
    /// Mechanical mirror deflection about yz', rad.
    pub d_beta_rad: f64,
    /// The measured distance, mm.
    pub z_meas_mm: f64,
}

/// The model the reconstruction uses unless told otherwise: the paper's eq. 1-3.
pub const DEFAULT_MODEL: GeometryModel = GeometryModel::SmallAngle;

/// The model named `name` (as [`GeometryModel::name`] writes it).
#[must_use]
pub fn model_from_name(name: &str) -> Option<GeometryModel> {
    GeometryModel::ALL.into_iter().find(|m| m.name() == name)
}

/// Reconstructed points together with the model that produced them.
#[derive(Debug, Clone, PartialEq)]
pub struct PointCloud {
    /// The geometry model the points were reconstructed with.
    pub model: GeometryModel,
    /// The points, in sample order.
    pub points: Vec<ScanPoint>,
}

/// Reconstructed points, the model that made them, and what was left out.
#[derive(Debug, Clone, PartialEq)]
pub struct Reconstruction {
    /// The points (one per sample with a finite distance), in sample order.
    pub cloud: PointCloud,
    /// Samples without a distance (sensor error: shading, out of range).
    pub missing_samples: usize,
    /// Samples whose time, angles or distance were not finite numbers.
    pub non_finite_samples: usize,
}

/// Turns samples into surface points with `scanner`'s geometry and model. Samples without
/// a distance become no point (they are counted, never guessed).
#[must_use]
pub fn reconstruct(samples: &[ScanSample], scanner: &Scanner) -> Reconstruction {
    reconstruct_each(samples.iter().copied(), scanner)
}

/// [`reconstruct`] of samples as they come (a frame paired as it is read): room for the
/// iterator's upper bound of points is reserved up front, so the cloud is never reallocated
/// while it grows (untouched room costs no memory).
#[must_use]
pub fn reconstruct_each(
    samples: impl IntoIterator<Item = ScanSample>,
    scanner: &Scanner,
) -> Reconstruction {
    let samples = samples.into_iter();
    let (lower, upper) = samples.size_hint();
    let mut points = Vec::with_capacity(upper.unwrap_or(lower));
    let (mut missing_samples, mut non_finite_samples) = (0, 0);
    for s in samples {
        let Some(z_meas_mm) = s.z_meas_mm else {
            missing_samples += 1;
            continue;
        };
        if ![s.t_s, s.d_alpha_rad, s.d_beta_rad, z_meas_mm]
            .iter()
            .all(|v| v.is_finite())
        {
            non_finite_samples += 1;
            continue;
        }
        let p = scanner.point(s.d_alpha_rad, s.d_beta_rad, z_meas_mm);
        points.push(ScanPoint {
            x_mm: p.x,
            y_mm: p.y,
            z_mm: p.z,
            t_s: s.t_s,
            d_alpha_rad: s.d_alpha_rad,
            d_beta_rad: s.d_beta_rad,
            z_meas_mm,
        });
    }
    Reconstruction {
        cloud: PointCloud {
            model: scanner.model(),
            points,
        },
        missing_samples,
        non_finite_samples,
    }
}
