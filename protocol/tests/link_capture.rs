//! Capture on its own: candump lines stamped with the virtual clock the loop sets; what it
//! holds is written with one `write` per flush, and never much more than its bound is held.

mod support;

use std::time::Duration;

use scanhil_protocol::can::{CanFrame, CanId};
use scanhil_protocol::link::{
    ByteCapture, CAPTURE_FLUSH_BYTES, CanCapture, CaptureClock, VirtualClock,
};

use support::SharedBuffer;

#[test]
fn can_capture_writes_candump_lines_at_virtual_time() {
    let out = SharedBuffer::default();
    let clock = VirtualClock::default();
    let mut capture = CanCapture::new(out.clone(), "fsm", CaptureClock::Virtual(clock.clone()));
    let frame = CanFrame::new(CanId::standard(0x110).unwrap(), &[0xDE, 0xAD]).unwrap();
    clock.set(Duration::from_micros(1_000_050));
    capture.record(&frame).unwrap();
    capture.flush().unwrap();
    let text = String::from_utf8(out.bytes()).unwrap();
    assert_eq!(text, "(1.000050) fsm 110#DEAD\n");
}

/// `--record-epoch`: the loop's time after the run's start on the wall clock, so the stamps
/// are Unix times and stay exactly the loop's periods apart.
#[test]
fn an_epoch_capture_adds_the_virtual_time_to_its_start() {
    let out = SharedBuffer::default();
    let clock = VirtualClock::default();
    let start = Duration::new(1_764_700_000, 999_990_000);
    let mut capture = CanCapture::new(
        out.clone(),
        "can0",
        CaptureClock::VirtualSinceEpoch {
            start,
            clock: clock.clone(),
        },
    );
    for period in [0, 1, 2] {
        clock.set(Duration::from_micros(50 * period));
        capture.record(&frame()).unwrap();
    }
    capture.flush().unwrap();
    assert_eq!(
        String::from_utf8(out.bytes()).unwrap(),
        "(1764700000.999990) can0 110#0102030405060708\n\
         (1764700001.000040) can0 110#0102030405060708\n\
         (1764700001.000090) can0 110#0102030405060708\n"
    );
}

/// [`CaptureClock::since_now`] starts at the wall clock's present reading.
#[test]
fn since_now_starts_at_the_wall_clock() {
    let before = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap();
    let CaptureClock::VirtualSinceEpoch { start, .. } =
        CaptureClock::since_now(VirtualClock::default())
    else {
        panic!("not an epoch clock");
    };
    let after = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap();
    assert!(
        before <= start && start <= after,
        "{before:?} {start:?} {after:?}"
    );
}

fn frame() -> CanFrame {
    CanFrame::new(CanId::standard(0x110).unwrap(), &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap()
}

#[test]
fn a_can_capture_writes_what_it_holds_with_one_write_per_flush() {
    let out = SharedBuffer::default();
    let mut capture = CanCapture::new(out.clone(), "fsm", CaptureClock::Wall);
    for _ in 0..4 {
        capture.record(&frame()).unwrap();
    }
    assert_eq!(out.writes(), 0);
    capture.flush().unwrap();
    assert_eq!(out.writes(), 1);
    let one_line = out.bytes().len() / 4;
    capture.flush().unwrap();
    assert_eq!(out.writes(), 1, "an empty flush writes nothing");
    capture.record(&frame()).unwrap();
    drop(capture);
    assert_eq!(
        (out.writes(), out.bytes().len()),
        (2, 5 * one_line),
        "drop writes the rest"
    );
}

#[test]
fn a_capture_never_holds_much_more_than_its_bound() {
    let out = SharedBuffer::default();
    let mut capture = ByteCapture::new(out.clone()).with_sent(SharedBuffer::default());
    let chunk = [0x5A_u8; 1000];
    for _ in 0..1000 {
        capture.record_received(&chunk).unwrap();
    }
    let held = 1000 * chunk.len() - out.bytes().len();
    assert!(held < CAPTURE_FLUSH_BYTES, "{held} bytes held");
    let chunks_per_write = CAPTURE_FLUSH_BYTES.div_ceil(chunk.len());
    assert_eq!(
        out.writes(),
        1000 / chunks_per_write,
        "one write per bound's worth"
    );
    capture.flush().unwrap();
    assert_eq!(out.bytes().len(), 1000 * chunk.len());
}
