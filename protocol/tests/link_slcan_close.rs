//! An SLCAN host sends `C` at every end of a session, over real pty pairs: an explicit close
//! (waiting for the CR), a drop (best effort), after a link error; a device asked to treats
//! the `C` as the end of its run; raw lines for conformance testing.

use std::time::{Duration, Instant};

use scanhil_protocol::can::{CanFrame, CanId};
use scanhil_protocol::link::slcan::{CLOSE_REPLY_TIMEOUT, MAX_RAW_LINE_LEN};
use scanhil_protocol::link::{CanLink, LinkError, LinkUri, PtyPair, Role, SerialLine};
use scanhil_protocol::slcan::SlcanMessage;

const READ_WAIT: Duration = Duration::from_secs(2);

/// The raw adapter on the pty master, the host on the slave path by URI (as a program opens a
/// real adapter). The raw side answers the host's `C`, `Sn`, `O` with CR.
async fn raw_adapter_and_host() -> (SerialLine, CanLink) {
    let pair = PtyPair::open().unwrap();
    let uri: LinkUri = format!("slcan:{}@1M", pair.slave_path().display())
        .parse()
        .unwrap();
    let mut raw = SerialLine::from_pty(pair, "raw").unwrap();
    let host = CanLink::open(&uri, Role::Host);
    let adapter = async {
        let mut seen = Vec::new();
        while seen.iter().filter(|&&b| b == b'\r').count() < 3 {
            let mut buf = [0; 64];
            let n = raw.read(&mut buf).await.unwrap();
            seen.extend_from_slice(&buf[..n]);
            let answers = buf[..n].iter().filter(|&&b| b == b'\r').count();
            raw.write_all(&b"\r".repeat(answers)).await.unwrap();
        }
        assert_eq!(seen, b"C\rS8\rO\r");
    };
    let (host, ()) = tokio::join!(host, adapter);
    (raw, host.unwrap())
}

/// Reads from the raw adapter until `until` is in what arrived, the line hangs up, or
/// [`READ_WAIT`] passes; answers every CR with `answer` (if any). Returns what arrived.
async fn read_adapter(raw: &mut SerialLine, until: &[u8], answer: Option<&[u8]>) -> Vec<u8> {
    let mut seen = Vec::new();
    let deadline = tokio::time::Instant::now() + READ_WAIT;
    while !seen.windows(until.len()).any(|w| w == until) {
        let mut buf = [0; 256];
        match tokio::time::timeout_at(deadline, raw.read(&mut buf)).await {
            Err(_) | Ok(Err(LinkError::HangUp { .. })) => break,
            Ok(Err(error)) => panic!("{error}"),
            Ok(Ok(n)) => {
                seen.extend_from_slice(&buf[..n]);
                if let Some(answer) = answer {
                    for _ in buf[..n].iter().filter(|&&b| b == b'\r') {
                        raw.write_all(answer).await.unwrap();
                    }
                }
            }
        }
    }
    seen
}

fn frame() -> CanFrame {
    CanFrame::new(CanId::standard(0x100).unwrap(), &[1, 2, 3]).unwrap()
}

#[tokio::test]
async fn an_explicit_close_sends_c_and_waits_for_the_ack() {
    let (mut raw, mut host) = raw_adapter_and_host().await;
    host.send(&frame()).await.unwrap();
    let (closed, seen) = tokio::join!(host.close(), read_adapter(&mut raw, b"C\r", Some(b"\r")));
    closed.unwrap();
    assert_eq!(seen, b"t1003010203\rC\r");
    assert!(!host.channel_open());
    // Closed once: neither a second close nor the drop sends `C` again.
    host.close().await.unwrap();
    drop(host);
    assert_eq!(read_adapter(&mut raw, b"C", None).await, b"");
}

#[tokio::test]
async fn a_close_waits_a_bounded_time_for_a_silent_adapter() {
    let (mut raw, mut host) = raw_adapter_and_host().await;
    let started = Instant::now();
    let (closed, seen) = tokio::join!(host.close(), read_adapter(&mut raw, b"C\r", None));
    let error = closed.unwrap_err();
    assert!(matches!(error, LinkError::NoReply { .. }), "{error}");
    assert!(error.to_string().contains("`C`"), "{error}");
    assert!(started.elapsed() < CLOSE_REPLY_TIMEOUT + Duration::from_millis(500));
    assert_eq!(seen, b"C\r");
}

#[tokio::test]
async fn dropping_an_open_host_link_sends_c() {
    let (mut raw, host) = raw_adapter_and_host().await;
    drop(host);
    assert_eq!(read_adapter(&mut raw, b"C\r", None).await, b"C\r");
}

#[tokio::test]
async fn dropping_a_host_whose_send_was_cancelled_mid_frame_ends_that_line_before_c() {
    let (mut raw, mut host) = raw_adapter_and_host().await;
    // Fill the line until a send cannot finish at once, then cancel it.
    let long = CanFrame::new(CanId::extended(0x1ABC_DEF0).unwrap(), &[0x55; 8]).unwrap();
    let mut cancelled = false;
    for _ in 0..100_000 {
        if tokio::time::timeout(Duration::from_millis(5), host.send(&long))
            .await
            .is_err()
        {
            cancelled = true;
            break;
        }
    }
    assert!(cancelled, "the pty never filled up");
    // The adapter reads what is on the line, making room (the unsent rest of the frame stays
    // with the host): the line now ends in the middle of a frame.
    let mut before = Vec::new();
    let mut buf = [0; 4096];
    while let Ok(Ok(n)) = tokio::time::timeout(Duration::from_millis(50), raw.read(&mut buf)).await
    {
        before.extend_from_slice(&buf[..n]);
    }
    assert!(
        !before.ends_with(b"\r"),
        "the cancelled frame was sent whole"
    );
    drop(host);
    let seen = read_adapter(&mut raw, b"\rC\r", None).await;
    assert!(
        seen.ends_with(b"\rC\r"),
        "ends with {:?}",
        &seen[seen.len().saturating_sub(40)..]
    );
}

#[tokio::test]
async fn after_a_link_error_close_and_drop_still_send_c() {
    let (mut raw, mut host) = raw_adapter_and_host().await;
    // The adapter refuses a frame: the next receive fails.
    raw.write_all(b"\x07").await.unwrap();
    let error = host.recv().await.unwrap_err();
    assert!(matches!(error, LinkError::AdapterRefused { .. }), "{error}");
    let (closed, seen) = tokio::join!(host.close(), read_adapter(&mut raw, b"C\r", Some(b"\r")));
    closed.unwrap();
    assert_eq!(seen, b"C\r");

    // A receive timeout (the watchdog's case), then the error path drops the link.
    let (mut raw, mut host) = raw_adapter_and_host().await;
    assert!(
        host.recv_timeout(Duration::from_millis(20))
            .await
            .unwrap()
            .is_none()
    );
    drop(host);
    assert_eq!(read_adapter(&mut raw, b"C\r", None).await, b"C\r");
}

#[tokio::test]
async fn closing_or_dropping_when_the_adapter_is_gone_neither_hangs_nor_panics() {
    let (raw, mut host) = raw_adapter_and_host().await;
    drop(raw);
    let started = Instant::now();
    let error = host.close().await.unwrap_err();
    assert!(matches!(error, LinkError::HangUp { .. }), "{error}");
    assert!(started.elapsed() < CLOSE_REPLY_TIMEOUT);
    let (raw, host) = raw_adapter_and_host().await;
    drop(raw);
    let started = Instant::now();
    drop(host);
    assert!(started.elapsed() < Duration::from_millis(100));
}

/// A device end asked to end its run on `C`, and a host that opened it.
async fn device_ending_on_close() -> (CanLink, CanLink) {
    let pair = PtyPair::open().unwrap();
    let uri: LinkUri = format!("slcan:{}", pair.slave_path().display())
        .parse()
        .unwrap();
    let mut device = CanLink::open_pty(pair, None, Role::Device).await.unwrap();
    device.end_run_on_close();
    let host = tokio::select! {
        host = CanLink::open(&uri, Role::Host) => host.unwrap(),
        got = device.recv() => panic!("device received {got:?} during the handshake"),
    };
    assert!(device.channel_open());
    (host, device)
}

#[tokio::test]
async fn a_device_ending_on_close_reports_the_hosts_c_after_the_frames_before_it() {
    let (mut host, mut device) = device_ending_on_close().await;
    host.send(&frame()).await.unwrap();
    assert_eq!(device.recv().await.unwrap(), frame());
    host.send(&frame()).await.unwrap();
    let (closed, received) = tokio::join!(host.close(), async {
        let first = device.recv().await;
        let second = tokio::time::timeout(READ_WAIT, device.recv()).await;
        (first, second.expect("no end of run within the wait"))
    });
    closed.unwrap();
    assert_eq!(received.0.unwrap(), frame());
    let end = received.1.unwrap_err();
    assert!(matches!(end, LinkError::ChannelClosed { .. }), "{end}");
    assert!(
        end.to_string().contains("closed the SLCAN channel"),
        "{end}"
    );
    assert!(!device.channel_open());
}

#[tokio::test]
async fn a_dropped_host_on_the_slave_path_ends_the_devices_run_with_c() {
    let (host, mut device) = device_ending_on_close().await;
    drop(host);
    // The `C` is read before the hang-up that follows it.
    let end = tokio::time::timeout(READ_WAIT, device.recv())
        .await
        .unwrap()
        .unwrap_err();
    assert!(matches!(end, LinkError::ChannelClosed { .. }), "{end}");
}

#[tokio::test]
async fn raw_lines_get_the_devices_answer_and_the_link_goes_on() {
    let (mut host, mut device) = device_ending_on_close().await;
    let (answer, ()) = tokio::join!(host.send_raw_line(b"xyz\xff"), async {
        assert!(
            device
                .recv_timeout(Duration::from_millis(300))
                .await
                .unwrap()
                .is_none()
        );
    });
    assert_eq!(answer.unwrap(), Some(SlcanMessage::Nack));
    host.send(&frame()).await.unwrap();
    assert_eq!(device.recv().await.unwrap(), frame());
    assert_eq!(device.stats().slcan.malformed_lines, 1);
    let refused = host.send_raw_line(b"t100\r").await.unwrap_err();
    assert!(refused.to_string().contains("no CR"), "{refused}");
    let long = vec![b'A'; MAX_RAW_LINE_LEN + 1];
    assert!(host.send_raw_line(&long).await.is_err());
}
