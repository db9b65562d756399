//! Injected faults in the one-process loop, one test per row of the table in `docs/faults.md`:
//! what the host detects, what the node detects, within how many periods, what the coils end
//! at and what `report.json` says. Every run also checks that every frame is accounted for:
//! the transport's own counts of what each side sent and received agree with the fault
//! injector's ledger.

use std::path::{Path, PathBuf};

use scanhil_controller::run::link_faults::FaultsConfig;
use scanhil_controller::run::scenario::Scenario;
use scanhil_lab::in_process::{InProcessOutcome, run};
use serde_json::Value;

fn scenarios_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenarios")
}

/// The small loop (2000 periods, no optics) with `faults` (the scenario's `faults` JSON).
fn small_loop(faults: Value) -> Scenario {
    let mut scenario = Scenario::load(&scenarios_dir().join("test-loop-small.json")).unwrap();
    scenario.faults = serde_json::from_value::<FaultsConfig>(faults).unwrap();
    scenario.check().unwrap();
    scenario
}

/// Runs `scenario` in process into a temporary folder; returns the outcome and the report's
/// `faults` section, after checking every frame is accounted for.
fn run_faulty(scenario: &Scenario) -> (InProcessOutcome, Value) {
    let dir = tempfile::tempdir().unwrap();
    let outcome = run(scenario, Some(dir.path())).unwrap();
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();
    let faults = report["faults"].clone();
    let wire = outcome.wire;
    let ledger = |direction: &str, field: &str| {
        faults["injected"]["frames"][direction]["ledger"][field]
            .as_u64()
            .unwrap_or_else(|| panic!("{direction}.{field} in {faults:#}"))
    };
    assert_eq!(wire.host_sent, ledger("host_to_node", "offered"));
    assert_eq!(wire.node_received, ledger("host_to_node", "delivered"));
    assert_eq!(wire.node_sent, ledger("node_to_host", "offered"));
    assert_eq!(wire.host_received, ledger("node_to_host", "delivered"));
    for direction in ["host_to_node", "node_to_host"] {
        assert_eq!(
            faults["injected"]["frames"][direction]["balances"], true,
            "{faults:#}"
        );
    }
    (outcome, faults)
}

fn at(direction: &str, period: u64, fault: &str, message: &str) -> Value {
    serde_json::json!({
        direction: { "at": [{ "period": period, "fault": fault, "message": message }] }
    })
}

fn host(faults: &Value, field: &str) -> u64 {
    faults["host_detected"][field].as_u64().unwrap()
}

fn node(faults: &Value, field: &str) -> u64 {
    faults["node_detected"][field].as_u64().unwrap()
}

/// The run completed every period and ended with the coils at zero: the host's zero command
/// (never faulted) acknowledged by the node, which is ready (not in a fault) and holds 0 A.
fn completed(outcome: &InProcessOutcome, faults: &Value) {
    let record = &outcome.run.record;
    assert_eq!(record.periods_done, record.periods_planned, "{faults:#}");
    assert!(record.stopped_by.is_none(), "{:?}", record.stopped_by);
    assert_eq!(faults["host_detected"]["stopped_by"], Value::Null);
    assert_eq!(faults["node_detected"]["final_state"], "ready");
    assert!(record.coils_at_end.zero_commanded && record.coils_at_end.acknowledged);
    held_at_zero(faults);
    assert_eq!(
        outcome.wire.stop_frames, 2,
        "the zero command and the end of the run"
    );
}

/// The node holds 0 A on both coils.
fn held_at_zero(faults: &Value) {
    let held = &faults["node_detected"]["held_coil_currents_a"];
    assert_eq!(held["a"], 0.0, "{held}");
    assert_eq!(held["b"], 0.0, "{held}");
}

fn injected_one(faults: &Value, direction: &str, fault: &str, period: u64) {
    let first = &faults["injected"]["frames"][direction]["first_faults"];
    assert_eq!(first.as_array().unwrap().len(), 1, "{first:#}");
    assert_eq!(first[0]["fault"], fault);
    assert_eq!(first[0]["period"], period);
}

#[test]
fn a_dropped_angle_reading_is_asked_for_again_with_its_step() {
    let (outcome, faults) =
        run_faulty(&small_loop(at("node_to_host", 500, "drop", "AngleReading")));
    completed(&outcome, &faults);
    injected_one(&faults, "node_to_host", "drop", 500);
    assert_eq!(host(&faults, "repeated_steps"), 1);
    assert_eq!(node(&faults, "repeated_steps"), 1);
    assert_eq!(node(&faults, "out_of_order_steps"), 0);
    assert_eq!(host(&faults, "late_readings"), 0);
}

#[test]
fn a_dropped_step_is_sent_again_and_stepped_once() {
    let (outcome, faults) = run_faulty(&small_loop(at("host_to_node", 500, "drop", "Step")));
    completed(&outcome, &faults);
    injected_one(&faults, "host_to_node", "drop", 500);
    assert_eq!(host(&faults, "repeated_steps"), 1);
    // The node never saw the first Step: the repeat is its only Step(500).
    assert_eq!(node(&faults, "repeated_steps"), 0);
    assert_eq!(outcome.run.record.periods_done, 2000);
}

#[test]
fn a_dropped_coil_command_leaves_the_node_one_stale_period() {
    let (outcome, faults) = run_faulty(&small_loop(at("host_to_node", 500, "drop", "CoilCommand")));
    completed(&outcome, &faults);
    assert_eq!(node(&faults, "command_gaps"), 1);
    // Period 0 steps before any command as well.
    assert_eq!(
        node(&faults, "stale_periods"),
        stale_periods_without_command_faults() + 1
    );
    assert_eq!(host(&faults, "repeated_steps"), 0);
}

#[test]
fn a_duplicated_reading_is_counted_late_and_not_used() {
    let (outcome, faults) = run_faulty(&small_loop(at(
        "node_to_host",
        500,
        "duplicate",
        "AngleReading",
    )));
    completed(&outcome, &faults);
    assert_eq!(host(&faults, "late_readings"), 1);
    assert_eq!(host(&faults, "angle_sequence_gaps"), 0);
}

#[test]
fn a_duplicated_step_is_answered_again_without_stepping() {
    let (outcome, faults) = run_faulty(&small_loop(at("host_to_node", 500, "duplicate", "Step")));
    completed(&outcome, &faults);
    assert_eq!(node(&faults, "repeated_steps"), 1);
    assert_eq!(host(&faults, "late_readings"), 1);
    let summary = &outcome.run.emulator_summary.as_ref().unwrap()["summary"];
    assert_eq!(summary["node"]["periods"], 2000, "stepped once per period");
}

#[test]
fn a_duplicated_coil_command_is_counted_as_a_repeat() {
    let (outcome, faults) = run_faulty(&small_loop(at(
        "host_to_node",
        500,
        "duplicate",
        "CoilCommand",
    )));
    completed(&outcome, &faults);
    assert_eq!(node(&faults, "repeated_commands"), 1);
    assert_eq!(node(&faults, "command_gaps"), 0);
}

#[test]
fn a_delayed_reading_is_replaced_by_the_repeat_and_counted_late_when_it_comes() {
    let mut faults = at("node_to_host", 500, "delay", "AngleReading");
    faults["node_to_host"]["delay_periods"] = 3.into();
    let (outcome, faults) = run_faulty(&small_loop(faults));
    completed(&outcome, &faults);
    assert_eq!(host(&faults, "repeated_steps"), 1);
    assert_eq!(node(&faults, "repeated_steps"), 1);
    assert_eq!(host(&faults, "late_readings"), 1);
}

#[test]
fn a_delayed_step_is_not_stepped_when_it_comes() {
    let mut faults = at("host_to_node", 500, "delay", "Step");
    faults["host_to_node"]["delay_periods"] = 3.into();
    let (outcome, faults) = run_faulty(&small_loop(faults));
    completed(&outcome, &faults);
    assert_eq!(host(&faults, "repeated_steps"), 1);
    assert_eq!(node(&faults, "out_of_order_steps"), 1);
    let summary = &outcome.run.emulator_summary.as_ref().unwrap()["summary"];
    assert_eq!(summary["node"]["periods"], 2000, "stepped once per period");
}

#[test]
fn a_delayed_coil_command_is_not_applied_when_it_comes() {
    let mut faults = at("host_to_node", 500, "delay", "CoilCommand");
    faults["host_to_node"]["delay_periods"] = 2.into();
    let (outcome, faults) = run_faulty(&small_loop(faults));
    completed(&outcome, &faults);
    assert_eq!(node(&faults, "late_commands"), 1);
    assert_eq!(node(&faults, "command_gaps"), 1);
}

#[test]
fn a_coil_command_reordered_behind_its_step_leaves_a_stale_period_and_comes_late() {
    let (outcome, faults) = run_faulty(&small_loop(at(
        "host_to_node",
        500,
        "reorder",
        "CoilCommand",
    )));
    completed(&outcome, &faults);
    assert_eq!(
        node(&faults, "stale_periods"),
        stale_periods_without_command_faults() + 1
    );
    assert_eq!(node(&faults, "command_gaps"), 0);
}

#[test]
fn a_reordered_reading_is_asked_for_again_and_the_held_one_counted_late() {
    let (outcome, faults) = run_faulty(&small_loop(at(
        "node_to_host",
        500,
        "reorder",
        "AngleReading",
    )));
    completed(&outcome, &faults);
    // Nothing else comes in period 500: the reading waits for the repeat's answer.
    assert_eq!(host(&faults, "repeated_steps"), 1);
    assert_eq!(host(&faults, "late_readings"), 1);
}

#[test]
fn bit_flips_in_readings_are_caught_when_they_hit_the_counter_or_a_high_angle_bit() {
    let at: Vec<Value> = (100..400)
        .map(|period| serde_json::json!({"period": period, "fault": "bit_flip", "message": "AngleReading"}))
        .collect();
    let (outcome, faults) = run_faulty(&small_loop(
        serde_json::json!({"seed": 17, "node_to_host": {"at": at}}),
    ));
    completed(&outcome, &faults);
    let flips = faults["injected"]["frames"]["node_to_host"]["first_faults"]
        .as_array()
        .unwrap();
    assert_eq!(flips.len(), 256, "the log keeps the first 256");
    let ledger = &faults["injected"]["frames"]["node_to_host"]["ledger"];
    assert_eq!(ledger["bit_flipped"], 300);
    // AngleReading: Seq in payload bits 0-15, Alpha 16-39, Beta 40-63 (24-bit, 1 urad per
    // count). A counter bit gives a gap or a late reading; an angle bit of weight 2^16
    // counts or more (field bits 16-23, payload bits 32-39 and 56-63) an angle beyond the
    // mirror's 31.4 mrad with margin; field bit 15 mostly does; lower angle bits pass
    // unnoticed. The log holds 256 of the 300 flips: bound the other 44.
    let bits: Vec<u64> = flips
        .iter()
        .map(|flip| flip["bit"].as_u64().unwrap())
        .collect();
    let counter_hits = bits.iter().filter(|&&bit| bit < 16).count() as u64;
    let high_angle_hits = bits
        .iter()
        .filter(|&&bit| (32..40).contains(&bit) || (56..64).contains(&bit))
        .count() as u64;
    let bit_15_hits = bits.iter().filter(|&&bit| bit == 31 || bit == 55).count() as u64;
    let sequence = host(&faults, "angle_sequence_gaps") + host(&faults, "late_readings");
    let implausible = host(&faults, "implausible_readings");
    assert!(counter_hits > 0 && high_angle_hits > 0, "{bits:?}");
    assert!(
        (counter_hits..=counter_hits + 44).contains(&sequence),
        "{counter_hits} counter hits logged, {sequence} caught"
    );
    assert!(
        (high_angle_hits..=high_angle_hits + bit_15_hits + 44).contains(&implausible),
        "{high_angle_hits} high angle hits logged, {implausible} caught"
    );
    assert_eq!(
        host(&faults, "repeated_steps"),
        sequence + implausible,
        "each caught one is asked for again"
    );
}

#[test]
fn a_node_that_goes_silent_ends_the_run_by_the_watchdog_with_zero_current() {
    // Every frame from the node is lost: the first reading never comes.
    let scenario = small_loop(serde_json::json!({"node_to_host": {"drop_rate": 1.0}}));
    let (outcome, faults) = run_faulty(&scenario);
    assert_eq!(outcome.run.record.periods_done, 0, "{faults:#}");
    let watchdog = u64::from(scenario.timing.watchdog_periods);
    assert_eq!(host(&faults, "repeated_steps"), watchdog - 1);
    assert_eq!(node(&faults, "repeated_steps"), watchdog - 1);
    let stopped_by = faults["host_detected"]["stopped_by"].as_str().unwrap();
    assert!(stopped_by.contains("link timeout"), "{stopped_by}");
    assert_eq!(faults["host_detected"]["stopped_in_period"], 0);
    // The host's zero command reached the node.
    held_at_zero(&faults);
}

/// Issue 20: with bit-flip injection the final zero command was itself corrupted. Every frame
/// the host sends has a bit flipped: the first Step never steps the node, so the run stops by
/// the watchdog after the node took a corrupted first command; the stop's zero command passes
/// no fault and the node ends at 0 A, whatever the seed (a flipped zero holds a current of
/// 2^bit uA unless the bit is in the counter: 40 of its 64 bits are currents).
#[test]
fn the_stops_zero_command_is_never_bit_flipped() {
    for seed in 1..=8 {
        let scenario = small_loop(serde_json::json!({
            "seed": seed,
            "host_to_node": {"bit_flip_rate": 1.0}
        }));
        let (outcome, faults) = run_faulty(&scenario);
        assert!(outcome.run.record.stopped_by.is_some(), "seed {seed}");
        assert!(
            outcome.run.record.coils_at_end.zero_commanded,
            "seed {seed}"
        );
        let ledger = &faults["injected"]["frames"]["host_to_node"]["ledger"];
        assert_eq!(
            ledger["bit_flipped"], ledger["offered"],
            "seed {seed}: {ledger}"
        );
        held_at_zero(&faults);
    }
}

#[test]
fn the_sensor_losing_its_peak_is_sent_and_seen_as_the_ild_error_values() {
    let mut scenario = Scenario::load(&scenarios_dir().join("test-duplo-stud.json")).unwrap();
    scenario.lead_in = scanhil_controller::run::lead_in::LeadIn::Fixed { duration_s: 0.01 };
    scenario.duration_s = 0.05;
    scenario.faults = serde_json::from_value::<FaultsConfig>(serde_json::json!({"sensor": {
        "laser_off": [{"from_s": 0.01, "to_s": 0.015}],
        "out_of_range": [{"from_s": 0.03, "to_s": 0.032}],
        "occlusion": {"bursts_per_s": 200.0, "burst_s": 0.0005}
    }}))
    .unwrap();
    scenario.check().unwrap();
    let dir = tempfile::tempdir().unwrap();
    // The samples are taken before the output folder is written (writing consumes them).
    let mut outcome = run(&scenario, None).unwrap();
    let held = |samples: &scanhil_controller::run::chunked::Chunked<_>| {
        samples.iter().copied().collect::<Vec<_>>()
    };
    let faulty_samples = held(&outcome.run.sensor.0);
    outcome.end = outcome.write(dir.path()).unwrap();
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();
    let faults = &report["faults"];
    completed(&outcome, faults);
    let injected = &faults["injected"]["sensor_samples"];
    let seen = &faults["host_detected"]["sensor_error_values"];
    // 5 ms and 2 ms at 20 kHz.
    assert_eq!(injected["laser_off"], 100, "{injected}");
    assert_eq!(injected["out_of_range"], 40, "{injected}");
    assert_eq!(seen["laser_off"], 100, "{seen}");
    assert!(
        seen["peak_after_range"].as_u64().unwrap_or(0) >= 40,
        "{seen}"
    );
    let occluded = injected["occluded"].as_u64().unwrap();
    assert!(occluded > 0, "{injected}");
    assert!(seen["no_peak"].as_u64().unwrap() >= occluded, "{seen}");
    // The same run without the faults: the errors added are exactly the ones injected, and
    // no error value became a point.
    let mut clean = scenario.clone();
    clean.faults = FaultsConfig::default();
    let clean = run(&clean, None).unwrap();
    let errors = |samples: &[scanhil_controller::run::sample_log::CountedSample]| {
        samples
            .iter()
            .filter(|s| matches!(s.value, scanhil_protocol::ild::IldValue::Error(_)))
            .count() as u64
    };
    let (faulty_samples, clean_samples) = (&faulty_samples[..], &held(&clean.run.sensor.0)[..]);
    assert_eq!(faulty_samples.len(), clean_samples.len());
    let is_error = |value: &scanhil_protocol::ild::IldValue| {
        matches!(value, scanhil_protocol::ild::IldValue::Error(_))
    };
    let changed: Vec<_> = faulty_samples
        .iter()
        .zip(clean_samples)
        .filter(|(faulty, clean)| faulty.value != clean.value)
        .collect();
    let injected_total = 100 + 40 + occluded;
    assert!(
        changed.len() as u64 <= injected_total,
        "{} changed, {injected_total} injected",
        changed.len()
    );
    assert!(changed.len() as u64 >= 140, "the windows' samples changed");
    assert!(
        changed.iter().all(|(faulty, _)| is_error(&faulty.value)),
        "every changed sample is an error value"
    );
    assert!(errors(faulty_samples) > errors(clean_samples));
}

#[test]
fn a_bit_flip_in_a_step_is_never_stepped_and_the_step_is_sent_again() {
    let at: Vec<Value> = (100..300)
        .map(|period| serde_json::json!({"period": period, "fault": "bit_flip", "message": "Step"}))
        .collect();
    let (outcome, faults) =
        run_faulty(&small_loop(serde_json::json!({"host_to_node": {"at": at}})));
    completed(&outcome, &faults);
    // Step's payload is its 32-bit period counter alone: every flip makes it another period,
    // counted and not stepped, or (bit 0 of an odd period) the period just stepped, answered
    // again with its reading, which the host counts late.
    let repeats = node(&faults, "repeated_steps");
    assert_eq!(node(&faults, "out_of_order_steps") + repeats, 200);
    assert_eq!(host(&faults, "late_readings"), repeats);
    assert_eq!(host(&faults, "repeated_steps"), 200);
    let summary = &outcome.run.emulator_summary.as_ref().unwrap()["summary"];
    assert_eq!(summary["node"]["periods"], 2000, "stepped once per period");
}

/// The node's stale periods in the same small loop with no fault on the commands: a fault
/// declared on the sensor's Distance frames, which this rig without a sensor never sends,
/// keeps the run's set-up the same (one past the run's end is refused as never firing).
fn stale_periods_without_command_faults() -> u64 {
    let clean = run_faulty(&small_loop(serde_json::json!({"node_to_host": {"at": [
        {"period": 1000, "fault": "drop", "message": "Distance"}
    ]}})))
    .1;
    node(&clean, "stale_periods")
}
