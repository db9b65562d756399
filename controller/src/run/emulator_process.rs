//! Starting `scanhil-emulator serve` as a separate process for the emulated nodes, and making
//! sure it goes away with the run.
//!
//! The emulator binary is found, in this order: the path given on the command line
//! (`--emulator`), the `SCANHIL_EMULATOR` environment variable, then `scanhil-emulator` next to
//! the running `scanhil` executable (the same cargo target directory).

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};

/// The environment variable that names the emulator binary.
pub const EMULATOR_ENV: &str = "SCANHIL_EMULATOR";

/// The emulator binary's file name.
pub const EMULATOR_BIN: &str = "scanhil-emulator";

/// Why the emulator could not be started.
#[derive(Debug, thiserror::Error)]
pub enum EmulatorError {
    /// No binary at the place looked at.
    #[error(
        "no emulator binary at {path} (from {source_of_path}); build it with \
         `cargo build -p scanhil-emulator`, or name it with --emulator or ${EMULATOR_ENV}"
    )]
    NotFound {
        /// Where it was looked for.
        path: PathBuf,
        /// Which rule gave that path.
        source_of_path: &'static str,
    },
    /// The process could not be started.
    #[error("cannot start {path}: {source}")]
    Spawn {
        /// The binary.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
}

/// Finds the emulator binary (see the module doc for the order).
///
/// # Errors
/// [`EmulatorError::NotFound`] naming the path tried and the rule that gave it.
pub fn locate_emulator(explicit: Option<&Path>) -> Result<PathBuf, EmulatorError> {
    let (path, source_of_path) = if let Some(path) = explicit {
        (path.to_owned(), "--emulator")
    } else if let Some(path) = std::env::var_os(EMULATOR_ENV) {
        (PathBuf::from(path), "$SCANHIL_EMULATOR")
    } else {
        let exe = std::env::current_exe().unwrap_or_default();
        let dir = exe.parent().unwrap_or(Path::new("."));
        (
            dir.join(format!("{EMULATOR_BIN}{}", std::env::consts::EXE_SUFFIX)),
            "next to the scanhil executable",
        )
    };
    if path.is_file() {
        Ok(path)
    } else {
        Err(EmulatorError::NotFound {
            path,
            source_of_path,
        })
    }
}

/// A running emulator process; killed and reaped when dropped.
#[derive(Debug)]
pub struct EmulatorProcess {
    child: Child,
    path: PathBuf,
}

impl EmulatorProcess {
    /// Starts `binary` with `args`; its stderr goes to ours (its errors reach the user), its
    /// stdout is piped (it reports its own summary there). It runs in a process group of its
    /// own, so a Ctrl-C on the terminal reaches the host alone, which then ends the emulator's
    /// run through the link ([`super::interrupt`]).
    ///
    /// # Errors
    /// [`EmulatorError::Spawn`] with the OS error.
    pub fn start(binary: &Path, args: &[String]) -> Result<EmulatorProcess, EmulatorError> {
        let child = Command::new(binary)
            .args(args)
            .process_group(0)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(|source| EmulatorError::Spawn {
                path: binary.to_owned(),
                source,
            })?;
        Ok(EmulatorProcess {
            child,
            path: binary.to_owned(),
        })
    }

    /// The process id (for tests that kill it mid-run).
    #[must_use]
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// The binary it runs.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Its stdout, line by line (read on a thread); empty after the first call.
    pub fn stdout_lines(&mut self) -> std::sync::mpsc::Receiver<String> {
        match self.child.stdout.take() {
            Some(pipe) => super::spawn_line_reader(pipe),
            None => std::sync::mpsc::channel().1,
        }
    }

    /// Waits up to `grace` for the process to exit by itself, then kills it. Returns its exit
    /// status, or `None` when it had to be killed.
    ///
    /// # Errors
    /// The OS error of waiting.
    pub fn finish(mut self, grace: std::time::Duration) -> std::io::Result<Option<ExitStatus>> {
        let deadline = std::time::Instant::now() + grace;
        loop {
            if let Some(status) = self.child.try_wait()? {
                return Ok(Some(status));
            }
            if std::time::Instant::now() >= deadline {
                self.child.kill()?;
                self.child.wait()?;
                return Ok(None);
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
    }
}

impl Drop for EmulatorProcess {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}
