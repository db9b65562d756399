//! The true surface of a scene, to score a reconstruction against: the emulator's own
//! [`Surface`] (the ground truth its optics trace against), queried at points of the
//! scanner's x-y plane, in the reconstruction's coordinates (z < 0 below the sensor).

use std::path::Path;

use scanhil_emulator::scene::Scene;
use scanhil_emulator::surface::Surface;

/// A scene's true surface.
#[derive(Debug, Clone)]
pub struct TrueSurface {
    surface: Surface,
}

impl TrueSurface {
    /// The scene's true surface, when it has one (a scene without optics has none).
    ///
    /// # Errors
    /// The surface's own error (a height map file that cannot be read), as text.
    pub fn from_scene(scene: &Scene) -> Result<Option<TrueSurface>, String> {
        let Some(config) = &scene.surface else {
            return Ok(None);
        };
        let base_dir = scene.base_dir().unwrap_or(Path::new("."));
        Surface::from_config(config, base_dir)
            .map(|surface| Some(TrueSurface { surface }))
            .map_err(|error| error.to_string())
    }

    /// The true z of the surface at `(x, y)`, in mm, if the surface is there.
    #[must_use]
    pub fn z_mm(&self, x_mm: f64, y_mm: f64) -> Option<f64> {
        self.surface.height_at(x_mm, y_mm)
    }
}
