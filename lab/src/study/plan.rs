//! The study file and its variants written out as scenario files.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use scanhil_controller::run::scenario::OutputsConfig;
use scanhil_scene::json_file;
use serde::Deserialize;
use serde_json::Value;

/// The most variants one study may expand to: each is a folder of files and a scan.
pub const MAX_VARIANTS: usize = 10_000;

/// The most runs of each variant a precision study may ask for (`repeats`).
pub const MAX_REPEATS: usize = 100;

/// The documents a study key can address.
const DOCUMENTS: [&str; 4] = ["scenario", "scene", "controller", "rig"];
/// The scenario fields that hold file paths (relative to the file that names them).
const PATH_FIELDS: [&str; 4] = ["rig", "scene", "truth", "controller"];

/// A loaded study file.
#[derive(Debug, Clone)]
pub struct Study {
    /// Where it was loaded from.
    pub path: PathBuf,
    /// Short name.
    pub name: String,
    /// Free text.
    pub description: String,
    /// The base scenario file.
    pub scenario: PathBuf,
    /// What every variant leaves out of its outputs (`None`: as the base scenario says): a
    /// study that only wants its table leaves out the recordings and the figures. A `false`
    /// here leaves out; a `true` keeps what the base scenario writes.
    pub outputs: Option<OutputsConfig>,
    /// One map of `key -> value` per variant, in order.
    pub variants: Vec<BTreeMap<String, Value>>,
    /// How many times `scanhil-study precision` runs each variant (1 to [`MAX_REPEATS`],
    /// default 1), so each run time carries its spread; `run` runs each variant once.
    pub repeats: usize,
    /// The index (from 0, in variant order) of the exact reference that
    /// `scanhil-study precision` measures the other variants against.
    pub reference: Option<usize>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct StudyFile {
    name: String,
    #[serde(default)]
    description: String,
    scenario: PathBuf,
    #[serde(default)]
    grid: Option<BTreeMap<String, Vec<Value>>>,
    #[serde(default)]
    list: Option<Vec<BTreeMap<String, Value>>>,
    #[serde(default)]
    outputs: Option<OutputsConfig>,
    #[serde(default)]
    repeats: Option<usize>,
    #[serde(default)]
    reference: Option<usize>,
}

impl Study {
    /// Reads a study file and expands its variants.
    ///
    /// # Errors
    /// A file that cannot be read or parsed (file, line, column), a key that names no
    /// document, an empty value list, both or neither of `grid` and `list`, more than
    /// [`MAX_VARIANTS`] variants, `repeats` outside 1 to [`MAX_REPEATS`], a `reference` that
    /// is not the index of a variant.
    pub fn load(path: &Path) -> anyhow::Result<Study> {
        Study::from_json_str(&json_file::read_text(path, "study")?, path)
    }

    /// Parses a study and expands its variants; `path` names it in errors and anchors its
    /// relative scenario path.
    ///
    /// # Errors
    /// As [`Study::load`], but for reading the file.
    pub fn from_json_str(text: &str, path: &Path) -> anyhow::Result<Study> {
        let file: StudyFile = json_file::parse(text, path)?;
        let variants = match (file.grid, file.list) {
            (Some(grid), None) => expand_grid(&grid).with_context(|| path.display().to_string())?,
            (None, Some(list)) => list,
            _ => bail!("{}: give exactly one of `grid` and `list`", path.display()),
        };
        if variants.is_empty() {
            bail!("{}: the study has no variant", path.display());
        }
        for key in variants.iter().flat_map(BTreeMap::keys) {
            check_key(key).with_context(|| path.display().to_string())?;
        }
        let repeats = file.repeats.unwrap_or(1);
        if !(1..=MAX_REPEATS).contains(&repeats) {
            bail!(
                "{}: `repeats` is {repeats}; expected 1 to {MAX_REPEATS}",
                path.display()
            );
        }
        if let Some(reference) = file.reference.filter(|&r| r >= variants.len()) {
            bail!(
                "{}: `reference` is {reference}, but the variants are numbered 0 to {} (the \
                 index of the reference's entry, from 0)",
                path.display(),
                variants.len() - 1
            );
        }
        let base = path.parent().unwrap_or(Path::new("."));
        Ok(Study {
            path: path.to_owned(),
            name: file.name,
            description: file.description,
            scenario: base.join(file.scenario),
            outputs: file.outputs,
            variants,
            repeats,
            reference: file.reference,
        })
    }

    /// Leaves out every variant's recordings and figures as well, where `recordings` or
    /// `figures` says so (`scanhil-study --no-recordings`, `--no-figures`).
    pub fn leave_out(&mut self, recordings: bool, figures: bool) {
        let outputs = self.outputs.unwrap_or_default();
        self.outputs = Some(OutputsConfig {
            recordings: outputs.recordings && !recordings,
            figures: outputs.figures && !figures,
        });
    }

    /// The keys any variant sets, in order: the table's parameter columns.
    #[must_use]
    pub fn keys(&self) -> Vec<String> {
        let mut keys: Vec<String> = self
            .variants
            .iter()
            .flat_map(|v| v.keys().cloned())
            .collect();
        keys.sort();
        keys.dedup();
        keys
    }

    /// Writes every variant's files under `out_dir/variants/NNNN/` and returns the scenario
    /// files, in order.
    ///
    /// # Errors
    /// A base file that cannot be read, a key whose path runs through a value that is not an
    /// object, a file that cannot be written.
    pub fn write_variants(&self, out_dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
        let base = BaseDocuments::load(&self.scenario)?;
        let study_dir = self.path.parent().unwrap_or(Path::new("."));
        self.variants
            .iter()
            .enumerate()
            .map(|(i, values)| {
                let dir = variant_dir(out_dir, i);
                std::fs::create_dir_all(&dir)
                    .with_context(|| format!("creating {}", dir.display()))?;
                base.write_variant(values, self.outputs, study_dir, &dir)
                    .with_context(|| format!("variant {} ({})", i + 1, describe(values)))
            })
            .collect()
    }
}

/// The folder of variant `index` (0-based): `variants/0001` for the first.
#[must_use]
pub fn variant_dir(out_dir: &Path, index: usize) -> PathBuf {
    out_dir.join("variants").join(format!("{:04}", index + 1))
}

/// `key=value, ...` for messages.
#[must_use]
pub fn describe(values: &BTreeMap<String, Value>) -> String {
    values
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn check_key(key: &str) -> anyhow::Result<()> {
    let (document, field) = key.split_once('.').unwrap_or((key, ""));
    if !DOCUMENTS.contains(&document) || field.is_empty() || field.split('.').any(str::is_empty) {
        bail!(
            "key `{key}`: expected `<document>.<field>[.<field>...]` with a document of \
             {DOCUMENTS:?}"
        );
    }
    Ok(())
}

fn expand_grid(
    grid: &BTreeMap<String, Vec<Value>>,
) -> anyhow::Result<Vec<BTreeMap<String, Value>>> {
    let mut count: usize = 1;
    for (key, values) in grid {
        if values.is_empty() {
            bail!("grid key `{key}` has no value");
        }
        count = count.saturating_mul(values.len());
    }
    if count > MAX_VARIANTS {
        bail!("the grid expands to {count} variants, more than {MAX_VARIANTS}");
    }
    let mut variants = vec![BTreeMap::new()];
    for (key, values) in grid {
        variants = variants
            .into_iter()
            .flat_map(|variant| {
                values.iter().map(move |value| {
                    let mut next = variant.clone();
                    next.insert(key.clone(), value.clone());
                    next
                })
            })
            .collect();
    }
    Ok(variants)
}

/// The base scenario and the documents it names, as JSON, with its paths made absolute.
struct BaseDocuments {
    scenario: Value,
    scenario_dir: PathBuf,
}

impl BaseDocuments {
    fn load(path: &Path) -> anyhow::Result<BaseDocuments> {
        let scenario = json_file::read(path, "scenario")?;
        Ok(BaseDocuments {
            scenario,
            scenario_dir: path.parent().unwrap_or(Path::new(".")).to_owned(),
        })
    }

    /// Writes `scenario.json` (and the documents the variant changes) into `dir`.
    fn write_variant(
        &self,
        values: &BTreeMap<String, Value>,
        outputs: Option<OutputsConfig>,
        study_dir: &Path,
        dir: &Path,
    ) -> anyhow::Result<PathBuf> {
        let mut scenario = self.scenario.clone();
        for field in PATH_FIELDS {
            if let Some(Value::String(relative)) = scenario.get(field) {
                let absolute = absolute(&self.scenario_dir.join(relative));
                scenario[field] = Value::String(absolute.display().to_string());
            }
        }
        // The study's outputs leave out (never turn on) what every variant writes; the
        // variant's own fields come after.
        if let Some(outputs) = outputs {
            for (field, kept) in [
                ("outputs.recordings", outputs.recordings),
                ("outputs.figures", outputs.figures),
            ] {
                if !kept {
                    set(&mut scenario, field, Value::Bool(false))?;
                }
            }
        }
        // Scenario fields first: a variant may point the scenario at another scene, then
        // change that scene.
        for (key, value) in values {
            if let Some(field) = key.strip_prefix("scenario.") {
                let value = match (PATH_FIELDS.contains(&field), value) {
                    (true, Value::String(relative)) => {
                        Value::String(absolute(&study_dir.join(relative)).display().to_string())
                    }
                    _ => value.clone(),
                };
                set(&mut scenario, field, value)?;
            }
        }
        for (document, kind) in [
            ("scene", "scene"),
            ("controller", "controller settings"),
            ("rig", "rig"),
        ] {
            let prefix = format!("{document}.");
            let changes: Vec<(&str, &Value)> = values
                .iter()
                .filter_map(|(k, v)| k.strip_prefix(&prefix).map(|field| (field, v)))
                .collect();
            if changes.is_empty() {
                continue;
            }
            let Some(Value::String(source)) = scenario.get(document) else {
                bail!("the scenario names no `{document}` to change");
            };
            let source = PathBuf::from(source);
            let mut json: Value = json_file::read(&source, kind)?;
            if document == "scene" {
                absolute_height_map(&mut json, source.parent().unwrap_or(Path::new(".")));
            }
            for (field, value) in changes {
                set(&mut json, field, value.clone())?;
            }
            let target = dir.join(format!("{document}.json"));
            write_json(&target, &json)?;
            // Absolute: the scenario resolves a relative path against its own folder, so a
            // study written under a relative `--out` would name `out/.../out/.../scene.json`.
            scenario[document] = Value::String(absolute(&target).display().to_string());
        }
        let target = dir.join("scenario.json");
        write_json(&target, &scenario)?;
        Ok(target)
    }
}

/// A height-map surface names its file relative to the scene; a scene written elsewhere
/// names it absolutely.
fn absolute_height_map(scene: &mut Value, scene_dir: &Path) {
    if let Some(Value::String(file)) = scene.pointer("/surface/file") {
        let absolute = absolute(&scene_dir.join(file)).display().to_string();
        scene["surface"]["file"] = Value::String(absolute);
    }
}

/// Sets the dotted `field` in `document`, creating objects on the way.
fn set(document: &mut Value, field: &str, value: Value) -> anyhow::Result<()> {
    let mut node = document;
    let parts: Vec<&str> = field.split('.').collect();
    for (depth, part) in parts.iter().enumerate() {
        let Value::Object(map) = node else {
            bail!(
                "`{}` is not an object, so `{field}` cannot be set",
                parts[..depth].join(".")
            );
        };
        if depth + 1 == parts.len() {
            map.insert((*part).to_owned(), value);
            return Ok(());
        }
        node = map
            .entry((*part).to_owned())
            .or_insert_with(|| Value::Object(serde_json::Map::new()));
    }
    Ok(())
}

/// The path made absolute, with `..` resolved when the file exists.
fn absolute(path: &Path) -> PathBuf {
    std::fs::canonicalize(path)
        .or_else(|_| std::path::absolute(path))
        .unwrap_or_else(|_| path.to_owned())
}

fn write_json(path: &Path, value: &Value) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(value).context("formatting JSON")? + "\n";
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(pairs: &[(&str, Vec<Value>)]) -> BTreeMap<String, Vec<Value>> {
        pairs
            .iter()
            .map(|(k, v)| ((*k).to_owned(), v.clone()))
            .collect()
    }

    #[test]
    fn a_grid_expands_to_every_combination() {
        let variants = expand_grid(&grid(&[
            ("scenario.seed", vec![1.into(), 2.into(), 3.into()]),
            ("scene.sensor.noise_rms_um", vec![0.0.into(), 1.5.into()]),
        ]))
        .unwrap();
        assert_eq!(variants.len(), 6);
        let mut seen: Vec<String> = variants.iter().map(describe).collect();
        seen.sort();
        seen.dedup();
        assert_eq!(seen.len(), 6, "{seen:?}");
    }

    #[test]
    fn an_oversized_or_empty_grid_is_refused() {
        let many: Vec<Value> = (0..101).map(Value::from).collect();
        let error = expand_grid(&grid(&[
            ("scenario.seed", many.clone()),
            ("scene.seed", many),
        ]))
        .unwrap_err();
        assert!(error.to_string().contains("10201 variants"), "{error}");
        let error = expand_grid(&grid(&[("scenario.seed", vec![])])).unwrap_err();
        assert!(error.to_string().contains("scenario.seed"), "{error}");
    }

    #[test]
    fn keys_must_name_a_document_and_a_field() {
        for key in ["seed", "plant.seed", "scene.", "scene..x"] {
            assert!(check_key(key).is_err(), "{key}");
        }
        assert!(check_key("controller.discretisation.method").is_ok());
    }

    #[test]
    fn set_creates_objects_and_refuses_to_cross_a_value() {
        let mut doc = serde_json::json!({"sensor": {"noise_rms_um": 1.5}, "seed": 3});
        set(&mut doc, "sensor.noise_rms_um", 0.0.into()).unwrap();
        set(&mut doc, "optics.spot.samples", 1.into()).unwrap();
        assert_eq!(doc["sensor"]["noise_rms_um"], 0.0);
        assert_eq!(doc["optics"]["spot"]["samples"], 1);
        let error = set(&mut doc, "seed.x", 1.into()).unwrap_err();
        assert!(
            error.to_string().contains("`seed` is not an object"),
            "{error}"
        );
    }
}
