//! Outputs that could not be written, kept instead of ending the scan: one file that cannot be
//! written (a full disk, a directory in its way, no permission) does not stop the others;
//! report.json lists each failed file with why (`outputs.failed`) and `scanhil scan` exits 3
//! naming them.
//!
//! The recordings are written while the loop runs: a [`RecordingFile`] remembers the first
//! error of its file and names the file in it, so a full disk stops the loop with a reason
//! that says which file, and the failure is listed with the others.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// Output files (names in the folder) that failed, with why.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct OutputFailures(BTreeMap<String, String>);

impl OutputFailures {
    /// `result` of writing `file`: its value, or `None` with the error kept (the first one
    /// for a file).
    pub fn attempt<T>(&mut self, file: &str, result: anyhow::Result<T>) -> Option<T> {
        match result {
            Ok(value) => Some(value),
            Err(error) => {
                self.add(file, scanhil_protocol::error_text::chain_text(&*error));
                None
            }
        }
    }

    /// Notes that `file` failed for `why` (a file's first failure is kept).
    pub fn add(&mut self, file: &str, why: String) {
        self.0.entry(file.to_owned()).or_insert(why);
    }

    /// The failures of `other` too.
    pub fn extend(&mut self, other: OutputFailures) {
        for (file, why) in other.0 {
            self.add(&file, why);
        }
    }

    /// True when every output was written.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Whether `file` failed.
    #[must_use]
    pub fn contains(&self, file: &str) -> bool {
        self.0.contains_key(file)
    }

    /// The failed files and why, by name.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &str)> {
        self.0
            .iter()
            .map(|(file, why)| (file.as_str(), why.as_str()))
    }
}

impl std::fmt::Display for OutputFailures {
    /// `file (why); file (why)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (i, (file, why)) in self.iter().enumerate() {
            let separator = if i == 0 { "" } else { "; " };
            write!(f, "{separator}{file} ({why})")?;
        }
        Ok(())
    }
}

/// A recording's file: its write errors name the file, and the first is kept for its
/// [`RecordingFailure`].
#[derive(Debug)]
pub struct RecordingFile {
    file: File,
    path: PathBuf,
    failure: Arc<OnceLock<String>>,
}

/// The first error of a [`RecordingFile`], readable after the file was handed to a link.
#[derive(Debug, Clone)]
pub struct RecordingFailure {
    /// The file's name in the output folder.
    pub name: &'static str,
    failure: Arc<OnceLock<String>>,
}

impl RecordingFailure {
    /// The first write error, if one happened.
    #[must_use]
    pub fn get(&self) -> Option<&str> {
        self.failure.get().map(String::as_str)
    }
}

impl RecordingFile {
    /// Creates `dir/name` (truncating it); returns the file and the handle of its failure.
    ///
    /// # Errors
    /// The OS error of creating it, naming the file.
    pub fn create(
        dir: &Path,
        name: &'static str,
    ) -> anyhow::Result<(RecordingFile, RecordingFailure)> {
        let path = dir.join(name);
        let file = File::create(&path)
            .map_err(|error| anyhow::anyhow!("cannot create {}: {error}", path.display()))?;
        let failure = Arc::new(OnceLock::new());
        Ok((
            RecordingFile {
                file,
                path,
                failure: failure.clone(),
            },
            RecordingFailure { name, failure },
        ))
    }

    fn failed(&self, error: std::io::Error) -> std::io::Error {
        let text = format!("writing {}: {error}", self.path.display());
        let _ = self.failure.set(text.clone());
        std::io::Error::new(error.kind(), text)
    }
}

impl Write for RecordingFile {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        self.file.write(bytes).map_err(|error| self.failed(error))
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush().map_err(|error| self.failed(error))
    }
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    use super::{OutputFailures, RecordingFile};

    #[test]
    fn a_full_disk_is_named_in_the_error_and_kept() {
        // /dev/full: every write fails with ENOSPC.
        let (mut file, failure) =
            RecordingFile::create(std::path::Path::new("/dev"), "full").expect("opening");
        let error = file.write_all(b"x").expect_err("the device is full");
        assert_eq!(error.kind(), std::io::ErrorKind::StorageFull);
        assert!(
            error.to_string().starts_with("writing /dev/full: "),
            "{error}"
        );
        assert_eq!(failure.get(), Some(error.to_string().as_str()));
        assert_eq!(failure.name, "full");
    }

    #[test]
    fn the_first_failure_of_a_file_is_kept_and_listed() {
        let mut failures = OutputFailures::default();
        assert_eq!(failures.attempt("a.png", anyhow::Ok(1)), Some(1));
        assert!(failures.is_empty());
        let none: Option<()> = failures.attempt("b.csv", Err(anyhow::anyhow!("first")));
        assert!(none.is_none());
        failures.add("b.csv", "second".into());
        failures.add("a.png", "later".into());
        assert_eq!(failures.to_string(), "a.png (later); b.csv (first)");
    }
}
