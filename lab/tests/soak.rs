//! The bounded soak: a million lockstep periods in one process with random faults on both
//! directions of the mirror's link (drop, delay, duplicate, reorder, bit flip). Every period
//! completes, the node steps exactly once per period, every frame is either delivered or
//! accounted for as injected (the transport's own counts against the injector's ledger), and
//! memory stays flat: the resident set, sampled at 10 %, 50 % and 100 % of the run, grows by
//! no more than [`SLACK_BYTES`] (the record keeps running sums, a window figure every 1000
//! periods and 4000 plot points; a byte per period would be 0.9 MiB over the 90 % sampled).
//!
//! `cargo test -p scanhil-lab --test soak -- --nocapture` prints the figures.

use std::path::Path;

use scanhil_controller::run::link_faults::FaultsConfig;
use scanhil_controller::run::plan::ScanPlan;
use scanhil_controller::run::scenario::Scenario;
use scanhil_lab::in_process::run_probed;

/// Periods of the soak.
const PERIODS: u64 = 1_000_000;

/// Growth of the resident set allowed (allocator and page granularity, the window figures).
const SLACK_BYTES: u64 = 2 << 20;

/// This process's resident set, bytes (Linux `/proc/self/statm`).
fn resident_bytes() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").expect("/proc/self/statm");
    let pages: u64 = statm.split_whitespace().nth(1).unwrap().parse().unwrap();
    pages * 4096
}

#[test]
fn a_million_periods_with_random_faults_lose_no_frame_and_hold_memory_flat() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenarios/test-loop-small.json");
    let mut scenario = Scenario::load(&path).unwrap();
    let period_s = 1.0 / scenario.rig.control_rate_hz;
    scenario.duration_s = PERIODS as f64 * period_s;
    let rates = serde_json::json!({
        "drop_rate": 1e-3, "delay_rate": 5e-4, "delay_periods": 3,
        "duplicate_rate": 1e-3, "reorder_rate": 5e-4, "bit_flip_rate": 2e-4
    });
    scenario.faults = serde_json::from_value::<FaultsConfig>(serde_json::json!({
        "seed": 2026, "host_to_node": rates, "node_to_host": rates
    }))
    .unwrap();
    scenario.check().unwrap();

    let mut samples: Vec<(u64, u64)> = Vec::new();
    let outcome = run_probed(
        &scenario,
        ScanPlan::new(&scenario).expect("the soak's plan"),
        None,
        &mut |k, _| {
            let periods = k + 1;
            if periods == PERIODS / 10 || periods == PERIODS / 2 || periods == PERIODS {
                samples.push((periods, resident_bytes()));
            }
        },
    )
    .unwrap();

    let record = &outcome.run.record;
    assert_eq!(record.periods_planned, PERIODS);
    assert_eq!(record.periods_done, PERIODS, "{:?}", record.stopped_by);
    assert!(record.stopped_by.is_none());
    let node = &outcome.run.emulator_summary.as_ref().unwrap()["summary"]["node"];
    assert_eq!(node["periods"], PERIODS, "the node stepped once per period");

    let faults = outcome.run.frame_faults.as_ref().unwrap();
    let wire = outcome.wire;
    for (name, direction, sent, received) in [
        (
            "host_to_node",
            &faults.host_to_node,
            wire.host_sent,
            wire.node_received,
        ),
        (
            "node_to_host",
            &faults.node_to_host,
            wire.node_sent,
            wire.host_received,
        ),
    ] {
        let ledger = direction.ledger;
        println!("{name}: {ledger:?}");
        assert!(ledger.balances(), "{name}: {ledger:?}");
        assert_eq!(
            ledger.offered, sent,
            "{name}: every frame sent went through the wire"
        );
        assert_eq!(
            ledger.delivered, received,
            "{name}: every frame passed was received"
        );
        for (kind, count) in ledger.fault_counts() {
            assert!(count > 100, "{name}: {kind} injected: {ledger:?}");
        }
    }
    let counters = outcome.run.mirror_counters;
    println!(
        "host: {counters:?}, repeated steps {}; node: {node}",
        record.repeated_steps
    );
    assert!(record.repeated_steps > 0);

    println!("resident set (periods, bytes): {samples:?}");
    assert_eq!(samples.len(), 3, "{samples:?}");
    let first_bytes = samples[0].1;
    let last_bytes = samples[2].1;
    let growth = last_bytes.saturating_sub(first_bytes);
    println!(
        "growth from 10 % to 100 %: {:.2} MiB",
        growth as f64 / f64::from(1 << 20)
    );
    assert!(
        growth <= SLACK_BYTES,
        "resident set grew {growth} bytes from 10 % to 100 % of the run (allowed {SLACK_BYTES})"
    );
    assert!(record.angles.is_none(), "no sensor: no angle history kept");
}
