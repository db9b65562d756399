//! An SLCAN adapter on a pty built from the project's SLCAN codec, for the python-can interop
//! check (`ci/interop/slcan_python_can.py`).
//!
//! `slcan-pty-peer FRAMES_FILE EXPECT`: creates a pty pair and prints `PTY <path>`; a client
//! opens that path as an SLCAN adapter. Commands are answered like an adapter does (CR for
//! `O`, `C`, `Sn` and empty lines, BEL for anything else). After the client's `O` the peer
//! sends every frame of FRAMES_FILE (candump `-L` lines) with the project's SLCAN encoder.
//! Every frame the client sends is decoded with the project's SLCAN decoder and printed as
//! `RECV <candump line>`; after EXPECT frames it prints `DONE`, and exits 0 once the client
//! has hung up the pty. Malformed lines are printed as `MALFORMED
//! <error>` (exit 1 at the end); not done within 20 s: exit 1.

use std::io::{Read, Write};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use scanhil_protocol::candump::{self, LogEntry, Timestamp};
use scanhil_protocol::slcan::{self, SlcanDecoder, SlcanMessage};
use serialport::{SerialPort, TTYPort};

/// How long the peer waits for its client before giving up.
const DEADLINE: Duration = Duration::from_secs(20);

fn main() -> ExitCode {
    match run() {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(err) => {
            eprintln!("slcan-pty-peer: {err}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<bool, String> {
    let args: Vec<String> = std::env::args().collect();
    let [_, frames_path, expect] = &args[..] else {
        return Err("usage: slcan-pty-peer FRAMES_FILE EXPECT".to_owned());
    };
    let expect: usize = expect
        .parse()
        .map_err(|e| format!("EXPECT {expect:?}: {e}"))?;
    let text = std::fs::read_to_string(frames_path).map_err(|e| format!("{frames_path}: {e}"))?;
    let frames = candump::parse_log(&text)
        .map(|entry| entry.map(|e| e.frame).map_err(|e| e.to_string()))
        .collect::<Result<Vec<_>, _>>()?;

    // The peer holds the slave end until the client has opened it (reads on a master without
    // any slave fail), then lets go, so that the client's hang-up ends the exchange.
    let (mut master, slave) = TTYPort::pair().map_err(|e| format!("pty pair: {e}"))?;
    master
        .set_timeout(Duration::from_millis(50))
        .map_err(|e| e.to_string())?;
    let path = slave.name().ok_or("the pty has no name")?;
    let mut slave = Some(slave);
    println!("PTY {path}");
    std::io::stdout().flush().map_err(|e| e.to_string())?;

    let started = Instant::now();
    let mut decoder = SlcanDecoder::new();
    let mut received = 0;
    let mut malformed = 0;
    let mut buf = [0u8; 256];
    let mut done = false;
    loop {
        if started.elapsed() > DEADLINE {
            return Err(format!(
                "timed out after {DEADLINE:?} with {received} of {expect} frames"
            ));
        }
        let n = match master.read(&mut buf) {
            Ok(0) if done => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
            // The client hung up after the exchange (its final `C` may be lost with the
            // hang-up: serialport reports the hang-up before reading what is pending).
            Err(_) if done => break,
            Err(e) => return Err(format!("read: {e}")),
        };
        if n > 0 {
            drop(slave.take());
        }
        for event in decoder.push(&buf[..n]) {
            let reply = match event {
                Ok(SlcanMessage::Frame(frame)) => {
                    received += 1;
                    let entry = LogEntry {
                        timestamp: Timestamp::default(),
                        interface: "slcan0".to_owned(),
                        frame,
                        len8_dlc: None,
                        direction: None,
                    };
                    println!("RECV {entry}");
                    if received == expect {
                        println!("DONE");
                        done = true;
                    }
                    continue;
                }
                Ok(SlcanMessage::Open) => {
                    let mut out = SlcanMessage::Ack.encode();
                    out.extend(frames.iter().map(slcan::encode_frame));
                    out
                }
                Ok(SlcanMessage::Close) => SlcanMessage::Ack.encode(),
                Ok(SlcanMessage::Bitrate(_) | SlcanMessage::Ack) => SlcanMessage::Ack.encode(),
                Ok(_) => SlcanMessage::Nack.encode(),
                Err(err) => {
                    malformed += 1;
                    println!("MALFORMED {err}");
                    SlcanMessage::Nack.encode()
                }
            };
            master
                .write_all(reply.as_bytes())
                .map_err(|e| format!("write: {e}"))?;
        }
    }
    Ok(malformed == 0 && received == expect)
}
