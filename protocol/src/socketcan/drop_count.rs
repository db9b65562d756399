//! Frames the kernel dropped for one socket: when a raw CAN socket's receive queue is full
//! (its `SO_RCVBUF`), a frame for it is discarded and the socket's `sk_drops` counter goes up
//! by one (`__sock_queue_rcv_skb` in net/core/sock.c). That counter is what `SO_RXQ_OVFL`
//! hands out with each received frame (candump's `DROPCOUNT` lines) and what `SO_MEMINFO`
//! returns at [`SK_MEMINFO_DROPS`] of its array of `u32`s; the link reads it with `SO_MEMINFO`
//! ([`drops_in_meminfo`]) when asked for its report. It is a `u32` that wraps; [`DropCount`]
//! counts from a first reading across one wrap.

/// The index of `sk_drops` in `SO_MEMINFO`'s array (`SK_MEMINFO_DROPS`, linux/sock_diag.h).
pub const SK_MEMINFO_DROPS: usize = 8;
/// The length of `SO_MEMINFO`'s array, in `u32`s (`SK_MEMINFO_VARS`, linux/sock_diag.h, since
/// Linux 4.12).
pub const SK_MEMINFO_VARS: usize = 9;

/// The drop counter in the bytes `SO_MEMINFO` returned (native-endian `u32`s); `None` when
/// they are too few to hold it.
#[must_use]
pub fn drops_in_meminfo(bytes: &[u8]) -> Option<u32> {
    let at = SK_MEMINFO_DROPS * 4;
    let word = bytes.get(at..at + 4)?;
    Some(u32::from_ne_bytes(word.try_into().ok()?))
}

/// Frames dropped since a first reading of the counter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DropCount {
    first: u32,
    latest: u32,
}

impl DropCount {
    /// Starts counting at the counter's value `first`.
    #[must_use]
    pub fn starting_at(first: u32) -> DropCount {
        DropCount {
            first,
            latest: first,
        }
    }

    /// Takes a later reading of the counter.
    pub fn observe(&mut self, counter: u32) {
        self.latest = counter;
    }

    /// Frames dropped between the first reading and the latest (the counter may have wrapped
    /// once in between).
    #[must_use]
    pub fn dropped(&self) -> u32 {
        self.latest.wrapping_sub(self.first)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_drop_counter_is_the_ninth_word_of_meminfo() {
        let words: Vec<u32> = (100..100 + SK_MEMINFO_VARS as u32).collect();
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_ne_bytes()).collect();
        assert_eq!(drops_in_meminfo(&bytes), Some(108));
        assert_eq!(drops_in_meminfo(&bytes[..SK_MEMINFO_VARS * 4 - 1]), None);
        assert_eq!(drops_in_meminfo(&bytes[..32]), None);
        assert_eq!(drops_in_meminfo(&[]), None);
        // A later kernel's longer array: the same word.
        let mut longer = bytes.clone();
        longer.extend_from_slice(&7u32.to_ne_bytes());
        assert_eq!(drops_in_meminfo(&longer), Some(108));
    }

    #[test]
    fn drops_are_counted_from_the_first_reading_across_a_wrap() {
        let mut count = DropCount::starting_at(5);
        assert_eq!(count.dropped(), 0);
        count.observe(12);
        assert_eq!(count.dropped(), 7);
        let mut wrapped = DropCount::starting_at(u32::MAX - 1);
        wrapped.observe(3);
        assert_eq!(wrapped.dropped(), 5);
    }
}
