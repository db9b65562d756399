//! The bench-like scene (`duplo-2x4-130mm-bench`: second mode, cross-talk pickup, OPA544
//! current loop, angle sensor bandwidth, nonlinearity and noise) over ptys: `scanhil identify`
//! sees it differ from eq. 4 only where its parts act, and the paper's PID, designed on eq. 4,
//! still scans the Duplo stud and tracks within its band of the nominal prediction.

use crate::util::{
    assert_coils_at_zero, assert_success, assert_tracks_as_predicted, fixture, number, report,
    run_scanhil,
};

/// The stud height of the Duplo scene, mm (the paper's mechanical reference).
const STUD_HEIGHT_MM: f64 = 4.663;
/// The measured (mean) stud height may differ from the truth by this much, mm (as the nominal
/// scene's test; measured: 10 um low).
const HEIGHT_TOLERANCE_MM: f64 = 0.02;
/// Below 100 Hz the bench-like mirror is eq. 4 to within this much, dB (issue 22).
const LOW_BAND_DB: f64 = 0.5;

/// Runs `scanhil identify` over a pty against the bench-like scene with the options `args`
/// (separated by spaces); the report's points.
fn identify(out: &std::path::Path, name: &str, args: &str) -> Vec<serde_json::Value> {
    let file = out.join(format!("{name}.json"));
    let scene = fixture("scenes/duplo-2x4-130mm-bench.json");
    let mut all = vec![
        "identify",
        "--fsm",
        "pty",
        "--scene",
        &scene,
        "--axis",
        "alpha",
        "--out",
        file.to_str().expect("UTF-8 path"),
    ];
    all.extend(args.split_whitespace());
    let output = run_scanhil(&all);
    assert_success(&output, &format!("scanhil identify ({name})"));
    let text = std::fs::read_to_string(&file).expect("identify wrote its report");
    let json: serde_json::Value = serde_json::from_str(&text).expect("the report is JSON");
    json["points"].as_array().expect("points").clone()
}

#[test]
fn identify_sees_the_bench_mirror_differ_from_eq_4_only_where_its_parts_act() {
    let out = tempfile::tempdir().expect("a temporary folder");
    // Below 100 Hz: eq. 4 within 0.5 dB (measured: 0.0003 and 0.05 dB at 30 and 90 Hz); a
    // settle of 1 s lets the 22 Hz resonance's start-up ring decay (time constant 0.22 s).
    let low = identify(
        out.path(),
        "low",
        "--from-hz 30 --to-hz 90 --points 2 --settle-s 1.0 --cycles 4 --blocks 2 --amplitude 0.05",
    );
    assert_eq!(low.len(), 2);
    for point in &low {
        let error_db = number(point, "/magnitude_error_db");
        assert!(error_db.abs() < LOW_BAND_DB, "below 100 Hz: {point:#}");
        assert!(number(point, "/measured/coherence") > 0.999, "{point:#}");
    }
    // Above: the second mode's resonance at 1.2 kHz (+28 dB over eq. 4: 1 / (2 x 0.02)), and
    // the cross-talk risen from eq. 4's -20 dB by the pickup's flat path (-2.8 dB at 2 kHz).
    // 1 A of excitation keeps the response above the sensor's 3 urad noise.
    let high = identify(
        out.path(),
        "high",
        "--from-hz 1200 --to-hz 2000 --points 2 --settle-s 0.1 --cycles 20 --blocks 2 --amplitude 1",
    );
    let resonance = &high[0];
    assert!(
        number(resonance, "/magnitude_error_db") > 20.0,
        "no second resonance: {resonance:#}"
    );
    let top = &high[1];
    let cross_db = number(top, "/measured/cross_axis_db") - number(top, "/measured/magnitude_db");
    assert!(
        cross_db > -10.0,
        "the cross-talk did not rise: {cross_db} dB, {top:#}"
    );
}

#[test]
fn the_papers_pid_scans_the_stud_on_the_bench_like_mirror_as_predicted() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let output = run_scanhil(&[
        "scan",
        &fixture("scenarios/test-duplo-stud-bench.json"),
        "--out",
        out.path().to_str().expect("UTF-8 path"),
    ]);
    assert_success(&output, "scanhil scan test-duplo-stud-bench");
    let report = report(out.path());
    assert_coils_at_zero(&report);
    // The parts act above 400 Hz, the Lissajous at 27 and 52 Hz: the loop tracks as the
    // nominal prediction says, in the nominal scene's band (measured / predicted: alpha 1.007,
    // beta 1.20 with alpha's cross-talk). Too good fails as well as too bad.
    assert_tracks_as_predicted(&report, &[("alpha", (0.97, 1.10)), ("beta", (1.0, 1.4))]);
    assert_eq!(number(&report, "/periods/saturated_in_frame"), 0.0);
    let height = number(&report, "/imaging/feature/height_mm");
    assert!(
        (height - STUD_HEIGHT_MM).abs() < HEIGHT_TOLERANCE_MM,
        "stud height {height} mm, truth {STUD_HEIGHT_MM} mm"
    );
    // The richer parts are listed, each with what it cost.
    let parts = report
        .pointer("/emulator/summary/parts/parts")
        .and_then(serde_json::Value::as_array)
        .expect("the emulator's summary lists the parts");
    for wanted in [
        "second_mode",
        "cross_talk_pickup",
        "current_loop",
        "angle_sensor_bandwidth",
        "angle_sensor_nonlinearity",
    ] {
        let part = parts
            .iter()
            .find(|p| p["part"] == wanted)
            .unwrap_or_else(|| panic!("{wanted} not in {parts:?}"));
        assert!(part["us_per_period"].as_f64().is_some_and(|us| us >= 0.0));
    }
}
