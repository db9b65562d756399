//! The lockstep loop over ptys against its floor, in one run (issue 12, target 1).
//!
//! - **Floor**: two processes (this binary and a copy of itself) ping-pong over one pty pair
//!   with one lockstep period's bytes each way: the host's CoilCommand and Step SLCAN lines
//!   (44 bytes), the node's AngleReading line and one ILD output cycle (28 bytes). Blocking
//!   reads and writes, nothing else: what a period costs on this machine at the least.
//! - **Loop**: `scanhil scan` of the main scenario (`duplo-lissajous-dual-tone`, the emulator
//!   it starts, both ptys) with a 0.1 s frame, once without lead-in and once with 1 s (20 000
//!   periods) of it: the difference over the extra periods is the loop's cost per period
//!   without start-up, imaging and output writing.
//! - **Main scan**: the scenario as shipped (its lead-in and 1 s frame), wall time per
//!   simulated second.
//!
//! - **Main scan against the floor**: the main scan's whole wall time (start-up, lead-in,
//!   frame, imaging, outputs) against the floor's time for as many round trips as it ran
//!   periods, the round's own floor (issue 23's figure).
//!
//! Rounds interleave the three so load on the machine hits them alike; medians of
//! `SCANHIL_BENCH_ROUNDS` rounds (default 5). The programs are this tree's, built in release,
//! or those in `SCANHIL_BENCH_BINARIES` (a folder with `scanhil` and `scanhil-emulator`: an
//! earlier build to compare with). JSON on stdout, a summary on stderr. Run:
//! `cargo bench -p scanhil-loop-tests --bench lockstep_floor`.

use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::os::fd::AsFd;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// The host's bytes in one period: CoilCommand(k) and Step(k) as SLCAN lines.
const HOST_BYTES: &[u8] = b"t10086300BF2FFF5F60FF\rt0214630000000\r\r";
/// The node's bytes in one period: AngleReading(k) as an SLCAN line and one ILD cycle.
const NODE_BYTES: &[u8] = b"t11086300A00200C20100\r6H\x8b$A\xc0";
/// Periods the floor runs per round.
const FLOOR_PERIODS: u64 = 20_000;
/// Set in the peer process: the pty slave to answer on.
const PEER_ENV: &str = "SCANHIL_FLOOR_PEER";

fn main() {
    if let Ok(slave) = std::env::var(PEER_ENV) {
        floor_peer(Path::new(&slave));
        return;
    }
    let rounds: usize = std::env::var("SCANHIL_BENCH_ROUNDS")
        .ok()
        .and_then(|text| text.parse().ok())
        .unwrap_or(5);
    let bin = release_binaries();
    let mut floor_us = Vec::new();
    let mut loop_us = Vec::new();
    let mut scan_s_per_s = Vec::new();
    let mut main_over_floor = Vec::new();
    for round in 0..rounds {
        floor_us.push(floor_us_per_period());
        let short = scan(&bin, &["--lead-in-s", "0", "--duration-s", "0.1"]);
        let long = scan(&bin, &["--lead-in-s", "1", "--duration-s", "0.1"]);
        loop_us.push((long.wall_s - short.wall_s) * 1e6 / (long.periods - short.periods) as f64);
        let main = scan(&bin, &[]);
        scan_s_per_s.push(main.wall_s / main.simulated_s);
        main_over_floor.push(main.wall_s / (floor_us[round] * 1e-6 * main.periods as f64));
        eprintln!(
            "round {}: floor {:.1} us/period, loop {:.1} us/period, main scan {:.3} s per simulated s ({:.2}x its periods of floor)",
            round + 1,
            floor_us[round],
            loop_us[round],
            scan_s_per_s[round],
            main_over_floor[round]
        );
    }
    let floor = median(&floor_us);
    let lockstep = median(&loop_us);
    let main = median(&scan_s_per_s);
    let whole = median(&main_over_floor);
    let figures = serde_json::json!({
        "rounds": rounds,
        "floor_us_per_period": floor,
        "loop_us_per_period": lockstep,
        "loop_over_floor": lockstep / floor,
        "main_scan_wall_s_per_simulated_s": main,
        "main_scan_times_real_time": 1.0 / main,
        "main_scan_over_floor": whole,
        "runs": {
            "floor_us": floor_us,
            "loop_us": loop_us,
            "main_scan_s_per_s": scan_s_per_s,
            "main_scan_over_floor": main_over_floor,
        },
        "load_average": std::fs::read_to_string("/proc/loadavg").unwrap_or_default().trim(),
    });
    eprintln!(
        "medians of {rounds}: floor {floor:.1} us/period, loop {lockstep:.1} us/period ({:.2}x the floor), main scan {main:.3} s per simulated s ({:.2}x real time, {whole:.2}x its periods of floor)",
        lockstep / floor,
        1.0 / main
    );
    println!("{figures:#}");
}

/// Builds the two programs in release (or takes them from `SCANHIL_BENCH_BINARIES`) and
/// copies them aside, so a concurrent build cannot swap them mid-run.
fn release_binaries() -> tempfile::TempDir {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().expect("a temporary folder");
    if let Some(given) = std::env::var_os("SCANHIL_BENCH_BINARIES") {
        let given = PathBuf::from(given);
        for name in ["scanhil", "scanhil-emulator"] {
            std::fs::copy(given.join(name), dir.path().join(name))
                .unwrap_or_else(|e| panic!("copying {name} from {}: {e}", given.display()));
        }
        return dir;
    }
    let status = Command::new(env!("CARGO"))
        .current_dir(root)
        .args([
            "build",
            "--release",
            "--bins",
            "-p",
            "scanhil-controller",
            "-p",
            "scanhil-emulator",
        ])
        .status()
        .expect("running cargo build");
    assert!(
        status.success(),
        "cargo build --release of the two programs failed"
    );
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| root.join("target"), PathBuf::from)
        .join("release");
    for name in ["scanhil", "scanhil-emulator"] {
        std::fs::copy(target.join(name), dir.path().join(name))
            .unwrap_or_else(|e| panic!("copying {name} from {}: {e}", target.display()));
    }
    dir
}

struct ScanRun {
    wall_s: f64,
    periods: u64,
    simulated_s: f64,
}

/// Runs the main scenario with `extra` arguments; its wall time and what it simulated.
fn scan(bin: &tempfile::TempDir, extra: &[&str]) -> ScanRun {
    let out = tempfile::tempdir().expect("a temporary folder");
    let scenario = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/scenarios/duplo-lissajous-dual-tone.json");
    let started = Instant::now();
    let output = Command::new(bin.path().join("scanhil"))
        .arg("scan")
        .arg(&scenario)
        .arg("--out")
        .arg(out.path())
        .args(extra)
        .output()
        .expect("running scanhil scan");
    let wall_s = started.elapsed().as_secs_f64();
    // Every period must have run; without a lead-in the frame holds the start-up transient,
    // so its tracking verdict may fail (exit 4): the time is what is measured here.
    assert!(
        matches!(output.status.code(), Some(0 | 4)),
        "scanhil scan {extra:?} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_reader(File::open(out.path().join("report.json")).expect("report.json"))
            .expect("report.json is JSON");
    assert_eq!(
        report["periods"]["done"], report["periods"]["planned"],
        "scanhil scan {extra:?} stopped early"
    );
    let periods = report["periods"]["done"].as_u64().expect("periods.done");
    let period_s = report["periods"]["period_s"]
        .as_f64()
        .expect("periods.period_s");
    ScanRun {
        wall_s,
        periods,
        simulated_s: periods as f64 * period_s,
    }
}

/// The floor, host side: a pty pair, the peer on its slave, [`FLOOR_PERIODS`] exchanges.
fn floor_us_per_period() -> f64 {
    let pty = nix::pty::openpty(None, None).expect("a pty pair");
    let mut settings = nix::sys::termios::tcgetattr(pty.slave.as_fd()).expect("termios");
    nix::sys::termios::cfmakeraw(&mut settings);
    nix::sys::termios::tcsetattr(
        pty.slave.as_fd(),
        nix::sys::termios::SetArg::TCSANOW,
        &settings,
    )
    .expect("raw mode");
    // The peer opens the slave by path; it must not inherit our ends, or it would never see
    // the host go away.
    for fd in [pty.master.as_fd(), pty.slave.as_fd()] {
        nix::fcntl::fcntl(
            fd,
            nix::fcntl::FcntlArg::F_SETFD(nix::fcntl::FdFlag::FD_CLOEXEC),
        )
        .expect("close-on-exec");
    }
    let slave = nix::unistd::ttyname(pty.slave.as_fd()).expect("the slave's path");
    let mut peer = Command::new(std::env::current_exe().expect("this binary"))
        .env(PEER_ENV, &slave)
        .spawn()
        .expect("starting the floor's peer");
    let mut master = File::from(pty.master);
    let mut answer = vec![0; NODE_BYTES.len()];
    // One exchange to know the peer is there, then the timed ones.
    exchange(&mut master, &mut answer);
    let started = Instant::now();
    for _ in 0..FLOOR_PERIODS {
        exchange(&mut master, &mut answer);
    }
    let elapsed = started.elapsed();
    drop(master);
    drop(pty.slave);
    peer.wait().expect("the floor's peer ends");
    elapsed.as_secs_f64() * 1e6 / FLOOR_PERIODS as f64
}

fn exchange(master: &mut File, answer: &mut [u8]) {
    master
        .write_all(HOST_BYTES)
        .expect("writing the host's period");
    master
        .read_exact(answer)
        .expect("reading the node's period");
    assert_eq!(answer, NODE_BYTES, "the peer's answer");
}

/// The floor, node side: answers each period's bytes until the host goes away.
fn floor_peer(slave: &Path) {
    let mut line = OpenOptions::new()
        .read(true)
        .write(true)
        .open(slave)
        .expect("opening the pty slave");
    let mut request = vec![0; HOST_BYTES.len()];
    while line.read_exact(&mut request).is_ok() {
        if line.write_all(NODE_BYTES).is_err() {
            break;
        }
    }
}

fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted[sorted.len() / 2]
}
