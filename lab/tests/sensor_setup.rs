//! The host's sensor set-up against the emulated sensor's port (the emulator's real device
//! end) and a scripted device, over real pty pairs: a correct configuration read back, the
//! laser switched off in the stream, the values decoded in the order `GETOUTINFO_RS422` gives,
//! mismatches refused naming both values, a device that answers errors.

use std::path::Path;

use scanhil_controller::rig::RigSensor;
use scanhil_controller::run::sensor_link::SensorLink;
use scanhil_controller::run::sensor_setup::{SensorSetupError, configure};
use scanhil_emulator::scene::Scene;
use scanhil_emulator::sensor::IldSample;
use scanhil_emulator::serve::sensor_port::SensorPort;
use scanhil_protocol::ild::command::{AddValue, AddValueSet, IldCommand, LineEnding};
use scanhil_protocol::ild::{IldError, IldValue, encode_cycle};
use scanhil_protocol::link::{CanLink, LinkError, PtyPair, Role, SerialLine};

fn scene() -> Scene {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes/duplo-2x4-130mm.json");
    Scene::load(&path).unwrap()
}

/// The host's sensor link on a pty master, the emulated sensor's port on its slave path.
fn host_and_emulated_sensor(scene: &Scene) -> (SensorLink, SensorPort) {
    let pair = PtyPair::open().unwrap();
    let uri = format!("ild:{}", pair.slave_path().display());
    let (device, _) = SensorPort::open(Some(&uri), scene, LineEnding::CrOrLf).unwrap();
    (SensorLink::on_pty(pair, 691_200).unwrap(), device)
}

/// Runs the set-up while the emulated sensor answers.
async fn set_up(
    host: &mut SensorLink,
    device: &mut SensorPort,
    expected: &RigSensor,
) -> Result<scanhil_controller::run::sensor_setup::ConfiguredSensor, SensorSetupError> {
    let link = host.ild_link_mut().unwrap();
    let (configured, layout) = tokio::select! {
        result = configure(link, expected) => result?,
        error = device.answer_commands() => panic!("the sensor port failed: {error}"),
    };
    host.set_layout(layout);
    Ok(configured)
}

fn sample(counter: u32) -> IldSample {
    IldSample {
        t_s: f64::from(counter) * 5e-5,
        counter,
        value: IldValue::Distance(30_000 + counter),
        true_distance_mm: Some(120.0),
    }
}

#[tokio::test]
async fn the_emulated_sensor_is_configured_and_read_back_then_streams() {
    let scene = scene();
    let (mut host, mut device) = host_and_emulated_sensor(&scene);
    // The counter as well: a cycle of two values, read from GETOUTINFO_RS422.
    let expected = RigSensor {
        extra_values: AddValueSet::of(&[AddValue::Counter]),
        ..expectation(&scene)
    };
    let report = set_up(&mut host, &mut device, &expected).await.unwrap();
    assert_eq!(report.device_name, "ILD2300");
    assert_eq!(report.range_span_mm, 100.0);
    assert_eq!(report.range_start_mm_expected, 70.0);
    assert_eq!(report.measuring_rate_set_hz, 20_000.0);
    assert_eq!(report.measuring_rate_read_back_hz, 20_000.0);
    assert_eq!(report.extra_values, vec!["COUNTER".to_owned()]);
    assert_eq!(
        report.output_values,
        vec!["DIST1".to_owned(), "COUNTER".to_owned()]
    );
    assert_eq!(report.baud_read_back, Some(691_200));
    assert_eq!(
        report.commands,
        [
            "OUTPUT NONE",
            "ECHO OFF",
            "GETINFO",
            "MEASRATE 20",
            "MEASRATE",
            "OUTDIST_RS422 DIST1",
            "OUTADD_RS422 COUNTER",
            "LASERPOW FULL",
            "BAUDRATE",
            "GETOUTINFO_RS422",
            "OUTPUT RS422",
        ]
    );

    // The stream runs with distance and counter; laser off turns the distances into the
    // laser-off error value.
    let mut fsm = CanLink::open_pty(PtyPair::open().unwrap(), None, Role::Device)
        .await
        .unwrap();
    device.offer(&[sample(1), sample(2)]);
    device.emit(1.0, &mut fsm).await.unwrap();
    let link = host.ild_link_mut().unwrap();
    let cycle = link.recv_cycle().await.unwrap();
    assert_eq!(
        (cycle.distance, cycle.extras),
        (IldValue::Distance(30_001), vec![1])
    );
    assert_eq!(link.recv_cycle().await.unwrap().extras, vec![2]);
    let off = tokio::select! {
        reply = link.command(&IldCommand::LaserPower(Some(false)), std::time::Duration::from_secs(1)) => reply.unwrap(),
        error = device.answer_commands() => panic!("{error}"),
    };
    assert!(off.is_ok(), "{off:?}");
    device.offer(&[sample(3)]);
    device.emit(1.0, &mut fsm).await.unwrap();
    let cycle = host.ild_link_mut().unwrap().recv_cycle().await.unwrap();
    assert_eq!(cycle.distance, IldValue::Error(IldError::LaserOff));
    assert_eq!(cycle.extras, vec![3]);
}

#[tokio::test]
async fn the_host_decodes_the_values_in_the_order_getoutinfo_gives() {
    // A sensor whose cycle puts the counter before the distance: the host must not take the
    // first value for the distance.
    let (mut host, device) = scripted_sensor(|command| match command {
        "GETINFO" => "Name: ILD2300\r\nMeasuring range: 100.00mm\r\n->".into(),
        "MEASRATE" => "MEASRATE 20\r\n->".into(),
        "BAUDRATE" => "BAUDRATE 691200\r\n->".into(),
        "GETOUTINFO_RS422" => "COUNTER\r\nDIST1\r\n->".into(),
        "OUTPUT RS422" => [
            b"->".to_vec(),
            encode_cycle(&[41, 30_041]),
            encode_cycle(&[42, 30_042]),
        ]
        .concat(),
        _ => "->".into(),
    });
    let expected = RigSensor {
        extra_values: AddValueSet::of(&[AddValue::Counter]),
        ..expectation(&scene())
    };
    let samples = async {
        let (configured, layout) = configure(host.ild_link_mut().unwrap(), &expected)
            .await
            .unwrap();
        assert_eq!(configured.output_values, ["COUNTER", "DIST1"]);
        host.set_layout(layout);
        let _ = tokio::time::timeout(std::time::Duration::from_millis(300), host.pump()).await;
        host.snapshot().0
    };
    let samples = tokio::select! {
        samples = samples => samples,
        () = device => panic!("the device ended"),
    };
    let got: Vec<(u64, IldValue)> = samples.iter().map(|s| (s.counter, s.value)).collect();
    assert_eq!(
        got,
        [
            (41, IldValue::Distance(30_041)),
            (42, IldValue::Distance(30_042))
        ]
    );
}

#[tokio::test]
async fn a_sensor_sending_other_values_than_the_rig_expects_is_refused() {
    let (mut host, device) = scripted_sensor(|command| match command {
        "GETINFO" => "Name: ILD2300\r\nMeasuring range: 100.00mm\r\n->".into(),
        "MEASRATE" => "MEASRATE 20\r\n->".into(),
        "GETOUTINFO_RS422" => "DIST1\r\nTEMP\r\n->".into(),
        _ => "->".into(),
    });
    let expected = expectation(&scene());
    let error = tokio::select! {
        result = configure(host.ild_link_mut().unwrap(), &expected) => result.unwrap_err(),
        () = device => panic!("the device ended"),
    };
    assert_eq!(
        error.to_string(),
        "sensor sends DIST1 TEMP per cycle (GETOUTINFO_RS422), the rig expects the distance \
         and NONE"
    );
}

/// The set-up's refusal against the emulated sensor when the rig expects `change` of what
/// the scene's sensor is.
async fn refusal(change: impl FnOnce(RigSensor) -> RigSensor) -> String {
    let scene = scene();
    let (mut host, mut device) = host_and_emulated_sensor(&scene);
    let expected = change(expectation(&scene));
    let error = set_up(&mut host, &mut device, &expected).await.unwrap_err();
    error.to_string()
}

#[tokio::test]
async fn a_different_measuring_rate_is_refused_naming_both_rates() {
    let text = refusal(|sensor| RigSensor {
        measuring_rate_hz: 10_000.0,
        ..sensor
    })
    .await;
    assert!(
        text.starts_with("sensor reports measuring rate 20000 Hz, the rig expects 10000 Hz"),
        "{text}"
    );
    assert!(
        text.contains("`MEASRATE 10`: E04 Wrong parameter"),
        "{text}"
    );
}

#[tokio::test]
async fn a_different_measuring_range_or_an_unknown_rate_is_refused() {
    let text = refusal(|sensor| RigSensor {
        range_span_mm: 50.0,
        ..sensor
    })
    .await;
    assert_eq!(
        text,
        "sensor reports measuring range 100.00 mm, the rig expects 50.00 mm"
    );
    let text = refusal(|sensor| RigSensor {
        measuring_rate_hz: 12_345.0,
        ..sensor
    })
    .await;
    assert!(text.contains("12345 Hz"), "{text}");
}

/// The host's sensor link on a pty's slave path, and a scripted device on its master
/// ([`scripted_device`]) to run beside it.
fn scripted_sensor(
    answer: impl Fn(&str) -> Vec<u8>,
) -> (SensorLink, impl std::future::Future<Output = ()>) {
    let pair = PtyPair::open().unwrap();
    let uri = format!("ild:{}", pair.slave_path().display())
        .parse()
        .unwrap();
    let device = scripted_device(SerialLine::from_pty(pair, "device").unwrap(), answer);
    (SensorLink::open(&uri).unwrap(), device)
}

/// A scripted device on the pty master: answers each command line (ended by LF, a CR before
/// it dropped) by `answer`.
async fn scripted_device(mut line: SerialLine, answer: impl Fn(&str) -> Vec<u8>) {
    let mut text = Vec::new();
    let mut buf = [0; 256];
    loop {
        let n = match line.read(&mut buf).await {
            Ok(n) => n,
            Err(LinkError::HangUp { .. }) => return,
            Err(error) => panic!("{error}"),
        };
        for &byte in &buf[..n] {
            match byte {
                b'\n' => {
                    let command = String::from_utf8_lossy(&text).into_owned();
                    text.clear();
                    line.write_all(&answer(&command)).await.unwrap();
                }
                b'\r' => {}
                _ => text.push(byte),
            }
        }
    }
}

#[tokio::test]
async fn a_device_answering_errors_fails_the_set_up_naming_command_and_error() {
    let expected = expectation(&scene());
    // Every command refused.
    let (mut host, device) = scripted_sensor(|_| b"E32 Timeout\r\n->".to_vec());
    let error = tokio::select! {
        result = configure(host.ild_link_mut().unwrap(), &expected) => result.unwrap_err(),
        () = device => panic!("the device ended"),
    };
    assert_eq!(
        error.to_string(),
        "sensor refused `OUTPUT NONE`: E32 Timeout"
    );

    // A sensor that does not know the laser command (its name is unchecked).
    let (mut host, device) = scripted_sensor(|command| match command {
        "GETINFO" => "Name: ILD2300\r\nSerial: 1\r\nMeasuring range: 100.00mm\r\n->".into(),
        "MEASRATE" => "MEASRATE 20\r\n->".into(),
        c if c.starts_with("LASERPOW") => "E01 Unknown command\r\n->".into(),
        _ => "->".into(),
    });
    let error = tokio::select! {
        result = configure(host.ild_link_mut().unwrap(), &expected) => result.unwrap_err(),
        () = device => panic!("the device ended"),
    };
    assert_eq!(
        error.to_string(),
        "sensor refused `LASERPOW FULL`: E01 Unknown command"
    );
}

/// What the host expects of the scene's sensor: its rate and range, the distance alone at the
/// factory baud rate.
fn expectation(scene: &Scene) -> RigSensor {
    let sensor = scene.sensor.unwrap_or_default();
    RigSensor {
        measuring_rate_hz: sensor.measuring_rate_hz,
        range_start_mm: sensor.range.start_mm,
        range_span_mm: sensor.range.span_mm,
        extra_values: AddValueSet::NONE,
        baud: 691_200,
    }
}
