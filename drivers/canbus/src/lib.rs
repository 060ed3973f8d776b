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
        match self.recv(self.now()) {
            Ok(f) => Ok(Some(f)),
            Err(BusError::Timeout) => Ok(None),
            Err(e) => Err(e),
        }
    }
    /// The bus's time: the monotonic clock on a real bus, the modelled clock on a
    /// [`MemBus::modelled`] bus. Drivers read time here, so that the same code runs on either.
    fn now(&self) -> Instant {
        Instant::now()
    }
    /// The wall clock at [`CanBus::now`], µs since the Unix epoch.
    fn utime(&self) -> i64 {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_micros() as i64)
    }
    /// Waits until `t` of the bus's time (on a modelled bus, the devices on it run until then).
    fn wait_until(&mut self, t: Instant) {
        if let Some(d) = t.checked_duration_since(Instant::now()) {
            std::thread::sleep(d);
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
    fn try_recv(&mut self) -> Result<Option<CanFrame>, BusError> {
        (**self).try_recv()
    }
    fn now(&self) -> Instant {
        (**self).now()
    }
    fn utime(&self) -> i64 {
        (**self).utime()
    }
    fn wait_until(&mut self, t: Instant) {
        (**self).wait_until(t)
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
    /// The modelled time, on a [`MemBus::modelled`] bus.
    modelled: Option<Instant>,
    /// The wall clock at `started`, µs since the Unix epoch.
    utime0: i64,
}

impl Inner {
    fn now(&self) -> Instant {
        self.modelled.unwrap_or_else(Instant::now)
    }
}

/// A device a modelled bus steps as its time moves: a fake drive, say.
pub trait Device: Send {
    /// Takes in what has arrived on `bus` and does what is due by `now`.
    fn step(&mut self, now: Instant, bus: &mut MemNode);
}

/// A device on a modelled bus, shared with whoever attached it.
pub type Attached<D> = Arc<Mutex<D>>;

struct Attachment {
    node: MemNode,
    device: Arc<Mutex<dyn Device>>,
    tick: Duration,
    next: Instant,
}

/// An in-memory CAN bus at a chosen bit rate. Frames are seen by every other node once their
/// time on the wire (their exact length, stuff bits included) has passed, one frame at a time.
///
/// Made with [`MemBus::new`], the bus runs on the monotonic clock and its nodes wait as on a
/// real bus (threads on both sides). Made with [`MemBus::modelled`], it runs on a clock that
/// moves only when one thread waits on it ([`CanBus::recv`], [`CanBus::wait_until`],
/// [`MemBus::advance_to`]): time then jumps from event to event (a frame's arrival, a
/// device's step), stepping the [`Device`]s attached to it on the way, so that a test of a
/// master and its devices does not depend on how the machine schedules threads.
#[derive(Clone)]
pub struct MemBus {
    inner: Arc<(Mutex<Inner>, Condvar)>,
    devices: Arc<Mutex<Vec<Attachment>>>,
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
    /// A bus at `bits_per_second` (1 000 000 for a typical robot bus) on the monotonic clock.
    pub fn new(bits_per_second: u32) -> MemBus {
        MemBus::make(bits_per_second, false)
    }

    /// A bus at `bits_per_second` on a modelled clock, which starts now and moves only when a
    /// node waits; one thread uses it (the test's), the devices attached run on it.
    pub fn modelled(bits_per_second: u32) -> MemBus {
        MemBus::make(bits_per_second, true)
    }

    fn make(bits_per_second: u32, modelled: bool) -> MemBus {
        let now = Instant::now();
        let utime0 = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_micros() as i64);
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
                    modelled: modelled.then_some(now),
                    utime0,
                }),
                Condvar::new(),
            )),
            devices: Arc::default(),
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
            elapsed: g.now() - g.started,
        }
    }

    /// Puts the bus in (or out of) bus-off: every operation then fails with [`BusError::BusOff`].
    pub fn set_bus_off(&self, off: bool) {
        self.lock().bus_off = off;
        self.inner.1.notify_all();
    }

    /// The bus's time (see [`CanBus::now`]).
    pub fn now(&self) -> Instant {
        self.lock().now()
    }

    /// The wall clock at [`MemBus::now`], µs since the Unix epoch: on a modelled bus, the wall
    /// clock when it was made plus the modelled time since.
    pub fn utime(&self) -> i64 {
        let g = self.lock();
        match g.modelled {
            Some(t) => g.utime0 + (t - g.started).as_micros() as i64,
            None => std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_micros() as i64),
        }
    }

    /// True on a [`MemBus::modelled`] bus.
    pub fn is_modelled(&self) -> bool {
        self.lock().modelled.is_some()
    }

    /// Attaches `device` on a node of its own, stepped every `tick` of the modelled time and
    /// whenever a frame reaches it; the handle shares it with the caller. Only a modelled bus
    /// steps its devices (on a bus on the monotonic clock, give a device a thread of its own).
    pub fn attach<D: Device + 'static>(&self, device: D, tick: Duration) -> Attached<D> {
        let shared = Arc::new(Mutex::new(device));
        let node = self.node();
        let next = self.now();
        self.devices
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(Attachment {
                node,
                device: shared.clone(),
                tick: tick.max(Duration::from_micros(1)),
                next,
            });
        shared
    }

    /// Moves the modelled time to `t`, stepping the devices on the way (on a bus on the
    /// monotonic clock, sleeps until `t`).
    pub fn advance_to(&self, t: Instant) {
        if !self.is_modelled() {
            if let Some(d) = t.checked_duration_since(Instant::now()) {
                std::thread::sleep(d);
            }
            return;
        }
        while self.now() < t {
            self.step_to(t);
        }
    }

    /// One event of the modelled time: the devices due now are stepped, then the time moves
    /// to the next event (a frame's arrival, a device's step) or `limit`, whichever is first.
    ///
    /// # Panics
    ///
    /// When the bus is waited on while its devices step: from a device's own step, or from a
    /// second thread (one thread drives a modelled bus; its time could not move otherwise).
    fn step_to(&self, limit: Instant) {
        let mut devices = match self.devices.try_lock() {
            Ok(d) => d,
            Err(std::sync::TryLockError::Poisoned(p)) => p.into_inner(),
            Err(std::sync::TryLockError::WouldBlock) => panic!(
                "a modelled CAN bus was waited on while its devices stepped (from a device's \
                 step, or a second thread): one thread drives a modelled bus"
            ),
        };
        let now = self.now();
        for a in devices.iter_mut() {
            let arrived = {
                let g = self.lock();
                g.inboxes[a.node.index].front().is_some_and(|d| d.at <= now)
            };
            if a.next <= now || arrived {
                a.device
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .step(now, &mut a.node);
                while a.next <= now {
                    a.next += a.tick;
                }
            }
        }
        let mut g = self.lock();
        // Each inbox is in order of arrival: the first still to come, past those due.
        let arrival = g
            .inboxes
            .iter()
            .filter_map(|q| q.get(q.partition_point(|d| d.at <= now)).map(|d| d.at))
            .min();
        let next = devices
            .iter()
            .map(|a| a.next)
            .chain(arrival)
            .fold(limit, Instant::min);
        if next > now {
            g.modelled = Some(next);
        }
    }
}

/// One node's connection to a [`MemBus`].
#[derive(Debug, Clone)]
pub struct MemNode {
    bus: MemBus,
    index: usize,
}

impl MemNode {
    /// The bus this node is on.
    pub fn bus(&self) -> &MemBus {
        &self.bus
    }

    /// The next frame that has arrived by the bus's time, with when it arrived (the end of its
    /// time on the wire): a sniffer's timestamp, as a CAN interface stamps what it receives.
    pub fn try_recv_stamped(&mut self) -> Option<(Instant, CanFrame)> {
        let mut g = self.bus.lock();
        let now = g.now();
        let q = &mut g.inboxes[self.index];
        if q.front().is_some_and(|d| d.at <= now) {
            q.pop_front().map(|d| (d.at, d.frame))
        } else {
            None
        }
    }
}

impl CanBus for MemNode {
    fn send(&mut self, frame: &CanFrame, _deadline: Instant) -> Result<(), BusError> {
        // Worked out before the bus is held: every node's send waits on the lock.
        let bits = frame.wire_bits();
        let mut g = self.bus.lock();
        if g.bus_off {
            return Err(BusError::BusOff);
        }
        let now = g.now();
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
            let now = g.now();
            let modelled = g.modelled.is_some();
            match g.inboxes[self.index].front() {
                Some(d) if d.at <= now => {
                    let d = g.inboxes[self.index].pop_front().expect("front");
                    return Ok(d.frame);
                }
                _ if now >= deadline => return Err(BusError::Timeout),
                _ if modelled => {
                    drop(g);
                    self.bus.step_to(deadline);
                    g = self.bus.lock();
                }
                Some(d) => {
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

    fn now(&self) -> Instant {
        self.bus.now()
    }

    fn utime(&self) -> i64 {
        self.bus.utime()
    }

    fn wait_until(&mut self, t: Instant) {
        self.bus.advance_to(t)
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

    /// Answers every frame with its identifier plus one, and counts its steps.
    struct Echo {
        steps: u32,
    }

    impl Device for Echo {
        fn step(&mut self, now: Instant, bus: &mut MemNode) {
            self.steps += 1;
            while let Ok(Some(f)) = bus.try_recv() {
                let reply = CanFrame::standard(f.raw_id() as u16 + 1, f.data()).unwrap();
                bus.send(&reply, now).unwrap();
            }
        }
    }

    #[test]
    fn a_modelled_bus_moves_only_when_waited_on_and_steps_its_devices_on_the_way() {
        let bus = MemBus::modelled(125_000);
        let t0 = bus.now();
        let echo = bus.attach(Echo { steps: 0 }, Duration::from_millis(1));
        let mut host = bus.node();
        // The machine's time does not move it.
        std::thread::sleep(Duration::from_millis(5));
        assert_eq!(bus.now(), t0);
        assert_eq!(host.now(), t0);
        // A request and its echo: each takes its exact time on the wire, and the device
        // answers as the request arrives, not at its next tick.
        let f = CanFrame::standard(0x600, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
        let echoed = CanFrame::standard(0x601, f.data()).unwrap();
        let bit = Duration::from_secs_f64(1.0 / 125_000.0);
        let wire = bit * f.wire_bits() + bit * echoed.wire_bits();
        host.send(&f, t0).unwrap();
        let r = host.recv(t0 + Duration::from_secs(1)).unwrap();
        assert_eq!((r.raw_id(), r.data()), (0x601, f.data()));
        assert_eq!(bus.now() - t0, wire);
        assert_eq!(host.try_recv_stamped(), None);
        // Nothing comes: the wait ends at its deadline, exactly.
        let before = bus.now();
        let ms = Duration::from_millis(1);
        assert_eq!(host.recv(before + ms * 5), Err(BusError::Timeout));
        assert_eq!(bus.now(), before + ms * 5);
        // The device stepped on its ticks (0 to 6 ms) and when the request arrived.
        bus.advance_to(t0 + ms * 10);
        assert_eq!(bus.now(), t0 + ms * 10);
        assert_eq!(echo.lock().unwrap().steps, 10 + 1);
        // The wall clock of the modelled time moves with it.
        let u = bus.utime();
        bus.advance_to(bus.now() + Duration::from_millis(250));
        assert_eq!(bus.utime() - u, 250_000);
        // A stamped receive gives each frame's arrival.
        host.send(&f, bus.now()).unwrap();
        let sent = bus.now();
        bus.advance_to(sent + ms * 5);
        let (at, r) = host.try_recv_stamped().unwrap();
        assert_eq!((r.raw_id(), at - sent), (0x601, wire));
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
