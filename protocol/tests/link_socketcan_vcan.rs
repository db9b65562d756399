//! SocketCAN links over a live `vcan0` (cargo feature `vcan`). They run inside the throwaway
//! VM (`ci/vm/socketcan-tests.sh`) or on a host whose kernel has CAN and whose vcan0 is up
//! (`modprobe vcan; ip link add dev vcan0 type vcan; ip link set up vcan0`). Without vcan0
//! they fail: nothing is skipped.
#![cfg(feature = "vcan")]

mod support;

mod vcan {
    use std::time::Duration;

    use super::support::{SharedBuffer, assert_nothing_arrives};
    use scanhil_protocol::can::{CanFrame, CanId};
    use scanhil_protocol::candump;
    use scanhil_protocol::link::{
        ArrivalSource, CanCapture, CanLink, CaptureClock, LinkUri, RecvError, Role, VirtualClock,
        Watchdog,
    };
    use scanhil_protocol::socketcan::interface_state::InterfaceReading;
    use scanhil_protocol::socketcan::send_retry::RetryCounts;

    /// The tests share one bus: one at a time, or they would see each other's frames.
    static BUS: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

    async fn two_nodes() -> (CanLink, CanLink) {
        let uri: LinkUri = "socketcan:vcan0@1M".parse().unwrap();
        let a = CanLink::open(&uri, Role::Host)
            .await
            .expect("vcan0 must be up");
        let b = CanLink::open(&uri, Role::Device).await.unwrap();
        (a, b)
    }

    fn frames() -> Vec<CanFrame> {
        let std_id = CanId::standard(0x110).unwrap();
        let ext_id = CanId::extended(0x1ABC_DEF0).unwrap();
        vec![
            CanFrame::new(std_id, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap(),
            CanFrame::new(ext_id, &[9]).unwrap(),
            CanFrame::new(std_id, &[]).unwrap(),
            CanFrame::new_remote(std_id, 4).unwrap(),
            CanFrame::new_fd(std_id, &[0xA5; 16], true, false).unwrap(),
            CanFrame::new_fd(ext_id, &[0x3C; 64], false, true).unwrap(),
        ]
    }

    #[tokio::test]
    async fn vcan_frames_cross_both_ways_in_order() {
        let _bus = BUS.lock().await;
        let (mut a, mut b) = two_nodes().await;
        assert_eq!(a.bus_bitrate(), Some(1_000_000));
        for frame in frames() {
            a.send(&frame).await.unwrap();
        }
        for expected in frames() {
            assert_eq!(b.recv().await.unwrap(), expected);
        }
        for k in 0..1000u16 {
            let frame = CanFrame::new(CanId::standard(0x100).unwrap(), &k.to_le_bytes()).unwrap();
            b.send(&frame).await.unwrap();
            assert_eq!(a.recv().await.unwrap(), frame);
        }
        assert_eq!(a.stats().frames_received, 1000);
        assert_eq!(b.stats().frames_sent, 1000);
    }

    #[tokio::test]
    async fn vcan_timeouts_and_watchdog_fire_on_a_quiet_bus() {
        let _bus = BUS.lock().await;
        let (mut a, _b) = two_nodes().await;
        assert_nothing_arrives(&mut a, Duration::from_millis(30)).await;
        let mut watchdog = Watchdog::new(a.name(), Duration::from_millis(1), 20);
        let Err(RecvError::Timeout(timeout)) = a.recv_watched(&mut watchdog).await else {
            panic!("the watchdog did not fire");
        };
        assert!(timeout.to_string().contains("socketcan:vcan0"), "{timeout}");
    }

    #[tokio::test]
    async fn vcan_capture_writes_candump_lines() {
        let _bus = BUS.lock().await;
        let (mut a, mut b) = two_nodes().await;
        let log = SharedBuffer::default();
        let clock = VirtualClock::default();
        b.set_capture(CanCapture::new(
            log.clone(),
            "vcan0",
            CaptureClock::Virtual(clock.clone()),
        ));
        for (k, frame) in frames().iter().enumerate() {
            clock.set(Duration::from_micros(50 * k as u64));
            a.send(frame).await.unwrap();
            b.recv().await.unwrap();
        }
        // The capture writes before the link waits again, or when told to: the last frame's
        // line is still held here.
        b.flush_capture().unwrap();
        let text = String::from_utf8(log.bytes()).unwrap();
        let logged: Vec<CanFrame> = text
            .lines()
            .map(|line| candump::parse_line(line).unwrap().frame)
            .collect();
        assert_eq!(logged, frames());
    }

    /// What netlink says of a vcan: up, and no bit rate, state or error counters; the link
    /// says so and keeps the URI's bit rate for the bus-load check alone. Nothing was dropped
    /// or retried on a quiet bus.
    #[tokio::test]
    async fn vcan_reports_no_controller_and_says_so() {
        let _bus = BUS.lock().await;
        let (_a, b) = two_nodes().await;
        let report = b.report().socketcan.expect("a SocketCAN link's report");
        assert_eq!(
            report.interface,
            Some(InterfaceReading {
                is_up: true,
                ..InterfaceReading::default()
            })
        );
        assert_eq!(
            report.notes,
            [
                "interface vcan0 reports no bit rate, state or error counters (a virtual \
              interface, vcan, has none): the URI's @BITRATE 1000000 bit/s is used for the \
              bus-load check only"
            ]
        );
        assert_eq!(report.dropped_frames, Some(0));
        assert_eq!(report.send_retries, RetryCounts::default());
        assert!(
            b.open_summary()
                .contains("a virtual interface, vcan, has none")
        );
    }

    /// An interface that is down is refused when the link opens, naming it and the command
    /// that brings it up (a second vcan made here, left down).
    #[tokio::test]
    async fn vcan_down_is_refused_at_open() {
        use scanhil_protocol::link::LinkError;
        use socketcan::nl::CanInterface;
        let made = CanInterface::create_vcan("vcandown0", None)
            .expect("creating a vcan needs root and the vcan module (the VM has both)");
        let opened = CanLink::open(&"socketcan:vcandown0".parse().unwrap(), Role::Host).await;
        made.delete().expect("deleting the vcan made here");
        let error = opened.expect_err("a down interface opened");
        assert!(matches!(error, LinkError::Interface { .. }), "{error}");
        assert_eq!(
            error.to_string(),
            "cannot use socketcan:vcandown0: interface vcandown0 is down (bring it up: `sudo ip \
             link set up vcandown0`)"
        );
    }

    /// The arrival of a frame is the kernel's receive time: a frame read 20 ms after it was
    /// sent arrived 20 ms before its read, by `recv` and by `try_recv` alike.
    #[tokio::test]
    async fn vcan_arrivals_are_the_kernels_receive_times() {
        let _bus = BUS.lock().await;
        let (mut a, mut b) = two_nodes().await;
        let frame = CanFrame::new(CanId::standard(0x110).unwrap(), &[1]).unwrap();
        for nonblocking in [false, true] {
            a.send(&frame).await.unwrap();
            std::thread::sleep(Duration::from_millis(20));
            let got = if nonblocking {
                b.try_recv().unwrap().expect("a frame already there")
            } else {
                b.recv().await.unwrap()
            };
            assert_eq!(got, frame);
            let arrival = b.last_arrival().unwrap();
            assert_eq!(arrival.source, ArrivalSource::Kernel);
            let age = arrival.read_at - arrival.on_bus_at;
            assert!(
                (Duration::from_millis(19)..Duration::from_secs(1)).contains(&age),
                "read {age:?} after the kernel's stamp"
            );
        }
    }

    /// A receiver that does not read while far more frames come than its socket's receive
    /// queue holds: the kernel drops the rest, and the link counts every one of them.
    #[tokio::test]
    async fn vcan_frames_the_kernel_dropped_are_counted() {
        let _bus = BUS.lock().await;
        let (mut a, mut b) = two_nodes().await;
        const SENT: u32 = 5000;
        for k in 0..SENT {
            let frame = CanFrame::new(CanId::standard(0x100).unwrap(), &k.to_le_bytes()).unwrap();
            a.send(&frame).await.unwrap();
        }
        let dropped = b
            .report()
            .socketcan
            .and_then(|report| report.dropped_frames)
            .expect("the drop counter");
        let mut received = 0;
        while b.try_recv().unwrap().is_some() {
            received += 1;
        }
        assert!(
            dropped > 0 && received > 0,
            "{received} received, {dropped} dropped"
        );
        assert_eq!(
            received + dropped,
            SENT,
            "{received} received, {dropped} dropped"
        );
    }

    /// `CAN_ERR_ACK` and `CAN_ERR_BUSOFF` (linux/can/error.h).
    const CAN_ERR_ACK: u32 = 0x20;
    const CAN_ERR_BUSOFF: u32 = 0x40;

    /// Error frames on vcan0: a real bus's controllers make them; on vcan0 a raw socket
    /// writes them with `CAN_ERR_FLAG` set, and every socket subscribed to errors gets them.
    #[tokio::test]
    async fn vcan_error_frames_are_counted_and_bus_off_ends_the_receive() {
        use scanhil_protocol::link::LinkError;
        use socketcan::{CanErrorFrame, Socket};
        let _bus = BUS.lock().await;
        let (mut sender, mut receiver) = two_nodes().await;
        let injector = socketcan::CanSocket::open("vcan0").unwrap();
        injector
            .write_frame(&CanErrorFrame::new_error(CAN_ERR_ACK, &[]).unwrap())
            .expect("vcan0 takes an error frame from a raw socket");
        let data = CanFrame::new(CanId::standard(0x123).unwrap(), &[1]).unwrap();
        sender.send(&data).await.unwrap();
        assert_eq!(receiver.recv().await.unwrap(), data);
        assert_eq!(receiver.stats().bus_error_frames, 1);
        injector
            .write_frame(&CanErrorFrame::new_error(CAN_ERR_BUSOFF, &[]).unwrap())
            .unwrap();
        let error = receiver.recv().await.unwrap_err();
        assert!(matches!(error, LinkError::BusOff { .. }), "{error}");
        assert!(error.to_string().contains("bus-off"), "{error}");
    }
}
