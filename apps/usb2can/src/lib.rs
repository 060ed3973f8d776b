//! The logic of `stride-usb2can`: the bounded send queue (frames from LCM wait their turn for
//! the wire; a full queue refuses new ones, a frame past its age is dropped, not sent late)
//! and the gateway's counters, published as `stride.can_bus_status_t`.

mod app;

pub use app::{Cli, GatewayApp};

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use stride_can::CanFrame;
use stride_can_lcm::{msg_to_frame, BadFrame};
use stride_canbus::{BusError, CanBus};
use stride_lcmtypes::stride::{CanBusStatusT, CanFrameT, HeaderT};

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
    /// Frames the interface failed to send, or did not confirm in time; none is sent again
    /// (a frame the interface may have sent must not go twice).
    pub send_errors: u64,
    /// Times the interface went bus-off.
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

    /// Frames from LCM dropped before the wire: queue full, too old, or no frame.
    pub fn dropped(&self) -> u64 {
        self.dropped_queue_full + self.dropped_stale + self.invalid
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

/// How a turn of sending ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TurnEnd {
    /// Nothing is left to send.
    Drained,
    /// The turn's time ran out with frames waiting: come back at once.
    Slice,
    /// The interface takes nothing now (its queue is full, or bus-off): come back later.
    Blocked,
}

/// How long before its receipt (`received_utime`) a frame stamped `utime` was sent, both µs
/// on the wall clock: its stamp is taken when it is at most [`STAMP_TRUSTED`] before the
/// receipt (the sender's clock, the same computer's or one synchronised with it); a stamp
/// after the receipt, or older (none: 0, a clock that is not synchronised), counts as sent
/// at the receipt.
pub fn sent_before(utime: i64, received_utime: i64) -> Duration {
    let waited = received_utime.saturating_sub(utime);
    if (0..=STAMP_TRUSTED.as_micros() as i64).contains(&waited) {
        Duration::from_micros(waited as u64)
    } else {
        Duration::ZERO
    }
}

/// How far before its receipt a frame's stamp is still taken for its sending (beyond: a
/// clock not synchronised with this one).
pub const STAMP_TRUSTED: Duration = Duration::from_secs(10);

/// What a turn of sending did.
#[derive(Debug, Clone, PartialEq)]
pub struct Turn {
    /// How it ended.
    pub end: TurnEnd,
    /// The frames that went out, in order.
    pub sent: Vec<CanFrame>,
    /// Frames that failed (not sent again), with why.
    pub failed: Vec<(CanFrame, BusError)>,
    /// The interface went bus-off in this turn (it was not before).
    pub bus_off: bool,
}

/// The LCM-to-wire side of the gateway: the send queue, the counters, and whether the
/// interface is bus-off.
#[derive(Debug, Clone)]
pub struct Gateway {
    /// Frames waiting for the wire.
    pub queue: SendQueue,
    /// The counters.
    pub stats: GatewayStats,
    bus_off: bool,
}

impl Gateway {
    /// A gateway with an empty queue.
    pub fn new(queue: SendQueue) -> Gateway {
        Gateway {
            queue,
            stats: GatewayStats::default(),
            bus_off: false,
        }
    }

    /// Takes a batch's frames from LCM that liblcm received at `arrived` (`received_utime` on
    /// the wall clock): each queued, or counted as refused; returns why each refused element
    /// is no frame. A frame is as old as its sender's stamp says ([`sent_before`]): one that
    /// waited for a gateway held up by its computer is not sent as if it were new.
    pub fn take(
        &mut self,
        frames: &[CanFrameT],
        arrived: Instant,
        received_utime: i64,
    ) -> Vec<BadFrame> {
        let mut bad = Vec::new();
        for e in frames {
            match msg_to_frame(e) {
                Ok(f) => {
                    let since = arrived
                        .checked_sub(sent_before(e.utime, received_utime))
                        .unwrap_or(arrived);
                    self.queue.push(f, since, &mut self.stats);
                }
                Err(why) => {
                    self.stats.invalid += 1;
                    bad.push(why);
                }
            }
        }
        bad
    }

    /// Sends waiting frames, oldest first, until `until`, the queue is empty, or the
    /// interface takes no more. A frame the interface refuses (its queue full, bus-off)
    /// waits for the next turn; one it fails or does not confirm is counted and dropped.
    pub fn send(&mut self, bus: &mut (impl CanBus + ?Sized), until: Instant) -> Turn {
        let mut turn = Turn {
            end: TurnEnd::Drained,
            sent: Vec::new(),
            failed: Vec::new(),
            bus_off: false,
        };
        loop {
            let now = Instant::now();
            let Some(f) = self.queue.next(now, &mut self.stats) else {
                turn.end = TurnEnd::Drained;
                return turn;
            };
            if now >= until {
                turn.end = TurnEnd::Slice;
                return turn;
            }
            match bus.send(&f, now + Duration::from_millis(5)) {
                Ok(()) => {
                    self.stats.to_wire += 1;
                    self.queue.sent();
                    self.bus_off = false;
                    turn.sent.push(f);
                }
                Err(BusError::TxQueueFull) => {
                    turn.end = TurnEnd::Blocked;
                    return turn;
                }
                Err(BusError::BusOff) => {
                    turn.bus_off = self.on_bus_off();
                    turn.end = TurnEnd::Blocked;
                    return turn;
                }
                Err(e) => {
                    self.stats.send_errors += 1;
                    self.queue.sent();
                    turn.failed.push((f, e));
                }
            }
        }
    }

    /// The interface reported bus-off; true when it was not before (counted once per
    /// episode).
    pub fn on_bus_off(&mut self) -> bool {
        let new = !self.bus_off;
        if new {
            self.stats.bus_off += 1;
        }
        self.bus_off = true;
        new
    }

    /// A frame came from the wire: the bus is up.
    pub fn on_received(&mut self, frames: usize) {
        self.stats.from_wire += frames as u64;
        if frames > 0 {
            self.bus_off = false;
        }
    }

    /// True while the interface is bus-off.
    pub fn is_bus_off(&self) -> bool {
        self.bus_off
    }

    /// The gateway's status message.
    pub fn status(&self, header: HeaderT, bus: &str, device: &str) -> CanBusStatusT {
        status_msg(header, bus, device, &self.stats, &self.queue)
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
    use stride_canbus::MemBus;

    /// A bus that fails every send with `e`.
    struct Failing(BusError);

    impl CanBus for Failing {
        fn send(&mut self, _: &CanFrame, _: Instant) -> Result<(), BusError> {
            Err(self.0.clone())
        }
        fn recv(&mut self, _: Instant) -> Result<CanFrame, BusError> {
            Err(BusError::Timeout)
        }
    }

    fn gateway(frames: u16) -> Gateway {
        let mut g = Gateway::new(SendQueue::new(100, Duration::from_secs(10)));
        for i in 0..frames {
            g.queue.push(frame(i), Instant::now(), &mut g.stats);
        }
        g
    }

    #[test]
    fn a_send_the_interface_did_not_confirm_is_not_sent_again() {
        let mut g = gateway(3);
        let later = Instant::now() + Duration::from_secs(1);
        let t = g.send(&mut Failing(BusError::Timeout), later);
        assert_eq!(t.end, TurnEnd::Drained);
        assert_eq!(t.failed.len(), 3);
        assert_eq!(
            (g.stats.send_errors, g.stats.to_wire, g.queue.len()),
            (3, 0, 0)
        );
    }

    #[test]
    fn bus_off_is_counted_once_and_the_frames_wait() {
        let mut g = gateway(3);
        let later = Instant::now() + Duration::from_secs(1);
        for i in 0..5 {
            let t = g.send(&mut Failing(BusError::BusOff), later);
            assert_eq!((t.end, t.bus_off), (TurnEnd::Blocked, i == 0));
        }
        assert_eq!((g.stats.bus_off, g.queue.len()), (1, 3));
        assert!(g.is_bus_off());
        // Frames from the wire again: the bus is back; a second bus-off is a second episode.
        g.on_received(1);
        assert!(!g.is_bus_off());
        assert!(g.on_bus_off());
        assert_eq!(g.stats.bus_off, 2);
        // A full interface queue is no error: the frame waits its turn.
        let t = g.send(&mut Failing(BusError::TxQueueFull), later);
        assert_eq!(
            (t.end, g.queue.len(), g.stats.send_errors),
            (TurnEnd::Blocked, 3, 0)
        );
    }

    #[test]
    fn a_turn_sends_in_order_and_ends_with_its_slice() {
        let bus = MemBus::new(1_000_000);
        let (mut a, mut b) = (bus.node(), bus.node());
        let mut g = gateway(3);
        let t = g.send(&mut a, Instant::now());
        assert_eq!((t.end, t.sent.len()), (TurnEnd::Slice, 0));
        let t = g.send(&mut a, Instant::now() + Duration::from_secs(1));
        assert_eq!(t.end, TurnEnd::Drained);
        assert_eq!(t.sent, [frame(0), frame(1), frame(2)]);
        let got: Vec<_> = (0..3)
            .map(|_| b.recv(Instant::now() + Duration::from_secs(1)).unwrap())
            .collect();
        assert_eq!(got, t.sent);
        // A batch with a bad element: the good ones queued, the bad one counted.
        let mut bad = stride_can_lcm::frame_to_msg(&frame(7), 0);
        bad.dlc = 9;
        let good = stride_can_lcm::frame_to_msg(&frame(8), 0);
        assert_eq!(g.take(&[good, bad], Instant::now(), 0).len(), 1);
        assert_eq!((g.queue.len(), g.stats.invalid), (1, 1));
    }

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

    /// A stress run: a gateway held up by its loaded computer read a flood's frames 0.6 s
    /// after they were published and sent them as new (630 ms after their publication,
    /// against an age bound of 100 ms). A frame is as old as its sender's stamp.
    #[test]
    fn a_frame_that_waited_for_the_gateway_is_as_old_as_its_senders_stamp() {
        let mut g = Gateway::new(SendQueue::new(100, Duration::from_millis(100)));
        let t0 = Instant::now();
        let received = 1_000_000_000;
        let stamped = |utime: i64| {
            let mut m = stride_can_lcm::frame_to_msg(&frame(0), utime);
            m.utime = utime;
            m
        };
        let frames = [
            stamped(received - 600_000), // waited 0.6 s before the gateway read it: stale
            stamped(received - 20_000),  // 20 ms: goes
            stamped(0),                  // no stamp: as old as its receipt
            stamped(received + 5_000),   // a clock ahead: as old as its receipt
            stamped(received - 60_000_000), // a clock a minute behind: likewise
        ];
        assert!(g.take(&frames, t0, received).is_empty());
        let mut n = 0;
        while g
            .queue
            .next(t0 + Duration::from_millis(50), &mut g.stats)
            .is_some()
        {
            g.queue.sent();
            n += 1;
        }
        assert_eq!((n, g.stats.dropped_stale), (4, 1));
        assert_eq!(
            sent_before(received - 20_000, received),
            Duration::from_millis(20)
        );
    }
}
