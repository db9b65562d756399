//! Work-precision of whole scans: each variant of a study (a configuration) run `repeats`
//! times, its wall time against its errors against the study's exact reference
//! (`scanhil-study precision`).
//!
//! Every run of configuration `c` in repeat `r` writes `variants/NNNN/repeat-RR/` (the output
//! folder of `scanhil scan`). Its errors, against the reference's run of the same repeat (same
//! seed, so the same noise draws):
//! - tracking: rms over periods and both axes of the difference between the mirror angles the
//!   node reported (the angle readings of `fsm.log`, 1 urad steps) and the reference's, urad;
//! - stud height: `imaging.feature.height_mm` minus the reference's, um;
//! - surface: rms error of the measured height-map cells against the true surface
//!   (`imaging.truth_error.covered_rms_mm`), um; against the truth, not the reference.
//!
//! The errors of a fixed seed are the same in every repeat; the repeats give the run time
//! its spread. The pure parts ([`parse_period_angles`], [`angle_difference_rms_urad`],
//! [`errors_against`], [`Spread::of`], [`pareto_front`]) have unit tests; [`run`] runs the
//! scans, [`collect`] reads them and writes `precision.csv`, `precision.json` and the figure.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use scanhil_controller::run::verdict::Status;
use scanhil_protocol::candump::{LogRecord, parse_record};
use scanhil_protocol::message::{Message, ids};
use scanhil_report::{Axis, Chart, LogZero, Series, draw_charts};
use serde::Serialize;
use serde_json::Value;

use super::plan::{Study, describe, variant_dir};
use super::run::{ScanJob, VariantOutcome, run_scans};
use super::table::{Row, parameter_cell, quote};

/// The rows, one per configuration and repeat.
pub const PRECISION_CSV: &str = "precision.csv";
/// The rows and the per-configuration summaries.
pub const PRECISION_JSON: &str = "precision.json";
/// The work-precision figure (SVG; a PNG beside it).
pub const PRECISION_SVG: &str = "precision.svg";
/// The same figure as PNG.
pub const PRECISION_PNG: &str = "precision.png";
/// The record of the loop whose angle readings give the per-period mirror angles.
pub const ANGLE_RECORD: &str = scanhil_controller::run::output::FSM_LOG;

/// The result folder of configuration `index` (0-based) in repeat `repeat` (0-based):
/// `variants/0001/repeat-01` for the first.
#[must_use]
pub fn repeat_dir(out_dir: &Path, index: usize, repeat: usize) -> PathBuf {
    variant_dir(out_dir, index).join(format!("repeat-{:02}", repeat + 1))
}

/// Writes the study's variants and runs every configuration `study.repeats` times on `jobs`
/// threads, in rounds (every configuration once, then again), so a slow spell of a shared
/// machine spreads over all configurations rather than weighing on one. With one thread
/// (the default of `scanhil-study precision`) no two scans run at once, so no run time is
/// inflated by another scan.
///
/// # Errors
/// A study without a `reference`, one whose `outputs` leave out the recordings (the angles
/// are read from `fsm.log`), variant files that cannot be written.
pub fn run(study: &Study, out_dir: &Path, jobs: usize) -> anyhow::Result<Vec<VariantOutcome>> {
    check(study)?;
    let scenarios = study.write_variants(out_dir)?;
    let scans: Vec<ScanJob> = (0..study.repeats)
        .flat_map(|repeat| {
            scenarios
                .iter()
                .enumerate()
                .map(move |(variant, scenario)| ScanJob {
                    variant,
                    scenario: scenario.clone(),
                    result: repeat_dir(out_dir, variant, repeat),
                })
        })
        .collect();
    Ok(run_scans(study, &scans, jobs))
}

/// Refuses a study that cannot be a precision study.
fn check(study: &Study) -> anyhow::Result<()> {
    if study.reference.is_none() {
        bail!(
            "{}: a precision study names its exact reference: `reference`, the index of its \
             entry (from 0)",
            study.path.display()
        );
    }
    if study.outputs.is_some_and(|o| !o.recordings) {
        bail!(
            "{}: `outputs.recordings` is false, but a precision study reads each run's \
             mirror angles from its {ANGLE_RECORD}",
            study.path.display()
        );
    }
    Ok(())
}

/// One run: a configuration in one repeat, its time and its errors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PrecisionRow {
    /// 1-based configuration (variant) number.
    pub configuration: usize,
    /// 1-based repeat number.
    pub repeat: usize,
    /// Whether this is the study's reference.
    pub reference: bool,
    /// The values the study set, by key.
    pub parameters: BTreeMap<String, Value>,
    /// The run's verdict (`None`: no report).
    pub verdict: Option<Status>,
    /// Wall time of the whole scan (`run_time_s` of its report), s.
    pub run_time_s: Option<f64>,
    /// Rms over periods and both axes of the reported mirror angles minus the reference's,
    /// urad.
    pub tracking_vs_reference_urad: Option<f64>,
    /// The stud height measured, mm.
    pub stud_height_mm: Option<f64>,
    /// The stud height minus the reference's, um.
    pub stud_height_vs_reference_um: Option<f64>,
    /// Rms error of the measured cells against the true surface, um.
    pub surface_rms_um: Option<f64>,
    /// Why the run is not complete or an error is missing.
    pub problem: Option<String>,
}

/// The figures of one result folder that the errors are made of.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RunRecord {
    /// The mirror angles the node reported, one `[alpha, beta]` per period, urad.
    pub angles_urad: Vec<[i32; 2]>,
    /// The stud height, mm.
    pub stud_height_mm: Option<f64>,
    /// Rms error against the true surface, mm.
    pub surface_rms_mm: Option<f64>,
}

/// One run's errors against the reference's run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RunErrors {
    /// See [`PrecisionRow::tracking_vs_reference_urad`].
    pub tracking_urad: Option<f64>,
    /// See [`PrecisionRow::stud_height_vs_reference_um`].
    pub stud_height_um: Option<f64>,
    /// See [`PrecisionRow::surface_rms_um`].
    pub surface_rms_um: Option<f64>,
    /// Why an error is missing.
    pub problems: Vec<String>,
}

/// The errors of `run` against `reference` (see the module doc).
#[must_use]
pub fn errors_against(run: &RunRecord, reference: &RunRecord) -> RunErrors {
    let mut problems = Vec::new();
    let tracking_urad = angle_difference_rms_urad(&run.angles_urad, &reference.angles_urad)
        .map_err(|problem| problems.push(problem))
        .ok();
    let stud_height_um = match (run.stud_height_mm, reference.stud_height_mm) {
        (Some(h), Some(r)) => Some((h - r) * 1e3),
        (None, _) => {
            problems.push("no stud height measured".into());
            None
        }
        (_, None) => {
            problems.push("the reference measured no stud height".into());
            None
        }
    };
    let surface_rms_um = run.surface_rms_mm.map(|e| e * 1e3);
    if surface_rms_um.is_none() {
        problems.push("no error against the true surface".into());
    }
    RunErrors {
        tracking_urad,
        stud_height_um,
        surface_rms_um,
        problems,
    }
}

/// Rms over periods and both axes of `run - reference`, urad.
///
/// # Errors
/// Records of different lengths (a run that stopped early), or empty ones.
pub fn angle_difference_rms_urad(run: &[[i32; 2]], reference: &[[i32; 2]]) -> Result<f64, String> {
    if run.len() != reference.len() {
        return Err(format!(
            "{} periods of angles against the reference's {}",
            run.len(),
            reference.len()
        ));
    }
    if run.is_empty() {
        return Err("no period of angles recorded".into());
    }
    let sum2: f64 = run
        .iter()
        .zip(reference)
        .flat_map(|(a, r)| [0, 1].map(|axis| f64::from(a[axis]) - f64::from(r[axis])))
        .map(|d| d * d)
        .sum();
    Ok((sum2 / (2 * run.len()) as f64).sqrt())
}

/// The mirror angles of every period from a candump `-L` record of the loop (`fsm.log`): the
/// angle readings (`AngleReading`, or the FD `AnglesDistanceFd`), in order; other frames are
/// passed over.
///
/// # Errors
/// `PATH:LINE: ...` for a line that is not a candump record, an angle reading that does not
/// decode, or one whose period counter does not follow the one before (a period missing).
pub fn parse_period_angles(text: &str, path: &Path) -> anyhow::Result<Vec<[i32; 2]>> {
    let mut angles = Vec::new();
    let mut last_seq: Option<u16> = None;
    for (index, line) in text.lines().enumerate() {
        let at = || format!("{}:{}", path.display(), index + 1);
        if line.trim().is_empty() {
            continue;
        }
        let record = parse_record(line).map_err(|kind| anyhow::anyhow!("{}: {kind}", at()))?;
        let LogRecord::Frame(entry) = record else {
            continue;
        };
        let id = entry.frame.id();
        if id.is_extended()
            || ![ids::ANGLE_READING, ids::ANGLES_DISTANCE_FD]
                .map(u32::from)
                .contains(&id.as_raw())
        {
            continue;
        }
        let reading = match Message::decode(&entry.frame) {
            Ok(
                Message::AngleReading(reading)
                | Message::AnglesDistanceFd {
                    angles: reading, ..
                },
            ) => reading,
            Ok(other) => bail!("{}: expected an angle reading, found {other:?}", at()),
            Err(error) => bail!("{}: {error}", at()),
        };
        if let Some(last) = last_seq.filter(|&last| reading.seq != last.wrapping_add(1)) {
            bail!(
                "{}: the angle reading of period {} follows that of period {last}: a period \
                 is missing",
                at(),
                reading.seq
            );
        }
        last_seq = Some(reading.seq);
        angles.push([reading.alpha_urad, reading.beta_urad]);
    }
    Ok(angles)
}

/// Reads a result folder's [`RunRecord`] (its `fsm.log` and the figures of its `row`).
fn read_record(result: &Path, row: &Row) -> anyhow::Result<RunRecord> {
    let path = result.join(ANGLE_RECORD);
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    Ok(RunRecord {
        angles_urad: parse_period_angles(&text, &path)?,
        stud_height_mm: row.stud_height_mm,
        surface_rms_mm: row.rms_error_mm,
    })
}

/// Median, least and largest of a set of values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Spread {
    /// The median (the mean of the middle two of an even count).
    pub median: f64,
    /// The least.
    pub min: f64,
    /// The largest.
    pub max: f64,
}

impl Spread {
    /// The spread of the finite `values`; `None` when there is none.
    #[must_use]
    pub fn of(values: &[f64]) -> Option<Spread> {
        let mut sorted: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        let median = match n {
            0 => return None,
            _ if n % 2 == 1 => sorted[n / 2],
            _ => (sorted[n / 2 - 1] + sorted[n / 2]) / 2.0,
        };
        Some(Spread {
            median,
            min: sorted[0],
            max: sorted[n - 1],
        })
    }
}

/// Which of `points` are on the Pareto front when every coordinate is to be as small as
/// possible: a point is on it when no other point is at most as large in every coordinate
/// and smaller in one. A point that is `None` or not finite is neither on the front nor
/// counted against the others.
#[must_use]
pub fn pareto_front<const N: usize>(points: &[Option<[f64; N]>]) -> Vec<bool> {
    let usable: Vec<Option<&[f64; N]>> = points
        .iter()
        .map(|p| p.as_ref().filter(|p| p.iter().all(|v| v.is_finite())))
        .collect();
    let dominates = |a: &[f64; N], b: &[f64; N]| {
        a.iter().zip(b).all(|(x, y)| x <= y) && a.iter().zip(b).any(|(x, y)| x < y)
    };
    usable
        .iter()
        .map(|p| p.is_some_and(|p| !usable.iter().flatten().any(|other| dominates(other, p))))
        .collect()
}

/// One configuration over its repeats.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// 1-based configuration number.
    pub configuration: usize,
    /// Whether it is the reference.
    pub reference: bool,
    /// The values the study set, by key.
    pub parameters: BTreeMap<String, Value>,
    /// Its runs.
    pub runs: usize,
    /// Its complete runs.
    pub complete: usize,
    /// Wall time per scan over the repeats (median, min, max), s.
    pub run_time_s: Option<Spread>,
    /// Median over the repeats, urad.
    pub tracking_vs_reference_urad: Option<f64>,
    /// Median over the repeats, mm.
    pub stud_height_mm: Option<f64>,
    /// Median over the repeats, um.
    pub stud_height_vs_reference_um: Option<f64>,
    /// Median over the repeats, um.
    pub surface_rms_um: Option<f64>,
    /// Whether no other configuration is as fast and as accurate in every error and better in
    /// one (median time; tracking error, |stud height error|, surface rms).
    pub pareto: bool,
}

impl Summary {
    /// The coordinates the Pareto front is taken over, when the configuration has them all
    /// and every run of it is complete.
    fn objectives(&self) -> Option<[f64; 4]> {
        (self.complete == self.runs).then_some(())?;
        Some([
            self.run_time_s?.median,
            self.tracking_vs_reference_urad?,
            self.stud_height_vs_reference_um?.abs(),
            self.surface_rms_um?,
        ])
    }
}

/// Groups `rows` by configuration (in order) into summaries, with the Pareto front marked.
#[must_use]
pub fn summarise(rows: &[PrecisionRow]) -> Vec<Summary> {
    let mut configurations: Vec<usize> = rows.iter().map(|r| r.configuration).collect();
    configurations.sort_unstable();
    configurations.dedup();
    let mut summaries: Vec<Summary> = configurations
        .into_iter()
        .map(|configuration| {
            let runs: Vec<&PrecisionRow> = rows
                .iter()
                .filter(|r| r.configuration == configuration)
                .collect();
            let median = |figure: fn(&PrecisionRow) -> Option<f64>| {
                Spread::of(&runs.iter().filter_map(|r| figure(r)).collect::<Vec<_>>())
                    .map(|s| s.median)
            };
            Summary {
                configuration,
                reference: runs[0].reference,
                parameters: runs[0].parameters.clone(),
                runs: runs.len(),
                complete: runs
                    .iter()
                    .filter(|r| r.verdict == Some(Status::Complete))
                    .count(),
                run_time_s: Spread::of(
                    &runs.iter().filter_map(|r| r.run_time_s).collect::<Vec<_>>(),
                ),
                tracking_vs_reference_urad: median(|r| r.tracking_vs_reference_urad),
                stud_height_mm: median(|r| r.stud_height_mm),
                stud_height_vs_reference_um: median(|r| r.stud_height_vs_reference_um),
                surface_rms_um: median(|r| r.surface_rms_um),
                pareto: false,
            }
        })
        .collect();
    let objectives: Vec<Option<[f64; 4]>> = summaries.iter().map(Summary::objectives).collect();
    for (summary, on_front) in summaries.iter_mut().zip(pareto_front(&objectives)) {
        summary.pareto = on_front;
    }
    summaries
}

/// A precision study's table: every run and every configuration's summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Precision {
    /// The study's name.
    pub study: String,
    /// The study file.
    pub file: String,
    /// The base scenario.
    pub scenario: String,
    /// Runs of each configuration.
    pub repeats: usize,
    /// The reference's configuration number (1-based).
    pub reference: usize,
    /// One row per configuration and repeat, configuration first.
    pub rows: Vec<PrecisionRow>,
    /// One per configuration.
    pub summaries: Vec<Summary>,
}

/// Reads every run's result folder and writes `precision.csv`, `precision.json`,
/// `precision.svg` and `precision.png` into `out_dir`.
///
/// # Errors
/// A study without a `reference`; an output file that cannot be written. (A run without a
/// readable report or record is a row with its problem, not an error.)
pub fn collect(study: &Study, out_dir: &Path) -> anyhow::Result<Precision> {
    check(study)?;
    let reference = study.reference.unwrap_or_default();
    let mut rows = Vec::new();
    let results: Vec<Vec<(Row, Result<RunRecord, String>)>> = (0..study.repeats)
        .map(|repeat| {
            (0..study.variants.len())
                .map(|index| {
                    let dir = repeat_dir(out_dir, index, repeat);
                    let row = Row::from_result_dir(study, index, &dir);
                    let record = if row.verdict.is_some() {
                        read_record(&dir, &row)
                            .map_err(|e| scanhil_protocol::error_text::chain_text(&*e))
                    } else {
                        Err("no report".to_owned())
                    };
                    (row, record)
                })
                .collect()
        })
        .collect();
    for index in 0..study.variants.len() {
        for (repeat, round) in results.iter().enumerate() {
            let (row, record) = &round[index];
            let mut problems: Vec<String> = row.problem.iter().cloned().collect();
            let errors = match (record, &round[reference].1) {
                (Ok(record), Ok(reference_record)) => errors_against(record, reference_record),
                (Err(problem), _) => RunErrors {
                    surface_rms_um: row.rms_error_mm.map(|e| e * 1e3),
                    problems: vec![problem.clone()],
                    ..RunErrors::default()
                },
                (_, Err(problem)) => RunErrors {
                    surface_rms_um: row.rms_error_mm.map(|e| e * 1e3),
                    problems: vec![format!(
                        "the reference's run (configuration {}, repeat {}) gives no errors to \
                         compare with: {problem}",
                        reference + 1,
                        repeat + 1
                    )],
                    ..RunErrors::default()
                },
            };
            for problem in errors.problems {
                if !problems.contains(&problem) {
                    problems.push(problem);
                }
            }
            rows.push(PrecisionRow {
                configuration: index + 1,
                repeat: repeat + 1,
                reference: index == reference,
                parameters: study.variants[index].clone(),
                verdict: row.verdict,
                run_time_s: row.run_time_s,
                tracking_vs_reference_urad: errors.tracking_urad,
                stud_height_mm: row.stud_height_mm,
                stud_height_vs_reference_um: errors.stud_height_um,
                surface_rms_um: errors.surface_rms_um,
                problem: (!problems.is_empty()).then(|| problems.join("; ")),
            });
        }
    }
    let precision = Precision {
        study: study.name.clone(),
        file: study.path.display().to_string(),
        scenario: study.scenario.display().to_string(),
        repeats: study.repeats,
        reference: reference + 1,
        summaries: summarise(&rows),
        rows,
    };
    write_outputs(study, &precision, out_dir)?;
    Ok(precision)
}

fn write_outputs(study: &Study, precision: &Precision, out_dir: &Path) -> anyhow::Result<()> {
    let json_path = out_dir.join(PRECISION_JSON);
    scanhil_protocol::whole_file::write_file(
        &json_path,
        serde_json::to_string_pretty(precision).context("formatting precision.json")? + "\n",
    )
    .with_context(|| format!("writing {}", json_path.display()))?;
    let csv_path = out_dir.join(PRECISION_CSV);
    let mut csv = Vec::new();
    write_csv(&mut csv, &study.keys(), precision).context("formatting precision.csv")?;
    scanhil_protocol::whole_file::write_file(&csv_path, csv)
        .with_context(|| format!("writing {}", csv_path.display()))?;
    let charts = charts(precision);
    for name in [PRECISION_SVG, PRECISION_PNG] {
        let path = out_dir.join(name);
        draw_charts(&path, &charts).with_context(|| format!("drawing {}", path.display()))?;
    }
    Ok(())
}

/// The columns after the configuration number and the parameters.
const COLUMNS: [&str; 10] = [
    "repeat",
    "reference",
    "verdict",
    "run_time_s",
    "tracking_vs_reference_urad",
    "stud_height_mm",
    "stud_height_vs_reference_um",
    "surface_rms_um",
    "pareto",
    "problem",
];

/// Writes one CSV row per run (RFC 4180 quoting); empty cells where a figure is missing;
/// `pareto` is its configuration's.
///
/// # Errors
/// The writer's error.
pub fn write_csv(
    out: &mut impl Write,
    keys: &[String],
    precision: &Precision,
) -> std::io::Result<()> {
    let header: Vec<String> = std::iter::once("configuration".to_owned())
        .chain(keys.iter().cloned())
        .chain(COLUMNS.iter().map(|c| (*c).to_owned()))
        .collect();
    let line = |cells: &[String]| cells.iter().map(|c| quote(c)).collect::<Vec<_>>().join(",");
    writeln!(out, "{}", line(&header))?;
    let figure = |v: Option<f64>| v.map_or(String::new(), |v| v.to_string());
    for row in &precision.rows {
        let pareto = precision
            .summaries
            .iter()
            .any(|s| s.configuration == row.configuration && s.pareto);
        let mut cells = vec![row.configuration.to_string()];
        cells.extend(keys.iter().map(|k| parameter_cell(row.parameters.get(k))));
        cells.push(row.repeat.to_string());
        cells.push(row.reference.to_string());
        cells.push(row.verdict.map_or(String::new(), |v| v.name().to_owned()));
        cells.extend(
            [
                row.run_time_s,
                row.tracking_vs_reference_urad,
                row.stud_height_mm,
                row.stud_height_vs_reference_um,
                row.surface_rms_um,
            ]
            .map(figure),
        );
        cells.push(pareto.to_string());
        cells.push(row.problem.clone().unwrap_or_default());
        writeln!(out, "{}", line(&cells))?;
    }
    Ok(())
}

/// One figure of a configuration's summary.
type SummaryFigure = fn(&Summary) -> Option<f64>;

/// One log-log panel per error: each configuration at its median run time with a bar from
/// its least to its largest, and the Pareto front's members marked. An error of 0
/// (the reference's, and any configuration's equal to it) is drawn below the smallest
/// nonzero one ([`LogZero`]); the axis label says so.
#[must_use]
pub fn charts(precision: &Precision) -> Vec<Chart> {
    let panels: [(&str, SummaryFigure); 3] = [
        ("tracking rms vs reference [urad]", |s| {
            s.tracking_vs_reference_urad
        }),
        ("|stud height - reference| [um]", |s| {
            s.stud_height_vs_reference_um.map(f64::abs)
        }),
        ("surface rms vs truth [um]", |s| s.surface_rms_um),
    ];
    let gap = (f64::NAN, f64::NAN);
    panels
        .into_iter()
        .map(|(label, error)| {
            let zero = LogZero::of(precision.summaries.iter().filter_map(error));
            let placed: Vec<(&Summary, Spread, f64)> = precision
                .summaries
                .iter()
                .filter_map(|s| {
                    let e = error(s)?;
                    Some((s, s.run_time_s?, zero.map_or(e, |z| z.place(e))))
                })
                .collect();
            let front: Vec<(f64, f64)> = placed
                .iter()
                .filter(|(s, ..)| s.pareto)
                .map(|(_, t, e)| (t.median, *e))
                .collect();
            let note = zero.map_or_else(String::new, |z| z.note("the reference's"));
            Chart {
                title: format!(
                    "{}: {} configurations x {} runs",
                    precision.study,
                    precision.summaries.len(),
                    precision.repeats
                ),
                x_label: "wall time per scan [s]".into(),
                y_label: format!("{label}{note}"),
                x_axis: Axis::Log,
                y_axis: Axis::Log,
                series: vec![
                    Series {
                        label: "configuration (median time)".into(),
                        // A gap after every point: markers, no line between configurations.
                        points: placed
                            .iter()
                            .flat_map(|(_, t, e)| [(t.median, *e), gap])
                            .collect(),
                        markers: true,
                    },
                    Series {
                        label: "least to largest time".into(),
                        points: placed
                            .iter()
                            .flat_map(|(_, t, e)| [(t.min, *e), (t.max, *e), gap])
                            .collect(),
                        markers: false,
                    },
                    Series {
                        label: "on the Pareto front (time and all three errors)".into(),
                        // Marked, not joined: the front is over four figures, and a line
                        // through its members in one panel's two would read as a 2-D front.
                        points: front.into_iter().flat_map(|point| [point, gap]).collect(),
                        markers: true,
                    },
                ],
            }
        })
        .collect()
}

/// `key=value, ...` of a configuration, `reference` for the reference's.
#[must_use]
pub fn name(summary: &Summary) -> String {
    let values = describe(&summary.parameters);
    if summary.reference {
        format!("{values} (reference)")
    } else {
        values
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn angle_readings_are_read_per_period_and_other_frames_passed_over() {
        let log = "(0.000000) fsm 100#0000000000000000\n\
                   (0.000050) fsm 110#0000020000FCFFFF\n\
                   \n\
                   (0.000100) fsm 110#0100030000000000\n\
                   (0.000100) fsm 021#02000000\n";
        let angles = parse_period_angles(log, Path::new("r/fsm.log")).unwrap();
        assert_eq!(angles, [[2, -4], [3, 0]]);
    }

    #[test]
    fn a_bad_line_or_a_missing_period_is_named_by_file_and_line() {
        let bad = "(0.000050) fsm 110#0000020000FCFFFF\nnot a frame\n";
        let error = parse_period_angles(bad, Path::new("r/fsm.log")).unwrap_err();
        assert!(error.to_string().starts_with("r/fsm.log:2: "), "{error}");
        let gap = "(0.000050) fsm 110#0000020000FCFFFF\n(0.000150) fsm 110#0200020000FCFFFF\n";
        let error = parse_period_angles(gap, Path::new("r/fsm.log")).unwrap_err();
        assert!(
            error.to_string().starts_with("r/fsm.log:2: ") && error.to_string().contains("missing"),
            "{error}"
        );
        let short = "(0.000050) fsm 110#000002\n";
        let error = parse_period_angles(short, Path::new("r/fsm.log")).unwrap_err();
        assert!(error.to_string().starts_with("r/fsm.log:1: "), "{error}");
    }

    #[test]
    fn the_angle_difference_is_the_rms_over_periods_and_axes() {
        let reference = [[0, 0], [10, -10]];
        assert_eq!(angle_difference_rms_urad(&reference, &reference), Ok(0.0));
        // Differences 3, 4, 0, 0: rms sqrt(25 / 4).
        let run = [[3, 4], [10, -10]];
        assert_eq!(angle_difference_rms_urad(&run, &reference), Ok(2.5));
        assert!(angle_difference_rms_urad(&run[..1], &reference).is_err());
        assert!(angle_difference_rms_urad(&[], &[]).is_err());
    }

    #[test]
    fn errors_against_the_reference_are_differences_in_um_and_urad() {
        let reference = RunRecord {
            angles_urad: vec![[1, 1]; 4],
            stud_height_mm: Some(4.6),
            surface_rms_mm: Some(0.5),
        };
        let same = errors_against(&reference, &reference);
        assert_eq!(same.tracking_urad, Some(0.0));
        assert_eq!(same.stud_height_um, Some(0.0));
        assert_eq!(same.surface_rms_um, Some(500.0));
        assert!(same.problems.is_empty());
        let run = RunRecord {
            angles_urad: vec![[3, 1]; 4],
            stud_height_mm: Some(4.65),
            surface_rms_mm: None,
        };
        let errors = errors_against(&run, &reference);
        assert_eq!(errors.tracking_urad, Some(2f64.sqrt()));
        assert!((errors.stud_height_um.unwrap() - 50.0).abs() < 1e-9);
        assert_eq!(errors.problems, ["no error against the true surface"]);
    }

    #[test]
    fn a_spread_is_median_least_and_largest_of_the_finite_values() {
        assert_eq!(Spread::of(&[]), None);
        assert_eq!(
            Spread::of(&[3.0, 1.0, f64::NAN, 2.0]),
            Some(Spread {
                median: 2.0,
                min: 1.0,
                max: 3.0
            })
        );
        assert_eq!(
            Spread::of(&[4.0, 1.0, 2.0, 3.0]).map(|s| s.median),
            Some(2.5)
        );
        // Five repeats, the study's count: the third of the sorted times.
        assert_eq!(
            Spread::of(&[0.5, 0.1, 0.4, 0.2, 0.3]).map(|s| s.median),
            Some(0.3)
        );
    }

    #[test]
    fn the_front_leaves_out_the_dominated_the_missing_and_the_not_finite() {
        let front = pareto_front(&[
            Some([1.0, 5.0]),
            Some([2.0, 2.0]),
            Some([3.0, 2.0]),
            None,
            Some([f64::NAN, 0.0]),
            Some([2.0, 2.0]),
        ]);
        assert_eq!(front, [true, true, false, false, false, true]);
    }

    fn row(configuration: usize, repeat: usize, time: f64, tracking: f64) -> PrecisionRow {
        PrecisionRow {
            configuration,
            repeat,
            reference: configuration == 1,
            parameters: BTreeMap::new(),
            verdict: Some(Status::Complete),
            run_time_s: Some(time),
            tracking_vs_reference_urad: Some(tracking),
            stud_height_mm: Some(4.6),
            stud_height_vs_reference_um: Some(0.0),
            surface_rms_um: Some(10.0),
            problem: None,
        }
    }

    #[test]
    fn summaries_give_each_configuration_its_time_spread_and_front_flag() {
        let rows = [
            row(1, 1, 0.3, 0.0),
            row(1, 2, 0.1, 0.0),
            row(1, 3, 0.2, 0.0),
            row(2, 1, 0.05, 2.0),
            row(2, 2, 0.07, 2.0),
            row(3, 1, 0.5, 3.0),
            row(3, 2, 0.6, 3.0),
        ];
        let summaries = summarise(&rows);
        assert_eq!(summaries.len(), 3);
        assert_eq!(
            summaries[0].run_time_s,
            Some(Spread {
                median: 0.2,
                min: 0.1,
                max: 0.3
            })
        );
        assert!(summaries[0].reference && summaries[0].runs == 3);
        assert_eq!(
            summaries.iter().map(|s| s.pareto).collect::<Vec<_>>(),
            [true, true, false]
        );
        // A configuration with a run that is not complete is not on the front.
        let mut rows = rows.to_vec();
        rows[3].verdict = Some(Status::Stopped);
        assert!(!summarise(&rows)[1].pareto);
    }

    proptest! {
        #[test]
        fn no_front_member_is_dominated_and_every_other_point_is_dominated_by_one(
            points in proptest::collection::vec(
                proptest::option::weighted(0.9, [0u8..6, 0u8..6, 0u8..6].prop_map(|p| p.map(f64::from))),
                0..24,
            )
        ) {
            let front = pareto_front(&points);
            let dominates = |a: &[f64; 3], b: &[f64; 3]| {
                a.iter().zip(b).all(|(x, y)| x <= y) && a.iter().zip(b).any(|(x, y)| x < y)
            };
            let members: Vec<&[f64; 3]> = points
                .iter()
                .zip(&front)
                .filter(|(_, on)| **on)
                .filter_map(|(p, _)| p.as_ref())
                .collect();
            for (point, on) in points.iter().zip(&front) {
                match point {
                    None => prop_assert!(!on),
                    Some(p) if *on => {
                        prop_assert!(!points.iter().flatten().any(|q| dominates(q, p)));
                    }
                    Some(p) => prop_assert!(members.iter().any(|m| dominates(m, p))),
                }
            }
        }
    }
}
