//! Progressive imaging figures (the paper's Fig. 6 and error against scan time), as a bench
//! binary anyone can rerun:
//!
//! ```text
//! cargo bench -p scanhil-lab --bench imaging_progressive -- [--out DIR]
//! ```
//!
//! Simulates one second of ideal scanning (perfect tracking, 20 kHz sensor, no noise) of a
//! Duplo-like stud 130 mm below the mirror, through the exact reflection (the physical truth),
//! for the Lissajous 27/52 Hz and raster 2/34 Hz trajectories; reconstructs with each model;
//! writes to DIR (default `target/imaging-progressive`):
//! - `progressive.json`: per reconstruction model, per trajectory, the error at 100
//!   checkpoints (coverage, RMS/max over measured cells, RMS/max of the filled image);
//! - `progressive.svg` (and `.png`): the same against scan time, Lissajous and raster side by side
//!   (reconstructed with the paper's model);
//! - `{lissajous,raster}_{0.05,0.1,0.25,0.5,1}s.png`: the image after that much scan time,
//!   missing cells grey (Fig. 6);
//! - `timing.json`: wall time of each stage (a benchmark figure, not a test);
//! - `{lissajous,raster}_samples.csv`: the simulated recordings, ready for
//!   `scanhil reconstruct`;
//! - `duplo.json`, `duplo_{lissajous,raster}.png`, `duplo_*_samples.csv`: the paper's
//!   validation through the emulator's optics and sensor (`fixtures/scenes/duplo-2x4-130mm.json`:
//!   shading, 130 um spot, sensor noise): the stud's height and spread for each trajectory
//!   and reconstruction model, and the height maps above the base plane.

#[path = "../../controller/tests/imaging_support/mod.rs"]
mod imaging_support;

use std::path::{Path, PathBuf};
use std::time::Instant;

use imaging_support::{lissajous, raster, stud_scene};
use scanhil_controller::imaging::feature::FeatureParams;
use scanhil_controller::imaging::fill::FillMethod;
use scanhil_controller::imaging::grid::{GridMethod, GridSpec};
use scanhil_controller::imaging::pipeline::{ImagingOptions, image_samples};
use scanhil_controller::imaging::progressive::{
    ProgressiveComparison, ProgressiveRun, ScanScene, progressive_errors, progressive_maps,
    simulate_samples,
};
use scanhil_controller::imaging::reconstruct::reconstruct;
use scanhil_controller::imaging::recording::write_recording_csv;
use scanhil_geometry::{GeometryModel, Scanner};
use scanhil_lab::emulated_imaging::EmulatedScanner;

const SAMPLE_RATE_HZ: f64 = 20_000.0;
const PITCH_MM: f64 = 0.25;
const SNAPSHOTS_S: [f64; 5] = [0.05, 0.1, 0.25, 0.5, 1.0];

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1).filter(|a| a != "--bench");
    // Benches run in the package folder; default to the workspace's target folder.
    let mut out = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../target/imaging-progressive"
    ));
    while let Some(a) = args.next() {
        match a.as_str() {
            "--out" => out = args.next().map(PathBuf::from).unwrap_or(out),
            other => anyhow::bail!("unknown argument '{other}' (use --out DIR)"),
        }
    }
    std::fs::create_dir_all(&out)?;
    let truth_model = GeometryModel::ExactReflection;
    let scene = stud_scene(truth_model);
    let checkpoints: Vec<f64> = (1..=100).map(|k| k as f64 * 0.01).collect();
    let trajectories: [(&str, imaging_support::Angles); 2] =
        [("lissajous", lissajous), ("raster", raster)];
    let mut timing = serde_json::Map::new();
    let mut samples = Vec::new();
    for (name, angles) in trajectories {
        let start = Instant::now();
        let s = simulate_samples(angles, &scene, SAMPLE_RATE_HZ, 1.0);
        timing.insert(
            format!("simulate_{name}_s"),
            start.elapsed().as_secs_f64().into(),
        );
        let file = std::fs::File::create(out.join(format!("{name}_samples.csv")))?;
        write_recording_csv(std::io::BufWriter::new(file), &s)?;
        samples.push((name, s));
    }
    let mut comparisons = Vec::new();
    for model in [GeometryModel::SmallAngle, GeometryModel::ExactReflection] {
        let scanner = Scanner::paper(model);
        let clouds: Vec<_> = samples
            .iter()
            .map(|(name, s)| (*name, s.len(), reconstruct(s, &scanner)))
            .collect();
        let spec = GridSpec::covering(
            clouds[0].2.cloud.points.iter().map(|p| (p.x_mm, p.y_mm)),
            PITCH_MM,
        )?;
        let mut comparison = ProgressiveComparison::new(
            model,
            Some(truth_model),
            spec,
            GridMethod::default(),
            FillMethod::Nearest,
        );
        for (name, n, r) in &clouds {
            let start = Instant::now();
            let points = progressive_errors(
                &r.cloud.points,
                spec,
                comparison.grid_method,
                comparison.fill,
                &checkpoints,
                |x, y| scene.true_z_mm(x, y),
            );
            timing.insert(
                format!("progressive_errors_{name}_{}_s", model.name()),
                start.elapsed().as_secs_f64().into(),
            );
            comparison.runs.push(ProgressiveRun {
                name: (*name).to_string(),
                samples: *n,
                missing_samples: r.missing_samples,
                points,
            });
            if model == GeometryModel::SmallAngle {
                for (t, map) in
                    progressive_maps(&r.cloud.points, spec, comparison.grid_method, &SNAPSHOTS_S)
                {
                    map.draw_png(
                        &out.join(format!("{name}_{t}s.png")),
                        &format!("{name} after {t} s"),
                        "z_s (mm)",
                    )?;
                }
            }
        }
        if model == GeometryModel::SmallAngle {
            comparison.draw(&out.join("progressive.svg"))?;
            comparison.draw(&out.join("progressive.png"))?;
        }
        comparisons.push(comparison);
    }
    std::fs::write(
        out.join("progressive.json"),
        serde_json::to_string_pretty(&comparisons)? + "\n",
    )?;
    std::fs::write(
        out.join("timing.json"),
        serde_json::to_string_pretty(&timing)? + "\n",
    )?;
    for c in &comparisons {
        println!(
            "reconstruction {} (truth {}), grid {}x{} of {} mm:",
            c.reconstruction_model,
            c.simulation_model.as_deref().unwrap_or("-"),
            c.grid.nx,
            c.grid.ny,
            c.grid.pitch_mm
        );
        println!(
            "  t_s   trajectory  coverage  covered_rms_mm  covered_median_mm  image_rms_mm  image_max_mm"
        );
        for &t in &SNAPSHOTS_S {
            for run in &c.runs {
                if let Some(p) = run.points.iter().find(|p| (p.t_s - t).abs() < 1e-9) {
                    println!(
                        "  {:<5} {:<11} {:>8.3}  {:>14.4}  {:>17.5}  {:>12.4}  {:>12.3}",
                        t,
                        run.name,
                        p.coverage_fraction,
                        p.covered_rms_mm.unwrap_or(f64::NAN),
                        p.covered_median_abs_mm.unwrap_or(f64::NAN),
                        p.image_rms_mm.unwrap_or(f64::NAN),
                        p.image_max_mm.unwrap_or(f64::NAN)
                    );
                }
            }
        }
    }
    duplo_feature_heights(&out)?;
    println!("wrote {}", out.display());
    Ok(())
}

/// The paper's validation: the Duplo stud's height through the emulator's optics (exact
/// reflection, shading, 130 um spot) and ILD 2300 (1.5 um noise, 18-bit values), one 1 s
/// frame per trajectory, reconstructed with each model.
fn duplo_feature_heights(out: &Path) -> anyhow::Result<()> {
    let scene =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes/duplo-2x4-130mm.json");
    let mut rows = Vec::new();
    println!("Duplo stud (fixtures/scenes/duplo-2x4-130mm.json, truth 4.663 mm), 1 s at 20 kHz:");
    println!("  trajectory  model             height_mm  std_mm  points  missing  plane_tilt_deg");
    for (name, angles) in [
        ("lissajous", lissajous as imaging_support::Angles),
        ("raster", raster),
    ] {
        let mut scanner = EmulatedScanner::from_scene_file(&scene)?;
        let samples = scanner.simulate_samples(angles, 1.0);
        let file = std::fs::File::create(out.join(format!("duplo_{name}_samples.csv")))?;
        write_recording_csv(std::io::BufWriter::new(file), &samples)?;
        for model in GeometryModel::ALL {
            let options = ImagingOptions {
                model,
                subtract_plane: true,
                feature: Some(FeatureParams::default()),
                ..ImagingOptions::default()
            };
            let imaging = image_samples(&samples, &options)?;
            let f = imaging
                .feature
                .as_ref()
                .expect("asked for a feature")
                .as_ref()
                .map_err(|error| anyhow::anyhow!("{error}"))?;
            let tilt_deg = f.plane.plane.tilt_rad().to_degrees();
            println!(
                "  {name:<11} {:<16} {:>10.4} {:>7.4} {:>7} {:>8} {:>15.4}",
                model.name(),
                f.height_mm,
                f.std_mm,
                f.points,
                imaging.reconstruction.missing_samples,
                tilt_deg
            );
            if model == GeometryModel::SmallAngle {
                imaging.map.draw_png(
                    &out.join(format!("duplo_{name}.png")),
                    &format!("Duplo stud, {name}"),
                    "height above the base plane (mm)",
                )?;
            }
            rows.push(serde_json::json!({
                "trajectory": name,
                "model": model.name(),
                "samples": samples.len(),
                "missing_samples": imaging.reconstruction.missing_samples,
                "feature": f,
            }));
        }
    }
    std::fs::write(
        out.join("duplo.json"),
        serde_json::to_string_pretty(&rows)? + "\n",
    )?;
    Ok(())
}
