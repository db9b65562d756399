//! The exact model: the laser, a ray along -y from the sensor reference, reflected by the
//! law of reflection `r = d - 2 (d . n) n` on the deflected mirror plane.
//!
//! # The 3D setup (chosen to coincide with eq. 1-3 at zero deflection)
//! - The mirror rotates about its pivot `P = (0, -y_FSM + z_FSM tan(alpha), z_FSM)`, a point on
//!   its reflecting surface `z_FSM` above the laser line (the laser meets the mirror's lower
//!   part, as the paper's setup section says).
//! - `d_alpha` turns the mirror about the x axis through `P`: its angle against the vertical
//!   becomes `gamma = alpha + d_alpha`, and its normal (facing the sensor)
//!   `n0 = (0, cos gamma, -sin gamma)`.
//! - `d_beta` turns it about its own in-plane axis `(0, sin gamma, cos gamma)` through `P` (the
//!   paper's yz' axis, carried along by `d_alpha`; this is what makes eq. 2b's
//!   `cos(alpha + d_alpha)`): `n = cos(d_beta) n0 + sin(d_beta) (1, 0, 0)`.
//!
//! The laser line lies on the `d_beta` axis's plane, so the hit point is
//! `(0, -(y_FSM + dy), 0)` with `dy = z_FSM [tan(alpha + d_alpha) - tan(alpha)]`, which equals
//! eq. 1 to first order (eq. 1 is its mirror image in `d_alpha`; they differ by 0.046 mm at
//! +-1.5 deg). The reflected direction's angles equal eq. 2a exactly for `d_beta = 0` and
//! eq. 2b to first order.

use nalgebra::{Point3, Vector3};

use crate::ScannerSetup;
use crate::beam_ray::BeamRay;

/// Direction of the laser leaving the sensor (before the mirror): -y.
pub const LASER_DIRECTION: Vector3<f64> = Vector3::new(0.0, -1.0, 0.0);

/// The deflected mirror's plane: a point on it and its unit normal (facing the sensor).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MirrorPlane {
    /// The pivot, a point of the reflecting surface, mm.
    pub pivot_mm: Point3<f64>,
    /// Unit normal, on the side the laser comes from.
    pub normal: Vector3<f64>,
}

impl MirrorPlane {
    /// The mirror plane for the mechanical deflections (rad).
    #[must_use]
    pub fn deflected(setup: &ScannerSetup, d_alpha_rad: f64, d_beta_rad: f64) -> MirrorPlane {
        let alpha = setup.alpha_rad();
        let (sin_g, cos_g) = (alpha + d_alpha_rad).sin_cos();
        let (sin_b, cos_b) = d_beta_rad.sin_cos();
        MirrorPlane {
            pivot_mm: Point3::new(
                0.0,
                -setup.y_fsm_mm + setup.z_fsm_mm * alpha.tan(),
                setup.z_fsm_mm,
            ),
            normal: Vector3::new(sin_b, cos_b * cos_g, -cos_b * sin_g),
        }
    }

    /// Mirror image of a direction (law of reflection).
    #[must_use]
    pub fn reflect_direction(&self, d: &Vector3<f64>) -> Vector3<f64> {
        d - 2.0 * d.dot(&self.normal) * self.normal
    }

    /// Mirror image of a point across the plane.
    #[must_use]
    pub fn reflect_point(&self, p: &Point3<f64>) -> Point3<f64> {
        p - 2.0 * (p - self.pivot_mm).dot(&self.normal) * self.normal
    }

    /// Where the line `from + s * d` meets the plane: `s`, or `None` if parallel.
    #[must_use]
    pub fn line_parameter(&self, from: &Point3<f64>, d: &Vector3<f64>) -> Option<f64> {
        let denom = d.dot(&self.normal);
        (denom.abs() > 1e-12).then(|| (self.pivot_mm - from).dot(&self.normal) / denom)
    }
}

/// The exact beam after the mirror. Its direction is a unit vector.
#[must_use]
pub fn beam(setup: &ScannerSetup, d_alpha_rad: f64, d_beta_rad: f64) -> BeamRay {
    let mirror = MirrorPlane::deflected(setup, d_alpha_rad, d_beta_rad);
    // The laser line (x = 0, z = 0) lies in the plane of the d_beta axis, so the mirror
    // always meets it, at this closed form of `line_parameter` (which is never parallel).
    let alpha = setup.alpha_rad();
    let path = setup.y_fsm_mm + setup.z_fsm_mm * ((alpha + d_alpha_rad).tan() - alpha.tan());
    BeamRay {
        origin_mm: Point3::new(0.0, -path, 0.0),
        direction: mirror.reflect_direction(&LASER_DIRECTION),
        path_to_origin_mm: path,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_hit_point_lies_on_the_mirror() {
        let s = ScannerSetup::default();
        for (a, b) in [(0.0, 0.0), (0.026, -0.02), (-0.026, 0.026)] {
            let ray = beam(&s, a, b);
            let mirror = MirrorPlane::deflected(&s, a, b);
            let along = mirror
                .line_parameter(&Point3::origin(), &LASER_DIRECTION)
                .unwrap();
            assert!((along - ray.path_to_origin_mm).abs() < 1e-12);
            assert!((ray.direction.norm() - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn rest_beam_goes_straight_down() {
        let ray = beam(&ScannerSetup::default(), 0.0, 0.0);
        assert!((ray.direction - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-15);
        assert!((ray.origin_mm - Point3::new(0.0, -10.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn reflecting_a_point_twice_is_identity() {
        let m = MirrorPlane::deflected(&ScannerSetup::default(), 0.01, -0.02);
        let p = Point3::new(1.0, 2.0, 3.0);
        assert!((m.reflect_point(&m.reflect_point(&p)) - p).norm() < 1e-12);
    }
}
