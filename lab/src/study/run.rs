//! Running a study's variants in this process, across every core: a pool of worker threads
//! takes the variants in order, each runs its scenario through the one-process loop into its
//! result folder; a progress bar counts them (on a terminal only).

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use scanhil_controller::run::scenario::Scenario;

use super::plan::{Study, describe};
use super::table::{FAILURE_FILE, RESULT_DIR};

/// How a variant's run went.
#[derive(Debug, Clone, PartialEq)]
pub enum VariantOutcome {
    /// The scan ran (complete or stopped early: its report says which).
    Ran,
    /// The scan could not run; the message says why.
    Failed(String),
}

/// One scan to run: a variant's scenario file and the folder its outputs go to.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanJob {
    /// The variant's index (0-based, for messages).
    pub variant: usize,
    /// Its scenario file.
    pub scenario: PathBuf,
    /// The result folder the run writes.
    pub result: PathBuf,
}

/// Runs the variants whose scenario files are `scenarios` (in the order of
/// [`Study::write_variants`]) on `jobs` threads (at least 1); each writes
/// `<its folder>/result/`. Returns each variant's outcome in order.
#[must_use]
pub fn run_variants(study: &Study, scenarios: &[PathBuf], jobs: usize) -> Vec<VariantOutcome> {
    let scans: Vec<ScanJob> = scenarios
        .iter()
        .enumerate()
        .map(|(variant, scenario)| ScanJob {
            variant,
            scenario: scenario.clone(),
            result: result_dir(scenario),
        })
        .collect();
    run_scans(study, &scans, jobs)
}

/// Runs `scans` on `jobs` threads (at least 1), taken in order: with one thread, one after
/// another. A scan that cannot run leaves its reason in its result folder
/// ([`FAILURE_FILE`]). Returns each scan's outcome in order.
#[must_use]
pub fn run_scans(study: &Study, scans: &[ScanJob], jobs: usize) -> Vec<VariantOutcome> {
    let next = AtomicUsize::new(0);
    let outcomes: Mutex<Vec<Option<VariantOutcome>>> = Mutex::new(vec![None; scans.len()]);
    let bar = indicatif::ProgressBar::new(scans.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{prefix} [{bar:40}] {pos}/{len} scans, {elapsed} (eta {eta})",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    bar.set_prefix(study.name.clone());
    std::thread::scope(|scope| {
        for _ in 0..jobs.max(1).min(scans.len().max(1)) {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(scan) = scans.get(i) else {
                        break;
                    };
                    let outcome = run_one(scan).unwrap_or_else(|error| {
                        let message = scanhil_protocol::error_text::chain_text(&*error);
                        bar.suspend(|| {
                            eprintln!(
                                "variant {} ({}): {message}",
                                scan.variant + 1,
                                describe(&study.variants[scan.variant])
                            );
                        });
                        record_failure(&scan.result, &message);
                        VariantOutcome::Failed(message)
                    });
                    if let Ok(mut outcomes) = outcomes.lock() {
                        outcomes[i] = Some(outcome);
                    }
                    bar.inc(1);
                }
            });
        }
    });
    bar.finish_and_clear();
    outcomes
        .into_inner()
        .unwrap_or_default()
        .into_iter()
        .map(|o| o.unwrap_or_else(|| VariantOutcome::Failed("not run".into())))
        .collect()
}

/// The result folder of the variant whose scenario file is `scenario_path`.
fn result_dir(scenario_path: &Path) -> PathBuf {
    scenario_path
        .parent()
        .unwrap_or(Path::new("."))
        .join(RESULT_DIR)
}

/// Runs one scan in process into its result folder.
fn run_one(scan: &ScanJob) -> anyhow::Result<VariantOutcome> {
    let scenario = Scenario::load(&scan.scenario)?;
    crate::in_process::run(&scenario, Some(&scan.result))?;
    Ok(VariantOutcome::Ran)
}

/// Keeps why a scan could not run in its result folder `dir`, for the table
/// ([`super::table::FAILURE_FILE`]); best effort, the message is printed as well.
fn record_failure(dir: &Path, message: &str) {
    let _ = std::fs::create_dir_all(dir);
    let _ = std::fs::write(dir.join(FAILURE_FILE), format!("{message}\n"));
}

/// The number of worker threads by default: one per core.
#[must_use]
pub fn default_jobs() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}
