//! What is in front of the sensor: the scene's surface, its ray intersection, and its ground
//! truth (the true height at any (x, y)), so a scan can be scored.
//!
//! Coordinates are the scanner's (see `scanhil-geometry`): mm, origin at the sensor's
//! reference point, z up, so surfaces lie at negative z; a surface's `distance_mm` is `|z|`.
//! The resting beam comes down at `(0, -10)` ([`REST_SPOT_Y_MM`]), the default centre of the
//! shapes that have one.
//!
//! Every shape is a set of [`Face`]s bounding solids seen from above; the first hit is the
//! nearest face crossing ([`face`] explains why that is exact).

pub mod bounds;
pub mod cell_grid;
pub mod duplo;
pub mod face;
pub mod height_map;
pub mod hit;

use std::path::{Path, PathBuf};

use nalgebra::{Point3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

pub use face::Face;
use height_map::{HeightField, HeightGrid};
pub use hit::Hit;

/// y of the resting beam's spot for the paper's setup (`-y_FSM`), mm: the default centre.
pub const REST_SPOT_Y_MM: f64 = -10.0;
/// Half extent of the step's two levels (they are rectangles this large), mm.
const STEP_HALF_EXTENT_MM: f64 = 1.0e4;
/// Height above everything from which ground-truth rays start, mm.
const GROUND_TRUTH_RAY_START_Z_MM: f64 = 1.0e5;

fn rest_spot_y_mm() -> f64 {
    REST_SPOT_Y_MM
}
fn one() -> f64 {
    1.0
}
fn duplo_distance_mm() -> f64 {
    130.0
}
fn duplo_center_x_mm() -> f64 {
    -duplo::PITCH_MM / 2.0
}
fn duplo_center_y_mm() -> f64 {
    REST_SPOT_Y_MM - duplo::PITCH_MM / 2.0
}
fn yes() -> bool {
    true
}

/// Which horizontal axis a step runs across.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StepAxis {
    /// The step's edge is the line `x = edge_mm`.
    X,
    /// The step's edge is the line `y = edge_mm`.
    Y,
}

/// A scene's surface, as written in its JSON (`"kind"` names the shape).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum SurfaceConfig {
    /// A level plane, `z = -distance_mm`.
    Plane {
        /// Distance below the sensor reference, mm.
        distance_mm: f64,
    },
    /// A plane through `(center_x_mm, center_y_mm, -distance_mm)` rising by `tan(slope_x_deg)`
    /// per mm of x and `tan(slope_y_deg)` per mm of y.
    TiltedPlane {
        /// Distance of the plane below the sensor at the centre, mm.
        distance_mm: f64,
        /// Rise along x, degrees.
        #[serde(default)]
        slope_x_deg: f64,
        /// Rise along y, degrees.
        #[serde(default)]
        slope_y_deg: f64,
        /// Centre x, mm.
        #[serde(default)]
        center_x_mm: f64,
        /// Centre y, mm.
        #[serde(default = "rest_spot_y_mm")]
        center_y_mm: f64,
    },
    /// Two levels with a vertical wall: `z = -distance_mm` where the axis coordinate is below
    /// `edge_mm`, `-distance_mm + height_mm` from `edge_mm` on.
    Step {
        /// Distance of the lower-coordinate level below the sensor, mm.
        distance_mm: f64,
        /// Height of the other level above it (negative: a step down), mm.
        height_mm: f64,
        /// The axis the step runs across.
        axis: StepAxis,
        /// Position of the edge along `axis`, mm.
        #[serde(default = "rest_spot_y_mm")]
        edge_mm: f64,
    },
    /// A sphere, optionally on a level base plane.
    Sphere {
        /// Radius, mm.
        radius_mm: f64,
        /// Distance of the centre below the sensor, mm.
        center_distance_mm: f64,
        /// Centre x, mm.
        #[serde(default)]
        center_x_mm: f64,
        /// Centre y, mm.
        #[serde(default = "rest_spot_y_mm")]
        center_y_mm: f64,
        /// Distance of a base plane below the sensor, mm (none: only the sphere).
        #[serde(default)]
        base_distance_mm: Option<f64>,
    },
    /// Heights from a PNG (8/16-bit grey, `value / max * height_scale_mm`) or CSV
    /// (`value * height_scale_mm`) file, added to the plane at `distance_mm`.
    HeightMap {
        /// The file, relative to the scene file's directory.
        file: PathBuf,
        /// Distance of the map's zero height below the sensor, mm.
        distance_mm: f64,
        /// Sample spacing, mm.
        pixel_mm: f64,
        /// Height scale (PNG: height of full white; CSV: mm per unit), mm.
        #[serde(default = "one")]
        height_scale_mm: f64,
        /// x of the map's centre, mm.
        #[serde(default)]
        center_x_mm: f64,
        /// y of the map's centre, mm.
        #[serde(default = "rest_spot_y_mm")]
        center_y_mm: f64,
    },
    /// The paper's Duplo 2x4 brick with hollow studs (see [`duplo`] for its dimensions).
    #[serde(rename = "duplo_2x4")]
    Duplo2x4 {
        /// Distance of the brick's top face (the plane around the studs) below the sensor, mm.
        #[serde(default = "duplo_distance_mm")]
        top_distance_mm: f64,
        /// x of the brick's centre, mm (default: a stud's axis on the resting beam).
        #[serde(default = "duplo_center_x_mm")]
        center_x_mm: f64,
        /// y of the brick's centre, mm (default: a stud's axis on the resting beam).
        #[serde(default = "duplo_center_y_mm")]
        center_y_mm: f64,
        /// Rotation of the brick about the vertical through its centre, degrees (0: long side
        /// along y).
        #[serde(default)]
        rotation_deg: f64,
        /// Whether a table plane lies under the brick.
        #[serde(default = "yes")]
        table: bool,
    },
}

/// Why a surface could not be built.
#[derive(Debug, thiserror::Error)]
pub enum SurfaceError {
    /// A numeric field is out of its domain.
    #[error("surface field `{field}` = {value} must be {requirement}")]
    Invalid {
        /// The field's JSON name.
        field: &'static str,
        /// The value found.
        value: f64,
        /// What it must be.
        requirement: &'static str,
    },
    /// A height-map file could not be read.
    #[error("height map {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A PNG height map is not a usable image.
    #[error("height map {}: {message}", path.display())]
    Image {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A CSV height map has a bad value.
    #[error("height map {}, line {line}, column {column}: {reason}", path.display())]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column (value index in the row).
        column: usize,
        /// What is wrong.
        reason: String,
    },
    /// The height-map file is neither `.png` nor `.csv`.
    #[error("height map {}: unsupported file type (expected .png or .csv)", path.display())]
    UnsupportedFile {
        /// The file.
        path: PathBuf,
    },
    /// The height map has fewer than 2 x 2 samples.
    #[error("height map {}: {cols} x {rows} samples, at least 2 x 2 needed", path.display())]
    HeightMapTooSmall {
        /// The file.
        path: PathBuf,
        /// Samples per row.
        cols: usize,
        /// Rows.
        rows: usize,
    },
}

/// A rigid placement of a shape's local frame: rotation about z, then translation.
#[derive(Debug, Clone, PartialEq)]
struct Placement {
    rotation: Rotation3<f64>,
    translation: Vector3<f64>,
}

/// The surface in front of the sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct Surface {
    kind: &'static str,
    faces: Vec<Face>,
    placement: Option<Placement>,
}

impl Surface {
    /// Builds the surface of `config`; relative height-map paths are resolved against
    /// `base_dir` (the scene file's directory).
    ///
    /// # Errors
    /// [`SurfaceError`] naming the bad field, or the height-map file and what is wrong in it.
    pub fn from_config(config: &SurfaceConfig, base_dir: &Path) -> Result<Surface, SurfaceError> {
        let plane = |z: f64, normal: Vector3<f64>, x: f64, y: f64| Face::Plane {
            point: Point3::new(x, y, z),
            normal,
        };
        let (kind, faces, placement) = match config {
            SurfaceConfig::Plane { distance_mm } => {
                check_distance("distance_mm", *distance_mm)?;
                (
                    "plane",
                    vec![plane(-distance_mm, Vector3::z(), 0.0, 0.0)],
                    None,
                )
            }
            SurfaceConfig::TiltedPlane {
                distance_mm,
                slope_x_deg,
                slope_y_deg,
                center_x_mm,
                center_y_mm,
            } => {
                check_distance("distance_mm", *distance_mm)?;
                check_slope("slope_x_deg", *slope_x_deg)?;
                check_slope("slope_y_deg", *slope_y_deg)?;
                check_finite("center_x_mm", *center_x_mm)?;
                check_finite("center_y_mm", *center_y_mm)?;
                let normal = Vector3::new(
                    -slope_x_deg.to_radians().tan(),
                    -slope_y_deg.to_radians().tan(),
                    1.0,
                )
                .normalize();
                (
                    "tilted_plane",
                    vec![plane(-distance_mm, normal, *center_x_mm, *center_y_mm)],
                    None,
                )
            }
            SurfaceConfig::Step {
                distance_mm,
                height_mm,
                axis,
                edge_mm,
            } => {
                check_distance("distance_mm", *distance_mm)?;
                check_finite("height_mm", *height_mm)?;
                check_finite("edge_mm", *edge_mm)?;
                (
                    "step",
                    step_faces(-distance_mm, *height_mm, *axis, *edge_mm),
                    None,
                )
            }
            SurfaceConfig::Sphere {
                radius_mm,
                center_distance_mm,
                center_x_mm,
                center_y_mm,
                base_distance_mm,
            } => {
                check_positive("radius_mm", *radius_mm)?;
                check_distance("center_distance_mm", *center_distance_mm)?;
                check_finite("center_x_mm", *center_x_mm)?;
                check_finite("center_y_mm", *center_y_mm)?;
                let center = Point3::new(*center_x_mm, *center_y_mm, -center_distance_mm);
                let mut faces = vec![Face::Sphere {
                    center,
                    radius: *radius_mm,
                }];
                if let Some(base) = base_distance_mm {
                    check_distance("base_distance_mm", *base)?;
                    faces.push(plane(-base, Vector3::z(), 0.0, 0.0));
                }
                ("sphere", faces, None)
            }
            SurfaceConfig::HeightMap {
                file,
                distance_mm,
                pixel_mm,
                height_scale_mm,
                center_x_mm,
                center_y_mm,
            } => {
                check_distance("distance_mm", *distance_mm)?;
                check_positive("pixel_mm", *pixel_mm)?;
                check_finite("height_scale_mm", *height_scale_mm)?;
                check_finite("center_x_mm", *center_x_mm)?;
                check_finite("center_y_mm", *center_y_mm)?;
                let grid = HeightGrid::load(&base_dir.join(file), *height_scale_mm)?;
                let field =
                    HeightField::new(grid, *pixel_mm, *center_x_mm, *center_y_mm, -distance_mm);
                ("height_map", vec![Face::HeightField(Box::new(field))], None)
            }
            SurfaceConfig::Duplo2x4 {
                top_distance_mm,
                center_x_mm,
                center_y_mm,
                rotation_deg,
                table,
            } => {
                check_distance("top_distance_mm", *top_distance_mm)?;
                check_finite("center_x_mm", *center_x_mm)?;
                check_finite("center_y_mm", *center_y_mm)?;
                check_finite("rotation_deg", *rotation_deg)?;
                let placement = Placement {
                    rotation: Rotation3::from_axis_angle(
                        &Vector3::z_axis(),
                        rotation_deg.to_radians(),
                    ),
                    translation: Vector3::new(*center_x_mm, *center_y_mm, -top_distance_mm),
                };
                ("duplo_2x4", duplo::faces(*table), Some(placement))
            }
        };
        Ok(Surface {
            kind,
            faces,
            placement,
        })
    }

    /// The shape's name, as in the JSON `"kind"`.
    #[must_use]
    pub fn kind(&self) -> &'static str {
        self.kind
    }

    /// The first point where the ray `origin_mm + t * direction` (any non-zero direction)
    /// meets the surface with `0 < t < t_max_mm` (t in mm along the unit direction).
    #[must_use]
    pub fn first_hit(
        &self,
        origin_mm: &Point3<f64>,
        direction: &Vector3<f64>,
        t_max_mm: f64,
    ) -> Option<Hit> {
        let unit = direction.try_normalize(1e-300)?;
        if !origin_mm
            .coords
            .iter()
            .chain(unit.iter())
            .all(|v| v.is_finite())
        {
            return None;
        }
        let (origin, dir) = match &self.placement {
            Some(p) => (
                Point3::from(p.rotation.inverse() * (origin_mm.coords - p.translation)),
                p.rotation.inverse() * unit,
            ),
            None => (*origin_mm, unit),
        };
        let hit = face::nearest_hit(&self.faces, &origin, &dir, t_max_mm)?;
        Some(match &self.placement {
            Some(p) => Hit {
                t_mm: hit.t_mm,
                point_mm: Point3::from(p.rotation * hit.point_mm.coords + p.translation),
                normal: p.rotation * hit.normal,
            },
            None => hit,
        })
    }

    /// Ground truth: the z (mm, negative below the sensor) of the topmost surface at (x, y),
    /// `None` where there is none (beside a sphere without a base).
    #[must_use]
    pub fn height_at(&self, x_mm: f64, y_mm: f64) -> Option<f64> {
        let start = Point3::new(x_mm, y_mm, GROUND_TRUTH_RAY_START_Z_MM);
        self.first_hit(&start, &-Vector3::z(), f64::INFINITY)
            .map(|h| h.point_mm.z)
    }
}

/// A step's two levels and its wall.
fn step_faces(z_low: f64, height: f64, axis: StepAxis, edge: f64) -> Vec<Face> {
    let (across, along) = match axis {
        StepAxis::X => (Vector3::x(), Vector3::y()),
        StepAxis::Y => (Vector3::y(), Vector3::x()),
    };
    let z_high = z_low + height;
    let level = |z: f64, side: f64| Face::Rect {
        center: Point3::from(
            across * (edge + side * STEP_HALF_EXTENT_MM) + Vector3::new(0.0, 0.0, z),
        ),
        u: across,
        half_u: STEP_HALF_EXTENT_MM,
        v: along,
        half_v: STEP_HALF_EXTENT_MM,
        normal: Vector3::z(),
    };
    let wall = Face::Rect {
        center: Point3::from(across * edge + Vector3::new(0.0, 0.0, (z_low + z_high) / 2.0)),
        u: along,
        half_u: STEP_HALF_EXTENT_MM,
        v: Vector3::z(),
        half_v: height.abs() / 2.0,
        // The wall faces the lower side.
        normal: if height >= 0.0 { -across } else { across },
    };
    vec![level(z_low, -1.0), level(z_high, 1.0), wall]
}

fn check_finite(field: &'static str, value: f64) -> Result<(), SurfaceError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(SurfaceError::Invalid {
            field,
            value,
            requirement: "finite",
        })
    }
}

fn check_positive(field: &'static str, value: f64) -> Result<(), SurfaceError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(SurfaceError::Invalid {
            field,
            value,
            requirement: "finite and > 0",
        })
    }
}

/// Distances are `|z|` below the sensor: positive.
fn check_distance(field: &'static str, value: f64) -> Result<(), SurfaceError> {
    check_positive(field, value)
}

fn check_slope(field: &'static str, value: f64) -> Result<(), SurfaceError> {
    if value.is_finite() && value.abs() < 89.0 {
        Ok(())
    } else {
        Err(SurfaceError::Invalid {
            field,
            value,
            requirement: "finite, between -89 and 89 degrees",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DOWN: Vector3<f64> = Vector3::new(0.0, 0.0, -1.0);

    fn build(json: &str) -> Surface {
        let config: SurfaceConfig = serde_json::from_str(json).unwrap();
        Surface::from_config(&config, Path::new(env!("CARGO_MANIFEST_DIR"))).unwrap()
    }

    fn down_from(x: f64, y: f64) -> Hit {
        build_cached()
            .first_hit(&Point3::new(x, y, 0.0), &DOWN, f64::INFINITY)
            .unwrap()
    }

    fn build_cached() -> Surface {
        build(r#"{"kind": "duplo_2x4"}"#)
    }

    #[test]
    fn plane_hit_and_truth() {
        let s = build(r#"{"kind": "plane", "distance_mm": 130.0}"#);
        let dir = Vector3::new(0.05, -0.03, -1.0);
        let h = s
            .first_hit(&Point3::new(0.0, -10.0, 0.0), &dir, f64::INFINITY)
            .unwrap();
        assert!((h.point_mm.z + 130.0).abs() < 1e-12);
        assert!((h.t_mm - 130.0 * dir.norm()).abs() < 1e-9);
        assert_eq!(s.height_at(3.0, 4.0), Some(-130.0));
        assert_eq!(s.kind(), "plane");
    }

    #[test]
    fn tilted_plane_rises_with_its_slope() {
        let s = build(r#"{"kind": "tilted_plane", "distance_mm": 100.0, "slope_x_deg": 45.0}"#);
        assert!((s.height_at(0.0, -10.0).unwrap() + 100.0).abs() < 1e-9);
        assert!((s.height_at(2.0, 7.0).unwrap() + 98.0).abs() < 1e-9);
        let h = s
            .first_hit(&Point3::new(2.0, 0.0, 0.0), &DOWN, f64::INFINITY)
            .unwrap();
        assert!((h.normal - Vector3::new(-1.0, 0.0, 1.0).normalize()).norm() < 1e-12);
    }

    #[test]
    fn step_levels_and_wall() {
        let s = build(
            r#"{"kind": "step", "distance_mm": 130.0, "height_mm": 5.0, "axis": "y", "edge_mm": 0.0}"#,
        );
        assert_eq!(s.height_at(0.0, -1.0), Some(-130.0));
        assert_eq!(s.height_at(0.0, 1.0), Some(-125.0));
        // A ray moving towards +y below the top level meets the wall, which faces -y.
        let h = s
            .first_hit(
                &Point3::new(0.0, -1.0, -127.0),
                &Vector3::y(),
                f64::INFINITY,
            )
            .unwrap();
        assert!((h.point_mm.y).abs() < 1e-12 && (h.normal + Vector3::y()).norm() < 1e-12);
        let down =
            build(r#"{"kind": "step", "distance_mm": 130.0, "height_mm": -5.0, "axis": "x"}"#);
        // The edge defaults to -10 mm; from there on the level is 5 mm lower.
        assert_eq!(down.height_at(-10.0 - 1e-9, 0.0), Some(-130.0));
        assert_eq!(down.height_at(-10.0 + 1e-9, 0.0), Some(-135.0));
    }

    #[test]
    fn sphere_with_and_without_base() {
        let s = build(
            r#"{"kind": "sphere", "radius_mm": 8.0, "center_distance_mm": 135.0, "base_distance_mm": 135.0}"#,
        );
        assert!((s.height_at(0.0, -10.0).unwrap() + 127.0).abs() < 1e-9);
        let z = s.height_at(4.0, -10.0).unwrap();
        assert!((z - (-135.0 + (64.0f64 - 16.0).sqrt())).abs() < 1e-9);
        assert_eq!(s.height_at(9.0, -10.0), Some(-135.0));
        let bare = build(r#"{"kind": "sphere", "radius_mm": 8.0, "center_distance_mm": 135.0}"#);
        assert_eq!(bare.height_at(9.0, -10.0), None);
    }

    #[test]
    fn duplo_stud_top_bore_and_top_face() {
        let rest = [0.0, REST_SPOT_Y_MM];
        // The default placement puts a stud's axis on the resting beam: the bore's floor.
        assert!((down_from(rest[0], rest[1]).point_mm.z + 130.0).abs() < 1e-9);
        // The stud's ring, 4 mm from the axis.
        let ring = down_from(4.0, REST_SPOT_Y_MM);
        assert!((ring.point_mm.z - (-130.0 + duplo::STUD_HEIGHT_MM)).abs() < 1e-9);
        // Between studs: the brick's top face.
        assert!((down_from(0.0, REST_SPOT_Y_MM - 8.0).point_mm.z + 130.0).abs() < 1e-9);
        // Off the brick: the table, 19.2 mm lower.
        let table = build_cached().height_at(20.0, REST_SPOT_Y_MM).unwrap();
        assert!((table + 130.0 + duplo::BODY_HEIGHT_MM).abs() < 1e-9);
        // A ray travelling sideways into the stud meets its outer wall, normal outwards.
        let h = build_cached()
            .first_hit(
                &Point3::new(-10.0, REST_SPOT_Y_MM, -128.0),
                &Vector3::x(),
                f64::INFINITY,
            )
            .unwrap();
        assert!((h.point_mm.x + 4.7).abs() < 1e-9 && (h.normal + Vector3::x()).norm() < 1e-9);
    }

    #[test]
    fn duplo_rotation_moves_the_studs() {
        let s = build(
            r#"{"kind": "duplo_2x4", "rotation_deg": 90.0, "center_x_mm": 0.0, "center_y_mm": 0.0}"#,
        );
        // Local stud (8, 8) rotates to (-8, 8): its ring is at 4 mm from that axis.
        assert!(
            (s.height_at(-8.0 + 4.0, 8.0).unwrap() - (-130.0 + duplo::STUD_HEIGHT_MM)).abs() < 1e-9
        );
        assert!((s.height_at(-8.0, 8.0).unwrap() + 130.0).abs() < 1e-9);
    }

    /// The same surface with every group opened: the flat face list (the intersection before
    /// faces were grouped), the oracle for the grouped one.
    fn flat(surface: &Surface) -> Surface {
        fn open(faces: &[Face], into: &mut Vec<Face>) {
            for face in faces {
                match face {
                    Face::Group { faces, .. } => open(faces, into),
                    Face::Grid(grid) => open(grid.faces(), into),
                    other => into.push(other.clone()),
                }
            }
        }
        let mut faces = Vec::new();
        open(&surface.faces, &mut faces);
        assert!(faces.len() > surface.faces.len(), "nothing was grouped");
        Surface {
            faces,
            ..surface.clone()
        }
    }

    fn rotated_duplo() -> Surface {
        build(r#"{"kind": "duplo_2x4", "rotation_deg": 33.0, "center_x_mm": 1.5}"#)
    }

    #[test]
    fn grouped_duplo_answers_as_its_flat_faces_on_a_fine_grid_and_on_its_edges() {
        let (hw, hl) = (duplo::BODY_WIDTH_MM / 2.0, duplo::BODY_LENGTH_MM / 2.0);
        let r = [
            duplo::STUD_BORE_DIAMETER_MM / 2.0,
            duplo::STUD_OUTER_DIAMETER_MM / 2.0,
        ];
        // Local x and y where faces end: the body's sides, each stud's walls.
        let mut edges_x = vec![-hw, hw];
        let mut edges_y = vec![-hl, hl];
        for [x, y] in duplo::stud_centers() {
            for r in r {
                edges_x.extend([x - r, x + r]);
                edges_y.extend([y - r, y + r]);
            }
        }
        let grid = (0..420).map(|k| -42.0 + 0.2 * f64::from(k));
        for surface in [build_cached(), rotated_duplo()] {
            let oracle = flat(&surface);
            let local = |x: f64, y: f64| match &surface.placement {
                Some(p) => Point3::from(p.rotation * Vector3::new(x, y, 0.0) + p.translation),
                None => Point3::new(x, y, 0.0),
            };
            let mut rays: Vec<(Point3<f64>, Vector3<f64>)> = Vec::new();
            for x in grid.clone() {
                for y in grid.clone() {
                    rays.push((Point3::new(x, y - 10.0, 0.0), DOWN));
                    rays.push((Point3::new(x, y, 0.0), Vector3::new(0.01, -0.02, -1.0)));
                }
            }
            for &x in &edges_x {
                for &y in &edges_y {
                    for (dx, dy) in [(0.0, 0.0), (1e-12, 0.0), (0.0, -1e-12)] {
                        let p = local(x + dx, y + dy);
                        rays.push((Point3::new(p.x, p.y, 0.0), DOWN));
                    }
                }
            }
            for (origin, dir) in rays {
                assert_eq!(
                    surface.first_hit(&origin, &dir, f64::INFINITY),
                    oracle.first_hit(&origin, &dir, f64::INFINITY),
                    "{origin:?} {dir:?}"
                );
            }
        }
    }

    proptest::proptest! {
        #[test]
        fn grouped_duplo_answers_as_its_flat_faces_for_any_ray(
            ox in -50.0..50.0f64, oy in -70.0..50.0f64, oz in -160.0..10.0f64,
            dx in -1.0..1.0f64, dy in -1.0..1.0f64, dz in -1.0..1.0f64,
            t_max in proptest::prop_oneof![proptest::strategy::Just(f64::INFINITY), 0.0..200.0f64],
            bounce in proptest::bool::ANY,
        ) {
            for surface in [build_cached(), rotated_duplo()] {
                let oracle = flat(&surface);
                let origin = Point3::new(ox, oy, oz);
                let dir = Vector3::new(dx, dy, dz);
                let hit = surface.first_hit(&origin, &dir, t_max);
                proptest::prop_assert_eq!(hit, oracle.first_hit(&origin, &dir, t_max));
                // A second path starting on the surface (as a reflection does).
                if let (true, Some(h)) = (bounce, hit) {
                    let out = Vector3::new(dy, dz, dx.abs() + 0.1);
                    proptest::prop_assert_eq!(
                        surface.first_hit(&h.point_mm, &out, t_max),
                        oracle.first_hit(&h.point_mm, &out, t_max)
                    );
                }
            }
        }
    }

    #[test]
    fn height_map_fixture_loads_relative_to_base_dir() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("m.csv"), "0,0\n2,2\n").unwrap();
        let config: SurfaceConfig = serde_json::from_str(
            r#"{"kind": "height_map", "file": "m.csv", "distance_mm": 100.0, "pixel_mm": 1.0, "center_y_mm": 0.0}"#,
        )
        .unwrap();
        let s = Surface::from_config(&config, dir.path()).unwrap();
        // Row 0 (+y edge) is 0, row 1 (-y edge) is 2 mm.
        assert!((s.height_at(0.0, 0.5).unwrap() + 100.0).abs() < 1e-9);
        assert!((s.height_at(0.0, -0.5).unwrap() + 98.0).abs() < 1e-9);
        assert!((s.height_at(0.0, 0.0).unwrap() + 99.0).abs() < 1e-9);
    }

    #[test]
    fn dimple_fixtures_png_and_csv_are_the_same_surface() {
        let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/surfaces");
        let load = |file: &str| {
            let json = format!(
                r#"{{"kind": "height_map", "file": "{file}", "distance_mm": 130.0, "pixel_mm": 0.1}}"#
            );
            let config: SurfaceConfig = serde_json::from_str(&json).unwrap();
            Surface::from_config(&config, &fixtures).unwrap()
        };
        let (png, csv) = (load("dimple.png"), load("dimple.csv"));
        // Dimple bottom (1 mm deep) on the resting beam; plateau at 1 mm outside 4 mm.
        for (x, y, want) in [
            (0.0, -10.0, -130.0),
            (4.5, -10.0, -129.0),
            (0.0, -5.5, -129.0),
        ] {
            for s in [&png, &csv] {
                let z = s.height_at(x, y).unwrap();
                assert!((z - want).abs() < 1e-5, "({x}, {y}): {z}");
            }
        }
        for k in 0..50 {
            let (x, y) = (-5.0 + 0.2 * f64::from(k), -10.0 + 0.1 * f64::from(k % 7));
            let (a, b) = (png.height_at(x, y).unwrap(), csv.height_at(x, y).unwrap());
            assert!((a - b).abs() < 1e-5, "({x}, {y}): {a} vs {b}");
        }
    }

    #[test]
    fn bad_fields_and_files_are_named() {
        let config: SurfaceConfig = serde_json::from_str(
            r#"{"kind": "sphere", "radius_mm": -1.0, "center_distance_mm": 100.0}"#,
        )
        .unwrap();
        let err = Surface::from_config(&config, Path::new("."))
            .unwrap_err()
            .to_string();
        assert!(err.contains("radius_mm"), "{err}");
        let config: SurfaceConfig = serde_json::from_str(
            r#"{"kind": "height_map", "file": "nope.csv", "distance_mm": 100.0, "pixel_mm": 1.0}"#,
        )
        .unwrap();
        let err = Surface::from_config(&config, Path::new("/nonexistent"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("nope.csv"), "{err}");
        assert!(
            serde_json::from_str::<SurfaceConfig>(r#"{"kind": "plane", "distance": 1.0}"#).is_err()
        );
    }
}
