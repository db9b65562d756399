//! Identification against the emulator's plant (in process, through `PlantLink`): the measured
//! response matches eq. 4 within the stated tolerance, and the emulator's cross-talk, amplifier
//! and sensor noise show up where they should.

use std::path::Path;

use scanhil_controller::identify::{ResponsePoint, SteppedSine, Target, identify};
use scanhil_controller::link::{LinkError, PlantLink};
use scanhil_controller::plant_model::PlantModel;
use scanhil_controller::trajectory::SensingAxis;
use scanhil_emulator::plant::Plant;
use scanhil_emulator::scene::Scene;
use scanhil_protocol::plant_units::{ActuatorPair, SensingPair};

/// The emulator's plant as a link: one `Plant::step` per exchange.
struct EmulatedPlant {
    plant: Plant,
    period_s: f64,
}

impl PlantLink for EmulatedPlant {
    fn exchange(&mut self, coil_currents_a: ActuatorPair) -> Result<SensingPair, LinkError> {
        let step = self.plant.step(coil_currents_a).map_err(|e| LinkError {
            message: e.to_string(),
        })?;
        Ok(step.measured_angles_rad)
    }

    fn period_s(&self) -> f64 {
        self.period_s
    }
}

fn emulated(parts: &str) -> EmulatedPlant {
    let json = format!(r#"{{"name": "identify", "seed": 3, "parts": [{parts}]}}"#);
    let scene = Scene::from_json_str(&json, Path::new("inline.json")).unwrap();
    EmulatedPlant {
        period_s: scene.period_s(),
        plant: Plant::from_scene(&scene).unwrap(),
    }
}

fn measure(link: &mut EmulatedPlant, frequencies_hz: Vec<f64>) -> Vec<ResponsePoint> {
    let plan = SteppedSine {
        axis: SensingAxis::Alpha,
        frequencies_hz,
        amplitude: 0.02,
        settle_s: 3.0,
        cycles_per_block: 3,
        blocks: 3,
    };
    identify(link, &plan, &mut Target::OpenLoop).unwrap()
}

fn phase_error_deg(p: &ResponsePoint, model: nalgebra::Complex<f64>) -> f64 {
    (p.phase_deg - model.arg().to_degrees() + 180.0).rem_euclid(360.0) - 180.0
}

#[test]
fn emulated_mirror_axes_match_eq_4() {
    let mut link = emulated(r#""axes""#);
    let t = link.period_s;
    let model = PlantModel::default();
    for p in measure(&mut link, vec![3.0, 22.39, 60.0, 250.0, 1000.0]) {
        // Stated tolerance: eq. 4 with a period and a half of delay, within 0.5 % and 0.2 deg.
        let g = model.continuous_response(p.f_hz, 1.5 * t);
        assert!(
            (p.magnitude / g.norm() - 1.0).abs() < 5e-3,
            "{} Hz: {p:?} vs |G| {}",
            p.f_hz,
            g.norm()
        );
        assert!(phase_error_deg(&p, g).abs() < 0.2, "{} Hz: {p:?}", p.f_hz);
        assert!(p.coherence > 1.0 - 1e-6, "{p:?}");
    }
}

#[test]
fn emulated_cross_talk_amplifier_and_noise_are_measured() {
    let mut link = emulated(r#""axes", "cross_talk", "amplifier", "angle_sensor_noise""#);
    let t = link.period_s;
    let model = PlantModel::default();
    let points = measure(&mut link, vec![10.0, 100.0, 400.0, 3000.0]);
    let mut cross_talk_checked = 0;
    for p in &points[..3] {
        // The 10 kHz amplifier adds at most atan(f / 10 kHz) of lag below 400 Hz; the
        // cross-talk changes the direct response by about 1 %; the noise adds a random error
        // of about sqrt((1 - c) / (2 blocks c)) for coherence c (twice that is allowed).
        let g = model.continuous_response(p.f_hz, 1.5 * t);
        let random = 2.0 * ((1.0 - p.coherence) / (2.0 * 3.0 * p.coherence)).sqrt();
        assert!(
            (p.magnitude / g.norm() - 1.0).abs() < 0.02 + random,
            "{p:?} vs |G| {}",
            g.norm()
        );
        let lag = (p.f_hz / 10_000.0).atan().to_degrees();
        assert!(
            phase_error_deg(p, g).abs() < lag + 0.5 + random.to_degrees(),
            "{p:?}"
        );
        // Cross-talk about 20 dB below the direct response (the paper's Fig. 4), checked
        // where the noise does not mask the small cross-axis response.
        if p.coherence > 0.999 {
            let below = p.magnitude_db - p.cross_axis_db;
            assert!(
                (15.0..25.0).contains(&below),
                "{} Hz: cross-talk {below} dB below",
                p.f_hz
            );
            cross_talk_checked += 1;
        }
    }
    assert!(cross_talk_checked >= 2, "{points:?}");
    // Sensor noise: coherence falls where the response is small.
    assert!(points[0].coherence > 0.999, "{:?}", points[0]);
    assert!(points[3].coherence < points[0].coherence, "{points:?}");
}
