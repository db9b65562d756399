//! `scanhil design`'s rules: the dual-tone at the rate a 1 Mbit/s bus carries, the alpha-tuned
//! PID's refusal there, refusals with their poles, a bus's transit, the reach of a rate (the
//! command as a user runs it: `control_cli.rs`).

use std::path::{Path, PathBuf};

use scanhil_controller::design::alpha_tuning::AlphaTuning;
use scanhil_controller::design::reach::{TRACK_TO, pid_reach, tone_reach};
use scanhil_controller::design::tones::ToneRule;
use scanhil_controller::design::{DesignError, DesignRequest, Margins, Rule};
use scanhil_controller::discretise::Method;
use scanhil_controller::plant_model::PlantModel;
use scanhil_controller::rig::Rig;
use scanhil_controller::run::bus_load::max_control_rate_hz;
use scanhil_controller::run::scenario::TimingMode;
use scanhil_controller::settings::{ControllerSettings, LawSettings};
use scanhil_controller::trajectory::Trajectory;
use scanhil_protocol::bus_load::Bitrates;

fn fixture(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures")
        .join(relative)
}

fn paper_lissajous() -> Trajectory {
    Trajectory::Lissajous {
        alpha_hz: 52.0,
        beta_hz: 27.0,
        alpha_amplitude_rad: 1.5f64.to_radians(),
        beta_amplitude_rad: 1.5f64.to_radians(),
        relative_phase_rad: 0.0,
    }
}

fn request(rate_hz: f64, method: Method) -> DesignRequest {
    DesignRequest {
        name: "test".into(),
        plant: PlantModel::default(),
        rate_hz,
        method,
        margins: Margins::default(),
        trajectory: Some(paper_lissajous()),
        coil_current_limit_a: 6.0,
    }
}

fn prewarped() -> Method {
    Method::TustinPrewarped {
        prewarp_hz: vec![27.0, 52.0],
    }
}

fn tones(rate_hz: f64) -> ToneRule {
    ToneRule {
        tones_hz: vec![27.0, 52.0],
        width_hz: 1.0,
        damping: 1e-4,
        rolloff_hz: ToneRule::default_rolloff_hz(rate_hz),
    }
}

#[test]
fn the_bus_rig_runs_at_the_bus_budgets_rate_and_its_controller_is_todays_design() {
    let rig = Rig::load(&fixture("rigs/paper-bench-1mbit.json")).unwrap();
    let bus = rig.bus.expect("the rig states its bus");
    let rates = Bitrates {
        nominal_bps: bus.bitrate_bps,
        data_bps: bus.bitrate_bps,
    };
    let max = max_control_rate_hz(TimingMode::Lockstep, rates, 0.0);
    assert_eq!(rig.control_rate_hz, max.floor(), "bus budget {max} Hz");
    // The shipped controller is what the rule gives today (not a stale copy).
    let shipped =
        ControllerSettings::load(&fixture("controllers/dual-tone-2736hz-designed.json")).unwrap();
    let design = request(rig.control_rate_hz, prewarped())
        .design(&Rule::DualTone(tones(rig.control_rate_hz)))
        .unwrap();
    let (LawSettings::DualTone(now), LawSettings::DualTone(file)) =
        (&design.settings.law, &shipped.law)
    else {
        panic!("both are dual-tones");
    };
    let same = |a: &[f64], b: &[f64]| {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= 1e-9 * x.abs().max(1e-300))
    };
    assert!(
        same(&[now.k], &[file.k])
            && same(&now.waz_rad_s, &file.waz_rad_s)
            && same(&now.wbz_rad_s, &file.wbz_rad_s)
            && same(&now.zeta_bz, &file.zeta_bz)
            && same(&now.wbp_rad_s, &file.wbp_rad_s)
            && same(&now.zeta_bp, &file.zeta_bp),
        "regenerate the fixture with `scanhil design --rig fixtures/rigs/paper-bench-1mbit.json \
         --rate-hz bus --kind dual-tone`: {now:?} against {file:?}"
    );
    assert_eq!(shipped.control_rate_hz, rig.control_rate_hz);
}

#[test]
fn the_dual_tone_at_the_bus_rate_tracks_its_tones_with_wide_margins() {
    let design = request(2736.0, prewarped())
        .design(&Rule::DualTone(tones(2736.0)))
        .unwrap();
    let f = &design.figures;
    // Narrow tones: L crosses 1 either side of each tone at about +-90 degrees.
    assert_eq!(f.gain_crossovers.len(), 4, "{:?}", f.gain_crossovers);
    assert!(f.phase_margin_deg.unwrap() > 80.0, "{f:?}");
    assert!(f.gain_margin_db.unwrap() > 20.0, "{f:?}");
    for at in &f.at_drive {
        assert!(at.t_db.abs() < 0.05 && at.t_deg.abs() < 0.1, "{at:?}");
        // The error at a tone is about damping f / width: 1e-4 x 27 or 52 / 1.
        let expected = 1e-4 * at.f_hz / 1.0;
        assert!(
            (at.error_relative / expected - 1.0).abs() < 0.1,
            "{at:?}: expected about {expected}"
        );
    }
    let predicted = f.predicted_tracking.unwrap();
    assert!(
        predicted.alpha_rms_relative.unwrap() < 0.005,
        "{predicted:?}"
    );
    assert!(
        predicted.beta_rms_relative.unwrap() < 0.005,
        "{predicted:?}"
    );
    // Eq. 5's form: the equaliser's zero pair sits on the plant's resonance (as Table I's
    // 141 rad/s pair on 140.68), the tones on the drive, and the roll-off at the rate / 8.
    let LawSettings::DualTone(params) = &design.settings.law else {
        panic!("a dual-tone");
    };
    assert!(params.wbz_rad_s.contains(&140.68) && params.zeta_bz.contains(&0.0321));
    let tau = std::f64::consts::TAU;
    for w in [tau * 27.0, tau * 52.0, tau * 342.0] {
        assert!(
            params.wbp_rad_s.iter().any(|p| (p - w).abs() < 1e-9 * w),
            "{w} rad/s in {:?}",
            params.wbp_rad_s
        );
    }
}

#[test]
fn at_the_bus_rate_no_alpha_tuned_pid_keeps_45_degrees_and_the_paper_pid_keeps_seven() {
    let request = request(2736.0, Method::Tustin);
    match request.highest_pid(&AlphaTuning::paper(f64::NAN)) {
        Err(DesignError::Refused { reason, poles }) => {
            assert!(reason.contains("phase margin"), "{reason}");
            assert!(!poles.is_empty(), "{reason}");
        }
        other => panic!("expected a refusal, got {other:?}"),
    }
    // Table II's rule at its 211 Hz: a period and a half of 365 us costs 42 degrees at the
    // crossover; stable on the nominal plant, with 7 degrees and 1.8 dB left.
    match request.design(&Rule::AlphaTuning(AlphaTuning::paper(211.0))) {
        Err(DesignError::Refused { reason, poles }) => {
            assert!(reason.contains("phase margin 7.3 deg"), "{reason}");
            assert!(reason.contains("gain margin 1.7 dB"), "{reason}");
            assert!(poles.iter().all(|p| p.abs < 1.0), "{poles:?}");
            assert_eq!(poles.len(), 4);
        }
        other => panic!("expected a refusal, got {other:?}"),
    }
}

#[test]
fn a_rate_too_low_for_the_drive_is_refused_with_the_poles() {
    // 120 Hz: the 52 Hz tone sits 8 Hz under Nyquist and the roll-off (15 Hz) under both
    // tones; the loop is unstable.
    let request = request(120.0, prewarped());
    match request.design(&Rule::DualTone(tones(120.0))) {
        Err(DesignError::Refused { reason, poles }) => {
            assert!(reason.contains("unstable"), "{reason}");
            assert!(poles.iter().any(|p| p.abs > 1.0), "{poles:?}");
        }
        other => panic!("expected a refusal, got {other:?}"),
    }
    // A stated margin above what the tones give is refused too, with the slowest poles.
    let strict = DesignRequest {
        margins: Margins {
            phase_deg: 89.0,
            gain_db: 6.0,
        },
        ..self::request(2736.0, prewarped())
    };
    match strict.design(&Rule::DualTone(tones(2736.0))) {
        Err(DesignError::Refused { reason, poles }) => {
            assert!(reason.contains("below the 89 deg asked"), "{reason}");
            assert_eq!(poles.len(), 4);
            assert!(poles.iter().all(|p| p.abs < 1.0));
        }
        other => panic!("expected a refusal, got {other:?}"),
    }
}

#[test]
fn a_transit_on_the_bus_is_designed_for() {
    // 300 us of transit at 2736 Hz: 5.6 and 10.8 degrees more lag at the tones. The rule turns
    // the tones' phases to match, so T stays 1 at the drive; the controller designed without
    // the transit, run on the delayed plant, misses the tones' phase.
    let delayed = PlantModel {
        extra_delay_s: 300e-6,
        ..PlantModel::default()
    };
    let with = DesignRequest {
        plant: delayed,
        ..request(2736.0, prewarped())
    }
    .design(&Rule::DualTone(tones(2736.0)))
    .unwrap();
    assert_eq!(with.settings.plant.extra_delay_s, 300e-6);
    for at in &with.figures.at_drive {
        assert!(at.t_db.abs() < 0.05 && at.t_deg.abs() < 0.1, "{at:?}");
    }
    let without = request(2736.0, prewarped())
        .design(&Rule::DualTone(tones(2736.0)))
        .unwrap();
    let mut mismatched = without.settings.clone();
    mismatched.plant = delayed;
    let figures =
        scanhil_controller::design::evaluate(&mismatched, Some(&paper_lissajous()), &[27.0, 52.0])
            .unwrap();
    let (matched_pm, mismatched_pm) = (
        with.figures.phase_margin_deg.unwrap(),
        figures.phase_margin_deg.unwrap(),
    );
    assert!(
        mismatched_pm < matched_pm - 4.0,
        "the transit's lag shows: {mismatched_pm} against {matched_pm}"
    );
}

#[test]
fn the_reach_is_where_the_error_reaches_one_per_cent() {
    // PID at 20 kHz: the highest crossover keeping 45 degrees, and the sine whose error is
    // exactly 1 % rms there.
    let request_pid = request(20_000.0, Method::Tustin);
    let pid = pid_reach(&request_pid, &AlphaTuning::paper(f64::NAN)).unwrap();
    assert!(
        (150.0..211.0).contains(&pid.crossover_hz),
        "the paper's 211 Hz keeps only 43.7 deg: {pid:?}"
    );
    let design = request_pid
        .design(&Rule::AlphaTuning(AlphaTuning::paper(pid.crossover_hz)))
        .unwrap();
    let nominal = design
        .settings
        .nominal_loop(design.settings.build().unwrap().axis());
    let error = (nominal.loop_gain(pid.sine_hz) + 1.0).inv().norm() / std::f64::consts::SQRT_2;
    assert!((error - TRACK_TO).abs() < 1e-6, "{error} at {pid:?}");
    // No PID at the bus rate.
    assert_eq!(
        pid_reach(
            &request(2736.0, Method::Tustin),
            &AlphaTuning::paper(f64::NAN)
        ),
        None
    );
    // The dual-tone's reach at the bus rate: the highest 52:27 pair within 1 %, and 5 % more
    // is over it.
    let reach = tone_reach(&request(2736.0, prewarped()), &tones(2736.0)).unwrap();
    let worst = [
        reach.predicted_tracking.alpha_rms_relative.unwrap(),
        reach.predicted_tracking.beta_rms_relative.unwrap(),
    ]
    .into_iter()
    .fold(0.0, f64::max);
    assert!(worst <= TRACK_TO && worst > 0.95 * TRACK_TO, "{reach:?}");
    assert!((reach.drive_hz[1] / reach.drive_hz[0] - 52.0 / 27.0).abs() < 1e-9);
    let beyond = 1.05 * reach.drive_hz[1] / 52.0;
    let further = DesignRequest {
        trajectory: Some(Trajectory::Lissajous {
            alpha_hz: 52.0 * beyond,
            beta_hz: 27.0 * beyond,
            alpha_amplitude_rad: 1.5f64.to_radians(),
            beta_amplitude_rad: 1.5f64.to_radians(),
            relative_phase_rad: 0.0,
        }),
        method: Method::TustinPrewarped {
            prewarp_hz: vec![27.0 * beyond, 52.0 * beyond],
        },
        ..request(2736.0, prewarped())
    };
    let rule = ToneRule {
        tones_hz: further.drive_hz(),
        ..tones(2736.0)
    };
    let over = further.design(&Rule::DualTone(rule)).unwrap();
    assert!(
        over.figures
            .predicted_tracking
            .unwrap()
            .alpha_rms_relative
            .unwrap()
            > TRACK_TO,
        "{:?}",
        over.figures.predicted_tracking
    );
}
