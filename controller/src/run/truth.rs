//! The true surface of a scene, to score a reconstruction against: the surface height at a
//! point of the scanner's x-y plane, in the reconstruction's coordinates. (Adapter: the
//! emulator's scenes do not expose their surface yet, so no scene has a known truth here;
//! this is the one place to change when they do.)

use scanhil_emulator::scene::Scene;

/// A scene's true surface.
#[derive(Debug, Clone)]
pub struct TrueSurface {
    _scene_name: String,
}

impl TrueSurface {
    /// The scene's true surface, when it has one that can be queried.
    #[must_use]
    pub fn from_scene(_scene: &Scene) -> Option<TrueSurface> {
        None
    }

    /// The true z of the surface at `(x, y)`, in mm, if the surface is there.
    #[must_use]
    pub fn z_mm(&self, _x_mm: f64, _y_mm: f64) -> Option<f64> {
        None
    }
}
