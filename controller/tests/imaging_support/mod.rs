//! Shared by the imaging tests and benches (of this crate and of `scanhil-lab`): the paper's
//! trajectories as angle functions and a Duplo-like stud scene with a known surface. Library
//! calls only, so another crate's tests can include it.

#![allow(dead_code)]

use scanhil_controller::imaging::progressive::HeightFieldScene;
use scanhil_controller::trajectory::{SensingAxis, Trajectory};
use scanhil_geometry::{GeometryModel, Scanner};

/// The mechanical full range, rad (1.5 deg).
pub const FULL_RANGE_RAD: f64 = 1.5 * std::f64::consts::PI / 180.0;
/// The brick's top, z_s in mm (the paper's 130 mm).
pub const BASE_Z_MM: f64 = -130.0;
/// The stud's height (the paper's stage-scanner reference), mm.
pub const STUD_HEIGHT_MM: f64 = 4.663;

/// Mirror deflections `(d_alpha, d_beta)` in rad against time in s.
pub type Angles = fn(f64) -> (f64, f64);

/// `trajectory`'s `(d_alpha, d_beta)` at `t` s.
fn angles(trajectory: &Trajectory, t: f64) -> (f64, f64) {
    let reference = trajectory.reference_rad(t);
    (reference.alpha, reference.beta)
}

/// Lissajous 27 Hz on d_beta (x), 52 Hz on d_alpha (y), zero phase, full range.
pub fn lissajous(t: f64) -> (f64, f64) {
    let lissajous = Trajectory::Lissajous {
        alpha_hz: 52.0,
        beta_hz: 27.0,
        alpha_amplitude_rad: FULL_RANGE_RAD,
        beta_amplitude_rad: FULL_RANGE_RAD,
        relative_phase_rad: 0.0,
    };
    angles(&lissajous, t)
}

/// Raster: 2 Hz slow triangle on d_alpha (y), 34 Hz fast triangle on d_beta (x).
pub fn raster(t: f64) -> (f64, f64) {
    let raster = Trajectory::Raster {
        slow_hz: 2.0,
        fast_hz: 34.0,
        slow_axis: SensingAxis::Alpha,
        alpha_amplitude_rad: FULL_RANGE_RAD,
        beta_amplitude_rad: FULL_RANGE_RAD,
        fast_max_harmonic: None,
    };
    angles(&raster, t)
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
