//! The study's table: one row per variant, read from its result folder's `report.json`, so
//! a study run here and one run by a batch system give the same table. Written as
//! `study.csv` and `study.json`.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

use anyhow::Context;
use serde_json::Value;

use super::plan::{Study, variant_dir};
use scanhil_controller::run::verdict::Status;

/// The result folder inside a variant's folder.
pub const RESULT_DIR: &str = "result";
/// In a result folder without a report: why the variant could not run.
pub const FAILURE_FILE: &str = "failure.txt";

/// One variant's figures.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Row {
    /// 1-based variant number.
    pub variant: usize,
    /// The values the study set, by key.
    pub parameters: BTreeMap<String, Value>,
    /// The run's verdict: complete, stopped or failed (`None`: no report).
    pub verdict: Option<Status>,
    /// Why the variant has no figures or is not complete (the verdict's reasons).
    pub problem: Option<String>,
    /// The feature (stud) height, mm.
    pub stud_height_mm: Option<f64>,
    /// Its standard deviation, mm.
    pub stud_std_mm: Option<f64>,
    /// Tracking error over the recorded frame, rms relative to the reference's peak: alpha.
    pub tracking_rms_relative_alpha: Option<f64>,
    /// The same for beta.
    pub tracking_rms_relative_beta: Option<f64>,
    /// Height-map cells measured, fraction.
    pub coverage: Option<f64>,
    /// Median |error| of the measured cells against the true surface, mm.
    pub median_abs_error_mm: Option<f64>,
    /// Rms error of the measured cells against the true surface, mm (the cells that straddle
    /// a step weigh in, which the median leaves out).
    pub rms_error_mm: Option<f64>,
    /// Wall time of the scan, s (as the runner measured it).
    pub run_time_s: Option<f64>,
    /// The scene's active parts with what each costs per control period (the emulator's
    /// `parts`), in dependency order; empty without an emulator summary.
    pub parts: Vec<PartTime>,
}

/// One active part of a variant's scene and its cost.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PartTime {
    /// The part's name.
    pub part: String,
    /// Its measured marginal cost per control period, in microseconds.
    pub us_per_period: f64,
}

impl Row {
    /// The row of variant `index` (0-based) from its report, or with the problem when the
    /// report is missing or unreadable.
    #[must_use]
    pub fn from_result(study: &Study, out_dir: &Path, index: usize) -> Row {
        let result = variant_dir(out_dir, index).join(RESULT_DIR);
        Row::from_result_dir(study, index, &result)
    }

    /// The row of variant `index` (0-based) from the result folder `result` (its
    /// `report.json`, or [`FAILURE_FILE`] when the run could not start).
    #[must_use]
    pub fn from_result_dir(study: &Study, index: usize, result: &Path) -> Row {
        let report_path = result.join("report.json");
        let mut row = Row {
            variant: index + 1,
            parameters: study.variants[index].clone(),
            verdict: None,
            problem: None,
            stud_height_mm: None,
            stud_std_mm: None,
            tracking_rms_relative_alpha: None,
            tracking_rms_relative_beta: None,
            coverage: None,
            median_abs_error_mm: None,
            rms_error_mm: None,
            run_time_s: None,
            parts: Vec::new(),
        };
        let report = std::fs::read_to_string(&report_path)
            .map_err(|error| format!("{}: {error}", report_path.display()))
            .and_then(|text| {
                serde_json::from_str::<Value>(&text)
                    .map_err(|error| format!("{}: {error}", report_path.display()))
            });
        let report = match report {
            Ok(report) => report,
            Err(problem) => {
                let failure = std::fs::read_to_string(result.join(FAILURE_FILE));
                row.problem = Some(failure.map_or(problem, |text| text.trim_end().to_owned()));
                return row;
            }
        };
        let number = |pointer: &str| report.pointer(pointer).and_then(Value::as_f64);
        row.verdict = verdict_of(&report);
        let reasons: Vec<&str> = report
            .pointer("/outcome/reasons")
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
            .filter_map(Value::as_str)
            .collect();
        row.problem = (!reasons.is_empty())
            .then(|| reasons.join("; "))
            .or_else(|| {
                report
                    .pointer("/outcome/stopped_by")
                    .and_then(Value::as_str)
                    .map(str::to_owned)
            })
            .or_else(|| {
                report
                    .pointer("/imaging/feature_error")
                    .and_then(Value::as_str)
                    .map(str::to_owned)
            });
        row.stud_height_mm = number("/imaging/feature/height_mm");
        row.stud_std_mm = number("/imaging/feature/std_mm");
        row.tracking_rms_relative_alpha = number("/tracking_error/frame/alpha/rms_relative");
        row.tracking_rms_relative_beta = number("/tracking_error/frame/beta/rms_relative");
        row.coverage = number("/imaging/coverage_fraction");
        row.median_abs_error_mm = number("/imaging/truth_error/covered_median_abs_mm");
        row.rms_error_mm = number("/imaging/truth_error/covered_rms_mm");
        row.run_time_s = number("/run_time_s");
        row.parts = report
            .pointer("/emulator/summary/parts/parts")
            .and_then(Value::as_array)
            .map(|parts| {
                parts
                    .iter()
                    .filter_map(|p| {
                        Some(PartTime {
                            part: p.get("part")?.as_str()?.to_owned(),
                            us_per_period: p.get("us_per_period")?.as_f64()?,
                        })
                    })
                    .collect()
            })
            .unwrap_or_default();
        row
    }
}

/// A report's verdict: `outcome.verdict`, or for a report written before verdicts,
/// `outcome.complete` read as complete or stopped.
fn verdict_of(report: &Value) -> Option<Status> {
    match report.pointer("/outcome/verdict").and_then(Value::as_str) {
        Some("complete") => Some(Status::Complete),
        Some("stopped") => Some(Status::Stopped),
        Some("failed") => Some(Status::Failed),
        _ => report
            .pointer("/outcome/complete")
            .and_then(Value::as_bool)
            .map(|complete| {
                if complete {
                    Status::Complete
                } else {
                    Status::Stopped
                }
            }),
    }
}

/// Reads every variant's result and writes `study.csv` and `study.json` into `out_dir`.
///
/// # Errors
/// A table file that cannot be written. (A variant without a readable report is a row with
/// its problem, not an error.)
pub fn collect(study: &Study, out_dir: &Path) -> anyhow::Result<Vec<Row>> {
    let rows: Vec<Row> = (0..study.variants.len())
        .map(|i| Row::from_result(study, out_dir, i))
        .collect();
    let json_path = out_dir.join("study.json");
    let json = serde_json::json!({
        "study": study.name,
        "file": study.path.display().to_string(),
        "scenario": study.scenario.display().to_string(),
        "rows": rows,
    });
    scanhil_protocol::whole_file::write_file(
        &json_path,
        serde_json::to_string_pretty(&json).context("formatting study.json")? + "\n",
    )
    .with_context(|| format!("writing {}", json_path.display()))?;
    let csv_path = out_dir.join("study.csv");
    let mut csv = Vec::new();
    write_csv(&mut csv, &study.keys(), &rows).context("formatting study.csv")?;
    scanhil_protocol::whole_file::write_file(&csv_path, csv)
        .with_context(|| format!("writing {}", csv_path.display()))?;
    Ok(rows)
}

/// The figure columns after the variant number and the parameters.
const FIGURE_COLUMNS: [&str; 11] = [
    "verdict",
    "stud_height_mm",
    "stud_std_mm",
    "tracking_rms_relative_alpha",
    "tracking_rms_relative_beta",
    "coverage",
    "median_abs_error_mm",
    "rms_error_mm",
    "run_time_s",
    "parts_us_per_period",
    "problem",
];

/// Writes the table as CSV (RFC 4180 quoting); empty cells where a figure is missing.
///
/// # Errors
/// The writer's error.
pub fn write_csv(out: &mut impl Write, keys: &[String], rows: &[Row]) -> std::io::Result<()> {
    let header: Vec<String> = std::iter::once("variant".to_owned())
        .chain(keys.iter().cloned())
        .chain(FIGURE_COLUMNS.iter().map(|c| (*c).to_owned()))
        .collect();
    writeln!(
        out,
        "{}",
        header
            .iter()
            .map(|h| quote(h))
            .collect::<Vec<_>>()
            .join(",")
    )?;
    let figure = |v: Option<f64>| v.map_or(String::new(), |v| v.to_string());
    for row in rows {
        let mut cells = vec![row.variant.to_string()];
        cells.extend(keys.iter().map(|k| parameter_cell(row.parameters.get(k))));
        cells.push(row.verdict.map_or(String::new(), |v| v.name().to_owned()));
        cells.extend(
            [
                row.stud_height_mm,
                row.stud_std_mm,
                row.tracking_rms_relative_alpha,
                row.tracking_rms_relative_beta,
                row.coverage,
                row.median_abs_error_mm,
                row.rms_error_mm,
                row.run_time_s,
            ]
            .map(figure),
        );
        cells.push(
            row.parts
                .iter()
                .map(|p| format!("{}:{:.3}", p.part, p.us_per_period))
                .collect::<Vec<_>>()
                .join(" "),
        );
        cells.push(row.problem.clone().unwrap_or_default());
        writeln!(
            out,
            "{}",
            cells.iter().map(|c| quote(c)).collect::<Vec<_>>().join(",")
        )?;
    }
    Ok(())
}

/// A parameter's CSV cell: a string as it is, any other value as JSON, empty when unset.
pub(crate) fn parameter_cell(value: Option<&Value>) -> String {
    match value {
        None => String::new(),
        Some(Value::String(s)) => s.clone(),
        Some(other) => other.to_string(),
    }
}

/// A CSV cell, quoted when it holds a comma, a quote or a line break.
pub(crate) fn quote(cell: &str) -> String {
    if cell.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", cell.replace('"', "\"\""))
    } else {
        cell.to_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_quotes_what_needs_it_and_leaves_missing_figures_empty() {
        let row = Row {
            variant: 1,
            parameters: BTreeMap::from([
                ("scenario.seed".to_owned(), Value::from(3)),
                ("scenario.controller".to_owned(), Value::from("/a,b.json")),
            ]),
            verdict: Some(Status::Stopped),
            problem: Some("link timeout: \"x\"".into()),
            stud_height_mm: Some(4.66),
            stud_std_mm: None,
            tracking_rms_relative_alpha: None,
            tracking_rms_relative_beta: None,
            coverage: None,
            median_abs_error_mm: None,
            rms_error_mm: Some(0.25),
            run_time_s: Some(0.5),
            parts: vec![
                PartTime {
                    part: "axes".into(),
                    us_per_period: 0.02,
                },
                PartTime {
                    part: "sensor".into(),
                    us_per_period: 1.4159,
                },
            ],
        };
        let keys = vec!["scenario.controller".to_owned(), "scenario.seed".to_owned()];
        let mut out = Vec::new();
        write_csv(&mut out, &keys, &[row]).unwrap();
        let text = String::from_utf8(out).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "variant,scenario.controller,scenario.seed,verdict,stud_height_mm,stud_std_mm,\
             tracking_rms_relative_alpha,tracking_rms_relative_beta,coverage,\
             median_abs_error_mm,rms_error_mm,run_time_s,parts_us_per_period,problem"
        );
        assert_eq!(
            lines[1],
            "1,\"/a,b.json\",3,stopped,4.66,,,,,,0.25,0.5,axes:0.020 sensor:1.416,\"link timeout: \"\"x\"\"\""
        );
    }
}
