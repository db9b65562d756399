//! Lockstep determinism across the sensor's transports: the sensor's samples as Distance frames
//! on the mirror's CAN link (`--sensor fsm`, as on a CAN bus) and on its own ILD RS422 stream
//! (`--sensor pty`) give the same scan, bit for bit, every sample included, and the run ends
//! with the end-of-run exchange on the mirror link (the node's Status(ready) last).

use crate::util::{assert_success, decode_candump, fixture, report, run_scanhil};
use scanhil_protocol::message::{Message, NodeId, NodeState};

#[test]
fn distance_frames_and_the_ild_stream_give_the_same_scan() {
    let scan = |sensor: &str| {
        let out = tempfile::tempdir().expect("a temporary folder");
        let output = run_scanhil(&[
            "scan",
            &fixture("scenarios/vcan-small.json"),
            "--fsm",
            "pty",
            "--sensor",
            sensor,
            "--out",
            out.path().to_str().expect("UTF-8 path"),
        ]);
        assert_success(&output, &format!("scanhil scan --sensor {sensor}"));
        out
    };
    let on_can = scan("fsm");
    let on_ild = scan("pty");
    for file in ["points.ply", "height_map.csv", "progressive.svg"] {
        let can = std::fs::read(on_can.path().join(file)).expect("the CAN run's file");
        let ild = std::fs::read(on_ild.path().join(file)).expect("the ILD run's file");
        assert!(!can.is_empty(), "{file} is empty");
        assert!(
            can == ild,
            "{file} differs between the sensor on CAN and on its ILD stream"
        );
    }
    let (can, ild) = (report(on_can.path()), report(on_ild.path()));
    let periods = &can["periods"]["planned"];
    for (name, run) in [("CAN", &can), ("ILD", &ild)] {
        assert_eq!(
            &run["samples"]["sensor_samples"], periods,
            "{name}: one sample per period at 20 kHz, the last period's included"
        );
        assert_eq!(
            run["emulator"]["killed"], false,
            "{name}: the emulator was killed"
        );
    }
    assert_eq!(can["imaging"]["feature"], ild["imaging"]["feature"]);
    // The ILD sensor was configured and read back before the run; on CAN there is no line.
    let setup = &ild["sensor_setup"];
    assert_eq!(setup["status"], "configured", "{setup}");
    assert_eq!(setup["device_name"], "ILD2300", "{setup}");
    assert_eq!(setup["measuring_rate_read_back_hz"], 20000.0, "{setup}");
    assert_eq!(setup["range_span_mm"], 100.0, "{setup}");
    let skipped = &can["sensor_setup"];
    assert_eq!(skipped["status"], "skipped", "{skipped}");
    assert!(
        skipped["reason"]
            .as_str()
            .is_some_and(|r| r.contains("`fsm`")),
        "{skipped}"
    );

    let recording = decode_candump(&on_can.path().join("fsm.log"));
    let text = std::fs::read_to_string(on_can.path().join("fsm.log")).expect("fsm.log");
    let last = text.lines().last().expect("a recorded frame");
    let (id, data) = last
        .split(' ')
        .nth(2)
        .and_then(|frame| frame.split_once('#'))
        .expect("a candump frame");
    let frame = scanhil_protocol::can::CanFrame::new(
        scanhil_protocol::can::CanId::standard(u16::from_str_radix(id, 16).expect("hex id"))
            .expect("an 11-bit id"),
        &scanhil_protocol::can::parse_hex(data.as_bytes()).expect("hex data"),
    )
    .expect("a classical frame");
    match Message::decode(&frame).expect("the last frame decodes") {
        Message::Status(status) => {
            assert_eq!(status.node, NodeId::Fsm, "the last frame is the node's");
            assert_eq!(status.state, NodeState::Ready, "the node ends ready");
        }
        other => panic!("the run ends with {other:?}, not the node's Status(ready)"),
    }
    assert!(recording.frames > 0);
}
