//! Stability on load and the stiff dual-tone controller at 20 kHz: which discretisations are
//! accepted, which refused (with their poles), and where the tone poles land.

use std::path::{Path, PathBuf};

use scanhil_controller::accuracy::tone_placements;
use scanhil_controller::discretise::Method;
use scanhil_controller::settings::{ControllerSettings, SettingsError};
use scanhil_scene::json_file::JsonFileError;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/controllers")
        .join(name)
}

fn with_method(name: &str, method: Method) -> ControllerSettings {
    ControllerSettings {
        discretisation: method,
        ..ControllerSettings::load(&fixture(name)).unwrap()
    }
}

#[test]
fn forward_euler_dual_tone_is_refused_with_its_poles() {
    let settings = ControllerSettings::load(&fixture("dual-tone-forward-euler.json")).unwrap();
    let err = settings.build().unwrap_err();
    let SettingsError::Unstable { poles, what, .. } = &err else {
        panic!("expected Unstable, got {err}");
    };
    assert_eq!(what, "the discrete controller");
    // The 4.07e4 rad/s pole lands at 1 - 4.07e4 * 50 us = -1.035.
    assert!(poles.iter().any(|p| (p.re + 1.035).abs() < 1e-9), "{err}");
    // The tone poles leave the unit circle too (|1 + s T| > 1 for lightly damped poles).
    assert!(
        poles
            .iter()
            .filter(|p| p.abs > 1.0 && p.f_hz > 20.0 && p.f_hz < 60.0)
            .count()
            == 4
    );
    let message = err.to_string();
    assert!(
        message.contains("dual-tone-forward-euler.json") && message.contains("-1.035"),
        "{message}"
    );
}

#[test]
fn every_other_shipped_controller_is_accepted() {
    for entry in std::fs::read_dir(fixture("")).unwrap() {
        let path = entry.unwrap().path();
        let settings = ControllerSettings::load(&path).unwrap();
        let refused = path.to_string_lossy().contains("forward-euler");
        assert_eq!(settings.build().is_err(), refused, "{}", path.display());
    }
}

#[test]
fn dual_tone_at_20_khz_accepts_all_methods_but_forward_euler() {
    for method in Method::all(&[27.0, 52.0]) {
        let name = method.name();
        let result = with_method("dual-tone.json", method.clone()).build();
        assert_eq!(
            result.is_err(),
            method == Method::ForwardEuler,
            "{name}: {:?}",
            result.err()
        );
    }
}

#[test]
fn forward_euler_pid_at_20_khz_is_accepted_but_not_at_1_khz() {
    // The PID's fastest pole (wt = 4375 rad/s) maps to 1 - wt T: fine at 20 kHz, not at 1 kHz.
    let settings = with_method("pid-series.json", Method::ForwardEuler);
    assert!(settings.build().is_ok());
    let slow = ControllerSettings {
        control_rate_hz: 1000.0,
        ..settings
    };
    let err = slow.build().unwrap_err();
    assert!(err.to_string().contains("unstable"), "{err}");
}

fn tones(settings: &ControllerSettings) -> Vec<(f64, f64, f64)> {
    let poles = settings.axis_controller().unwrap().linear().poles();
    tone_placements(settings, &poles)
        .iter()
        .map(|t| (t.continuous_hz, t.error_mhz, t.discrete_damping))
        .collect()
}

#[test]
fn tustin_warps_the_tones_and_prewarping_hits_them() {
    let t = 50e-6;
    let tustin = tones(&with_method("dual-tone.json", Method::Tustin));
    assert_eq!(tustin.len(), 2);
    for &(f, err_mhz, _) in &tustin {
        // Tustin maps an undamped pole at w to (2/T) atan(w T / 2).
        let w = std::f64::consts::TAU * f;
        let expected = ((2.0 / t) * (w * t / 2.0).atan() / std::f64::consts::TAU - f) * 1e3;
        assert!(
            (err_mhz - expected).abs() < 0.01,
            "{f} Hz: {err_mhz} vs {expected} mHz"
        );
        assert!(err_mhz < -0.1, "Tustin warps {f} Hz by only {err_mhz} mHz");
    }
    let prewarped = tones(&with_method(
        "dual-tone.json",
        Method::TustinPrewarped {
            prewarp_hz: vec![27.0, 52.0],
        },
    ));
    for &(f, err_mhz, _) in &prewarped {
        assert!(
            err_mhz.abs() < 0.01,
            "prewarped: {f} Hz off by {err_mhz} mHz"
        );
    }
    for method in [Method::ZeroOrderHold, Method::MatchedPoleZero] {
        for (f, err_mhz, _) in tones(&with_method("dual-tone.json", method.clone())) {
            assert!(
                err_mhz.abs() < 1e-3,
                "{}: {f} Hz off by {err_mhz} mHz",
                method.name()
            );
        }
    }
    // Backward Euler keeps the tones stable by damping them tens of times more.
    for (f, _, damping) in tones(&with_method("dual-tone.json", Method::BackwardEuler)) {
        assert!(
            damping > 30.0 * 1e-4,
            "backward Euler: {f} Hz damping only {damping}"
        );
    }
}

#[test]
fn exact_tone_option_puts_the_discrete_tones_at_27_and_52_hz() {
    let printed = tones(&ControllerSettings::load(&fixture("dual-tone.json")).unwrap());
    assert!((printed[0].0 - 27.0563).abs() < 1e-3 && (printed[1].0 - 52.0437).abs() < 1e-3);
    let exact = ControllerSettings::load(&fixture("dual-tone-exact-tones.json")).unwrap();
    let placed = tones(&exact);
    for (&(f, err_mhz, _), target) in placed.iter().zip([27.0, 52.0]) {
        assert!(
            (f - target).abs() < 1e-6 && err_mhz.abs() < 0.01,
            "{f} Hz, {err_mhz} mHz"
        );
    }
    // With the tones exactly on the drive frequencies, T is closer to 1 there.
    let at = |s: &ControllerSettings| {
        let axis = s.axis_controller().unwrap();
        s.nominal_loop(&axis).report(&[27.0, 52.0]).at
    };
    let (a, b) = (
        at(&ControllerSettings::load(&fixture("dual-tone.json")).unwrap()),
        at(&exact),
    );
    for (p, e) in a.iter().zip(&b) {
        assert!(
            e.magnitude_db.abs() < p.magnitude_db.abs() && e.phase_deg.abs() < p.phase_deg.abs()
        );
        assert!(e.phase_deg.abs() < 1.0, "{e:?}");
    }
}

#[test]
fn bad_settings_name_the_field_and_the_file() {
    let text = std::fs::read_to_string(fixture("pid-series.json")).unwrap();
    let bad = text.replace("\"kp\": 2.567", "\"kp\": -2.567");
    let err = ControllerSettings::from_json_str(&bad, Path::new("bad.json")).unwrap_err();
    assert!(
        err.to_string().contains("bad.json") && err.to_string().contains("law.kp"),
        "{err}"
    );
    let bad = text.replace("\"tustin\"", "\"bilinear\"");
    let err = ControllerSettings::from_json_str(&bad, Path::new("bad.json")).unwrap_err();
    assert!(
        matches!(err, SettingsError::File(JsonFileError::Parse { line, .. }) if line > 1),
        "{err}"
    );
}
