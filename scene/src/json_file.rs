//! JSON files (the host's rig descriptions, scenarios and controller settings, the emulator's
//! scenes and their true surfaces, studies): read and parsed with errors that name the file and, for a parse error, its line
//! and column. Each file kind checks its own fields after this and adds its own errors.

use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;

/// Why a JSON file could not be read or parsed.
#[derive(Debug, thiserror::Error)]
pub enum JsonFileError {
    /// The file could not be read.
    #[error("cannot read {kind} {path}: {source}")]
    Io {
        /// What the file is ("rig", "scenario", "controller settings", "scene").
        kind: &'static str,
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The JSON did not parse or did not match the format.
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What serde said.
        message: String,
    },
}

/// Reads the text of the `kind` file at `path`.
///
/// # Errors
/// [`JsonFileError::Io`].
pub fn read_text(path: &Path, kind: &'static str) -> Result<String, JsonFileError> {
    std::fs::read_to_string(path).map_err(|source| JsonFileError::Io {
        kind,
        path: path.to_owned(),
        source,
    })
}

/// Parses `text` as a `T`; `origin` names it in errors.
///
/// # Errors
/// [`JsonFileError::Parse`] with the line and column.
pub fn parse<T: DeserializeOwned>(text: &str, origin: &Path) -> Result<T, JsonFileError> {
    serde_json::from_str(text).map_err(|error| JsonFileError::Parse {
        path: origin.to_owned(),
        line: error.line(),
        column: error.column(),
        message: error.to_string(),
    })
}

/// Reads and parses the `kind` file at `path` as a `T`: [`read_text`], then [`parse`].
///
/// # Errors
/// [`JsonFileError`] naming the file (and the line and column of a parse error).
pub fn read<T: DeserializeOwned>(path: &Path, kind: &'static str) -> Result<T, JsonFileError> {
    parse(&read_text(path, kind)?, path)
}
