//! Counting lost messages from their sequence numbers.

/// Counts the messages lost on one channel from the sequence numbers of those that arrive.
///
/// liblcm drops messages silently (a full subscription queue, a full kernel buffer, a lost
/// fragment); a gap in a publisher's sequence numbers is how a receiver notices. liblcm does
/// not tell a receiver who sent a message, and a channel may carry several publishers (two
/// processes, a log replayed beside live traffic, a publisher that restarted at 0), so the
/// tracker tells them apart by their numbers: it keeps up to [`MAX_STREAMS`](Self::MAX_STREAMS)
/// *streams*, each the last number of one presumed publisher.
///
/// A number `s` *follows* a stream whose last number is `l` when `s - l`, in wrapping `i64`
/// arithmetic (so `i64::MIN` follows `i64::MAX`), is between 1 and
/// [`MAX_GAP`](Self::MAX_GAP)` + 1`.
///
/// * **Lost**: a number that follows a stream joins the one it follows most closely (on a
///   tie, the one used last), and the `s - l - 1` numbers it skipped count as lost.
/// * **New stream**: any other number starts a stream and counts nothing lost: a new
///   publisher, a restart, a replay, a duplicate, a number at or behind every stream's last
///   (a late message), or a jump over more than `MAX_GAP` numbers. When all streams are taken,
///   the one used least recently is forgotten.
///
/// The count is exact for publishers whose numbers go up by one per message, skip at most
/// `MAX_GAP` at a time and stay more than `MAX_GAP + 1` away from every other publisher's on
/// the channel. A message that arrives late counts as lost (its gap was counted when its
/// successor arrived). Arithmetic wraps or saturates; nothing panics.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct SequenceTracker {
    streams: [Stream; SequenceTracker::MAX_STREAMS],
    /// How many of `streams` are in use.
    len: usize,
    /// Ticks once per number observed; a stream's `used` is the tick it was last used on.
    clock: u64,
    last: Option<i64>,
    lost: u64,
    started: u64,
}

#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
struct Stream {
    last: i64,
    used: u64,
}

impl SequenceTracker {
    /// How many streams (presumed publishers) one tracker keeps at once.
    pub const MAX_STREAMS: usize = 32;
    /// The most numbers one step may skip and still count as lost; a longer jump starts a new
    /// stream instead.
    pub const MAX_GAP: u64 = 4096;

    /// A tracker that has seen nothing yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records sequence number `seq`; returns how many messages were lost just before it
    /// (0 when `seq` starts a new stream).
    pub fn observe(&mut self, seq: i64) -> u64 {
        self.clock = self.clock.wrapping_add(1);
        self.last = Some(seq);
        let mut best: Option<(usize, u64)> = None;
        for (i, s) in self.streams[..self.len].iter().enumerate() {
            // Two's complement: the wrapping difference, read as unsigned, is 1..=MAX_GAP + 1
            // exactly when `seq` lies that far ahead of `s.last`.
            let ahead = seq.wrapping_sub(s.last) as u64;
            if ahead == 0 || ahead > Self::MAX_GAP + 1 {
                continue;
            }
            let closer = match best {
                None => true,
                Some((j, b)) => ahead < b || (ahead == b && s.used > self.streams[j].used),
            };
            if closer {
                best = Some((i, ahead));
            }
        }
        let slot = match best {
            Some((i, ahead)) => {
                self.streams[i] = Stream {
                    last: seq,
                    used: self.clock,
                };
                let gap = ahead - 1;
                self.lost = self.lost.saturating_add(gap);
                return gap;
            }
            None if self.len < Self::MAX_STREAMS => {
                self.len += 1;
                self.len - 1
            }
            None => (0..self.len)
                .min_by_key(|&i| self.streams[i].used)
                .unwrap_or(0),
        };
        self.streams[slot] = Stream {
            last: seq,
            used: self.clock,
        };
        self.started = self.started.saturating_add(1);
        0
    }

    /// Total messages lost so far (the sum of what [`observe`](Self::observe) returned).
    pub fn lost(&self) -> u64 {
        self.lost
    }

    /// Streams started so far: the first number seen, and every number that followed no
    /// stream (another publisher, a restart, a replay, a duplicate, a late message, a jump
    /// over more than [`MAX_GAP`](Self::MAX_GAP) numbers).
    pub fn streams(&self) -> u64 {
        self.started
    }

    /// Streams started after the first: [`streams`](Self::streams) minus one.
    pub fn restarts(&self) -> u64 {
        self.started.saturating_sub(1)
    }

    /// Streams held now (at most [`MAX_STREAMS`](Self::MAX_STREAMS)).
    pub fn tracked(&self) -> usize {
        self.len
    }

    /// The last sequence number seen.
    pub fn last(&self) -> Option<i64> {
        self.last
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const GAP: u64 = SequenceTracker::MAX_GAP;

    fn observe_all(t: &mut SequenceTracker, seqs: impl IntoIterator<Item = i64>) -> u64 {
        seqs.into_iter().map(|s| t.observe(s)).sum()
    }

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
        assert_eq!(t.streams(), 2);
        assert_eq!(t.last(), Some(2));
    }

    #[test]
    fn a_jump_across_the_whole_i64_range_is_a_new_stream_not_an_overflow() {
        let mut t = SequenceTracker::new();
        assert_eq!(t.observe(i64::MIN), 0);
        assert_eq!(t.observe(i64::MAX), 0);
        assert_eq!(t.observe(-1), 0);
        // MIN follows MAX (a wrapping counter) and 0 follows -1: no new streams.
        assert_eq!(t.observe(i64::MIN), 0);
        assert_eq!(t.observe(0), 0);
        assert_eq!(t.observe(i64::MAX / 2), 0);
        assert_eq!(t.lost(), 0);
        assert_eq!(t.streams(), 4);
    }

    #[test]
    fn a_counter_that_wraps_from_max_to_min_loses_nothing() {
        let mut t = SequenceTracker::new();
        let lost = observe_all(&mut t, [i64::MAX - 1, i64::MAX, i64::MIN, i64::MIN + 3]);
        assert_eq!(lost, 2);
        assert_eq!(t.streams(), 1);
    }

    #[test]
    fn a_log_replayed_beside_live_traffic_counts_nothing_lost() {
        let mut t = SequenceTracker::new();
        observe_all(&mut t, 700_000..701_100);
        // The replay starts at 0 while the live publisher goes on.
        let lost = observe_all(&mut t, (0..500).flat_map(|i| [i, 701_100 + i]));
        assert_eq!(lost, 0);
        assert_eq!(t.streams(), 2);
    }

    #[test]
    fn a_second_publisher_and_a_restart_count_only_real_gaps() {
        let mut t = SequenceTracker::new();
        observe_all(&mut t, 5000..5100);
        // A second publisher from 0, interleaved; it skips 3 and the first skips 2.
        let mut lost = observe_all(&mut t, [0, 5100, 1, 5103, 5, 5104, 6]);
        // The first restarts at 0 beside the second, which goes on from 7.
        lost += observe_all(&mut t, [0, 7, 1, 8, 2, 9]);
        assert_eq!(lost, 3 + 2);
        assert_eq!(t.streams(), 3);
    }

    #[test]
    fn duplicates_and_late_messages_count_nothing_lost() {
        let mut t = SequenceTracker::new();
        let lost = observe_all(&mut t, [10, 10, 11, 11, 12, 9, 13]);
        assert_eq!(lost, 0);
        assert_eq!(t.streams(), 3);
    }

    #[test]
    fn a_jump_over_more_than_max_gap_starts_a_stream() {
        let mut t = SequenceTracker::new();
        t.observe(0);
        assert_eq!(t.observe(GAP as i64 + 1), GAP);
        assert_eq!(t.observe(2 * GAP as i64 + 3), 0);
        assert_eq!(t.streams(), 2);
    }

    #[test]
    fn the_least_recently_used_stream_is_forgotten() {
        let mut t = SequenceTracker::new();
        let far = 1_000_000i64;
        for k in 0..SequenceTracker::MAX_STREAMS as i64 {
            t.observe(k * far);
        }
        // Use every stream but the first again, then start a ninth: the first goes.
        for k in 1..SequenceTracker::MAX_STREAMS as i64 {
            t.observe(k * far + 1);
        }
        t.observe(100 * far);
        assert_eq!(t.tracked(), SequenceTracker::MAX_STREAMS);
        assert_eq!(t.observe(2), 0, "stream 0 was forgotten");
        let newest = (SequenceTracker::MAX_STREAMS as i64 - 1) * far;
        assert_eq!(t.observe(newest + 3), 1, "the stream used last was kept");
    }

    /// Loss counts of the reliability findings: a dozen nodes' heartbeats on one channel were
    /// more publishers than the tracker kept streams for (8): one forgotten joined another's
    /// stream and counted its gap as lost, and real losses went uncounted. With each publisher
    /// starting at a random point (as stride's stampers do) and room for them all, nothing is
    /// counted lost on a bus that lost nothing, and a real loss still is.
    #[test]
    fn twelve_publishers_on_one_channel_are_told_apart() {
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            rng
        };
        // Starts as a stamper's: anywhere in [0, 2^62).
        let mut seq: Vec<i64> = (0..12).map(|_| (next() >> 2) as i64).collect();
        let mut t = SequenceTracker::new();
        for round in 0..300 {
            // Each beats once a round, in an order that changes.
            let mut order: Vec<usize> = (0..12).collect();
            for i in (1..12).rev() {
                order.swap(i, next() as usize % (i + 1));
            }
            for p in order {
                // Publisher 3 loses two beats at round 100.
                if p == 3 && (100..102).contains(&round) {
                    seq[p] += 1;
                    continue;
                }
                t.observe(seq[p]);
                seq[p] += 1;
            }
        }
        assert_eq!(t.lost(), 2);
        assert_eq!(t.streams(), 12);
    }

    /// Mostly consecutive, sometimes a drop of up to MAX_GAP messages.
    fn drops(max_len: usize) -> impl Strategy<Value = Vec<u64>> {
        prop::collection::vec(
            prop_oneof![6 => Just(0u64), 3 => 1..=8u64, 1 => 0..=GAP],
            1..max_len,
        )
    }

    /// The numbers a publisher starting at `start` sends, skipping `drops[i]` before each.
    fn received(start: i64, drops: &[u64]) -> Vec<i64> {
        let mut s = start.wrapping_sub(1);
        drops
            .iter()
            .map(|&d| {
                s = s.wrapping_add(1).wrapping_add(d as i64);
                s
            })
            .collect()
    }

    const MAX_LEN: usize = 100;
    /// More than any publisher's numbers span in these tests.
    const SPAN: u64 = MAX_LEN as u64 * (GAP + 1);

    proptest! {
        #[test]
        fn arbitrary_numbers_never_panic(
            seqs in prop::collection::vec(
                prop_oneof![
                    any::<i64>(),
                    Just(i64::MIN), Just(i64::MAX), Just(0i64), Just(-1i64),
                    (-3i64..=3).prop_map(|d| i64::MAX.wrapping_add(d)),
                    (-(GAP as i64) - 3..=GAP as i64 + 3),
                ],
                0..300,
            )
        ) {
            let mut t = SequenceTracker::new();
            let mut sum = 0u64;
            for &s in &seqs {
                let gap = t.observe(s);
                prop_assert!(gap <= GAP);
                sum += gap;
                prop_assert!(t.tracked() <= SequenceTracker::MAX_STREAMS);
            }
            prop_assert_eq!(t.lost(), sum);
            prop_assert_eq!(t.streams() == 0, seqs.is_empty());
            prop_assert!(t.streams() <= seqs.len() as u64);
            prop_assert_eq!(t.last(), seqs.last().copied());
        }

        #[test]
        fn one_publisher_with_random_drops_counts_exactly_the_drops(
            start in any::<i64>(),
            drops in drops(MAX_LEN),
        ) {
            let mut t = SequenceTracker::new();
            // The first number starts the stream: a drop before it cannot be seen.
            let expected: u64 = drops[1..].iter().sum();
            observe_all(&mut t, received(start, &drops));
            prop_assert_eq!(t.lost(), expected);
            prop_assert_eq!(t.streams(), 1);
        }

        #[test]
        fn two_interleaved_publishers_count_exactly_their_own_drops(
            start in any::<i64>(),
            offset in (SPAN + GAP + 2)..=(u64::MAX - SPAN - GAP - 2),
            drops_a in drops(MAX_LEN),
            drops_b in drops(MAX_LEN),
            order in prop::collection::vec(any::<bool>(), 2 * MAX_LEN),
        ) {
            let a = received(start, &drops_a);
            let b = received(start.wrapping_add(offset as i64), &drops_b);
            let (mut a, mut b) = (a.into_iter().peekable(), b.into_iter().peekable());
            let mut t = SequenceTracker::new();
            for take_a in order.into_iter().chain(std::iter::repeat(true)) {
                let next = match (take_a, a.peek().is_some(), b.peek().is_some()) {
                    (_, false, false) => break,
                    (true, true, _) | (false, true, false) => a.next(),
                    _ => b.next(),
                };
                t.observe(next.unwrap());
            }
            let expected: u64 = drops_a[1..].iter().sum::<u64>() + drops_b[1..].iter().sum::<u64>();
            prop_assert_eq!(t.lost(), expected);
            prop_assert_eq!(t.streams(), 2);
        }
    }
}
