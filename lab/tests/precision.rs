//! `scanhil-study precision` end to end through the binary: a tiny study (the reference, a
//! small-angle optics and a trapezoid plant, each run twice) writes its rows, summaries and
//! figure; the reference's errors are exactly 0; a study with a bad `reference` or `repeats`
//! is refused naming the file and the field.

#[allow(dead_code)]
#[path = "../../tests/loop/util.rs"]
mod util;

use std::path::Path;
use std::process::Output;

use scanhil_lab::study::plan::Study;
use scanhil_lab::study::precision::{self, repeat_dir};
use serde_json::Value;
use util::root;

/// Writes a study of the Duplo stud test scan (0.05 s, no lead-in) with `fields` beside the
/// three configurations, and runs `scanhil-study precision` on it into `dir/out`.
fn precision(dir: &Path, fields: &str) -> Output {
    write_study(dir, fields);
    std::process::Command::new(env!("CARGO_BIN_EXE_scanhil-study"))
        .args(["precision", "study.json", "--out", "out"])
        .current_dir(dir)
        .output()
        .expect("running scanhil-study")
}

/// Writes `dir/study.json`: the Duplo stud test scan (0.05 s, no lead-in) as the reference, with
/// small-angle optics and with a trapezoid plant, and `fields` beside them.
fn write_study(dir: &Path, fields: &str) -> std::path::PathBuf {
    let study = dir.join("study.json");
    let short = r#""scenario.duration_s": 0.05, "scenario.lead_in": { "mode": "none" }"#;
    let text = format!(
        r#"{{ "name": "tiny", "scenario": "{}", {fields},
            "outputs": {{ "figures": false }},
            "list": [
                {{ {short} }},
                {{ {short}, "scene.optics.model": "small_angle" }},
                {{ {short}, "scene.integrator.method": "trapezoid" }}
            ] }}"#,
        root()
            .join("fixtures/scenarios/test-duplo-stud.json")
            .display()
    );
    std::fs::write(&study, text).expect("writing the study");
    study
}

#[test]
fn a_precision_study_writes_every_run_and_measures_against_its_reference() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let output = precision(dir.path(), r#""repeats": 2, "reference": 0"#);
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(0), "{stdout}\n{stderr}");
    let out = dir.path().join("out");
    for file in [
        "precision.csv",
        "precision.json",
        "precision.svg",
        "precision.png",
    ] {
        let bytes = std::fs::metadata(out.join(file)).map_or(0, |m| m.len());
        assert!(bytes > 100, "{file}: {bytes} bytes");
    }
    assert!(
        out.join("variants/0003/repeat-02/report.json").is_file(),
        "each run has its own result folder"
    );

    let json: Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("precision.json")).expect("precision.json"),
    )
    .expect("precision.json is JSON");
    let rows = json["rows"].as_array().expect("rows");
    let summaries = json["summaries"].as_array().expect("summaries");
    assert_eq!((rows.len(), summaries.len()), (6, 3), "{json:#}");
    for row in rows {
        assert_eq!(row["verdict"], "complete", "{row:#}");
        assert!(
            row["run_time_s"].as_f64().is_some_and(|t| t > 0.0),
            "{row:#}"
        );
    }
    let of = |configuration: u64| -> Vec<&Value> {
        rows.iter()
            .filter(|r| r["configuration"] == configuration)
            .collect()
    };
    for reference in of(1) {
        assert_eq!(reference["reference"], true);
        assert_eq!(
            reference["tracking_vs_reference_urad"], 0.0,
            "{reference:#}"
        );
        assert_eq!(
            reference["stud_height_vs_reference_um"], 0.0,
            "{reference:#}"
        );
    }
    let reference_surface = of(1)[0]["surface_rms_um"].as_f64().expect("a surface rms");
    for small_angle in of(2) {
        let surface = small_angle["surface_rms_um"]
            .as_f64()
            .expect("a surface rms");
        let height = small_angle["stud_height_vs_reference_um"]
            .as_f64()
            .expect("a height error");
        assert!(
            surface != reference_surface || height != 0.0,
            "the small-angle optics measure as the exact: {small_angle:#}"
        );
    }
    for trapezoid in of(3) {
        let tracking = trapezoid["tracking_vs_reference_urad"]
            .as_f64()
            .expect("a tracking error");
        assert!(tracking > 0.0, "{trapezoid:#}");
    }
    // The reference has no error against itself: nothing beats it in all three errors.
    assert_eq!(summaries[0]["pareto"], true, "{json:#}");
    assert!(stdout.contains("Pareto front"), "{stdout}");

    let csv = std::fs::read_to_string(out.join("precision.csv")).expect("precision.csv");
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 7, "{csv}");
    let header: Vec<&str> = lines[0].split(',').collect();
    assert_eq!(header[0], "configuration");
    let column = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("no column {name}: {csv}"))
    };
    for line in &lines[1..] {
        let cells: Vec<&str> = line.split(',').collect();
        let configuration: usize = cells[0].parse().expect("a configuration number");
        let pareto = &summaries[configuration - 1]["pareto"];
        assert_eq!(
            cells[column("pareto")],
            pareto.to_string(),
            "the row's flag is its configuration's: {line}"
        );
        assert!(["1", "2"].contains(&cells[column("repeat")]), "{line}");
    }
}

#[test]
fn a_bad_reference_or_repeats_is_refused_naming_the_file_and_the_field() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    for (fields, field) in [
        (r#""repeats": 2, "reference": 3"#, "`reference` is 3"),
        (r#""repeats": 0, "reference": 0"#, "`repeats` is 0"),
        (r#""repeats": 101, "reference": 0"#, "`repeats` is 101"),
        (r#""repeats": 1"#, "`reference`"),
    ] {
        let output = precision(dir.path(), fields);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{fields}: {stderr}");
        assert!(
            stderr.contains("study.json") && stderr.contains(field),
            "{fields}: {stderr}"
        );
        assert!(!dir.path().join("out/precision.csv").exists(), "{fields}");
    }
}

#[test]
fn a_run_whose_record_is_lost_keeps_its_row_and_says_why_and_so_does_every_run_of_its_repeat() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let study = Study::load(&write_study(dir.path(), r#""repeats": 2, "reference": 0"#))
        .expect("the study loads");
    let out = dir.path().join("out");
    precision::run(&study, &out, 1).expect("the runs");
    // The small-angle run of repeat 1 and the reference's run of repeat 2 lose their records.
    let record = |configuration, repeat| {
        repeat_dir(&out, configuration, repeat).join(precision::ANGLE_RECORD)
    };
    std::fs::remove_file(record(1, 0)).expect("removing a record");
    std::fs::remove_file(record(0, 1)).expect("removing the reference's record");
    let table = precision::collect(&study, &out).expect("the table");
    assert_eq!(
        table.reference, 1,
        "the reference as numbered in the outputs"
    );
    let row = |configuration: usize, repeat: usize| {
        table
            .rows
            .iter()
            .find(|r| r.configuration == configuration && r.repeat == repeat)
            .expect("a row")
    };
    // Repeat 1: the reference and the trapezoid have their errors and no problem.
    for configuration in [1, 3] {
        let fine = row(configuration, 1);
        assert_eq!(fine.problem, None, "{fine:?}");
        assert!(fine.tracking_vs_reference_urad.is_some(), "{fine:?}");
    }
    // The lost record: no tracking error, the surface still from its report, the file named.
    let lost = row(2, 1);
    assert_eq!(lost.tracking_vs_reference_urad, None);
    let problem = lost.problem.as_deref().expect("a problem");
    assert!(problem.contains(precision::ANGLE_RECORD), "{problem}");
    // Repeat 2: the reference's loss leaves every other run without errors, saying so once.
    for configuration in [2, 3] {
        let orphan = row(configuration, 2);
        let problem = orphan.problem.as_deref().expect("a problem");
        assert!(
            problem.contains("the reference's run (configuration 1, repeat 2)"),
            "{problem}"
        );
        assert_eq!(
            problem.matches("the reference's run").count(),
            1,
            "{problem}"
        );
        assert_eq!(orphan.stud_height_vs_reference_um, None);
    }
    // The surface's rms is against the truth, so it stays, in um from the report's mm.
    for (configuration, repeat) in [(2, 1), (2, 2), (3, 2)] {
        let report: Value = serde_json::from_str(
            &std::fs::read_to_string(
                repeat_dir(&out, configuration - 1, repeat - 1).join("report.json"),
            )
            .expect("report.json"),
        )
        .expect("JSON");
        let rms_mm = report["imaging"]["truth_error"]["covered_rms_mm"]
            .as_f64()
            .expect("a surface rms");
        let row = row(configuration, repeat);
        assert!(
            row.surface_rms_um
                .is_some_and(|um| (um - rms_mm * 1e3).abs() < 1e-9),
            "{row:?}"
        );
    }
    // A configuration with a run in error is off the front, and its rows in the CSV say so.
    let csv = std::fs::read_to_string(out.join(precision::PRECISION_CSV)).expect("the CSV");
    let header: Vec<&str> = csv.lines().next().expect("a header").split(',').collect();
    let pareto = header
        .iter()
        .position(|h| *h == "pareto")
        .expect("a pareto column");
    for line in csv.lines().skip(1) {
        let cells: Vec<&str> = line.split(',').collect();
        let summary = &table.summaries[cells[0].parse::<usize>().expect("a number") - 1];
        assert_eq!(cells[pareto], summary.pareto.to_string(), "{line}");
    }
    assert!(table.summaries.iter().any(|s| !s.pareto));
    assert!(precision::name(&table.summaries[0]).ends_with("(reference)"));
    assert!(!precision::name(&table.summaries[1]).contains("reference"));
}
