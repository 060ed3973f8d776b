//! Counting lost messages from their sequence numbers.

/// Tracks one publisher's sequence numbers and counts the gaps between them.
///
/// liblcm drops messages silently (full subscription queue, full kernel buffer, a lost
/// fragment); a gap in the per-publisher sequence number is how a receiver notices.
/// A sequence number that goes backwards is taken as a restarted publisher.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct SequenceTracker {
    last: Option<i64>,
    lost: u64,
    restarts: u64,
}

impl SequenceTracker {
    /// A tracker that has seen nothing yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records sequence number `seq`; returns how many messages were lost just before it.
    pub fn observe(&mut self, seq: i64) -> u64 {
        let gap = match self.last {
            Some(last) if seq > last => (seq - last - 1) as u64,
            Some(_) => {
                self.restarts += 1;
                0
            }
            None => 0,
        };
        self.last = Some(seq);
        self.lost += gap;
        gap
    }

    /// Total messages lost so far.
    pub fn lost(&self) -> u64 {
        self.lost
    }

    /// How many times the sequence went backwards (publisher restarts or duplicates).
    pub fn restarts(&self) -> u64 {
        self.restarts
    }

    /// The last sequence number seen.
    pub fn last(&self) -> Option<i64> {
        self.last
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_gaps_and_restarts() {
        let mut t = SequenceTracker::new();
        assert_eq!(t.observe(0), 0);
        assert_eq!(t.observe(1), 0);
        assert_eq!(t.observe(5), 3);
        assert_eq!(t.observe(0), 0);
        assert_eq!(t.observe(2), 1);
        assert_eq!(t.lost(), 4);
        assert_eq!(t.restarts(), 1);
        assert_eq!(t.last(), Some(2));
    }
}
