//! The fuzz targets' short run, in every `cargo test`: each kept input of
//! `fuzz/corpus/<target>/` (seeds and what the long runs found) and `fuzz/regressions/<target>/`
//! (inputs that crashed a target once, kept after the fix), then random bytes and mutated kept
//! inputs (proptest). The long, coverage-guided runs are AFL++'s (docs/testing.md, Fuzzing).

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use scanhil_fuzz::{TARGETS, Target, target};

/// Random and mutated inputs per target and kind: a second or two per target in debug.
const CASES: u32 = 400;
/// The longest random input.
const MAX_RANDOM_LEN: usize = 512;

/// The files under `fuzz/<folder>/<target>/`, in name order.
fn files(folder: &str, target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(folder)
        .join(target);
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return Vec::new();
    };
    let mut paths: Vec<PathBuf> = entries.map(|e| e.unwrap().path()).collect();
    paths.sort();
    paths
        .into_iter()
        .map(|path| {
            let bytes = std::fs::read(&path).unwrap();
            (path, bytes)
        })
        .collect()
}

/// Runs `target` on `bytes`, naming `origin` if it panics.
fn run_named(target: &Target, origin: &Path, bytes: &[u8]) {
    if let Err(panic) = std::panic::catch_unwind(|| (target.run)(bytes)) {
        let message = panic
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_owned()))
            .unwrap_or_default();
        panic!("{}: {} panicked: {message}", origin.display(), target.name);
    }
}

#[test]
fn every_target_has_seeds_and_every_kept_input_runs_clean() {
    for target in &TARGETS {
        let corpus = files("corpus", target.name);
        assert!(
            corpus.iter().any(|(path, _)| path
                .file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("seed-"))),
            "{} has no seed in fuzz/corpus/{}",
            target.name,
            target.name
        );
        for (path, bytes) in corpus.iter().chain(&files("regressions", target.name)) {
            run_named(target, path, bytes);
        }
    }
}

#[test]
fn every_regression_belongs_to_a_target() {
    let fuzz = Path::new(env!("CARGO_MANIFEST_DIR"));
    for folder in [fuzz.join("regressions"), fuzz.join("corpus")] {
        let Ok(entries) = std::fs::read_dir(&folder) else {
            continue;
        };
        for entry in entries {
            let name = entry.unwrap().file_name();
            let name = name.to_string_lossy();
            assert!(
                target(&name).is_some(),
                "{}/{name} is no target",
                folder.display()
            );
        }
    }
}

/// A kept input with a few bytes overwritten, inserted or removed.
fn mutated(kept: Vec<Vec<u8>>) -> impl Strategy<Value = Vec<u8>> {
    let edits = prop::collection::vec((any::<usize>(), any::<u8>(), 0u8..3), 1..8);
    (prop::sample::select(kept), edits).prop_map(|(mut bytes, edits)| {
        for (at, byte, kind) in edits {
            let at = at % (bytes.len() + 1);
            match kind {
                0 if at < bytes.len() => bytes[at] = byte,
                1 => bytes.insert(at, byte),
                _ if at < bytes.len() => {
                    bytes.remove(at);
                }
                _ => bytes.push(byte),
            }
        }
        bytes
    })
}

/// Random bytes, then mutated kept inputs, through the target called `name`.
fn fuzz_briefly(name: &str) {
    let target = target(name).unwrap();
    let kept: Vec<Vec<u8>> = files("corpus", name)
        .into_iter()
        .chain(files("regressions", name))
        .map(|(_, bytes)| bytes)
        .collect();
    let config = Config {
        cases: CASES,
        failure_persistence: None,
        ..Config::default()
    };
    let inputs = [
        prop::collection::vec(any::<u8>(), 0..MAX_RANDOM_LEN).boxed(),
        mutated(kept).boxed(),
    ];
    for strategy in inputs {
        let result = TestRunner::new(config.clone()).run(&strategy, |bytes| {
            (target.run)(&bytes);
            Ok(())
        });
        if let Err(error) = result {
            panic!("{name}: {error}");
        }
    }
}

macro_rules! short_runs {
    ($($name:ident),* $(,)?) => {
        $(
            #[test]
            fn $name() {
                fuzz_briefly(stringify!($name));
            }
        )*

        #[test]
        fn every_target_has_a_short_run() {
            let names = [$(stringify!($name)),*];
            for target in &TARGETS {
                assert!(names.contains(&target.name), "{} has no short run", target.name);
            }
        }
    };
}

short_runs!(
    slcan,
    candump,
    ild_stream,
    can_messages,
    ild_commands,
    ild_replies,
    decode,
    replay,
    ply,
    surfaces,
    scenario,
    documents,
);
