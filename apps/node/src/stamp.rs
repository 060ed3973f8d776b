//! Headers for outgoing messages.

use stride_lcmtypes::stride::HeaderT;

use lcm::now_utime;

/// Makes the headers of one publisher's messages on one channel: the current time and a
/// sequence number counting up by one, so receivers can count what they lose.
///
/// Each stamper starts its numbers at a random point of [0, 2^62): a receiver tells the
/// publishers of one channel apart by their numbers (a dozen nodes' heartbeats on one channel,
/// each counting from the same start, would read as one stream that loses messages), and a
/// publisher restarted is a new stream, not a jump back.
#[derive(Debug, Clone)]
pub struct Stamper {
    next: i64,
    frame: String,
}

impl Default for Stamper {
    fn default() -> Self {
        Stamper::new("")
    }
}

/// A random start for a sequence, in [0, 2^62).
fn random_start() -> i64 {
    use std::hash::{BuildHasher, Hasher};
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNT: AtomicU64 = AtomicU64::new(0);
    // std's hasher keys come from the system's randomness, once per process.
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(COUNT.fetch_add(1, Ordering::Relaxed));
    h.write_u32(std::process::id());
    h.write_i64(now_utime());
    (h.finish() >> 2) as i64
}

impl Stamper {
    /// A stamper for data in `frame` ("" when none applies), its numbers from a random start.
    pub fn new(frame: impl Into<String>) -> Self {
        Stamper::starting_at(random_start(), frame)
    }

    /// A stamper whose first number is `first` (a replay, a test).
    pub fn starting_at(first: i64, frame: impl Into<String>) -> Self {
        Stamper {
            next: first,
            frame: frame.into(),
        }
    }

    /// The next header.
    pub fn stamp(&mut self) -> HeaderT {
        let h = HeaderT {
            utime: now_utime(),
            sequence: self.next,
            frame: self.frame.clone(),
        };
        self.next = self.next.wrapping_add(1);
        h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sequence_counts_up() {
        let mut s = Stamper::new("world");
        let a = s.stamp();
        let b = s.stamp();
        assert_eq!(b.sequence, a.sequence + 1);
        assert_eq!(a.frame, "world");
        assert!(b.utime >= a.utime && a.utime > 0);
        let mut z = Stamper::starting_at(0, "");
        assert_eq!((z.stamp().sequence, z.stamp().sequence), (0, 1));
    }

    #[test]
    fn publishers_start_their_numbers_far_apart() {
        let starts: Vec<i64> = (0..12).map(|_| Stamper::new("").stamp().sequence).collect();
        for (i, a) in starts.iter().enumerate() {
            assert!(*a >= 0);
            for b in &starts[i + 1..] {
                assert!(a.abs_diff(*b) > 1 << 20, "{starts:?}");
            }
        }
    }
}
