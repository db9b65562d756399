//! The optical path: from the mirror's mechanical angles to the laser spot on the surface,
//! the sensor distance `z_meas` along the folded beam, and shading.
//!
//! Shading rules (as on the real sensor, the result is "no distance", never a wrong one):
//! - **illumination**: the beam's first hit is the spot. Where an edge is steeper than the
//!   beam, the beam cannot reach the surface behind it and lands on the edge's wall at a
//!   grazing angle; a spot whose surface normal is more than `max_incidence_deg` from the
//!   incoming beam scatters too little and too widely: [`ShadeReason::GrazingIllumination`];
//! - **reflection**: the light goes from the spot to the receiver via the mirror
//!   ([`scanhil_geometry::ReceiverPath`]); the spot must face the receiver within
//!   `max_viewing_deg` ([`ShadeReason::ReceiverFacesAway`]) and nothing may cross the path
//!   between the spot and the mirror ([`ShadeReason::ReflectionPathBlocked`]).
//!
//! With `spot` set, the 130 um spot is sampled at several points of its footprint (parallel
//! rays across the beam); the distance is the mean over the samples that are not shaded, and
//! the spot is shaded only when all samples are.
//!
//! With `multiple_reflections` set, each seen sample also sends a specular share of its light
//! to a second spot on the surface; when the receiver sees that one too, the sample's distance
//! is the one the ILD reads from the intensity-weighted centroid of the two images
//! ([`multipath`] has the model and its assumptions). Absent (the default), the optics are
//! exactly those without it.
//!
//! With a [`ReceiverModel`] (the scene's parts `receiver_intensity` and `speckle`,
//! [`receiver`]), each seen sample also carries its intensity at the receiver, the spot's
//! distance is the intensity-weighted mean of its samples, and the spot's centroid moves with
//! the surface's speckle. Without one every seen sample counts alike, with intensity 1.

pub mod multipath;
pub mod receiver;

use nalgebra::{Point3, Vector3};
use scanhil_geometry::{BeamRay, GeometryModel, ReceiverPath, Scanner, ScannerSetup, SetupError};
use scanhil_protocol::plant_units::SensingPair;
use serde::{Deserialize, Serialize};

use scanhil_scene::surface::Surface;

use multipath::{MultipathConfig, SecondBounce, View};
use receiver::{Speckle, SurfaceFinish};

/// Longest beam stretch searched for a surface, mm (far beyond the sensor's range).
const BEAM_SEARCH_LENGTH_MM: f64 = 1.0e4;

fn default_max_angle_deg() -> f64 {
    80.0
}
fn yes() -> bool {
    true
}
/// The paper's laser spot diameter, mm (the spot's default, and the speckle's correlation
/// length without a `spot` section).
pub const DEFAULT_SPOT_DIAMETER_MM: f64 = 0.13;

fn default_spot_diameter_mm() -> f64 {
    DEFAULT_SPOT_DIAMETER_MM
}
fn default_spot_samples() -> usize {
    7
}

/// Spot averaging: the footprint sampled by parallel rays.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpotConfig {
    /// Spot diameter, mm (the paper's 130 um by default).
    #[serde(default = "default_spot_diameter_mm")]
    pub diameter_mm: f64,
    /// Rays across the footprint (1 to 64), in a sunflower pattern.
    #[serde(default = "default_spot_samples")]
    pub samples: usize,
}

/// The optics of a scene (the scene's `optics` section).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpticsConfig {
    /// Geometry model: `exact_reflection` (default) or `small_angle`.
    #[serde(default)]
    pub model: GeometryModel,
    /// Mechanical setup (paper values by default).
    #[serde(default)]
    pub setup: ScannerSetup,
    /// Whether shading is evaluated (the plant overrides this from the scene's parts).
    #[serde(default = "yes")]
    pub shading: bool,
    /// Largest angle between the surface normal and the way back along the beam that still
    /// gives a peak, degrees.
    #[serde(default = "default_max_angle_deg")]
    pub max_incidence_deg: f64,
    /// Largest angle between the surface normal and the path to the receiver that still gives
    /// a peak, degrees.
    #[serde(default = "default_max_angle_deg")]
    pub max_viewing_deg: f64,
    /// Spot averaging; absent or null: a point spot.
    #[serde(default)]
    pub spot: Option<SpotConfig>,
    /// A second bounce of the laser light ([`multipath`]); absent or null: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub multiple_reflections: Option<MultipathConfig>,
}

impl Default for OpticsConfig {
    fn default() -> Self {
        OpticsConfig {
            model: GeometryModel::default(),
            setup: ScannerSetup::default(),
            shading: true,
            max_incidence_deg: default_max_angle_deg(),
            max_viewing_deg: default_max_angle_deg(),
            spot: None,
            multiple_reflections: None,
        }
    }
}

/// Why the optics could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OpticsError {
    /// The mechanical setup is unusable.
    #[error("optics.setup: {0}")]
    Setup(#[from] SetupError),
    /// A field is out of its domain.
    #[error("optics field `{field}` = {value} must be {requirement}")]
    Invalid {
        /// The field's JSON name.
        field: &'static str,
        /// The value found.
        value: f64,
        /// What it must be.
        requirement: &'static str,
    },
}

/// Why the sensor gets no peak from a spot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShadeReason {
    /// The beam meets the surface too obliquely (an edge steeper than the beam).
    GrazingIllumination,
    /// The spot does not face the receiver closely enough.
    ReceiverFacesAway,
    /// The surface blocks the path from the spot to the mirror.
    ReflectionPathBlocked,
    /// No path from the spot to the receiver through the mirror.
    NoReceiverPath,
}

impl ShadeReason {
    /// Stable snake_case name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            ShadeReason::GrazingIllumination => "grazing_illumination",
            ShadeReason::ReceiverFacesAway => "receiver_faces_away",
            ShadeReason::ReflectionPathBlocked => "reflection_path_blocked",
            ShadeReason::NoReceiverPath => "no_receiver_path",
        }
    }
}

/// What the optics deliver to the sensor for one mirror position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OpticalOutcome {
    /// The true distance along the folded beam (no sensor noise), mm.
    Distance {
        /// Sensor reference to the spot along the beam, mm.
        z_meas_mm: f64,
        /// The light reaching the receiver, relative to a white matte surface facing it at
        /// mid-range ([`receiver::intensity`]); 1 when the intensity is not modelled.
        intensity: f64,
    },
    /// The beam meets no surface (or leaves no usable mirror path).
    Miss,
    /// The spot is shaded: no peak.
    Shaded(ShadeReason),
}

/// The optics' answer for one mirror position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpticalReading {
    /// The beam after the mirror.
    pub beam: BeamRay,
    /// Where the beam's centre meets the surface, mm (`None` on a miss).
    pub spot_mm: Option<Point3<f64>>,
    /// Ground truth: the surface's z at the spot's (x, y), mm.
    pub true_height_mm: Option<f64>,
    /// The distance or why there is none.
    pub outcome: OpticalOutcome,
}

/// The optical path onto a surface.
#[derive(Debug, Clone)]
pub struct Optics {
    scanner: Scanner,
    surface: Surface,
    shading: bool,
    cos_max_incidence: f64,
    cos_max_viewing: f64,
    /// Offsets across the beam, as fractions of the spot radius along two unit axes.
    spot_pattern: Vec<[f64; 2]>,
    spot_radius_mm: f64,
    /// The second bounce, when the scene asks for it.
    multipath: Option<SecondBounce>,
    /// The receiver's intensity and speckle, when the scene lists them.
    receiver: ReceiverModel,
}

/// What the receiver adds to the optics: the parts `receiver_intensity` and `speckle`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ReceiverModel {
    /// The surface's finish, to weigh each seen sample by its intensity (`None`: all alike).
    pub intensity: Option<SurfaceFinish>,
    /// The surface's speckle (`None`: none).
    pub speckle: Option<Speckle>,
}

impl Optics {
    /// Optics with a checked configuration over `surface`.
    ///
    /// # Errors
    /// [`OpticsError`] naming the bad field.
    pub fn new(config: &OpticsConfig, surface: Surface) -> Result<Optics, OpticsError> {
        let scanner = Scanner::new(config.setup, config.model)?;
        let angle = |field: &'static str, value: f64| {
            if value.is_finite() && value > 0.0 && value <= 90.0 {
                Ok(value.to_radians().cos())
            } else {
                Err(OpticsError::Invalid {
                    field,
                    value,
                    requirement: "in (0, 90] degrees",
                })
            }
        };
        let cos_max_incidence = angle("max_incidence_deg", config.max_incidence_deg)?;
        let cos_max_viewing = angle("max_viewing_deg", config.max_viewing_deg)?;
        let (spot_pattern, spot_radius_mm) = match config.spot {
            None => (vec![[0.0, 0.0]], 0.0),
            Some(spot) => {
                if !(spot.diameter_mm.is_finite() && spot.diameter_mm > 0.0) {
                    return Err(OpticsError::Invalid {
                        field: "spot.diameter_mm",
                        value: spot.diameter_mm,
                        requirement: "finite and > 0",
                    });
                }
                if !(1..=64).contains(&spot.samples) {
                    return Err(OpticsError::Invalid {
                        field: "spot.samples",
                        value: spot.samples as f64,
                        requirement: "between 1 and 64",
                    });
                }
                (sunflower(spot.samples), spot.diameter_mm / 2.0)
            }
        };
        let multipath = config
            .multiple_reflections
            .as_ref()
            .map(SecondBounce::new)
            .transpose()
            .map_err(|value| OpticsError::Invalid {
                field: "multiple_reflections.specular_share",
                value,
                requirement: "in [0, 1)",
            })?;
        Ok(Optics {
            scanner,
            surface,
            shading: config.shading,
            cos_max_incidence,
            cos_max_viewing,
            spot_pattern,
            spot_radius_mm,
            multipath,
            receiver: ReceiverModel::default(),
        })
    }

    /// The same optics with the receiver's intensity and speckle (the plant's parts
    /// `receiver_intensity` and `speckle`).
    #[must_use]
    pub fn with_receiver(mut self, receiver: ReceiverModel) -> Optics {
        self.receiver = receiver;
        self
    }

    /// The same optics with shading switched on or off (the plant's `shading` part).
    #[must_use]
    pub fn with_shading(mut self, on: bool) -> Optics {
        self.shading = on;
        self
    }

    /// Whether shading is evaluated.
    #[must_use]
    pub fn shading(&self) -> bool {
        self.shading
    }

    /// The surface (ground truth for scoring).
    #[must_use]
    pub fn surface(&self) -> &Surface {
        &self.surface
    }

    /// The scanner geometry and model.
    #[must_use]
    pub fn scanner(&self) -> &Scanner {
        &self.scanner
    }

    /// Whether the second bounce (`multiple_reflections`) is modelled.
    #[must_use]
    pub fn multiple_reflections(&self) -> bool {
        self.multipath.is_some()
    }

    /// Where the spot lands and what distance the optics deliver, for the mirror's mechanical
    /// angles (rad). Never panics; non-finite angles give [`OpticalOutcome::Miss`].
    #[must_use]
    pub fn observe(&self, mechanical_angles_rad: SensingPair) -> OpticalReading {
        let SensingPair { alpha, beta } = mechanical_angles_rad;
        let beam = self.scanner.beam(alpha, beta);
        let miss = OpticalReading {
            beam,
            spot_mm: None,
            true_height_mm: None,
            outcome: OpticalOutcome::Miss,
        };
        let length = beam.direction.norm();
        let usable = beam.path_to_origin_mm.is_finite()
            && beam.path_to_origin_mm > 0.0
            && beam.origin_mm.coords.iter().all(|v| v.is_finite())
            && length.is_finite()
            && length > 0.5;
        if !usable {
            return miss;
        }
        let unit = beam.direction / length;
        let Some(center) = self
            .surface
            .first_hit(&beam.origin_mm, &unit, BEAM_SEARCH_LENGTH_MM)
        else {
            return miss;
        };
        let true_height_mm = self.surface.height_at(center.point_mm.x, center.point_mm.y);
        // Spot samples: the centre only, or parallel rays across the footprint.
        let (across_1, across_2) = perpendicular_axes(&unit);
        // Intensity-weighted and plain sums of the seen samples' distances.
        let (mut weighted_mm, mut sum_intensity, mut plain_mm) = (0.0, 0.0, 0.0);
        let mut count = 0usize;
        let mut first_shade = None;
        let mut centre_path = None;
        for &[a, b] in &self.spot_pattern {
            let offset = if a == 0.0 && b == 0.0 {
                None
            } else {
                Some(self.spot_radius_mm * (a * across_1 + b * across_2))
            };
            let hit = match offset {
                None => Some(center),
                Some(offset) => {
                    self.surface
                        .first_hit(&(beam.origin_mm + offset), &unit, BEAM_SEARCH_LENGTH_MM)
                }
            };
            let Some(hit) = hit else { continue };
            match self.shade(alpha, beta, &unit, &hit) {
                Ok(path) => {
                    let t_mm = match &self.multipath {
                        None => hit.t_mm,
                        Some(bounce) => {
                            let view = View {
                                surface: &self.surface,
                                scanner: &self.scanner,
                                d_alpha_rad: alpha,
                                d_beta_rad: beta,
                                shading: self.shading,
                            };
                            let origin = beam.origin_mm + offset.unwrap_or_else(Vector3::zeros);
                            bounce
                                .apparent_t_mm(&view, &origin, &unit, &hit)
                                .unwrap_or(hit.t_mm)
                        }
                    };
                    let z_mm = beam.z_meas_at(t_mm / length);
                    // The path to the receiver, found once: shading's, or traced here when the
                    // intensity needs it (or the speckle, for the centre).
                    let needs_path = self.receiver.intensity.is_some()
                        || (offset.is_none() && self.receiver.speckle.is_some());
                    let path = path.or_else(|| {
                        needs_path
                            .then(|| self.scanner.receiver_path(alpha, beta, &hit.point_mm))
                            .flatten()
                    });
                    if offset.is_none() {
                        centre_path = path;
                    }
                    let intensity = match &self.receiver.intensity {
                        None => 1.0,
                        Some(finish) => path.map_or(0.0, |path| {
                            receiver::intensity(finish, &hit.normal, &-unit, &path.direction, z_mm)
                        }),
                    };
                    weighted_mm += intensity * z_mm;
                    sum_intensity += intensity;
                    plain_mm += z_mm;
                    count += 1;
                }
                Err(reason) => {
                    first_shade.get_or_insert(reason);
                }
            }
        }
        // The centre is always a sample and was hit, so with none seen one was shaded.
        let outcome = match (count, first_shade) {
            (0, reason) => reason.map_or(OpticalOutcome::Miss, OpticalOutcome::Shaded),
            _ => {
                // Samples that send no light still place the spot when none sends any (the
                // receiver then calls it too dark).
                let z_mm = if sum_intensity > 0.0 {
                    weighted_mm / sum_intensity
                } else {
                    plain_mm / count as f64
                };
                OpticalOutcome::Distance {
                    z_meas_mm: z_mm
                        + self.speckle_mm(alpha, beta, &unit, &center, centre_path, z_mm),
                    intensity: sum_intensity / self.spot_pattern.len() as f64,
                }
            }
        };
        OpticalReading {
            beam,
            spot_mm: Some(center.point_mm),
            true_height_mm,
            outcome,
        }
    }

    /// Why a hit gives no peak, or, when it does, the path to the receiver if the rules
    /// looked at it (never with shading off).
    fn shade(
        &self,
        d_alpha: f64,
        d_beta: f64,
        unit_beam: &Vector3<f64>,
        hit: &scanhil_scene::surface::Hit,
    ) -> Result<Option<ReceiverPath>, ShadeReason> {
        if !self.shading {
            return Ok(None);
        }
        if -unit_beam.dot(&hit.normal) < self.cos_max_incidence {
            return Err(ShadeReason::GrazingIllumination);
        }
        let Some(path) = self.scanner.receiver_path(d_alpha, d_beta, &hit.point_mm) else {
            return Err(ShadeReason::NoReceiverPath);
        };
        if path.direction.dot(&hit.normal) < self.cos_max_viewing {
            return Err(ShadeReason::ReceiverFacesAway);
        }
        match self
            .surface
            .first_hit(&hit.point_mm, &path.direction, path.length_mm)
        {
            Some(_) => Err(ShadeReason::ReflectionPathBlocked),
            None => Ok(Some(path)),
        }
    }

    /// The speckle's centroid error for the spot centred on `center`, seen at `z_mm`, mm (0
    /// without speckle, or without a path to the receiver). `centre_path` is the centre's
    /// path if the samples found it (traced here when the centre was shaded).
    fn speckle_mm(
        &self,
        d_alpha: f64,
        d_beta: f64,
        unit_beam: &Vector3<f64>,
        center: &scanhil_scene::surface::Hit,
        centre_path: Option<ReceiverPath>,
        z_mm: f64,
    ) -> f64 {
        let Some(speckle) = &self.receiver.speckle else {
            return 0.0;
        };
        let Some(path) = centre_path.or_else(|| {
            self.scanner
                .receiver_path(d_alpha, d_beta, &center.point_mm)
        }) else {
            return 0.0;
        };
        let sin_triangulation = unit_beam.cross(&path.direction).norm();
        let cos_incidence = (-unit_beam.dot(&center.normal)).clamp(0.0, 1.0);
        speckle.error_mm(&center.point_mm, z_mm, sin_triangulation, cos_incidence)
    }
}

/// Two unit vectors perpendicular to `d` and to each other.
fn perpendicular_axes(d: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if d.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let a = d.cross(&helper).normalize();
    (a, d.cross(&a))
}

/// `n` points spread evenly over the unit disk (Vogel's sunflower), the first at the centre.
fn sunflower(n: usize) -> Vec<[f64; 2]> {
    let golden_angle = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|k| {
            if k == 0 {
                return [0.0, 0.0];
            }
            let r = (k as f64 / (n - 1) as f64).sqrt();
            let (s, c) = (k as f64 * golden_angle).sin_cos();
            [r * c, r * s]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use scanhil_scene::surface::{SurfaceConfig, duplo};
    use std::path::Path;

    fn optics(surface_json: &str, config: OpticsConfig) -> Optics {
        let surface: SurfaceConfig = serde_json::from_str(surface_json).unwrap();
        Optics::new(
            &config,
            Surface::from_config(&surface, Path::new(".")).unwrap(),
        )
        .unwrap()
    }

    fn angles(alpha_deg: f64, beta_deg: f64) -> SensingPair {
        SensingPair {
            alpha: alpha_deg.to_radians(),
            beta: beta_deg.to_radians(),
        }
    }

    fn z_meas(reading: &OpticalReading) -> f64 {
        match reading.outcome {
            OpticalOutcome::Distance { z_meas_mm, .. } => z_meas_mm,
            other => panic!("expected a distance, got {other:?}"),
        }
    }

    #[test]
    fn plane_distance_round_trips_through_reconstruction() {
        for model in GeometryModel::ALL {
            let o = optics(
                r#"{"kind": "plane", "distance_mm": 130.0}"#,
                OpticsConfig {
                    model,
                    ..OpticsConfig::default()
                },
            );
            for (a, b) in [(0.0, 0.0), (1.5, 1.5), (-1.2, 0.7)] {
                let r = o.observe(angles(a, b));
                let p = o
                    .scanner()
                    .point(a.to_radians(), b.to_radians(), z_meas(&r));
                assert!((p.z + 130.0).abs() < 1e-9, "{model} {a} {b}: {p}");
                assert!((p - r.spot_mm.unwrap()).norm() < 1e-9);
                assert_eq!(r.true_height_mm, Some(-130.0));
            }
            // At rest the beam goes straight down from y_FSM: z_meas = 10 + 130.
            assert!((z_meas(&o.observe(angles(0.0, 0.0))) - 140.0).abs() < 1e-9);
        }
    }

    #[test]
    fn nothing_below_is_a_miss() {
        let o = optics(
            r#"{"kind": "sphere", "radius_mm": 1.0, "center_distance_mm": 130.0}"#,
            OpticsConfig::default(),
        );
        assert_eq!(o.observe(angles(1.5, 0.0)).outcome, OpticalOutcome::Miss);
        assert!(matches!(
            o.observe(angles(0.0, 0.0)).outcome,
            OpticalOutcome::Distance { .. }
        ));
    }

    /// A step up towards -y (high where y < edge) seen by a beam tilting to -y: where the beam
    /// would reach the low floor right behind the edge, it meets the vertical wall instead.
    #[test]
    fn step_edge_shades_the_illumination_and_never_gives_a_wrong_distance() {
        // Low level at 130 mm for y >= edge, high level 4 mm up for y < edge: height_mm is
        // relative to the y < edge side, so describe it from there.
        let step = r#"{"kind": "step", "distance_mm": 126.0, "height_mm": -4.0, "axis": "y", "edge_mm": -13.0}"#;
        let o = optics(step, OpticsConfig::default());
        let surface = o.surface().clone();
        let mut shaded = 0;
        for k in 0..=300 {
            let a = -1.5 + 3.0 * f64::from(k) / 300.0;
            let r = o.observe(angles(a, 0.0));
            match r.outcome {
                OpticalOutcome::Distance { z_meas_mm, .. } => {
                    // Any distance reported is the true one: reconstruction lands on the surface.
                    let p = o.scanner().point(a.to_radians(), 0.0, z_meas_mm);
                    let truth = surface.height_at(p.x, p.y).unwrap();
                    assert!((p.z - truth).abs() < 1e-6, "alpha {a}: {} vs {truth}", p.z);
                }
                OpticalOutcome::Shaded(_) => shaded += 1,
                OpticalOutcome::Miss => panic!("miss at {a}"),
            }
        }
        assert!(shaded > 0, "the wall must shade some positions");
        // The spots that land on the wall itself (the beam cannot reach the floor right behind
        // the edge) are shaded as grazing illumination; the fine sweep must find some.
        let on_wall: Vec<_> = (0..=3000)
            .map(|k| o.observe(angles(-1.5 + 3.0 * f64::from(k) / 3000.0, 0.0)))
            .filter(|r| {
                r.spot_mm
                    .is_some_and(|p| (p.y + 13.0).abs() < 1e-9 && p.z < -126.0 - 1e-9)
            })
            .collect();
        assert!(!on_wall.is_empty(), "no spot on the wall");
        for r in on_wall {
            assert_eq!(
                r.outcome,
                OpticalOutcome::Shaded(ShadeReason::GrazingIllumination)
            );
        }
    }

    #[test]
    fn wall_facing_away_from_the_receiver_blocks_the_reflection_path() {
        // High level for y >= edge, 8 mm up: the wall faces -y, while the receiver looks from +y.
        // Spots on the low floor just before the edge send their light into the wall.
        let step = r#"{"kind": "step", "distance_mm": 130.0, "height_mm": 8.0, "axis": "y", "edge_mm": -9.0}"#;
        let o = optics(step, OpticsConfig::default());
        let reasons: Vec<_> = (0..=300)
            .map(|k| o.observe(angles(-1.5 + 3.0 * f64::from(k) / 300.0, 0.0)))
            .filter_map(|r| match r.outcome {
                OpticalOutcome::Shaded(reason) => Some(reason),
                _ => None,
            })
            .collect();
        assert!(
            reasons.contains(&ShadeReason::ReflectionPathBlocked),
            "{reasons:?}"
        );
        // Without shading the same positions all give distances.
        let unshaded = o.clone().with_shading(false);
        assert!((0..=300).all(|k| matches!(
            unshaded.observe(angles(-1.5 + 3.0 * f64::from(k) / 300.0, 0.0)).outcome,
            OpticalOutcome::Distance { .. }
        )));
    }

    #[test]
    fn duplo_stud_height_from_distances() {
        let o = optics(r#"{"kind": "duplo_2x4"}"#, OpticsConfig::default());
        // Find a mirror angle whose spot is on the stud's ring and one on the top face.
        let z_at = |alpha_deg: f64, beta_deg: f64| {
            let r = o.observe(angles(alpha_deg, beta_deg));
            o.scanner()
                .point(alpha_deg.to_radians(), beta_deg.to_radians(), z_meas(&r))
                .z
        };
        // beta 1.3 deg puts the spot 4.0 mm from the stud's axis (x = 0): mid-ring
        // (3.25 to 4.7 mm); alpha -1.4 deg puts it at y = -2.85 mm, on the top face beyond it.
        let top = z_at(-1.4, 0.0);
        let ring = z_at(0.0, 1.3);
        assert!(
            ((ring - top) - duplo::STUD_HEIGHT_MM).abs() < 1e-9,
            "{ring} - {top} = {}",
            ring - top
        );
    }

    #[test]
    fn spot_averaging_smooths_a_step_edge() {
        let step = r#"{"kind": "step", "distance_mm": 130.0, "height_mm": 0.05, "axis": "x", "edge_mm": 0.0}"#;
        let config = OpticsConfig {
            spot: Some(SpotConfig {
                diameter_mm: 0.13,
                samples: 19,
            }),
            shading: false,
            ..OpticsConfig::default()
        };
        let o = optics(step, config);
        let at_edge = z_meas(&o.observe(angles(0.0, 0.0)));
        // Half the footprint on each level: between the two distances.
        assert!(at_edge < 140.0 && at_edge > 140.0 - 0.05, "{at_edge}");
        // Fully on the upper level, the footprint's mean is the centre's distance (within
        // 0.1 um: the sunflower pattern is not exactly centred).
        let point = optics(
            step,
            OpticsConfig {
                shading: false,
                ..OpticsConfig::default()
            },
        );
        let away = z_meas(&o.observe(angles(0.0, 0.2)));
        let away_point = z_meas(&point.observe(angles(0.0, 0.2)));
        assert!((away - away_point).abs() < 1e-4, "{away} vs {away_point}");
    }

    #[test]
    fn with_receiver_intensity_a_spot_carries_its_light_and_weighs_its_samples_by_it() {
        let plane = r#"{"kind": "plane", "distance_mm": 130.0}"#;
        let finish = SurfaceFinish {
            reflectance: 0.5,
            ..SurfaceFinish::default()
        };
        let model = ReceiverModel {
            intensity: Some(finish),
            speckle: None,
        };
        let point = optics(plane, OpticsConfig::default()).with_receiver(model);
        for (a, b) in [(0.0, 0.0), (1.2, -0.8)] {
            let r = point.observe(angles(a, b));
            let OpticalOutcome::Distance {
                z_meas_mm,
                intensity,
            } = r.outcome
            else {
                panic!("{r:?}")
            };
            let path = point
                .scanner()
                .receiver_path(a.to_radians(), b.to_radians(), &r.spot_mm.unwrap())
                .unwrap();
            // Matte: reflectance cos(view) (L_ref / L)^2, the plane's normal straight up.
            let expected = 0.5 * path.direction.z * (120.0 / z_meas_mm).powi(2);
            assert!(
                (intensity - expected).abs() < 1e-12,
                "{intensity} {expected}"
            );
            // The distance is the one without the receiver model (one sample).
            let plain = optics(plane, OpticsConfig::default()).observe(angles(a, b));
            assert_eq!(z_meas(&plain), z_meas_mm);
            // A 7-ray spot's intensity is its rays' mean: on the plane, nearly the centre's.
            let seven = OpticsConfig {
                spot: Some(SpotConfig {
                    diameter_mm: DEFAULT_SPOT_DIAMETER_MM,
                    samples: 7,
                }),
                ..OpticsConfig::default()
            };
            let spot = optics(plane, seven.clone()).with_receiver(model);
            let OpticalOutcome::Distance { intensity, .. } = spot.observe(angles(a, b)).outcome
            else {
                panic!("a distance")
            };
            assert!(
                (intensity / expected - 1.0).abs() < 0.01,
                "{intensity} {expected}"
            );
            // A black finish sends no light: the spot is still placed (by its plain mean), with
            // intensity 0, for the receiver to call too dark.
            let black = optics(plane, seven.clone()).with_receiver(ReceiverModel {
                intensity: Some(SurfaceFinish {
                    reflectance: 0.0,
                    ..finish
                }),
                speckle: None,
            });
            let dark = black.observe(angles(a, b)).outcome;
            let lit = optics(plane, seven).observe(angles(a, b));
            assert_eq!(
                dark,
                OpticalOutcome::Distance {
                    z_meas_mm: z_meas(&lit),
                    intensity: 0.0
                }
            );
        }
        // Nothing on the beam stays a miss with the receiver model.
        let sphere = r#"{"kind": "sphere", "radius_mm": 1.0, "center_distance_mm": 130.0, "center_x_mm": 50.0}"#;
        let empty = optics(sphere, OpticsConfig::default()).with_receiver(model);
        assert_eq!(
            empty.observe(angles(0.0, 0.0)).outcome,
            OpticalOutcome::Miss
        );
        // A spot across a step's two levels (its wall samples grazing, so shaded): its
        // distance leans to the brighter, nearer level, against the plain mean of its samples.
        let step = r#"{"kind": "step", "distance_mm": 126.0, "height_mm": -4.0, "axis": "y", "edge_mm": -13.0}"#;
        let spot = OpticsConfig {
            spot: Some(SpotConfig {
                diameter_mm: 2.0,
                samples: 16,
            }),
            ..OpticsConfig::default()
        };
        let plain = optics(step, spot.clone());
        let weighted = optics(step, spot).with_receiver(model);
        // Across the edge the spot's mean is between the levels, 1 to 3 mm from its centre's.
        let centre = optics(step, OpticsConfig::default());
        let edge_alpha = (0..=400)
            .map(|k| -1.5 + 3.0 * f64::from(k) / 400.0)
            .find(|&a| {
                let spread = (z_meas(&plain.observe(angles(a, 0.0)))
                    - z_meas(&centre.observe(angles(a, 0.0))))
                .abs();
                (1.0..3.0).contains(&spread)
            })
            .expect("an alpha with the spot across the edge");
        let (z_plain, z_weighted) = (
            z_meas(&plain.observe(angles(edge_alpha, 0.0))),
            z_meas(&weighted.observe(angles(edge_alpha, 0.0))),
        );
        assert!(z_weighted < z_plain, "{z_weighted} {z_plain}");
        assert!(z_plain - z_weighted < 1.0, "{z_weighted} {z_plain}");
    }

    #[test]
    fn with_speckle_a_spot_moves_by_the_surface_s_fixed_pattern_at_its_rms() {
        let plane = r#"{"kind": "plane", "distance_mm": 130.0}"#;
        let finish = SurfaceFinish {
            roughness_um: 2.0,
            ..SurfaceFinish::default()
        };
        let speckle = Speckle::new(
            &finish,
            &receiver::ReceiverOptics {
                wavelength_nm: 670.0,
                aperture_mm: 12.0,
            },
            0.13,
            5,
        );
        let plain = optics(plane, OpticsConfig::default());
        let speckled = plain.clone().with_receiver(ReceiverModel {
            intensity: None,
            speckle: Some(speckle),
        });
        let (mut sum_sq, mut n) = (0.0, 0.0);
        for i in 0..40 {
            for j in 0..40 {
                let (a, b) = (-1.0 + 0.05 * f64::from(i), -1.0 + 0.05 * f64::from(j));
                let r = speckled.observe(angles(a, b));
                let error = z_meas(&r) - z_meas(&plain.observe(angles(a, b)));
                assert_eq!(z_meas(&speckled.observe(angles(a, b))), z_meas(&r));
                let path = plain
                    .scanner()
                    .receiver_path(a.to_radians(), b.to_radians(), &r.spot_mm.unwrap())
                    .unwrap();
                let sin_theta = r.beam.direction.normalize().cross(&path.direction).norm();
                let cos_inc = -r.beam.direction.normalize().z;
                let rms = speckle.rms_mm(z_meas(&r), sin_theta, cos_inc);
                // The error is the field's at the spot, added to the distance.
                let expected = speckle.error_mm(
                    &r.spot_mm.unwrap(),
                    z_meas(&plain.observe(angles(a, b))),
                    sin_theta,
                    cos_inc,
                );
                assert!((error - expected).abs() < 1e-9, "{error} {expected}");
                sum_sq += (error / rms).powi(2);
                n += 1.0;
            }
        }
        // 1600 spots 0.05 deg apart (several spot diameters on the plane): unit rms.
        let rms = (sum_sq / n).sqrt();
        assert!((rms - 1.0).abs() < 0.1, "{rms}");
    }

    #[test]
    fn config_defaults_and_errors() {
        let c: OpticsConfig = serde_json::from_str("{}").unwrap();
        assert_eq!(c, OpticsConfig::default());
        let c: OpticsConfig =
            serde_json::from_str(r#"{"model": "small_angle", "spot": {}}"#).unwrap();
        assert_eq!(c.model, GeometryModel::SmallAngle);
        assert_eq!(
            c.spot,
            Some(SpotConfig {
                diameter_mm: 0.13,
                samples: 7
            })
        );
        let surface = Surface::from_config(
            &serde_json::from_str(r#"{"kind": "plane", "distance_mm": 100.0}"#).unwrap(),
            Path::new("."),
        )
        .unwrap();
        let bad = OpticsConfig {
            max_viewing_deg: 0.0,
            ..OpticsConfig::default()
        };
        let err = Optics::new(&bad, surface).unwrap_err().to_string();
        assert!(err.contains("max_viewing_deg"), "{err}");
    }

    /// One surface of each kind, the height map from the dimple fixture.
    const SURFACES: [&str; 6] = [
        r#"{"kind": "plane", "distance_mm": 130.0}"#,
        r#"{"kind": "tilted_plane", "distance_mm": 130.0, "slope_x_deg": 20.0, "slope_y_deg": -10.0}"#,
        r#"{"kind": "step", "distance_mm": 130.0, "height_mm": 3.0, "axis": "y"}"#,
        r#"{"kind": "sphere", "radius_mm": 8.0, "center_distance_mm": 135.0}"#,
        r#"{"kind": "height_map", "file": "../fixtures/surfaces/dimple.csv", "distance_mm": 130.0, "pixel_mm": 0.1}"#,
        r#"{"kind": "duplo_2x4"}"#,
    ];

    proptest! {
        #[test]
        fn observe_never_panics_and_stays_finite(
            alpha in -1e6f64..1e6,
            beta in -1e6f64..1e6,
            small in any::<bool>(),
            surface in 0..SURFACES.len(),
        ) {
            let model = if small { GeometryModel::SmallAngle } else { GeometryModel::ExactReflection };
            let spot = Some(SpotConfig { diameter_mm: 0.13, samples: 3 });
            let surface_config: SurfaceConfig = serde_json::from_str(SURFACES[surface]).unwrap();
            let base = Path::new(env!("CARGO_MANIFEST_DIR"));
            let o = Optics::new(
                &OpticsConfig { model, spot, ..OpticsConfig::default() },
                Surface::from_config(&surface_config, base).unwrap(),
            )
            .unwrap();
            // Any finite angle, and the same scaled into the mirror's range.
            for scale in [1.0, 1e-6] {
                let r = o.observe(SensingPair { alpha: alpha * scale, beta: beta * scale });
                if let OpticalOutcome::Distance { z_meas_mm, .. } = r.outcome {
                    prop_assert!(z_meas_mm.is_finite());
                    prop_assert!(r.spot_mm.unwrap().coords.iter().all(|v| v.is_finite()));
                }
            }
        }
    }
}
