//! Speed of the imaging chain on one 20 kHz frame (20 000 samples of the simulated stud):
//! reconstruction (both models), gridding (both methods), fills, RANSAC and feature height
//! (on `[f64; 3]` and on the reconstructed points in place) and the binary PLY writer.
//!
//! `cargo bench -p scanhil-controller --bench imaging`

#[path = "../tests/imaging_support/mod.rs"]
mod imaging_support;

use criterion::{Criterion, criterion_group, criterion_main};
use imaging_support::{lissajous, stud_scene};
use scanhil_controller::imaging::feature::{FeatureParams, feature_height};
use scanhil_controller::imaging::fill::{FillMethod, fill_missing};
use scanhil_controller::imaging::grid::{GridMethod, GridSpec, grid_points};
use scanhil_controller::imaging::ply::{PlyEncoding, write_ply};
use scanhil_controller::imaging::progressive::simulate_samples;
use scanhil_controller::imaging::ransac::{RansacParams, fit_plane};
use scanhil_controller::imaging::reconstruct::reconstruct;
use scanhil_geometry::{GeometryModel, Scanner};

fn imaging(c: &mut Criterion) {
    let samples = simulate_samples(
        lissajous,
        &stud_scene(GeometryModel::ExactReflection),
        20_000.0,
        1.0,
    );
    for model in GeometryModel::ALL {
        let scanner = Scanner::paper(model);
        c.bench_function(&format!("reconstruct_20k_{}", model.name()), |b| {
            b.iter(|| reconstruct(&samples, &scanner))
        });
    }
    let cloud = reconstruct(&samples, &Scanner::paper(GeometryModel::SmallAngle)).cloud;
    let xyz: Vec<[f64; 3]> = cloud
        .points
        .iter()
        .map(|p| [p.x_mm, p.y_mm, p.z_mm])
        .collect();
    let spec = GridSpec::covering(xyz.iter().map(|p| (p[0], p[1])), 0.1).unwrap();
    for (name, method) in [
        ("cell_mean", GridMethod::CellMean),
        ("inverse_distance", GridMethod::default()),
    ] {
        c.bench_function(&format!("grid_20k_{name}_0.1mm"), |b| {
            b.iter(|| grid_points(xyz.iter().map(|p| (p[0], p[1], p[2])), spec, method))
        });
    }
    let map = grid_points(
        xyz.iter().map(|p| (p[0], p[1], p[2])),
        spec,
        GridMethod::default(),
    );
    for fill in [FillMethod::Nearest, FillMethod::Diffusion] {
        c.bench_function(&format!("fill_{fill:?}_{}x{}", spec.nx, spec.ny), |b| {
            b.iter(|| {
                let mut m = map.clone();
                fill_missing(&mut m, fill)
            })
        });
    }
    // On coordinates, and on the reconstructed points in place (as the pipeline measures).
    c.bench_function("ransac_plane_20k", |b| {
        b.iter(|| fit_plane(&xyz, &RansacParams::default()).unwrap())
    });
    c.bench_function("ransac_plane_20k_scan_points", |b| {
        b.iter(|| fit_plane(&cloud.points, &RansacParams::default()).unwrap())
    });
    c.bench_function("feature_height_20k", |b| {
        b.iter(|| feature_height(&xyz, &FeatureParams::default()).unwrap())
    });
    c.bench_function("feature_height_20k_scan_points", |b| {
        b.iter(|| feature_height(&cloud.points, &FeatureParams::default()).unwrap())
    });
    c.bench_function("ply_binary_write_20k", |b| {
        b.iter(|| {
            let mut out = Vec::with_capacity(1 << 21);
            write_ply(&mut out, &cloud, PlyEncoding::BinaryLittleEndian).unwrap();
            out
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = imaging
}
criterion_main!(benches);
