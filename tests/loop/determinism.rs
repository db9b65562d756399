//! Lockstep determinism: the same scenario and seed twice, bit-identical outputs.

use crate::util::{assert_success, fixture, run_scanhil};

#[test]
fn the_same_seed_gives_bit_identical_recordings_and_reports() {
    let runs: Vec<tempfile::TempDir> = (0..2)
        .map(|_| {
            let out = tempfile::tempdir().expect("a temporary folder");
            let output = run_scanhil(&[
                "scan",
                &fixture("scenarios/test-duplo-stud.json"),
                "--duration-s",
                "0.05",
                "--out",
                out.path().to_str().expect("UTF-8 path"),
            ]);
            assert_success(&output, "scanhil scan");
            out
        })
        .collect();
    for file in ["fsm.log", "sensor.ild", "report.json", "points.ply"] {
        let first = std::fs::read(runs[0].path().join(file)).expect("first run's file");
        let second = std::fs::read(runs[1].path().join(file)).expect("second run's file");
        assert!(!first.is_empty(), "{file} is empty");
        assert!(
            first == second,
            "{file} differs between two runs with the same seed"
        );
    }
}
