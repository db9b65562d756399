//! How a link error ends a serve run: which outcome, `ended_by` and exit status each error
//! gives, the mirror node's state after a link failure (coils at zero, state fault), and the
//! shell's wind-down on a real SLCAN pty (the fault frame reaches the host, the reason is in
//! the report). The whole process on SocketCAN, bus-off included, is `serve_vcan.rs` (VM).

use std::io;
use std::path::Path;
use std::time::Duration;

use scanhil_emulator::serve::lockstep_node::last_frames;
use scanhil_emulator::serve::mirror_node::MirrorNode;
use scanhil_emulator::serve::sensor_port::SensorPort;
use scanhil_emulator::serve::wind_down::end_on_link_error;
use scanhil_emulator::serve::{RunEnd, ServeLinks, ServeOutcome, load_plant};
use scanhil_protocol::link::{CanLink, LinkError, LinkUri, PtyPair, Role};
use scanhil_protocol::message::{FaultKind, Message, NodeId, NodeState};
use scanhil_protocol::plant_units::ActuatorPair;

fn bus_off() -> LinkError {
    LinkError::BusOff {
        link: "socketcan:can0".into(),
        detail: "controller problems: bus-off".into(),
    }
}

fn io_failure() -> LinkError {
    LinkError::Io {
        link: "slcan:/dev/ttyACM0".into(),
        op: "read",
        source: io::Error::from_raw_os_error(EPROTO),
    }
}

/// Linux's `EPROTO`: an OS error no line turns into a hang-up.
const EPROTO: i32 = 71;

/// A node holding 1.5 A / -0.5 A on its coils.
fn node_with_current() -> MirrorNode {
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../fixtures/scenes/protocol-only.json"
    );
    let (_, plant) = load_plant(Path::new(scene), None).unwrap();
    let mut node = MirrorNode::new(plant);
    node.on_command(0, ActuatorPair { a: 1.5, b: -0.5 });
    node.step().unwrap();
    assert_eq!(node.held_command_a(), ActuatorPair { a: 1.5, b: -0.5 });
    node
}

#[test]
fn each_link_error_ends_the_run_as_its_kind_says() {
    let cases = [
        (bus_off(), RunEnd::BusOff, ServeOutcome::LinkFailed, 3),
        (
            io_failure(),
            RunEnd::LinkFailed,
            ServeOutcome::LinkFailed,
            3,
        ),
        (
            LinkError::Protocol {
                link: "ild:/dev/ttyUSB0".into(),
                detail: "a line longer than 256 bytes".into(),
            },
            RunEnd::LinkFailed,
            ServeOutcome::LinkFailed,
            3,
        ),
        (
            LinkError::HangUp {
                link: "slcan:/dev/pts/3".into(),
            },
            RunEnd::HangUp,
            ServeOutcome::Finished,
            0,
        ),
        (
            LinkError::ChannelClosed {
                link: "slcan:/dev/pts/3".into(),
            },
            RunEnd::HostClosedChannel,
            ServeOutcome::Finished,
            0,
        ),
    ];
    for (error, ended_by, outcome, exit_status) in cases {
        assert_eq!(RunEnd::of_link_error(&error), ended_by, "{error}");
        assert_eq!(ended_by.outcome(), outcome, "{error}");
        assert_eq!(outcome.exit_status(), exit_status, "{error}");
    }
    assert_eq!(RunEnd::Watchdog.outcome().exit_status(), 3);
    // The names the summary carries.
    assert_eq!(serde_json::json!(RunEnd::BusOff), "bus_off");
    assert_eq!(serde_json::json!(RunEnd::LinkFailed), "link_failed");
    assert_eq!(serde_json::json!(ServeOutcome::LinkFailed), "link_failed");
}

#[test]
fn a_link_failure_zeroes_the_coils_and_leaves_the_node_in_fault() {
    let mut node = node_with_current();
    let faults_before = node.counters().faults;
    let fault = node.on_link_failure();
    assert_eq!(fault, (FaultKind::LinkTimeout, 0), "no period missed");
    assert_eq!(node.state(), NodeState::Fault);
    assert_eq!(node.held_command_a(), ActuatorPair::default());
    assert_eq!(node.counters().faults, faults_before + 1);
    // A command after the failure is not applied.
    node.on_command(1, ActuatorPair { a: 1.0, b: 1.0 });
    assert_eq!(node.held_command_a(), ActuatorPair::default());
    let [fault_frame, status_frame] = last_frames(&node, fault).unwrap();
    let Message::Fault(fault) = Message::decode(&fault_frame).unwrap() else {
        panic!("not a fault frame: {fault_frame:?}");
    };
    assert_eq!(
        (fault.node, fault.kind, fault.detail),
        (NodeId::Fsm, FaultKind::LinkTimeout, 0)
    );
    let Message::Status(status) = Message::decode(&status_frame).unwrap() else {
        panic!("not a status frame: {status_frame:?}");
    };
    assert_eq!((status.node, status.state), (NodeId::Fsm, NodeState::Fault));
}

/// The links of a serve run (no sensor) on the device end of an SLCAN pty, and a host opened
/// on it (the `C`, `Sn`, `O` handshake answered by the node's receive meanwhile).
async fn slcan_links() -> (ServeLinks, CanLink) {
    let mut fsm = CanLink::open_pty(PtyPair::open().unwrap(), None, Role::Device)
        .await
        .unwrap();
    fsm.end_run_on_close();
    let uri: LinkUri = format!("slcan:{}", &fsm.name()["slcan:".len()..])
        .parse()
        .unwrap();
    let (host, _) = tokio::join!(CanLink::open(&uri, Role::Host), async {
        while !fsm.channel_open() {
            fsm.recv_timeout(Duration::from_millis(10)).await.unwrap();
        }
    });
    let links = ServeLinks {
        fsm,
        sensor: SensorPort::Off,
    };
    (links, host.unwrap())
}

#[tokio::test]
async fn a_link_failure_on_slcan_sends_the_fault_frame_and_says_why() {
    let (mut links, mut host) = slcan_links().await;
    let mut node = node_with_current();
    let (report, received) = tokio::join!(
        end_on_link_error(&mut node, &mut links, io_failure().into()),
        async {
            let wait = Duration::from_secs(5);
            let fault = host
                .recv_timeout(wait)
                .await
                .unwrap()
                .expect("a fault frame");
            let status = host
                .recv_timeout(wait)
                .await
                .unwrap()
                .expect("a status frame");
            // Closing the channel ends the node's linger at once.
            drop(host);
            (fault, status)
        }
    );
    let report = report.unwrap();
    assert_eq!(report.outcome, ServeOutcome::LinkFailed);
    assert_eq!(report.ended_by, RunEnd::LinkFailed);
    let error = report.error.unwrap();
    assert!(
        error.starts_with("read on slcan:/dev/ttyACM0 failed: "),
        "{error}"
    );
    assert_eq!(node.state(), NodeState::Fault);
    assert_eq!(node.held_command_a(), ActuatorPair::default());
    let (fault, status) = received;
    assert!(
        matches!(Message::decode(&fault), Ok(Message::Fault(f)) if f.kind == FaultKind::LinkTimeout),
        "{fault:?}"
    );
    assert!(
        matches!(Message::decode(&status), Ok(Message::Status(s)) if s.state == NodeState::Fault),
        "{status:?}"
    );
}

#[tokio::test]
async fn a_hang_up_finishes_the_run_and_leaves_the_coils_as_they_were() {
    let (mut links, _host) = slcan_links().await;
    let mut node = node_with_current();
    let hang_up = LinkError::HangUp {
        link: links.fsm.name().to_owned(),
    };
    let report = end_on_link_error(&mut node, &mut links, hang_up.into())
        .await
        .unwrap();
    assert_eq!(report.outcome, ServeOutcome::Finished);
    assert_eq!(report.ended_by, RunEnd::HangUp);
    assert_eq!(report.error, None);
    assert_eq!(node.state(), NodeState::Running);
}

#[tokio::test]
async fn an_error_that_is_no_link_error_is_passed_on() {
    let (mut links, _host) = slcan_links().await;
    let mut node = node_with_current();
    let error = end_on_link_error(&mut node, &mut links, anyhow::anyhow!("a plant error"))
        .await
        .unwrap_err();
    assert_eq!(error.to_string(), "a plant error");
    assert_eq!(node.state(), NodeState::Running);
}
