//! Files written whole or not at all: an output is written under a temporary name beside it
//! (`.STEM.partial.EXT`, the same file system) and renamed over its name only once it was
//! written and flushed, so a full disk or a process killed mid-write never leaves a truncated
//! file under the output's name that looks whole. A symlink or a special file in the output's place
//! (the user sent it to another disk, to `/dev/null`) is written through instead, as before:
//! renaming over it would replace the user's link.

use std::io;
use std::path::{Path, PathBuf};

/// The temporary name `path` is written under, in the same folder: `.STEM.partial.EXT`
/// (the extension kept last, as the plotting and image writers choose their format by it),
/// `.NAME.partial` without an extension.
#[must_use]
pub fn partial_path(path: &Path) -> PathBuf {
    let part = |p: Option<&std::ffi::OsStr>| p.map(|s| s.to_string_lossy().into_owned());
    let name = match (part(path.file_stem()), part(path.extension())) {
        (Some(stem), Some(extension)) => format!(".{stem}.partial.{extension}"),
        (stem, _) => format!(".{}.partial", stem.unwrap_or_default()),
    };
    path.with_file_name(name)
}

/// Writes `path` with `write`, which is given the path to write to: the temporary name,
/// renamed over `path` when `write` succeeds and removed when it fails; `path` itself when a
/// symlink or anything but a regular file is in its place. `rename_error` turns a failed
/// rename into `write`'s error type.
///
/// # Errors
/// `write`'s error, or the rename's through `rename_error`.
pub fn write_whole<T, E>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<T, E>,
    rename_error: impl FnOnce(io::Error) -> E,
) -> Result<T, E> {
    let in_place = std::fs::symlink_metadata(path).is_ok_and(|m| !m.file_type().is_file());
    if in_place {
        return write(path);
    }
    let partial = partial_path(path);
    let result = write(&partial).and_then(|value| {
        std::fs::rename(&partial, path)
            .map(|()| value)
            .map_err(rename_error)
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&partial);
    }
    result
}

/// [`std::fs::write`] through [`write_whole`].
///
/// # Errors
/// The OS error of writing or renaming.
pub fn write_file(path: &Path, contents: impl AsRef<[u8]>) -> io::Result<()> {
    write_whole(path, |partial| std::fs::write(partial, contents), |e| e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_appears_whole_or_not_at_all() {
        let dir = tempfile::tempdir().expect("a temporary folder");
        let path = dir.path().join("report.json");
        write_file(&path, "first\n").expect("written");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "first\n");
        // A write that fails half-way leaves the earlier file and no partial one.
        let failed: io::Result<()> = write_whole(
            &path,
            |partial| {
                std::fs::write(partial, "trunc")?;
                Err(io::Error::from_raw_os_error(28))
            },
            |e| e,
        );
        assert_eq!(failed.unwrap_err().raw_os_error(), Some(28));
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "first\n");
        assert!(!partial_path(&path).exists());
        assert_eq!(partial_path(&path), dir.path().join(".report.partial.json"));
        assert_eq!(
            partial_path(Path::new("d/fsm")),
            Path::new("d/.fsm.partial")
        );
    }

    #[test]
    fn a_symlink_in_the_outputs_place_is_written_through() {
        let dir = tempfile::tempdir().expect("a temporary folder");
        let target = dir.path().join("elsewhere.json");
        let path = dir.path().join("report.json");
        std::os::unix::fs::symlink(&target, &path).expect("a symlink");
        write_file(&path, "through\n").expect("written");
        assert!(
            std::fs::symlink_metadata(&path)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "through\n");
        // /dev/full in its place: the error is the write's, the link stays.
        let full = dir.path().join("full.json");
        std::os::unix::fs::symlink("/dev/full", &full).expect("a symlink");
        assert_eq!(write_file(&full, "x").unwrap_err().raw_os_error(), Some(28));
        assert!(
            std::fs::symlink_metadata(&full)
                .unwrap()
                .file_type()
                .is_symlink()
        );
    }
}
