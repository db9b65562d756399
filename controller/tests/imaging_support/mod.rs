//! Shared by the imaging tests: the paper's trajectories as angle functions and a Duplo-like
//! stud scene with a known surface.

#![allow(dead_code)]

use scanhil_controller::imaging::progressive::HeightFieldScene;
use scanhil_geometry::{GeometryModel, Scanner};

/// The mechanical full range, rad (1.5 deg).
pub const FULL_RANGE_RAD: f64 = 1.5 * std::f64::consts::PI / 180.0;
/// The brick's top, z_s in mm (the paper's 130 mm).
pub const BASE_Z_MM: f64 = -130.0;
/// The stud's height (the paper's stage-scanner reference), mm.
pub const STUD_HEIGHT_MM: f64 = 4.663;

/// Mirror deflections `(d_alpha, d_beta)` in rad against time in s.
pub type Angles = fn(f64) -> (f64, f64);

/// Lissajous 27 Hz on d_beta (x), 52 Hz on d_alpha (y), zero phase, full range.
pub fn lissajous(t: f64) -> (f64, f64) {
    let w = 2.0 * std::f64::consts::PI;
    (
        FULL_RANGE_RAD * (w * 52.0 * t).sin(),
        FULL_RANGE_RAD * (w * 27.0 * t).sin(),
    )
}

fn triangle(f_hz: f64, t: f64) -> f64 {
    let phase = (f_hz * t).rem_euclid(1.0);
    if phase < 0.5 {
        4.0 * phase - 1.0
    } else {
        3.0 - 4.0 * phase
    }
}

/// Raster: 2 Hz slow triangle on d_alpha (y), 34 Hz fast triangle on d_beta (x).
pub fn raster(t: f64) -> (f64, f64) {
    (
        FULL_RANGE_RAD * triangle(2.0, t),
        FULL_RANGE_RAD * triangle(34.0, t),
    )
}

/// Where the undeflected beam meets the brick top.
pub fn field_centre() -> (f64, f64) {
    let ray = Scanner::paper(GeometryModel::ExactReflection).beam(0.0, 0.0);
    let t = (BASE_Z_MM - ray.origin_mm.z) / ray.direction.z;
    let p = ray.origin_mm + t * ray.direction;
    (p.x, p.y)
}

/// A brick top at z = -130 mm with a hollow stud (outer radius 4.7 mm, inner 3.4 mm,
/// height 4.663 mm) centred in the field of view.
pub fn stud_surface() -> impl Fn(f64, f64) -> f64 + Copy {
    let (cx, cy) = field_centre();
    move |x: f64, y: f64| {
        let r = (x - cx).hypot(y - cy);
        if (3.4..=4.7).contains(&r) {
            BASE_Z_MM + STUD_HEIGHT_MM
        } else {
            BASE_Z_MM
        }
    }
}

/// The stud scene seen through `model`'s beam, over the ILD 2300-100 range.
pub fn stud_scene(model: GeometryModel) -> HeightFieldScene<impl Fn(f64, f64) -> f64 + Copy> {
    HeightFieldScene {
        scanner: Scanner::paper(model),
        surface: stud_surface(),
        range_mm: (70.0, 170.0),
    }
}
