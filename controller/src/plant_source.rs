//! Where a design's plant comes from (`scanhil design --plant FILE`): eq. 4 as printed, a
//! controller file's nominal plant, or a scene file's mirror (the host reads the scene's JSON
//! itself: it links no emulator code). The file's kind is told by its keys: `law` a
//! controller, `parts` a scene.
//!
//! From a scene: eq. 4's parameters of each axis (the `mirror` section's common values, then
//! the axis' own `mirror.alpha` / `mirror.beta` section, `y` / `x` accepted, as the emulator
//! resolves them), its delay beyond one of the scene's periods as extra delay (the emulator
//! delays the measured angle by it), and, with the `amplifier` part on, its current loop's lag
//! `1 / (2 pi bandwidth)` as extra delay too (the first-order lag's phase to first order in
//! frequency; 16 us at 10 kHz).

use std::path::Path;

use anyhow::Context;
use serde_json::Value;

use crate::plant_model::PlantModel;
use crate::trajectory::SensingAxis;
use scanhil_scene::json_file;

/// The amplifier's bandwidth a scene gets when it does not state one, Hz (the emulator's
/// default: the paper's 10 kHz).
const DEFAULT_AMPLIFIER_HZ: f64 = 10_000.0;

/// The control rate a scene has when it states none, Hz (the emulator's: the paper's 20 kHz).
const DEFAULT_CONTROL_RATE_HZ: f64 = 20_000.0;

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
            let plant = |axis| {
                scene_mirror(&value, parts, axis).map_err(|(field, reason)| {
                    anyhow::anyhow!("{}: field `{field}`: {reason}", path.display())
                })
            };
            return Ok(PlantSource {
                description: named("the scene's mirror"),
                alpha: plant(SensingAxis::Alpha)?,
                beta: plant(SensingAxis::Beta)?,
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

/// Eq. 4 of `axis` in a scene's `mirror` section (the paper's values where it is silent), with
/// its delay beyond one period, and the amplifier's lag when the part is on, as extra delay.
fn scene_mirror(
    scene: &Value,
    parts: &Value,
    axis: SensingAxis,
) -> Result<PlantModel, (String, String)> {
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
    let mut delay_s = None;
    if let Some(mirror) = scene.get("mirror") {
        let alias = match axis {
            SensingAxis::Alpha => "y",
            SensingAxis::Beta => "x",
        };
        let own = [axis.name(), alias]
            .into_iter()
            .find_map(|name| mirror.get(name).map(|section| (name, section)));
        let sections = std::iter::once((String::from("mirror."), mirror))
            .chain(own.map(|(name, section)| (format!("mirror.{name}."), section)));
        for (prefix, section) in sections {
            for (key, slot) in [
                ("dc_gain", &mut plant.dc_gain),
                ("natural_freq_rad_s", &mut plant.natural_freq_rad_s),
                ("damping_ratio", &mut plant.damping_ratio),
            ] {
                if let Some(v) = number(section, key, format!("{prefix}{key}"))? {
                    *slot = v;
                }
            }
            if let Some(v) = number(section, "delay_s", format!("{prefix}delay_s"))? {
                delay_s = Some(v);
            }
        }
    }
    if let Some(delay_s) = delay_s {
        let rate_hz = scene
            .get("control_rate_hz")
            .and_then(Value::as_f64)
            .unwrap_or(DEFAULT_CONTROL_RATE_HZ);
        plant.extra_delay_s = (delay_s - 1.0 / rate_hz).max(0.0);
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
        plant.extra_delay_s += 1.0 / (std::f64::consts::TAU * bandwidth);
    }
    Ok(plant)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(scene: &serde_json::Value) -> anyhow::Result<PlantSource> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scene.json");
        std::fs::write(&path, scene.to_string()).unwrap();
        PlantSource::load(&path)
    }

    #[test]
    fn each_axis_of_a_scene_is_its_own_section_over_the_common_values() {
        let scene = serde_json::json!({
            "name": "s", "parts": ["axes"], "control_rate_hz": 10000.0,
            "mirror": {"dc_gain": 9.8, "damping_ratio": 0.05,
                       "alpha": {"natural_freq_rad_s": 160.0, "delay_s": 1.5e-4},
                       "x": {"dc_gain": 12.6}},
        });
        let source = load(&scene).unwrap();
        let alpha = source.axis(SensingAxis::Alpha);
        assert_eq!(
            (alpha.dc_gain, alpha.natural_freq_rad_s, alpha.damping_ratio),
            (9.8, 160.0, 0.05)
        );
        assert!((alpha.extra_delay_s - 0.5e-4).abs() < 1e-15, "{alpha:?}");
        let beta = source.axis(SensingAxis::Beta);
        assert_eq!(
            (beta.dc_gain, beta.natural_freq_rad_s, beta.damping_ratio),
            (12.6, 140.68, 0.05)
        );
        assert_eq!(beta.extra_delay_s, 0.0);
    }

    #[test]
    fn an_axis_value_that_cannot_be_is_named_with_its_axis() {
        let scene = serde_json::json!({
            "name": "s", "parts": ["axes", "amplifier"],
            "mirror": {"beta": {"damping_ratio": -1.0}},
        });
        let error = load(&scene).unwrap_err().to_string();
        assert!(
            error.ends_with("field `mirror.beta.damping_ratio`: -1.0 must be a positive number"),
            "{error}"
        );
        // The amplifier's lag adds to the axis' own delay.
        let scene = serde_json::json!({
            "name": "s", "parts": ["axes", "amplifier"], "amplifier": {"bandwidth_hz": 1000.0},
            "mirror": {"delay_s": 1e-4},
        });
        let alpha = load(&scene).unwrap().axis(SensingAxis::Alpha);
        let want = 0.5e-4 + 1.0 / (std::f64::consts::TAU * 1000.0);
        assert!((alpha.extra_delay_s - want).abs() < 1e-15, "{alpha:?}");
    }
}
