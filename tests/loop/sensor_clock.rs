//! The real-sensor clock path and the sensor's line: a real ILD declares no clock, so the
//! host estimates it from arrivals and pairs the samples with it.
//!
//! - With the counter: the Duplo stud scan at a sensor rate whose two values a cycle fit the
//!   factory baud rate (10 kHz; 20 kHz would need 1.32 MBaud), on a sensor with a clock of its
//!   own (sample 0 at 40 us, counter from 250 000, wrapping mid-run), once with the emulator the
//!   host starts (which declares `counter_zero_s`), once against an emulator started apart
//!   (`--no-emulator`, as real devices are: nothing declared). Both runs see the same bytes;
//!   only the clock differs.
//! - The distance alone, the real 20 kHz configuration at 691 200 baud, against an emulator
//!   started apart: the samples are placed by their arrival alone, and the stud is measured
//!   within 0.02 mm.
//! - The same scan with the counter as well at 20 kHz is refused before any output, naming
//!   the rate, the values, the baud and the baud it needs.
//!
//! Lockstep, not real time: every byte of two runs is the same, so any difference in the
//! result is the clock alone; in real time this shared machine does not hold 20 kHz and two
//! runs' tracking (and so their point clouds) would differ for reasons of their own.
//!
//! Tolerances, from the estimate's bound: in lockstep an arrival is known on the loop axis
//! only to the period in which it came, and a cycle's last byte arrives its transmit time
//! after it was measured (the emulated line paces it), which the estimate takes off; so the
//! estimate lies within one control period after the true instant, never before.

use std::path::Path;

use crate::util::{ServedEmulator, assert_success, fixture, number, report, run_scanhil};

/// The control period, s (20 kHz).
const PERIOD_S: f64 = 5e-5;
/// The sensor's rate with the counter: two values a cycle fit 691 200 baud (660 000 needed).
const COUNTED_RATE_HZ: f64 = 10_000.0;
/// The sensor's clock in the counter's scene: sample 0 at this loop time, s, ...
const CLOCK_OFFSET_S: f64 = 4e-5;
/// ... with this counter value (18 bits: it wraps 1.2 s into the run).
const COUNTER_START: u64 = 250_000;
/// Stud heights of the two runs may differ by this much, mm: the estimate moves each sample
/// by under a period, about 50 urad of mirror angle at the Lissajous' peak speed, 13 um on
/// the brick, which shifts only the stud's rim cells.
const HEIGHT_DIFFERENCE_MM: f64 = 0.005;
/// The stud height of the Duplo scene, mm (the paper's mechanical reference).
const STUD_HEIGHT_MM: f64 = 4.663;
/// The stud measured on the arrival path may differ from it by this much, mm.
const STUD_TOLERANCE_MM: f64 = 0.02;

/// Writes the Duplo scene with the sensor at `rate_hz` (and, when given, its own clock), a
/// paper-bench rig with that sensor rate and `extra_values`, and test-duplo-stud pointing at
/// both. Returns the scene's and the scenario's paths.
fn write_fixtures(
    dir: &Path,
    rate_hz: f64,
    extra_values: &[&str],
    clock: Option<(f64, u64)>,
) -> (String, String) {
    let read = |relative: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(fixture(relative)).expect(relative))
            .expect("fixture JSON")
    };
    let write = |name: &str, value: &serde_json::Value| {
        let path = dir.join(name);
        std::fs::write(&path, value.to_string()).expect("writing a fixture");
        path.to_str().expect("UTF-8 path").to_owned()
    };
    let mut scene = read("scenes/duplo-2x4-130mm.json");
    scene["sensor"]["measuring_rate_hz"] = rate_hz.into();
    if let Some((offset_s, counter_start)) = clock {
        scene["sensor"]["clock_offset_s"] = offset_s.into();
        scene["sensor"]["counter_start"] = counter_start.into();
    }
    let scene = write("duplo.json", &scene);
    let mut rig = read("rigs/paper-bench.json");
    rig["sensor"]["measuring_rate_hz"] = rate_hz.into();
    rig["sensor"]["extra_values"] = extra_values.into();
    let rig = write("rig.json", &rig);
    let mut scenario = read("scenarios/test-duplo-stud.json");
    scenario["rig"] = rig.into();
    scenario["controller"] = fixture("controllers/pid-series.json").into();
    scenario["scene"] = scene.clone().into();
    (scene, write("scenario.json", &scenario))
}

/// `scanhil scan SCENARIO --no-emulator` against an emulator of `scene` started apart, as real
/// devices are, into `out`.
fn scan_of_devices_started_apart(scene: &str, scenario: &str, out: &Path) {
    let emulator = ServedEmulator::start(&[
        "--scene",
        scene,
        "--seed",
        "7",
        "--fsm",
        "slcan:pty",
        "--sensor",
        "ild:pty",
        "--watchdog-periods",
        "200",
        "--lockstep-answer-allowance-s",
        "0.05",
        "--timing",
        "lockstep",
    ]);
    let output = run_scanhil(&[
        "scan",
        scenario,
        "--no-emulator",
        "--fsm",
        &format!("slcan:{}", emulator.path("fsm")),
        "--sensor",
        &format!("ild:{}", emulator.path("sensor")),
        "--out",
        out.to_str().expect("UTF-8 path"),
    ]);
    assert_success(&output, "scan with the estimated sensor clock");
    drop(emulator);
}

#[test]
fn the_estimated_sensor_clock_gives_the_declared_clocks_scan() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let (scene, scenario) = write_fixtures(
        dir.path(),
        COUNTED_RATE_HZ,
        &["counter"],
        Some((CLOCK_OFFSET_S, COUNTER_START)),
    );

    // Declared: the host starts the emulator, whose summary gives counter_zero_s.
    let declared_dir = dir.path().join("declared");
    let declared_out = declared_dir.to_str().expect("UTF-8 path");
    let output = run_scanhil(&["scan", &scenario, "--out", declared_out]);
    assert_success(&output, "scan with the declared sensor clock");
    // Estimated: the emulator started apart, as real devices are; nothing declared.
    let estimated_dir = dir.path().join("estimated");
    scan_of_devices_started_apart(&scene, &scenario, &estimated_dir);

    let declared = report(&declared_dir);
    let estimated = report(&estimated_dir);
    assert!(
        estimated["emulator"].is_null(),
        "no emulator summary on the real-sensor path: {}",
        estimated["emulator"]
    );
    assert_eq!(
        declared["sensor_setup"]["output_values"],
        serde_json::json!(["DIST1", "COUNTER"])
    );

    // The declared clock is the scene's; the estimate lies within one period after it.
    let declared_zero_s = number(&declared, "/samples/sensor_clock/counter_zero_s");
    let true_zero_s = CLOCK_OFFSET_S - COUNTER_START as f64 / COUNTED_RATE_HZ;
    assert!(
        (declared_zero_s - true_zero_s).abs() < 1e-9,
        "declared {declared_zero_s} s, scene {true_zero_s} s"
    );
    let estimated_zero_s = number(&estimated, "/samples/sensor_clock/counter_zero_s");
    let late_s = estimated_zero_s - declared_zero_s;
    assert!(
        (-1e-9..=PERIOD_S).contains(&late_s),
        "estimate {estimated_zero_s} s is {late_s} s after the declared {declared_zero_s} s \
         (allowed: 0 to one period, {PERIOD_S} s)"
    );

    let paired = |r: &serde_json::Value| number(r, "/samples/paired");
    let height = |r: &serde_json::Value| number(r, "/imaging/feature/height_mm");
    let samples = |r: &serde_json::Value| number(r, "/samples/sensor_samples");
    eprintln!(
        "clock late by {late_s} s; stud {} / {} mm; samples {} / {}, paired {} / {}",
        height(&declared),
        height(&estimated),
        samples(&declared),
        samples(&estimated),
        paired(&declared),
        paired(&estimated),
    );
    // The same samples (the run started apart may miss the last cycles: the host's drain
    // ends the stream without the end-of-run exchange of the emulator it started), paired
    // the same way but for the frame's two edges.
    assert!(
        (samples(&declared) - samples(&estimated)).abs() <= 2.0,
        "samples: declared {}, estimated {}",
        samples(&declared),
        samples(&estimated)
    );
    assert!(
        (paired(&declared) - paired(&estimated)).abs() <= 2.0,
        "paired: declared {}, estimated {}",
        paired(&declared),
        paired(&estimated)
    );
    // Tracking is the loop's, not the pairing's: identical.
    assert_eq!(declared["tracking_error"], estimated["tracking_error"]);

    let difference = (height(&declared) - height(&estimated)).abs();
    assert!(
        difference <= HEIGHT_DIFFERENCE_MM,
        "stud height: declared {} mm, estimated {} mm",
        height(&declared),
        height(&estimated)
    );
}

#[test]
fn the_distance_alone_at_20_khz_pairs_by_arrival_and_measures_the_stud() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let (scene, scenario) = write_fixtures(dir.path(), 20_000.0, &[], None);
    let out = dir.path().join("out");
    scan_of_devices_started_apart(&scene, &scenario, &out);
    let report = report(&out);
    assert_eq!(
        report["sensor_setup"]["output_values"],
        serde_json::json!(["DIST1"]),
        "{}",
        report["sensor_setup"]
    );
    assert_eq!(report["links"]["sensor"]["counter_gaps"], 0);
    // The arrival bound, less the line's 43.4 us per cycle: within a period after the true
    // instant of the first cycle the host counts (the sensor's first sample, at the end of
    // period 0: 50 us).
    let zero_s = number(&report, "/samples/sensor_clock/counter_zero_s");
    assert!(
        (PERIOD_S - 1e-9..=2.0 * PERIOD_S).contains(&zero_s),
        "estimated first sample at {zero_s} s, measured at {PERIOD_S} s"
    );
    let height = number(&report, "/imaging/feature/height_mm");
    eprintln!(
        "by arrival alone: first sample estimated at {zero_s} s; stud {height} mm; samples {}, \
         paired {}",
        number(&report, "/samples/sensor_samples"),
        number(&report, "/samples/paired")
    );
    assert!(
        (height - STUD_HEIGHT_MM).abs() < STUD_TOLERANCE_MM,
        "stud {height} mm by arrival alone, truth {STUD_HEIGHT_MM} mm"
    );
}

#[test]
fn the_counter_at_20_khz_does_not_fit_the_factory_baud_and_is_refused_before_any_output() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let (_, scenario) = write_fixtures(dir.path(), 20_000.0, &["counter"], None);
    let out = dir.path().join("out");
    let output = run_scanhil(&["scan", &scenario, "--out", out.to_str().expect("UTF-8")]);
    assert_eq!(output.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains(
            "field `sensor.extra_values`: the ILD line at 691200 baud cannot carry 2 value(s) \
             per cycle (DIST1 COUNTER) at 20 kHz: the manual's rule BR > 33 x MR x m / ODR \
             needs more than 1320000 baud"
        ),
        "{stderr}"
    );
    assert!(!out.exists(), "nothing written before the refusal");
}
