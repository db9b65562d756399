//! ILD links over real pty pairs: the value stream with arrival times, command/reply exchange
//! (also in the middle of the stream), resynchronisation, timeouts, hang-up and raw capture.

mod support;

use std::time::{Duration, Instant};

use scanhil_protocol::ild::command::{
    ECHO_DONE_SUFFIX, IldCommand, IldCommandError, IldReply, LineEnding, MeasuringRate,
};
use scanhil_protocol::ild::stream::encode_cycle;
use scanhil_protocol::ild::{IldError, IldValue};
use scanhil_protocol::link::{ByteCapture, IldLink, LinkError, LinkUri, PtyPair, Role, SerialLine};

use support::SharedBuffer;

const REPLY_WAIT: Duration = Duration::from_secs(2);

/// The emulated sensor on a pty master; the host opened the slave path by URI.
fn host_and_device() -> (IldLink, IldLink) {
    let pair = PtyPair::open().unwrap();
    let uri: LinkUri = format!("ild:{}", pair.slave_path().display())
        .parse()
        .unwrap();
    let device = IldLink::open_pty(pair, 691_200, Role::Device).unwrap();
    let host = IldLink::open(&uri, Role::Host).unwrap();
    (host, device)
}

/// The host on a pty master, a raw line on the slave for the test to play the sensor by hand.
fn host_and_raw_sensor() -> (IldLink, SerialLine) {
    let pair = PtyPair::open().unwrap();
    let path = pair.slave_path().to_owned();
    let raw = SerialLine::open(&path, 691_200, "raw").unwrap();
    (IldLink::open_pty(pair, 691_200, Role::Host).unwrap(), raw)
}

#[tokio::test]
async fn cycles_arrive_in_order_with_their_extras_and_arrival_times() {
    let (mut host, mut device) = host_and_device();
    host.set_values_per_cycle(2);
    let sent: Vec<[u32; 2]> = vec![[643, 0], [32_000, 1], [262_076, 2], [64_876, 262_143]];
    for cycle in &sent {
        device.send_cycle(cycle).await.unwrap();
    }
    let mut last_arrival = None;
    for (k, cycle) in sent.iter().enumerate() {
        let got = host.recv_cycle().await.unwrap();
        assert_eq!(got.distance, IldValue::from_raw(cycle[0]));
        assert_eq!(got.extras, vec![cycle[1]]);
        assert_eq!(got.offset, 6 * k as u64);
        if let Some(previous) = last_arrival {
            assert!(got.arrived >= previous);
        }
        last_arrival = Some(got.arrived);
    }
    assert_eq!(sent[2][0], 262_076);
    assert!(matches!(
        IldValue::from_raw(sent[2][0]),
        IldValue::Error(IldError::NoPeak)
    ));
    assert_eq!(host.counters().incomplete_cycles, 0);
}

#[tokio::test]
async fn the_host_resynchronises_after_lost_and_corrupted_bytes() {
    let (mut host, raw) = host_and_raw_sensor();
    let mut bytes = encode_cycle(&[1000]);
    let broken = encode_cycle(&[2000]);
    bytes.extend_from_slice(&broken[..2]); // its H byte is lost
    // Two stray H bytes: the first completes the broken value's L M as a further value of a
    // cycle whose start was lost (an orphan), the second is skipped.
    bytes.extend_from_slice(&[0xC0, 0xFF]);
    bytes.extend_from_slice(&encode_cycle(&[3000]));
    raw.write_all(&bytes).await.unwrap();
    assert_eq!(
        host.recv_cycle().await.unwrap().distance,
        IldValue::Distance(1000)
    );
    assert_eq!(
        host.recv_cycle().await.unwrap().distance,
        IldValue::Distance(3000)
    );
    let counters = host.counters();
    assert_eq!(counters.sync_losses, 1, "{counters:?}");
    assert_eq!(counters.skipped_bytes, 1, "{counters:?}");
    assert_eq!(counters.orphan_values, 1, "{counters:?}");
}

#[tokio::test]
async fn a_cycle_missing_its_extras_is_delivered_and_counted_incomplete() {
    let (mut host, raw) = host_and_raw_sensor();
    host.set_values_per_cycle(2);
    let mut bytes = encode_cycle(&[1000]);
    bytes.extend_from_slice(&encode_cycle(&[2000, 7]));
    raw.write_all(&bytes).await.unwrap();
    let first = host.recv_cycle().await.unwrap();
    assert_eq!(
        (first.distance, first.extras.len()),
        (IldValue::Distance(1000), 0)
    );
    let second = host.recv_cycle().await.unwrap();
    assert_eq!(second.extras, vec![7]);
    assert_eq!(host.counters().incomplete_cycles, 1);
}

/// Device side of one exchange: receives a command line and answers it.
async fn answer_one(device: &mut IldLink, echo: bool) -> IldCommand {
    let request = device.recv_command().await.unwrap();
    let echo_line = echo.then(|| request.line.clone());
    let command = request.command.unwrap();
    let reply = match &command {
        IldCommand::GetInfo => IldReply {
            echo: echo_line,
            lines: vec!["Name: ILD2300".into(), "Measuring range: 100.00mm".into()],
            ..IldReply::default()
        },
        _ => IldReply {
            echo: echo_line.map(|line| line + ECHO_DONE_SUFFIX),
            ..IldReply::default()
        },
    };
    device.reply(&reply).await.unwrap();
    command
}

#[tokio::test]
async fn commands_and_replies_cross_the_link_with_and_without_echo() {
    let (mut host, mut device) = host_and_device();
    let (reply, command) = tokio::join!(
        host.command(&IldCommand::GetInfo, REPLY_WAIT),
        answer_one(&mut device, false)
    );
    assert_eq!(command, IldCommand::GetInfo);
    let reply = reply.unwrap();
    assert!(reply.is_ok());
    assert_eq!(reply.lines[0], "Name: ILD2300");

    let (reply, _) = tokio::join!(
        host.command(&IldCommand::Echo(Some(true)), REPLY_WAIT),
        answer_one(&mut device, false)
    );
    assert!(reply.unwrap().is_ok());
    let rate = IldCommand::MeasRate(Some(MeasuringRate::Khz20));
    let (reply, command) = tokio::join!(
        host.command(&rate, REPLY_WAIT),
        answer_one(&mut device, true)
    );
    assert_eq!(command, rate);
    let reply = reply.unwrap();
    assert_eq!(reply.echo.as_deref(), Some("MEASRATE 20 ok"));
    assert!(reply.lines.is_empty() && reply.is_ok(), "{reply:?}");
}

#[tokio::test]
async fn the_host_ends_its_lines_in_cr_lf_and_an_lf_device_ignores_cr_alone() {
    let (mut host, mut device) = host_and_device();
    device.set_line_ending(LineEnding::Lf);
    // CR LF is taken by either kind of device.
    let (reply, command) = tokio::join!(
        host.command(&IldCommand::GetInfo, REPLY_WAIT),
        answer_one(&mut device, false)
    );
    assert!(reply.unwrap().is_ok());
    assert_eq!(command, IldCommand::GetInfo);
    // CR alone ends no line at an LF device: no reply.
    let lone_cr = tokio::select! {
        reply = host.command_ending_in(&IldCommand::GetInfo, "\r", Duration::from_millis(100)) => reply,
        request = device.recv_command() => panic!("an LF device took a CR line: {request:?}"),
    };
    assert!(
        matches!(lone_cr, Err(LinkError::NoReply { .. })),
        "{lone_cr:?}"
    );
    // The CR was ignored but its line's text waits in the device: the next line ending in LF
    // runs on from it, and is refused.
    let stale = async {
        let request = device.recv_command().await.unwrap();
        let error = request.command.clone().unwrap_err();
        device
            .reply(&IldReply::refusal(None, &error))
            .await
            .unwrap();
        request.line
    };
    let (reply, line) = tokio::join!(
        host.command_ending_in(&IldCommand::Echo(Some(false)), "\n", REPLY_WAIT),
        stale
    );
    assert_eq!(line, "GETINFOECHO OFF");
    assert!(!reply.unwrap().is_ok());
    // LF alone is a line end.
    let (reply, command) = tokio::join!(
        host.command_ending_in(&IldCommand::Echo(Some(false)), "\n", REPLY_WAIT),
        answer_one(&mut device, false)
    );
    assert!(reply.unwrap().is_ok());
    assert_eq!(command, IldCommand::Echo(Some(false)));
}

#[tokio::test]
async fn the_device_refuses_unknown_and_malformed_commands() {
    let pair = PtyPair::open().unwrap();
    let path = pair.slave_path().to_owned();
    let mut device = IldLink::open_pty(pair, 691_200, Role::Device).unwrap();
    let mut raw = SerialLine::open(&path, 691_200, "raw").unwrap();
    raw.write_all(b"FROB 1\r\nMEASRATE fast\r").await.unwrap();
    let unknown = device.recv_command().await.unwrap();
    assert_eq!(unknown.line, "FROB 1");
    let error = unknown.command.unwrap_err();
    assert!(matches!(error, IldCommandError::UnknownCommand(_)));
    device
        .reply(&IldReply::refusal(None, &error))
        .await
        .unwrap();
    let mut answer = Vec::new();
    while !answer.ends_with(b"->") {
        let mut buf = [0; 64];
        let n = raw.read(&mut buf).await.unwrap();
        answer.extend_from_slice(&buf[..n]);
    }
    assert!(
        answer.starts_with(b"E01"),
        "{}",
        String::from_utf8_lossy(&answer)
    );
    let wrong = device.recv_command().await.unwrap();
    assert!(matches!(
        wrong.command,
        Err(IldCommandError::WrongParameter { .. })
    ));
}

#[tokio::test]
async fn a_reply_in_the_middle_of_the_stream_leaves_the_later_values_intact() {
    let (mut host, mut raw) = host_and_raw_sensor();
    let exchange = async {
        let mut got = Vec::new();
        while !got.ends_with(b"\n") {
            let mut buf = [0; 64];
            let n = raw.read(&mut buf).await.unwrap();
            got.extend_from_slice(&buf[..n]);
        }
        assert_eq!(got, b"OUTPUT NONE\r\n");
        let mut bytes = encode_cycle(&[1234]); // in flight before the sensor stopped
        bytes.extend_from_slice(b"\r\n->");
        bytes.extend_from_slice(&encode_cycle(&[4321]));
        raw.write_all(&bytes).await.unwrap();
    };
    let stop = IldCommand::Output(Some("NONE".into()));
    let (reply, ()) = tokio::join!(host.command(&stop, REPLY_WAIT), exchange);
    assert!(reply.unwrap().is_ok());
    assert_eq!(
        host.recv_cycle().await.unwrap().distance,
        IldValue::Distance(4321)
    );
}

#[tokio::test]
async fn timeouts_fire_on_a_silent_sensor() {
    let (mut host, _device) = host_and_device();
    let started = Instant::now();
    assert!(
        host.recv_cycle_timeout(Duration::from_millis(30))
            .await
            .unwrap()
            .is_none()
    );
    assert!(started.elapsed() >= Duration::from_millis(30));
    assert!(host.try_recv_cycle().unwrap().is_none());

    let error = host
        .command(&IldCommand::GetInfo, Duration::from_millis(50))
        .await
        .unwrap_err();
    assert!(matches!(error, LinkError::NoReply { .. }), "{error}");
    assert!(error.to_string().contains("`GETINFO`"), "{error}");
}

#[tokio::test]
async fn the_host_sees_the_sensor_hang_up() {
    let (mut host, mut device) = host_and_device();
    device.send_cycle(&[5]).await.unwrap();
    assert_eq!(
        host.recv_cycle().await.unwrap().distance,
        IldValue::Distance(5)
    );
    drop(device);
    let error = host.recv_cycle().await.unwrap_err();
    assert!(matches!(error, LinkError::HangUp { .. }), "{error}");
    assert!(error.to_string().starts_with("ild:/dev/pts/"), "{error}");
}

#[tokio::test]
async fn the_raw_capture_holds_exactly_the_bytes_that_crossed() {
    let (mut host, mut device) = host_and_device();
    let received = SharedBuffer::default();
    let sent = SharedBuffer::default();
    host.set_capture(ByteCapture::new(received.clone()).with_sent(sent.clone()));
    let mut expected = Vec::new();
    for k in 0..50u32 {
        device.send_cycle(&[k * 1000]).await.unwrap();
        expected.extend_from_slice(&encode_cycle(&[k * 1000]));
    }
    for _ in 0..50 {
        host.recv_cycle().await.unwrap();
    }
    let (reply, _) = tokio::join!(
        host.command(&IldCommand::GetInfo, REPLY_WAIT),
        answer_one(&mut device, false)
    );
    reply.unwrap();
    host.flush_capture().unwrap();
    let received = received.bytes();
    assert_eq!(&received[..expected.len()], &expected[..]);
    assert!(received.ends_with(b"->"));
    assert_eq!(sent.bytes().as_slice(), b"GETINFO\r\n");
}

/// The controller's default set-up: host on the master, the emulated sensor opens the slave
/// path by URI.
#[tokio::test]
async fn controller_flow_host_on_the_master_sensor_on_the_slave_path() {
    let pair = PtyPair::open().unwrap();
    let sensor_uri: LinkUri = format!("ild:{}@691200", pair.slave_path().display())
        .parse()
        .unwrap();
    let mut host = IldLink::open_pty(pair, 691_200, Role::Host).unwrap();
    let sensor = tokio::spawn(async move {
        let mut sensor = IldLink::open(&sensor_uri, Role::Device).unwrap();
        assert_eq!(answer_one(&mut sensor, false).await, IldCommand::GetInfo);
        for raw in [100, 200, 300] {
            sensor.send_cycle(&[raw]).await.unwrap();
        }
        let error = sensor.recv_command().await.unwrap_err();
        assert!(matches!(error, LinkError::HangUp { .. }), "{error}");
    });
    let reply = host
        .command(&IldCommand::GetInfo, REPLY_WAIT)
        .await
        .unwrap();
    assert_eq!(reply.lines[1], "Measuring range: 100.00mm");
    for raw in [100, 200, 300] {
        assert_eq!(
            host.recv_cycle().await.unwrap().distance,
            IldValue::Distance(raw)
        );
    }
    drop(host);
    sensor.await.unwrap();
}
