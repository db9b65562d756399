//! Accuracy against cost of the discretisation methods for the dual-tone controller (and the
//! two PID readings): tone placement error, tracking error of a simulated Lissajous 52/27 Hz
//! half-range scan with the nominal plant, and the run time of one control period
//! (`ScanController::step`, both axes). Writes JSON to stdout and to
//! `target/control_discretisation.json`.
//!
//! Run: `cargo bench -p scanhil-controller --bench control_discretisation`.

use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use scanhil_controller::accuracy::compare_methods;
use scanhil_controller::settings::ControllerSettings;
use scanhil_controller::trajectory::Trajectory;
use scanhil_protocol::plant_units::{FULL_RANGE_DEG, SensingPair};

/// Periods timed per controller.
const TIMED_PERIODS: u32 = 2_000_000;
/// Simulated scan time, s (the error is taken over the last second).
const SIMULATED_S: f64 = 6.0;

fn ns_per_period(settings: &ControllerSettings) -> Option<f64> {
    let mut controller = settings.build().ok()?;
    let reference = SensingPair {
        alpha: 1e-3,
        beta: -1e-3,
    };
    let start = Instant::now();
    let mut measured = SensingPair::default();
    for k in 0..TIMED_PERIODS {
        let u = controller.step(black_box(reference), black_box(measured));
        measured.alpha = 1e-9 * f64::from(k % 7) + u.a * 1e-12;
        measured.beta = u.b * 1e-12;
    }
    Some(start.elapsed().as_secs_f64() * 1e9 / f64::from(TIMED_PERIODS))
}

fn main() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/controllers");
    let half = 0.5 * FULL_RANGE_DEG.to_radians();
    let lissajous = Trajectory::Lissajous {
        alpha_hz: 52.0,
        beta_hz: 27.0,
        alpha_amplitude_rad: half,
        beta_amplitude_rad: half,
        relative_phase_rad: 0.0,
    };
    let mut rows = Vec::new();
    for file in [
        "dual-tone.json",
        "dual-tone-exact-tones.json",
        "pid-series.json",
        "pid-parallel.json",
    ] {
        let settings =
            ControllerSettings::load(&fixtures.join(file)).expect("shipped fixture loads");
        for comparison in compare_methods(&settings, &[27.0, 52.0], &lissajous, SIMULATED_S, 1.0) {
            let method = settings_with(&settings, &comparison.method);
            rows.push(serde_json::json!({
                "controller": file,
                "comparison": comparison,
                "ns_per_period": method.as_ref().and_then(ns_per_period),
            }));
        }
    }
    let json = serde_json::json!({
        "simulated_s": SIMULATED_S,
        "timed_periods": TIMED_PERIODS,
        "trajectory": lissajous,
        "rows": rows,
    });
    let text = serde_json::to_string_pretty(&json).expect("JSON of plain values");
    println!("{text}");
    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/control_discretisation.json");
    if let Err(e) = std::fs::write(&out, &text) {
        eprintln!("could not write {}: {e}", out.display());
    }
}

/// `settings` with the method named `name` (as `Method::name` prints it).
fn settings_with(settings: &ControllerSettings, name: &str) -> Option<ControllerSettings> {
    scanhil_controller::discretise::Method::all(&[27.0, 52.0])
        .into_iter()
        .find(|m| m.name() == name)
        .map(|m| ControllerSettings {
            discretisation: m,
            ..settings.clone()
        })
}
