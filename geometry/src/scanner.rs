//! [`Scanner`]: one geometry model, chosen by [`GeometryModel`], behind one interface.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use crate::beam_ray::BeamRay;
use crate::receiver::ReceiverPath;
use crate::setup::{ScannerSetup, SetupError};
use crate::{exact, small_angle};

/// Which model turns mirror deflections into the beam.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GeometryModel {
    /// The paper's eq. 1-3 (small-angle), as the paper reconstructs its scans.
    SmallAngle,
    /// Exact vector reflection on the deflected mirror plane: the physical truth.
    #[default]
    ExactReflection,
}

impl GeometryModel {
    /// Both models, for reports that compare them.
    pub const ALL: [GeometryModel; 2] = [GeometryModel::SmallAngle, GeometryModel::ExactReflection];

    /// The model's stable snake_case name, as in JSON and reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            GeometryModel::SmallAngle => "small_angle",
            GeometryModel::ExactReflection => "exact_reflection",
        }
    }
}

impl std::fmt::Display for GeometryModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The scanner geometry with a chosen model: beam rays for the emulator, points for the
/// reconstruction. Cheap to copy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scanner {
    setup: ScannerSetup,
    model: GeometryModel,
}

impl Scanner {
    /// A scanner with a checked setup.
    ///
    /// # Errors
    /// [`SetupError`] naming the first unusable field of `setup`.
    pub fn new(setup: ScannerSetup, model: GeometryModel) -> Result<Scanner, SetupError> {
        setup.validate()?;
        Ok(Scanner { setup, model })
    }

    /// The paper's setup with the given model.
    #[must_use]
    pub fn paper(model: GeometryModel) -> Scanner {
        Scanner {
            setup: ScannerSetup::default(),
            model,
        }
    }

    /// The mechanical setup.
    #[must_use]
    pub fn setup(&self) -> &ScannerSetup {
        &self.setup
    }

    /// The model in use.
    #[must_use]
    pub fn model(&self) -> GeometryModel {
        self.model
    }

    /// The beam for the mirror's mechanical deflections `d_alpha_rad` (about x, spot along y)
    /// and `d_beta_rad` (about the mirror's in-plane axis, spot along x).
    #[must_use]
    pub fn beam(&self, d_alpha_rad: f64, d_beta_rad: f64) -> BeamRay {
        match self.model {
            GeometryModel::SmallAngle => small_angle::beam(&self.setup, d_alpha_rad, d_beta_rad),
            GeometryModel::ExactReflection => exact::beam(&self.setup, d_alpha_rad, d_beta_rad),
        }
    }

    /// Reconstruction: the surface point `(x_s, y_s, z_s)` in mm for the deflections (rad)
    /// and the sensor's distance `z_meas_mm`.
    #[must_use]
    pub fn point(&self, d_alpha_rad: f64, d_beta_rad: f64, z_meas_mm: f64) -> Point3<f64> {
        self.beam(d_alpha_rad, d_beta_rad).point_at(z_meas_mm)
    }

    /// The reflection path from a spot at `spot_mm` back to the receiver via the deflected
    /// mirror (the physical mirror, whatever the model); `None` if there is none.
    #[must_use]
    pub fn receiver_path(
        &self,
        d_alpha_rad: f64,
        d_beta_rad: f64,
        spot_mm: &Point3<f64>,
    ) -> Option<ReceiverPath> {
        ReceiverPath::from_spot(&self.setup, d_alpha_rad, d_beta_rad, spot_mm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FULL_RANGE_RAD: f64 = 1.5 * std::f64::consts::PI / 180.0;

    /// Samples of the +-1.5 deg square of deflections, corners and edges included.
    fn deflection_grid(n: usize) -> impl Iterator<Item = (f64, f64)> {
        let step = 2.0 * FULL_RANGE_RAD / (n - 1) as f64;
        (0..n).flat_map(move |i| {
            (0..n).map(move |j| {
                (
                    -FULL_RANGE_RAD + i as f64 * step,
                    -FULL_RANGE_RAD + j as f64 * step,
                )
            })
        })
    }

    /// Field of view at sensor distance `z_meas` (small-angle model, as the paper computed
    /// it): the x extent that the whole y range covers (the narrowest row, at d_alpha's end
    /// where the beam is shortest) and the y extent along the centre line.
    fn field_of_view(scanner: &Scanner, z_meas: f64) -> (f64, f64) {
        let f = FULL_RANGE_RAD;
        let x_width = [-f, f]
            .iter()
            .map(|&a| scanner.point(a, f, z_meas).x - scanner.point(a, -f, z_meas).x)
            .fold(f64::INFINITY, f64::min);
        let y_height = scanner.point(-f, 0.0, z_meas).y - scanner.point(f, 0.0, z_meas).y;
        (x_width, y_height)
    }

    #[test]
    fn model_names_are_stable() {
        assert_eq!(GeometryModel::SmallAngle.name(), "small_angle");
        assert_eq!(
            GeometryModel::ExactReflection.to_string(),
            "exact_reflection"
        );
        let m: GeometryModel = serde_json::from_str("\"small_angle\"").unwrap();
        assert_eq!(m, GeometryModel::SmallAngle);
        assert_eq!(GeometryModel::default(), GeometryModel::ExactReflection);
    }

    #[test]
    fn fields_of_view_match_the_paper() {
        // Paper: 4.3 x 8 mm near 60 mm, 11.5 x 18.5 mm at the far end (rounded figures).
        for model in GeometryModel::ALL {
            let s = Scanner::paper(model);
            let (near_x, near_y) = field_of_view(&s, 70.0);
            let (far_x, far_y) = field_of_view(&s, 170.0);
            assert!((near_x - 4.3).abs() < 0.05, "{model}: near x {near_x}");
            assert!((near_y - 8.0).abs() < 0.05, "{model}: near y {near_y}");
            assert!((far_x - 11.5).abs() < 0.05, "{model}: far x {far_x}");
            assert!((far_y - 18.5).abs() < 0.05, "{model}: far y {far_y}");
            let near_z = s.point(0.0, 0.0, 70.0).z;
            assert!((near_z + 60.0).abs() < 1e-9, "{model}: {near_z}");
        }
    }

    #[test]
    fn smallest_far_distance_is_158_8_mm() {
        for model in GeometryModel::ALL {
            let s = Scanner::paper(model);
            let closest = deflection_grid(31)
                .map(|(a, b)| -s.point(a, b, 170.0).z)
                .fold(f64::INFINITY, f64::min);
            assert!((closest - 158.8).abs() < 0.05, "{model}: {closest}");
        }
    }

    #[test]
    fn point_and_beam_round_trip() {
        for model in GeometryModel::ALL {
            let s = Scanner::paper(model);
            for (a, b) in deflection_grid(7) {
                for z_meas in [70.0, 123.4, 170.0] {
                    let ray = s.beam(a, b);
                    let p = s.point(a, b, z_meas);
                    // The point lies on the ray, at the ray parameter z_meas - path.
                    let t = (p - ray.origin_mm).dot(&ray.direction) / ray.direction.norm_squared();
                    assert!((ray.z_meas_at(t) - z_meas).abs() < 1e-9, "{model} {a} {b}");
                    assert!((ray.origin_mm + t * ray.direction - p).norm() < 1e-9);
                    assert!((ray.direction.norm() - 1.0).abs() < 2e-6);
                }
            }
        }
    }

    #[test]
    fn models_differ_by_a_few_hundredths_of_a_degree() {
        let small = Scanner::paper(GeometryModel::SmallAngle);
        let exact = Scanner::paper(GeometryModel::ExactReflection);
        let mut worst_angle_deg: f64 = 0.0;
        let mut worst_point_mm: f64 = 0.0;
        for (a, b) in deflection_grid(21) {
            let (ds, de) = (small.beam(a, b).direction, exact.beam(a, b).direction);
            worst_angle_deg = worst_angle_deg.max(ds.angle(&de).to_degrees());
            worst_point_mm =
                worst_point_mm.max((small.point(a, b, 170.0) - exact.point(a, b, 170.0)).norm());
        }
        assert!(
            worst_angle_deg > 0.005 && worst_angle_deg < 0.05,
            "{worst_angle_deg}"
        );
        // Direction difference times the far path plus the hit point shift (0.046 mm).
        assert!(
            worst_point_mm > 0.01 && worst_point_mm < 0.2,
            "{worst_point_mm}"
        );
        // At zero deflection they coincide.
        assert!((small.point(0.0, 0.0, 130.0) - exact.point(0.0, 0.0, 130.0)).norm() < 1e-12);
    }

    #[test]
    fn spot_moves_as_the_conventions_say() {
        let s = Scanner::paper(GeometryModel::ExactReflection);
        let rest = s.point(0.0, 0.0, 130.0);
        assert!(s.point(0.01, 0.0, 130.0).y < rest.y);
        assert!(s.point(0.0, 0.01, 130.0).x > rest.x);
    }

    #[test]
    fn new_rejects_a_bad_setup() {
        let setup = ScannerSetup {
            y_fsm_mm: -1.0,
            ..ScannerSetup::default()
        };
        assert_eq!(
            Scanner::new(setup, GeometryModel::SmallAngle)
                .unwrap_err()
                .field,
            "y_fsm_mm"
        );
    }
}
