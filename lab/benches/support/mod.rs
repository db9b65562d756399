//! What the lab's bench binaries share: the workspace root, and where their JSON goes.

use std::path::{Path, PathBuf};

/// The workspace root (fixtures are found from it).
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Prints `json` and writes it to `target/<name>.json` (or under `CARGO_TARGET_DIR`).
pub fn publish(name: &str, json: &serde_json::Value) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(json)?;
    println!("{text}");
    let target =
        std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root().join("target"), PathBuf::from);
    std::fs::create_dir_all(&target)?;
    let out = target.join(format!("{name}.json"));
    std::fs::write(&out, &text)?;
    eprintln!("written to {}", out.display());
    Ok(())
}
