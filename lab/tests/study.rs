//! Studies: variants written as scenario files, run in process across threads, and tabulated;
//! the same files run by `scanhil scan` (as a batch system would) give the same table row.

#[allow(dead_code)]
#[path = "../../tests/loop/util.rs"]
mod util;

use std::path::Path;

use scanhil_controller::run::scenario::Scenario;
use scanhil_controller::run::verdict::Status;
use scanhil_lab::study::plan::{Study, variant_dir};
use scanhil_lab::study::run::{VariantOutcome, run_variants};
use scanhil_lab::study::table::{RESULT_DIR, collect};
use util::{assert_success, root, run_scanhil};

fn write_study(dir: &Path, body: &str) -> Study {
    let path = dir.join("study.json");
    let scenario = root().join("fixtures/scenarios/test-loop-small.json");
    let text = format!(
        r#"{{ "name": "t", "scenario": "{}", {body} }}"#,
        scenario.display()
    );
    std::fs::write(&path, text).expect("writing the study");
    Study::load(&path).expect("the study loads")
}

#[test]
fn a_study_runs_its_variants_on_threads_and_tabulates_them() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let controllers = root().join("fixtures/controllers");
    let study = write_study(
        dir.path(),
        &format!(
            r#""grid": {{
                "scenario.duration_s": [0.02],
                "scenario.controller": ["{}", "{}"],
                "controller.discretisation.method": ["tustin", "backward_euler"]
            }}"#,
            controllers.join("pid-series.json").display(),
            controllers.join("pid-parallel.json").display(),
        ),
    );
    let out = dir.path().join("out");
    let scenarios = study
        .write_variants(&out)
        .expect("the variants are written");
    assert_eq!(scenarios.len(), 4);
    for scenario in &scenarios {
        let loaded = Scenario::load(scenario).expect("a variant is a scenario scanhil loads");
        assert!((loaded.duration_s - 0.02).abs() < 1e-12);
    }
    let outcomes = run_variants(&study, &scenarios, 2);
    assert!(
        outcomes.iter().all(|o| *o == VariantOutcome::Ran),
        "{outcomes:?}"
    );
    let rows = collect(&study, &out).expect("the table is written");
    assert_eq!(rows.len(), 4);
    let alpha: Vec<f64> = rows
        .iter()
        .map(|row| {
            assert_eq!(row.verdict, Some(Status::Complete), "{row:?}");
            assert!(row.run_time_s.is_some_and(|t| t > 0.0), "{row:?}");
            row.tracking_rms_relative_alpha.expect("a tracking figure")
        })
        .collect();
    // Four controllers, four different tracking errors: the variants really differ.
    for i in 0..4 {
        for j in i + 1..4 {
            assert_ne!(
                alpha[i],
                alpha[j],
                "variants {} and {} track alike",
                i + 1,
                j + 1
            );
        }
    }
    let csv = std::fs::read_to_string(out.join("study.csv")).expect("study.csv");
    assert_eq!(csv.lines().count(), 5, "{csv}");
    assert!(csv.starts_with(
        "variant,controller.discretisation.method,scenario.controller,scenario.duration_s,verdict,"
    ));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("study.json")).expect("json"))
            .expect("study.json is JSON");
    assert_eq!(json["rows"].as_array().map(Vec::len), Some(4));
}

#[test]
fn a_variant_run_by_scanhil_scan_gives_the_same_row_as_in_process() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let study = write_study(
        dir.path(),
        r#""list": [ { "scenario.duration_s": 0.02, "scenario.seed": 5, "scene.seed": 9 } ]"#,
    );
    let in_process = dir.path().join("here");
    let scenarios = study.write_variants(&in_process).expect("written");
    assert_eq!(run_variants(&study, &scenarios, 1), [VariantOutcome::Ran]);
    let here = collect(&study, &in_process).expect("table").remove(0);

    let batch = dir.path().join("batch");
    let scenarios = study.write_variants(&batch).expect("written");
    let result = variant_dir(&batch, 0).join(RESULT_DIR);
    let scenario = scenarios[0].to_str().expect("UTF-8");
    let out = result.to_str().expect("UTF-8");
    assert_success(
        &run_scanhil(&["scan", scenario, "--out", out]),
        "scanhil scan",
    );
    let there = collect(&study, &batch).expect("table").remove(0);
    assert_eq!(here.verdict, Some(Status::Complete));
    // Both runs list the scene's parts, each with a measured cost (the costs differ: they
    // are wall times).
    let names = |row: &scanhil_lab::study::table::Row| {
        row.parts.iter().map(|p| p.part.clone()).collect::<Vec<_>>()
    };
    assert!(names(&here).contains(&"axes".to_owned()), "{here:?}");
    assert_eq!(names(&here), names(&there));
    assert!(
        here.parts
            .iter()
            .chain(&there.parts)
            .all(|p| p.us_per_period.is_finite() && p.us_per_period >= 0.0),
        "{here:?} {there:?}"
    );
    assert_eq!(here.parameters, there.parameters);
    assert_eq!(
        here.tracking_rms_relative_alpha,
        there.tracking_rms_relative_alpha
    );
    assert_eq!(
        here.tracking_rms_relative_beta,
        there.tracking_rms_relative_beta
    );
}

#[test]
fn a_variant_that_cannot_run_is_a_row_with_its_reason() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let study = write_study(
        dir.path(),
        r#""list": [
            { "scenario.duration_s": 0.02 },
            { "scenario.duration_s": 0.02, "controller.discretisation.method": "nonsense" }
        ]"#,
    );
    let out = dir.path().join("out");
    let scenarios = study.write_variants(&out).expect("written");
    let outcomes = run_variants(&study, &scenarios, 2);
    assert_eq!(outcomes[0], VariantOutcome::Ran);
    assert!(matches!(&outcomes[1], VariantOutcome::Failed(m) if m.contains("nonsense")));
    let rows = collect(&study, &out).expect("table");
    assert_eq!(rows[0].verdict, Some(Status::Complete));
    assert_eq!(rows[1].verdict, None);
    let problem = rows[1].problem.as_deref().unwrap_or_default();
    assert!(problem.contains("nonsense"), "{problem}");
}

#[test]
fn study_files_with_bad_keys_or_shapes_are_refused_naming_the_file() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    for (body, expected) in [
        (r#""grid": { "plant.seed": [1] }"#, "plant.seed"),
        (r#""list": []"#, "no variant"),
        (
            r#""grid": { "scenario.seed": [1] }, "list": [{}]"#,
            "exactly one",
        ),
    ] {
        let path = dir.path().join("bad.json");
        let scenario = root().join("fixtures/scenarios/test-loop-small.json");
        std::fs::write(
            &path,
            format!(
                r#"{{ "name": "t", "scenario": "{}", {body} }}"#,
                scenario.display()
            ),
        )
        .expect("writing");
        let error = load_refusal(&path);
        assert!(
            error.contains("bad.json") && error.contains(expected),
            "{error}"
        );
    }
}

/// The whole message (causes too) of `Study::load`'s refusal of `path`.
fn load_refusal(path: &Path) -> String {
    format!("{:#}", Study::load(path).expect_err("refused"))
}

#[test]
fn unreadable_or_malformed_study_and_base_files_are_refused_naming_file_line_and_column() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let missing = dir.path().join("missing.json");
    let malformed = dir.path().join("malformed.json");
    std::fs::write(&malformed, "{\n  \"name\": \"t\",\n  \"scenario\": 7\n}").expect("writing");
    for (error, start) in [
        (
            load_refusal(&missing),
            format!("cannot read study {}: ", missing.display()),
        ),
        (
            load_refusal(&malformed),
            format!("{}:3:15: invalid type", malformed.display()),
        ),
    ] {
        assert!(error.starts_with(&start), "{error}");
    }

    // A study that changes the scene of a base scenario whose scene is not JSON.
    let scene = dir.path().join("scene.json");
    std::fs::write(&scene, "{\n  \"name\": \"s\",\n  oops\n}").expect("writing");
    let base = dir.path().join("base.json");
    std::fs::write(&base, r#"{"scene": "scene.json"}"#).expect("writing");
    let study = dir.path().join("study.json");
    std::fs::write(
        &study,
        r#"{ "name": "t", "scenario": "base.json", "list": [{ "scene.seed": 1 }] }"#,
    )
    .expect("writing");
    let study = Study::load(&study).expect("the study loads");
    let error = format!(
        "{:#}",
        study
            .write_variants(&dir.path().join("out"))
            .expect_err("refused")
    );
    let scene = scene.canonicalize().expect("the scene's absolute path");
    assert!(
        error.contains(&format!("{}:3:3: ", scene.display())),
        "{error}"
    );
}

#[test]
fn a_study_under_a_relative_out_runs_every_variant_and_its_table_carries_each_verdict() {
    // As the README runs it: `scanhil-study run STUDY --out out/study` from another folder.
    // Each variant changes the scene, so each writes a scene of its own that its scenario
    // names; the second's amplitudes are scaled to nothing by the power check.
    let dir = tempfile::tempdir().expect("a temporary folder");
    let study = dir.path().join("study.json");
    let text = format!(
        r#"{{ "name": "relative", "scenario": "{}", "list": [
            {{ "scenario.duration_s": 0.02, "scene.seed": 1 }},
            {{ "scenario.duration_s": 0.02, "scene.seed": 2,
               "scenario.trajectory.alpha_amplitude_rad": 1e300,
               "scenario.trajectory.beta_amplitude_rad": 1e300 }}
        ] }}"#,
        root()
            .join("fixtures/scenarios/test-loop-small.json")
            .display()
    );
    std::fs::write(&study, text).expect("writing the study");
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_scanhil-study"))
        .current_dir(dir.path())
        .args(["run", "study.json", "--out", "out/study", "--jobs", "1"])
        .output()
        .expect("running scanhil-study");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(4), "a failed verdict: {stderr}");
    assert!(!stderr.contains("out/study/variants/0001/out"), "{stderr}");
    let csv = std::fs::read_to_string(dir.path().join("out/study/study.csv")).expect("study.csv");
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows.len(), 3, "{csv}");
    assert!(rows[1].contains(",complete,"), "{csv}");
    assert!(
        rows[2].contains(",failed,") && rows[2].contains("does not move the mirror"),
        "{csv}"
    );
    assert!(
        stderr.contains("variant 2 failed: the reference does not move"),
        "{stderr}"
    );
}

#[test]
fn every_shipped_study_writes_variants_the_host_and_the_emulator_accept() {
    let dir = root().join("fixtures/studies");
    let mut studies = 0;
    for entry in std::fs::read_dir(&dir).expect("fixtures/studies") {
        let path = entry.expect("an entry").path();
        if path.extension().is_none_or(|e| e != "json") {
            continue;
        }
        let out = tempfile::tempdir().expect("a temporary folder");
        let study = Study::load(&path).unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
        let scenarios = study
            .write_variants(out.path())
            .unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
        assert!(!scenarios.is_empty(), "{}", path.display());
        for scenario in &scenarios {
            let fail = |e: &dyn std::fmt::Display| -> ! {
                panic!("{}: {}: {e:#}", path.display(), scenario.display())
            };
            Scenario::load(scenario).unwrap_or_else(|e| fail(&e));
            // The scene a variant changes is checked as the emulator will read it.
            let text = std::fs::read_to_string(scenario).unwrap_or_else(|e| fail(&e));
            let json: serde_json::Value = serde_json::from_str(&text).unwrap_or_else(|e| fail(&e));
            let scene = scenario
                .parent()
                .expect("a folder")
                .join(json["scene"].as_str().expect("a scene path"));
            scanhil_emulator::scene::Scene::load(&scene).unwrap_or_else(|e| fail(&e));
        }
        studies += 1;
    }
    assert!(studies >= 4, "{studies} studies in {}", dir.display());
}
