//! The scan's output folder, claimed for one scan at a time: a lock file held for the whole
//! scan (`.scanhil.lock`, an exclusive `flock`), so a second scan into the same folder is
//! refused instead of splicing its recordings into the first's; and the files an earlier scan
//! wrote there are removed first, so a re-scan never leaves stale outputs beside a new report.
//! Other files in the folder are left alone, and so are a symlink in an output's place (the
//! user sent that output elsewhere, another disk or `/dev/null`: written through when the scan
//! writes it) and a directory in an output's way (said on stderr; that output then fails
//! alone and report.json lists it, [`super::output_failures`]).

use std::fs::File;
use std::path::{Path, PathBuf};

use anyhow::Context;
use nix::fcntl::{Flock, FlockArg};

use super::output::{FSM_LOG, REPORT, SENSOR_CAPTURE, TRACKING_SVG};
use crate::imaging::pipeline::IMAGING_OUTPUTS;

/// The lock file's name inside the folder.
pub const LOCK_FILE: &str = ".scanhil.lock";

/// The files a scan writes into its folder besides the imaging's
/// ([`IMAGING_OUTPUTS`]).
const RUN_FILES: [&str; 4] = [REPORT, FSM_LOG, SENSOR_CAPTURE, TRACKING_SVG];

/// Every file a scan writes into its folder.
fn scan_files() -> impl Iterator<Item = &'static str> {
    RUN_FILES.into_iter().chain(IMAGING_OUTPUTS)
}

/// A claimed output folder; the claim ends when this is dropped.
#[derive(Debug)]
pub struct OutputFolder {
    path: PathBuf,
    _lock: Flock<File>,
}

impl OutputFolder {
    /// Creates `path` if needed, locks it for this scan and removes an earlier scan's files.
    ///
    /// # Errors
    /// A folder that cannot be created, a lock held by another scan (named with its process
    /// id), a stale file that cannot be removed.
    pub fn claim(path: &Path) -> anyhow::Result<OutputFolder> {
        std::fs::create_dir_all(path).with_context(|| format!("creating {}", path.display()))?;
        let lock_path = path.join(LOCK_FILE);
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .read(true)
            .write(true)
            .open(&lock_path)
            .with_context(|| format!("opening {}", lock_path.display()))?;
        let mut lock =
            Flock::lock(file, FlockArg::LockExclusiveNonblock).map_err(|(file, _)| {
                let holder = std::io::read_to_string(&file).unwrap_or_default();
                anyhow::anyhow!(
                    "{} is the output folder of another scan still running ({}); give another \
                 --out",
                    path.display(),
                    holder.trim()
                )
            })?;
        use std::io::{Seek, Write};
        lock.set_len(0)
            .and_then(|()| lock.rewind())
            .and_then(|_| write!(lock, "process {}", std::process::id()))
            .with_context(|| format!("writing {}", lock_path.display()))?;
        for name in scan_files() {
            // What a scan killed mid-write left under its temporary name.
            let partial = scanhil_protocol::whole_file::partial_path(&path.join(name));
            if partial.is_file() {
                std::fs::remove_file(&partial)
                    .with_context(|| format!("removing {}", partial.display()))?;
            }
            let stale = path.join(name);
            let Ok(metadata) = std::fs::symlink_metadata(&stale) else {
                continue;
            };
            if metadata.file_type().is_symlink() {
                // The user sent this output elsewhere (another disk, /dev/null): kept.
                continue;
            }
            if metadata.is_dir() {
                eprintln!(
                    "warning: {} is a directory in the way of output {name}: that output will \
                     not be written",
                    stale.display()
                );
                continue;
            }
            std::fs::remove_file(&stale)
                .with_context(|| format!("removing the earlier scan's {}", stale.display()))?;
        }
        Ok(OutputFolder {
            path: path.to_owned(),
            _lock: lock,
        })
    }

    /// The folder.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }
}
