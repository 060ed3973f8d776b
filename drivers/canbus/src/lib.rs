//! One CAN bus abstraction, [`CanBus`], with deadlines on every call, and its backends:
//! [`MemBus`], an in-memory bus with any number of nodes where each frame takes its real time
//! on the wire at the chosen bit rate (so timing-sensitive code meets realistic delays and bus
//! load is measured), [`slcan::SlcanBus`], a USB2CAN dongle speaking SLCAN on a serial port,
//! and (feature `socketcan`) a Linux kernel interface. The bus carried over LCM is
//! `stride-can-lcm`'s.

pub mod slcan;
#[cfg(feature = "socketcan")]
pub mod socketcan;
mod spec;

pub use spec::{BusSpec, BUS_FORMS};

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

pub use stride_can::CanFrame;

/// Why a bus operation failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BusError {
    /// The deadline passed before the operation could complete.
    #[error("timed out")]
    Timeout,
    /// The transmit queue is full (the bus is saturated or the controller is stuck).
    #[error("transmit queue full")]
    TxQueueFull,
    /// The controller is bus-off.
    #[error("bus off")]
    BusOff,
    /// The underlying device failed.
    #[error("device error: {0}")]
    Device(String),
}

/// A CAN bus as a driver sees it: send and receive frames, each call bounded by a deadline.
pub trait CanBus {
    /// Queues `frame` for transmission; fails if it cannot be queued by `deadline`.
    fn send(&mut self, frame: &CanFrame, deadline: Instant) -> Result<(), BusError>;
    /// The next frame from another node, waiting until `deadline`.
    fn recv(&mut self, deadline: Instant) -> Result<CanFrame, BusError>;
    /// The next frame if one is already there.
    fn try_recv(&mut self) -> Result<Option<CanFrame>, BusError> {
        match self.recv(Instant::now()) {
            Ok(f) => Ok(Some(f)),
            Err(BusError::Timeout) => Ok(None),
            Err(e) => Err(e),
        }
    }
}

impl<T: CanBus + ?Sized> CanBus for Box<T> {
    fn send(&mut self, frame: &CanFrame, deadline: Instant) -> Result<(), BusError> {
        (**self).send(frame, deadline)
    }
    fn recv(&mut self, deadline: Instant) -> Result<CanFrame, BusError> {
        (**self).recv(deadline)
    }
}

/// Counters of a [`MemBus`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BusStats {
    /// Frames carried.
    pub frames: u64,
    /// Time the wire was busy.
    pub busy: Duration,
    /// Time since the bus was made.
    pub elapsed: Duration,
}

impl BusStats {
    /// Busy time over elapsed time, 0..=1.
    pub fn load(&self) -> f64 {
        if self.elapsed.is_zero() {
            0.0
        } else {
            (self.busy.as_secs_f64() / self.elapsed.as_secs_f64()).min(1.0)
        }
    }
}

struct Delivery {
    at: Instant,
    frame: CanFrame,
}

struct Inner {
    bit_time: Duration,
    free_at: Instant,
    inboxes: Vec<VecDeque<Delivery>>,
    /// Frames each node has on the wire or waiting for it.
    in_flight: Vec<VecDeque<Instant>>,
    frames: u64,
    busy: Duration,
    started: Instant,
    bus_off: bool,
}

/// An in-memory CAN bus at a chosen bit rate. Frames are seen by every other node once their
/// time on the wire (their exact length, stuff bits included) has passed, one frame at a time.
#[derive(Clone)]
pub struct MemBus {
    inner: Arc<(Mutex<Inner>, Condvar)>,
}

impl std::fmt::Debug for MemBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MemBus")
            .field("stats", &self.stats())
            .finish()
    }
}

/// How many frames a node may have waiting for the wire before sends fail.
pub const TX_QUEUE: usize = 64;

impl MemBus {
    /// A bus at `bits_per_second` (1 000 000 for a typical robot bus).
    pub fn new(bits_per_second: u32) -> MemBus {
        let now = Instant::now();
        MemBus {
            inner: Arc::new((
                Mutex::new(Inner {
                    bit_time: Duration::from_secs_f64(1.0 / bits_per_second as f64),
                    free_at: now,
                    inboxes: Vec::new(),
                    in_flight: Vec::new(),
                    frames: 0,
                    busy: Duration::ZERO,
                    started: now,
                    bus_off: false,
                }),
                Condvar::new(),
            )),
        }
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.0.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Connects a new node.
    pub fn node(&self) -> MemNode {
        let mut g = self.lock();
        g.inboxes.push(VecDeque::new());
        g.in_flight.push(VecDeque::new());
        MemNode {
            bus: self.clone(),
            index: g.inboxes.len() - 1,
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> BusStats {
        let g = self.lock();
        BusStats {
            frames: g.frames,
            busy: g.busy,
            elapsed: g.started.elapsed(),
        }
    }

    /// Puts the bus in (or out of) bus-off: every operation then fails with [`BusError::BusOff`].
    pub fn set_bus_off(&self, off: bool) {
        self.lock().bus_off = off;
        self.inner.1.notify_all();
    }
}

/// One node's connection to a [`MemBus`].
#[derive(Debug, Clone)]
pub struct MemNode {
    bus: MemBus,
    index: usize,
}

impl CanBus for MemNode {
    fn send(&mut self, frame: &CanFrame, _deadline: Instant) -> Result<(), BusError> {
        // Worked out before the bus is held: every node's send waits on the lock.
        let bits = frame.wire_bits();
        let mut g = self.bus.lock();
        if g.bus_off {
            return Err(BusError::BusOff);
        }
        let now = Instant::now();
        let q = &mut g.in_flight[self.index];
        while q.front().is_some_and(|t| *t <= now) {
            q.pop_front();
        }
        if q.len() >= TX_QUEUE {
            return Err(BusError::TxQueueFull);
        }
        let on_wire = g.bit_time * bits;
        let start = g.free_at.max(now);
        let end = start + on_wire;
        g.free_at = end;
        g.busy += on_wire;
        g.frames += 1;
        g.in_flight[self.index].push_back(end);
        for (i, inbox) in g.inboxes.iter_mut().enumerate() {
            if i != self.index {
                inbox.push_back(Delivery {
                    at: end,
                    frame: *frame,
                });
            }
        }
        drop(g);
        self.bus.inner.1.notify_all();
        Ok(())
    }

    fn recv(&mut self, deadline: Instant) -> Result<CanFrame, BusError> {
        let mut g = self.bus.lock();
        loop {
            if g.bus_off {
                return Err(BusError::BusOff);
            }
            let now = Instant::now();
            match g.inboxes[self.index].front() {
                Some(d) if d.at <= now => {
                    let d = g.inboxes[self.index].pop_front().expect("front");
                    return Ok(d.frame);
                }
                Some(d) => {
                    if now >= deadline {
                        return Err(BusError::Timeout);
                    }
                    let wake = d.at.min(deadline);
                    g = self
                        .bus
                        .inner
                        .1
                        .wait_timeout(g, wake - now)
                        .unwrap_or_else(|p| p.into_inner())
                        .0;
                }
                None => {
                    if now >= deadline {
                        return Err(BusError::Timeout);
                    }
                    g = self
                        .bus
                        .inner
                        .1
                        .wait_timeout(g, deadline - now)
                        .unwrap_or_else(|p| p.into_inner())
                        .0;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn soon(ms: u64) -> Instant {
        Instant::now() + Duration::from_millis(ms)
    }

    #[test]
    fn broadcast_to_every_other_node() {
        let bus = MemBus::new(1_000_000);
        let mut a = bus.node();
        let mut b = bus.node();
        let mut c = bus.node();
        let f = CanFrame::standard(0x181, &[1, 2, 3]).unwrap();
        a.send(&f, soon(10)).unwrap();
        assert_eq!(b.recv(soon(100)).unwrap(), f);
        assert_eq!(c.recv(soon(100)).unwrap(), f);
        assert_eq!(a.recv(soon(5)), Err(BusError::Timeout));
        assert_eq!(b.try_recv().unwrap(), None);
    }

    #[test]
    fn frames_take_their_time_on_the_wire() {
        // 200 8-byte frames at 125 kbit/s: 200 x their exact length (at least 111 bits each)
        // is at least 178 ms of wire time.
        let bus = MemBus::new(125_000);
        let mut a = bus.node();
        let mut b = bus.node();
        let f = CanFrame::standard(0x201, &[0; 8]).unwrap();
        let t0 = Instant::now();
        let mut sent = 0;
        let mut got = 0;
        while got < 200 {
            while sent < 200 && a.send(&f, soon(1)).is_ok() {
                sent += 1;
            }
            b.recv(soon(1000)).unwrap();
            got += 1;
        }
        let took = t0.elapsed();
        let s = bus.stats();
        assert_eq!(s.frames, 200);
        assert_eq!(
            s.busy,
            Duration::from_secs_f64(1.0 / 125_000.0) * f.wire_bits() * 200
        );
        assert!(took >= s.busy - Duration::from_millis(2), "{took:?} {s:?}");
        // Busy time is exact; the load figure also depends on scheduling, so only its range
        // is checked.
        assert!(s.load() > 0.0 && s.load() <= 1.0, "{s:?}");
    }

    #[test]
    fn queue_limit_and_bus_off() {
        let bus = MemBus::new(10_000);
        let mut a = bus.node();
        let _b = bus.node();
        let f = CanFrame::standard(0x201, &[0; 8]).unwrap();
        let mut ok = 0;
        while a.send(&f, soon(1)).is_ok() {
            ok += 1;
        }
        assert_eq!(ok, TX_QUEUE);
        assert_eq!(a.send(&f, soon(1)), Err(BusError::TxQueueFull));
        bus.set_bus_off(true);
        assert_eq!(a.send(&f, soon(1)), Err(BusError::BusOff));
        let mut c = bus.node();
        assert_eq!(c.recv(soon(1)), Err(BusError::BusOff));
    }
}
