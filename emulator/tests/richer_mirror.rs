//! The richer mirror, part by part, against each part's analytic response: the second mode,
//! the cross-talk's pickup path, the current loop (with and without back-EMF, and its voltage
//! limit), the angle sensor's bandwidth and nonlinearity; and the stiffness refusals that
//! cover the new states.

use std::path::Path;

use nalgebra::{Complex, DMatrix, DVector};

use scanhil_emulator::drive_model::{DriveModel, DriveParts};
use scanhil_emulator::drive_stepper::DriveStepper;
use scanhil_emulator::integrator::IntegratorConfig;
use scanhil_emulator::mirror::SensingAxis;
use scanhil_emulator::plant::{Plant, PlantError, PlantEvent};
use scanhil_emulator::scene::Scene;
use scanhil_protocol::plant_units::{
    ActuatorPair, RAD_PER_OUTPUT_UNIT, SensingPair, actuator_from_sensing,
};

type C64 = Complex<f64>;

fn scene(parts: &str, extra: &str) -> Scene {
    let json = format!(r#"{{"name": "rich", "parts": [{parts}] {extra}}}"#);
    Scene::from_json_str(&json, Path::new("rich.json")).expect("test scene is valid")
}

fn model(s: &Scene) -> DriveModel {
    DriveModel::build(&DriveParts::of_scene(s))
}

/// The model's response at `f_hz` from a command of 1 A on sensing axis `from` to the measured
/// angle of `to`, in output units per A: `c (jw - A)^-1 B u + d u`.
fn measured_response(m: &DriveModel, from: SensingAxis, to: SensingAxis, f_hz: f64) -> C64 {
    let coils = actuator_from_sensing(match from {
        SensingAxis::Alpha => SensingPair {
            alpha: 1.0,
            beta: 0.0,
        },
        SensingAxis::Beta => SensingPair {
            alpha: 0.0,
            beta: 1.0,
        },
    });
    let n = m.states();
    let s = C64::new(0.0, std::f64::consts::TAU * f_hz);
    let lhs = DMatrix::<C64>::from_fn(n, n, |i, j| {
        (if i == j { s } else { C64::new(0.0, 0.0) }) - C64::new(m.a[(i, j)], 0.0)
    });
    let rhs = DVector::<C64>::from_fn(n, |i, _| {
        C64::new(m.b[(i, 0)] * coils.a + m.b[(i, 1)] * coils.b, 0.0)
    });
    let x = lhs.lu().solve(&rhs).expect("jw is not an eigenvalue");
    let row = m.measured_rows[match to {
        SensingAxis::Alpha => 0,
        SensingAxis::Beta => 1,
    }]
    .as_ref()
    .expect("the axis moves");
    let states: C64 = row.c.iter().zip(x.iter()).map(|(c, x)| x * *c).sum();
    states + C64::new(row.d[0] * coils.a + row.d[1] * coils.b, 0.0)
}

/// Eq. 4 without its delay at `s`.
fn eq4(s: C64) -> C64 {
    let (k, ws, z) = (11.4, 140.68, 3.21e-2);
    C64::new(k * ws * ws, 0.0) / (s * s + s * (2.0 * z * ws) + ws * ws)
}

fn jw(f_hz: f64) -> C64 {
    C64::new(0.0, std::f64::consts::TAU * f_hz)
}

const FREQUENCIES_HZ: [f64; 7] = [1.0, 22.4, 100.0, 422.0, 1200.0, 3000.0, 9000.0];

fn assert_close(got: C64, want: C64, what: &str, f_hz: f64) {
    assert!(
        (got - want).norm() <= 1e-9 * want.norm(),
        "{what} at {f_hz} Hz: {got} against {want}"
    );
}

#[test]
fn the_second_mode_multiplies_eq_4_by_its_resonance_and_keeps_the_dc_gain() {
    for (extra, zero) in [
        ("", None),
        (
            r#", "mirror": {"second_mode": {"natural_freq_hz": 1500, "damping_ratio": 0.03,
                 "zero_freq_hz": 900, "zero_damping_ratio": 0.01}}"#,
            Some((900.0, 0.01)),
        ),
    ] {
        let s = scene(r#""axes", "second_mode""#, extra);
        let m = model(&s);
        let mode = s.mirror.axis(SensingAxis::Alpha).second_mode;
        for f in FREQUENCIES_HZ {
            let w2 = std::f64::consts::TAU * mode.natural_freq_hz;
            let num = match zero {
                None => C64::new(w2 * w2, 0.0),
                Some((fz, zz)) => {
                    let wz: f64 = std::f64::consts::TAU * fz;
                    (jw(f) * jw(f) + jw(f) * (2.0 * zz * wz) + wz * wz) * (w2 * w2 / (wz * wz))
                }
            };
            let h2 = num / (jw(f) * jw(f) + jw(f) * (2.0 * mode.damping_ratio * w2) + w2 * w2);
            let want = eq4(jw(f)) * h2;
            assert_close(
                measured_response(&m, SensingAxis::Alpha, SensingAxis::Alpha, f),
                want,
                "second mode",
                f,
            );
            let (re, im) = mode.response_at(std::f64::consts::TAU * f);
            assert_close(C64::new(re, im), h2, "response_at", f);
        }
        // Without the part the same scene is eq. 4.
        let plain = model(&scene(r#""axes""#, extra));
        assert_close(
            measured_response(&plain, SensingAxis::Alpha, SensingAxis::Alpha, 1200.0),
            eq4(jw(1200.0)),
            "eq. 4",
            1200.0,
        );
    }
}

#[test]
fn the_pickup_adds_a_flat_path_so_the_cross_talk_rises_above_the_relevant_band() {
    let s = scene(r#""axes", "cross_talk", "cross_talk_pickup""#, "");
    let m = model(&s);
    let p_units_per_a = s.cross_talk.pickup_urad_per_a.alpha_from_beta * 1e-6 / RAD_PER_OUTPUT_UNIT;
    let mut ratio_db = Vec::new();
    for f in FREQUENCIES_HZ {
        let want = eq4(jw(f)) * 0.1 + p_units_per_a;
        let cross = measured_response(&m, SensingAxis::Beta, SensingAxis::Alpha, f);
        assert_close(cross, want, "cross-talk", f);
        let direct = measured_response(&m, SensingAxis::Alpha, SensingAxis::Alpha, f);
        assert_close(direct, eq4(jw(f)), "direct", f);
        ratio_db.push(20.0 * (cross.norm() / direct.norm()).log10());
    }
    // -20 dB within 2 dB up to 422 Hz, then rising: +20 dB at 9 kHz.
    for (f, db) in FREQUENCIES_HZ.iter().zip(&ratio_db) {
        if *f <= 422.0 {
            assert!((db + 20.0).abs() < 2.0, "{f} Hz: {db} dB");
        }
    }
    assert!(ratio_db[6] > 10.0, "{ratio_db:?}");
    // Without the pickup the ratio is -20 dB at every frequency.
    let constant = model(&scene(r#""axes", "cross_talk""#, ""));
    let r = measured_response(&constant, SensingAxis::Beta, SensingAxis::Alpha, 9000.0)
        / measured_response(&constant, SensingAxis::Alpha, SensingAxis::Alpha, 9000.0);
    assert!((r.norm() - 0.1).abs() < 1e-12, "{r}");
}

#[test]
fn the_current_loop_is_its_pi_closed_on_the_coil_and_first_order_at_ten_khz_by_design() {
    // Back-EMF off: I/C = (kp s + ki) / (L s^2 + (R + kp) s + ki), kp/L = 2 pi 10 kHz.
    let s = scene(
        r#""axes", "amplifier", "current_loop""#,
        r#", "current_loop": {"inertia_kg_m2": 0.0, "integral_corner_hz": 150.0}"#,
    );
    let m = model(&s);
    let cl = m.current_loop.unwrap().values;
    assert!((cl.kp_v_per_a / cl.inductance_h / (std::f64::consts::TAU * 1e4) - 1.0).abs() < 1e-12);
    for f in FREQUENCIES_HZ {
        let loop_tf = (jw(f) * cl.kp_v_per_a + cl.ki_v_per_a_s)
            / (jw(f) * jw(f) * cl.inductance_h
                + jw(f) * (cl.resistance_ohm + cl.kp_v_per_a)
                + cl.ki_v_per_a_s);
        let (re, im) = cl.response_at(std::f64::consts::TAU * f);
        assert_close(C64::new(re, im), loop_tf, "response_at", f);
        assert_close(
            measured_response(&m, SensingAxis::Alpha, SensingAxis::Alpha, f),
            eq4(jw(f)) * loop_tf,
            "current loop",
            f,
        );
    }
    // By design (the PI zero on the coil's pole) the loop is first order at 10 kHz, the
    // paper's amplifier bandwidth.
    let designed = model(&scene(
        r#""axes", "amplifier", "current_loop""#,
        r#", "current_loop": {"inertia_kg_m2": 0.0}"#,
    ));
    let first_order = model(&scene(r#""axes", "amplifier""#, ""));
    for f in FREQUENCIES_HZ {
        let a = measured_response(&designed, SensingAxis::Alpha, SensingAxis::Alpha, f);
        let b = measured_response(&first_order, SensingAxis::Alpha, SensingAxis::Alpha, f);
        assert!((a - b).norm() <= 1e-8 * b.norm(), "{f} Hz: {a} against {b}");
    }
}

#[test]
fn the_back_emf_is_the_mirrors_velocity_through_the_torque_constant() {
    let s = scene(r#""axes", "amplifier", "current_loop""#, "");
    let m = model(&s);
    let cl = m.current_loop.unwrap().values;
    let (k, ws) = (11.4, 140.68);
    let kt_rad = cl.inertia_kg_m2 * ws * ws * k * RAD_PER_OUTPUT_UNIT * RAD_PER_OUTPUT_UNIT;
    for f in FREQUENCIES_HZ {
        let s = jw(f);
        let controller = C64::new(cl.kp_v_per_a, 0.0) + C64::new(cl.ki_v_per_a_s, 0.0) / s;
        let current = controller
            / (s * cl.inductance_h + cl.resistance_ohm + controller + s * eq4(s) * kt_rad);
        assert_close(
            measured_response(&m, SensingAxis::Alpha, SensingAxis::Alpha, f),
            eq4(s) * current,
            "back-EMF",
            f,
        );
    }
}

#[test]
fn the_angle_sensor_bandwidth_is_a_first_order_low_pass_on_what_it_sees() {
    let s = scene(
        r#""axes", "cross_talk", "cross_talk_pickup", "angle_sensor_bandwidth""#,
        r#", "angle_sensor": {"bandwidth_hz": 2000.0}"#,
    );
    let m = model(&s);
    let p = s.cross_talk.pickup_urad_per_a.alpha_from_beta * 1e-6 / RAD_PER_OUTPUT_UNIT;
    let wf = std::f64::consts::TAU * 2000.0;
    for f in FREQUENCIES_HZ {
        let lp = C64::new(wf, 0.0) / (jw(f) + wf);
        assert_close(
            measured_response(&m, SensingAxis::Alpha, SensingAxis::Alpha, f),
            eq4(jw(f)) * lp,
            "filtered direct",
            f,
        );
        assert_close(
            measured_response(&m, SensingAxis::Beta, SensingAxis::Alpha, f),
            (eq4(jw(f)) * 0.1 + p) * lp,
            "filtered cross",
            f,
        );
    }
}

#[test]
fn a_large_step_slews_at_the_voltage_limit_before_the_current_limit() {
    // 2 A on coil a from rest, mirror held (no axes): L di/dt = v_max - R i while the PI asks
    // for more than v_max, i.e. until kp (2 - i) <= v_max (its integral frozen at 0).
    let s = scene(
        r#""amplifier", "current_loop""#,
        r#", "current_loop": {"inertia_kg_m2": 0.0}"#,
    );
    let m = model(&s);
    let cl = m.current_loop.unwrap();
    let v = cl.values;
    let period_s = s.period_s();
    let mut stepper = DriveStepper::new(&m, period_s, IntegratorConfig::default()).unwrap();
    let mut x = m.initial_state([0.0, 0.0]);
    let i_exit = 2.0 - v.max_voltage_v / v.kp_v_per_a;
    let tau = v.inductance_h / v.resistance_ohm;
    let t_exit = -tau * (1.0 - i_exit * v.resistance_ohm / v.max_voltage_v).ln();
    let mut t = 0.0;
    let mut saturated_periods = 0;
    while t + period_s < t_exit {
        let saturated = stepper.step(&mut x, [2.0, 0.0]);
        t += period_s;
        saturated_periods += 1;
        assert_eq!(saturated, [true, false]);
        let ramp = v.max_voltage_v / v.resistance_ohm * (1.0 - (-t / tau).exp());
        assert!(
            (x[cl.current[0]] - ramp).abs() < 1e-12 * ramp.max(1.0) + 1e-12,
            "{t}: {} against {ramp}",
            x[cl.current[0]]
        );
        assert_eq!(x[cl.integral[0]], 0.0, "the integral is frozen");
    }
    assert!(
        saturated_periods >= 1,
        "v_max {} V, exit at {t_exit} s",
        v.max_voltage_v
    );
    // Past the exit the loop is linear again and settles on the command, well below the
    // 4 A current limit it never reached.
    let mut last = [true, false];
    for _ in 0..200 {
        last = stepper.step(&mut x, [2.0, 0.0]);
    }
    assert_eq!(last, [false, false]);
    assert!(
        (x[cl.current[0]] - 2.0).abs() < 1e-6,
        "{}",
        x[cl.current[0]]
    );

    // Through the plant: the period is reported, the current limit is not.
    let mut plant =
        Plant::from_scene(&scene(r#""axes", "amplifier", "current_loop""#, "")).unwrap();
    plant.step(ActuatorPair { a: 2.0, b: 0.0 }).unwrap();
    let out = plant.step(ActuatorPair { a: 2.0, b: 0.0 }).unwrap();
    assert_eq!(
        out.events,
        [PlantEvent::VoltageLimited { a: true, b: false }]
    );
    // A small step stays linear.
    let mut plant =
        Plant::from_scene(&scene(r#""axes", "amplifier", "current_loop""#, "")).unwrap();
    for _ in 0..3 {
        assert!(
            plant
                .step(ActuatorPair { a: 0.05, b: 0.0 })
                .unwrap()
                .events
                .is_empty()
        );
    }
}

#[test]
fn the_stiff_current_loop_and_sensor_filter_refuse_rk4_at_one_substep() {
    for parts in [
        r#""axes", "amplifier", "current_loop""#,
        r#""axes", "angle_sensor_bandwidth""#,
    ] {
        let s = scene(parts, r#", "integrator": {"method": "rk4"}"#);
        let err = Plant::from_scene(&s).unwrap_err();
        assert!(matches!(err, PlantError::Unstable { .. }), "{parts}: {err}");
        let mut fine = s.clone();
        fine.integrator.substeps = 4;
        assert!(Plant::from_scene(&fine).is_ok(), "{parts}");
    }
    // The trapezoid rule takes every model, the saturated ones included.
    let trap = scene(
        r#""axes", "amplifier", "current_loop""#,
        r#", "integrator": {"method": "trapezoid"}"#,
    );
    assert!(Plant::from_scene(&trap).is_ok());
}

#[test]
fn explicit_euler_is_refused_where_its_map_grows_and_accepted_where_it_does_not() {
    // The bench-like drive: the 1.2 kHz second mode (zeta 0.02) is the part explicit Euler
    // cannot damp at 8 sub-steps (`(w2 h)^2 / 2 > zeta_2 w2 h`), and can at 16. At 16 the
    // saturated models' sub-steps are 0.1 us, where the eigenvalues of the map itself cluster
    // within 1e-4 of 1 and the solver's rounding on them once refused it (eigenvalue 1.00009).
    let parts = r#""axes", "second_mode", "cross_talk", "cross_talk_pickup", "amplifier",
        "current_loop", "angle_sensor_bandwidth""#;
    for (substeps, stable) in [(8, false), (16, true)] {
        let s = scene(
            parts,
            &format!(r#", "integrator": {{"method": "explicit_euler", "substeps": {substeps}}}"#),
        );
        match Plant::from_scene(&s) {
            Ok(_) => assert!(stable, "{substeps} sub-steps accepted"),
            Err(err) => assert!(!stable, "{substeps} sub-steps: {err}"),
        }
    }
}

#[test]
fn the_nonlinearity_bends_what_the_sensor_reports_not_the_mirror() {
    let fs = 10.0 * RAD_PER_OUTPUT_UNIT;
    let s = scene(
        r#""angle_sensor_nonlinearity""#,
        &format!(
            r#", "mirror": {{"initial_angles_rad": {{"alpha": {fs}, "beta": {}}}}}"#,
            -0.5 * fs
        ),
    );
    let mut plant = Plant::from_scene(&s).unwrap();
    let out = plant.step(ActuatorPair::default()).unwrap();
    assert_eq!(out.true_angles_rad.alpha, fs);
    assert!((out.measured_angles_rad.alpha / fs - 1.01).abs() < 1e-12);
    assert!((out.measured_angles_rad.beta / fs + 0.5 * 1.0025).abs() < 1e-12);
}

#[test]
fn a_second_mode_and_a_sensor_filter_start_at_rest_at_the_initial_angle() {
    let s = scene(
        r#""axes", "second_mode", "angle_sensor_bandwidth""#,
        r#", "mirror": {"initial_angles_rad": {"alpha": 0.01, "beta": 0.0}}"#,
    );
    let plant = Plant::from_scene(&s).unwrap();
    assert!((plant.true_angles_rad().alpha - 0.01).abs() < 1e-15);
}

#[test]
fn each_richer_value_is_refused_with_its_field_named() {
    use scanhil_emulator::cross_talk::{CrossTalkConfig, Pickup};
    use scanhil_emulator::scene::SceneError;
    let refused = |parts: &str, extra: &str| -> String {
        let json = format!(r#"{{"name": "rich", "parts": [{parts}] {extra}}}"#);
        match Scene::from_json_str(&json, Path::new("rich.json")) {
            Err(SceneError::Invalid { field, .. }) => field,
            other => panic!("{extra}: {other:?}"),
        }
    };
    let sensor = r#""axes", "angle_sensor_bandwidth""#;
    for (extra, field) in [
        (
            r#", "angle_sensor": {"bandwidth_hz": 0.0}"#,
            "angle_sensor.bandwidth_hz",
        ),
        (
            r#", "angle_sensor": {"bandwidth_hz": -5.0}"#,
            "angle_sensor.bandwidth_hz",
        ),
        (
            r#", "angle_sensor": {"nonlinearity_percent": 31.0}"#,
            "angle_sensor.nonlinearity_percent",
        ),
        (
            r#", "angle_sensor": {"nonlinearity_percent": -31.0}"#,
            "angle_sensor.nonlinearity_percent",
        ),
    ] {
        assert_eq!(refused(sensor, extra), field, "{extra}");
    }
    // The limits themselves pass: 30 % and any bandwidth above zero.
    for extra in [
        r#", "angle_sensor": {"nonlinearity_percent": 30.0}"#,
        r#", "angle_sensor": {"nonlinearity_percent": -30.0, "bandwidth_hz": 1e-3}"#,
    ] {
        scene(sensor, extra);
    }
    let current_loop = r#""axes", "amplifier", "current_loop""#;
    for (extra, field) in [
        (
            r#", "current_loop": {"coil_inductance_h": 0.0}"#,
            "current_loop.coil_inductance_h",
        ),
        (
            r#", "current_loop": {"coil_resistance_ohm": -1.0}"#,
            "current_loop.coil_resistance_ohm",
        ),
        (
            r#", "current_loop": {"supply_v": 10.0, "headroom_v": 10.0}"#,
            "current_loop.headroom_v",
        ),
        (
            r#", "current_loop": {"headroom_v": -0.5}"#,
            "current_loop.headroom_v",
        ),
        (
            r#", "current_loop": {"inertia_kg_m2": -1e-6}"#,
            "current_loop.inertia_kg_m2",
        ),
    ] {
        assert_eq!(refused(current_loop, extra), field, "{extra}");
    }
    scene(
        current_loop,
        r#", "current_loop": {"headroom_v": 0.0, "inertia_kg_m2": 0.0}"#,
    );
    for (extra, field) in [
        (
            r#", "mirror": {"second_mode": {"natural_freq_hz": 1200.0, "damping_ratio": 0.0}}"#,
            "mirror.second_mode.damping_ratio",
        ),
        (
            r#", "mirror": {"beta": {"second_mode": {"natural_freq_hz": -1.0, "damping_ratio": 0.02}}}"#,
            "mirror.beta.second_mode.natural_freq_hz",
        ),
        // Beyond what the exact discretisation can step (1e40 once spun forever).
        (
            r#", "mirror": {"second_mode": {"natural_freq_hz": 1e40, "damping_ratio": 0.02}}"#,
            "mirror.second_mode.natural_freq_hz",
        ),
        (
            r#", "mirror": {"second_mode": {"natural_freq_hz": 1200.0, "damping_ratio": 1e40}}"#,
            "mirror.second_mode.damping_ratio",
        ),
        (
            r#", "mirror": {"second_mode": {"natural_freq_hz": 1200.0, "damping_ratio": 0.02, "zero_freq_hz": 1.6e7}}"#,
            "mirror.second_mode.zero_freq_hz",
        ),
        (
            r#", "mirror": {"second_mode": {"natural_freq_hz": 1200.0, "damping_ratio": 0.02, "zero_freq_hz": 900.0, "zero_damping_ratio": 1001.0}}"#,
            "mirror.second_mode.zero_damping_ratio",
        ),
    ] {
        assert_eq!(refused(r#""axes", "second_mode""#, extra), field, "{extra}");
    }
    // Buffers sized in periods: a rate of 2e25 Hz once asked for a 1.6e14-byte power window,
    // and so would a window of 1e9 s (found by AFL++).
    let rate = r#"{"name": "fast", "parts": ["axes"], "control_rate_hz": 2e25}"#;
    // (The plant itself may be stepped at up to 10 MHz, for integrator studies.)
    match Scene::from_json_str(rate, Path::new("fast.json")) {
        Err(SceneError::Invalid { field, .. }) => assert_eq!(field, "control_rate_hz"),
        other => panic!("{other:?}"),
    }
    for window in [
        r#", "power_limit": {"limit_w": 30.0, "window_s": 1e9}"#,
        r#", "control_rate_hz": 1e7, "power_limit": {"limit_w": 30.0, "window_s": 1.0}"#,
    ] {
        assert_eq!(
            refused(r#""axes", "power_limit""#, window),
            "power_limit.window_s",
            "{window}"
        );
    }
    // A pickup cannot be written non-finite in JSON; the check stands behind the library too.
    let nan = CrossTalkConfig {
        pickup_urad_per_a: Pickup {
            alpha_from_beta: 1.0,
            beta_from_alpha: f64::NAN,
        },
        ..CrossTalkConfig::default()
    };
    assert_eq!(
        nan.validate().unwrap_err().0,
        "cross_talk.pickup_urad_per_a.beta_from_alpha"
    );
    assert!(CrossTalkConfig::default().validate().is_ok());
}
