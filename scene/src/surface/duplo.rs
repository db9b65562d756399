//! The paper's validation object: a LEGO Duplo 2x4 brick with hollow cylindrical studs.
//!
//! Dimensions (mm). Duplo is built on twice the LEGO System grid; the LEGO figures are the
//! widely published System brick dimensions (8.0 mm pitch, 9.6 mm brick height, 0.1 mm play on
//! each side, 4.8 mm stud diameter, 6.51 mm underside tube diameter).
//! - pitch 16.0: twice LEGO's 8.0 mm (Duplo and LEGO bricks interlock on this grid);
//! - body 31.6 x 63.6 x 19.2: `n * 16 - 0.4` per side (twice LEGO's 0.2 mm play) and twice
//!   LEGO's 9.6 mm height (assumption: scaled, not measured);
//! - stud outer diameter 9.4: measured Duplo studs are about 9.35-9.4 mm;
//! - stud height 4.663: the paper's mechanical-stage measurement, the scene's reference;
//! - stud bore 6.5: a LEGO 2x2 brick's underside tube (6.51 mm) clamps into a Duplo stud, so
//!   the bore matches it (assumption); the bore's floor is flush with the brick's top face
//!   (assumption: depth = stud height).
//!
//! Local frame: origin at the centre of the brick's top face, x across the brick (2 studs),
//! y along it (4 studs), z up.

use nalgebra::{Point3, Vector3};

use super::bounds::Aabb;
use super::cell_grid::CellGrid;
use super::face::Face;

/// Stud pitch, mm.
pub const PITCH_MM: f64 = 16.0;
/// Brick body width (x, 2 studs), mm.
pub const BODY_WIDTH_MM: f64 = 31.6;
/// Brick body length (y, 4 studs), mm.
pub const BODY_LENGTH_MM: f64 = 63.6;
/// Brick body height without studs, mm.
pub const BODY_HEIGHT_MM: f64 = 19.2;
/// Stud outer diameter, mm.
pub const STUD_OUTER_DIAMETER_MM: f64 = 9.4;
/// Stud bore diameter, mm.
pub const STUD_BORE_DIAMETER_MM: f64 = 6.5;
/// Stud height above the top face: the paper's reference value, mm.
pub const STUD_HEIGHT_MM: f64 = 4.663;
/// Studs across (x) and along (y).
pub const STUDS: (usize, usize) = (2, 4);

/// Stud axes in the local frame, (x, y) mm.
#[must_use]
pub fn stud_centers() -> Vec<[f64; 2]> {
    let offset = |n: usize, k: usize| (k as f64 - (n as f64 - 1.0) / 2.0) * PITCH_MM;
    (0..STUDS.0)
        .flat_map(|i| (0..STUDS.1).map(move |j| [offset(STUDS.0, i), offset(STUDS.1, j)]))
        .collect()
}

/// The brick's faces in its local frame, and the table under it when `table` is set.
///
/// The brick's faces are grouped in its bounding box, the studs in a grid of one cell per
/// stud, each stud's faces in its own box, so a ray tests a stud only when it passes near it
/// (the answer is the flat list's, see [`Face::Group`]).
#[must_use]
pub fn faces(table: bool) -> Vec<Face> {
    let (hw, hl, h) = (BODY_WIDTH_MM / 2.0, BODY_LENGTH_MM / 2.0, BODY_HEIGHT_MM);
    let side =
        |normal: Vector3<f64>, along: Vector3<f64>, half_along: f64, offset: f64| Face::Rect {
            center: Point3::origin() + offset * normal - Vector3::new(0.0, 0.0, h / 2.0),
            u: along,
            half_u: half_along,
            v: Vector3::z(),
            half_v: h / 2.0,
            normal,
        };
    let mut brick = vec![
        Face::Rect {
            center: Point3::origin(),
            u: Vector3::x(),
            half_u: hw,
            v: Vector3::y(),
            half_v: hl,
            normal: Vector3::z(),
        },
        side(Vector3::x(), Vector3::y(), hl, hw),
        side(-Vector3::x(), Vector3::y(), hl, hw),
        side(Vector3::y(), Vector3::x(), hw, hl),
        side(-Vector3::y(), Vector3::x(), hw, hl),
    ];
    let half_grid = |n: usize| n as f64 * PITCH_MM / 2.0;
    brick.push(Face::Grid(Box::new(CellGrid::new(
        [-half_grid(STUDS.0), -half_grid(STUDS.1)],
        PITCH_MM,
        STUDS,
        (0.0, STUD_HEIGHT_MM),
        stud_centers().into_iter().map(stud).collect(),
    ))));
    let mut faces = vec![Face::Group {
        bounds: Aabb::around(
            Point3::new(-hw, -hl, -h),
            Point3::new(hw, hl, STUD_HEIGHT_MM),
        ),
        faces: brick,
    }];
    if table {
        faces.push(Face::Plane {
            point: Point3::new(0.0, 0.0, -h),
            normal: Vector3::z(),
        });
    }
    faces
}

/// One hollow stud on `axis_xy`: its top ring, outer wall and bore, in its bounding box.
fn stud(axis_xy: [f64; 2]) -> Face {
    let (r_in, r_out) = (STUD_BORE_DIAMETER_MM / 2.0, STUD_OUTER_DIAMETER_MM / 2.0);
    let wall = |radius, solid_inside| Face::Cylinder {
        axis_xy,
        radius,
        z_min: 0.0,
        z_max: STUD_HEIGHT_MM,
        solid_inside,
    };
    let [x, y] = axis_xy;
    Face::Group {
        bounds: Aabb::around(
            Point3::new(x - r_out, y - r_out, 0.0),
            Point3::new(x + r_out, y + r_out, STUD_HEIGHT_MM),
        ),
        faces: vec![
            Face::Annulus {
                center: Point3::new(x, y, STUD_HEIGHT_MM),
                r_in,
                r_out,
            },
            wall(r_out, true),
            wall(r_in, false),
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn studs_sit_on_the_grid_inside_the_body() {
        let centers = stud_centers();
        assert_eq!(centers.len(), 8);
        assert!(centers.contains(&[8.0, 8.0]) && centers.contains(&[-8.0, -24.0]));
        for [x, y] in centers {
            assert!(x.abs() + STUD_OUTER_DIAMETER_MM / 2.0 < BODY_WIDTH_MM / 2.0);
            assert!(y.abs() + STUD_OUTER_DIAMETER_MM / 2.0 < BODY_LENGTH_MM / 2.0);
        }
    }
}
