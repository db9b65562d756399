//! The PID of Table II: both readings, their discrete paths, limits and anti-windup.

use nalgebra::Complex;
use scanhil_controller::discretise::Method;
use scanhil_controller::pid::{Pid, PidForm, PidParams};

const T: f64 = 50e-6;

fn table_ii(form: PidForm) -> PidParams {
    PidParams {
        form,
        kp: 2.567,
        kd: 5.8e-3,
        ki: 340.32,
        wt_rad_s: 4375.0,
    }
}

#[test]
fn continuous_forms_are_the_two_readings() {
    let s = Complex::new(0.0, std::f64::consts::TAU * 240.0);
    let p = table_ii(PidForm::Parallel);
    let parallel = s.inv() * p.ki + p.kp + s * p.kd / (s / p.wt_rad_s + 1.0);
    assert!((p.continuous().eval(s) - parallel).norm() < 1e-12 * parallel.norm());
    let p = table_ii(PidForm::Series);
    let (wi, wd) = (p.ki / p.kp, p.kp / p.kd);
    let series = (s.inv() * wi + 1.0) * (s / wd + 1.0) / (s / p.wt_rad_s + 1.0) * p.kp;
    assert!((p.continuous().eval(s) - series).norm() < 1e-12 * series.norm());
    // Table II nearly fits alpha tuning (wd = wc / alpha, wt = wc alpha, wi ~ wc / 10) with
    // alpha = 3 and wc = 2 pi 240 in the series form: it gives alpha = 3.14, fc = 221 Hz.
    let fc = (wd * p.wt_rad_s).sqrt() / std::f64::consts::TAU;
    let alpha = (p.wt_rad_s / wd).sqrt();
    assert!((fc - 240.0).abs() < 0.1 * 240.0, "{fc} Hz");
    assert!((alpha - 3.0).abs() < 0.2, "alpha {alpha}");
    assert!((std::f64::consts::TAU * fc / wi - 10.0).abs() < 1.0);
}

#[test]
fn unsaturated_run_equals_the_linear_cascade() {
    for form in [PidForm::Series, PidForm::Parallel] {
        for method in Method::all(&[240.0]) {
            let mut pid = Pid::new(&table_ii(form), &method, T, 1e9);
            let mut linear = pid.linear();
            for k in 0..2000 {
                let e = (k as f64 * 0.013).sin() + 0.3;
                let (a, b) = (pid.step(e), linear.step(e));
                assert!(
                    (a - b).abs() < 1e-9 * (1.0 + b.abs()),
                    "{form:?} {}: {a} vs {b}",
                    method.name()
                );
            }
        }
    }
}

#[test]
fn tustin_pid_matches_the_continuous_one_well_below_nyquist() {
    for form in [PidForm::Series, PidForm::Parallel] {
        let params = table_ii(form);
        let pid = Pid::new(&params, &Method::Tustin, T, 1e9);
        for f in [10.0, 100.0, 240.0] {
            let c = params
                .continuous()
                .eval(Complex::new(0.0, std::f64::consts::TAU * f));
            let d = pid.linear().response(f, T);
            assert!(
                (d - c).norm() < 0.01 * c.norm(),
                "{form:?} at {f} Hz: {d} vs {c}"
            );
        }
    }
}

#[test]
fn output_is_limited_and_the_integrator_does_not_wind_up() {
    let limit = 1.0;
    // At either limit (issue 20: switching the anti-windup off at the negative limit alone
    // once passed every controller test).
    for sign in [1.0, -1.0] {
        let mut pid = Pid::new(&table_ii(PidForm::Parallel), &Method::Tustin, T, limit);
        // A large error for 0.5 s saturates the output ...
        for _ in 0..10_000 {
            let u = pid.step(sign * 5.0);
            assert!(u.abs() <= limit, "{u}");
        }
        // ... and when the error reverses, the output leaves the limit at once, because the
        // integrator held still while saturated.
        let after = sign * pid.step(-sign * 0.5);
        assert!(
            after < limit,
            "still saturated at {sign} x the limit: {after}"
        );
    }
    // Without the limit, the integral holds ki * 5 * 0.5 = 850 input units (less the
    // derivative kick kd wt 5.5 = 140 of the reversal).
    let mut unlimited = Pid::new(&table_ii(PidForm::Parallel), &Method::Tustin, T, 1e9);
    for _ in 0..10_000 {
        unlimited.step(5.0);
    }
    assert!(unlimited.step(-0.5) > 600.0);
}
