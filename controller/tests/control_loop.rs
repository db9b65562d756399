//! The nominal closed loop: the analyze figures for the shipped controllers, and tracking a
//! simulated Lissajous with the nominal plant, PID against dual-tone.

use std::path::{Path, PathBuf};

use scanhil_controller::accuracy::simulate_tracking;
use scanhil_controller::settings::ControllerSettings;
use scanhil_controller::trajectory::Trajectory;
use scanhil_protocol::plant_units::{RAD_PER_OUTPUT_UNIT, SensingPair};

fn load(name: &str) -> ControllerSettings {
    let path: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/controllers")
        .join(name);
    ControllerSettings::load(&path).unwrap()
}

#[test]
fn pid_loop_figures_are_near_but_not_at_the_papers_claims() {
    // The paper: 240 Hz crossover, 45 deg margin, 422 Hz bandwidth, 2.8 dB peak at 155 Hz.
    for (name, crossover, margin, bandwidth) in [
        ("pid-series.json", 213.1, 43.7, 385.9),
        ("pid-parallel.json", 224.2, 49.7, 405.9),
    ] {
        let s = load(name);
        let axis = s.axis_controller().unwrap();
        let r = s.nominal_loop(&axis).report(&[]);
        assert!(r.stable, "{name}");
        assert!(
            (r.crossover_hz.unwrap() - crossover).abs() < 0.5,
            "{name}: {r:?}"
        );
        assert!(
            (r.phase_margin_deg.unwrap() - margin).abs() < 0.5,
            "{name}: {r:?}"
        );
        assert!(
            (r.bandwidth_3db_hz.unwrap() - bandwidth).abs() < 0.5,
            "{name}: {r:?}"
        );
        assert!(r.peak_db > 2.0 && r.peak_db < 4.0, "{name}: {}", r.peak_db);
    }
}

#[test]
fn closed_loop_poles_agree_with_a_simulated_step() {
    // The spectral radius from the eigenvalues bounds the decay of a simulated error.
    let s = load("pid-series.json");
    let mut controller = s.build().unwrap();
    let axis = controller.axis().clone();
    let radius = s.nominal_loop(&axis).report(&[]).spectral_radius;
    let step = Trajectory::Step {
        axis: scanhil_controller::trajectory::SensingAxis::Alpha,
        amplitude_rad: 1e-3,
        at_s: 0.0,
    };
    let mut plant = scanhil_controller::link::NominalPlantLink::new(&s.plant, s.period_s(), 0.0, 0);
    let mut y = SensingPair::default();
    let mut errors = Vec::new();
    for k in 0..4000 {
        let r = step.reference_rad(k as f64 * s.period_s());
        errors.push((r.alpha - y.alpha).abs());
        let u = controller.step(r, y);
        y = scanhil_controller::link::PlantLink::exchange(&mut plant, u).unwrap();
    }
    let bound = 1e-3 * 50.0 * radius.powi(4000);
    assert!(errors[3999] < bound, "error {} above {bound}", errors[3999]);
    assert!(
        errors[3999] < 1e-3 * 0.01,
        "step not tracked: {}",
        errors[3999]
    );
}

#[test]
fn dual_tone_tracks_the_lissajous_better_than_the_pid() {
    let amplitude = 0.2 * 10.0 * RAD_PER_OUTPUT_UNIT; // 20 % of full range
    let lissajous = Trajectory::Lissajous {
        alpha_hz: 52.0,
        beta_hz: 27.0,
        alpha_amplitude_rad: amplitude,
        beta_amplitude_rad: amplitude,
        relative_phase_rad: 0.0,
    };
    let run = |name: &str| {
        let s = load(name);
        let mut c = s.build().unwrap();
        simulate_tracking(&s, &mut c, &lissajous, 6.0, 1.0)
    };
    let pid = run("pid-series.json");
    let dual = run("dual-tone-exact-tones.json");
    let printed = run("dual-tone.json");
    // The PID leaves a few percent of the amplitude (|1 - T| at 52 Hz).
    assert!(
        pid.rms_alpha_urad > 0.02 * amplitude * 1e6 / 2f64.sqrt(),
        "{pid:?}"
    );
    assert!(
        dual.rms_alpha_urad < 0.2 * pid.rms_alpha_urad,
        "dual {dual:?} vs pid {pid:?}"
    );
    // At 27 Hz the PID is already good (|1 - T| = 1.2 %); the dual-tone's finite tone gain
    // leaves about 1 %.
    assert!(
        dual.rms_beta_urad < pid.rms_beta_urad,
        "dual {dual:?} vs pid {pid:?}"
    );
    // Table I's tones sit 56 mHz and 44 mHz off the drive frequencies: visibly worse.
    assert!(
        printed.rms_alpha_urad > dual.rms_alpha_urad,
        "{printed:?} vs {dual:?}"
    );
    assert_eq!(dual.saturated_periods, 0);
}

#[test]
fn scan_controller_scales_rotates_and_clips() {
    let s = load("pid-series.json");
    let mut c = s.build().unwrap();
    // A small alpha error: both coils carry u / sqrt 2 with the same sign; beta-only: opposite.
    let tiny = 1e-7;
    let u = c.step(
        SensingPair {
            alpha: tiny,
            beta: 0.0,
        },
        SensingPair::default(),
    );
    assert!(u.a > 0.0 && (u.a - u.b).abs() < 1e-15, "{u:?}");
    // The first-period command is the proportional path at high frequency: kp (wt / wd)
    // times the error in output units (Tustin: b0 of the discrete paths).
    let axis_a = u.a * std::f64::consts::SQRT_2;
    let expected = s.axis_controller().unwrap().linear().sections()[0].b[0]
        * s.axis_controller().unwrap().linear().sections()[1].b[0]
        * tiny
        / RAD_PER_OUTPUT_UNIT;
    assert!(
        (axis_a - expected).abs() < 1e-12 * expected.abs().max(1.0),
        "{axis_a} vs {expected}"
    );
    c.reset();
    let u = c.step(
        SensingPair {
            alpha: 0.0,
            beta: tiny,
        },
        SensingPair::default(),
    );
    assert!(u.b > 0.0 && (u.a + u.b).abs() < 1e-15, "{u:?}");
    // A huge error on both axes: each coil is clipped to the coil limit and counted.
    c.reset();
    let big = SensingPair {
        alpha: 0.02,
        beta: -0.02,
    };
    let u = c.step(big, SensingPair::default());
    assert!(u.a.abs() <= s.coil_current_limit_a && u.b.abs() <= s.coil_current_limit_a);
    assert!((u.a.abs() - s.coil_current_limit_a).abs() < 1e-12, "{u:?}");
    c.step(big, SensingPair::default());
    assert!(c.saturated_periods() >= 1);
    c.reset();
    assert_eq!(c.saturated_periods(), 0);
}
