//! A scene file's true surface: the `surface` section of `fixtures/scenes/*.json`, read
//! without the plant sections (dynamics, optics, sensor) that only the emulator interprets.
//! Relative height-map paths resolve against the scene file's directory, as in the emulator.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::json_file::{self, JsonFileError};
use crate::surface::{Surface, SurfaceConfig, SurfaceError};

/// The true surface of a scene, to score a reconstruction against.
#[derive(Debug, Clone, PartialEq)]
pub struct TrueScene {
    /// The scene's name.
    pub name: String,
    /// Where it was read from.
    pub path: PathBuf,
    surface: Surface,
}

/// Why a scene's true surface could not be read.
#[derive(Debug, thiserror::Error)]
pub enum TruthError {
    /// The file could not be read or parsed (file, line and column).
    #[error(transparent)]
    File(#[from] JsonFileError),
    /// The scene has no `surface` section.
    #[error("{path}: the scene has no `surface` to score against")]
    NoSurface {
        /// The scene file.
        path: PathBuf,
    },
    /// The surface could not be built (a height map that cannot be read).
    #[error("{path}: surface: {source}")]
    Surface {
        /// The scene file.
        path: PathBuf,
        /// The surface's own error.
        source: SurfaceError,
    },
}

/// The parts of a scene file the truth needs; every other section is left to the emulator.
#[derive(Deserialize)]
struct SceneTruthFile {
    name: String,
    #[serde(default)]
    surface: Option<SurfaceConfig>,
}

impl TrueScene {
    /// Reads the true surface of the scene file at `path`.
    ///
    /// # Errors
    /// [`TruthError`] naming the file (and line and column for a parse error).
    pub fn from_scene_file(path: &Path) -> Result<TrueScene, TruthError> {
        TrueScene::from_json_str(&json_file::read_text(path, "scene")?, path)
    }

    /// Reads the true surface of scene JSON; `path` names it in errors and anchors relative
    /// height-map paths.
    ///
    /// # Errors
    /// As [`TrueScene::from_scene_file`], but for reading the file.
    pub fn from_json_str(text: &str, path: &Path) -> Result<TrueScene, TruthError> {
        let file: SceneTruthFile = json_file::parse(text, path)?;
        let config = file.surface.ok_or_else(|| TruthError::NoSurface {
            path: path.to_owned(),
        })?;
        let base_dir = path.parent().unwrap_or(Path::new("."));
        let surface =
            Surface::from_config(&config, base_dir).map_err(|source| TruthError::Surface {
                path: path.to_owned(),
                source,
            })?;
        Ok(TrueScene {
            name: file.name,
            path: path.to_owned(),
            surface,
        })
    }

    /// A true scene around an already built surface.
    #[must_use]
    pub fn new(name: String, path: PathBuf, surface: Surface) -> TrueScene {
        TrueScene {
            name,
            path,
            surface,
        }
    }

    /// The true z of the surface at `(x, y)` in the scanner's coordinates, mm, where the
    /// surface is there.
    #[must_use]
    pub fn z_mm(&self, x_mm: f64, y_mm: f64) -> Option<f64> {
        self.surface.height_at(x_mm, y_mm)
    }

    /// The surface.
    #[must_use]
    pub fn surface(&self) -> &Surface {
        &self.surface
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixture(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../fixtures/scenes")
            .join(name)
    }

    #[test]
    fn the_duplo_scene_has_its_stud_above_the_brick_top() {
        let truth = TrueScene::from_scene_file(&fixture("duplo-2x4-130mm.json")).unwrap();
        // The brick's centre (-8, -18) lies between four studs; a stud's ring 4 mm off its axis.
        let top = truth.z_mm(-8.0, -18.0).unwrap();
        let [x, y] = crate::surface::duplo::stud_centers()[0];
        let stud = truth.z_mm(-8.0 + x + 4.0, -18.0 + y).unwrap();
        assert!((top + 130.0).abs() < 1e-9, "top {top}");
        assert!((stud - top - 4.663).abs() < 1e-9, "top {top}, stud {stud}");
    }

    #[test]
    fn a_scene_with_a_height_map_resolves_it_beside_the_scene_file() {
        let truth = TrueScene::from_scene_file(&fixture("height-map-csv.json")).unwrap();
        assert!(truth.z_mm(0.0, -10.0).is_some());
    }

    #[test]
    fn a_scene_without_a_surface_is_refused_by_name() {
        let error = TrueScene::from_scene_file(&fixture("loop-fast.json")).unwrap_err();
        assert!(matches!(error, TruthError::NoSurface { .. }), "{error}");
        assert!(error.to_string().contains("loop-fast.json"));
    }

    #[test]
    fn a_bad_surface_names_file_line_and_column() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.json");
        std::fs::write(
            &path,
            "{\n \"name\": \"x\",\n \"surface\": {\"kind\": \"cube\"}\n}",
        )
        .unwrap();
        let error = TrueScene::from_scene_file(&path).unwrap_err().to_string();
        assert!(error.contains("bad.json:3:"), "{error}");
    }
}
