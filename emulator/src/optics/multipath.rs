//! Multiple reflections: a second bounce of the laser light, and the distance bias it causes.
//!
//! The paper's Fig. 10 caption blames the edge artefacts of the Duplo stud on multiple
//! reflections. This module models the simplest case, one extra bounce, as an option of the
//! optics (`optics.multiple_reflections`; absent: off, and the optics do not call this module).
//!
//! # Model
//! For a spot sample `P` that the receiver sees (the primary shading rules passed):
//! 1. **Split**: a share `s` (`specular_share`) of the light reaching `P` is reflected
//!    specularly, `r = d - 2 (d.n) n` for the beam direction `d` and `P`'s normal `n`; the rest,
//!    `1 - s`, scatters diffusely (Lambertian).
//! 2. **Secondary spot**: the specular ray from `P` meets the surface again at `Q` (the first hit
//!    along `r`; nothing hit: no secondary). `Q` receives all of the specular light and scatters
//!    its own diffuse share `1 - s` of it.
//! 3. **Visibility**: `Q` must have a path to the receiver through the mirror and face it
//!    (`cos > 0`); with shading on, nothing may block the path from `Q` to the mirror (the same
//!    rule as the primary's `reflection_path_blocked`).
//! 4. **Weights**: a Lambertian spot sends the receiver a power proportional to its diffuse
//!    power times the cosine between its normal and the path to the receiver:
//!    `w_P = (1 - s) cos(view_P)`, `w_Q = s (1 - s) cos(view_Q)`.
//! 5. **Apparent distance**: the receiver pinhole images both spots onto the ILD's line
//!    detector. In the unfolded frame (the pinhole mirrored by the deflected mirror, `I'`) the
//!    detector position is the triangulation angle `psi` of a point, measured at `I'` within the
//!    triangulation plane (the plane through `I'` and the laser ray; the out-of-plane offset falls
//!    across the detector line and is ignored). The ILD reports the distance of the
//!    intensity-weighted centroid `psi_c = (w_P psi_P + w_Q psi_Q) / (w_P + w_Q)`, converted as
//!    the sensor does: the point of the laser ray seen at `psi_c`.
//!
//! # Assumptions (not measured)
//! - Default `s` = 0.1: ABS plastic is glossy; Fresnel alone gives 4 % at normal incidence for
//!   a refractive index of 1.5, and the gloss lobe of a moulded brick adds to it.
//! - The specular lobe is a single mirror ray (no gloss width); only one extra bounce; the
//!   specular ray's direct glint into the receiver is ignored (the receiver sits 11-19 deg off
//!   the beam, away from the specular direction of the faces that are lit).
//! - The ILD evaluates one peak over both images (they overlap on the detector, as for a
//!   secondary spot a few mm away); it does not separate two peaks.
//! - A primary spot that is shaded stays shaded: light that reaches the floor after a bounce
//!   off a wall lit at grazing incidence gives no peak here.

use nalgebra::{Point3, Vector3};
use scanhil_geometry::exact::MirrorPlane;
use scanhil_geometry::{ReceiverPath, Scanner};
use scanhil_scene::surface::{Hit, Surface};
use serde::{Deserialize, Serialize};

/// Longest stretch searched for the secondary spot, mm (the whole scene).
const BOUNCE_SEARCH_LENGTH_MM: f64 = 1.0e4;

fn default_specular_share() -> f64 {
    0.1
}

/// The optics' `multiple_reflections` section: a second bounce of the laser light.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MultipathConfig {
    /// Share of the light at a spot reflected specularly, the rest scattering diffusely, in
    /// [0, 1) (default 0.1, an assumption for glossy ABS).
    #[serde(default = "default_specular_share")]
    pub specular_share: f64,
}

impl Default for MultipathConfig {
    fn default() -> Self {
        MultipathConfig {
            specular_share: default_specular_share(),
        }
    }
}

/// The second bounce, checked and ready.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SecondBounce {
    specular_share: f64,
}

/// What the bounce needs of the optics for one mirror position.
pub(crate) struct View<'a> {
    /// The surface the light bounces on.
    pub surface: &'a Surface,
    /// The scanner (setup for the mirror and the receiver).
    pub scanner: &'a Scanner,
    /// Mirror deflection about x, rad.
    pub d_alpha_rad: f64,
    /// Mirror deflection about the in-plane axis, rad.
    pub d_beta_rad: f64,
    /// Whether blocked paths are evaluated.
    pub shading: bool,
}

/// The secondary spot and the two weights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Secondary {
    /// Where the specular ray lands, mm.
    pub point_mm: Point3<f64>,
    /// Receiver power from the primary spot, relative to the beam's.
    pub primary_weight: f64,
    /// Receiver power from the secondary spot, relative to the beam's.
    pub secondary_weight: f64,
}

impl SecondBounce {
    /// The bounce for `config`; `Err(value)` when the share is outside [0, 1).
    pub(crate) fn new(config: &MultipathConfig) -> Result<SecondBounce, f64> {
        let s = config.specular_share;
        if s.is_finite() && (0.0..1.0).contains(&s) {
            Ok(SecondBounce { specular_share: s })
        } else {
            Err(s)
        }
    }

    /// The secondary spot for the primary `hit` of the ray along the unit `direction`, when
    /// the receiver sees one with a weight above zero.
    pub(crate) fn secondary(
        &self,
        view: &View<'_>,
        direction: &Vector3<f64>,
        hit: &Hit,
    ) -> Option<Secondary> {
        let s = self.specular_share;
        let towards_surface = direction.dot(&hit.normal);
        if s == 0.0 || towards_surface >= 0.0 {
            return None;
        }
        let cos_view = |point: &Point3<f64>, normal: &Vector3<f64>| {
            view.scanner
                .receiver_path(view.d_alpha_rad, view.d_beta_rad, point)
                .map(|path| (path, path.direction.dot(normal)))
        };
        let (_, cos_primary) = cos_view(&hit.point_mm, &hit.normal)?;
        let specular = direction - 2.0 * towards_surface * hit.normal;
        let second = view
            .surface
            .first_hit(&hit.point_mm, &specular, BOUNCE_SEARCH_LENGTH_MM)?;
        let (path, cos_secondary) = cos_view(&second.point_mm, &second.normal)?;
        if cos_secondary <= 0.0 {
            return None;
        }
        if view.shading
            && view
                .surface
                .first_hit(&second.point_mm, &path.direction, path.length_mm)
                .is_some()
        {
            return None;
        }
        Some(Secondary {
            point_mm: second.point_mm,
            primary_weight: (1.0 - s) * cos_primary.max(0.0),
            secondary_weight: s * (1.0 - s) * cos_secondary,
        })
    }

    /// The distance along the ray `origin_mm + t direction` (unit direction) that the ILD
    /// reports for the primary `hit` and its secondary spot: the ray point seen at the
    /// intensity-weighted triangulation angle. `None` when no secondary spot is seen (the
    /// caller keeps the primary's own distance, bit for bit).
    pub(crate) fn apparent_t_mm(
        &self,
        view: &View<'_>,
        origin_mm: &Point3<f64>,
        direction: &Vector3<f64>,
        hit: &Hit,
    ) -> Option<f64> {
        let secondary = self.secondary(view, direction, hit)?;
        let plane = TriangulationPlane::new(view, origin_mm, direction)?;
        let total = secondary.primary_weight + secondary.secondary_weight;
        let psi = (secondary.primary_weight * plane.angle_rad(&hit.point_mm)
            + secondary.secondary_weight * plane.angle_rad(&secondary.point_mm))
            / total;
        plane.ray_parameter_mm(psi).filter(|t| t.is_finite())
    }
}

/// The receiver's triangulation plane in the unfolded frame: through the pinhole's mirror
/// image `I'` and the laser ray; 2-D coordinates with `I'` at the origin and the ray's origin on
/// the first axis.
struct TriangulationPlane {
    pinhole_image_mm: Point3<f64>,
    e1: Vector3<f64>,
    e2: Vector3<f64>,
    /// Distance from `I'` to the ray's origin, mm.
    origin_distance_mm: f64,
    /// The ray's unit direction in plane coordinates.
    direction_2d: [f64; 2],
}

impl TriangulationPlane {
    fn new(
        view: &View<'_>,
        origin_mm: &Point3<f64>,
        direction: &Vector3<f64>,
    ) -> Option<TriangulationPlane> {
        let setup = view.scanner.setup();
        let mirror = MirrorPlane::deflected(setup, view.d_alpha_rad, view.d_beta_rad);
        let pinhole_image_mm = mirror.reflect_point(&ReceiverPath::pinhole(setup));
        let to_origin = origin_mm - pinhole_image_mm;
        let origin_distance_mm = to_origin.norm();
        let e1 = to_origin.try_normalize(1e-12)?;
        let normal = direction.cross(&e1).try_normalize(1e-12)?;
        let e2 = normal.cross(&e1);
        Some(TriangulationPlane {
            pinhole_image_mm,
            e1,
            e2,
            origin_distance_mm,
            direction_2d: [direction.dot(&e1), direction.dot(&e2)],
        })
    }

    /// The angle at `I'` between the ray's origin and `point` projected into the plane, rad.
    fn angle_rad(&self, point: &Point3<f64>) -> f64 {
        let v = point - self.pinhole_image_mm;
        v.dot(&self.e2).atan2(v.dot(&self.e1))
    }

    /// The parameter `t` (mm along the unit direction) of the ray point seen at `psi_rad`.
    fn ray_parameter_mm(&self, psi_rad: f64) -> Option<f64> {
        let (sin, cos) = psi_rad.sin_cos();
        let [ux, uy] = self.direction_2d;
        let denom = cos * uy - sin * ux;
        (denom.abs() > 1e-15).then(|| sin * self.origin_distance_mm / denom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanhil_geometry::{GeometryModel, ScannerSetup};
    use std::path::Path;

    fn scanner() -> Scanner {
        Scanner::new(ScannerSetup::default(), GeometryModel::ExactReflection).unwrap()
    }

    fn surface(json: &str) -> Surface {
        Surface::from_config(&serde_json::from_str(json).unwrap(), Path::new(".")).unwrap()
    }

    #[test]
    fn a_point_on_the_ray_maps_back_to_its_own_distance() {
        let scanner = scanner();
        let plane_surface = surface(r#"{"kind": "plane", "distance_mm": 130.0}"#);
        for (a, b) in [(0.0, 0.0), (0.02, -0.01), (-0.025, 0.026)] {
            let view = View {
                surface: &plane_surface,
                scanner: &scanner,
                d_alpha_rad: a,
                d_beta_rad: b,
                shading: true,
            };
            let beam = scanner.beam(a, b);
            let plane = TriangulationPlane::new(&view, &beam.origin_mm, &beam.direction).unwrap();
            for t in [60.0, 125.0, 160.0] {
                let psi = plane.angle_rad(&(beam.origin_mm + t * beam.direction));
                let back = plane.ray_parameter_mm(psi).unwrap();
                assert!((back - t).abs() < 1e-9, "{a} {b}: {t} -> {back}");
            }
            // Farther points are seen further from the baseline (the line to the ray's origin),
            // so a secondary spot above the primary pulls the distance shorter.
            let near = plane.angle_rad(&(beam.origin_mm + 100.0 * beam.direction));
            let far = plane.angle_rad(&(beam.origin_mm + 150.0 * beam.direction));
            assert!(far.abs() > near.abs(), "{near} {far}");
        }
    }

    #[test]
    fn a_level_plane_has_no_secondary_spot() {
        let scanner = scanner();
        let plane_surface = surface(r#"{"kind": "plane", "distance_mm": 130.0}"#);
        let bounce = SecondBounce::new(&MultipathConfig::default()).unwrap();
        let view = View {
            surface: &plane_surface,
            scanner: &scanner,
            d_alpha_rad: 0.01,
            d_beta_rad: 0.01,
            shading: true,
        };
        let beam = scanner.beam(0.01, 0.01);
        let hit = plane_surface
            .first_hit(&beam.origin_mm, &beam.direction, 1e4)
            .unwrap();
        assert_eq!(bounce.secondary(&view, &beam.direction, &hit), None);
    }

    #[test]
    fn shares_outside_zero_to_one_are_refused() {
        for bad in [-0.1, 1.0, f64::NAN] {
            assert!(
                SecondBounce::new(&MultipathConfig {
                    specular_share: bad
                })
                .is_err()
            );
        }
        assert!(SecondBounce::new(&MultipathConfig::default()).is_ok());
        let c: MultipathConfig = serde_json::from_str("{}").unwrap();
        assert_eq!(c.specular_share, 0.1);
    }
}
