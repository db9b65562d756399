//! `scanhil design`: a controller designed for a plant and the rate a rig (or its bus) runs
//! at, checked against stated margins, written as a controller file; exit 1 with the poles
//! when the rule gives no design that keeps them.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use scanhil_controller::design::alpha_tuning::AlphaTuning;
use scanhil_controller::design::reach::{pid_reach, tone_reach};
use scanhil_controller::design::tones::ToneRule;
use scanhil_controller::design::{Design, DesignError, DesignRequest, Margins, Rule};
use scanhil_controller::discretise::Method;
use scanhil_controller::plant_source::PlantSource;
use scanhil_controller::rig::Rig;
use scanhil_controller::run::bus_load::max_control_rate_hz;
use scanhil_controller::run::scenario::TimingMode;
use scanhil_controller::trajectory::Trajectory;
use scanhil_protocol::bus_load::Bitrates;
use scanhil_protocol::plant_units::FULL_RANGE_DEG;

/// The design rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    /// The paper's alpha-tuned series PID (Table II's rule).
    Pid,
    /// Resonant tones at the trajectory's drive frequencies on the equalised plant (eq. 5's
    /// form).
    DualTone,
}

/// The discretisation methods on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum MethodArg {
    /// Bilinear.
    Tustin,
    /// Bilinear, exact at --prewarp-hz (default: the drive frequencies).
    TustinPrewarped,
    /// Zero-order hold.
    ZeroOrderHold,
    /// Matched pole-zero.
    MatchedPoleZero,
    /// Forward Euler (refused where it is unstable).
    ForwardEuler,
    /// Backward Euler.
    BackwardEuler,
}

/// Arguments of `scanhil design`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The rig: its control rate (the default rate), its bus (`--rate-hz bus`, the bus's
    /// transit as delay).
    #[arg(long)]
    rig: PathBuf,
    /// The plant: a scene file, or a controller file (its nominal plant); default eq. 4 as
    /// printed.
    #[arg(long)]
    plant: Option<PathBuf>,
    /// The plant's axis to design for when the two differ.
    #[arg(long, value_enum, default_value = "alpha")]
    axis: scanhil_controller::trajectory::SensingAxis,
    /// The control rate, Hz, or `bus`: the highest rate the rig's bus carries (the bus
    /// budget's lockstep figure). Default: the rig's control rate.
    #[arg(long)]
    rate_hz: Option<String>,
    /// The design rule.
    #[arg(long, value_enum)]
    kind: Kind,
    /// The trajectory (a trajectory JSON, or a scenario whose `trajectory` is taken); default
    /// the paper's Lissajous 52/27 Hz at full range.
    #[arg(long, conflicts_with = "lissajous")]
    trajectory: Option<PathBuf>,
    /// A full-range Lissajous ALPHA_HZ,BETA_HZ instead of --trajectory.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    lissajous: Option<Vec<f64>>,
    /// The discretisation (default: tustin-prewarped at the drive frequencies for a dual-tone,
    /// tustin for a PID).
    #[arg(long, value_enum)]
    method: Option<MethodArg>,
    /// Prewarp frequencies for --method tustin-prewarped, Hz (default: the drive frequencies).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    prewarp_hz: Option<Vec<f64>>,
    /// The smallest phase margin a design must keep, degrees.
    #[arg(long, default_value_t = Margins::default().phase_deg, allow_negative_numbers = true)]
    phase_margin_deg: f64,
    /// The smallest gain margin a design must keep, dB.
    #[arg(long, default_value_t = Margins::default().gain_db, allow_negative_numbers = true)]
    gain_margin_db: f64,
    /// PID: the crossover, Hz (default: the highest that keeps the margins).
    #[arg(long, allow_negative_numbers = true)]
    crossover_hz: Option<f64>,
    /// PID: alpha (the lead's ratio).
    #[arg(long, default_value_t = 3.0, allow_negative_numbers = true)]
    alpha: f64,
    /// PID: the integrator's corner is the crossover over this.
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
    integrator_ratio: f64,
    /// PID: the derivative stops at this times alpha times the crossover (Table II: 1.1).
    #[arg(long, default_value_t = 1.1, allow_negative_numbers = true)]
    taming: f64,
    /// Dual-tone: each tone's width, Hz (its error decays as exp(-2 pi width t)).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    tone_width_hz: f64,
    /// Dual-tone: the tones' damping (Table I: 1e-4; 0 is a pure internal model).
    #[arg(long, default_value_t = 1e-4, allow_negative_numbers = true)]
    tone_damping: f64,
    /// Dual-tone: the roll-off pair's frequency, Hz (default: the rate / 8).
    #[arg(long, allow_negative_numbers = true)]
    rolloff_hz: Option<f64>,
    /// The coil current limit written into the controller, A.
    #[arg(long, default_value_t = 6.0, allow_negative_numbers = true)]
    coil_current_limit_a: f64,
    /// The controller's name (default: from the kind and the rate).
    #[arg(long)]
    name: Option<String>,
    /// Write the controller file here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print the design as JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// Runs `scanhil design`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let rig = Rig::load(&args.rig)?;
    let (rate_hz, rate_source) = rate(&args, &rig)?;
    let source = match &args.plant {
        Some(path) => PlantSource::load(path)?,
        None => PlantSource::paper(),
    };
    let mut plant = source.axis(args.axis);
    let transit_s = rig.bus.map_or(0.0, |bus| bus.transit_s);
    plant.extra_delay_s += transit_s;
    let trajectory = trajectory(&args)?;
    let mut request = DesignRequest {
        name: String::new(),
        plant,
        rate_hz,
        method: Method::Tustin,
        margins: Margins {
            phase_deg: args.phase_margin_deg,
            gain_db: args.gain_margin_db,
        },
        trajectory: Some(trajectory),
        coil_current_limit_a: args.coil_current_limit_a,
    };
    check_option("--coil-current-limit-a", args.coil_current_limit_a)?;
    let drive_hz = request.drive_hz();
    request.method = method(&args, args.kind, &drive_hz);
    request.name = args.name.clone().unwrap_or_else(|| {
        format!(
            "{} at {rate_hz} Hz",
            match args.kind {
                Kind::Pid => "alpha-tuned PID",
                Kind::DualTone => "dual-tone",
            }
        )
    });
    let pid_template = AlphaTuning {
        crossover_hz: args.crossover_hz.unwrap_or(f64::NAN),
        alpha: args.alpha,
        integrator_ratio: args.integrator_ratio,
        taming: args.taming,
    };
    let tone_template = ToneRule {
        tones_hz: drive_hz.clone(),
        width_hz: args.tone_width_hz,
        damping: args.tone_damping,
        rolloff_hz: args
            .rolloff_hz
            .unwrap_or_else(|| ToneRule::default_rolloff_hz(rate_hz)),
    };
    let result = match (args.kind, args.crossover_hz) {
        (Kind::Pid, Some(_)) => request.design(&Rule::AlphaTuning(pid_template)),
        (Kind::Pid, None) => request.highest_pid(&pid_template),
        (Kind::DualTone, _) => request.design(&Rule::DualTone(tone_template.clone())),
    };
    // Each rule's reach with its own discretisation (the one asked for the kind designed).
    let with_method = |kind| DesignRequest {
        method: method(&args, kind, &drive_hz),
        ..request.clone()
    };
    let reach = serde_json::json!({
        "track_to_rms_relative": scanhil_controller::design::reach::TRACK_TO,
        "pid": pid_reach(&with_method(Kind::Pid), &pid_template),
        "dual_tone": tone_reach(&with_method(Kind::DualTone), &tone_template),
    });
    let header = serde_json::json!({
        "rig": rig.path.display().to_string(),
        "rate_hz": rate_hz,
        "rate_source": rate_source,
        "bus_transit_s": transit_s,
        "plant_source": source.describe(),
        "axis": args.axis,
        "plant": request.plant,
        "method": request.method.name(),
        "margins": request.margins,
        "trajectory": request.trajectory,
    });
    match result {
        Ok(design) => {
            if let Some(out) = &args.out {
                let text = serde_json::to_string_pretty(&design.settings)?;
                std::fs::write(out, text + "\n")
                    .with_context(|| format!("writing {}", out.display()))?;
            }
            if args.json {
                let json = serde_json::json!({
                    "design": header,
                    "rule": design.rule,
                    "controller": design.settings,
                    "figures": design.figures,
                    "reach": reach,
                    "written": args.out.as_ref().map(|p| p.display().to_string()),
                });
                scanhil_protocol::outln!("{}", serde_json::to_string_pretty(&json)?)?;
            } else {
                print_design(&header, &design, &reach, args.out.as_deref())?;
            }
            Ok(ExitCode::SUCCESS)
        }
        Err(error @ DesignError::Refused { .. }) => {
            if args.json {
                let json = serde_json::json!({
                    "design": header,
                    "refused": error.to_string(),
                    "reach": reach,
                });
                scanhil_protocol::outln!("{}", serde_json::to_string_pretty(&json)?)?;
            } else {
                print_header(&header)?;
                print_reach(&reach, rate_hz)?;
            }
            eprintln!("scanhil: design {error}");
            Ok(ExitCode::FAILURE)
        }
        Err(error) => Err(error.into()),
    }
}

/// The rate and where it came from.
fn rate(args: &Args, rig: &Rig) -> anyhow::Result<(f64, String)> {
    match args.rate_hz.as_deref() {
        None => Ok((
            rig.control_rate_hz,
            format!("the rig's control rate ({})", rig.path.display()),
        )),
        Some("bus") => {
            let bus = rig.bus.with_context(|| {
                format!(
                    "--rate-hz bus: rig {} states no `bus` (bitrate_bps)",
                    rig.path.display()
                )
            })?;
            let rates = Bitrates {
                nominal_bps: bus.bitrate_bps,
                data_bps: bus.bitrate_bps,
            };
            let max = max_control_rate_hz(TimingMode::Lockstep, rates, 0.0).floor();
            anyhow::ensure!(
                max > 0.0,
                "--rate-hz bus: no loop fits {} bit/s",
                bus.bitrate_bps
            );
            Ok((
                max,
                format!(
                    "the highest lockstep loop rate {} bit/s carries (bus budget, 100 %)",
                    bus.bitrate_bps
                ),
            ))
        }
        Some(text) => {
            let rate: f64 = text
                .parse()
                .ok()
                .filter(|r: &f64| r.is_finite() && *r > 0.0)
                .with_context(|| format!("--rate-hz {text}: a positive number of Hz, or `bus`"))?;
            Ok((rate, "--rate-hz".into()))
        }
    }
}

fn check_option(flag: &str, value: f64) -> anyhow::Result<()> {
    anyhow::ensure!(
        value.is_finite() && value > 0.0,
        "{flag} {value}: must be positive and finite"
    );
    Ok(())
}

/// The trajectory asked for (default: the paper's Lissajous).
fn trajectory(args: &Args) -> anyhow::Result<Trajectory> {
    let full = FULL_RANGE_DEG.to_radians();
    let lissajous = |alpha_hz: f64, beta_hz: f64| Trajectory::Lissajous {
        alpha_hz,
        beta_hz,
        alpha_amplitude_rad: full,
        beta_amplitude_rad: full,
        relative_phase_rad: 0.0,
    };
    if let Some(f) = &args.lissajous {
        anyhow::ensure!(
            f.len() == 2,
            "--lissajous takes two comma-separated numbers, got {f:?}"
        );
        return Ok(lissajous(f[0], f[1]));
    }
    let Some(path) = &args.trajectory else {
        return Ok(lissajous(52.0, 27.0));
    };
    read_trajectory(path)
}

/// A trajectory JSON, or the `trajectory` of a scenario.
fn read_trajectory(path: &Path) -> anyhow::Result<Trajectory> {
    let text = scanhil_scene::json_file::read_text(path, "trajectory")?;
    let value: serde_json::Value = scanhil_scene::json_file::parse(&text, path)?;
    let value = value.get("trajectory").cloned().unwrap_or(value);
    serde_json::from_value(value).with_context(|| {
        format!(
            "{}: not a trajectory (or a scenario with one)",
            path.display()
        )
    })
}

/// The discretisation of a rule: the one asked when `kind` is the kind designed, else the
/// kind's default.
fn method(args: &Args, kind: Kind, drive_hz: &[f64]) -> Method {
    let prewarp_hz = args.prewarp_hz.clone().unwrap_or_else(|| drive_hz.to_vec());
    let asked = args.method.filter(|_| kind == args.kind);
    let chosen = asked.unwrap_or(match kind {
        Kind::Pid => MethodArg::Tustin,
        Kind::DualTone => MethodArg::TustinPrewarped,
    });
    match chosen {
        MethodArg::Tustin => Method::Tustin,
        MethodArg::TustinPrewarped => Method::TustinPrewarped { prewarp_hz },
        MethodArg::ZeroOrderHold => Method::ZeroOrderHold,
        MethodArg::MatchedPoleZero => Method::MatchedPoleZero,
        MethodArg::ForwardEuler => Method::ForwardEuler,
        MethodArg::BackwardEuler => Method::BackwardEuler,
    }
}

fn print_header(header: &serde_json::Value) -> std::io::Result<()> {
    let plant = &header["plant"];
    scanhil_protocol::outln!(
        "design at {} Hz ({}), rig {}",
        header["rate_hz"],
        header["rate_source"].as_str().unwrap_or(""),
        header["rig"].as_str().unwrap_or("")
    )?;
    scanhil_protocol::outln!(
        "plant: {} axis {}: K {}, ws {} rad/s, zeta {}, delay one period + {} s (bus transit {} s)",
        header["plant_source"].as_str().unwrap_or(""),
        header["axis"].as_str().unwrap_or(""),
        plant["dc_gain"],
        plant["natural_freq_rad_s"],
        plant["damping_ratio"],
        plant
            .get("extra_delay_s")
            .and_then(serde_json::Value::as_f64)
            .unwrap_or(0.0),
        header["bus_transit_s"]
    )?;
    scanhil_protocol::outln!(
        "margins asked: {} deg, {} dB; discretisation {}",
        header["margins"]["phase_deg"],
        header["margins"]["gain_db"],
        header["method"].as_str().unwrap_or("")
    )?;
    Ok(())
}

fn print_design(
    header: &serde_json::Value,
    design: &Design,
    reach: &serde_json::Value,
    out: Option<&Path>,
) -> std::io::Result<()> {
    print_header(header)?;
    scanhil_protocol::outln!("rule: {}", design.settings.description)?;
    let f = &design.figures;
    let opt =
        |v: Option<f64>, unit: &str| v.map_or("none".to_string(), |v| format!("{v:.3} {unit}"));
    scanhil_protocol::outln!("nominal closed loop (stable):")?;
    scanhil_protocol::outln!("  crossover            {}", opt(f.crossover_hz, "Hz"))?;
    scanhil_protocol::outln!(
        "  phase margin (min)   {}   gain crossovers: {}",
        opt(f.phase_margin_deg, "deg"),
        f.gain_crossovers
            .iter()
            .map(|c| format!("{:.2} Hz ({:+.1} deg)", c.f_hz, c.phase_margin_deg))
            .collect::<Vec<_>>()
            .join(", ")
    )?;
    scanhil_protocol::outln!("  gain margin          {}", opt(f.gain_margin_db, "dB"))?;
    scanhil_protocol::outln!(
        "  sensitivity peak     {:.2} dB at {:.2} Hz",
        f.sensitivity_peak_db,
        f.sensitivity_peak_hz
    )?;
    scanhil_protocol::outln!("  -3 dB bandwidth      {}", opt(f.bandwidth_3db_hz, "Hz"))?;
    scanhil_protocol::outln!(
        "  peak of T            {:.2} dB at {:.2} Hz",
        f.peak_db,
        f.peak_hz
    )?;
    for at in &f.at_drive {
        scanhil_protocol::outln!(
            "  at {:8.3} Hz: T {:+.4} dB {:+.3} deg, error of a sine {:.3} %",
            at.f_hz,
            at.t_db,
            at.t_deg,
            100.0 * at.error_relative
        )?;
    }
    if let Some(p) = f.predicted_tracking {
        let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{:.3} %", 100.0 * v));
        scanhil_protocol::outln!(
            "  predicted tracking error (rms / peak): alpha {}, beta {}",
            pct(p.alpha_rms_relative),
            pct(p.beta_rms_relative)
        )?;
    }
    scanhil_protocol::outln!(
        "  slowest pole |z| {:.9}: settles to 1e-3 in {:.2} s",
        f.spectral_radius,
        f.settle_s
    )?;
    print_reach(reach, header["rate_hz"].as_f64().unwrap_or(f64::NAN))?;
    if let Some(out) = out {
        scanhil_protocol::outln!("written: {}", out.display())?;
    }
    Ok(())
}

fn print_reach(reach: &serde_json::Value, rate_hz: f64) -> std::io::Result<()> {
    scanhil_protocol::outln!(
        "reach at {rate_hz} Hz (tracked to 1 % rms of the peak, margins kept):"
    )?;
    match reach["pid"].as_object() {
        Some(p) => scanhil_protocol::outln!(
            "  PID: crossover {:.1} Hz at most; sines up to {:.2} Hz",
            p["crossover_hz"].as_f64().unwrap_or(f64::NAN),
            p["sine_hz"].as_f64().unwrap_or(f64::NAN)
        )?,
        None => scanhil_protocol::outln!("  PID: no alpha-tuned PID keeps the margins")?,
    }
    match reach["dual_tone"].as_object() {
        Some(d) => scanhil_protocol::outln!(
            "  dual-tone: drive frequencies up to {} Hz (the trajectory's, scaled together)",
            d["drive_hz"]
                .as_array()
                .map(|a| a
                    .iter()
                    .map(|v| format!("{:.1}", v.as_f64().unwrap_or(f64::NAN)))
                    .collect::<Vec<_>>()
                    .join(", "))
                .unwrap_or_default()
        )?,
        None => scanhil_protocol::outln!(
            "  dual-tone: no scaling of the trajectory's drive frequencies tracks to 1 %"
        )?,
    }
    Ok(())
}
