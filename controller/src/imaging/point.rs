//! A point in space as the plane fit, the feature measurement and the grid read it: `[x, y,
//! z]` in mm, or a reconstructed [`ScanPoint`] read in place, so a frame's points are
//! measured without a copy of their coordinates.

use super::reconstruct::ScanPoint;

/// A point with x, y and z in mm.
pub trait Point3 {
    /// `[x, y, z]`, mm.
    fn xyz_mm(&self) -> [f64; 3];

    /// Whether x, y and z are all finite.
    fn is_finite(&self) -> bool {
        self.xyz_mm().iter().all(|v| v.is_finite())
    }
}

impl Point3 for [f64; 3] {
    #[inline]
    fn xyz_mm(&self) -> [f64; 3] {
        *self
    }
}

impl Point3 for ScanPoint {
    #[inline]
    fn xyz_mm(&self) -> [f64; 3] {
        [self.x_mm, self.y_mm, self.z_mm]
    }
}
