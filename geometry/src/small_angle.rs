//! The paper's eq. 1-3, a small-angle model of the reflection, with the readings recorded in
//! `docs/paper-readings.md`: the `theta` of eq. 3a is the `vartheta` of eq. 2b, the stray
//! `- y_FSM - dy` under eq. 3b is the tail of `y_s`, and `z_s` is negative below the mirror.
//!
//! ```text
//! dy       = z_FSM [tan(alpha) - tan(alpha - d_alpha)]                  (1)
//! phi      = 90 deg - 2 alpha - 2 d_alpha                               (2a)
//! vartheta = 2 d_beta cos(alpha + d_alpha)                              (2b)
//! x_s =  [z_meas - y_FSM - dy] cos(phi) sin(vartheta)                   (3a)
//! y_s =  [z_meas - y_FSM - dy] sin(phi) cos(vartheta) - y_FSM - dy      (3b)
//! z_s = -[z_meas - y_FSM - dy] cos(phi) cos(vartheta)                   (3c)
//! ```

use nalgebra::{Point3, Vector3};

use crate::ScannerSetup;
use crate::beam_ray::BeamRay;

/// The intermediate quantities of eq. 1-2 for one mirror deflection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmallAngleTerms {
    /// Eq. 1: the shift of the mirror hit point along the laser (-y), mm.
    pub dy_mm: f64,
    /// Eq. 2a: beam angle in the yz plane (towards +y from -z), rad.
    pub phi_rad: f64,
    /// Eq. 2b: beam angle in the xz plane (towards +x), rad.
    pub vartheta_rad: f64,
}

/// Evaluates eq. 1-2.
#[must_use]
pub fn terms(setup: &ScannerSetup, d_alpha_rad: f64, d_beta_rad: f64) -> SmallAngleTerms {
    let alpha = setup.alpha_rad();
    SmallAngleTerms {
        dy_mm: setup.z_fsm_mm * (alpha.tan() - (alpha - d_alpha_rad).tan()),
        phi_rad: std::f64::consts::FRAC_PI_2 - 2.0 * alpha - 2.0 * d_alpha_rad,
        vartheta_rad: 2.0 * d_beta_rad * (alpha + d_alpha_rad).cos(),
    }
}

/// The beam of eq. 3: origin on the mirror at `(0, -y_FSM - dy, 0)`, reached after
/// `y_FSM + dy`, direction `(cos phi sin vartheta, sin phi cos vartheta, -cos phi cos vartheta)`.
/// That vector is eq. 3 as printed; its length is `sqrt(1 - sin^2 phi sin^2 vartheta)`, within
/// 2e-6 of one over +-1.5 deg, and it is kept as is so that `origin + (z_meas - path) *
/// direction` is exactly eq. 3.
#[must_use]
pub fn beam(setup: &ScannerSetup, d_alpha_rad: f64, d_beta_rad: f64) -> BeamRay {
    let t = terms(setup, d_alpha_rad, d_beta_rad);
    let path = setup.y_fsm_mm + t.dy_mm;
    let (sin_phi, cos_phi) = t.phi_rad.sin_cos();
    let (sin_theta, cos_theta) = t.vartheta_rad.sin_cos();
    BeamRay {
        origin_mm: Point3::new(0.0, -path, 0.0),
        direction: Vector3::new(
            cos_phi * sin_theta,
            sin_phi * cos_theta,
            -cos_phi * cos_theta,
        ),
        path_to_origin_mm: path,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eq. 3 written out literally, to check that `beam` is eq. 3 and nothing else.
    fn eq3(d_alpha: f64, d_beta: f64, z_meas: f64) -> [f64; 3] {
        let s = ScannerSetup::default();
        let t = terms(&s, d_alpha, d_beta);
        let l = z_meas - s.y_fsm_mm - t.dy_mm;
        [
            l * t.phi_rad.cos() * t.vartheta_rad.sin(),
            l * t.phi_rad.sin() * t.vartheta_rad.cos() - s.y_fsm_mm - t.dy_mm,
            -l * t.phi_rad.cos() * t.vartheta_rad.cos(),
        ]
    }

    #[test]
    fn beam_reproduces_eq3() {
        let s = ScannerSetup::default();
        for (a, b, z) in [
            (0.0, 0.0, 70.0),
            (0.02, -0.01, 130.0),
            (-0.026, 0.026, 170.0),
        ] {
            let p = beam(&s, a, b).point_at(z);
            let want = eq3(a, b, z);
            for i in 0..3 {
                assert!(
                    (p[i] - want[i]).abs() < 1e-12,
                    "{a} {b} {z}: {p} vs {want:?}"
                );
            }
        }
    }

    #[test]
    fn zero_deflection_points_straight_down_from_y_fsm() {
        let s = ScannerSetup::default();
        let t = terms(&s, 0.0, 0.0);
        assert!(t.dy_mm.abs() < 1e-12 && t.phi_rad.abs() < 1e-12 && t.vartheta_rad == 0.0);
        let p = beam(&s, 0.0, 0.0).point_at(130.0);
        assert!((p - Point3::new(0.0, -10.0, -120.0)).norm() < 1e-12);
    }
}
