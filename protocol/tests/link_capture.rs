//! Capture on its own: candump lines stamped with the virtual clock the loop sets.

mod support;

use std::time::Duration;

use scanhil_protocol::can::{CanFrame, CanId};
use scanhil_protocol::link::{CanCapture, CaptureClock, VirtualClock};

use support::SharedBuffer;

#[test]
fn can_capture_writes_candump_lines_at_virtual_time() {
    let out = SharedBuffer::default();
    let clock = VirtualClock::default();
    let mut capture = CanCapture::new(out.clone(), "fsm", CaptureClock::Virtual(clock.clone()));
    let frame = CanFrame::new(CanId::standard(0x110).unwrap(), &[0xDE, 0xAD]).unwrap();
    clock.set(Duration::from_micros(1_000_050));
    capture.record(&frame).unwrap();
    let text = String::from_utf8(out.bytes()).unwrap();
    assert_eq!(text, "(1.000050) fsm 110#DEAD\n");
}
