//! `scanhil identify`: a stepped-sine system analyser on one sensing axis, of the open-loop
//! plant (the paper's Fig. 4) or of the closed loop (Fig. 8, 9), with coherence; JSON and a
//! Bode plot beside the nominal model.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use nalgebra::Complex;
use scanhil_controller::closed_loop_figures::closed_loop_figures;
use scanhil_controller::identify::{
    ResponsePoint, SteppedSine, SweptSinePlan, Target, identify, identify_swept,
};
use scanhil_controller::link::{NominalPlantLink, PlantLink};
use scanhil_controller::run::plant_link::LinkedPlant;
use scanhil_controller::run::scenario::NodeLink;
use scanhil_controller::settings::ControllerSettings;
use scanhil_controller::trajectory::SensingAxis;
use scanhil_report::{Axis, Chart, Series, draw_charts};

/// The model's response at a frequency (Hz), drawn beside the measurement.
type ModelResponse = Box<dyn Fn(f64) -> Complex<f64>>;

/// Which plant to excite.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum PlantChoice {
    /// The in-process nominal model (eq. 4, ZOH, one period of delay), with --noise-urad.
    Nominal,
}

/// What to measure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Mode {
    /// Coil command to angle (paper units, output V per input V).
    OpenLoop,
    /// Reference to angle with --controller (T).
    ClosedLoop,
}

/// The excitation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Excitation {
    /// One sine per frequency, settled, averaged over --blocks blocks of --cycles periods.
    Stepped,
    /// --blocks logarithmic sweeps from --from-hz to --to-hz of --sweep-s each, with
    /// --quiet-s of rest after each; the response is estimated at the --points frequencies.
    Swept,
}

/// Arguments of `scanhil identify`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The plant to excite.
    #[arg(long, value_enum, default_value = "nominal")]
    plant: PlantChoice,
    /// Excite a mirror node on a real link instead of --plant: `pty` (the emulator on a pty
    /// pair, serving --scene), `slcan:PATH[@BITRATE]` or `socketcan:IFACE`.
    #[arg(long)]
    fsm: Option<String>,
    /// The scene the emulator serves with `--fsm pty`.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Open or closed loop.
    #[arg(long, value_enum, default_value = "open-loop")]
    mode: Mode,
    /// Controller settings for --mode closed-loop (also sets the control rate).
    #[arg(long)]
    controller: Option<PathBuf>,
    /// The excited sensing axis.
    #[arg(long, value_enum, default_value = "alpha")]
    axis: SensingAxis,
    /// Lowest frequency, Hz.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    from_hz: f64,
    /// Highest frequency, Hz.
    #[arg(long, default_value_t = 2000.0, allow_negative_numbers = true)]
    to_hz: f64,
    /// Number of log-spaced frequencies.
    #[arg(long, default_value_t = 40, allow_negative_numbers = true)]
    points: usize,
    /// Excitation amplitude: input units (A) open loop (default 0.02), mrad of reference closed loop (default 0.1; keep the coil command below its limit at high frequency).
    #[arg(long, allow_negative_numbers = true)]
    amplitude: Option<f64>,
    /// Stepped or swept sine.
    #[arg(long, value_enum, default_value = "stepped")]
    excitation: Excitation,
    /// Duration of one sweep (--excitation swept), s.
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
    sweep_s: f64,
    /// Rest after each sweep (--excitation swept), s: several decay times of the plant or loop.
    #[arg(long, default_value_t = 2.5, allow_negative_numbers = true)]
    quiet_s: f64,
    /// Settling time before each measurement, s (the plant's decay time is 0.22 s).
    #[arg(long, default_value_t = 2.5, allow_negative_numbers = true)]
    settle_s: f64,
    /// Whole periods per averaging block.
    #[arg(long, default_value_t = 4, allow_negative_numbers = true)]
    cycles: u32,
    /// Averaging blocks per frequency, or sweeps (>= 2 for a meaningful coherence).
    #[arg(long, default_value_t = 4, allow_negative_numbers = true)]
    blocks: u32,
    /// White angle noise of the nominal plant, urad RMS.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    noise_urad: f64,
    /// Seed of the noise.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    seed: u64,
    /// Control rate when no controller is given, Hz.
    #[arg(long, default_value_t = 20_000.0, allow_negative_numbers = true)]
    rate_hz: f64,
    /// Write the JSON result here (it is printed otherwise).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write the Bode plot (measured and model, magnitude, phase, coherence), .svg or .png.
    #[arg(long)]
    plot: Option<PathBuf>,
}

/// Runs `scanhil identify`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        args.from_hz > 0.0 && args.to_hz > args.from_hz,
        "--from-hz must be positive and below --to-hz"
    );
    anyhow::ensure!(
        args.blocks >= 1 && args.cycles >= 1,
        "--blocks and --cycles must be at least 1"
    );
    let settings = args
        .controller
        .as_ref()
        .map(|p| ControllerSettings::load(p))
        .transpose()?;
    let period_s = settings
        .as_ref()
        .map_or(1.0 / args.rate_hz, ControllerSettings::period_s);
    anyhow::ensure!(
        args.to_hz < 0.5 / period_s,
        "--to-hz must be below Nyquist ({} Hz)",
        0.5 / period_s
    );
    let plant_model = settings.as_ref().map(|s| s.plant).unwrap_or_default();
    let mut link: Box<dyn PlantLink> = match (&args.fsm, args.plant) {
        (Some(fsm), _) => Box::new(LinkedPlant::connect(
            &NodeLink::parse(fsm),
            args.scene.as_deref(),
            None,
            period_s,
        )?),
        (None, PlantChoice::Nominal) => Box::new(NominalPlantLink::new(
            &plant_model,
            period_s,
            args.noise_urad * 1e-6,
            args.seed,
        )),
    };
    let (mut target, amplitude, model): (Target, f64, ModelResponse) = match args.mode {
        Mode::OpenLoop => (
            Target::OpenLoop,
            args.amplitude.unwrap_or(0.02),
            Box::new(move |f| plant_model.discrete(period_s).response(f, period_s)),
        ),
        Mode::ClosedLoop => {
            let settings = settings
                .as_ref()
                .context("--mode closed-loop needs --controller FILE")?;
            let controller = settings.build()?;
            let nominal = settings.nominal_loop(controller.axis());
            (
                Target::ClosedLoop(Box::new(controller)),
                args.amplitude.unwrap_or(0.1) * 1e-3,
                Box::new(move |f| nominal.complementary(f)),
            )
        }
    };
    let frequencies_hz = SteppedSine::log_frequencies(args.from_hz, args.to_hz, args.points);
    let (points, plan) = match args.excitation {
        Excitation::Stepped => {
            let plan = SteppedSine {
                axis: args.axis,
                frequencies_hz,
                amplitude,
                settle_s: args.settle_s,
                cycles_per_block: args.cycles,
                blocks: args.blocks,
            };
            (
                identify(link.as_mut(), &plan, &mut target)?,
                serde_json::to_value(&plan)?,
            )
        }
        Excitation::Swept => {
            let plan = SweptSinePlan {
                axis: args.axis,
                start_hz: args.from_hz,
                stop_hz: args.to_hz,
                sweep_s: args.sweep_s,
                quiet_s: args.quiet_s,
                sweeps: args.blocks,
                amplitude,
                frequencies_hz,
            };
            (
                identify_swept(link.as_mut(), &plan, &mut target)?,
                serde_json::to_value(&plan)?,
            )
        }
    };
    let coils_at_end = link.end();
    let rows: Vec<serde_json::Value> = points
        .iter()
        .map(|p| {
            let m = model(p.f_hz);
            serde_json::json!({
                "measured": p,
                "model_magnitude_db": 20.0 * m.norm().log10(),
                "model_phase_deg": m.arg().to_degrees(),
                "magnitude_error_db": p.magnitude_db - 20.0 * m.norm().log10(),
                "phase_error_deg": wrap_deg(p.phase_deg - m.arg().to_degrees()),
            })
        })
        .collect();
    // Closed loop: the loop's figures from the measured T beside the model's on the same grid.
    let loop_figures = (args.mode == Mode::ClosedLoop).then(|| {
        let measured: Vec<(f64, Complex<f64>)> = points
            .iter()
            .map(|p| {
                (
                    p.f_hz,
                    Complex::from_polar(p.magnitude, p.phase_deg.to_radians()),
                )
            })
            .collect();
        let modelled: Vec<(f64, Complex<f64>)> =
            points.iter().map(|p| (p.f_hz, model(p.f_hz))).collect();
        serde_json::json!({
            "measured": closed_loop_figures(&measured),
            "model": closed_loop_figures(&modelled),
        })
    });
    let json = serde_json::json!({
        "plant": args
            .fsm
            .clone()
            .unwrap_or_else(|| format!("{:?}", args.plant).to_lowercase()),
        "mode": format!("{:?}", args.mode),
        "controller": args.controller.as_ref().map(|p| p.display().to_string()),
        "plan": plan,
        "noise_urad_rms": args.noise_urad,
        "seed": args.seed,
        "model": if args.mode == Mode::OpenLoop { "z^-1 ZOH(eq. 4)" } else { "nominal T = CP/(1+CP)" },
        "points": rows,
        "loop": loop_figures,
        "coils_at_end": coils_at_end,
    });
    let text = serde_json::to_string_pretty(&json)?;
    match &args.out {
        Some(path) => {
            std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?
        }
        None => scanhil_protocol::outln!("{text}")?,
    }
    if let Some(path) = &args.plot {
        plot(path, &points, &*model).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}

fn wrap_deg(d: f64) -> f64 {
    (d + 180.0).rem_euclid(360.0) - 180.0
}

fn plot(
    path: &std::path::Path,
    points: &[ResponsePoint],
    model: &dyn Fn(f64) -> Complex<f64>,
) -> anyhow::Result<()> {
    let series = |label: &str, pts: Vec<(f64, f64)>, markers| Series {
        label: label.into(),
        points: pts,
        markers,
    };
    let panel = |title: &str, y_label: &str, y_axis, series| Chart {
        title: title.into(),
        x_label: "frequency [Hz]".into(),
        y_label: y_label.into(),
        x_axis: Axis::Log,
        y_axis,
        series,
    };
    let m: Vec<(f64, Complex<f64>)> = points.iter().map(|p| (p.f_hz, model(p.f_hz))).collect();
    draw_charts(
        path,
        &[
            panel(
                "magnitude",
                "|H| [dB]",
                Axis::Linear,
                vec![
                    series(
                        "measured",
                        points.iter().map(|p| (p.f_hz, p.magnitude_db)).collect(),
                        true,
                    ),
                    series(
                        "model",
                        m.iter()
                            .map(|(f, h)| (*f, 20.0 * h.norm().log10()))
                            .collect(),
                        false,
                    ),
                    series(
                        "cross axis",
                        points.iter().map(|p| (p.f_hz, p.cross_axis_db)).collect(),
                        true,
                    ),
                ],
            ),
            panel(
                "phase",
                "arg H [deg]",
                Axis::Linear,
                vec![
                    series(
                        "measured",
                        points.iter().map(|p| (p.f_hz, p.phase_deg)).collect(),
                        true,
                    ),
                    series(
                        "model",
                        m.iter().map(|(f, h)| (*f, h.arg().to_degrees())).collect(),
                        false,
                    ),
                ],
            ),
            panel(
                "coherence",
                "gamma^2",
                Axis::Linear,
                vec![series(
                    "coherence",
                    points.iter().map(|p| (p.f_hz, p.coherence)).collect(),
                    true,
                )],
            ),
        ],
    )?;
    Ok(())
}
