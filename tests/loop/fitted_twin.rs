//! `scanhil identify --fit` against a mirror that is not the paper's (each axis its own gain,
//! frequency and damping, unequal cross-talk), measured over a pty in lockstep: the fit recovers
//! the scene's parameters, refits the kept recording without the device, and writes a scene
//! the emulator serves as the twin of the mirror it measured. And the bench twin's chain at the
//! rate a 1 Mbit/s bus carries: measure, fit, design for the fit, scan the Duplo stud.

use std::path::Path;

use scanhil_controller::fit::models::ModelParams;
use scanhil_emulator::scene::Scene;
use scanhil_protocol::plant_units::SensingAxis;
use serde_json::Value;

use crate::util::{
    assert_success, assert_tracks_as_predicted, fixture, number, report, run_scanhil,
};

const SCENE: &str = "scenes/mirror-differing-10khz.json";
/// The scene's control period, s.
const PERIOD_S: f64 = 1e-4;
/// The tolerances: gain and natural frequency within 1 %, damping within 5 % (measured
/// at 8 points: K 0.003 %, ws 0.1 %, zeta 1 %).
const GAIN_AND_FREQUENCY: f64 = 0.01;
const DAMPING: f64 = 0.05;
/// The twin against the original over 2-2000 Hz (the figures; the fit's own 1 %
/// would not give them near a resonance of damping 0.04: the phase moves 1 / zeta rad per
/// relative frequency error there).
const TWIN_DB: f64 = 0.5;
const TWIN_DEG: f64 = 3.0;

fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Each axis' eq. 4 as the emulator serves it from `scene` (its delay: one period unless set).
fn served_models(scene: &Path) -> Vec<(SensingAxis, ModelParams)> {
    let scene = Scene::load(scene).unwrap_or_else(|e| panic!("the emulator reads it: {e}"));
    SensingAxis::BOTH
        .iter()
        .map(|&axis| {
            let d = scene.mirror.axis(axis);
            let params = ModelParams {
                dc_gain: d.dc_gain,
                natural_freq_rad_s: d.natural_freq_rad_s,
                damping_ratio: d.damping_ratio,
                delay_s: d.delay_s.unwrap_or(PERIOD_S),
                lag_rad_s: None,
                mode: None,
            };
            (axis, params)
        })
        .collect()
}

/// The estimate `name` of `axis` in an identify result.
fn estimate(result: &Value, axis: SensingAxis, name: &str) -> f64 {
    let fit = result["fit"]["axes"]
        .as_array()
        .and_then(|axes| axes.iter().find(|a| a["axis"] == axis.name()))
        .unwrap_or_else(|| panic!("no fit of {axis:?}"));
    assert_eq!(fit["chosen"], "eq4", "{axis:?}: {}", fit["selection"]);
    let entry = fit["estimates"]
        .as_array()
        .and_then(|e| e.iter().find(|e| e["name"] == name))
        .unwrap_or_else(|| panic!("{axis:?}: no estimate {name}"));
    number(entry, "/value")
}

/// `scanhil identify --fsm pty --scene SCENE` with a short plan (0.8 s settling, two blocks of
/// one cycle, 0.05 A) and `args`.
fn identify_over_a_pty(scene: &str, args: &[&str]) -> std::process::Output {
    let mut all = vec![
        "identify",
        "--fsm",
        "pty",
        "--scene",
        scene,
        "--settle-s",
        "0.8",
        "--cycles",
        "1",
        "--blocks",
        "2",
        "--amplitude",
        "0.05",
    ];
    all.extend(args);
    run_scanhil(&all)
}

fn wrap_deg(d: f64) -> f64 {
    (d + 180.0).rem_euclid(360.0) - 180.0
}

#[test]
fn identify_fit_recovers_a_differing_mirror_refits_its_recording_and_writes_its_twin() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let path = |name: &str| dir.path().join(name).display().to_string();
    let scene = fixture(SCENE);
    let (fit_json, record, twin, plot) = (
        path("fit.json"),
        path("recording"),
        path("twin.json"),
        path("fit.svg"),
    );
    let output = identify_over_a_pty(
        &scene,
        &[
            "--fit",
            "--points",
            "8",
            "--out",
            &fit_json,
            "--record",
            &record,
            "--write-scene",
            &twin,
            "--plot",
            &plot,
        ],
    );
    assert_success(&output, "scanhil identify --fit");
    let live = read_json(Path::new(&fit_json));
    assert_eq!(
        live["coils_at_end"],
        serde_json::json!({"zero_commanded": true, "acknowledged": true})
    );

    let truth = served_models(Path::new(&scene));
    for (axis, want) in &truth {
        for (name, want, tolerance) in [
            ("dc_gain", want.dc_gain, GAIN_AND_FREQUENCY),
            (
                "natural_freq_rad_s",
                want.natural_freq_rad_s,
                GAIN_AND_FREQUENCY,
            ),
            ("damping_ratio", want.damping_ratio, DAMPING),
        ] {
            let got = estimate(&live, *axis, name);
            assert!(
                (got / want - 1.0).abs() < tolerance,
                "{axis:?} {name}: fitted {got}, the scene's {want}"
            );
        }
    }
    // The scene's couplings (0.12 onto beta, 0.08 onto alpha), to 1 %.
    for (to, want) in [("beta", 0.12), ("alpha", 0.08)] {
        let c = live["fit"]["cross_talk"]
            .as_array()
            .and_then(|c| c.iter().find(|c| c["to"] == to))
            .unwrap_or_else(|| panic!("no cross-talk onto {to}"));
        let got = number(c, "/coefficient");
        assert!(
            (got / want - 1.0).abs() < 0.01,
            "onto {to}: {got}, want {want}"
        );
    }
    assert!(
        std::fs::metadata(&plot).is_ok_and(|m| m.len() > 1000),
        "the Bode plot is written"
    );

    // The kept run, analysed again without the device: the same fit (the recording holds
    // the commands as sent, in 1 uA steps, where the live analysis used the exact sine).
    let refit_json = path("refit.json");
    let output = run_scanhil(&["identify", "--from", &record, "--fit", "--out", &refit_json]);
    assert_success(&output, "scanhil identify --from --fit");
    let refit = read_json(Path::new(&refit_json));
    for axis in SensingAxis::BOTH {
        for name in ["dc_gain", "natural_freq_rad_s", "damping_ratio", "delay_s"] {
            let (a, b) = (estimate(&live, axis, name), estimate(&refit, axis, name));
            assert!(
                (a / b - 1.0).abs() < 1e-4,
                "{axis:?} {name}: live {a}, refit {b}"
            );
        }
    }

    // The written scene is one the emulator loads, and its mirror answers as the original
    // over 2-2000 Hz.
    let twin_models = served_models(Path::new(&twin));
    for ((axis, original), (_, fitted)) in truth.iter().zip(&twin_models) {
        let (original, fitted) = (original.sampled(PERIOD_S), fitted.sampled(PERIOD_S));
        for i in 0..=200 {
            let f_hz = 2.0 * 1000f64.powf(f64::from(i) / 200.0);
            let ratio = fitted.response(f_hz) / original.response(f_hz);
            let (db, deg) = (20.0 * ratio.norm().log10(), ratio.arg().to_degrees());
            assert!(
                db.abs() < TWIN_DB && deg.abs() < TWIN_DEG,
                "{axis:?} at {f_hz:.1} Hz: the twin is {db:+.3} dB, {deg:+.2} deg off"
            );
        }
    }
    let twin_scene = read_json(Path::new(&twin));
    assert_eq!(
        twin_scene["parts"],
        serde_json::json!(["axes", "cross_talk"])
    );

    // Served: the twin and the original measured alike over the pty answer alike (the same
    // plan, so its settling residue is common to both).
    let served = |scene: &str, name: &str| {
        let out = path(name);
        let output = identify_over_a_pty(
            scene,
            &[
                "--axis",
                "both",
                "--from-hz",
                "5",
                "--to-hz",
                "200",
                "--points",
                "3",
                "--out",
                &out,
            ],
        );
        assert_success(&output, &format!("scanhil identify --scene {scene}"));
        read_json(Path::new(&out))
    };
    let (original, twin) = (
        served(&scene, "original.json"),
        served(&twin, "served.json"),
    );
    for (original, twin) in original["axes"]
        .as_array()
        .unwrap()
        .iter()
        .zip(twin["axes"].as_array().unwrap())
    {
        let axis = &twin["axis"];
        for (a, b) in original["points"]
            .as_array()
            .unwrap()
            .iter()
            .zip(twin["points"].as_array().unwrap())
        {
            let f_hz = number(b, "/measured/f_hz");
            let db = number(b, "/measured/magnitude_db") - number(a, "/measured/magnitude_db");
            let deg = wrap_deg(number(b, "/measured/phase_deg") - number(a, "/measured/phase_deg"));
            assert!(
                db.abs() < TWIN_DB && deg.abs() < TWIN_DEG,
                "{axis} served at {f_hz:.1} Hz: {db:+.3} dB, {deg:+.2} deg from the original"
            );
        }
    }
}

/// The bench of the chain: the Duplo brick at 2736 Hz (the rate a 1 Mbit/s bus carries) with
/// a mirror that is not the paper's (K 9.8, ws 160 rad/s, zeta 0.045 on both axes).
const BENCH: &str = "scenes/duplo-2x4-130mm-2736hz-other-mirror.json";
/// The stud's height, mm (the paper's mechanical reference), and what the loop designed for
/// the fitted mirror must measure it to (measured: 4.6 um low).
const STUD_HEIGHT_MM: f64 = 4.663;
const HEIGHT_TOLERANCE_MM: f64 = 0.05;

/// Scans the bench with `controller` (the 1 Mbit/s Duplo scenario's, with the bench's scene)
/// into `dir/name`, expecting the exit status `exit` (0: complete, 4: the verdict failed); its
/// report.
fn scan_bench(dir: &Path, name: &str, controller: &str, exit: i32) -> Value {
    let mut scenario = read_json(Path::new(&fixture(
        "scenarios/duplo-lissajous-dual-tone-1mbit.json",
    )));
    scenario["name"] = format!("the bench with {name}").into();
    scenario["rig"] = fixture("rigs/paper-bench-1mbit.json").into();
    scenario["scene"] = fixture(BENCH).into();
    scenario["controller"] = controller.into();
    let scenario_path = dir.join(format!("scenario-{name}.json"));
    std::fs::write(&scenario_path, scenario.to_string()).expect("writing the scenario");
    let out = dir.join(name);
    let output = run_scanhil(&[
        "scan",
        scenario_path.to_str().expect("UTF-8 path"),
        "--out",
        out.to_str().expect("UTF-8 path"),
    ]);
    if exit == 0 {
        assert_success(&output, &format!("scanhil scan of the bench with {name}"));
    } else {
        assert_eq!(
            output.status.code(),
            Some(exit),
            "scanhil scan of the bench with {name}: {}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    report(&out)
}

#[test]
fn measured_fitted_and_designed_for_at_the_bus_rate_the_loop_scans_the_duplo_stud() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let path = |name: &str| dir.path().join(name).display().to_string();
    // 1. Measure the bench's mirror over SLCAN on a pty at its rate and fit it (a design is
    //    for one axis' plant and the bench's axes are alike; the twin keeps the bench's
    //    scene, the other axis as the bench states it).
    let (twin, fit_json) = (path("twin.json"), path("fit.json"));
    let output = identify_over_a_pty(
        &fixture(BENCH),
        &[
            "--axis",
            "alpha",
            "--fit",
            "--from-hz",
            "2",
            "--to-hz",
            "1000",
            "--points",
            "10",
            "--write-scene",
            &twin,
            "--out",
            &fit_json,
        ],
    );
    assert_success(&output, "scanhil identify --fit of the bench");
    let fit = read_json(Path::new(&fit_json));
    let ws = estimate(&fit, SensingAxis::Alpha, "natural_freq_rad_s");
    assert!((ws / 160.0 - 1.0).abs() < GAIN_AND_FREQUENCY, "ws {ws}");
    // 2. Design a dual-tone for the fitted mirror at the rate the rig's bus carries.
    let controller = path("designed.json");
    let output = run_scanhil(&[
        "design",
        "--rig",
        &fixture("rigs/paper-bench-1mbit.json"),
        "--plant",
        &twin,
        "--rate-hz",
        "bus",
        "--kind",
        "dual-tone",
        "--out",
        &controller,
    ]);
    assert_success(&output, "scanhil design for the twin");
    // 3. It scans the bench as predicted (measured / predicted: alpha 1.01, beta 1.03) and
    //    measures the stud.
    let report = scan_bench(dir.path(), "designed", &controller, 0);
    assert_eq!(number(&report, "/rig/control_rate_hz"), 2736.0);
    assert_tracks_as_predicted(&report, &[("alpha", (0.97, 1.1)), ("beta", (0.97, 1.2))]);
    let height = number(&report, "/imaging/feature/height_mm");
    assert!(
        (height - STUD_HEIGHT_MM).abs() < HEIGHT_TOLERANCE_MM,
        "stud height {height} mm, truth {STUD_HEIGHT_MM} mm"
    );
    // The design for eq. 4 as printed does not track this mirror (measured: 700 times its
    // prediction, the stud at 19.8 mm): the fit is what made the loop. Its run's verdict is
    // failed (exit 4: tracking beyond its limit).
    let paper = scan_bench(
        dir.path(),
        "paper-design",
        &fixture("controllers/dual-tone-2736hz-designed.json"),
        4,
    );
    let alpha = number(&paper, "/tracking_error/frame/alpha/rms_relative")
        / number(&paper, "/predicted_tracking_error/alpha_rms_relative");
    assert!(alpha > 10.0, "the paper's design tracks the bench: {alpha}");
}
