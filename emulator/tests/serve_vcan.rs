//! `scanhil-emulator serve` as a whole process on a live `vcan0` (cargo feature `vcan`): a
//! bus-off ends the run with the coils at zero, the node's fault frame on the bus, the reason
//! in the summary line and exit 3. Runs inside the throwaway VM (`ci/vm/socketcan-tests.sh`) or
//! on a host whose vcan0 is up; without vcan0 it fails: nothing is skipped.
#![cfg(feature = "vcan")]

mod vcan {
    use std::io::{BufRead, BufReader};
    use std::process::{Child, Command, ExitStatus, Stdio};
    use std::sync::mpsc;
    use std::time::{Duration, Instant};

    use scanhil_protocol::can::CanFrame;
    use scanhil_protocol::link::{CanLink, LinkError, LinkUri, Role};
    use scanhil_protocol::message::{CoilCommand, FaultKind, Message, NodeId, NodeState};
    use scanhil_protocol::plant_units::ActuatorPair;
    use socketcan::{CanErrorFrame, Socket};

    const SCENE: &str = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../fixtures/scenes/protocol-only.json"
    );

    /// The tests share one bus: one at a time, or they would see each other's frames.
    static BUS: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

    /// `CAN_ERR_ACK` and `CAN_ERR_BUSOFF` (linux/can/error.h).
    const CAN_ERR_ACK: u32 = 0x20;
    const CAN_ERR_BUSOFF: u32 = 0x40;

    /// How long the emulator may take to end after the bus-off (it ends at its next receive;
    /// the VM runs code 10-90x slower than the host). Its watchdog allows 10 s of silence, so
    /// the watchdog cannot pose as the cause.
    const EXIT_BOUND: Duration = Duration::from_secs(5);

    /// The emulator serving the mirror node on vcan0, with the lines it prints.
    struct Emulator {
        child: Child,
        stdout: mpsc::Receiver<String>,
    }

    impl Emulator {
        /// Starts `serve` on vcan0 with `args` (the timing), and reads its ready line.
        fn start(args: &[&str]) -> Emulator {
            let mut child = Command::new(env!("CARGO_BIN_EXE_scanhil-emulator"))
                .args(["serve", "--scene", SCENE, "--fsm", "socketcan:vcan0"])
                .args(args)
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .expect("run scanhil-emulator");
            let (lines, stdout) = mpsc::channel();
            let out = BufReader::new(child.stdout.take().unwrap());
            std::thread::spawn(move || {
                for line in out.lines().map_while(Result::ok) {
                    if lines.send(line).is_err() {
                        break;
                    }
                }
            });
            let emulator = Emulator { child, stdout };
            let ready = emulator.line(Duration::from_secs(30));
            assert_eq!(ready["event"], "ready", "{ready}");
            emulator
        }

        /// The next JSON line it prints, within `wait`.
        fn line(&self, wait: Duration) -> serde_json::Value {
            let line = self
                .stdout
                .recv_timeout(wait)
                .expect("a line from scanhil-emulator");
            serde_json::from_str(&line).unwrap_or_else(|e| panic!("{e}: {line}"))
        }

        /// Its exit status within `bound` (killed and failing the test otherwise).
        fn exit_within(&mut self, bound: Duration) -> ExitStatus {
            let start = Instant::now();
            loop {
                if let Some(status) = self.child.try_wait().unwrap() {
                    return status;
                }
                if start.elapsed() > bound {
                    self.child.kill().unwrap();
                    self.child.wait().unwrap();
                    panic!("scanhil-emulator still running {bound:?} after the bus-off");
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        }

        fn stderr(&mut self) -> String {
            let mut text = String::new();
            std::io::Read::read_to_string(self.child.stderr.as_mut().unwrap(), &mut text).unwrap();
            text
        }
    }

    /// The next frame the host receives that `wanted` picks, within `wait`; the host's own
    /// link reports the injected bus-off too, which is skipped here.
    async fn next_frame(
        host: &mut CanLink,
        wait: Duration,
        wanted: impl Fn(&Message) -> bool,
    ) -> Message {
        let deadline = tokio::time::Instant::now() + wait;
        loop {
            let left = deadline.saturating_duration_since(tokio::time::Instant::now());
            match host.recv_timeout(left).await {
                Ok(Some(frame)) => {
                    if let Ok(message) = Message::decode(&frame)
                        && wanted(&message)
                    {
                        return message;
                    }
                }
                Ok(None) => panic!("no such frame within {wait:?}"),
                Err(LinkError::BusOff { .. }) => {}
                Err(error) => panic!("{error}"),
            }
        }
    }

    fn encode(message: Message) -> CanFrame {
        message.encode().unwrap()
    }

    /// Writes an ACK error frame, then a bus-off one, to vcan0 from a raw socket; returns when.
    fn inject_ack_then_bus_off() -> Instant {
        let injector = socketcan::CanSocket::open("vcan0").unwrap();
        for class in [CAN_ERR_ACK, CAN_ERR_BUSOFF] {
            injector
                .write_frame(&CanErrorFrame::new_error(class, &[]).unwrap())
                .expect("vcan0 takes an error frame from a raw socket");
        }
        Instant::now()
    }

    /// Asserts the emulator ended on the bus-off injected at `injected`: exit 3 within
    /// [`EXIT_BOUND`], the summary's outcome, reason, error frame count, fault state and zero
    /// currents, the reason on stderr. Returns the summary.
    fn assert_ended_by_the_bus_off(
        emulator: &mut Emulator,
        injected: Instant,
    ) -> serde_json::Value {
        let status = emulator.exit_within(EXIT_BOUND);
        let ended_after = injected.elapsed();
        let stderr = emulator.stderr();
        assert_eq!(status.code(), Some(3), "{stderr}");
        let summary = emulator.line(Duration::from_secs(1));
        assert_eq!(summary["event"], "summary", "{summary}");
        assert_eq!(summary["outcome"], "link_failed", "{summary}");
        assert_eq!(summary["ended_by"], "bus_off", "{summary}");
        let error = summary["error"].as_str().unwrap_or_default();
        assert!(
            error.contains("socketcan:vcan0: the CAN controller went bus-off"),
            "{summary}"
        );
        assert_eq!(summary["link"]["bus_error_frames"], 2, "{summary}");
        assert_eq!(summary["final_state"], "fault", "{summary}");
        assert_eq!(
            summary["held_coil_currents_a"],
            serde_json::json!({"a": 0.0, "b": 0.0}),
            "{summary}"
        );
        assert!(
            stderr.contains("bus-off") && stderr.contains("coil currents zeroed"),
            "{stderr}"
        );
        eprintln!("serve ended {ended_after:?} after the bus-off: {summary}");
        summary
    }

    /// The host on vcan0 commanding 1 A / -0.5 A (period 0).
    async fn host_with_current() -> CanLink {
        let uri: LinkUri = "socketcan:vcan0".parse().unwrap();
        let mut host = CanLink::open(&uri, Role::Host)
            .await
            .expect("vcan0 must be up");
        let command = CoilCommand::from_amps(0, ActuatorPair { a: 1.0, b: -0.5 });
        host.send(&encode(Message::CoilCommand(command)))
            .await
            .unwrap();
        host
    }

    #[tokio::test]
    async fn vcan_bus_off_ends_serve_with_zero_coils_the_fault_frame_and_exit_3() {
        let _bus = BUS.lock().await;
        let mut emulator = Emulator::start(&["--timing", "lockstep", "--watchdog-periods", "1000"]);
        // One period with current on the coils: the bus-off must find them held.
        let mut host = host_with_current().await;
        host.send(&encode(Message::Step { step: 0 })).await.unwrap();
        next_frame(&mut host, Duration::from_secs(10), |m| {
            matches!(m, Message::AngleReading(_))
        })
        .await;

        let injected = inject_ack_then_bus_off();
        // The node's fault frame still reaches the bus (vcan0 has no real bus-off).
        let fault = next_frame(
            &mut host,
            EXIT_BOUND,
            |m| matches!(m, Message::Fault(f) if f.node == NodeId::Fsm),
        )
        .await;
        let Message::Fault(fault) = fault else {
            unreachable!()
        };
        assert_eq!((fault.kind, fault.detail), (FaultKind::LinkTimeout, 0));
        let status = next_frame(
            &mut host,
            EXIT_BOUND,
            |m| matches!(m, Message::Status(s) if s.node == NodeId::Fsm),
        )
        .await;
        assert!(
            matches!(status, Message::Status(s) if s.state == NodeState::Fault),
            "{status:?}"
        );
        assert_ended_by_the_bus_off(&mut emulator, injected);
    }

    /// Real time: the clock runs from the ready line on SocketCAN; the bus-off ends the ticks
    /// and the timing measured so far stays in the summary. (The node's last frames are not
    /// looked for here: they go out among 20 000 readings a second.)
    #[tokio::test]
    async fn vcan_bus_off_ends_a_real_time_serve_with_its_timing_and_exit_3() {
        let _bus = BUS.lock().await;
        // The watchdog allows 10 s of silence (200 000 periods), so it cannot pose as the cause.
        let mut emulator = Emulator::start(&[
            "--timing",
            "realtime",
            "--watchdog-periods",
            "200000",
            "--probe-s",
            "0",
        ]);
        let mut host = host_with_current().await;
        for _ in 0..2 {
            next_frame(&mut host, Duration::from_secs(10), |m| {
                matches!(m, Message::AngleReading(_))
            })
            .await;
        }
        let summary = assert_ended_by_the_bus_off(&mut emulator, inject_ack_then_bus_off());
        assert!(
            summary["timing"]["deadline_held"].is_boolean(),
            "the timing so far: {summary}"
        );
    }
}
