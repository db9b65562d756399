//! How fast the one-process loop ([`scanhil_lab::in_process::run`]) runs, as a multiple of
//! real time (simulated seconds / wall seconds), on the paper's Duplo Lissajous frame
//! (`fixtures/scenarios/duplo-lissajous-dual-tone.json`: 52/27 Hz, full range, dual-tone
//! controller, 1 s, no lead-in here so the frame is all that runs) in three plants:
//! - `dynamics`: the mirror only (axes, cross-talk, amplifier, power limit, angle-sensor
//!   noise), no optics and no sensor;
//! - `duplo_shading_sensor`: the whole scene with shading and the ILD at 20 kHz, one ray per
//!   sample;
//! - `duplo_spot7`: the same with the scene's 7-ray spot (the fixture as shipped).
//!
//! No output folder is written: what is timed is the loop (host, in-memory link, node, plant).
//! Each case runs [`RUNS`] times; the median wall time is reported, and the median CPU time
//! of the process beside it (on a loaded machine the wall time also counts the time other
//! processes had the core; the CPU time does not). As the machine's own
//! floor, the same number of periods of `Plant::step` alone (the emulated plant without host,
//! controller or protocol) is timed in the same run, and each case is reported against it.
//! Writes JSON to stdout and to `target/in_process_speed.json`.
//!
//! Run: `cargo bench -p scanhil-lab --bench in_process_speed [-- CASE...]` (default: every
//! case).

mod support;

use std::path::{Path, PathBuf};
use std::time::Instant;

use scanhil_controller::run::lead_in::LeadIn;
use scanhil_controller::run::scenario::Scenario;
use scanhil_emulator::serve::load_plant;
use scanhil_protocol::plant_units::ActuatorPair;
use support::root;

/// Runs per case (median reported).
const RUNS: usize = 5;

/// One bench case: its name, and how the shipped Duplo scene and the scenario are changed.
struct Case {
    name: &'static str,
    /// Parts removed from the scene.
    without_parts: &'static [&'static str],
    /// Whether the scene's spot averaging is removed (one ray per sample).
    single_ray: bool,
}

const CASES: [Case; 3] = [
    Case {
        name: "dynamics",
        without_parts: &["optics", "shading", "sensor", "sensor_noise"],
        single_ray: false,
    },
    Case {
        name: "duplo_shading_sensor",
        without_parts: &[],
        single_ray: true,
    },
    Case {
        name: "duplo_spot7",
        without_parts: &[],
        single_ray: false,
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

/// `work` run [`RUNS`] times: its last result, and the median wall and CPU seconds.
fn median_timed<T>(mut work: impl FnMut() -> anyhow::Result<T>) -> anyhow::Result<(T, f64, f64)> {
    let (mut walls, mut cpus, mut out) = (Vec::new(), Vec::new(), None);
    for _ in 0..RUNS {
        let (wall, cpu) = (Instant::now(), cpu_s()?);
        out = Some(work()?);
        walls.push(wall.elapsed().as_secs_f64());
        cpus.push(cpu_s()? - cpu);
    }
    let median = |mut values: Vec<f64>| {
        values.sort_by(f64::total_cmp);
        values[values.len() / 2]
    };
    let out = out.ok_or_else(|| anyhow::anyhow!("no run"))?;
    Ok((out, median(walls), median(cpus)))
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
        let scenario = scenario(case, dir.path())?;
        let (outcome, wall_s, cpu_s) =
            median_timed(|| scanhil_lab::in_process::run(&scenario, None))?;
        let periods = outcome.run.record.periods_done;
        let simulated_s = periods as f64 / scenario.rig.control_rate_hz;
        let scene = scenario.scene.as_deref().unwrap_or(Path::new(""));
        let ((), plant_wall_s, plant_cpu_s) =
            median_timed(|| plant_alone(scene, scenario.seed, periods))?;
        rows.push(serde_json::json!({
            "case": case.name,
            "periods": periods,
            "simulated_s": simulated_s,
            "wall_s": wall_s,
            "cpu_s": cpu_s,
            "real_time_multiple": simulated_s / wall_s,
            "real_time_multiple_cpu": simulated_s / cpu_s,
            "cpu_ns_per_period": cpu_s * 1e9 / periods as f64,
            "plant_alone_cpu_ns_per_period": plant_cpu_s * 1e9 / periods as f64,
            "plant_alone_real_time_multiple": simulated_s / plant_wall_s,
            "loop_over_plant_alone_cpu": cpu_s / plant_cpu_s,
        }));
    }
    support::publish(
        "in_process_speed",
        &serde_json::json!({ "runs": RUNS, "cases": rows }),
    )?;
    Ok(())
}
