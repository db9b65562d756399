//! The faces surfaces are built from, each with an exact ray intersection.
//!
//! A surface is the boundary of a union of solids seen from above. A ray that starts outside
//! every solid first touches the union where it first crosses any face, so the first hit of a
//! surface is the nearest face crossing, whatever face it is. Normals point out of the solid.
//!
//! Faces may be gathered in a [`Face::Group`] inside a bounding box: a ray that misses the box
//! skips them all. The nearest crossing is the same as over the flat list (ties go to the
//! earlier face in both), so grouping only changes how fast the answer comes.

use nalgebra::{Point3, Vector3};

use super::bounds::Aabb;
use super::cell_grid::CellGrid;
use super::height_map::HeightField;
use super::hit::{Hit, T_MIN_MM};

/// One face of a surface.
#[derive(Debug, Clone, PartialEq)]
pub enum Face {
    /// An unbounded plane through `point` with outward unit `normal`.
    Plane {
        /// A point of the plane.
        point: Point3<f64>,
        /// Outward unit normal.
        normal: Vector3<f64>,
    },
    /// A rectangle: `center + a u + b v` with `|a| <= half_u`, `|b| <= half_v`.
    Rect {
        /// Centre of the rectangle.
        center: Point3<f64>,
        /// First in-plane unit axis.
        u: Vector3<f64>,
        /// Half extent along `u`, mm.
        half_u: f64,
        /// Second in-plane unit axis.
        v: Vector3<f64>,
        /// Half extent along `v`, mm.
        half_v: f64,
        /// Outward unit normal (perpendicular to `u` and `v`).
        normal: Vector3<f64>,
    },
    /// A horizontal ring facing up, `r_in <= r <= r_out` around `center`.
    Annulus {
        /// Centre of the ring (its z is the ring's height).
        center: Point3<f64>,
        /// Inner radius, mm (0 for a disk).
        r_in: f64,
        /// Outer radius, mm.
        r_out: f64,
    },
    /// A vertical cylinder wall between `z_min` and `z_max`.
    Cylinder {
        /// Axis position (x, y), mm.
        axis_xy: [f64; 2],
        /// Radius, mm.
        radius: f64,
        /// Bottom of the wall, mm.
        z_min: f64,
        /// Top of the wall, mm.
        z_max: f64,
        /// Whether the solid is inside (normal points away from the axis) or outside (a bore:
        /// normal points to the axis).
        solid_inside: bool,
    },
    /// A sphere (solid inside).
    Sphere {
        /// Centre, mm.
        center: Point3<f64>,
        /// Radius, mm.
        radius: f64,
    },
    /// A height map's triangulated surface.
    HeightField(Box<HeightField>),
    /// Faces that all lie inside `bounds`, tested only when the ray meets it.
    Group {
        /// A box around every face of the group.
        bounds: Aabb,
        /// The faces, in order (the earlier wins a tie).
        faces: Vec<Face>,
    },
    /// Faces in a uniform x-y grid, tested only in the cells the ray crosses.
    Grid(Box<CellGrid<Face>>),
}

impl Face {
    /// The nearest crossing of the ray `origin + t dir` (unit `dir`) with `T_MIN_MM < t <
    /// t_max`, or `None`.
    #[must_use]
    pub fn intersect(&self, origin: &Point3<f64>, dir: &Vector3<f64>, t_max: f64) -> Option<Hit> {
        match self {
            Face::Plane { point, normal } => {
                let t = plane_t(origin, dir, point, normal)?;
                within(t, t_max).then(|| hit(origin, dir, t, *normal))
            }
            Face::Rect {
                center,
                u,
                half_u,
                v,
                half_v,
                normal,
            } => {
                let t = plane_t(origin, dir, center, normal)?;
                let p = origin + t * dir;
                let d = p - center;
                let inside = d.dot(u).abs() <= *half_u && d.dot(v).abs() <= *half_v;
                (within(t, t_max) && inside).then_some(Hit {
                    t_mm: t,
                    point_mm: p,
                    normal: *normal,
                })
            }
            Face::Annulus {
                center,
                r_in,
                r_out,
            } => {
                let t = plane_t(origin, dir, center, &Vector3::z())?;
                let p = origin + t * dir;
                let r = (p.x - center.x).hypot(p.y - center.y);
                (within(t, t_max) && r >= *r_in && r <= *r_out).then(|| Hit {
                    t_mm: t,
                    point_mm: p,
                    normal: Vector3::z(),
                })
            }
            Face::Cylinder {
                axis_xy,
                radius,
                z_min,
                z_max,
                solid_inside,
            } => {
                let (ox, oy) = (origin.x - axis_xy[0], origin.y - axis_xy[1]);
                let a = dir.x * dir.x + dir.y * dir.y;
                let b = ox * dir.x + oy * dir.y;
                let c = ox * ox + oy * oy - radius * radius;
                quadratic_roots(a, b, c)
                    .into_iter()
                    .flatten()
                    .find_map(|t| {
                        let p = origin + t * dir;
                        (within(t, t_max) && p.z >= *z_min && p.z <= *z_max).then(|| {
                            let radial =
                                Vector3::new(p.x - axis_xy[0], p.y - axis_xy[1], 0.0) / *radius;
                            let normal = if *solid_inside { radial } else { -radial };
                            Hit {
                                t_mm: t,
                                point_mm: p,
                                normal,
                            }
                        })
                    })
            }
            Face::Sphere { center, radius } => {
                let o = origin - center;
                let roots = quadratic_roots(
                    dir.norm_squared(),
                    o.dot(dir),
                    o.norm_squared() - radius * radius,
                );
                roots.into_iter().flatten().find_map(|t| {
                    within(t, t_max).then(|| {
                        let p = origin + t * dir;
                        Hit {
                            t_mm: t,
                            point_mm: p,
                            normal: (p - center) / *radius,
                        }
                    })
                })
            }
            Face::HeightField(field) => field.intersect(origin, dir, t_max),
            Face::Group { bounds, faces } => bounds
                .meets(origin, dir, T_MIN_MM, t_max)
                .then(|| nearest_hit(faces, origin, dir, t_max))
                .flatten(),
            Face::Grid(grid) => nearest_hit(
                grid.faces_along(origin, dir, T_MIN_MM, t_max),
                origin,
                dir,
                t_max,
            ),
        }
    }
}

/// The nearest crossing of the ray with any of `faces` (the earliest face on a tie).
#[must_use]
pub fn nearest_hit<'a>(
    faces: impl IntoIterator<Item = &'a Face>,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    t_max: f64,
) -> Option<Hit> {
    faces
        .into_iter()
        .filter_map(|f| f.intersect(origin, dir, t_max))
        .min_by(|a, b| a.t_mm.total_cmp(&b.t_mm))
}

fn within(t: f64, t_max: f64) -> bool {
    t > T_MIN_MM && t < t_max
}

fn hit(origin: &Point3<f64>, dir: &Vector3<f64>, t: f64, normal: Vector3<f64>) -> Hit {
    Hit {
        t_mm: t,
        point_mm: origin + t * dir,
        normal,
    }
}

/// Ray parameter where the ray meets the plane, `None` if parallel.
fn plane_t(
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    point: &Point3<f64>,
    normal: &Vector3<f64>,
) -> Option<f64> {
    let denom = dir.dot(normal);
    (denom.abs() > 1e-15).then(|| (point - origin).dot(normal) / denom)
}

/// Roots of `a t^2 + 2 b t + c = 0`, smaller first (numerically stable form).
fn quadratic_roots(a: f64, b: f64, c: f64) -> [Option<f64>; 2] {
    if a <= 1e-300 {
        return [None, None];
    }
    let disc = b * b - a * c;
    if disc < 0.0 || !disc.is_finite() {
        return [None, None];
    }
    let q = -(b + b.signum() * disc.sqrt());
    let (r1, r2) = if q == 0.0 { (0.0, 0.0) } else { (q / a, c / q) };
    [Some(r1.min(r2)), Some(r1.max(r2))]
}

#[cfg(test)]
mod tests {
    use super::*;

    const DOWN: Vector3<f64> = Vector3::new(0.0, 0.0, -1.0);

    #[test]
    fn plane_and_rect_hits() {
        let plane = Face::Plane {
            point: Point3::new(0.0, 0.0, -100.0),
            normal: Vector3::z(),
        };
        let h = plane
            .intersect(&Point3::origin(), &DOWN, f64::INFINITY)
            .unwrap();
        assert!((h.t_mm - 100.0).abs() < 1e-12);
        assert!(plane.intersect(&Point3::origin(), &DOWN, 50.0).is_none());
        let rect = Face::Rect {
            center: Point3::new(0.0, 0.0, -10.0),
            u: Vector3::x(),
            half_u: 1.0,
            v: Vector3::y(),
            half_v: 2.0,
            normal: Vector3::z(),
        };
        assert!(
            rect.intersect(&Point3::new(0.9, 1.9, 0.0), &DOWN, f64::INFINITY)
                .is_some()
        );
        assert!(
            rect.intersect(&Point3::new(1.1, 0.0, 0.0), &DOWN, f64::INFINITY)
                .is_none()
        );
    }

    #[test]
    fn cylinder_wall_from_outside_and_from_a_bore() {
        let outer = Face::Cylinder {
            axis_xy: [0.0, 0.0],
            radius: 2.0,
            z_min: -1.0,
            z_max: 1.0,
            solid_inside: true,
        };
        let h = outer
            .intersect(&Point3::new(-5.0, 0.0, 0.0), &Vector3::x(), f64::INFINITY)
            .unwrap();
        assert!((h.t_mm - 3.0).abs() < 1e-12 && (h.normal + Vector3::x()).norm() < 1e-12);
        let bore = Face::Cylinder {
            axis_xy: [0.0, 0.0],
            radius: 2.0,
            z_min: -1.0,
            z_max: 1.0,
            solid_inside: false,
        };
        let h = bore
            .intersect(&Point3::origin(), &Vector3::x(), f64::INFINITY)
            .unwrap();
        assert!((h.t_mm - 2.0).abs() < 1e-12 && (h.normal + Vector3::x()).norm() < 1e-12);
        // Above the wall's top: no hit.
        assert!(
            outer
                .intersect(&Point3::new(-5.0, 0.0, 1.5), &Vector3::x(), f64::INFINITY)
                .is_none()
        );
    }

    #[test]
    fn sphere_near_side_and_annulus_hole() {
        let s = Face::Sphere {
            center: Point3::new(0.0, 0.0, -50.0),
            radius: 5.0,
        };
        let h = s
            .intersect(&Point3::origin(), &DOWN, f64::INFINITY)
            .unwrap();
        assert!((h.t_mm - 45.0).abs() < 1e-12 && (h.normal - Vector3::z()).norm() < 1e-12);
        let ring = Face::Annulus {
            center: Point3::new(0.0, 0.0, -1.0),
            r_in: 1.0,
            r_out: 2.0,
        };
        assert!(
            ring.intersect(&Point3::new(0.5, 0.0, 0.0), &DOWN, f64::INFINITY)
                .is_none()
        );
        assert!(
            ring.intersect(&Point3::new(1.5, 0.0, 0.0), &DOWN, f64::INFINITY)
                .is_some()
        );
    }
}
