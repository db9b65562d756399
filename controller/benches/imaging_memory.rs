//! Peak heap of the imaging once a frame's points exist, per point: a large synthetic frame
//! (the simulated stud, Lissajous at 20 kHz) is reconstructed, then each step after that is
//! measured by a counting allocator as the most bytes it held at once beyond what was live
//! when it began. The floor is the frame's points themselves (56 B each): the ratio says how
//! much of a second frame the step holds (0.0 is none). Prints JSON.
//!
//! `cargo bench -p scanhil-controller --bench imaging_memory [-- SECONDS]` (default 10 s:
//! 200 000 samples)

#[path = "../tests/imaging_support/mod.rs"]
mod imaging_support;

use std::alloc::{GlobalAlloc, Layout, System};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};

use imaging_support::{lissajous, stud_scene};
use scanhil_controller::imaging::feature::FeatureParams;
use scanhil_controller::imaging::pipeline::{ImagingOptions, image_points, write_outputs};
use scanhil_controller::imaging::ply::PlyEncoding;
use scanhil_controller::imaging::progressive::{ScanFrame, simulate_samples};
use scanhil_controller::imaging::reconstruct::{Reconstruction, ScanPoint, reconstruct};
use scanhil_geometry::{GeometryModel, Scanner};

/// The system allocator, counting the bytes live now and the most live since the last
/// [`CountingHeap::measure`] began.
struct CountingHeap {
    live: AtomicUsize,
    peak: AtomicUsize,
}

#[global_allocator]
static HEAP: CountingHeap = CountingHeap {
    live: AtomicUsize::new(0),
    peak: AtomicUsize::new(0),
};

impl CountingHeap {
    fn grew(&self, bytes: usize) {
        let live = self.live.fetch_add(bytes, Ordering::Relaxed) + bytes;
        self.peak.fetch_max(live, Ordering::Relaxed);
    }

    fn shrank(&self, bytes: usize) {
        self.live.fetch_sub(bytes, Ordering::Relaxed);
    }

    /// Runs `step` and returns its value with the most bytes it held at once beyond those
    /// live when it began.
    fn measure<T>(&self, step: impl FnOnce() -> T) -> (T, usize) {
        let before = self.live.load(Ordering::Relaxed);
        self.peak.store(before, Ordering::Relaxed);
        let value = step();
        (value, self.peak.load(Ordering::Relaxed) - before)
    }
}

// SAFETY: every call is passed to `System` unchanged; the counters only observe sizes.
unsafe impl GlobalAlloc for CountingHeap {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            self.grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            self.grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(p, layout) };
        self.shrank(layout.size());
    }

    unsafe fn realloc(&self, p: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let q = unsafe { System.realloc(p, layout, new_size) };
        if !q.is_null() {
            self.grew(new_size);
            self.shrank(layout.size());
        }
        q
    }
}

/// One step's peak, absolute and against the frame's points.
fn figures(peak_bytes: usize, points: usize) -> serde_json::Value {
    let point_bytes = std::mem::size_of::<ScanPoint>();
    serde_json::json!({
        "peak_bytes": peak_bytes,
        "bytes_per_point": peak_bytes as f64 / points as f64,
        "ratio_to_the_points": peak_bytes as f64 / (points * point_bytes) as f64,
    })
}

/// The steps after reconstruction on `reconstruction` with `options`, measured.
fn measure_imaging(
    reconstruction: Reconstruction,
    options: &ImagingOptions,
    length_s: f64,
) -> anyhow::Result<serde_json::Value> {
    let points = reconstruction.cloud.points.len();
    let (imaging, image_peak) = HEAP.measure(|| image_points(reconstruction, options));
    let mut imaging = imaging?;
    let frame = ScanFrame::from_first_sample(
        imaging.reconstruction.cloud.points.iter().map(|p| p.t_s),
        length_s,
    );
    let ((), score_peak) = HEAP.measure(|| imaging.score_progressive(None, frame));
    let dir = tempfile::tempdir()?;
    let (report, write_peak) = HEAP.measure(|| {
        write_outputs(
            &imaging,
            dir.path(),
            PlyEncoding::BinaryLittleEndian,
            &BTreeMap::new(),
        )
    });
    anyhow::ensure!(
        report?.failed_files.is_empty(),
        "an output could not be written"
    );
    Ok(serde_json::json!({
        "image_points": figures(image_peak, points),
        "score_progressive": figures(score_peak, points),
        "write_outputs": figures(write_peak, points),
    }))
}

fn main() -> anyhow::Result<()> {
    // `cargo bench` passes `--bench`; a number is the frame's length.
    let length_s: f64 = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(10.0);
    let samples = simulate_samples(
        lissajous,
        &stud_scene(GeometryModel::ExactReflection),
        20_000.0,
        length_s,
    );
    let scan = ImagingOptions {
        feature: Some(FeatureParams::default()),
        ..ImagingOptions::default()
    };
    let plane = ImagingOptions {
        subtract_plane: true,
        ..ImagingOptions::default()
    };
    let scanner = Scanner::new(scan.setup, scan.model)?;
    let reconstruction = reconstruct(&samples, &scanner);
    drop(samples);
    let points = reconstruction.cloud.points.len();
    let results = serde_json::json!({
        "frame_s": length_s,
        "points": points,
        "point_bytes": std::mem::size_of::<ScanPoint>(),
        "points_bytes": points * std::mem::size_of::<ScanPoint>(),
        "feature_z_map": measure_imaging(reconstruction.clone(), &scan, length_s)?,
        "plane_subtracted_map": measure_imaging(reconstruction, &plane, length_s)?,
    });
    println!("{}", serde_json::to_string_pretty(&results)?);
    Ok(())
}
