//! What a run leaves out (`outputs` in a scenario, a study's `outputs` for every variant): the
//! files are not written, the report lists them, and nothing else changes.

use std::path::Path;

use scanhil_controller::run::output::{FIGURE_FILES, RECORDING_FILES};
use scanhil_lab::study::plan::{Study, variant_dir};
use scanhil_lab::study::run::{VariantOutcome, run_variants};
use scanhil_lab::study::table::{RESULT_DIR, collect};

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn write_study(dir: &Path, body: &str) -> std::path::PathBuf {
    let path = dir.join("study.json");
    let scenario = root().join("fixtures/scenarios/test-duplo-stud.json");
    let text = format!(
        r#"{{ "name": "t", "scenario": "{}", {body} }}"#,
        scenario.display()
    );
    std::fs::write(&path, text).expect("writing the study");
    path
}

fn report(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("report.json")).expect("report.json");
    serde_json::from_str(&text).expect("JSON")
}

/// What a run that leaves out both writes no more of (the loop test in
/// `tests/loop/out_folder.rs` spells the list out).
fn left_out() -> Vec<&'static str> {
    [RECORDING_FILES.as_slice(), FIGURE_FILES.as_slice()].concat()
}

#[test]
fn a_study_that_leaves_out_recordings_and_figures_tabulates_the_same_results() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    // The study leaves both out; its second variant turns them on again (a variant's own
    // fields come after the study's outputs).
    let study = Study::load(&write_study(
        dir.path(),
        r#""outputs": { "recordings": false, "figures": false },
           "list": [
               { "scenario.duration_s": 0.05 },
               { "scenario.duration_s": 0.05, "scenario.outputs.recordings": true,
                 "scenario.outputs.figures": true }
           ]"#,
    ))
    .expect("the study loads");
    let out = dir.path().join("out");
    let scenarios = study.write_variants(&out).expect("written");
    assert_eq!(
        run_variants(&study, &scenarios, 2),
        [VariantOutcome::Ran, VariantOutcome::Ran]
    );
    let lean = variant_dir(&out, 0).join(RESULT_DIR);
    let full = variant_dir(&out, 1).join(RESULT_DIR);
    for file in left_out() {
        assert!(!lean.join(file).exists(), "{file} written");
        assert!(full.join(file).exists(), "{file} missing");
    }
    assert_eq!(
        report(&lean)["outputs"]["left_out"],
        serde_json::json!(left_out())
    );
    assert_eq!(report(&full)["outputs"]["left_out"], serde_json::json!([]));
    for file in ["points.ply", "height_map.csv", "profiles.csv"] {
        assert_eq!(
            std::fs::read(lean.join(file)).expect("written"),
            std::fs::read(full.join(file)).expect("written"),
            "{file}"
        );
    }
    let rows = collect(&study, &out).expect("the table");
    let (lean, full) = (&rows[0], &rows[1]);
    assert!(lean.stud_height_mm.is_some(), "{lean:?}");
    assert_eq!(lean.stud_height_mm, full.stud_height_mm);
    assert_eq!(lean.coverage, full.coverage);
    assert_eq!(
        lean.tracking_rms_relative_alpha,
        full.tracking_rms_relative_alpha
    );
}

#[test]
fn a_study_whose_outputs_name_an_unknown_file_is_refused_naming_it() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let path = write_study(
        dir.path(),
        r#""outputs": { "plots": false }, "list": [ {} ]"#,
    );
    let error = format!("{:#}", Study::load(&path).expect_err("refused"));
    assert!(
        error.contains("study.json") && error.contains("plots"),
        "{error}"
    );
}

#[test]
fn leaving_out_only_ever_leaves_out() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let mut study = Study::load(&write_study(
        dir.path(),
        r#""outputs": { "figures": false }, "list": [ { "scenario.duration_s": 0.05 } ]"#,
    ))
    .expect("the study loads");
    study.leave_out(true, false);
    let written = study
        .write_variants(&dir.path().join("out"))
        .expect("written");
    let scenario = scanhil_controller::run::scenario::Scenario::load(&written[0]).expect("loads");
    assert!(!scenario.outputs.recordings && !scenario.outputs.figures);
    // `true` in a study's outputs keeps what the base scenario says: a base that leaves the
    // figures out keeps them out.
    let base = dir.path().join("base.json");
    let text = std::fs::read_to_string(root().join("fixtures/scenarios/test-duplo-stud.json"))
        .expect("the fixture")
        .replacen('{', r#"{ "outputs": { "figures": false },"#, 1)
        .replace("\"../", &format!("\"{}/fixtures/", root().display()));
    std::fs::write(&base, text).expect("writing");
    let path = dir.path().join("keeps.json");
    std::fs::write(
        &path,
        format!(
            r#"{{ "name": "t", "scenario": "{}", "outputs": {{ "figures": true }}, "list": [ {{}} ] }}"#,
            base.display()
        ),
    )
    .expect("writing");
    let study = Study::load(&path).expect("loads");
    let written = study
        .write_variants(&dir.path().join("keeps"))
        .expect("written");
    let scenario = scanhil_controller::run::scenario::Scenario::load(&written[0]).expect("loads");
    assert!(!scenario.outputs.figures && scenario.outputs.recordings);
}
