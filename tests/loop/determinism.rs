//! Lockstep determinism: the same scenario and seed twice, bit-identical outputs.

use crate::util::{assert_success, fixture, report, run_scanhil};

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
    // The report is the same but for the wall-clock figures, which are there: the run time
    // and what each part of the scene costs per period (measured before the run); and the
    // mirror link's name, the pty each run was given.
    let [first, second] = [0, 1].map(|i| {
        let mut report = report(runs[i].path());
        let link = report["links"]["mirror_link"]["link"].take();
        assert!(
            link.as_str()
                .is_some_and(|uri| uri.starts_with("slcan:/dev/")),
            "{link}"
        );
        let run_time_s = report["run_time_s"].take();
        assert!(run_time_s.as_f64().is_some_and(|t| t > 0.0), "{run_time_s}");
        let costs = &mut report["emulator"]["summary"]["parts"];
        for figure in ["plant_us_per_period", "bare_us_per_period"] {
            assert!(costs[figure].take().as_f64().is_some_and(|us| us >= 0.0));
        }
        for part in costs["parts"].as_array_mut().expect("the parts") {
            assert!(
                part["us_per_period"]
                    .take()
                    .as_f64()
                    .is_some_and(|us| us >= 0.0)
            );
        }
        report
    });
    assert_eq!(first, second, "report.json differs beyond its run time");
    for file in [
        "fsm.log",
        "sensor.ild",
        "points.ply",
        "height_map.png",
        "height_map.csv",
        "snapshots.png",
        "profiles.csv",
    ] {
        let first = std::fs::read(runs[0].path().join(file)).expect("first run's file");
        let second = std::fs::read(runs[1].path().join(file)).expect("second run's file");
        assert!(!first.is_empty(), "{file} is empty");
        assert!(
            first == second,
            "{file} differs between two runs with the same seed"
        );
    }
}
