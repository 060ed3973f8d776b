//! The logic of `stride-usb2can`: the bounded send queue (frames from LCM wait their turn for
//! the wire; a full queue refuses new ones, a frame past its age is dropped, not sent late)
//! and the gateway's counters, published as `stride.can_bus_status_t`.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use stride_can::CanFrame;
use stride_lcmtypes::stride::{CanBusStatusT, HeaderT};

/// Counters of the gateway since start.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GatewayStats {
    /// Frames from the wire to LCM.
    pub from_wire: u64,
    /// Frames from LCM to the wire.
    pub to_wire: u64,
    /// Frames dropped because the send queue was full.
    pub dropped_queue_full: u64,
    /// Frames dropped because they waited longer than the age limit.
    pub dropped_stale: u64,
    /// Frame elements from LCM that are no frame.
    pub invalid: u64,
    /// Frames the interface failed to send for good.
    pub send_errors: u64,
    /// Times the interface reported bus-off.
    pub bus_off: u64,
}

impl GatewayStats {
    /// A one-line summary with rates over `secs`.
    pub fn summary(&self, previous: &GatewayStats, secs: f64) -> String {
        let rate = |a: u64, b: u64| a.saturating_sub(b) as f64 / secs.max(1e-9);
        format!(
            "{:.0} frames/s from the wire, {:.0} frames/s to the wire; dropped: {} queue full, \
             {} stale, {} invalid; {} send errors, {} bus-off",
            rate(self.from_wire, previous.from_wire),
            rate(self.to_wire, previous.to_wire),
            self.dropped_queue_full,
            self.dropped_stale,
            self.invalid,
            self.send_errors,
            self.bus_off
        )
    }

    /// Frames dropped for any reason.
    pub fn dropped(&self) -> u64 {
        self.dropped_queue_full + self.dropped_stale + self.invalid + self.send_errors
    }
}

/// Frames waiting for the wire, oldest first: at most `capacity` of them, none older than
/// `max_age` when its turn comes.
#[derive(Debug, Clone)]
pub struct SendQueue {
    frames: VecDeque<(Instant, CanFrame)>,
    capacity: usize,
    max_age: Duration,
}

impl SendQueue {
    /// An empty queue.
    pub fn new(capacity: usize, max_age: Duration) -> SendQueue {
        SendQueue {
            frames: VecDeque::with_capacity(capacity.min(4096)),
            capacity: capacity.max(1),
            max_age,
        }
    }

    /// Queues a frame that arrived at `now`; false (and counted) when the queue is full.
    pub fn push(&mut self, frame: CanFrame, now: Instant, stats: &mut GatewayStats) -> bool {
        if self.frames.len() >= self.capacity {
            stats.dropped_queue_full += 1;
            return false;
        }
        self.frames.push_back((now, frame));
        true
    }

    /// The next frame to send at `now`, after dropping (and counting) those past their age.
    /// It stays queued until [`SendQueue::sent`]: a frame the interface could not take yet
    /// is tried again, until it too is past its age.
    pub fn next(&mut self, now: Instant, stats: &mut GatewayStats) -> Option<CanFrame> {
        while let Some((at, f)) = self.frames.front() {
            if now.saturating_duration_since(*at) <= self.max_age {
                return Some(*f);
            }
            self.frames.pop_front();
            stats.dropped_stale += 1;
        }
        None
    }

    /// The frame [`SendQueue::next`] gave is done with (sent, or failed for good).
    pub fn sent(&mut self) {
        self.frames.pop_front();
    }

    /// Frames waiting.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// True when nothing waits.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// The most frames that may wait.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// The age limit.
    pub fn max_age(&self) -> Duration {
        self.max_age
    }
}

/// The gateway's status message.
pub fn status_msg(
    header: HeaderT,
    bus: &str,
    device: &str,
    stats: &GatewayStats,
    queue: &SendQueue,
) -> CanBusStatusT {
    CanBusStatusT {
        header,
        bus: bus.to_owned(),
        device: device.to_owned(),
        from_wire: stats.from_wire as i64,
        to_wire: stats.to_wire as i64,
        dropped_queue_full: stats.dropped_queue_full as i64,
        dropped_stale: stats.dropped_stale as i64,
        invalid: stats.invalid as i64,
        send_errors: stats.send_errors as i64,
        bus_off: stats.bus_off as i64,
        queue_depth: queue.len() as i32,
        queue_capacity: queue.capacity() as i32,
        max_age_ms: queue.max_age().as_millis().min(i32::MAX as u128) as i32,
    }
}

/// The channel of bus `name`'s status.
pub fn status_channel(name: &str) -> String {
    format!("CAN_{}_STATUS", name.to_uppercase())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(i: u16) -> CanFrame {
        CanFrame::standard(0x600 + i, &[i as u8]).unwrap()
    }

    #[test]
    fn a_full_send_queue_refuses_and_counts() {
        let mut s = GatewayStats::default();
        let mut q = SendQueue::new(3, Duration::from_millis(100));
        let t0 = Instant::now();
        for i in 0..5 {
            q.push(frame(i), t0, &mut s);
        }
        assert_eq!((q.len(), s.dropped_queue_full), (3, 2));
        // Oldest first, each until it is sent.
        assert_eq!(q.next(t0, &mut s), Some(frame(0)));
        assert_eq!(q.next(t0, &mut s), Some(frame(0)));
        q.sent();
        assert_eq!(q.next(t0, &mut s), Some(frame(1)));
    }

    #[test]
    fn a_frame_past_its_age_is_dropped_not_sent_late() {
        let mut s = GatewayStats::default();
        let mut q = SendQueue::new(100, Duration::from_millis(100));
        let t0 = Instant::now();
        q.push(frame(0), t0, &mut s);
        q.push(frame(1), t0 + Duration::from_millis(80), &mut s);
        // At 150 ms the first is 150 ms old: dropped; the second (70 ms) goes.
        assert_eq!(
            q.next(t0 + Duration::from_millis(150), &mut s),
            Some(frame(1))
        );
        assert_eq!(s.dropped_stale, 1);
        assert_eq!(q.next(t0 + Duration::from_millis(500), &mut s), None);
        assert_eq!((s.dropped_stale, q.len()), (2, 0));
        let m = status_msg(HeaderT::default(), "left", "slcan:x", &s, &q);
        assert_eq!(
            (m.dropped_stale, m.queue_capacity, m.max_age_ms),
            (2, 100, 100)
        );
        assert!(s.summary(&GatewayStats::default(), 1.0).contains("2 stale"));
        assert_eq!(status_channel("left_leg"), "CAN_LEFT_LEG_STATUS");
    }
}
