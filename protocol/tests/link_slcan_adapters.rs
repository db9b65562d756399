//! The SLCAN host against adapters as their firmware behaves, over real pty pairs: the device
//! end playing each adapter (silent CANable, Lawicel with acks, Lawicel with timestamps), and
//! a raw line playing what an adapter reports (bus state and error lines, status flags, free
//! text, stamped frames).

use std::time::Duration;

use scanhil_protocol::can::{CanFrame, CanId};
use scanhil_protocol::link::slcan::RAW_LINE_REPLY_TIMEOUT;
use scanhil_protocol::link::slcan::device::{CANABLE_VERSION, EmulatedAdapter};
use scanhil_protocol::link::{
    ArrivalSource, CanLink, LinkError, LinkUri, PtyPair, Role, SerialLine,
};
use scanhil_protocol::slcan::SlcanMessage;
use scanhil_protocol::slcan::bus_status::BusState;

/// How long a receive may take before the test fails (rather than hangs).
const RECV_LIMIT: Duration = Duration::from_secs(5);

/// The link's next frame (or error), failing the test after [`RECV_LIMIT`].
async fn recv(link: &mut CanLink) -> Result<CanFrame, LinkError> {
    tokio::time::timeout(RECV_LIMIT, link.recv())
        .await
        .unwrap_or_else(|_| panic!("{}: nothing received within {RECV_LIMIT:?}", link.name()))
}

fn std_frame(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::new(CanId::standard(id).unwrap(), data).unwrap()
}

fn ext_frame(id: u32, data: &[u8]) -> CanFrame {
    CanFrame::new(CanId::extended(id).unwrap(), data).unwrap()
}

/// A device end playing `adapter` on a pty master, and a host that opened the slave path by
/// `slcan:PATH{suffix}`.
async fn host_and_adapter(adapter: EmulatedAdapter, suffix: &str) -> (CanLink, CanLink) {
    let pair = PtyPair::open().unwrap();
    let uri: LinkUri = format!("slcan:{}{suffix}", pair.slave_path().display())
        .parse()
        .unwrap();
    let mut device = CanLink::open_pty(pair, None, Role::Device).await.unwrap();
    device.play_slcan_adapter(adapter);
    let host = tokio::select! {
        host = CanLink::open(&uri, Role::Host) => host.unwrap(),
        got = device.recv() => panic!("the device received {got:?} during the open"),
    };
    assert!(device.channel_open(), "{adapter}");
    (host, device)
}

/// Frames both ways, then the version and the close, with the device answering meanwhile.
async fn session(host: &mut CanLink, device: &mut CanLink) -> Option<String> {
    let out = [std_frame(0x100, &[1, 2, 3]), ext_frame(0x1ABC_DEF0, &[4])];
    for frame in out {
        host.send(&frame).await.unwrap();
        assert_eq!(recv(device).await.unwrap(), frame);
    }
    for frame in out.iter().rev() {
        device.send(frame).await.unwrap();
        assert_eq!(recv(host).await.unwrap(), *frame);
    }
    let version = tokio::select! {
        version = host.adapter_version() => version.unwrap(),
        got = device.recv() => panic!("the device received {got:?} while answering V"),
    };
    let (closed, _) = tokio::join!(
        host.close(),
        device.recv_timeout(Duration::from_millis(300))
    );
    closed.unwrap();
    version
}

#[tokio::test]
async fn a_silent_canable_at_1_mbit_is_opened_used_and_closed() {
    let (mut host, mut device) = host_and_adapter(EmulatedAdapter::Canable, "@1000000").await;
    assert_eq!(device.slcan_bitrate(), Some(1_000_000));
    let version = session(&mut host, &mut device).await;
    assert_eq!(version.as_deref(), Some(CANABLE_VERSION), "its free-text V");
    let stats = host.stats().slcan;
    assert_eq!(stats.unanswered_commands, 4, "C, S8, O, C: {stats:?}");
    assert_eq!(stats.text_lines, 1);
    assert_eq!(stats.malformed_lines, 0);
    assert_eq!(stats.transmit_acks, 0);
    assert_eq!(host.last_arrival().unwrap().source, ArrivalSource::Read);
}

#[tokio::test]
async fn s7_sets_750k_on_a_canable_and_800k_on_a_lawicel() {
    let (_host, device) = host_and_adapter(EmulatedAdapter::Canable, "@750k").await;
    assert_eq!(device.slcan_bitrate(), Some(750_000));
    let (_host, device) = host_and_adapter(EmulatedAdapter::Lawicel, "@800k?family=lawicel").await;
    assert_eq!(device.slcan_bitrate(), Some(800_000));
}

#[tokio::test]
async fn a_lawicel_adapter_acks_every_frame_and_is_asked_for_its_flags() {
    let (mut host, mut device) =
        host_and_adapter(EmulatedAdapter::Lawicel, "@1M?family=lawicel").await;
    let version = session(&mut host, &mut device).await;
    assert_eq!(version.as_deref(), Some("1013"));
    let stats = host.stats().slcan;
    assert_eq!(stats.transmit_acks, 2, "z and Z: {stats:?}");
    assert_eq!(stats.unanswered_commands, 0);
    assert_eq!(stats.bus.status_replies, 2, "F after O and before C");
    assert_eq!(stats.bus.state, Some(BusState::ErrorActive));
    assert_eq!(stats.malformed_lines, 0);
}

#[tokio::test]
async fn a_lawicel_adapter_with_timestamps_on_stamps_every_frame_it_forwards() {
    let (mut host, mut device) =
        host_and_adapter(EmulatedAdapter::LawicelTimestamps, "@1M?family=lawicel").await;
    session(&mut host, &mut device).await;
    let stats = host.stats().slcan;
    assert_eq!(stats.stamped_frames, 2, "{stats:?}");
    assert_eq!(stats.malformed_lines, 0);
    let arrival = host.last_arrival().unwrap();
    assert_eq!(arrival.source, ArrivalSource::Adapter);
    assert!(arrival.on_bus_at <= arrival.read_at);
}

/// A host on a pty master opened at 1 Mbit/s against a raw line that answers every command
/// with CR (an adapter that answers), and that raw line.
async fn host_and_raw_adapter() -> (CanLink, SerialLine) {
    let pair = PtyPair::open().unwrap();
    let path = pair.slave_path().to_owned();
    let mut raw = SerialLine::open(&path, 115_200, "raw").unwrap();
    let host = CanLink::open_pty(pair, Some(1_000_000), Role::Host);
    let adapter = async {
        let mut crs = 0;
        while crs < 3 {
            let mut buf = [0; 64];
            let n = raw.read(&mut buf).await.unwrap();
            let answers = buf[..n].iter().filter(|&&b| b == b'\r').count();
            crs += answers;
            raw.write_all(&b"\r".repeat(answers)).await.unwrap();
        }
    };
    let (host, ()) = tokio::join!(host, adapter);
    (host.unwrap(), raw)
}

#[tokio::test]
async fn an_adapters_bus_off_line_ends_the_receive_after_the_frames_before_it() {
    let (mut host, raw) = host_and_raw_adapter().await;
    raw.write_all(b"sa000000\re1a\rsp128131\rt1001AA\rsb000256\rt1001BB\r")
        .await
        .unwrap();
    assert_eq!(recv(&mut host).await.unwrap(), std_frame(0x100, &[0xAA]));
    assert_eq!(recv(&mut host).await.unwrap(), std_frame(0x100, &[0xBB]));
    let error = recv(&mut host).await.unwrap_err();
    assert!(matches!(error, LinkError::BusOff { .. }), "{error}");
    assert!(
        error.to_string().contains("the adapter reports bus-off"),
        "{error}"
    );
    let stats = host.stats();
    assert_eq!(stats.slcan.bus.state, Some(BusState::BusOff));
    assert_eq!(stats.slcan.bus.tx_errors, Some(256));
    assert_eq!(stats.slcan.bus.state_lines, 3);
    assert_eq!(stats.slcan.bus.errors.ack, 1);
    assert_eq!(stats.bus_error_frames, 1, "the e line");
    assert_eq!(stats.slcan.malformed_lines, 0);
}

#[tokio::test]
async fn flags_free_text_and_stamped_frames_are_taken_not_counted_malformed() {
    let (mut host, raw) = host_and_raw_adapter().await;
    raw.write_all(b"F24\rCANable debug: hello\rt1001AA0010\rt1001BB0012\rT1ABCDEF00EA5F\r")
        .await
        .unwrap();
    assert_eq!(recv(&mut host).await.unwrap(), std_frame(0x100, &[0xAA]));
    let first = host.last_arrival().unwrap();
    assert_eq!(recv(&mut host).await.unwrap(), std_frame(0x100, &[0xBB]));
    let second = host.last_arrival().unwrap();
    assert_eq!(recv(&mut host).await.unwrap(), ext_frame(0x1ABC_DEF0, &[]));
    for arrival in [first, second] {
        assert_eq!(arrival.source, ArrivalSource::Adapter);
        assert!(arrival.on_bus_at <= arrival.read_at);
    }
    assert!(second.on_bus_at >= first.on_bus_at);
    let stats = host.stats().slcan;
    assert_eq!(stats.stamped_frames, 3);
    assert_eq!(stats.text_lines, 1);
    assert_eq!(stats.last_text.as_deref(), Some("CANable debug: hello"));
    assert_eq!(stats.bus.state, Some(BusState::ErrorPassive));
    assert_eq!(
        stats.bus.last_status_flags,
        Some(vec!["error_warning", "error_passive"])
    );
    assert_eq!(stats.malformed_lines, 0, "{stats:?}");
}

/// Conformance sends garbage lines one after the other: a silent adapter, which answers none,
/// is not waited for (five waits would starve the node's watchdog).
#[tokio::test]
async fn raw_lines_to_a_silent_adapter_are_not_waited_for() {
    let (mut host, mut device) = host_and_adapter(EmulatedAdapter::Silent, "").await;
    let started = std::time::Instant::now();
    for line in [&b"xyz"[..], b"t12", b"\xff\xfe"] {
        assert_eq!(host.send_raw_line(line).await.unwrap(), None);
    }
    assert!(
        started.elapsed() < RAW_LINE_REPLY_TIMEOUT,
        "{:?}",
        started.elapsed()
    );
    // The lines did go out: the device counts them malformed, and answers none.
    host.send(&std_frame(0x100, &[9])).await.unwrap();
    assert_eq!(recv(&mut device).await.unwrap(), std_frame(0x100, &[9]));
    assert_eq!(device.stats().slcan.malformed_lines, 3);
    // An adapter that answers is waited for, and its BEL returned.
    let (mut host, mut device) = host_and_adapter(EmulatedAdapter::Lawicel, "").await;
    let (answer, _) = tokio::join!(
        host.send_raw_line(b"xyz"),
        device.recv_timeout(Duration::from_millis(100))
    );
    assert_eq!(answer.unwrap(), Some(SlcanMessage::Nack));
}
