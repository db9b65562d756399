//! Where a design's plant comes from (`scanhil design --plant FILE`): eq. 4 as printed, a
//! controller file's nominal plant, or a scene file's mirror (the host reads the scene's JSON
//! itself: it links no emulator code). The file's kind is told by its keys: `law` a
//! controller, `parts` a scene.
//!
//! From a scene: eq. 4's parameters of each axis, and, with the `amplifier` part on, its
//! current loop's lag `1 / (2 pi bandwidth)` as extra delay (the first-order lag's phase to
//! first order in frequency; 16 us at 10 kHz).

use std::path::Path;

use anyhow::Context;
use serde_json::Value;

use crate::plant_model::PlantModel;
use crate::trajectory::SensingAxis;
use scanhil_scene::json_file;

/// The amplifier's bandwidth a scene gets when it does not state one, Hz (the emulator's
/// default: the paper's 10 kHz).
const DEFAULT_AMPLIFIER_HZ: f64 = 10_000.0;

/// A plant for each sensing axis, and where it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantSource {
    /// What the plant is (for reports).
    pub description: String,
    /// The alpha axis' plant.
    pub alpha: PlantModel,
    /// The beta axis' plant.
    pub beta: PlantModel,
}

impl PlantSource {
    /// Eq. 4 as printed, both axes.
    #[must_use]
    pub fn paper() -> PlantSource {
        PlantSource {
            description: "eq. 4 as printed".into(),
            alpha: PlantModel::default(),
            beta: PlantModel::default(),
        }
    }

    /// Reads a controller file's nominal plant or a scene's mirror.
    ///
    /// # Errors
    /// A file that does not read or parse, is neither kind, or has unusable values (named).
    pub fn load(path: &Path) -> anyhow::Result<PlantSource> {
        let text = json_file::read_text(path, "plant")?;
        let value: Value = json_file::parse(&text, path)?;
        let named = |what: &str| format!("{}: {what}", path.display());
        if value.get("law").is_some() {
            let plant: PlantModel = match value.get("plant") {
                Some(p) => {
                    serde_json::from_value(p.clone()).with_context(|| named("field `plant`"))?
                }
                None => PlantModel::default(),
            };
            return Ok(PlantSource {
                description: named("the controller's nominal plant"),
                alpha: plant,
                beta: plant,
            });
        }
        if let Some(parts) = value.get("parts") {
            let plant = scene_mirror(&value, parts).map_err(|(field, reason)| {
                anyhow::anyhow!("{}: field `{field}`: {reason}", path.display())
            })?;
            return Ok(PlantSource {
                description: named("the scene's mirror"),
                alpha: plant,
                beta: plant,
            });
        }
        anyhow::bail!(
            "{}: neither a controller file (`law`) nor a scene (`parts`)",
            path.display()
        )
    }

    /// One axis' plant.
    #[must_use]
    pub fn axis(&self, axis: SensingAxis) -> PlantModel {
        match axis {
            SensingAxis::Alpha => self.alpha,
            SensingAxis::Beta => self.beta,
        }
    }

    /// What the plant is.
    #[must_use]
    pub fn describe(&self) -> &str {
        &self.description
    }
}

/// Eq. 4 of a scene's `mirror` section (the paper's values where it is silent), with the
/// amplifier's lag as extra delay when the part is on.
fn scene_mirror(scene: &Value, parts: &Value) -> Result<PlantModel, (String, String)> {
    let mut plant = PlantModel::default();
    let number =
        |section: &Value, key: &str, field: String| -> Result<Option<f64>, (String, String)> {
            match section.get(key) {
                None => Ok(None),
                Some(v) => v
                    .as_f64()
                    .filter(|x| x.is_finite() && *x > 0.0)
                    .map(Some)
                    .ok_or((field, format!("{v} must be a positive number"))),
            }
        };
    if let Some(mirror) = scene.get("mirror") {
        for (key, slot) in [
            ("dc_gain", &mut plant.dc_gain),
            ("natural_freq_rad_s", &mut plant.natural_freq_rad_s),
            ("damping_ratio", &mut plant.damping_ratio),
        ] {
            if let Some(v) = number(mirror, key, format!("mirror.{key}"))? {
                *slot = v;
            }
        }
    }
    let has = |name: &str| {
        parts
            .as_array()
            .is_some_and(|list| list.iter().any(|p| p.as_str() == Some(name)))
    };
    if has("amplifier") {
        let bandwidth = match scene.get("amplifier") {
            Some(a) => number(a, "bandwidth_hz", "amplifier.bandwidth_hz".into())?,
            None => None,
        }
        .unwrap_or(DEFAULT_AMPLIFIER_HZ);
        plant.extra_delay_s = 1.0 / (std::f64::consts::TAU * bandwidth);
    }
    Ok(plant)
}
