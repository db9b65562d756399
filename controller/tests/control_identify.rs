//! Identification through a plant link: the nominal model recovers eq. 4 and its coherence.

use scanhil_controller::identify::{SteppedSine, SweptSinePlan, Target, identify, identify_swept};
use scanhil_controller::link::NominalPlantLink;
use scanhil_controller::plant_model::PlantModel;
use scanhil_controller::settings::ControllerSettings;
use scanhil_controller::trajectory::SensingAxis;

const T: f64 = 50e-6;

fn plan(axis: SensingAxis, frequencies_hz: Vec<f64>, amplitude: f64) -> SteppedSine {
    SteppedSine {
        axis,
        frequencies_hz,
        amplitude,
        settle_s: 3.0,
        cycles_per_block: 3,
        blocks: 3,
    }
}

#[test]
fn open_loop_identification_recovers_eq_4() {
    let model = PlantModel::default();
    let frequencies = vec![3.0, 15.0, 22.39, 30.0, 100.0, 400.0, 1000.0];
    for axis in [SensingAxis::Alpha, SensingAxis::Beta] {
        let mut link = NominalPlantLink::new(&model, T, 0.0, 0);
        let points = identify(
            &mut link,
            &plan(axis, frequencies.clone(), 0.02),
            &mut Target::OpenLoop,
        )
        .unwrap();
        for p in &points {
            // Eq. 4 with its one-period delay, plus the hold's half period.
            let g = model.continuous_response(p.f_hz, 1.5 * T);
            let mag_err = (p.magnitude / g.norm() - 1.0).abs();
            let phase_err = (p.phase_deg - g.arg().to_degrees() + 180.0).rem_euclid(360.0) - 180.0;
            // Stated tolerance: 0.5 % in magnitude, 0.2 degree in phase (the residue of the
            // 3 s settling of a plant with a 0.22 s decay, and the hold's sinc).
            assert!(
                mag_err < 5e-3,
                "{axis:?} {} Hz: |H| {} vs {}",
                p.f_hz,
                p.magnitude,
                g.norm()
            );
            assert!(
                phase_err.abs() < 0.2,
                "{axis:?} {} Hz: phase error {phase_err}",
                p.f_hz
            );
            assert!(
                p.coherence > 1.0 - 1e-6,
                "{} Hz: coherence {}",
                p.f_hz,
                p.coherence
            );
            assert!(
                p.cross_axis_db < -200.0,
                "the nominal axes are uncoupled: {}",
                p.cross_axis_db
            );
        }
        let peak = points
            .iter()
            .max_by(|a, b| a.magnitude.total_cmp(&b.magnitude))
            .unwrap();
        assert!(
            (peak.f_hz - 22.39).abs() < 0.5,
            "resonance at {} Hz",
            peak.f_hz
        );
    }
}

#[test]
fn noise_lowers_the_coherence_where_the_response_is_small() {
    let model = PlantModel::default();
    let mut link = NominalPlantLink::new(&model, T, 20e-6, 7);
    let points = identify(
        &mut link,
        &plan(SensingAxis::Alpha, vec![22.39, 1500.0], 0.02),
        &mut Target::OpenLoop,
    )
    .unwrap();
    assert!(points[0].coherence > 0.999, "{:?}", points[0]);
    assert!(points[1].coherence < 0.99, "{:?}", points[1]);
    // Same seed, same result.
    let mut again = NominalPlantLink::new(&model, T, 20e-6, 7);
    let repeat = identify(
        &mut again,
        &plan(SensingAxis::Alpha, vec![22.39, 1500.0], 0.02),
        &mut Target::OpenLoop,
    )
    .unwrap();
    assert_eq!(points, repeat);
}

#[test]
fn closed_loop_identification_recovers_the_nominal_t() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/controllers/pid-series.json");
    let settings = ControllerSettings::load(&path).unwrap();
    let controller = settings.build().unwrap();
    let nominal = settings.nominal_loop(controller.axis());
    let mut link = NominalPlantLink::new(&settings.plant, T, 0.0, 0);
    let mut target = Target::ClosedLoop(Box::new(controller));
    let points = identify(
        &mut link,
        &plan(SensingAxis::Beta, vec![27.0, 155.0, 400.0], 1e-4),
        &mut target,
    )
    .unwrap();
    for p in &points {
        let t = nominal.complementary(p.f_hz);
        assert!(
            (p.magnitude / t.norm() - 1.0).abs() < 1e-3,
            "{} Hz: {} vs {}",
            p.f_hz,
            p.magnitude,
            t.norm()
        );
        assert!(
            (p.phase_deg - t.arg().to_degrees()).abs() < 0.1,
            "{} Hz",
            p.f_hz
        );
    }
}

#[test]
fn swept_sine_identification_recovers_eq_4_too() {
    let model = PlantModel::default();
    let plan = SweptSinePlan {
        axis: SensingAxis::Beta,
        start_hz: 1.0,
        stop_hz: 2000.0,
        sweep_s: 4.0,
        quiet_s: 3.0,
        sweeps: 2,
        amplitude: 0.02,
        frequencies_hz: vec![5.0, 22.39, 100.0, 400.0, 1000.0],
    };
    let mut link = NominalPlantLink::new(&model, T, 0.0, 0);
    let points = identify_swept(&mut link, &plan, &mut Target::OpenLoop).unwrap();
    for p in &points {
        let g = model.continuous_response(p.f_hz, 1.5 * T);
        let phase_err = (p.phase_deg - g.arg().to_degrees() + 180.0).rem_euclid(360.0) - 180.0;
        // Same stated tolerance as the stepped sine: 0.5 % and 0.2 degree.
        assert!(
            (p.magnitude / g.norm() - 1.0).abs() < 5e-3,
            "{} Hz: {p:?} vs {}",
            p.f_hz,
            g.norm()
        );
        assert!(phase_err.abs() < 0.2, "{} Hz: {phase_err}", p.f_hz);
        assert!(p.coherence > 1.0 - 1e-6, "{p:?}");
    }
    // With noise the repetitions disagree and the coherence says so.
    let mut noisy = NominalPlantLink::new(&model, T, 50e-6, 11);
    let points = identify_swept(&mut noisy, &plan, &mut Target::OpenLoop).unwrap();
    assert!(points[4].coherence < 0.99, "{:?}", points[4]);
}
