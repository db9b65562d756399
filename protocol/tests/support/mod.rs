//! Helpers shared by the link tests (each test binary uses the part it needs).
#![allow(dead_code)]

use std::io::{self, Write};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use scanhil_protocol::link::CanLink;

/// A writer whose bytes (and `write` calls) the test reads back: clones share one buffer, so
/// a capture can own one clone while the test keeps another.
#[derive(Clone, Default)]
pub struct SharedBuffer(Arc<Mutex<(Vec<u8>, usize)>>);

impl SharedBuffer {
    /// Everything written so far.
    pub fn bytes(&self) -> Vec<u8> {
        self.0.lock().unwrap().0.clone()
    }

    /// How many `write` calls it took.
    pub fn writes(&self) -> usize {
        self.0.lock().unwrap().1
    }
}

impl Write for SharedBuffer {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let mut shared = self.0.lock().unwrap();
        shared.0.extend_from_slice(buf);
        shared.1 += 1;
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// Asserts that `link` receives nothing within `wait`, that the wait lasted at least `wait`,
/// and that nothing is queued afterwards.
pub async fn assert_nothing_arrives(link: &mut CanLink, wait: Duration) {
    let started = Instant::now();
    assert!(link.recv_timeout(wait).await.unwrap().is_none());
    assert!(started.elapsed() >= wait);
    assert!(link.try_recv().unwrap().is_none());
}
