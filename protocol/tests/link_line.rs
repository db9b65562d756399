//! A byte line over a real pty pair when its output is full: a write waits for the peer to read
//! and then completes, every byte in order; a write into a full line whose peer is gone is a
//! hang-up, not a wait for ever. (A line is registered for reading only; it waits for room
//! only when a write finds the line full, see `SerialLine::write_some`.)

use std::cell::Cell;
use std::time::Duration;

use scanhil_protocol::link::{LinkError, PtyPair, SerialLine};

/// Longer than any of these waits should take.
const BOUND: Duration = Duration::from_secs(5);

/// Writes filler bytes without waiting until the line takes no more; returns how many it took.
fn fill(line: &SerialLine) -> usize {
    let mut taken = 0;
    loop {
        let mut pending = vec![0x55; 4096];
        line.try_flush_pending(&mut pending).unwrap();
        taken += 4096 - pending.len();
        if !pending.is_empty() {
            return taken;
        }
    }
}

#[tokio::test(flavor = "current_thread")]
async fn a_write_into_a_full_line_waits_for_the_reader_then_completes_in_order() {
    let pair = PtyPair::open().unwrap();
    let writer = SerialLine::open(pair.slave_path(), 115_200, "writer").unwrap();
    let mut reader = SerialLine::from_pty(pair, "reader").unwrap();
    let filled = fill(&writer);
    let tail: Vec<u8> = (0..10_000u32).map(|i| (i % 251) as u8).collect();
    let written = Cell::new(false);
    let write = async {
        writer.write_all(&tail).await.unwrap();
        written.set(true);
    };
    let read = async {
        tokio::time::sleep(Duration::from_millis(100)).await;
        assert!(
            !written.get(),
            "the write finished although the line was full and nobody read"
        );
        let mut got = Vec::new();
        while got.len() < filled + tail.len() {
            let mut buf = [0; 4096];
            let n = tokio::time::timeout(BOUND, reader.read(&mut buf))
                .await
                .expect("the written bytes arrive")
                .unwrap();
            got.extend_from_slice(&buf[..n]);
        }
        got
    };
    let ((), got) = tokio::join!(write, read);
    assert!(written.get());
    assert_eq!(got.len(), filled + tail.len());
    assert!(got[..filled].iter().all(|&b| b == 0x55));
    assert_eq!(&got[filled..], &tail[..]);
}

#[tokio::test(flavor = "current_thread")]
async fn a_write_into_a_full_line_whose_peer_is_gone_is_a_hang_up() {
    let pair = PtyPair::open().unwrap();
    let peer = SerialLine::open(pair.slave_path(), 115_200, "peer").unwrap();
    let mut writer = SerialLine::from_pty(pair, "writer").unwrap();
    // The peer speaks first, so the writer lets go of its own hold on the peer's end.
    peer.write_all(b"hello").await.unwrap();
    let mut buf = [0; 16];
    tokio::time::timeout(BOUND, writer.read(&mut buf))
        .await
        .expect("the peer's bytes arrive")
        .unwrap();
    fill(&writer);
    drop(peer);
    let outcome = tokio::time::timeout(BOUND, writer.write_all(&[0xAA; 4096]))
        .await
        .expect("a write to a full line whose peer is gone ends");
    assert!(
        matches!(outcome, Err(LinkError::HangUp { ref link }) if link == "writer"),
        "{outcome:?}"
    );
}
