//! The host's lockstep loop as a state machine, without I/O: frames fed in by hand, what it
//! sends, when it stops and how it ends.

use std::path::Path;
use std::time::Duration;

use scanhil_controller::run::host_inbox::HostInbox;
use scanhil_controller::run::host_loop::{Heard, HostAction, HostLoop, LoopRecord};
use scanhil_controller::run::loop_error::LoopError;
use scanhil_controller::run::power_backoff::PowerBackoff;
use scanhil_controller::scan_controller::ScanController;
use scanhil_controller::settings::ControllerSettings;
use scanhil_controller::trajectory::Trajectory;
use scanhil_protocol::can::{CanFrame, CanId};
use scanhil_protocol::message::{
    AngleReading, CoilCommand, Fault, FaultKind, Message, NodeId, NodeState, Status, ids,
};
use scanhil_protocol::plant_units::SensingPair;

/// A host loop of `periods` periods, filing into an inbox named `test`.
fn host_loop<'a>(
    controller: &'a mut ScanController,
    trajectory: &'a Trajectory,
    periods: u64,
) -> HostLoop<'a> {
    let record = LoopRecord::new(controller.period_s(), periods);
    HostLoop::new(controller, trajectory, record, HostInbox::new("test"))
}

fn controller() -> ScanController {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/controllers/pid-series.json");
    ControllerSettings::load(&path).unwrap().build().unwrap()
}

fn trajectory() -> Trajectory {
    Trajectory::Lissajous {
        alpha_hz: 52.0,
        beta_hz: 27.0,
        alpha_amplitude_rad: 0.01,
        beta_amplitude_rad: 0.005,
        relative_phase_rad: 0.0,
    }
}

fn now() -> tokio::time::Instant {
    tokio::time::Instant::now()
}

fn reading(seq: u16) -> CanFrame {
    let angles = SensingPair {
        alpha: 1e-4,
        beta: -2e-4,
    };
    Message::AngleReading(AngleReading::from_rad(seq, angles))
        .encode()
        .unwrap()
}

fn node_status(state: NodeState, step: u32) -> CanFrame {
    Message::Status(Status {
        node: NodeId::Fsm,
        state,
        step,
        node_time_us: 0,
    })
    .encode()
    .unwrap()
}

fn decoded(action: HostAction) -> Vec<(Message, f64)> {
    let HostAction::Send(frames) = action else {
        panic!("expected frames to send, got {action:?}");
    };
    decode_all(&frames)
}

/// The frames of a stop: the zero command, the end of the run (never faulted).
fn decoded_stop(action: HostAction) -> Vec<(Message, f64)> {
    let HostAction::SendStop(frames) = action else {
        panic!("expected the stop's frames, got {action:?}");
    };
    decode_all(&frames)
}

/// The messages as the node reads them: through the bytes a link carries.
fn decode_all(
    frames: &[scanhil_controller::run::host_loop::StampedMessage],
) -> Vec<(Message, f64)> {
    frames
        .iter()
        .map(|f| (Message::decode(&f.frame().unwrap()).unwrap(), f.t_s))
        .collect()
}

#[test]
fn a_run_sends_command_and_step_per_period_counts_what_it_files_and_ends_with_the_node() {
    let mut controller = controller();
    let period_s = controller.period_s();
    let trajectory = trajectory();
    let mut host = host_loop(&mut controller, &trajectory, 2);
    for k in 0..2u64 {
        let sent = decoded(host.next_action());
        assert_eq!(sent.len(), 2);
        assert!(matches!(sent[0].0, Message::CoilCommand(c) if c.seq == k as u16));
        assert_eq!(sent[1].0, Message::Step { step: k as u32 });
        assert!(sent.iter().all(|(_, t_s)| *t_s == k as f64 * period_s));
        let awaited = HostAction::AwaitReading {
            period: k,
            t_s: (k + 1) as f64 * period_s,
        };
        assert_eq!(host.next_action(), awaited);
        // Foreign, malformed, a stale reading and a status: filed, the period goes on.
        let foreign = CanFrame::new(CanId::standard(0x555).unwrap(), &[1, 2]).unwrap();
        let malformed = CanFrame::new(CanId::standard(ids::ANGLE_READING).unwrap(), &[0]).unwrap();
        assert_eq!(host.on_frame(foreign, now()), Heard::Nothing);
        assert_eq!(host.on_frame(malformed, now()), Heard::Nothing);
        assert_eq!(host.on_frame(reading(k as u16 + 7), now()), Heard::Nothing);
        let status = node_status(NodeState::Running, k as u32);
        assert_eq!(host.on_frame(status, now()), Heard::Nothing);
        assert_eq!(host.next_action(), awaited);
        assert_eq!(host.on_frame(reading(k as u16), now()), Heard::Reading(k));
    }
    // The end: zero current (the next period's counter), then the controller's Status.
    let end = decoded_stop(host.next_action());
    assert!(
        matches!(end[..], [(Message::CoilCommand(c), t0), (Message::Status(s), t1)]
            if c.seq == 2 && c.current_a_ua == 0 && c.current_b_ua == 0
            && s.node == NodeId::Controller && s.state == NodeState::Ready
            && t0 == 2.0 * period_s && t1 == t0),
        "{end:?}"
    );
    assert!(host.record().coils_at_end.zero_commanded);
    assert!(!host.record().coils_at_end.acknowledged);
    assert_eq!(
        host.next_action(),
        HostAction::AwaitNodeReady {
            t_s: 2.0 * period_s
        }
    );
    assert_eq!(host.on_frame(reading(1), now()), Heard::Nothing);
    let ready = node_status(NodeState::Ready, 2);
    assert_eq!(host.on_frame(ready, now()), Heard::Ended);
    assert_eq!(host.next_action(), HostAction::Done);

    let (record, inbox) = host.finish();
    assert_eq!(record.periods_done, 2);
    assert!(record.stopped_by.is_none());
    assert!(
        record.coils_at_end.acknowledged,
        "the node's Status(ready) after the zero acknowledges it"
    );
    let counters = inbox.counters();
    assert_eq!(counters.foreign_frames, 2);
    assert_eq!(counters.malformed_frames, 2);
    assert_eq!(
        counters.angle_readings, 4,
        "the reading after the end is not counted"
    );
    assert_eq!(counters.angle_sequence_gaps, 2);
    // Two running heartbeats and the end: the first heartbeat and the change to ready are
    // kept, the repeated heartbeat only counted.
    assert_eq!(counters.status_frames, 3);
    let events = inbox.events();
    assert_eq!(events.len(), 2, "{events:?}");
    assert_eq!(
        events[0].t_s, period_s,
        "filed at the loop time it was awaited at"
    );
    assert_eq!(events[1].status, Some(NodeState::Ready));
    assert_eq!(events[1].t_s, 2.0 * period_s);
}

#[test]
fn the_nodes_link_timeout_fault_stops_the_run_with_a_zero_command() {
    let mut controller = controller();
    let period_s = controller.period_s();
    let trajectory = trajectory();
    let mut host = host_loop(&mut controller, &trajectory, 10);
    decoded(host.next_action());
    assert_eq!(host.on_frame(reading(0), now()), Heard::Reading(0));
    decoded(host.next_action());
    let fault = Message::Fault(Fault {
        node: NodeId::Fsm,
        kind: FaultKind::LinkTimeout,
        detail: 200,
        step: 1,
    })
    .encode()
    .unwrap();
    assert_eq!(host.on_frame(fault, now()), Heard::Stopped);
    let zero = decoded_stop(host.next_action());
    assert!(
        matches!(zero[..], [(Message::CoilCommand(c), t_s)] if c.seq == 1
            && c.current_a_ua == 0 && c.current_b_ua == 0 && t_s == 2.0 * period_s),
        "{zero:?}"
    );
    assert_eq!(host.next_action(), HostAction::Done);
    let (record, _) = host.finish();
    assert_eq!(record.periods_done, 1);
    assert!(record.coils_at_end.zero_commanded && !record.coils_at_end.acknowledged);
    assert!(matches!(
        record.stopped_by,
        Some(LoopError::NodeFault {
            kind: FaultKind::LinkTimeout,
            ..
        })
    ));
}

#[test]
fn silence_stops_a_period_but_ends_the_run_quietly_after_the_last() {
    let timeout = |period| LoopError::LinkTimeout {
        link: "test".into(),
        period,
        periods: 1,
        waited: Duration::ZERO,
    };
    let mut controller = controller();
    let trajectory = trajectory();
    let mut host = host_loop(&mut controller, &trajectory, 1);
    decoded(host.next_action());
    assert_eq!(host.on_frame(reading(0), now()), Heard::Reading(0));
    decoded_stop(host.next_action());
    host.on_error(timeout(1));
    assert_eq!(host.next_action(), HostAction::Done);
    let (record, _) = host.finish();
    assert!(
        record.stopped_by.is_none(),
        "a node without the end exchange"
    );
    assert!(record.coils_at_end.zero_commanded && !record.coils_at_end.acknowledged);

    let mut host = host_loop(&mut controller, &trajectory, 1);
    decoded(host.next_action());
    host.on_error(timeout(0));
    decoded_stop(host.next_action());
    assert_eq!(host.next_action(), HostAction::Done);
    let (record, _) = host.finish();
    assert_eq!(record.periods_done, 0);
    assert!(matches!(
        record.stopped_by,
        Some(LoopError::LinkTimeout { .. })
    ));
}

/// Each period's command is the controller's answer to the reference at that period's start,
/// scaled by the power back-off, and each reading is recorded against the reference at the
/// instant it was taken (the one the next period commands), computed once for both.
#[test]
fn each_period_commands_the_reference_at_its_start_and_records_against_the_next() {
    let (mut looped, mut by_hand) = (controller(), controller());
    let trajectory = trajectory();
    let period_s = looped.period_s();
    let periods = 200;
    let backoff = PowerBackoff::new(Some(50.0), 30.0, 0.9, 20);
    let mut twin_backoff = backoff.clone();
    let mut host = host_loop(&mut looped, &trajectory, periods).with_backoff(backoff);
    let mut measured = SensingPair::default();
    let power_limit = Message::Fault(Fault {
        node: NodeId::Fsm,
        kind: FaultKind::PowerLimit,
        detail: 31_000,
        step: 50,
    })
    .encode()
    .unwrap();
    for k in 0..periods {
        let HostAction::Send(frames) = host.next_action() else {
            panic!("period {k}'s frames");
        };
        let reference = |k: u64, backoff: &PowerBackoff| {
            let unscaled = trajectory.reference_rad(k as f64 * period_s);
            SensingPair {
                alpha: unscaled.alpha * backoff.scale_at(k),
                beta: unscaled.beta * backoff.scale_at(k),
            }
        };
        let command = by_hand.step(reference(k, &twin_backoff), measured);
        assert_eq!(
            Message::decode(&frames[0].frame().unwrap()).unwrap(),
            Message::CoilCommand(CoilCommand::from_amps(k as u16, command)),
            "period {k}"
        );
        assert!(matches!(
            host.next_action(),
            HostAction::AwaitReading { .. }
        ));
        if k == 50 {
            assert_eq!(host.on_frame(power_limit, now()), Heard::Nothing);
            twin_backoff.on_power_limit(k);
        }
        // A mirror that follows exactly, but for the wire's rounding to whole urad.
        let reading = AngleReading::from_rad(k as u16, reference(k + 1, &twin_backoff));
        measured = reading.rad();
        let frame = Message::AngleReading(reading).encode().unwrap();
        assert_eq!(host.on_frame(frame, now()), Heard::Reading(k));
    }
    assert!(
        twin_backoff.scale_at(periods) < 0.9,
        "the back-off acted: {}",
        twin_backoff.scale_at(periods)
    );
    let (record, _) = host.finish();
    let run = record.tracking.summary().whole_run;
    assert_eq!(run.periods, periods);
    for axis in [run.alpha, run.beta] {
        assert!(axis.max_abs_urad <= 0.5, "{axis:?}");
        assert!(axis.reference_peak_urad > 2000.0, "{axis:?}");
    }
}
