//! `scanhil identify`: a system analyser on the sensing axes, of the open-loop plant (the
//! paper's Fig. 4) or of the closed loop (Fig. 8, 9), with coherence; JSON and a Bode plot
//! beside the nominal model. `--fit` fits eq. 4 (or a richer model) to each axis and the
//! cross-talk between them, and writes the bench's twin (`--write-scene`, `--write-rig`);
//! `--record DIR` keeps the run, `--from DIR` analyses a kept run again without the device.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use nalgebra::Complex;
use scanhil_controller::closed_loop_figures::closed_loop_figures;
use scanhil_controller::fit::models::{ModelParams, SampledModel};
use scanhil_controller::fit::{AxisFit, CrossTalkFit, Measured, fit_axis, fit_cross_talk, twin};
use scanhil_controller::identify::{
    Plan, ResponsePoint, SteppedSine, SweptSinePlan, Target, identify_plans,
};
use scanhil_controller::identify_recording::{RECORDING, RESULT, RecordedPeriods};
use scanhil_controller::link::{NominalPlantLink, PlantLink};
use scanhil_controller::run::plant_link::LinkedPlant;
use scanhil_controller::run::scenario::NodeLink;
use scanhil_controller::settings::ControllerSettings;
use scanhil_controller::trajectory::SensingAxis;
use scanhil_protocol::message::RAD_PER_COUNT;
use scanhil_protocol::plant_units::RAD_PER_OUTPUT_UNIT;
use scanhil_report::{Axis, Chart, Series, draw_charts};
use scanhil_scene::json_file;
use serde_json::{Value, json};

/// One Bode panel of the fit plot: its title, its y label, and the measured point's and a
/// response's value in it.
type BodePanel = (
    String,
    &'static str,
    fn(&ResponsePoint) -> f64,
    fn(Complex<f64>) -> f64,
);

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

/// The excited axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum AxisChoice {
    /// The alpha axis.
    Alpha,
    /// The beta axis.
    Beta,
    /// Alpha, then beta.
    Both,
}

/// Arguments of `scanhil identify`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The plant to excite.
    #[arg(long, value_enum, default_value = "nominal")]
    plant: PlantChoice,
    /// Excite a mirror node on a real link instead of --plant: `pty` (the emulator on a pty
    /// pair, serving --scene), `slcan:PATH[@BITRATE]` or `socketcan:IFACE`.
    #[arg(long, conflicts_with = "from")]
    fsm: Option<String>,
    /// The scene the emulator serves with `--fsm pty` (also the base of --write-scene).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Open or closed loop.
    #[arg(long, value_enum, default_value = "open-loop")]
    mode: Mode,
    /// Controller settings for --mode closed-loop (also sets the control rate).
    #[arg(long)]
    controller: Option<PathBuf>,
    /// The excited sensing axis, or both one after the other (default: both with --fit,
    /// alpha otherwise).
    #[arg(long, value_enum)]
    axis: Option<AxisChoice>,
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
    /// Control rate when no controller is given, Hz (default: the --scene's, else 20 kHz).
    #[arg(long, allow_negative_numbers = true)]
    rate_hz: Option<f64>,
    /// Write the JSON result here (it is printed otherwise).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write the Bode plot (measured and model, magnitude, phase, coherence; with --fit the
    /// fit and the residual), .svg or .png.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Fit each open-loop axis (eq. 4, or a richer model by BIC) and the cross-talk.
    #[arg(long)]
    fit: bool,
    /// Keep the run in this folder: every frame on the mirror's link (`fsm.log`) and the
    /// result (`identify.json`), for `--from` (needs --fsm).
    #[arg(long)]
    record: Option<PathBuf>,
    /// Analyse a run kept with --record again, without the device.
    #[arg(long)]
    from: Option<PathBuf>,
    /// With --fit: write the fitted plant as a scene (--scene's, with its plant sections
    /// replaced, or a new one).
    #[arg(long, requires = "fit")]
    write_scene: Option<PathBuf>,
    /// With --fit: write --rig with its mirror section's cross-talk (and its rate) as fitted.
    #[arg(long, requires_all = ["fit", "rig"])]
    write_rig: Option<PathBuf>,
    /// The rig --write-rig starts from.
    #[arg(long)]
    rig: Option<PathBuf>,
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
    anyhow::ensure!(
        args.record.is_none() || args.fsm.is_some(),
        "--record keeps the frames of a link: give --fsm"
    );
    anyhow::ensure!(
        !args.fit || args.mode == Mode::OpenLoop,
        "--fit fits the open-loop plant: --mode open-loop"
    );
    let settings = args
        .controller
        .as_ref()
        .map(|p| ControllerSettings::load(p))
        .transpose()?;
    let plant_model = settings.as_ref().map(|s| s.plant).unwrap_or_default();
    let Measurement {
        period_s,
        plans,
        points: measured,
        coils_at_end,
    } = match &args.from {
        Some(dir) => from_recording(dir)?,
        None => measure(&args, settings.as_ref(), &plant_model)?,
    };
    let model: ModelResponse = match (args.mode, &settings) {
        (Mode::ClosedLoop, Some(settings)) => {
            let controller = settings.build()?;
            let nominal = settings.nominal_loop(controller.axis());
            Box::new(move |f| nominal.complementary(f))
        }
        _ => Box::new(move |f| plant_model.discrete(period_s).response(f, period_s)),
    };
    let axes: Vec<Value> = plans
        .iter()
        .zip(&measured)
        .map(|(plan, points)| json!({ "axis": plan.axis(), "points": rows(points, &*model) }))
        .collect();
    // Over a link (or from its recording) the angles come in AngleReading's 1 urad steps.
    let reading_step = if args.fsm.is_some() || args.from.is_some() {
        RAD_PER_COUNT / RAD_PER_OUTPUT_UNIT
    } else {
        0.0
    };
    let fit = args
        .fit
        .then(|| fit_all(&plans, &measured, period_s, reading_step))
        .transpose()?;
    // Closed loop: the loop's figures from the measured T beside the model's on the same grid
    // (the first excited axis').
    let loop_figures = (args.mode == Mode::ClosedLoop)
        .then(|| measured.first())
        .flatten()
        .map(|points| {
            let measured: Vec<(f64, Complex<f64>)> =
                points.iter().map(|p| (p.f_hz, p.response())).collect();
            let modelled: Vec<(f64, Complex<f64>)> =
                points.iter().map(|p| (p.f_hz, model(p.f_hz))).collect();
            json!({
                "measured": closed_loop_figures(&measured),
                "model": closed_loop_figures(&modelled),
            })
        });
    let mut json = json!({
        "plant": args.from.as_ref().map_or_else(
            || args.fsm.clone().unwrap_or_else(|| format!("{:?}", args.plant).to_lowercase()),
            |dir| format!("recording {}", dir.display()),
        ),
        "mode": format!("{:?}", args.mode),
        "controller": args.controller.as_ref().map(|p| p.display().to_string()),
        "rate_hz": 1.0 / period_s,
        "plans": plans,
        "plan": plans.first(),
        "noise_urad_rms": args.noise_urad,
        "seed": args.seed,
        "model": if args.mode == Mode::OpenLoop { "z^-1 ZOH(eq. 4)" } else { "nominal T = CP/(1+CP)" },
        "axes": axes,
        "points": axes.first().map(|a| a["points"].clone()),
        "loop": loop_figures,
        "coils_at_end": coils_at_end,
    });
    if let Some((fits, cross_talk)) = &fit {
        json["fit"] = json!({ "axes": fits, "cross_talk": cross_talk });
        json["written"] = write_twin(&args, period_s, fits, cross_talk)?;
    }
    let text = serde_json::to_string_pretty(&json)?;
    if let Some(dir) = &args.record {
        let path = dir.join(RESULT);
        std::fs::write(&path, &text).with_context(|| format!("writing {}", path.display()))?;
    }
    match &args.out {
        Some(path) => {
            std::fs::write(path, &text).with_context(|| format!("writing {}", path.display()))?
        }
        None => scanhil_protocol::outln!("{text}")?,
    }
    if let Some((fits, cross_talk)) = &fit {
        let summary = summary(fits, cross_talk);
        if args.out.is_some() {
            scanhil_protocol::outln!("{summary}")?;
        } else {
            eprintln!("{summary}");
        }
    }
    if let Some(path) = &args.plot {
        match &fit {
            Some((fits, _)) => plot_fit(path, &measured, fits, period_s),
            None => plot(path, &measured[0], &*model),
        }
        .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// The plans of the command line.
fn plans(args: &Args, amplitude: f64) -> Vec<Plan> {
    let axes = match args.axis {
        Some(AxisChoice::Alpha) => vec![SensingAxis::Alpha],
        Some(AxisChoice::Beta) => vec![SensingAxis::Beta],
        Some(AxisChoice::Both) => SensingAxis::BOTH.to_vec(),
        None if args.fit => SensingAxis::BOTH.to_vec(),
        None => vec![SensingAxis::Alpha],
    };
    let frequencies_hz = SteppedSine::log_frequencies(args.from_hz, args.to_hz, args.points);
    let plan = match args.excitation {
        Excitation::Stepped => Plan::Stepped(SteppedSine {
            axis: SensingAxis::Alpha,
            frequencies_hz,
            amplitude,
            settle_s: args.settle_s,
            cycles_per_block: args.cycles,
            blocks: args.blocks,
        }),
        Excitation::Swept => Plan::Swept(SweptSinePlan {
            axis: SensingAxis::Alpha,
            start_hz: args.from_hz,
            stop_hz: args.to_hz,
            sweep_s: args.sweep_s,
            quiet_s: args.quiet_s,
            sweeps: args.blocks,
            amplitude,
            frequencies_hz,
        }),
    };
    axes.into_iter().map(|axis| plan.on_axis(axis)).collect()
}

/// The control period: the controller's, `--rate-hz`, the scene's, or 20 kHz.
fn period_s(args: &Args, settings: Option<&ControllerSettings>) -> anyhow::Result<f64> {
    if let Some(settings) = settings {
        return Ok(settings.period_s());
    }
    let rate_hz = match (args.rate_hz, &args.scene) {
        (Some(rate), _) => rate,
        (None, Some(scene)) => read_json(scene, "scene")?
            .get("control_rate_hz")
            .and_then(Value::as_f64)
            .unwrap_or(20_000.0),
        (None, None) => 20_000.0,
    };
    anyhow::ensure!(
        rate_hz.is_finite() && rate_hz > 0.0,
        "--rate-hz {rate_hz}: must be positive and finite"
    );
    Ok(1.0 / rate_hz)
}

/// What was measured, live or from a recording.
struct Measurement {
    /// The control period, s.
    period_s: f64,
    /// The plans, in the order they ran.
    plans: Vec<Plan>,
    /// Each plan's points.
    points: Vec<Vec<ResponsePoint>>,
    /// How the coils ended (null from a recording).
    coils_at_end: Value,
}

/// Measures through the nominal plant or a link; each plan's points and how the coils ended.
fn measure(
    args: &Args,
    settings: Option<&ControllerSettings>,
    plant_model: &scanhil_controller::plant_model::PlantModel,
) -> anyhow::Result<Measurement> {
    let period_s = period_s(args, settings)?;
    anyhow::ensure!(
        args.to_hz < 0.5 / period_s,
        "--to-hz must be below Nyquist ({} Hz)",
        0.5 / period_s
    );
    let (mut target, amplitude) = match args.mode {
        Mode::OpenLoop => (Target::OpenLoop, args.amplitude.unwrap_or(0.02)),
        Mode::ClosedLoop => {
            let settings = settings.context("--mode closed-loop needs --controller FILE")?;
            (
                Target::ClosedLoop(Box::new(settings.build()?)),
                args.amplitude.unwrap_or(0.1) * 1e-3,
            )
        }
    };
    let plans = plans(args, amplitude);
    if let Some(dir) = &args.record {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let (points, coils_at_end) = match &args.fsm {
        Some(fsm) => {
            let mut link = LinkedPlant::connect(
                &NodeLink::parse(fsm),
                args.scene.as_deref(),
                None,
                period_s,
                args.record.as_deref(),
            )?;
            let points = identify_plans(&mut link, &plans, &mut target);
            let coils_at_end = link.end();
            let failures = link.finish();
            let points = points?;
            anyhow::ensure!(
                failures.is_empty(),
                "the recording is incomplete: {}",
                failures.join("; ")
            );
            (points, json!(coils_at_end))
        }
        None => {
            let mut link =
                NominalPlantLink::new(plant_model, period_s, args.noise_urad * 1e-6, args.seed);
            let points = identify_plans(&mut link, &plans, &mut target)?;
            (points, json!(link.end()))
        }
    };
    Ok(Measurement {
        period_s,
        plans,
        points,
        coils_at_end,
    })
}

/// The period, plans and points of a kept run (`DIR/identify.json`, `DIR/fsm.log`).
fn from_recording(dir: &Path) -> anyhow::Result<Measurement> {
    let result_path = dir.join(RESULT);
    let result = read_json(&result_path, "identification")?;
    let field = |name: &str| {
        result
            .get(name)
            .with_context(|| format!("{}: no field `{name}`", result_path.display()))
    };
    anyhow::ensure!(
        field("mode")?.as_str() == Some("OpenLoop"),
        "{}: only an open-loop run can be analysed again (a closed loop's reference is not on \
         the wire)",
        result_path.display()
    );
    let rate_hz = field("rate_hz")?
        .as_f64()
        .filter(|r| r.is_finite() && *r > 0.0)
        .with_context(|| format!("{}: field `rate_hz` is not a rate", result_path.display()))?;
    let plans: Vec<Plan> = serde_json::from_value(field("plans")?.clone())
        .with_context(|| format!("{}: field `plans`", result_path.display()))?;
    let recording = dir.join(RECORDING);
    let points = RecordedPeriods::read(&recording)?.analyse(
        &plans,
        1.0 / rate_hz,
        &recording.display().to_string(),
    )?;
    Ok(Measurement {
        period_s: 1.0 / rate_hz,
        plans,
        points,
        coils_at_end: Value::Null,
    })
}

fn read_json(path: &Path, what: &'static str) -> anyhow::Result<Value> {
    let text = json_file::read_text(path, what)?;
    Ok(json_file::parse(&text, path)?)
}

/// One axis' points beside the model.
fn rows(points: &[ResponsePoint], model: &dyn Fn(f64) -> Complex<f64>) -> Vec<Value> {
    points
        .iter()
        .map(|p| {
            let m = model(p.f_hz);
            json!({
                "measured": p,
                "model_magnitude_db": 20.0 * m.norm().log10(),
                "model_phase_deg": m.arg().to_degrees(),
                "magnitude_error_db": p.magnitude_db - 20.0 * m.norm().log10(),
                "phase_error_deg": wrap_deg(p.phase_deg - m.arg().to_degrees()),
            })
        })
        .collect()
}

/// Each axis' fit, and the cross-talk of each excitation onto the other axis (when both were
/// measured); `reading_step` is the angle readings' resolution in output units (0 in
/// process).
fn fit_all(
    plans: &[Plan],
    measured: &[Vec<ResponsePoint>],
    period_s: f64,
    reading_step: f64,
) -> anyhow::Result<(Vec<AxisFit>, Vec<CrossTalkFit>)> {
    let as_measured = |plan: &Plan, p: &ResponsePoint, cross: bool| Measured {
        f_hz: p.f_hz,
        response: if cross {
            p.cross_response()
        } else {
            p.response()
        },
        coherence: if cross {
            p.cross_axis_coherence
        } else {
            p.coherence
        },
        blocks: plan.blocks(),
        resolution: Measured::resolution_of(reading_step, p.samples_per_block, p.excitation_dft),
    };
    let fits = plans
        .iter()
        .zip(measured)
        .map(|(plan, points)| {
            let direct: Vec<Measured> =
                points.iter().map(|p| as_measured(plan, p, false)).collect();
            fit_axis(plan.axis(), &direct, period_s)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut cross_talk = Vec::new();
    for (plan, points) in plans.iter().zip(measured) {
        let Some(other) = fits.iter().find(|f| f.axis == plan.axis().other()) else {
            continue;
        };
        let cross: Vec<Measured> = points.iter().map(|p| as_measured(plan, p, true)).collect();
        cross_talk.extend(fit_cross_talk(plan.axis(), &cross, other));
    }
    Ok((fits, cross_talk))
}

/// Writes --write-scene and --write-rig; what was written, and the decisions made.
fn write_twin(
    args: &Args,
    period_s: f64,
    fits: &[AxisFit],
    cross_talk: &[CrossTalkFit],
) -> anyhow::Result<Value> {
    let mut written = json!({});
    if let Some(path) = &args.write_scene {
        let base = args
            .scene
            .as_ref()
            .map(|p| read_json(p, "scene"))
            .transpose()?;
        let name = path
            .file_stem()
            .map_or("fitted".into(), |s| s.to_string_lossy().into_owned());
        let (scene, notes) = twin::scene(base.as_ref(), &name, 1.0 / period_s, fits, cross_talk);
        write_json(path, &scene)?;
        written["scene"] = json!({ "file": path.display().to_string(), "notes": notes.notes });
    }
    if let (Some(path), Some(rig)) = (&args.write_rig, &args.rig) {
        let rig = twin::rig(&read_json(rig, "rig")?, 1.0 / period_s, cross_talk);
        write_json(path, &rig)?;
        written["rig"] = json!(path.display().to_string());
    }
    Ok(written)
}

fn write_json(path: &Path, value: &Value) -> anyhow::Result<()> {
    std::fs::write(path, serde_json::to_string_pretty(value)? + "\n")
        .with_context(|| format!("writing {}", path.display()))
}

/// The fit in a few lines.
fn summary(fits: &[AxisFit], cross_talk: &[CrossTalkFit]) -> String {
    let mut lines = Vec::new();
    for fit in fits {
        let estimates: Vec<String> = fit
            .estimates
            .iter()
            .map(|e| {
                format!(
                    "{} {:.6e} +- {:.1e}{}",
                    e.name,
                    e.value,
                    e.std,
                    unit(e.unit)
                )
            })
            .collect();
        let worst = fit
            .residuals
            .iter()
            .max_by(|a, b| a.normalised.total_cmp(&b.normalised));
        let rms = (fit
            .residuals
            .iter()
            .map(|r| r.normalised.powi(2))
            .sum::<f64>()
            / fit.residuals.len().max(1) as f64)
            .sqrt();
        lines.push(format!(
            "fit {}: {:?}: {}; residual rms {rms:.2} sigma{}",
            fit.axis.name(),
            fit.chosen,
            estimates.join(", "),
            worst.map_or(String::new(), |w| format!(
                ", largest {:.2} sigma at {:.1} Hz ({:+.3} dB, {:+.2} deg)",
                w.normalised, w.f_hz, w.error_db, w.error_deg
            ))
        ));
        lines.push(format!("  {}", fit.selection));
    }
    for c in cross_talk {
        lines.push(format!(
            "cross-talk {} from {}: {:.5} +- {:.1e} ({:.2} dB; quadrature {:.1e})",
            c.to.name(),
            c.from.name(),
            c.coefficient,
            c.std,
            c.level_db,
            c.quadrature
        ));
    }
    lines.join("\n")
}

fn unit(unit: &str) -> String {
    if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    }
}

fn wrap_deg(d: f64) -> f64 {
    (d + 180.0).rem_euclid(360.0) - 180.0
}

fn series(label: &str, points: Vec<(f64, f64)>, markers: bool) -> Series {
    Series {
        label: label.into(),
        points,
        markers,
    }
}

fn panel(title: &str, y_label: &str, series: Vec<Series>) -> Chart {
    Chart {
        title: title.into(),
        x_label: "frequency [Hz]".into(),
        y_label: y_label.into(),
        x_axis: Axis::Log,
        y_axis: Axis::Linear,
        series,
    }
}

fn plot(
    path: &Path,
    points: &[ResponsePoint],
    model: &dyn Fn(f64) -> Complex<f64>,
) -> anyhow::Result<()> {
    let m: Vec<(f64, Complex<f64>)> = points.iter().map(|p| (p.f_hz, model(p.f_hz))).collect();
    draw_charts(
        path,
        &[
            panel(
                "magnitude",
                "|H| [dB]",
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

/// Per axis: magnitude and phase of the data, the fit and eq. 4 as printed (on a fine grid),
/// then both axes' residuals in standard uncertainties (in dB a reading below the angle
/// resolution, quantised to zero, would be -inf: the uncertainty says what it weighs).
fn plot_fit(
    path: &Path,
    measured: &[Vec<ResponsePoint>],
    fits: &[AxisFit],
    period_s: f64,
) -> anyhow::Result<()> {
    let nominal = ModelParams::paper(period_s).sampled(period_s);
    let mut charts = Vec::new();
    let mut residuals = Vec::new();
    for (points, fit) in measured.iter().zip(fits) {
        let (Some(first), Some(last)) = (points.first(), points.last()) else {
            continue;
        };
        let grid = SteppedSine::log_frequencies(first.f_hz, last.f_hz, 400);
        let fitted = fit.params.sampled(period_s);
        let curve = |model: &SampledModel, f: fn(Complex<f64>) -> f64| {
            grid.iter()
                .map(|&hz| (hz, f(model.response(hz))))
                .collect::<Vec<_>>()
        };
        let name = fit.axis.name();
        let panels: [BodePanel; 2] = [
            (
                format!("{name}: magnitude ({:?} fitted)", fit.chosen),
                "|H| [dB]",
                |p| p.magnitude_db,
                |h| 20.0 * h.norm().log10(),
            ),
            (
                format!("{name}: phase"),
                "arg H [deg]",
                |p| p.phase_deg,
                |h| h.arg().to_degrees(),
            ),
        ];
        for (title, y_label, of_point, of_model) in panels {
            charts.push(panel(
                &title,
                y_label,
                vec![
                    series(
                        "measured",
                        points.iter().map(|p| (p.f_hz, of_point(p))).collect(),
                        true,
                    ),
                    series("fit", curve(&fitted, of_model), false),
                    series("eq. 4 as printed", curve(&nominal, of_model), false),
                ],
            ));
        }
        residuals.push(series(
            name,
            fit.residuals
                .iter()
                .map(|r| (r.f_hz, r.normalised))
                .collect(),
            true,
        ));
    }
    charts.push(panel(
        "residual: |measured - fit| / its standard uncertainty",
        "sigma",
        residuals,
    ));
    draw_charts(path, &charts)?;
    Ok(())
}
