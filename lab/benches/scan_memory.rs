//! How a scan's memory grows with its frame: the one-process loop ([`scanhil_lab::in_process`],
//! the same host loop, pairing, imaging and output writer as `scanhil scan`) on the paper's
//! Duplo Lissajous frame (`fixtures/scenarios/duplo-lissajous-dual-tone.json`, the shipped
//! scene with its 7-ray spot, no lead-in) for frames of [`FRAMES_S`] seconds. The heap is
//! counted by the process's allocator ([`peak_alloc`]): for each frame, above what was held
//! before the scan, the peak while the loop runs, what it leaves for the writer, and the peak
//! while the output folder is written (pairing, reconstruction, imaging, files). The growth per frame period and per point is
//! the least-squares slope over the frames; a scan whose memory is flat in its length would
//! show 0. Writes JSON to stdout and to `target/scan_memory.json`.
//!
//! Run: `cargo bench -p scanhil-lab --bench scan_memory`.

mod support;

use peak_alloc::PeakAlloc;
use scanhil_controller::run::lead_in::LeadIn;
use scanhil_controller::run::scenario::Scenario;
use support::root;

#[global_allocator]
static HEAP: PeakAlloc = PeakAlloc;

/// The frames measured, s.
const FRAMES_S: [f64; 4] = [1.0, 2.0, 4.0, 8.0];

/// The peak heap while `work` runs, above `base` (bytes held before the scan).
fn peak_above<T>(
    base: usize,
    work: impl FnOnce() -> anyhow::Result<T>,
) -> anyhow::Result<(T, usize)> {
    HEAP.reset_peak_usage();
    let out = work()?;
    Ok((out, HEAP.peak_usage().saturating_sub(base)))
}

/// The least-squares slope of `y` against `x`.
fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let mean_x = points.iter().map(|p| p.0).sum::<f64>() / n;
    let mean_y = points.iter().map(|p| p.1).sum::<f64>() / n;
    let covariance: f64 = points.iter().map(|p| (p.0 - mean_x) * (p.1 - mean_y)).sum();
    let variance: f64 = points.iter().map(|p| (p.0 - mean_x).powi(2)).sum();
    covariance / variance
}

fn main() -> anyhow::Result<()> {
    let mut scenario =
        Scenario::load(&root().join("fixtures/scenarios/duplo-lissajous-dual-tone.json"))?;
    scenario.lead_in = LeadIn::None;
    let mut rows = Vec::new();
    let (mut by_period, mut by_point) = (Vec::new(), Vec::new());
    for frame_s in FRAMES_S {
        scenario.duration_s = frame_s;
        let dir = tempfile::tempdir()?;
        let base = HEAP.current_usage();
        let (mut outcome, loop_peak) =
            peak_above(base, || scanhil_lab::in_process::run(&scenario, None))?;
        let held_after_loop = HEAP.current_usage().saturating_sub(base);
        let periods = outcome.run.record.periods_done;
        // The writer's peak counts what the loop left too: the scan's peak is the larger.
        let (_, write_peak) = peak_above(base, || outcome.write(dir.path()))?;
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("report.json"))?)?;
        let points = report["imaging"]["points"]
            .as_u64()
            .ok_or_else(|| anyhow::anyhow!("report.json: no imaging.points"))?;
        let scan_peak = loop_peak.max(write_peak);
        by_period.push((periods as f64, scan_peak as f64));
        by_point.push((points as f64, scan_peak as f64));
        rows.push(serde_json::json!({
            "frame_s": frame_s,
            "periods": periods,
            "points": points,
            "loop_peak_mb": loop_peak as f64 / 1e6,
            "held_after_loop_mb": held_after_loop as f64 / 1e6,
            "write_peak_mb": write_peak as f64 / 1e6,
            "scan_peak_mb": scan_peak as f64 / 1e6,
            "scan_peak_bytes_per_period": scan_peak as f64 / periods as f64,
        }));
    }
    support::publish(
        "scan_memory",
        &serde_json::json!({
            "frames": rows,
            "growth_bytes_per_frame_period": slope(&by_period),
            "growth_bytes_per_point": slope(&by_point),
        }),
    )?;
    Ok(())
}
