//! An append-only sequence held in fixed-size chunks, for what a run keeps per period or per
//! sample (the sensor's samples, the mirror's angle readings): it grows without reallocating
//! (no moment with the old and the new buffer both held), and a consumer that reads it in
//! order frees what it has passed ([`Chunked::release_before`], [`Chunked::into_iter`]), so
//! imaging a long frame does not hold the frame's samples and its points at once.

use std::collections::VecDeque;

/// Makes freed chunks go back to the OS, for a program that holds long runs in [`Chunked`]
/// (call it at start-up, before any other thread). glibc's allocator raises its threshold
/// for serving a block as its own mapping to the size of the largest one freed, up to 32 MiB:
/// after the first, the 1 MiB chunks come from the heap, and freeing them as a frame is
/// paired does not shrink the process while the point cloud grows (a 60 s scan peaked at
/// 107 MB resident against 75 MB with this). A fixed threshold of 256 KiB keeps every chunk
/// a mapping of its own, unmapped when freed. Nothing on other C libraries.
pub fn return_freed_chunks_to_the_os() {
    #[cfg(target_env = "gnu")]
    // SAFETY: mallopt only sets an allocator parameter; called before other threads exist.
    unsafe {
        nix::libc::mallopt(nix::libc::M_MMAP_THRESHOLD, 256 * 1024);
    }
}

/// Items per chunk (1 MiB of 16-byte items).
const CHUNK_LEN: usize = 1 << 16;

/// An append-only sequence in chunks of 65 536 items; index `i` is the `i`-th item
/// pushed, also after the items before it were released.
#[derive(Debug, Clone, PartialEq)]
pub struct Chunked<T> {
    chunks: VecDeque<Vec<T>>,
    /// Items released from the front (whole chunks).
    released: usize,
    len: usize,
}

impl<T> Chunked<T> {
    /// An empty sequence.
    #[must_use]
    pub fn new() -> Chunked<T> {
        Chunked {
            chunks: VecDeque::new(),
            released: 0,
            len: 0,
        }
    }

    /// Appends `item` at index `self.len()`.
    pub fn push(&mut self, item: T) {
        match self.chunks.back_mut() {
            Some(chunk) if chunk.len() < CHUNK_LEN => chunk.push(item),
            _ => {
                let mut chunk = Vec::with_capacity(CHUNK_LEN);
                chunk.push(item);
                self.chunks.push_back(chunk);
            }
        }
        self.len += 1;
    }

    /// Items pushed, released ones included.
    #[must_use]
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when nothing was pushed.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Item `index`; `None` beyond the end or when it was released.
    #[must_use]
    pub fn get(&self, index: usize) -> Option<&T> {
        let held = index.checked_sub(self.released)?;
        self.chunks
            .get(held / CHUNK_LEN)
            .and_then(|chunk| chunk.get(held % CHUNK_LEN))
    }

    /// Frees the whole chunks before item `index` (items up to a chunk before it may stay).
    pub fn release_before(&mut self, index: usize) {
        while self.chunks.len() > 1 && self.released + CHUNK_LEN <= index {
            self.chunks.pop_front();
            self.released += CHUNK_LEN;
        }
    }

    /// The items still held, in order.
    pub fn iter(&self) -> impl Iterator<Item = &T> {
        self.chunks.iter().flatten()
    }
}

impl<T> Default for Chunked<T> {
    fn default() -> Self {
        Chunked::new()
    }
}

impl<T> FromIterator<T> for Chunked<T> {
    fn from_iter<I: IntoIterator<Item = T>>(items: I) -> Self {
        let mut chunked = Chunked::new();
        for item in items {
            chunked.push(item);
        }
        chunked
    }
}

/// The items of a [`Chunked`] in order, each chunk freed once it is passed.
#[derive(Debug)]
pub struct IntoIter<T> {
    chunks: std::collections::vec_deque::IntoIter<Vec<T>>,
    current: std::vec::IntoIter<T>,
    remaining: usize,
}

impl<T> Iterator for IntoIter<T> {
    type Item = T;

    fn next(&mut self) -> Option<T> {
        loop {
            if let Some(item) = self.current.next() {
                self.remaining -= 1;
                return Some(item);
            }
            self.current = self.chunks.next()?.into_iter();
        }
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.remaining, Some(self.remaining))
    }
}

impl<T> ExactSizeIterator for IntoIter<T> {}

impl<T> IntoIterator for Chunked<T> {
    type Item = T;
    type IntoIter = IntoIter<T>;

    /// The items still held, each chunk freed once passed.
    fn into_iter(self) -> IntoIter<T> {
        IntoIter {
            remaining: self.chunks.iter().map(Vec::len).sum(),
            chunks: self.chunks.into_iter(),
            current: Vec::new().into_iter(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_hold_across_chunks_and_after_a_release() {
        let n = 3 * CHUNK_LEN + 5;
        let mut chunked: Chunked<usize> = (0..n).collect();
        assert_eq!(chunked.len(), n);
        assert_eq!(chunked.get(CHUNK_LEN), Some(&CHUNK_LEN));
        assert_eq!(chunked.get(n - 1), Some(&(n - 1)));
        assert_eq!(chunked.get(n), None);
        // Releasing before an index inside chunk 2 frees chunks 0 and 1 only.
        chunked.release_before(2 * CHUNK_LEN + 7);
        assert_eq!(chunked.get(2 * CHUNK_LEN - 1), None);
        assert_eq!(chunked.get(2 * CHUNK_LEN), Some(&(2 * CHUNK_LEN)));
        assert_eq!(chunked.len(), n, "released items keep their indices");
        chunked.push(n);
        assert_eq!(chunked.get(n), Some(&n));
        assert!(chunked.iter().copied().eq(2 * CHUNK_LEN..=n));
    }

    #[test]
    fn the_last_chunk_is_never_released() {
        let mut chunked: Chunked<u8> = std::iter::repeat_n(1, CHUNK_LEN).collect();
        chunked.release_before(usize::MAX);
        assert_eq!(chunked.get(CHUNK_LEN - 1), Some(&1));
        chunked.push(2);
        assert_eq!(chunked.get(CHUNK_LEN), Some(&2));
    }

    #[test]
    fn into_iter_gives_every_held_item_in_order_with_an_exact_size() {
        let chunked: Chunked<u32> = (0..(2 * CHUNK_LEN as u32 + 3)).collect();
        let mut items = chunked.into_iter();
        assert_eq!(items.len(), 2 * CHUNK_LEN + 3);
        assert_eq!(items.next(), Some(0));
        assert_eq!(items.len(), 2 * CHUNK_LEN + 2);
        assert!(items.eq(1..(2 * CHUNK_LEN as u32 + 3)));
        assert_eq!(Chunked::<u8>::new().into_iter().next(), None);
    }
}
