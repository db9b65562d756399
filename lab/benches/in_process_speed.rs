//! How fast the one-process loop ([`scanhil_lab::in_process::run_plan`]) runs per control
//! period, against the plant alone, on the paper's Duplo Lissajous frame
//! (`fixtures/scenarios/duplo-lissajous-dual-tone.json`: 52/27 Hz, full range, dual-tone
//! controller, no lead-in here so the frame is all that runs) in four set-ups:
//! - `dynamics`: the mirror only (axes, cross-talk, amplifier, power limit, angle-sensor
//!   noise), no optics and no sensor, no output folder (nothing recorded);
//! - `dynamics_recorded`: the same with an output folder: `fsm.log` recorded (the figures
//!   left out, `outputs.figures` false);
//! - `duplo_shading_sensor`: the whole scene with shading and the ILD at 20 kHz, one ray per
//!   sample, no output folder;
//! - `duplo_spot7`: the same with the scene's 7-ray spot (the fixture as shipped).
//!
//! Per period, not per run: each round runs the scenario for [`SHORT_S`] and for [`LONG_S`]
//! simulated seconds (plans made beforehand, outside the timing) and divides the difference
//! in CPU time by the difference in periods, so what a run costs once (loading the scene,
//! measuring the parts' costs, the report) drops out; it is reported apart, as
//! `fixed_cpu_ms`. The process's CPU time is the figure (a loaded machine's wall time also
//! counts the time other processes had the core); wall time is beside it. Medians of
//! [`RUNS`] rounds.
//!
//! The floors, measured in the same run: `Plant::step` alone for as many periods (the
//! emulated plant without host, controller or protocol), and the host alone (the
//! trajectory's reference and the controller's step, what every period computes whatever
//! carries it). Each case is reported against the plant alone, the yardstick, and
//! against plant and host together, what no transport can go below.
//! Writes JSON to stdout and to `target/in_process_speed.json`.
//!
//! Run: `cargo bench -p scanhil-lab --bench in_process_speed [-- CASE...]` (default: every
//! case).

mod support;

use std::path::{Path, PathBuf};
use std::time::Instant;

use scanhil_controller::run::lead_in::LeadIn;
use scanhil_controller::run::plan::ScanPlan;
use scanhil_controller::run::scenario::Scenario;
use scanhil_emulator::serve::load_plant;
use scanhil_protocol::plant_units::{ActuatorPair, SensingPair};
use support::root;

/// Rounds per case (medians reported).
const RUNS: usize = 5;
/// The short run of each round, simulated s.
const SHORT_S: f64 = 1.0;
/// The long run of each round, simulated s.
const LONG_S: f64 = 3.0;

/// One bench case: its name, and how the shipped Duplo scene and the scenario are changed.
struct Case {
    name: &'static str,
    /// Parts removed from the scene.
    without_parts: &'static [&'static str],
    /// Whether the scene's spot averaging is removed (one ray per sample).
    single_ray: bool,
    /// Whether the run writes an output folder with its recordings (figures left out).
    recorded: bool,
}

/// The parts a mirror-only scene leaves out.
const DYNAMICS_ONLY: &[&str] = &["optics", "shading", "sensor", "sensor_noise"];

const CASES: [Case; 4] = [
    Case {
        name: "dynamics",
        without_parts: DYNAMICS_ONLY,
        single_ray: false,
        recorded: false,
    },
    Case {
        name: "dynamics_recorded",
        without_parts: DYNAMICS_ONLY,
        single_ray: false,
        recorded: true,
    },
    Case {
        name: "duplo_shading_sensor",
        without_parts: &[],
        single_ray: true,
        recorded: false,
    },
    Case {
        name: "duplo_spot7",
        without_parts: &[],
        single_ray: false,
        recorded: false,
    },
];

/// The shipped Duplo scene changed as `case` says, written into `dir`.
fn scene_file(case: &Case, dir: &Path) -> anyhow::Result<PathBuf> {
    let shipped = root().join("fixtures/scenes/duplo-2x4-130mm.json");
    let mut scene: serde_json::Value = serde_json::from_slice(&std::fs::read(&shipped)?)?;
    let parts = scene["parts"]
        .as_array_mut()
        .ok_or_else(|| anyhow::anyhow!("{}: no parts", shipped.display()))?;
    parts.retain(|part| !case.without_parts.iter().any(|name| part == name));
    let object = scene
        .as_object_mut()
        .ok_or_else(|| anyhow::anyhow!("{}: not an object", shipped.display()))?;
    if case.without_parts.contains(&"optics") {
        object.remove("optics");
        object.remove("surface");
    }
    if case.without_parts.contains(&"sensor") {
        object.remove("sensor");
    }
    if case.single_ray
        && let Some(optics) = object.get_mut("optics").and_then(|o| o.as_object_mut())
    {
        optics.remove("spot");
    }
    let path = dir.join(format!("{}.json", case.name));
    std::fs::write(&path, serde_json::to_vec_pretty(&scene)?)?;
    Ok(path)
}

fn scenario(case: &Case, dir: &Path) -> anyhow::Result<Scenario> {
    let mut scenario =
        Scenario::load(&root().join("fixtures/scenarios/duplo-lissajous-dual-tone.json"))?;
    scenario.scene = Some(scene_file(case, dir)?);
    scenario.lead_in = LeadIn::None;
    scenario.outputs.figures = false;
    if case.without_parts.contains(&"sensor") {
        scenario.rig.sensor = None;
    }
    Ok(scenario)
}

/// The process's CPU time so far, s.
fn cpu_s() -> anyhow::Result<f64> {
    let time = nix::time::clock_gettime(nix::time::ClockId::CLOCK_PROCESS_CPUTIME_ID)?;
    Ok(time.tv_sec() as f64 + time.tv_nsec() as f64 * 1e-9)
}

/// The wall and CPU seconds `work` takes, and its result.
fn timed<T>(work: impl FnOnce() -> anyhow::Result<T>) -> anyhow::Result<(T, f64, f64)> {
    let (wall, cpu) = (Instant::now(), cpu_s()?);
    let out = work()?;
    Ok((out, wall.elapsed().as_secs_f64(), cpu_s()? - cpu))
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// One run of `scenario` for `duration_s`, its plan made before the timing starts (into a
/// fresh output folder when `recorded`): periods done, wall s, CPU s.
fn loop_run(
    scenario: &Scenario,
    duration_s: f64,
    recorded: bool,
) -> anyhow::Result<(u64, f64, f64)> {
    let scenario = Scenario {
        duration_s,
        ..scenario.clone()
    };
    let plan = ScanPlan::new(&scenario)?;
    let out = recorded.then(tempfile::tempdir).transpose()?;
    let (outcome, wall_s, cpu_s) = timed(|| {
        scanhil_lab::in_process::run_plan(&scenario, plan, out.as_ref().map(|dir| dir.path()))
    })?;
    Ok((outcome.run.record.periods_done, wall_s, cpu_s))
}

/// `periods` bare plant steps of `scene` with a constant small command.
fn plant_alone(scene: &Path, seed: u64, periods: u64) -> anyhow::Result<()> {
    let (_, mut plant) = load_plant(scene, Some(seed))?;
    let command = ActuatorPair { a: 0.05, b: -0.05 };
    for _ in 0..periods {
        std::hint::black_box(plant.step(std::hint::black_box(command))?);
    }
    Ok(())
}

/// `periods` periods of the host's own arithmetic: the trajectory's reference and the
/// controller's step on a measurement that follows it (no frames, no record).
fn host_alone(scenario: &Scenario, periods: u64) -> anyhow::Result<()> {
    let ScanPlan {
        mut controller,
        trajectory,
        ..
    } = ScanPlan::new(scenario)?;
    let period_s = controller.period_s();
    let mut measured = SensingPair::default();
    for k in 0..periods {
        let reference = trajectory.reference_rad(k as f64 * period_s);
        std::hint::black_box(controller.step(reference, measured));
        measured = std::hint::black_box(reference);
    }
    Ok(())
}

/// Per-period figures of one case: medians over [`RUNS`] rounds of the long run less the
/// short one.
fn measure(case: &Case, scenario: &Scenario) -> anyhow::Result<serde_json::Value> {
    let scene = scenario.scene.clone().unwrap_or_default();
    let mut rows: Vec<[f64; 5]> = Vec::new();
    let mut periods = (0, 0);
    for _ in 0..RUNS {
        let (short, short_wall_s, short_cpu_s) = loop_run(scenario, SHORT_S, case.recorded)?;
        let (long, long_wall_s, long_cpu_s) = loop_run(scenario, LONG_S, case.recorded)?;
        let extra = (long - short) as f64;
        anyhow::ensure!(
            extra > 0.0,
            "{}: the long run did no more periods",
            case.name
        );
        let ((), _, plant_short_s) = timed(|| plant_alone(&scene, scenario.seed, short))?;
        let ((), _, plant_long_s) = timed(|| plant_alone(&scene, scenario.seed, long))?;
        let ((), _, host_s) = timed(|| host_alone(scenario, long - short))?;
        let loop_cpu_s = (long_cpu_s - short_cpu_s) / extra;
        rows.push([
            loop_cpu_s,
            (long_wall_s - short_wall_s) / extra,
            (plant_long_s - plant_short_s) / extra,
            host_s / extra,
            short_cpu_s - loop_cpu_s * short as f64,
        ]);
        periods = (short, long);
    }
    let column = |i: usize| median(rows.iter().map(|row| row[i]).collect());
    let (loop_s, wall_s, plant_s, host_s, fixed_s) =
        (column(0), column(1), column(2), column(3), column(4));
    let period_s = 1.0 / scenario.rig.control_rate_hz;
    Ok(serde_json::json!({
        "case": case.name,
        "recorded": case.recorded,
        "periods_short_long": [periods.0, periods.1],
        "loop_cpu_ns_per_period": loop_s * 1e9,
        "loop_wall_ns_per_period": wall_s * 1e9,
        "plant_alone_cpu_ns_per_period": plant_s * 1e9,
        "host_alone_cpu_ns_per_period": host_s * 1e9,
        "loop_over_plant_alone": loop_s / plant_s,
        "loop_over_plant_and_host_alone": loop_s / (plant_s + host_s),
        "real_time_multiple_cpu": period_s / loop_s,
        "plant_alone_real_time_multiple": period_s / plant_s,
        "fixed_cpu_ms": fixed_s * 1e3,
    }))
}

fn main() -> anyhow::Result<()> {
    let chosen: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    if let Some(unknown) = chosen
        .iter()
        .find(|c| !CASES.iter().any(|case| case.name == *c))
    {
        let names: Vec<&str> = CASES.iter().map(|case| case.name).collect();
        anyhow::bail!("unknown case '{unknown}' (cases: {})", names.join(", "));
    }
    let dir = tempfile::tempdir()?;
    let mut rows = Vec::new();
    for case in CASES
        .iter()
        .filter(|case| chosen.is_empty() || chosen.iter().any(|c| c == case.name))
    {
        rows.push(measure(case, &scenario(case, dir.path())?)?);
    }
    support::publish(
        "in_process_speed",
        &serde_json::json!({
            "runs": RUNS,
            "short_s": SHORT_S,
            "long_s": LONG_S,
            "cases": rows,
        }),
    )?;
    Ok(())
}
