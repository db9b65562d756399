//! The real-sensor clock path: a real ILD declares no clock, so the host estimates it from
//! arrivals (`estimate_sensor_clock`) and pairs the samples with it. The Duplo stud scan is
//! run twice in lockstep on a sensor with a clock of its own (sample 0 at 40 us, counter
//! starting at 250 000, so it wraps mid-run): once with the emulator the host starts (which
//! declares `counter_zero_s`), once against an emulator started apart (`--no-emulator`, as
//! real devices are: nothing declared). Both runs see the same bytes; only the clock differs.
//!
//! Lockstep, not real time: every byte of the two runs is the same, so any difference in the
//! result is the clock alone; in real time this shared machine does not hold 20 kHz and the
//! two runs' tracking (and so their point clouds) would differ for reasons of their own.
//!
//! Tolerances, from the estimate's bound: in lockstep an arrival is known on the loop axis
//! only to the period in which it came, so the estimate lies within one control period
//! (50 us) after the true `counter_zero_s`, never before. Here the last sample of a period
//! sits 10 us before its end, so the estimate is 10 us late; a clock off by one sample period
//! (50 us more) falls outside.

use std::path::Path;

use crate::util::{ServedEmulator, assert_success, fixture, number, report, run_scanhil};

/// The control period, s (20 kHz).
const PERIOD_S: f64 = 5e-5;
/// The sensor's clock in the test scene: sample 0 at this loop time, s, ...
const CLOCK_OFFSET_S: f64 = 4e-5;
/// ... with this counter value (18 bits: it wraps 0.6 s into the run).
const COUNTER_START: u64 = 250_000;
/// Stud heights of the two runs may differ by this much, mm: the estimate moves each sample
/// by 10 us, about 50 urad of mirror angle at the Lissajous' peak speed, 13 um on the brick,
/// which shifts only the stud's rim cells.
const HEIGHT_DIFFERENCE_MM: f64 = 0.005;

/// Writes the Duplo scene with the sensor's own clock, and test-duplo-stud pointing at it.
fn write_fixtures(dir: &Path) -> (String, String) {
    let mut scene: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(fixture("scenes/duplo-2x4-130mm.json")).expect("the scene"),
    )
    .expect("scene JSON");
    scene["sensor"]["clock_offset_s"] = CLOCK_OFFSET_S.into();
    scene["sensor"]["counter_start"] = COUNTER_START.into();
    let scene_path = dir.join("duplo-own-sensor-clock.json");
    std::fs::write(&scene_path, scene.to_string()).expect("writing the scene");
    let mut scenario: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(fixture("scenarios/test-duplo-stud.json")).expect("the scenario"),
    )
    .expect("scenario JSON");
    scenario["rig"] = fixture("rigs/paper-bench.json").into();
    scenario["controller"] = fixture("controllers/pid-series.json").into();
    scenario["scene"] = scene_path.to_str().expect("UTF-8 path").into();
    let scenario_path = dir.join("test-duplo-stud-own-clock.json");
    std::fs::write(&scenario_path, scenario.to_string()).expect("writing the scenario");
    (
        scene_path.to_str().expect("UTF-8").to_owned(),
        scenario_path.to_str().expect("UTF-8").to_owned(),
    )
}

#[test]
fn the_estimated_sensor_clock_gives_the_declared_clocks_scan() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let (scene, scenario) = write_fixtures(dir.path());

    // Declared: the host starts the emulator, whose summary gives counter_zero_s.
    let declared_dir = dir.path().join("declared");
    let declared_out = declared_dir.to_str().expect("UTF-8 path");
    let output = run_scanhil(&["scan", &scenario, "--out", declared_out]);
    assert_success(&output, "scan with the declared sensor clock");

    // Estimated: the emulator started apart, as real devices are; nothing declared.
    let emulator = ServedEmulator::start(&[
        "--scene",
        &scene,
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
    let estimated_dir = dir.path().join("estimated");
    let estimated_out = estimated_dir.to_str().expect("UTF-8 path");
    let output = run_scanhil(&[
        "scan",
        &scenario,
        "--no-emulator",
        "--fsm",
        &format!("slcan:{}", emulator.path("fsm")),
        "--sensor",
        &format!("ild:{}", emulator.path("sensor")),
        "--out",
        estimated_out,
    ]);
    assert_success(&output, "scan with the estimated sensor clock");
    drop(emulator);

    let declared = report(&declared_dir);
    let estimated = report(&estimated_dir);
    assert!(
        estimated["emulator"].is_null(),
        "no emulator summary on the real-sensor path: {}",
        estimated["emulator"]
    );

    // The declared clock is the scene's; the estimate lies within one period after it.
    let declared_zero_s = number(&declared, "/samples/sensor_clock/counter_zero_s");
    let true_zero_s = CLOCK_OFFSET_S - COUNTER_START as f64 / 20_000.0;
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
    eprintln!(
        "clock late by {late_s} s; stud {} / {} mm; samples {} / {}, paired {} / {}; \
         stud points {} / {}",
        height(&declared),
        height(&estimated),
        number(&declared, "/samples/sensor_samples"),
        number(&estimated, "/samples/sensor_samples"),
        paired(&declared),
        paired(&estimated),
        number(&declared, "/imaging/feature/points"),
        number(&estimated, "/imaging/feature/points"),
    );
    // The same samples (the run started apart may miss the last period's one: the host's
    // drain ends the stream without the end-of-run handshake of the emulator it started),
    // paired the same way but for the frame's two edges.
    let samples = |r: &serde_json::Value| number(r, "/samples/sensor_samples");
    assert!(
        (samples(&declared) - samples(&estimated)).abs() <= 1.0,
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
