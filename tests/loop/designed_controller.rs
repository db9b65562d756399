//! A controller `scanhil design` made for the rate a 1 Mbit/s bus carries, in a whole scan:
//! the Duplo brick at 2736 Hz over SLCAN on a pty, tracking as its design predicts.

use crate::util::{
    assert_success, assert_tracks_as_predicted, fixture, number, report, run_scanhil,
};

/// The stud height of the Duplo scene, mm (the paper's mechanical reference).
const STUD_HEIGHT_MM: f64 = 4.663;
/// What the designed loop must measure the stud to, mm (measured: 4.6 um low).
const HEIGHT_TOLERANCE_MM: f64 = 0.05;
/// The stud-top median, which the rim's averaged points do not move, mm (measured: 0.05 um).
const MEDIAN_TOLERANCE_MM: f64 = 0.005;

#[test]
fn the_dual_tone_designed_for_a_1_mbit_bus_scans_the_duplo_stud() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let output = run_scanhil(&[
        "scan",
        &fixture("scenarios/duplo-lissajous-dual-tone-1mbit.json"),
        "--out",
        out.path().to_str().expect("UTF-8 path"),
    ]);
    assert_success(&output, "scanhil scan duplo-lissajous-dual-tone-1mbit");
    let report = report(out.path());
    assert_eq!(number(&report, "/rig/control_rate_hz"), 2736.0);
    // The loop tracks as the design predicts (measured / predicted: alpha 1.01, beta 1.04; the
    // beta axis also carries alpha's cross-talk, which the one-axis prediction leaves out).
    // Too good fails as well as too bad.
    assert_tracks_as_predicted(&report, &[("alpha", (0.97, 1.1)), ("beta", (0.97, 1.2))]);
    for axis in ["alpha", "beta"] {
        let predicted = number(
            &report,
            &format!("/predicted_tracking_error/{axis}_rms_relative"),
        );
        assert!(predicted < 0.005, "{axis}: predicted {predicted}");
    }
    assert_eq!(number(&report, "/periods/saturated_in_frame"), 0.0);
    let height = number(&report, "/imaging/feature/height_mm");
    assert!(
        (height - STUD_HEIGHT_MM).abs() < HEIGHT_TOLERANCE_MM,
        "stud height {height} mm, truth {STUD_HEIGHT_MM} mm"
    );
    let median = number(&report, "/imaging/feature/median_mm");
    assert!(
        (median - STUD_HEIGHT_MM).abs() < MEDIAN_TOLERANCE_MM,
        "stud median {median} mm, truth {STUD_HEIGHT_MM} mm"
    );
}
