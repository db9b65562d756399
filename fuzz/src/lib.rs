#![warn(missing_docs)]
//! Fuzz targets for every parser that takes bytes from outside the program: the links (SLCAN,
//! the ILD stream, ILD commands and replies, CAN messages), recordings (candump logs and
//! `scanhil decode`), and files (PLY, height maps, scenario and the other JSON documents).
//!
//! A target is a plain function of arbitrary bytes ([`Target::run`]) that returns on any input
//! and panics only on a bug: a panic in the code under test, or a property of the parser that
//! does not hold (a decoded message that does not encode back, a decode that depends on how
//! the bytes were chunked, a value that passed a check it should not have). Two engines run
//! the same functions:
//! - `cargo test -p scanhil-fuzz` (and so CI): every kept input of `fuzz/corpus/<target>/` and
//!   `fuzz/regressions/<target>/`, then a few hundred random and mutated inputs per target
//!   with proptest: seconds, no coverage feedback.
//! - `scanhil-fuzz-afl <target>` (feature `afl`, built with `cargo afl build`): AFL++
//!   coverage-guided, for the long runs of docs/testing.md.
//!
//! Targets that read a document with a selector (`documents`, `surfaces`, `decode`, `replay`) take the
//! first byte as the selector and the rest as the document, so one target covers a family of
//! parsers. JSON documents are read as if they were in `fixtures/` (their relative paths to
//! rigs, controllers, scenes and height maps resolve to the repository's fixtures).

use std::path::PathBuf;

pub mod documents;
pub mod files;
pub mod ild;
pub mod recordings;
pub mod wire;

/// One fuzz target.
#[derive(Debug, Clone, Copy)]
pub struct Target {
    /// Its name: the folder of its corpus, the argument of `scanhil-fuzz-afl`.
    pub name: &'static str,
    /// What it feeds its bytes to.
    pub parsers: &'static str,
    /// Runs one input; panics only on a bug.
    pub run: fn(&[u8]),
}

/// Every target, in the order the long run takes them.
pub const TARGETS: [Target; 12] = [
    Target {
        name: "slcan",
        parsers: "SLCAN decoder (host replies and frames, device commands)",
        run: wire::slcan,
    },
    Target {
        name: "candump",
        parsers: "candump -L log reader",
        run: wire::candump,
    },
    Target {
        name: "ild_stream",
        parsers: "ILD 2300 RS422 value stream decoder",
        run: wire::ild_stream,
    },
    Target {
        name: "can_messages",
        parsers: "CAN message decoders (Message::decode, decode_signals)",
        run: wire::can_messages,
    },
    Target {
        name: "ild_commands",
        parsers: "ILD command lines (device end: parse, the emulated sensor's answer)",
        run: ild::commands,
    },
    Target {
        name: "ild_replies",
        parsers: "ILD replies (host end: reply parser, GETINFO, query answers)",
        run: ild::replies,
    },
    Target {
        name: "decode",
        parsers: "`scanhil decode` readers (candump, SLCAN, ILD)",
        run: recordings::decode,
    },
    Target {
        name: "replay",
        parsers: "a recorded session for `scanhil-emulator replay` (fsm.log, sensor.ild, report.json)",
        run: recordings::replay,
    },
    Target {
        name: "ply",
        parsers: "PLY reader (ASCII and binary, point clouds)",
        run: files::ply,
    },
    Target {
        name: "surfaces",
        parsers: "height-map surfaces (CSV, PNG) and the surface through them",
        run: files::surfaces,
    },
    Target {
        name: "scenario",
        parsers: "scenario JSON, its check and the scan's plan",
        run: documents::scenario,
    },
    Target {
        name: "documents",
        parsers: "rig, controller, scene (and its plant), study, true-scene JSON",
        run: documents::documents,
    },
];

/// The target called `name`.
#[must_use]
pub fn target(name: &str) -> Option<&'static Target> {
    TARGETS.iter().find(|t| t.name == name)
}

/// The repository's root (the fixtures' parent).
#[must_use]
pub fn repository_root() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// The first byte as a selector among `choices`, and the rest; `None` for no bytes.
fn select(data: &[u8], choices: usize) -> Option<(usize, &[u8])> {
    let (&first, rest) = data.split_first()?;
    Some((usize::from(first) % choices, rest))
}

/// A split point of `data` taken from its length and its last byte: where a second chunk
/// starts when a target checks that chunking changes nothing.
fn cut(data: &[u8]) -> usize {
    data.last()
        .map_or(0, |&last| usize::from(last) % (data.len() + 1))
}
