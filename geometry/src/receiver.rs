//! The triangulation receiver's view of the spot, folded by the same mirror as the laser.
//!
//! The receiver is an effective pinhole at `(0, receiver_setback_mm, receiver_baseline_mm)`
//! (behind the reference point, above the laser). Light from the spot reaches it via the
//! mirror: the straight line from the spot to the pinhole's mirror image crosses the mirror
//! plane at the point where the light is folded. The segment from the spot to that point is
//! the reflection path that a surface can block. The mirror's aperture is not checked: the
//! receiving lens is wide and its chief ray may pass the 2 inch mirror's rim at the far end
//! while most of the light does not.

use nalgebra::{Point3, Vector3};

use crate::ScannerSetup;
use crate::exact::MirrorPlane;

/// The reflection path from the spot to the mirror, on its way to the receiver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReceiverPath {
    /// Where the path meets the mirror, mm.
    pub mirror_point_mm: Point3<f64>,
    /// Unit direction from the spot towards the mirror point.
    pub direction: Vector3<f64>,
    /// Distance from the spot to the mirror point, mm.
    pub length_mm: f64,
}

impl ReceiverPath {
    /// The receiver pinhole, in sensor coordinates (mm).
    #[must_use]
    pub fn pinhole(setup: &ScannerSetup) -> Point3<f64> {
        Point3::new(0.0, setup.receiver_setback_mm, setup.receiver_baseline_mm)
    }

    /// The path from `spot_mm` to the receiver for the mirror deflections (rad); `None` when
    /// the spot is on the mirror's back side or on the mirror itself (no path).
    #[must_use]
    pub fn from_spot(
        setup: &ScannerSetup,
        d_alpha_rad: f64,
        d_beta_rad: f64,
        spot_mm: &Point3<f64>,
    ) -> Option<ReceiverPath> {
        let mirror = MirrorPlane::deflected(setup, d_alpha_rad, d_beta_rad);
        if (spot_mm - mirror.pivot_mm).dot(&mirror.normal) <= 0.0 {
            return None;
        }
        let image = mirror.reflect_point(&Self::pinhole(setup));
        let direction = (image - spot_mm).try_normalize(1e-12)?;
        let length_mm = mirror.line_parameter(spot_mm, &direction)?;
        (length_mm > 0.0).then(|| ReceiverPath {
            mirror_point_mm: spot_mm + length_mm * direction,
            direction,
            length_mm,
        })
    }

    /// The reflected-beam angle the paper quotes: elevation of the path above the horizontal
    /// (xy) plane, rad.
    #[must_use]
    pub fn elevation_rad(&self) -> f64 {
        self.direction.z.clamp(-1.0, 1.0).asin()
    }

    /// The triangulation angle at the spot: between the way back along the laser beam
    /// (`-beam_direction`) and this path, rad.
    #[must_use]
    pub fn triangulation_angle_rad(&self, beam_direction: &Vector3<f64>) -> f64 {
        let back = -beam_direction.normalize();
        back.dot(&self.direction).clamp(-1.0, 1.0).acos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exact;

    #[test]
    fn reproduces_the_papers_reflected_beam_angles_at_rest() {
        let s = ScannerSetup::default();
        let ray = exact::beam(&s, 0.0, 0.0);
        for (z_meas, want_deg, tri_deg) in [(70.0, 71.0, 19.0), (170.0, 79.1, 10.9)] {
            let spot = ray.point_at(z_meas);
            let path = ReceiverPath::from_spot(&s, 0.0, 0.0, &spot).unwrap();
            assert!((path.elevation_rad().to_degrees() - want_deg).abs() < 1e-9);
            let tri = path.triangulation_angle_rad(&ray.direction).to_degrees();
            assert!((tri - tri_deg).abs() < 1e-9, "{tri}");
            // The path leans towards +y (towards the sensor side), in the yz plane.
            assert!(path.direction.y > 0.0 && path.direction.x.abs() < 1e-12);
        }
    }

    #[test]
    fn folded_path_reaches_the_pinhole_with_the_law_of_reflection() {
        let s = ScannerSetup::default();
        let (a, b) = (0.02, -0.015);
        let spot = exact::beam(&s, a, b).point_at(120.0);
        let path = ReceiverPath::from_spot(&s, a, b, &spot).unwrap();
        let mirror = MirrorPlane::deflected(&s, a, b);
        let onwards = mirror.reflect_direction(&path.direction);
        let to_pinhole = (ReceiverPath::pinhole(&s) - path.mirror_point_mm).normalize();
        assert!((onwards - to_pinhole).norm() < 1e-12);
    }

    #[test]
    fn no_path_from_behind_the_mirror() {
        let s = ScannerSetup::default();
        assert!(ReceiverPath::from_spot(&s, 0.0, 0.0, &Point3::new(0.0, -50.0, 50.0)).is_none());
    }
}
