//! A recorded session served as the devices (`scanhil scan --replay`, `scanhil-emulator
//! replay`): the recording's own controller reproduces its outputs bit for bit, a changed one
//! is reported from its first diverging period, a bench-style capture replays the same, a
//! recording with a line missing is refused naming the line, and in real time the session is
//! served at its recorded times (a stall in the recording is a stall of the replay).
//!
//! The recording is `fixtures/recordings/replay-small/`: `fsm.log`, `sensor.ild`,
//! `report.json` and `points.ply` as `scanhil scan fixtures/scenarios/test-replay-small.json`
//! wrote them (docs/loop.md#replaying-a-recorded-session says how to make it again).

use std::path::{Path, PathBuf};
use std::process::Command;

use scanhil_protocol::candump::parse_line;
use scanhil_protocol::message::{CoilCommand, Message, NodeId};

use crate::util::{
    RUN_LIMIT, assert_coils_at_zero, assert_success, emulator, exits_within, fixture, report, root,
    run_scanhil,
};

const SCENARIO: &str = "scenarios/test-replay-small.json";

fn recording() -> PathBuf {
    root().join("fixtures/recordings/replay-small")
}

/// `scanhil scan SCENARIO --replay DIR --out OUT` and `extra`.
fn replay_scan(scenario: &str, dir: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "scan",
        scenario,
        "--replay",
        dir.to_str().expect("UTF-8 path"),
        "--out",
        out.to_str().expect("UTF-8 path"),
    ];
    args.extend(extra);
    run_scanhil(&args)
}

fn assert_same_file(first: &Path, second: &Path) {
    let read =
        |path: &Path| std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(
        read(first) == read(second),
        "{} and {} differ",
        first.display(),
        second.display()
    );
}

/// Asserts `out` holds the recording's outputs bit for bit: the mirror link's and the sensor's
/// recordings, the point cloud, and the report's imaging, samples and tracking.
fn assert_reproduces_the_recording(out: &Path) {
    for file in ["fsm.log", "sensor.ild", "points.ply"] {
        assert_same_file(&recording().join(file), &out.join(file));
    }
    let (mut recorded, mut replayed) = (report(&recording()), report(out));
    // The truth scene's path is where the checkout is, not a figure.
    for report in [&mut recorded, &mut replayed] {
        let truth = report["imaging"]["truth"].take();
        assert!(
            truth
                .as_str()
                .is_some_and(|path| path.ends_with("duplo-2x4-130mm.json"))
        );
    }
    for section in ["imaging", "samples", "tracking_error", "periods"] {
        assert_eq!(
            recorded[section], replayed[section],
            "report.json `{section}` differs"
        );
    }
    assert!(
        replayed["imaging"]["points"]
            .as_u64()
            .is_some_and(|n| n > 100),
        "the recording images its points: {}",
        replayed["imaging"]
    );
}

#[test]
fn the_recordings_controller_reproduces_its_outputs_bit_for_bit() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let output = replay_scan(
        &fixture(SCENARIO),
        &recording(),
        out.path(),
        &["--replay-must-match"],
    );
    assert_success(&output, "scanhil scan --replay --replay-must-match");
    assert_reproduces_the_recording(out.path());
    let report = report(out.path());
    let replay = &report["replay"];
    assert_eq!(
        replay["first_divergence"],
        serde_json::Value::Null,
        "{replay}"
    );
    assert_eq!(replay["differing"], 0, "{replay}");
    // Every period's command and the zero command at the end, each with its recorded one.
    assert_eq!(replay["compared"], 301, "{replay}");
    assert_eq!(replay["not_recorded"], 0, "{replay}");
    assert_eq!(
        report["outcome"]["verdict"], "complete",
        "{}",
        report["outcome"]
    );
    assert_coils_at_zero(&report);
    assert_eq!(report["emulator"]["summary"]["node"]["periods"], 300);
    assert_eq!(report["emulator"]["summary"]["node"]["sensor_cycles"], 300);
}

/// The coil commands of a candump log, in order.
fn commands(path: &Path) -> Vec<CoilCommand> {
    let text = std::fs::read_to_string(path).expect("the log");
    text.lines()
        .filter_map(
            |line| match Message::decode(&parse_line(line).expect("a frame line").frame) {
                Ok(Message::CoilCommand(command)) => Some(command),
                _ => None,
            },
        )
        .collect()
}

/// The test's own scenario: the recording's, under the paper's PID with `kp` changed.
fn changed_controller(dir: &Path) -> String {
    let fixtures = root().join("fixtures");
    let controller: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(fixtures.join("controllers/pid-series.json")).expect("the PID"),
    )
    .expect("JSON");
    let mut changed = controller.clone();
    changed["law"]["kp"] = serde_json::json!(3.0);
    assert_ne!(changed, controller);
    let controller_path = dir.join("pid-kp-3.json");
    std::fs::write(&controller_path, changed.to_string()).expect("writing the controller");
    let mut scenario: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fixture(SCENARIO)).expect("the scenario"))
            .expect("JSON");
    scenario["rig"] = fixtures
        .join("rigs/paper-bench.json")
        .display()
        .to_string()
        .into();
    scenario["scene"] = fixtures
        .join("scenes/duplo-2x4-130mm.json")
        .display()
        .to_string()
        .into();
    scenario["controller"] = controller_path.display().to_string().into();
    let path = dir.join("scenario.json");
    std::fs::write(&path, scenario.to_string()).expect("writing the scenario");
    path.display().to_string()
}

#[test]
fn a_changed_controller_is_reported_from_its_first_diverging_period() {
    let work = tempfile::tempdir().expect("a temporary folder");
    let scenario = changed_controller(work.path());
    let out = work.path().join("out");
    let output = replay_scan(&scenario, &recording(), &out, &[]);
    // Open loop: the replay answers whatever is commanded, and the divergence is a note.
    assert_success(&output, "scanhil scan --replay with another controller");
    let report = report(&out);
    let replay = &report["replay"];
    // The host's own recording against the session's, command by command.
    let (ours, recorded) = (
        commands(&out.join("fsm.log")),
        commands(&recording().join("fsm.log")),
    );
    assert_eq!(ours.len(), recorded.len());
    let first = ours
        .iter()
        .zip(&recorded)
        .position(|(a, b)| a != b)
        .expect("a changed gain changes a command");
    let differing = ours.iter().zip(&recorded).filter(|(a, b)| a != b).count();
    assert_eq!(replay["first_divergence"]["period"], first, "{replay}");
    assert_eq!(replay["differing"], differing, "{replay}");
    assert_eq!(replay["compared"], recorded.len(), "{replay}");
    for (axis, ua) in [
        ("a", ours[first].current_a_ua - recorded[first].current_a_ua),
        ("b", ours[first].current_b_ua - recorded[first].current_b_ua),
    ] {
        assert_eq!(
            replay["first_divergence"]["difference_a"][axis],
            f64::from(ua) / 1e6,
            "{replay}"
        );
    }
    let notes = report["outcome"]["notes"].to_string();
    assert!(
        notes.contains(&format!("differ from the recording's from period {first}")),
        "{notes}"
    );
    // The mirror moved as recorded: the same angles, so the same points.
    assert_same_file(&recording().join("points.ply"), &out.join("points.ply"));

    // A regression check in CI: the divergence fails the run.
    let strict = work.path().join("strict");
    let output = replay_scan(&scenario, &recording(), &strict, &["--replay-must-match"]);
    assert_eq!(output.status.code(), Some(4), "{output:?}");
    let reasons = crate::util::report(&strict)["outcome"]["reasons"].to_string();
    assert!(reasons.contains("--replay-must-match"), "{reasons}");
}

#[test]
fn a_bench_capture_on_can0_with_epoch_stamps_replays_the_same() {
    // The session as a technician's `candump -L -x can0` would have it: another interface,
    // epoch stamps, the direction column.
    let capture = tempfile::tempdir().expect("a temporary folder");
    let text = std::fs::read_to_string(recording().join("fsm.log")).expect("the log");
    let mut bench = String::new();
    for line in text.lines() {
        let entry = parse_line(line).expect("a frame line");
        let stamp = entry.timestamp.as_secs_f64() + 1_764_671_234.0;
        let (_, frame) = line.split_once(" fsm ").expect("the interface");
        let from_node = match Message::decode(&entry.frame) {
            Ok(Message::AngleReading(_)) => true,
            Ok(Message::Status(status)) => status.node == NodeId::Fsm,
            _ => false,
        };
        let direction = if from_node { 'R' } else { 'T' };
        bench += &format!("({stamp:.6}) can0 {frame} {direction}\n");
    }
    assert!(bench.contains("can0") && !bench.contains(" fsm "));
    std::fs::write(capture.path().join("fsm.log"), bench).expect("writing the capture");
    for file in ["sensor.ild", "report.json"] {
        std::fs::copy(recording().join(file), capture.path().join(file)).expect("copying");
    }
    let out = tempfile::tempdir().expect("a temporary folder");
    let output = replay_scan(
        &fixture(SCENARIO),
        capture.path(),
        out.path(),
        &["--replay-must-match"],
    );
    assert_success(&output, "scanhil scan --replay of a bench capture");
    assert_reproduces_the_recording(out.path());
}

#[test]
fn a_recording_with_a_line_removed_is_refused_naming_the_line() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let text = std::fs::read_to_string(recording().join("fsm.log")).expect("the log");
    // Period 100's AngleReading (counter 100 = 0x0064, little-endian first).
    let removed = text
        .lines()
        .position(|line| line.contains(" 110#6400"))
        .expect("period 100's reading");
    let kept: Vec<&str> = text
        .lines()
        .enumerate()
        .filter_map(|(i, line)| (i != removed).then_some(line))
        .collect();
    std::fs::write(dir.path().join("fsm.log"), kept.join("\n") + "\n").expect("writing");
    std::fs::copy(
        recording().join("sensor.ild"),
        dir.path().join("sensor.ild"),
    )
    .expect("copying");
    // The line after the removed one now holds the next period's reading.
    let line = kept[removed..]
        .iter()
        .position(|line| line.contains(" 110#"))
        .expect("a later reading")
        + removed
        + 1;
    let expected = format!(
        "fsm.log: line {line}: AngleReading counter 101 where period 100 (counter 100) was next"
    );

    // The emulator refuses it before any link opens: no ready line.
    let child = Command::new(emulator())
        .args([
            "replay",
            dir.path().to_str().expect("UTF-8 path"),
            "--scene",
        ])
        .arg(fixture("scenes/duplo-2x4-130mm.json"))
        .args(["--fsm", "slcan:pty"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("starting the emulator");
    let output = exits_within(child, RUN_LIMIT, "scanhil-emulator replay");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(output.stdout.is_empty(), "no ready line: {output:?}");
    assert!(stderr.contains(&expected), "{stderr}");

    // A scan against it ends before its loop, the emulator's reason on its stderr.
    let out = tempfile::tempdir().expect("a temporary folder");
    let output = replay_scan(&fixture(SCENARIO), dir.path(), out.path(), &[]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains(&expected), "{stderr}");
    assert!(!out.path().join("fsm.log").exists(), "no link opened");
}

#[test]
fn replay_flags_that_cannot_apply_are_refused_before_any_link_opens() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let dir = recording();
    let output = replay_scan(&fixture(SCENARIO), &dir, out.path(), &["--no-emulator"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("--replay") && stderr.contains("not with --no-emulator"),
        "{stderr}"
    );
    let output = run_scanhil(&[
        "scan",
        &fixture(SCENARIO),
        "--replay-must-match",
        "--out",
        out.path().to_str().expect("UTF-8 path"),
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("--replay-must-match: needs --replay DIR"),
        "{stderr}"
    );
    assert!(!out.path().join("fsm.log").exists(), "no link opened");
}

/// The watchdog of the real-time replays, periods: 1 s at 20 kHz, so a loaded machine's stalls
/// (and the 0.2 s stall recorded below) are no silence.
const REALTIME_WATCHDOG_PERIODS: &str = "20000";

/// The recording's folder copied to `dir` with every stamp from `from_s` on moved `by_s` later.
fn recording_with_a_stall(dir: &Path, from_s: f64, by_s: f64) {
    for file in ["sensor.ild", "report.json"] {
        std::fs::copy(recording().join(file), dir.join(file)).expect("copying the recording");
    }
    let log = std::fs::read_to_string(recording().join("fsm.log")).expect("the recording");
    let stalled: String = log
        .lines()
        .map(|line| {
            let (stamp, rest) = line
                .strip_prefix('(')
                .and_then(|line| line.split_once(')'))
                .expect("a candump -L line");
            let t_s: f64 = stamp.parse().expect("a stamp");
            let t_s = if t_s >= from_s { t_s + by_s } else { t_s };
            format!("({t_s:.6}){rest}\n")
        })
        .collect();
    std::fs::write(dir.join("fsm.log"), stalled).expect("writing the stalled recording");
}

#[test]
fn a_real_time_replay_answers_every_command_of_the_recordings_controller() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let output = replay_scan(
        &fixture(SCENARIO),
        &recording(),
        out.path(),
        &[
            "--timing",
            "realtime",
            "--watchdog-periods",
            REALTIME_WATCHDOG_PERIODS,
        ],
    );
    assert_success(&output, "scanhil scan --replay --timing realtime");
    let report = report(out.path());
    let replay = &report["replay"];
    // Real time has no CoilCommand(0): the host answers reading k with the command of k + 1,
    // each compared with the recorded one of its period, the end's zero command included.
    assert_eq!(replay["compared"], 300, "{replay}");
    assert_eq!(replay["not_recorded"], 0, "{replay}");
    let node = &report["emulator"]["summary"]["node"];
    assert_eq!(node["periods"], 300, "{node}");
    assert_eq!(node["sensor_cycles"], 300, "{node}");
    assert_eq!(
        report["outcome"]["verdict"], "complete",
        "{}",
        report["outcome"]
    );
    assert_coils_at_zero(&report);
    // The readings reached the host as recorded: the same angles, so with none missed the
    // recording's controller commands what it commanded then.
    if report["timing"]["controller"]["missed_readings"] == 0 {
        assert_eq!(replay["differing"], 0, "{replay}");
    }
}

#[test]
fn a_real_time_replay_keeps_the_recorded_timing() {
    // The recording's stamps from period 150 on (7.5 ms) are moved 0.2 s later: the replay
    // holds its readings back that long, as a session that stalled there would have.
    let dir = tempfile::tempdir().expect("a temporary folder");
    recording_with_a_stall(dir.path(), 0.0075, 0.2);
    let out = tempfile::tempdir().expect("a temporary folder");
    let output = replay_scan(
        &fixture(SCENARIO),
        dir.path(),
        out.path(),
        &[
            "--timing",
            "realtime",
            "--watchdog-periods",
            REALTIME_WATCHDOG_PERIODS,
        ],
    );
    assert_success(&output, "scanhil scan --replay DIR --timing realtime");
    let report = report(out.path());
    let interval = &report["timing"]["controller"]["reading_interval"];
    let longest_s = interval["max_s"].as_f64().expect("the longest interval");
    assert!(
        (0.19..1.0).contains(&longest_s),
        "the recorded 0.2 s stall between two readings: {interval}"
    );
    assert_eq!(report["emulator"]["summary"]["node"]["periods"], 300);
}
