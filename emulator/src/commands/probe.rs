//! `scanhil-emulator probe`: for a static mirror, where the spot lands, the true surface
//! height there, and what the ILD 2300 reports (raw value and distance, or the error), plus
//! the point the scene's geometry model reconstructs from it.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use serde::Serialize;

use scanhil_emulator::optics::OpticalOutcome;
use scanhil_emulator::scene::{Part, Scene};
use scanhil_protocol::ild::IldValue;
use scanhil_protocol::plant_units::SensingPair;

use super::print_or_broken_pipe;

/// Arguments of `scanhil-emulator probe`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene file (JSON); it must list the `optics` part.
    #[arg(long)]
    scene: PathBuf,
    /// Mechanical mirror deflection about x (alpha axis, spot along y), degrees.
    #[arg(long, allow_negative_numbers = true)]
    d_alpha: f64,
    /// Mechanical mirror deflection about the mirror's in-plane axis (beta, spot along x),
    /// degrees.
    #[arg(long, allow_negative_numbers = true)]
    d_beta: f64,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// What the optics found.
#[derive(Debug, Clone, PartialEq, Serialize)]
struct OpticsReport {
    /// `distance`, `miss` or `shaded`.
    outcome: &'static str,
    /// Why the spot is shaded (`shaded` only).
    shade_reason: Option<&'static str>,
    /// The noise-free distance along the folded beam, mm.
    true_distance_mm: Option<f64>,
    /// The light the spot sends the receiver, relative to a white matte surface facing it at
    /// mid-range (1 unless the scene lists `receiver_intensity`).
    intensity: Option<f64>,
}

/// What the sensor sent.
#[derive(Debug, Clone, PartialEq, Serialize)]
struct SensorReport {
    /// The 18-bit raw value.
    raw: u32,
    /// The distance it stands for, mm (`None` for an error value).
    distance_mm: Option<f64>,
    /// The error's name (`None` for a distance).
    error: Option<&'static str>,
    /// The surface point the scene's model reconstructs from the angles and the distance, mm.
    reconstructed_mm: Option<[f64; 3]>,
}

/// The probe's answer.
#[derive(Debug, Clone, PartialEq, Serialize)]
struct ProbeReport {
    scene: String,
    surface: &'static str,
    model: &'static str,
    shading: bool,
    /// Whether the second bounce is modelled (only in the JSON when it is).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    multiple_reflections: bool,
    d_alpha_deg: f64,
    d_beta_deg: f64,
    /// Where the laser meets the mirror, mm.
    beam_origin_mm: [f64; 3],
    /// The beam's direction after the mirror.
    beam_direction: [f64; 3],
    /// Laser path from the sensor reference to the mirror, mm.
    path_to_mirror_mm: f64,
    /// Where the beam meets the surface, mm (`None`: nothing there).
    spot_mm: Option<[f64; 3]>,
    /// Ground truth z of the surface at the spot's (x, y), mm.
    true_height_mm: Option<f64>,
    optics: OpticsReport,
    /// `None` when the scene does not list the `sensor` part.
    sensor: Option<SensorReport>,
}

/// Builds the scene's optics and sensor and probes one static mirror position.
fn probe(scene: &Scene, d_alpha_deg: f64, d_beta_deg: f64) -> anyhow::Result<ProbeReport> {
    anyhow::ensure!(
        scene.has(Part::Optics),
        "scene `{}` does not list the `optics` part: there is no optical path to probe",
        scene.name
    );
    anyhow::ensure!(
        d_alpha_deg.is_finite() && d_beta_deg.is_finite(),
        "--d-alpha and --d-beta must be finite (got {d_alpha_deg}, {d_beta_deg})"
    );
    let optics = scene
        .optical_path()
        .with_context(|| format!("scene `{}`", scene.name))?;
    let angles = SensingPair {
        alpha: d_alpha_deg.to_radians(),
        beta: d_beta_deg.to_radians(),
    };
    let reading = optics.observe(angles);
    let (outcome, shade_reason, true_distance_mm, intensity) = match reading.outcome {
        OpticalOutcome::Distance {
            z_meas_mm,
            intensity,
        } => ("distance", None, Some(z_meas_mm), Some(intensity)),
        OpticalOutcome::Miss => ("miss", None, None, None),
        OpticalOutcome::Shaded(reason) => ("shaded", Some(reason.name()), None, None),
    };
    let sensor = if scene.has(Part::Sensor) {
        let mut sensor = scene
            .triangulation_sensor()
            .with_context(|| format!("scene `{}`: sensor", scene.name))?;
        let value = sensor.value_for(&reading.outcome);
        let distance_mm = match value {
            IldValue::Distance(digital) => sensor.range().digital_to_mm(digital),
            IldValue::Error(_) => None,
        };
        Some(SensorReport {
            raw: value.raw(),
            distance_mm,
            error: match value {
                IldValue::Error(e) => Some(e.name()),
                IldValue::Distance(_) => None,
            },
            reconstructed_mm: distance_mm.map(|z| {
                optics
                    .scanner()
                    .point(angles.alpha, angles.beta, z)
                    .coords
                    .into()
            }),
        })
    } else {
        None
    };
    Ok(ProbeReport {
        scene: scene.name.clone(),
        surface: optics.surface().kind(),
        model: optics.scanner().model().name(),
        shading: optics.shading(),
        multiple_reflections: optics.multiple_reflections(),
        d_alpha_deg,
        d_beta_deg,
        beam_origin_mm: reading.beam.origin_mm.coords.into(),
        beam_direction: reading.beam.direction.into(),
        path_to_mirror_mm: reading.beam.path_to_origin_mm,
        spot_mm: reading.spot_mm.map(|p| p.coords.into()),
        true_height_mm: reading.true_height_mm,
        optics: OpticsReport {
            outcome,
            shade_reason,
            true_distance_mm,
            intensity,
        },
        sensor,
    })
}

fn format_point(p: &[f64; 3]) -> String {
    format!("({:.4}, {:.4}, {:.4})", p[0], p[1], p[2])
}

fn format_text(r: &ProbeReport) -> String {
    let or_none = |v: Option<String>| v.unwrap_or_else(|| "none".into());
    let mut lines = vec![
        format!(
            "scene          {} (surface {}, model {}, shading {}{})",
            r.scene,
            r.surface,
            r.model,
            if r.shading { "on" } else { "off" },
            if r.multiple_reflections {
                ", multiple reflections on"
            } else {
                ""
            }
        ),
        format!(
            "mirror         d_alpha {} deg, d_beta {} deg (mechanical)",
            r.d_alpha_deg, r.d_beta_deg
        ),
        format!(
            "beam           from {} mm (path to mirror {:.4} mm), direction ({:.6}, {:.6}, {:.6})",
            format_point(&r.beam_origin_mm),
            r.path_to_mirror_mm,
            r.beam_direction[0],
            r.beam_direction[1],
            r.beam_direction[2]
        ),
        format!(
            "spot           {}",
            or_none(
                r.spot_mm
                    .as_ref()
                    .map(|p| format!("{} mm", format_point(p)))
            )
        ),
        format!(
            "true height    {}",
            or_none(r.true_height_mm.map(|z| format!("z = {z:.4} mm")))
        ),
        format!(
            "optics         {}",
            match (r.optics.true_distance_mm, r.optics.shade_reason) {
                (Some(d), _) => format!(
                    "distance {d:.4} mm, intensity {:.4}",
                    r.optics.intensity.unwrap_or(1.0)
                ),
                (None, Some(reason)) => format!("shaded ({reason}): no distance"),
                (None, None) => "miss: no surface on the beam".into(),
            }
        ),
    ];
    match &r.sensor {
        None => lines.push("sensor         not in the scene's parts".into()),
        Some(s) => {
            lines.push(match (s.distance_mm, s.error) {
                (Some(d), _) => format!("sensor         raw {} = {d:.4} mm", s.raw),
                (None, e) => format!(
                    "sensor         raw {} = error {}",
                    s.raw,
                    e.unwrap_or("unknown_error")
                ),
            });
            if let Some(p) = &s.reconstructed_mm {
                lines.push(format!(
                    "reconstructed  {} mm ({})",
                    format_point(p),
                    r.model
                ));
            }
        }
    }
    lines.join("\n") + "\n"
}

/// Runs `scanhil-emulator probe`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let scene = Scene::load(&args.scene)
        .with_context(|| format!("loading scene {}", args.scene.display()))?;
    let report = probe(&scene, args.d_alpha, args.d_beta)?;
    let text = if args.json {
        serde_json::to_string_pretty(&report)? + "\n"
    } else {
        format_text(&report)
    };
    use std::io::Write;
    print_or_broken_pipe(std::io::stdout().write_all(text.as_bytes()))?;
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanhil_protocol::ild::MeasuringRange;
    use scanhil_scene::surface::duplo;
    use std::path::Path;

    fn fixture(name: &str) -> Scene {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../fixtures/scenes")
            .join(name);
        Scene::load(&path).unwrap()
    }

    fn reconstructed_z(scene: &Scene, d_alpha_deg: f64, d_beta_deg: f64) -> f64 {
        let report = probe(scene, d_alpha_deg, d_beta_deg).unwrap();
        report.sensor.unwrap().reconstructed_mm.unwrap()[2]
    }

    #[test]
    fn duplo_stud_height_through_the_sensor_is_the_reference_within_resolution() {
        let scene = fixture("duplo-2x4-130mm.json");
        assert!(scene.has(Part::SensorNoise) && scene.has(Part::Shading));
        // The stud's ring (beta 1.3 deg: 4.0 mm from its axis at x = 0, mid-ring) and the top
        // face beyond the stud (alpha -1.4 deg: y = -2.85 mm, the stud spans -14.7 to -5.3).
        let ring = reconstructed_z(&scene, 0.0, 1.3);
        let top = reconstructed_z(&scene, -1.4, 0.0);
        let digit = MeasuringRange::ILD2300_100.mm_per_digit();
        let height = ring - top;
        assert!(
            (height - duplo::STUD_HEIGHT_MM).abs() < 3.0 * digit,
            "stud height {height} mm, reference {} mm, digit {digit} mm",
            duplo::STUD_HEIGHT_MM
        );
    }

    #[test]
    fn report_carries_spot_truth_and_sensor_value() {
        let scene = fixture("duplo-2x4-130mm.json");
        let r = probe(&scene, 0.0, 1.3).unwrap();
        assert_eq!(
            (r.surface, r.model, r.shading),
            ("duplo_2x4", "exact_reflection", true)
        );
        let spot = r.spot_mm.unwrap();
        let truth = r.true_height_mm.unwrap();
        assert!((spot[2] - truth).abs() < 1e-9);
        assert!((truth - (-130.0 + duplo::STUD_HEIGHT_MM)).abs() < 1e-9);
        let sensor = r.sensor.unwrap();
        assert!(sensor.error.is_none() && sensor.raw <= 65_519);
        let text = format_text(&probe(&scene, 0.0, 1.3).unwrap());
        assert!(
            text.contains("raw ") && text.contains("true height    z = -125.3370 mm"),
            "{text}"
        );
    }

    #[test]
    fn shaded_and_unknown_positions_report_errors_not_distances() {
        let scene = fixture("step-3mm.json");
        // Sweep alpha across the wall at y = -10: some positions must be shaded, and those
        // give the sensor's no-peak error.
        let shaded: Vec<_> = (0..=200)
            .map(|k| probe(&scene, -1.5 + 0.015 * f64::from(k), 0.0).unwrap())
            .filter(|r| r.optics.outcome == "shaded")
            .collect();
        assert!(!shaded.is_empty());
        for r in shaded {
            let s = r.sensor.unwrap();
            assert_eq!(
                (s.error, s.distance_mm, s.raw),
                (Some("no_peak"), None, 262_076)
            );
        }
    }

    #[test]
    fn a_scene_without_optics_is_refused_by_name() {
        let scene = fixture("step-alpha.json");
        let err = probe(&scene, 0.0, 0.0).unwrap_err().to_string();
        assert!(err.contains("optics") && err.contains(&scene.name), "{err}");
    }
}
