//! SLCAN links over real pty pairs: host and device ends exchanging frames both ways, garbage
//! and resynchronisation, bit-rate commands, close and reopen, timeouts, hang-up, capture.

mod support;

use std::future::Future;
use std::time::{Duration, Instant};

use scanhil_protocol::can::{CanFrame, CanId};
use scanhil_protocol::candump;
use scanhil_protocol::link::slcan::{DEVICE_VERSION, REPLY_TIMEOUT, REPLY_WINDOW};
use scanhil_protocol::link::{
    CanCapture, CanLink, CaptureClock, LinkError, LinkUri, PtyPair, RecvError, Role, SerialLine,
    VirtualClock, Watchdog,
};

use support::{SharedBuffer, assert_nothing_arrives};

fn std_frame(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::new(CanId::standard(id).unwrap(), data).unwrap()
}

fn sample_frames() -> Vec<CanFrame> {
    vec![
        std_frame(0x100, &[1, 2, 3, 4, 5, 6, 7, 8]),
        CanFrame::new(CanId::extended(0x1ABC_DEF0).unwrap(), &[0xAA]).unwrap(),
        CanFrame::new_remote(CanId::standard(0x7FF).unwrap(), 3).unwrap(),
        CanFrame::new_fd(CanId::standard(0x140).unwrap(), &[0x5A; 12], true, false).unwrap(),
        std_frame(0x000, &[]),
    ]
}

/// Runs `work` while the device end answers the host's commands; the device must not receive
/// a frame meanwhile.
async fn while_serving<T>(device: &mut CanLink, work: impl Future<Output = T>) -> T {
    tokio::pin!(work);
    tokio::select! {
        out = &mut work => out,
        got = device.recv() => panic!("device end received {got:?} while serving a command"),
    }
}

/// A device end on a pty master and a host that opened the slave path by URI.
async fn host_and_device(bitrate: &str) -> (CanLink, CanLink) {
    let pair = PtyPair::open().unwrap();
    let uri: LinkUri = format!("slcan:{}{bitrate}", pair.slave_path().display())
        .parse()
        .unwrap();
    let mut device = CanLink::open_pty(pair, None, Role::Device).await.unwrap();
    let host = while_serving(&mut device, CanLink::open(&uri, Role::Host))
        .await
        .unwrap();
    (host, device)
}

/// A host on a pty master, and the raw slave line for the test to play the adapter by hand.
/// The raw side answers the host's `C`, `Sn`, `O` with CR and returns what it received.
async fn host_and_raw_adapter() -> (CanLink, SerialLine, String) {
    let pair = PtyPair::open().unwrap();
    let path = pair.slave_path().to_owned();
    let mut raw = SerialLine::open(&path, 115_200, "raw").unwrap();
    let host = CanLink::open_pty(pair, Some(1_000_000), Role::Host);
    let adapter = async {
        let mut seen = Vec::new();
        while seen.iter().filter(|&&b| b == b'\r').count() < 3 {
            let mut buf = [0; 64];
            let n = raw.read(&mut buf).await.unwrap();
            seen.extend_from_slice(&buf[..n]);
            let answers = buf[..n].iter().filter(|&&b| b == b'\r').count();
            raw.write_all(&b"\r".repeat(answers)).await.unwrap();
        }
        String::from_utf8(seen).unwrap()
    };
    let (host, seen) = tokio::join!(host, adapter);
    (host.unwrap(), raw, seen)
}

#[tokio::test]
async fn host_and_device_exchange_frames_both_ways_in_order() {
    let (mut host, mut device) = host_and_device("@500k").await;
    assert!(device.channel_open());
    assert_eq!(device.slcan_bitrate(), Some(500_000));
    assert_eq!(host.bus_bitrate(), Some(500_000));

    for frame in sample_frames() {
        host.send(&frame).await.unwrap();
    }
    for expected in sample_frames() {
        assert_eq!(device.recv().await.unwrap(), expected);
    }
    for frame in sample_frames().iter().rev() {
        device.send(frame).await.unwrap();
    }
    for expected in sample_frames().iter().rev() {
        assert_eq!(host.recv().await.unwrap(), *expected);
    }
    let version = while_serving(&mut device, host.adapter_version()).await;
    assert_eq!(version.unwrap().as_deref(), Some(DEVICE_VERSION));
    assert_eq!(host.stats().frames_sent, 5);
    assert_eq!(host.stats().frames_received, 5);
    assert_eq!(device.stats().frames_received, 5);
    assert_eq!(host.stats().slcan.malformed_lines, 0);
}

#[tokio::test]
async fn the_host_sends_c_s_o_on_open() {
    let (host, _raw, seen) = host_and_raw_adapter().await;
    assert_eq!(seen, "C\rS8\rO\r");
    assert_eq!(host.slcan_bitrate(), Some(1_000_000));
}

#[tokio::test]
async fn the_host_skips_garbage_and_adapter_acks_and_resynchronises() {
    let (mut host, raw, _) = host_and_raw_adapter().await;
    raw.write_all(b"t1238DEADBEEF01020304\rgar\xffbage\rz\rZ\r\rt12\rt3213010203\r")
        .await
        .unwrap();
    assert_eq!(
        host.recv().await.unwrap(),
        std_frame(0x123, &[0xDE, 0xAD, 0xBE, 0xEF, 1, 2, 3, 4])
    );
    // `t12` (too short) is one malformed line, then the stream is back in step.
    assert_eq!(host.recv().await.unwrap(), std_frame(0x321, &[1, 2, 3]));
    let stats = host.stats().slcan;
    assert_eq!(stats.malformed_lines, 2, "{stats:?}");
}

#[tokio::test]
async fn an_unsolicited_bel_is_reported_as_a_refused_frame() {
    let (mut host, raw, _) = host_and_raw_adapter().await;
    raw.write_all(b"\x07").await.unwrap();
    let error = host.recv().await.unwrap_err();
    assert!(matches!(error, LinkError::AdapterRefused { .. }), "{error}");
    assert_eq!(host.stats().slcan.refused_frames, 1);
}

#[tokio::test]
async fn the_device_skips_garbage_answers_bel_and_resynchronises() {
    let pair = PtyPair::open().unwrap();
    let path = pair.slave_path().to_owned();
    let mut device = CanLink::open_pty(pair, None, Role::Device).await.unwrap();
    let mut raw = SerialLine::open(&path, 115_200, "raw").unwrap();
    raw.write_all(b"\r\rO\rxyz\rt1238DEADBEEF01020304\r\x00\xff\rt12\rt3213010203\rV\r")
        .await
        .unwrap();
    assert_eq!(
        device.recv().await.unwrap(),
        std_frame(0x123, &[0xDE, 0xAD, 0xBE, 0xEF, 1, 2, 3, 4])
    );
    assert_eq!(device.recv().await.unwrap(), std_frame(0x321, &[1, 2, 3]));
    // Let the device answer the trailing `V`, then read all answers.
    assert!(
        device
            .recv_timeout(Duration::from_millis(50))
            .await
            .unwrap()
            .is_none()
    );
    let mut answers = Vec::new();
    while !answers.ends_with(b"V1013\r") {
        let mut buf = [0; 64];
        let n = raw.read(&mut buf).await.unwrap();
        answers.extend_from_slice(&buf[..n]);
    }
    assert_eq!(answers, b"\r\r\r\x07\x07\x07V1013\r");
    assert_eq!(device.stats().slcan.malformed_lines, 3);
}

#[tokio::test]
async fn bitrate_commands_close_and_reopen() {
    let (mut host, mut device) = host_and_device("@500000").await;
    assert_eq!(device.slcan_bitrate(), Some(500_000));

    while_serving(&mut device, host.close_channel())
        .await
        .unwrap();
    assert!(!device.channel_open());
    assert!(!host.channel_open());
    // A closed adapter forwards nothing, and the host may not transmit.
    device.send(&std_frame(0x110, &[1])).await.unwrap();
    assert_eq!(device.stats().slcan.dropped_while_closed, 1);
    assert!(
        host.recv_timeout(Duration::from_millis(50))
            .await
            .unwrap()
            .is_none()
    );
    let refused = host.send(&std_frame(0x100, &[1])).await.unwrap_err();
    assert!(refused.to_string().contains("closed"), "{refused}");

    while_serving(&mut device, host.open_channel(Some(125_000)))
        .await
        .unwrap();
    assert!(device.channel_open());
    assert_eq!(device.slcan_bitrate(), Some(125_000));
    device.send(&std_frame(0x110, &[2])).await.unwrap();
    assert_eq!(host.recv().await.unwrap(), std_frame(0x110, &[2]));

    let unsupported = host.open_channel(Some(123_456)).await.unwrap_err();
    assert!(unsupported.to_string().contains("123456"), "{unsupported}");
    assert!(unsupported.to_string().contains("S0..S9"), "{unsupported}");
}

#[tokio::test]
async fn an_adapter_refusing_the_bitrate_fails_the_open_naming_the_command() {
    let pair = PtyPair::open().unwrap();
    let path = pair.slave_path().to_owned();
    let mut raw = SerialLine::open(&path, 115_200, "raw").unwrap();
    let host = CanLink::open_pty(pair, Some(250_000), Role::Host);
    let adapter = async {
        let mut seen = Vec::new();
        loop {
            let mut buf = [0; 64];
            let n = raw.read(&mut buf).await.unwrap();
            seen.extend_from_slice(&buf[..n]);
            if seen.ends_with(b"C\r") {
                raw.write_all(b"\r").await.unwrap();
            }
            if seen.ends_with(b"S5\r") {
                raw.write_all(b"\x07").await.unwrap();
                return;
            }
        }
    };
    let (host, ()) = tokio::join!(host, adapter);
    let error = host.unwrap_err();
    assert!(matches!(error, LinkError::AdapterRefused { .. }), "{error}");
    assert!(error.to_string().contains("`S5`"), "{error}");
}

/// A CANable 2.x answers no command: the host waits briefly after each, sends no `Sn`
/// without a bit rate (the adapter keeps its own), and the link works.
#[tokio::test]
async fn a_silent_adapter_is_opened_after_brief_waits_keeping_its_own_bit_rate() {
    let pair = PtyPair::open().unwrap();
    let path = pair.slave_path().to_owned();
    let mut raw = SerialLine::open(&path, 115_200, "raw").unwrap();
    let started = Instant::now();
    let mut host = CanLink::open_pty(pair, None, Role::Host).await.unwrap();
    let took = started.elapsed();
    assert!(took >= 2 * REPLY_WINDOW, "{took:?}");
    assert!(host.channel_open());
    assert_eq!(host.slcan_bitrate(), None, "no bit rate was set");
    let stats = host.stats().slcan;
    assert_eq!(stats.unanswered_commands, 2, "{stats:?}");
    let mut seen = [0; 16];
    let n = raw.read(&mut seen).await.unwrap();
    assert_eq!(&seen[..n], b"C\rO\r");
    raw.write_all(b"t1230\r").await.unwrap();
    assert_eq!(host.recv().await.unwrap(), std_frame(0x123, &[]));
    host.send(&std_frame(0x100, &[1])).await.unwrap();
    let n = raw.read(&mut seen).await.unwrap();
    assert_eq!(&seen[..n], b"t100101\r");
}

/// An adapter that answered before and then falls silent is broken: its silence is an error
/// naming the command.
#[tokio::test]
async fn an_answering_adapter_falling_silent_fails_the_open_naming_the_command() {
    let pair = PtyPair::open().unwrap();
    let path = pair.slave_path().to_owned();
    let mut raw = SerialLine::open(&path, 115_200, "raw").unwrap();
    let host = CanLink::open_pty(pair, Some(500_000), Role::Host);
    let adapter = async {
        let mut seen = Vec::new();
        while !seen.ends_with(b"S6\r") {
            let mut buf = [0; 64];
            let n = raw.read(&mut buf).await.unwrap();
            seen.extend_from_slice(&buf[..n]);
            if seen == b"C\r" {
                raw.write_all(b"\r").await.unwrap();
            }
        }
    };
    let started = Instant::now();
    let (host, ()) = tokio::join!(host, adapter);
    let error = host.unwrap_err();
    assert!(matches!(error, LinkError::NoReply { .. }), "{error}");
    assert!(error.to_string().contains("`S6`"), "{error}");
    assert!(started.elapsed() >= REPLY_TIMEOUT);
}

#[tokio::test]
async fn receive_timeouts_and_the_watchdog_fire_on_a_quiet_link() {
    let (mut host, mut device) = host_and_device("").await;
    assert_nothing_arrives(&mut host, Duration::from_millis(30)).await;

    // 10 periods of 50 ms: the frame below must arrive well inside the allowance even on a
    // loaded machine (a 2 ms period gave a 20 ms allowance that a scheduler hiccup could eat).
    let mut watchdog = Watchdog::new(host.name(), Duration::from_millis(50), 10);
    device.send(&std_frame(0x110, &[9])).await.unwrap();
    assert_eq!(
        host.recv_watched(&mut watchdog).await.unwrap(),
        std_frame(0x110, &[9])
    );
    let started = Instant::now();
    let Err(RecvError::Timeout(timeout)) = host.recv_watched(&mut watchdog).await else {
        panic!("the watchdog did not fire");
    };
    // Fed when the frame arrived, just before `started`: the silence lasts the allowance less
    // that gap (a lower bound only, which a slow machine cannot break).
    assert!(started.elapsed() >= Duration::from_millis(450));
    assert_eq!(timeout.periods, 10);
    assert!(timeout.to_string().contains(host.name()), "{timeout}");
}

#[tokio::test]
async fn try_recv_delivers_a_frame_that_has_arrived() {
    let (mut host, mut device) = host_and_device("").await;
    host.send(&std_frame(0x100, &[4])).await.unwrap();
    let mut got = None;
    for _ in 0..200 {
        got = device.try_recv().unwrap();
        if got.is_some() {
            break;
        }
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    assert_eq!(got, Some(std_frame(0x100, &[4])));
}

#[tokio::test]
async fn the_device_sees_the_host_hang_up() {
    let (host, mut device) = host_and_device("").await;
    drop(host);
    let error = device.recv().await.unwrap_err();
    assert!(matches!(error, LinkError::HangUp { .. }), "{error}");
    assert!(error.to_string().contains("slcan:/dev/pts/"), "{error}");
}

#[tokio::test]
async fn the_host_on_the_master_sees_the_adapter_hang_up() {
    let (mut host, raw, _) = host_and_raw_adapter().await;
    drop(raw);
    let error = host.recv().await.unwrap_err();
    assert!(matches!(error, LinkError::HangUp { .. }), "{error}");
}

#[tokio::test]
async fn sending_to_an_adapter_that_hung_up_fails_instead_of_spinning() {
    // Regression: a pty whose other end is closed stays "writable" once its buffer is full,
    // and the host used to retry the refused write for ever at full CPU.
    let (mut host, raw, _) = host_and_raw_adapter().await;
    drop(raw);
    let frame = std_frame(0x100, &[1, 2, 3, 4, 5, 6, 7, 8]);
    let flood = async {
        for _ in 0..1_000_000 {
            host.send(&frame).await?;
        }
        Ok(())
    };
    let outcome = tokio::time::timeout(Duration::from_secs(10), flood)
        .await
        .expect("send neither succeeded nor failed within 10 s (spinning on a dead pty?)");
    let error = outcome.expect_err("a million frames went into a pty nobody holds");
    assert!(matches!(error, LinkError::HangUp { .. }), "{error}");
}

#[tokio::test]
async fn opening_a_missing_or_non_serial_path_names_it_and_the_os_error() {
    let uri: LinkUri = "slcan:/dev/no-such-adapter@1M".parse().unwrap();
    let error = CanLink::open(&uri, Role::Host).await.unwrap_err();
    let text = error.to_string();
    assert!(
        text.contains("slcan:/dev/no-such-adapter@1000000"),
        "{text}"
    );
    assert!(text.contains("No such file"), "{text}");

    let uri: LinkUri = "slcan:/dev/null".parse().unwrap();
    let text = CanLink::open(&uri, Role::Host)
        .await
        .unwrap_err()
        .to_string();
    assert!(text.contains("not a serial port"), "{text}");

    let pair = PtyPair::open().unwrap();
    let text = CanLink::open_pty(pair, Some(300_000), Role::Host)
        .await
        .unwrap_err()
        .to_string();
    assert!(text.contains("300000") && text.contains("S0..S9"), "{text}");
}

#[tokio::test]
async fn the_capture_records_every_frame_as_a_candump_line_in_order() {
    let (mut host, mut device) = host_and_device("").await;
    let log = SharedBuffer::default();
    let clock = VirtualClock::default();
    host.set_capture(CanCapture::new(
        log.clone(),
        "fsm",
        CaptureClock::Virtual(clock.clone()),
    ));
    let frames = sample_frames();
    for (k, frame) in frames.iter().enumerate() {
        clock.set(Duration::from_micros(50 * k as u64));
        host.send(frame).await.unwrap();
        device.recv().await.unwrap();
        device.send(frame).await.unwrap();
        host.recv().await.unwrap();
    }
    host.flush_capture().unwrap();
    let text = String::from_utf8(log.bytes()).unwrap();
    let entries: Vec<_> = text
        .lines()
        .map(|line| candump::parse_line(line).unwrap())
        .collect();
    assert_eq!(entries.len(), 2 * frames.len());
    for (k, pair) in entries.chunks(2).enumerate() {
        assert_eq!(pair[0].frame, frames[k]);
        assert_eq!(pair[1].frame, frames[k]);
        assert_eq!(pair[0].interface, "fsm");
        assert_eq!(pair[0].timestamp.nanos, 50_000 * k as u32);
    }
    assert!(
        text.starts_with("(0.000000) fsm 100#0102030405060708\n"),
        "{text}"
    );
}

/// A lockstep period as the loop runs it: the host queues its frames and flushes once; its
/// capture writes once per period (before it waits for the answer), lines in order, and the
/// rest when flushed at the end.
#[tokio::test]
async fn the_capture_writes_once_per_period_in_order() {
    let (mut host, mut device) = host_and_device("").await;
    let log = SharedBuffer::default();
    host.set_capture(CanCapture::new(log.clone(), "fsm", CaptureClock::Wall));
    let frames = sample_frames();
    let periods = 20;
    for k in 0..periods {
        host.queue(&frames[0]).await.unwrap();
        host.queue(&frames[1]).await.unwrap();
        assert_eq!(
            log.writes(),
            k,
            "nothing written while the period is queued"
        );
        host.flush().await.unwrap();
        assert_eq!(device.recv().await.unwrap(), frames[0]);
        assert_eq!(device.recv().await.unwrap(), frames[1]);
        device.send(&frames[2]).await.unwrap();
        assert_eq!(host.recv().await.unwrap(), frames[2]);
        assert_eq!(log.writes(), k + 1, "one capture write in period {k}");
    }
    host.flush_capture().unwrap();
    assert_eq!(log.writes(), periods + 1);
    let text = String::from_utf8(log.bytes()).unwrap();
    let recorded: Vec<_> = text
        .lines()
        .map(|line| candump::parse_line(line).unwrap().frame)
        .collect();
    let expected: Vec<_> = (0..periods)
        .flat_map(|_| frames[..3].iter().copied())
        .collect();
    assert_eq!(recorded, expected);
}

#[tokio::test]
async fn the_device_honours_listen_only_and_the_fd_data_bitrate_command() {
    let pair = PtyPair::open().unwrap();
    let path = pair.slave_path().to_owned();
    let mut device = CanLink::open_pty(pair, None, Role::Device).await.unwrap();
    let mut raw = SerialLine::open(&path, 115_200, "raw").unwrap();
    // Y5 while closed: ok; L: open listen-only; a frame: refused; C, O: open; Y5 while open:
    // refused; a frame: delivered.
    raw.write_all(b"Y5\rL\rt1230\rC\rO\rY5\rt1231AB\r")
        .await
        .unwrap();
    assert_eq!(device.recv().await.unwrap(), std_frame(0x123, &[0xAB]));
    let mut answers = Vec::new();
    while answers.len() < 6 {
        let mut buf = [0; 64];
        let n = raw.read(&mut buf).await.unwrap();
        answers.extend_from_slice(&buf[..n]);
    }
    assert_eq!(answers, b"\r\r\x07\r\r\x07");
    assert_eq!(device.stats().slcan.refused_frames, 1);
}

#[tokio::test]
async fn a_port_in_use_by_another_link_is_refused_with_the_reason() {
    let (host, _device) = host_and_device("").await;
    let path = host.name().trim_start_matches("slcan:").to_owned();
    let error = SerialLine::open(path.as_ref(), 115_200, host.name()).unwrap_err();
    let text = error.to_string();
    assert!(
        text.contains("another program has this port open"),
        "{text}"
    );
    assert!(
        text.starts_with(&format!("cannot open {}", host.name())),
        "{text}"
    );
}

/// The controller's default set-up: it creates the pair, keeps the master as host and starts
/// the emulator, which opens the slave path by URI as the device end.
#[tokio::test]
async fn controller_flow_host_on_the_master_device_on_the_slave_path() {
    let pair = PtyPair::open().unwrap();
    let device_uri: LinkUri = format!("slcan:{}", pair.slave_path().display())
        .parse()
        .unwrap();
    let emulator = async move {
        let mut device = CanLink::open(&device_uri, Role::Device).await.unwrap();
        // Serve the host's open, then echo one frame back with id + 0x10.
        let frame = device.recv().await.unwrap();
        assert!(device.channel_open());
        assert_eq!(device.slcan_bitrate(), Some(1_000_000));
        let id = CanId::standard(frame.id().as_raw() as u16 + 0x10).unwrap();
        device
            .send(&CanFrame::new(id, frame.data()).unwrap())
            .await
            .unwrap();
        // The host going away is a hang-up here too.
        let error = device.recv().await.unwrap_err();
        assert!(matches!(error, LinkError::HangUp { .. }), "{error}");
    };
    let controller = async move {
        let mut host = CanLink::open_pty(pair, Some(1_000_000), Role::Host)
            .await
            .unwrap();
        host.send(&std_frame(0x100, &[7, 7])).await.unwrap();
        assert_eq!(host.recv().await.unwrap(), std_frame(0x110, &[7, 7]));
        assert_eq!(host.bus_bitrate(), Some(1_000_000));
    };
    let emulator = tokio::spawn(emulator);
    controller.await;
    emulator.await.unwrap();
}
