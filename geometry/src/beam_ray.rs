//! The beam after the mirror: what both models ([`crate::small_angle`], [`crate::exact`])
//! compute for one deflection, and what the emulator's optics and the reconstruction use.

use nalgebra::{Point3, Vector3};

/// The beam after the mirror, for one mirror deflection.
///
/// Contract: the point `origin_mm + t * direction` is where a sensor reading of
/// `z_meas = path_to_origin_mm + t` places the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamRay {
    /// Where the laser meets the mirror, mm.
    pub origin_mm: Point3<f64>,
    /// Beam direction after the mirror: a unit vector for the exact model, eq. 3's vector (unit
    /// within 2e-6 over +-1.5 deg) for the small-angle model.
    pub direction: Vector3<f64>,
    /// Laser path from the sensor reference to `origin_mm`, mm.
    pub path_to_origin_mm: f64,
}

impl BeamRay {
    /// The surface point for a sensor distance `z_meas_mm`.
    #[must_use]
    pub fn point_at(&self, z_meas_mm: f64) -> Point3<f64> {
        self.origin_mm + (z_meas_mm - self.path_to_origin_mm) * self.direction
    }

    /// The sensor distance for the point `origin_mm + t_mm * direction`.
    #[must_use]
    pub fn z_meas_at(&self, t_mm: f64) -> f64 {
        self.path_to_origin_mm + t_mm
    }
}
