//! `scanhil compare`: two scan (or reconstruct) output folders side by side, the paper's
//! Fig. 6 (snapshots, rows = scans) and Fig. 10 (both scans' sections and the truth).

use std::path::PathBuf;
use std::process::ExitCode;

use scanhil_controller::imaging::compare::{ScanFolder, draw_comparison};

/// Arguments of `scanhil compare`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The first output folder (of `scanhil scan` or `scanhil reconstruct`).
    dir_a: PathBuf,
    /// The second output folder.
    dir_b: PathBuf,
    /// Folder for snapshots.png and profiles.svg.
    #[arg(long, default_value = "compare")]
    out: PathBuf,
    /// The scans' names in the figures, two separated by a comma (default: the folder names).
    #[arg(long, value_delimiter = ',')]
    labels: Option<Vec<String>>,
}

/// Runs `scanhil compare`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let dirs = [&args.dir_a, &args.dir_b];
    let labels: Vec<String> = match args.labels {
        Some(labels) => labels,
        None => dirs
            .iter()
            .map(|d| {
                d.file_name()
                    .map_or_else(|| d.display().to_string(), |n| n.to_string_lossy().into())
            })
            .collect(),
    };
    if labels.len() != 2 {
        anyhow::bail!("--labels: {} names given, 2 needed (A,B)", labels.len());
    }
    let scans = dirs
        .iter()
        .zip(&labels)
        .map(|(dir, label)| ScanFolder::read(dir, label))
        .collect::<Result<Vec<_>, _>>()?;
    for file in draw_comparison(&scans, &args.out)? {
        scanhil_protocol::outln!("wrote {}", file.display())?;
    }
    Ok(ExitCode::SUCCESS)
}
