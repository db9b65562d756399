//! Axis-aligned bounding boxes: a cheap test that lets a ray skip the faces inside a box it
//! cannot reach (a [`super::Face::Group`]).
//!
//! The test is conservative: a box built with [`Aabb::around`] is padded by [`PAD_MM`], far
//! more than the rounding of any face's own intersection at the scanner's scale (1e-13 mm at
//! 1e5 mm), so a ray whose face test would report a hit is never turned away and a grouped
//! surface answers exactly as its flat list of faces does.

use nalgebra::{Point3, Vector3};

/// Padding added on every side of a bounding box, mm.
pub const PAD_MM: f64 = 1e-6;

/// An axis-aligned box, `min <= p <= max` per coordinate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Smallest corner, mm.
    pub min: Point3<f64>,
    /// Largest corner, mm.
    pub max: Point3<f64>,
}

impl Aabb {
    /// The box from `min` to `max` grown by [`PAD_MM`] on every side.
    #[must_use]
    pub fn around(min: Point3<f64>, max: Point3<f64>) -> Aabb {
        let pad = Vector3::repeat(PAD_MM);
        Aabb {
            min: min - pad,
            max: max + pad,
        }
    }

    /// Whether the ray `origin + t dir` meets the box for some `t` in `[t_min, t_max]`.
    #[must_use]
    pub fn meets(&self, origin: &Point3<f64>, dir: &Vector3<f64>, t_min: f64, t_max: f64) -> bool {
        self.span(origin, dir, t_min, t_max).is_some()
    }

    /// The part `[enter, exit]` of `[t_min, t_max]` in which the ray `origin + t dir` is in
    /// the box, `None` if it never is (slab test; a zero direction component keeps the ray in
    /// that slab or out of it).
    #[must_use]
    pub fn span(
        &self,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        t_min: f64,
        t_max: f64,
    ) -> Option<(f64, f64)> {
        let (mut enter, mut exit) = (t_min, t_max);
        for axis in 0..3 {
            let (o, d) = (origin[axis], dir[axis]);
            let (lo, hi) = (self.min[axis], self.max[axis]);
            if d == 0.0 {
                if o < lo || o > hi {
                    return None;
                }
                continue;
            }
            let (t0, t1) = ((lo - o) / d, (hi - o) / d);
            let (near, far) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
            enter = enter.max(near);
            exit = exit.min(far);
            if enter > exit {
                return None;
            }
        }
        Some((enter, exit))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> Aabb {
        Aabb::around(Point3::new(-1.0, -1.0, -1.0), Point3::new(1.0, 1.0, 1.0))
    }

    #[test]
    fn rays_through_beside_and_along_the_box() {
        let b = unit_box();
        let down = Vector3::new(0.0, 0.0, -1.0);
        assert!(b.meets(&Point3::new(0.5, 0.5, 10.0), &down, 0.0, f64::INFINITY));
        assert!(!b.meets(&Point3::new(1.5, 0.5, 10.0), &down, 0.0, f64::INFINITY));
        // The box lies 9 to 11 mm along the ray: a shorter ray stops before it, a ray that
        // starts past it is gone.
        assert!(!b.meets(&Point3::new(0.5, 0.5, 10.0), &down, 0.0, 8.9));
        assert!(!b.meets(&Point3::new(0.5, 0.5, -2.0), &down, 0.0, f64::INFINITY));
        // Oblique: misses the corner region, then passes through it.
        let oblique = Vector3::new(1.0, 1.0, 0.0).normalize();
        assert!(!b.meets(&Point3::new(-3.0, 0.0, 0.0), &oblique, 0.0, f64::INFINITY));
        assert!(b.meets(&Point3::new(-1.5, -1.5, 0.0), &oblique, 0.0, f64::INFINITY));
        // A point on the face plane, grazing: inside by the padding.
        assert!(b.meets(&Point3::new(1.0, 0.0, 10.0), &down, 0.0, f64::INFINITY));
    }
}
