//! Helpers for the loop tests: the two programs' binaries (built once, same profile as the
//! tests), fixtures, and reading back what a run wrote.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use scanhil_protocol::ild::IldValue;
use scanhil_protocol::ild::stream::IldDecoder;
use scanhil_protocol::message::Message;

/// The workspace root: the package's folder, or the nearest folder above it with the
/// fixtures (a member crate that includes these helpers, such as `lab/`).
pub fn root() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest
        .ancestors()
        .find(|dir| dir.join("fixtures").is_dir())
        .unwrap_or(manifest)
        .to_owned()
}

/// A fixture path under `fixtures/`, as a string for command lines.
pub fn fixture(relative: &str) -> String {
    root().join("fixtures").join(relative).display().to_string()
}

/// The target profile directory the test binary runs from (`target/debug`).
fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("the test binary's path");
    // target/<profile>/deps/<test binary>
    exe.parent()
        .and_then(Path::parent)
        .expect("the test binary sits in target/<profile>/deps")
        .to_owned()
}

/// Builds `scanhil` and `scanhil-emulator` once (a no-op when `cargo test --workspace` has
/// already built them) and returns the profile directory they are in.
fn binaries() -> &'static Path {
    static BUILT: OnceLock<PathBuf> = OnceLock::new();
    BUILT.get_or_init(|| {
        let dir = profile_dir();
        let mut build = Command::new(env!("CARGO"));
        build.current_dir(root()).args([
            "build",
            "--bins",
            "-p",
            "scanhil-controller",
            "-p",
            "scanhil-emulator",
        ]);
        if dir.file_name().is_some_and(|name| name == "release") {
            build.arg("--release");
        }
        let status = build
            .status()
            .expect("running cargo build for the two programs");
        assert!(
            status.success(),
            "cargo build of scanhil and scanhil-emulator failed"
        );
        dir
    })
}

/// The `scanhil` binary.
pub fn scanhil() -> PathBuf {
    binaries().join("scanhil")
}

/// The `scanhil-emulator` binary.
pub fn emulator() -> PathBuf {
    binaries().join("scanhil-emulator")
}

/// The longest any single `scanhil` run in these tests may take before it is killed and the
/// test fails (a hang must never stall CI).
pub const RUN_LIMIT: std::time::Duration = std::time::Duration::from_secs(180);

/// The arguments of a real-time scan of `test-loop-small` for `duration_s` into `out`, then
/// `extra`. Its watchdog of 10 000 periods (0.5 s of ticks on the emulator's side) is far above
/// a loaded machine's hiccups, and the catch-up after one reads the host's queued commands.
pub fn realtime_scan_args(out: &Path, duration_s: &str, extra: &[&str]) -> Vec<String> {
    let mut args: Vec<String> = [
        "scan",
        &fixture("scenarios/test-loop-small.json"),
        "--timing",
        "realtime",
        "--duration-s",
        duration_s,
        "--watchdog-periods",
        "10000",
        "--out",
        out.to_str().expect("UTF-8 path"),
    ]
    .map(str::to_owned)
    .to_vec();
    args.extend(extra.iter().map(|arg| (*arg).to_owned()));
    args
}

/// Asserts that a complete scan's `report.json` says it ended with the coils at zero: the
/// host's zero command acknowledged by the node, which is ready and holds 0 A on both coils.
pub fn assert_coils_at_zero(report: &serde_json::Value) {
    let coils = &report["coils_at_end"];
    assert_eq!(coils["zero_commanded"], true, "{coils}");
    assert_eq!(coils["acknowledged"], true, "{coils}");
    assert_eq!(coils["node_final_state"], "ready", "{coils}");
    assert_eq!(coils["node_held_coil_currents_a"]["a"], 0.0, "{coils}");
    assert_eq!(coils["node_held_coil_currents_a"]["b"], 0.0, "{coils}");
    assert_eq!(
        report["emulator"]["summary"]["ended_by"], "controller_status",
        "the host's end of the run ended the emulator's: {}",
        report["emulator"]["summary"]
    );
}

/// Runs `scanhil` with `args` and returns its output; kills it and panics after [`RUN_LIMIT`].
pub fn run_scanhil(args: &[&str]) -> Output {
    run_scanhil_with(args, |_| {})
}

/// [`run_scanhil`] with the command set up further by `configure` first (limits, privileges).
pub fn run_scanhil_with(args: &[&str], configure: impl FnOnce(&mut Command)) -> Output {
    let mut command = Command::new(scanhil());
    configure(&mut command);
    let child = command
        .args(args)
        .env("SCANHIL_EMULATOR", emulator())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("starting scanhil");
    exits_within(child, RUN_LIMIT, &format!("scanhil {args:?}"))
}

/// Panics with both streams when `output` is not a success.
pub fn assert_success(output: &Output, what: &str) {
    assert!(
        output.status.success(),
        "{what} failed ({:?}):\nstdout:\n{}\nstderr:\n{}",
        output.status,
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
}

/// Asserts that a real-time scan ran every planned period: exit 0, or exit 4 with a failed
/// verdict whose only reasons are tracking (on a loaded machine a real-time loop over ptys
/// misses deadlines, the PID acts on stale commands and may not track; the verdict says so,
/// and the real-time tests check timing figures, not tracking). Returns the report.
pub fn assert_ran_every_period(output: &Output, dir: &Path) -> serde_json::Value {
    let stderr = String::from_utf8_lossy(&output.stderr);
    let report = report(dir);
    let outcome = &report["outcome"];
    match output.status.code() {
        Some(0) => assert_eq!(outcome["verdict"], "complete", "{outcome}"),
        Some(4) => {
            assert_eq!(outcome["verdict"], "failed", "{outcome}");
            let reasons = outcome["reasons"].as_array().expect("reasons");
            assert!(
                !reasons.is_empty()
                    && reasons.iter().all(|reason| reason
                        .as_str()
                        .is_some_and(|r| r.starts_with("the loop does not track"))),
                "only tracking may fail a real-time run that ran every period: {outcome}"
            );
        }
        other => panic!("exit {other:?}, not a run of every period; stderr:\n{stderr}"),
    }
    assert_eq!(outcome["stopped_by"], serde_json::Value::Null, "{outcome}");
    report
}

/// Reads and parses `report.json` in `dir`.
pub fn report(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("report.json")).expect("report.json written");
    serde_json::from_str(&text).expect("report.json is JSON")
}

/// A number at a JSON pointer, or a panic naming the pointer.
pub fn number(value: &serde_json::Value, pointer: &str) -> f64 {
    value
        .pointer(pointer)
        .and_then(serde_json::Value::as_f64)
        .unwrap_or_else(|| panic!("{pointer} is not a number in {value:#}"))
}

/// Asserts the frame's measured tracking error over the predicted one is inside each axis'
/// band (too good fails as well as too bad).
pub fn assert_tracks_as_predicted(report: &serde_json::Value, bands: &[(&str, (f64, f64))]) {
    for (axis, band) in bands {
        let measured = number(
            report,
            &format!("/tracking_error/frame/{axis}/rms_relative"),
        );
        let predicted = number(
            report,
            &format!("/predicted_tracking_error/{axis}_rms_relative"),
        );
        assert!(
            (band.0..=band.1).contains(&(measured / predicted)),
            "{axis}: measured {measured}, predicted {predicted}, band {band:?}"
        );
    }
}

/// What a recording held.
#[derive(Debug, Default)]
pub struct DecodedRecording {
    /// Lines (frames) in the candump log.
    pub frames: usize,
    /// AngleReading sequence counters, in order.
    pub angle_seqs: Vec<u16>,
    /// CoilCommand sequence counters, in order.
    pub command_seqs: Vec<u16>,
    /// Fault frames.
    pub faults: Vec<Message>,
    /// The last coil command, in A.
    pub last_command_a: Option<scanhil_protocol::plant_units::ActuatorPair>,
}

/// Decodes every line of a candump `-L` log with the protocol's decoder; panics naming the
/// line when one does not decode.
pub fn decode_candump(path: &Path) -> DecodedRecording {
    let text = std::fs::read_to_string(path).expect("the candump log exists");
    let mut decoded = DecodedRecording::default();
    for (i, line) in text.lines().enumerate() {
        let at = || format!("{}:{}: {line:?}", path.display(), i + 1);
        let mut fields = line.split(' ');
        let stamp = fields.next().unwrap_or_else(|| panic!("{}", at()));
        assert!(
            stamp.starts_with('(')
                && stamp.ends_with(')')
                && stamp[1..stamp.len() - 1].parse::<f64>().is_ok(),
            "bad timestamp at {}",
            at()
        );
        let _iface = fields.next().unwrap_or_else(|| panic!("{}", at()));
        let compact = fields.next().unwrap_or_else(|| panic!("{}", at()));
        let (id, data) = compact
            .split_once('#')
            .unwrap_or_else(|| panic!("{}", at()));
        let id = u16::from_str_radix(id, 16).unwrap_or_else(|_| panic!("{}", at()));
        let data = scanhil_protocol::can::parse_hex(data.as_bytes())
            .unwrap_or_else(|| panic!("bad data at {}", at()));
        let id = scanhil_protocol::can::CanId::standard(id).unwrap_or_else(|| panic!("{}", at()));
        let frame =
            scanhil_protocol::can::CanFrame::new(id, &data).unwrap_or_else(|_| panic!("{}", at()));
        let message = Message::decode(&frame).unwrap_or_else(|e| panic!("{e} at {}", at()));
        decoded.frames += 1;
        match message {
            Message::AngleReading(reading) => decoded.angle_seqs.push(reading.seq),
            Message::CoilCommand(command) => {
                decoded.command_seqs.push(command.seq);
                decoded.last_command_a = Some(command.amps());
            }
            Message::Fault(_) => decoded.faults.push(message),
            _ => {}
        }
    }
    decoded
}

/// Asserts that 16-bit sequence counters count up by one without a gap.
pub fn assert_gapless(seqs: &[u16], what: &str) {
    assert!(!seqs.is_empty(), "no {what} recorded");
    for pair in seqs.windows(2) {
        assert_eq!(
            pair[1],
            pair[0].wrapping_add(1),
            "{what} sequence jumps from {} to {}",
            pair[0],
            pair[1]
        );
    }
}

/// Decodes a raw ILD capture with the protocol's stream decoder; every cycle must be a
/// distance value, alone or with its counter, with no byte skipped. Returns (counter, value)
/// per cycle.
pub fn decode_ild(path: &Path) -> Vec<(Option<u32>, IldValue)> {
    let bytes = std::fs::read(path).expect("the ILD capture exists");
    let mut decoder = IldDecoder::new();
    let mut cycles: Vec<Vec<u32>> = Vec::new();
    for event in decoder.push(&bytes) {
        let word = event.unwrap_or_else(|gap| panic!("{}: {gap}", path.display()));
        if word.first_in_cycle {
            cycles.push(Vec::new());
        }
        cycles
            .last_mut()
            .unwrap_or_else(|| panic!("{}: stream starts mid-cycle", path.display()))
            .push(word.raw);
    }
    assert!(
        decoder.finish().is_none(),
        "{}: ends mid-value",
        path.display()
    );
    cycles
        .into_iter()
        .map(|cycle| match cycle[..] {
            [value] => (None, IldValue::from_raw(value)),
            [value, counter] => (Some(counter), IldValue::from_raw(value)),
            _ => panic!(
                "{}: a cycle is the distance, or the distance and its counter: {cycle:?}",
                path.display()
            ),
        })
        .collect()
}

/// An `scanhil-emulator serve` process started by a test, with its ready line.
pub struct ServedEmulator {
    /// The process.
    pub child: std::process::Child,
    /// The ready line.
    pub ready: serde_json::Value,
    lines: std::sync::mpsc::Receiver<String>,
}

impl ServedEmulator {
    /// Starts `scanhil-emulator serve` with `args` and waits for its ready line.
    pub fn start(args: &[&str]) -> ServedEmulator {
        use std::io::BufRead;
        let mut child = Command::new(emulator())
            .arg("serve")
            .args(args)
            .stdout(std::process::Stdio::piped())
            .spawn()
            .expect("starting scanhil-emulator serve");
        let stdout = child.stdout.take().expect("piped stdout");
        let (tx, lines) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in std::io::BufReader::new(stdout)
                .lines()
                .map_while(Result::ok)
            {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let first = lines
            .recv_timeout(std::time::Duration::from_secs(60))
            .expect("the emulator prints a ready line");
        let ready: serde_json::Value = serde_json::from_str(&first).expect("ready line is JSON");
        assert_eq!(ready["event"], "ready", "{ready}");
        ServedEmulator {
            child,
            ready,
            lines,
        }
    }

    /// The path of a link the emulator created (`"fsm"` or `"sensor"`), without its scheme.
    pub fn path(&self, node: &str) -> String {
        let uri = self.ready[node].as_str().expect("a link in the ready line");
        uri.split_once(':').expect("scheme:path").1.to_owned()
    }

    /// Waits for the process to exit (at most `timeout`) and returns its exit code and the
    /// summary line.
    pub fn finish(mut self, timeout: std::time::Duration) -> (Option<i32>, serde_json::Value) {
        let deadline = std::time::Instant::now() + timeout;
        let status = loop {
            if let Some(status) = self.child.try_wait().expect("waiting for the emulator") {
                break status;
            }
            assert!(
                std::time::Instant::now() < deadline,
                "the emulator did not exit in {timeout:?}"
            );
            std::thread::sleep(std::time::Duration::from_millis(10));
        };
        // The process has exited; its reader thread may not have passed on the last lines yet:
        // read until it ends at the pipe's end of file (5 s at most for a loaded machine).
        let mut summary = serde_json::Value::Null;
        while let Ok(line) = self.lines.recv_timeout(std::time::Duration::from_secs(5)) {
            if let Ok(value) = serde_json::from_str::<serde_json::Value>(&line)
                && value["event"] == "summary"
            {
                summary = value;
            }
        }
        (status.code(), summary)
    }
}

impl Drop for ServedEmulator {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// A minimal SLCAN host on a pty path, for tests that play the controller by hand.
pub struct SlcanHost {
    file: std::fs::File,
    frames: std::sync::mpsc::Receiver<Message>,
    reading: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl SlcanHost {
    /// Opens `path` and the channel (`O`).
    pub fn open(path: &str) -> SlcanHost {
        use scanhil_protocol::slcan::{SlcanDecoder, SlcanMessage};
        use std::io::{Read, Write};
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
            .expect("opening the pty");
        let mut reader = file.try_clone().expect("a second handle");
        let (tx, frames) = std::sync::mpsc::channel();
        let reading = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
        let still_reading = reading.clone();
        std::thread::spawn(move || {
            let mut decoder = SlcanDecoder::new();
            let mut buf = [0u8; 1024];
            while let Ok(n) = reader.read(&mut buf) {
                if n == 0 || !still_reading.load(std::sync::atomic::Ordering::SeqCst) {
                    break;
                }
                let frames = decoder
                    .push(&buf[..n])
                    .into_iter()
                    .filter_map(|event| match event {
                        Ok(SlcanMessage::Frame(frame)) => Message::decode(&frame).ok(),
                        _ => None,
                    });
                for message in frames {
                    if tx.send(message).is_err() {
                        return;
                    }
                }
            }
        });
        file.write_all(b"O\r").expect("opening the channel");
        SlcanHost {
            file,
            frames,
            reading,
        }
    }

    /// Stops reading the line for good (the reader reads at most one more chunk), while the
    /// line stays open: a host that stops reading.
    pub fn stop_reading(&self) {
        self.reading
            .store(false, std::sync::atomic::Ordering::SeqCst);
    }

    /// Sends `messages(k)` for k = `first`, `first + 1`, ... from a thread, without reading,
    /// until a write fails (the emulator has gone).
    pub fn spawn_blind_writer(
        &self,
        first: u32,
        messages: impl Fn(u32) -> Vec<Message> + Send + 'static,
    ) -> std::thread::JoinHandle<u32> {
        use std::io::Write;
        let mut file = self.file.try_clone().expect("a second handle");
        std::thread::spawn(move || {
            for k in first.. {
                for message in messages(k) {
                    let frame = message.encode().expect("encodable");
                    let line = scanhil_protocol::slcan::encode_frame(&frame);
                    if file.write_all(line.as_bytes()).is_err() {
                        return k;
                    }
                }
            }
            u32::MAX
        })
    }

    /// Sends a message.
    pub fn send(&mut self, message: &Message) {
        use std::io::Write;
        let frame = message.encode().expect("encodable");
        let line = scanhil_protocol::slcan::encode_frame(&frame);
        self.file
            .write_all(line.as_bytes())
            .expect("writing to the pty");
    }

    /// Writes one raw SLCAN line (a command such as `C`), adding the CR.
    pub fn write_line(&mut self, line: &str) {
        use std::io::Write;
        self.file
            .write_all(format!("{line}\r").as_bytes())
            .expect("writing to the pty");
    }

    /// The next message within `timeout`.
    pub fn recv(&self, timeout: std::time::Duration) -> Option<Message> {
        self.frames.recv_timeout(timeout).ok()
    }
}

/// Starts `scanhil scan` of test-loop-small against a mirror node on `fsm` (no emulator of
/// its own) in `timing`, for `duration_s` with a watchdog of `watchdog_periods`, into `out`;
/// stderr piped, stdout dropped.
pub fn start_scan_of_node(
    fsm: &str,
    timing: &str,
    duration_s: f64,
    watchdog_periods: u32,
    out: &Path,
) -> std::process::Child {
    let duration_s = duration_s.to_string();
    let watchdog_periods = watchdog_periods.to_string();
    spawn_scan_of_node(
        fsm,
        out,
        &[
            "--timing",
            timing,
            "--duration-s",
            &duration_s,
            "--watchdog-periods",
            &watchdog_periods,
        ],
    )
}

/// Starts `scanhil scan` of test-loop-small against a mirror node on `fsm` (`--no-emulator`)
/// into `out` with `scan_args`; stderr piped, stdout dropped.
fn spawn_scan_of_node(fsm: &str, out: &Path, scan_args: &[&str]) -> std::process::Child {
    Command::new(scanhil())
        .args([
            "scan",
            &fixture("scenarios/test-loop-small.json"),
            "--fsm",
            fsm,
            "--no-emulator",
            "--out",
            out.to_str().expect("UTF-8 path"),
        ])
        .args(scan_args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("starting scanhil")
}

/// Starts a 30 s `scanhil scan` of test-loop-small into `out` (stdout and stderr piped) and
/// waits until its candump log holds more than `bytes`: a scan well under way, to interrupt
/// or to compete with. Panics if it never gets there.
pub fn start_long_scan(out: &Path, bytes: u64) -> std::process::Child {
    let child = Command::new(scanhil())
        .args([
            "scan",
            &fixture("scenarios/test-loop-small.json"),
            "--duration-s",
            "30",
            "--out",
            out.to_str().expect("UTF-8 path"),
        ])
        .env("SCANHIL_EMULATOR", emulator())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("starting scanhil");
    assert!(recording_grows(out, bytes), "the scan never got going");
    child
}

/// Polls (every 50 ms, 60 s at most) until the scan writing into `out` has recorded more than
/// `bytes` of `fsm.log`; false if it never does.
pub fn recording_grows(out: &Path, bytes: u64) -> bool {
    let log = out.join("fsm.log");
    (0..1200).any(|_| {
        std::thread::sleep(std::time::Duration::from_millis(50));
        std::fs::metadata(&log).is_ok_and(|m| m.len() > bytes)
    })
}

/// Starts an emulator serving the mirror node (`loop-fast` scene) on a pty with
/// `emulator_args`, and a `scanhil scan` of test-loop-small against it (`--no-emulator`,
/// stdout dropped, stderr piped) with `scan_args`, into `out`.
pub fn scan_against_served_emulator(
    out: &Path,
    emulator_args: &[&str],
    scan_args: &[&str],
) -> (ServedEmulator, std::process::Child) {
    let scene = fixture("scenes/loop-fast.json");
    let mut args = vec!["--scene", &scene, "--fsm", "slcan:pty"];
    args.extend_from_slice(emulator_args);
    let emulator = ServedEmulator::start(&args);
    let fsm = format!("slcan:{}", emulator.path("fsm"));
    let child = spawn_scan_of_node(&fsm, out, scan_args);
    (emulator, child)
}

/// Sends signal `name` (`STOP`, `CONT`, `KILL`, `INT`, ...) to process `pid`.
pub fn signal(pid: u32, name: &str) {
    let status = Command::new("kill")
        .args([&format!("-{name}"), &pid.to_string()])
        .status()
        .expect("running kill");
    assert!(status.success(), "kill -{name} {pid}");
}

/// The process ids of `pid`'s children (from `/proc/PID/task/*/children`).
pub fn children(pid: u32) -> Vec<u32> {
    let tasks = std::fs::read_dir(format!("/proc/{pid}/task")).expect("the process's tasks");
    tasks
        .filter_map(Result::ok)
        .filter_map(|task| std::fs::read_to_string(task.path().join("children")).ok())
        .flat_map(|text| {
            text.split_whitespace()
                .filter_map(|id| id.parse().ok())
                .collect::<Vec<u32>>()
        })
        .collect()
}

/// Waits up to `limit` for `child` to exit, reading its piped stdout and stderr meanwhile (a
/// full pipe never holds it); kills and reaps it, and fails naming `what`, if it does not.
pub fn exits_within(
    mut child: std::process::Child,
    limit: Duration,
    what: &str,
) -> std::process::Output {
    // Each pipe is read to its end on a thread of its own, handed over through a channel so
    // that a killed scanhil's emulator (which shares its stderr) cannot hold the failure up.
    let drain = |pipe: Option<Box<dyn std::io::Read + Send>>| {
        let (sender, receiver) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut text = Vec::new();
            if let Some(mut pipe) = pipe {
                let _ = pipe.read_to_end(&mut text);
            }
            let _ = sender.send(text);
        });
        receiver
    };
    let stdout = drain(child.stdout.take().map(|p| Box::new(p) as _));
    let stderr = drain(child.stderr.take().map(|p| Box::new(p) as _));
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("polling scanhil") {
            break status;
        }
        if started.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            let stderr = stderr
                .recv_timeout(Duration::from_secs(2))
                .unwrap_or_default();
            panic!(
                "{what}: scanhil still running after {limit:?}; stderr:\n{}",
                String::from_utf8_lossy(&stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Output {
        status,
        stdout: stdout.recv().unwrap_or_default(),
        stderr: stderr.recv().unwrap_or_default(),
    }
}
