//! `scanhil-study`: runs a study (one scenario, many variants) and tabulates it.
//!
//! - `scanhil-study run STUDY --out DIR [--jobs N] [--no-recordings] [--no-figures]`: writes
//!   the variants, runs them in this process on N threads (default: one per core), writes
//!   `DIR/study.csv` and `study.json`. The two flags leave out every variant's recordings and
//!   pictures (the study file's `outputs`).
//! - `scanhil-study plan STUDY --out DIR`: writes the variants only and prints their scenario
//!   files, one per line, for a batch system to run with `scanhil scan FILE --out
//!   <its folder>/result`.
//! - `scanhil-study collect STUDY --out DIR`: tabulates the result folders a batch system
//!   wrote.
//! - `scanhil-study precision STUDY --out DIR [--jobs N]`: runs every variant the study's
//!   `repeats` times, one scan at a time by default (so no scan's wall time is inflated by
//!   another's), and writes `DIR/precision.csv`, `precision.json`, `precision.svg` and
//!   `precision.png`: wall time per scan against the errors against the study's `reference`.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use scanhil_controller::run::verdict::Status;
use scanhil_lab::study::plan::Study;
use scanhil_lab::study::precision;
use scanhil_lab::study::run::{VariantOutcome, default_jobs, run_variants};
use scanhil_lab::study::table::{Row, collect};

#[derive(Debug, Parser)]
#[command(
    name = "scanhil-study",
    version,
    about = "Runs scanhil scenario variants as one study"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Write the variants, run them here across the cores, and tabulate them.
    Run {
        /// The study file.
        study: PathBuf,
        /// The study's folder (variants/, study.csv, study.json).
        #[arg(long)]
        out: PathBuf,
        /// Worker threads (default: one per core).
        #[arg(long, allow_negative_numbers = true)]
        jobs: Option<usize>,
        #[command(flatten)]
        leave_out: LeaveOut,
    },
    /// Write the variants' files only; print their scenario files.
    Plan {
        /// The study file.
        study: PathBuf,
        /// The study's folder.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        leave_out: LeaveOut,
    },
    /// Run every variant `repeats` times and set its wall time against its errors against the
    /// study's `reference` (work-precision).
    Precision {
        /// The study file (with `reference` and `repeats`).
        study: PathBuf,
        /// The study's folder (variants/, precision.csv, precision.json, precision.svg,
        /// precision.png).
        #[arg(long)]
        out: PathBuf,
        /// Worker threads (default 1: two scans at once on a shared machine slow each other,
        /// and the wall time is what is measured).
        #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
        jobs: usize,
    },
    /// Tabulate the result folders of variants run elsewhere.
    Collect {
        /// The study file.
        study: PathBuf,
        /// The study's folder.
        #[arg(long)]
        out: PathBuf,
    },
}

/// What every variant leaves out, on top of the study file's `outputs`.
#[derive(Debug, clap::Args)]
struct LeaveOut {
    /// Leave out every variant's recordings (`fsm.log`, `sensor.ild`).
    #[arg(long)]
    no_recordings: bool,
    /// Leave out every variant's pictures (SVG, PNG); the table is the same.
    #[arg(long)]
    no_figures: bool,
}

impl LeaveOut {
    /// The study at `path`, leaving out what these flags say.
    fn load(&self, path: &std::path::Path) -> anyhow::Result<Study> {
        let mut study = Study::load(path)?;
        if self.no_recordings || self.no_figures {
            study.leave_out(self.no_recordings, self.no_figures);
        }
        Ok(study)
    }
}

fn main() -> ExitCode {
    scanhil_controller::run::chunked::return_freed_chunks_to_the_os();
    match run(Cli::parse()) {
        Ok(code) => code,
        Err(error) => {
            eprintln!(
                "scanhil-study: error: {}",
                scanhil_protocol::error_text::chain_text(&*error)
            );
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Run {
            study,
            out,
            jobs,
            leave_out,
        } => {
            let study = leave_out.load(&study)?;
            let jobs = jobs.unwrap_or_else(default_jobs);
            if jobs == 0 {
                anyhow::bail!("--jobs 0: at least one worker is needed");
            }
            let scenarios = study.write_variants(&out)?;
            let started = std::time::Instant::now();
            let outcomes = run_variants(&study, &scenarios, jobs);
            let rows = collect(&study, &out)?;
            let failed = outcomes
                .iter()
                .filter(|o| matches!(o, VariantOutcome::Failed(_)))
                .count();
            summarise(&rows, &out)?;
            scanhil_protocol::outln!(
                "{} variants on {jobs} threads in {:.2} s, {failed} failed",
                rows.len(),
                started.elapsed().as_secs_f64()
            )?;
            Ok(exit_code(rows.iter().map(|r| r.verdict)))
        }
        Command::Precision { study, out, jobs } => {
            if jobs == 0 {
                anyhow::bail!("--jobs 0: at least one worker is needed");
            }
            let study = Study::load(&study)?;
            let started = std::time::Instant::now();
            precision::run(&study, &out, jobs)?;
            let table = precision::collect(&study, &out)?;
            print_precision(&table, &out)?;
            scanhil_protocol::outln!(
                "{} scans ({} configurations x {}) on {jobs} thread(s) in {:.2} s",
                table.rows.len(),
                table.summaries.len(),
                table.repeats,
                started.elapsed().as_secs_f64()
            )?;
            Ok(precision_exit_code(&table))
        }
        Command::Plan {
            study,
            out,
            leave_out,
        } => {
            let study = leave_out.load(&study)?;
            for scenario in study.write_variants(&out)? {
                scanhil_protocol::outln!("{}", scenario.display())?;
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Collect { study, out } => {
            let rows = collect(&Study::load(&study)?, &out)?;
            summarise(&rows, &out)?;
            Ok(exit_code(rows.iter().map(|r| r.verdict)))
        }
    }
}

/// Prints each configuration's summary, the Pareto front and the files; each run that is not
/// complete or has no errors on stderr.
fn print_precision(table: &precision::Precision, out: &std::path::Path) -> std::io::Result<()> {
    for row in table.rows.iter().filter(|r| r.problem.is_some()) {
        eprintln!(
            "configuration {} repeat {} {}: {}",
            row.configuration,
            row.repeat,
            row.verdict.map_or("not run", Status::name),
            row.problem.as_deref().unwrap_or_default()
        );
    }
    let figure = |v: Option<f64>, digits: usize| {
        v.map_or_else(|| "-".to_owned(), |v| format!("{v:.digits$}"))
    };
    scanhil_protocol::outln!(
        "{:>3} {:>8} {:>17} {:>14} {:>10} {:>10} {:>11}  choices",
        "cfg",
        "time_s",
        "[min - max]",
        "tracking_urad",
        "height_mm",
        "dh_um",
        "surface_um"
    )?;
    for s in &table.summaries {
        let time = s.run_time_s;
        scanhil_protocol::outln!(
            "{:>3} {:>8} {:>17} {:>14} {:>10} {:>10} {:>11}{} {}",
            s.configuration,
            figure(time.map(|t| t.median), 4),
            time.map_or_else(
                || "-".to_owned(),
                |t| format!("[{:.4} - {:.4}]", t.min, t.max)
            ),
            figure(s.tracking_vs_reference_urad, 3),
            figure(s.stud_height_mm, 4),
            figure(s.stud_height_vs_reference_um, 2),
            figure(s.surface_rms_um, 1),
            if s.pareto { " *" } else { "  " },
            precision::name(s)
        )?;
    }
    let front: Vec<String> = table
        .summaries
        .iter()
        .filter(|s| s.pareto)
        .map(|s| s.configuration.to_string())
        .collect();
    scanhil_protocol::outln!(
        "Pareto front (*: not beaten in time and all three errors at once): configurations {}",
        front.join(", ")
    )?;
    scanhil_protocol::outln!(
        "wrote {}, {}, {} and {}",
        out.join(precision::PRECISION_CSV).display(),
        out.join(precision::PRECISION_JSON).display(),
        out.join(precision::PRECISION_SVG).display(),
        out.join(precision::PRECISION_PNG).display()
    )
}

/// As [`exit_code`] over the runs; when every run is complete but one has an error missing
/// (a record that could not be read: its row says why), 4.
fn precision_exit_code(table: &precision::Precision) -> ExitCode {
    let all_complete = table
        .rows
        .iter()
        .all(|r| r.verdict == Some(Status::Complete));
    let errors_missing = table.rows.iter().any(|r| {
        r.tracking_vs_reference_urad.is_none()
            || r.stud_height_vs_reference_um.is_none()
            || r.surface_rms_um.is_none()
    });
    if all_complete && errors_missing {
        ExitCode::from(Status::Failed.exit_code())
    } else {
        exit_code(table.rows.iter().map(|r| r.verdict))
    }
}

fn summarise(rows: &[Row], out: &std::path::Path) -> std::io::Result<()> {
    for row in rows.iter().filter(|r| r.verdict != Some(Status::Complete)) {
        eprintln!(
            "variant {} {}: {}",
            row.variant,
            row.verdict.map_or("not run", Status::name),
            row.problem.as_deref().unwrap_or("incomplete")
        );
    }
    scanhil_protocol::outln!(
        "wrote {} and {}",
        out.join("study.csv").display(),
        out.join("study.json").display()
    )
}

/// 0 when every run is complete; 3 when one stopped early or has no report; else 4 when one
/// completed with a result that is not valid (their rows say why), as `scanhil scan`.
fn exit_code(verdicts: impl Iterator<Item = Option<Status>>) -> ExitCode {
    let worst = verdicts
        .map(|verdict| verdict.unwrap_or(Status::Stopped))
        .map(Status::exit_code)
        .max_by_key(|code| match code {
            0 => 0,
            4 => 1,
            _ => 2,
        })
        .unwrap_or(0);
    ExitCode::from(worst)
}
