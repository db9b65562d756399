//! Where a ray meets a surface: the answer every face's intersection gives.

use nalgebra::{Point3, Vector3};

/// Nearest distance along a ray that counts as a hit; smaller ones are the ray's own start
/// point (a reflection path starts on the surface), in mm.
pub const T_MIN_MM: f64 = 1e-6;

/// A ray crossing a face: how far along the ray, where, and the outward unit normal there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the (unit-direction) ray, mm.
    pub t_mm: f64,
    /// The point hit, mm.
    pub point_mm: Point3<f64>,
    /// Outward unit normal of the surface at the point.
    pub normal: Vector3<f64>,
}
