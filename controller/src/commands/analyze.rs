//! `scanhil analyze`: the discrete controller of a settings file and its nominal closed loop.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use scanhil_controller::accuracy::{compare_methods, tone_placements};
use scanhil_controller::loop_analysis::ZPoint;
use scanhil_controller::settings::ControllerSettings;
use scanhil_controller::trajectory::Trajectory;
use scanhil_report::{Axis, Chart, Series, draw_charts};

/// Exit code when the controller or the nominal closed loop is unstable.
const UNSTABLE_EXIT: u8 = 3;

/// Arguments of `scanhil analyze`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The controller settings file (fixtures/controllers/*.json).
    #[arg(long)]
    controller: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
    /// Frequencies (Hz) at which to report |T| and its phase, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "27,52")]
    at: Vec<f64>,
    /// Write the Bode plot of T (magnitude dB and phase deg over log frequency), .svg or .png.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Also compare every discretisation method: tone placement and the tracking error of a
    /// simulated Lissajous 52/27 Hz scan (half range, so the coils do not saturate) with the
    /// nominal plant.
    #[arg(long)]
    compare_methods: bool,
    /// Simulated time for --compare-methods, s (the error is taken over the last second;
    /// at most 60 s).
    #[arg(long, default_value_t = 3.0, allow_negative_numbers = true)]
    compare_duration_s: f64,
}

/// The longest --compare-duration-s, s: every discretisation method is simulated that long.
const MAX_COMPARE_DURATION_S: f64 = 60.0;

/// Runs `scanhil analyze`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let duration_s = args.compare_duration_s;
    if !(duration_s.is_finite() && (1.0..=MAX_COMPARE_DURATION_S).contains(&duration_s)) {
        anyhow::bail!(
            "--compare-duration-s {duration_s}: must be between 1 s (the error is taken over \
             the last second) and {MAX_COMPARE_DURATION_S} s"
        );
    }
    let settings = ControllerSettings::load(&args.controller)?;
    let axis = settings.axis_controller()?;
    let linear = axis.linear();
    let t = settings.period_s();
    let nominal = settings.nominal_loop(&axis);
    let report = nominal.report(&args.at);
    let controller_poles = linear.poles();
    let controller_stable = controller_poles.iter().all(|p| p.norm() <= 1.0 + 1e-12);
    let z = |ps: Vec<nalgebra::Complex<f64>>| {
        ps.into_iter()
            .map(|p| ZPoint::new(p, t))
            .collect::<Vec<_>>()
    };
    let sections: Vec<serde_json::Value> = linear
        .sections()
        .iter()
        .map(|s| serde_json::json!({ "b": s.b, "a": s.a, "poles": z(s.poles()), "zeros": z(s.zeros()) }))
        .collect();
    let build = settings.build();
    let verdict = match &build {
        Ok(_) => "stable".to_string(),
        Err(e) => format!("refused: {e}"),
    };
    let comparison = args.compare_methods.then(|| {
        let prewarp = [27.0, 52.0];
        let lissajous = Trajectory::Lissajous {
            alpha_hz: 52.0,
            beta_hz: 27.0,
            alpha_amplitude_rad: 0.5 * scanhil_protocol::plant_units::FULL_RANGE_DEG.to_radians(),
            beta_amplitude_rad: 0.5 * scanhil_protocol::plant_units::FULL_RANGE_DEG.to_radians(),
            relative_phase_rad: 0.0,
        };
        compare_methods(
            &settings,
            &prewarp,
            &lissajous,
            args.compare_duration_s,
            1.0,
        )
    });
    let json = serde_json::json!({
        "controller": {
            "name": settings.name,
            "file": args.controller.display().to_string(),
            "law": settings.law,
            "discretisation": settings.discretisation.name(),
            "control_rate_hz": settings.control_rate_hz,
        },
        "continuous": settings.continuous(),
        "discrete": { "gain": linear.gain(), "sections": sections, "stable": controller_stable },
        "tones": tone_placements(&settings, &controller_poles),
        "nominal_loop": report,
        "verdict": verdict,
        "method_comparison": comparison,
    });
    if args.json {
        scanhil_protocol::outln!("{}", serde_json::to_string_pretty(&json)?)?;
    } else {
        print_text(&settings, &json, &report)?;
    }
    if let Some(path) = &args.plot {
        let bode = nominal.bode();
        let title = format!("T, {}", settings.discretisation.name());
        let magnitude: Vec<(f64, f64)> = bode.iter().map(|&(f, m, _)| (f, m)).collect();
        let phase: Vec<(f64, f64)> = bode.iter().map(|&(f, _, p)| (f, p)).collect();
        let panel = |title: String, y_label: &str, points| Chart {
            title,
            x_label: "frequency [Hz]".into(),
            y_label: y_label.into(),
            x_axis: Axis::Log,
            y_axis: Axis::Linear,
            series: vec![Series {
                label: "model".into(),
                points,
                markers: false,
            }],
        };
        draw_charts(
            path,
            &[
                panel(
                    format!("{title}: magnitude (nominal plant)"),
                    "|T| [dB]",
                    magnitude,
                ),
                panel(format!("{title}: phase"), "arg T [deg]", phase),
            ],
        )
        .with_context(|| format!("writing the Bode plot {}", path.display()))?;
    }
    Ok(if build.is_ok() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(UNSTABLE_EXIT)
    })
}

fn print_text(
    settings: &ControllerSettings,
    json: &serde_json::Value,
    report: &scanhil_controller::loop_analysis::LoopReport,
) -> std::io::Result<()> {
    let opt =
        |v: Option<f64>, unit: &str| v.map_or("none".to_string(), |x| format!("{x:.3} {unit}"));
    scanhil_protocol::outln!(
        "controller: {} ({}, {} at {} Hz)",
        settings.name,
        settings.origin.display(),
        settings.discretisation.name(),
        settings.control_rate_hz
    )?;
    scanhil_protocol::outln!(
        "discrete sections (b0 b1 b2 / 1 a1 a2), gain {}:",
        json["discrete"]["gain"]
    )?;
    for s in json["discrete"]["sections"]
        .as_array()
        .into_iter()
        .flatten()
    {
        scanhil_protocol::outln!("  b = {}  a = {}", s["b"], s["a"])?;
        for kind in ["poles", "zeros"] {
            for p in s[kind].as_array().into_iter().flatten() {
                scanhil_protocol::outln!(
                    "    {kind:5} {:+.9} {:+.9}j  |z| = {:.9}  {:.4} Hz",
                    p["re"].as_f64().unwrap_or(0.0),
                    p["im"].as_f64().unwrap_or(0.0),
                    p["abs"].as_f64().unwrap_or(0.0),
                    p["f_hz"].as_f64().unwrap_or(0.0)
                )?;
            }
        }
    }
    for tone in json["tones"].as_array().into_iter().flatten() {
        scanhil_protocol::outln!(
            "tone: continuous {:.6} Hz -> discrete {:.6} Hz ({:+.4} mHz), damping {:.3e} -> {:.3e}",
            tone["continuous_hz"].as_f64().unwrap_or(0.0),
            tone["discrete_hz"].as_f64().unwrap_or(0.0),
            tone["error_mhz"].as_f64().unwrap_or(0.0),
            tone["continuous_damping"].as_f64().unwrap_or(0.0),
            tone["discrete_damping"].as_f64().unwrap_or(0.0)
        )?;
    }
    scanhil_protocol::outln!(
        "nominal closed loop ({}):",
        if report.stable { "stable" } else { "UNSTABLE" }
    )?;
    scanhil_protocol::outln!("  crossover            {}", opt(report.crossover_hz, "Hz"))?;
    for c in &report.gain_crossovers {
        scanhil_protocol::outln!(
            "    |L| = 1 at {:.3} Hz, phase margin {:.2} deg",
            c.f_hz,
            c.phase_margin_deg
        )?;
    }
    scanhil_protocol::outln!(
        "  phase margin (min)   {}",
        opt(report.phase_margin_deg, "deg")
    )?;
    scanhil_protocol::outln!(
        "  gain margin          {}",
        opt(report.gain_margin_db, "dB")
    )?;
    for c in &report.phase_crossovers {
        scanhil_protocol::outln!(
            "    arg L = 180 deg at {:.3} Hz, gain margin {:.2} dB",
            c.f_hz,
            c.gain_margin_db
        )?;
    }
    scanhil_protocol::outln!(
        "  -3 dB bandwidth      {}",
        opt(report.bandwidth_3db_hz, "Hz")
    )?;
    scanhil_protocol::outln!(
        "  peak of T            {:.3} dB at {:.3} Hz",
        report.peak_db,
        report.peak_hz
    )?;
    for v in &report.at {
        scanhil_protocol::outln!(
            "  T at {:>8.3} Hz      {:+.4} dB, {:+.4} deg",
            v.f_hz,
            v.magnitude_db,
            v.phase_deg
        )?;
    }
    scanhil_protocol::outln!("  spectral radius      {:.9}", report.spectral_radius)?;
    scanhil_protocol::outln!(
        "  closed-loop poles    {}",
        report
            .closed_loop_poles
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join(", ")
    )?;
    scanhil_protocol::outln!("verdict: {}", json["verdict"].as_str().unwrap_or(""))?;
    if let Some(rows) = json["method_comparison"].as_array() {
        scanhil_protocol::outln!(
            "method comparison (Lissajous 52/27 Hz, half range, nominal plant, error over the last second):"
        )?;
        for row in rows {
            let track = &row["tracking"];
            let tones: Vec<String> = row["tones"]
                .as_array()
                .into_iter()
                .flatten()
                .map(|t| format!("{:+.3} mHz", t["error_mhz"].as_f64().unwrap_or(0.0)))
                .collect();
            if row["accepted"].as_bool() == Some(true) {
                scanhil_protocol::outln!(
                    "  {:32} tones {:28} rms error alpha {:9.3} urad, beta {:9.3} urad, {} saturated periods",
                    row["method"].as_str().unwrap_or(""),
                    tones.join(", "),
                    track["rms_alpha_urad"].as_f64().unwrap_or(0.0),
                    track["rms_beta_urad"].as_f64().unwrap_or(0.0),
                    track["saturated_periods"]
                )?;
            } else {
                scanhil_protocol::outln!(
                    "  {:32} tones {:28} REFUSED",
                    row["method"].as_str().unwrap_or(""),
                    tones.join(", ")
                )?;
            }
        }
    }
    Ok(())
}
