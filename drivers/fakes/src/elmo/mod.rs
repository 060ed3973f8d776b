//! A fake Elmo CANopen drive, driven only through its [`CanBus`] as a real one would be.
//!
//! What it implements, each in its own file:
//! * [`od`]: the object dictionary (CiA 301 communication area with every record's
//!   "highest sub-index", CiA 402 and Elmo objects, access rights, what may be mapped), served
//!   by `stride-canopen`'s pure SDO server; writes have the drive's side effects.
//! * [`nmt`]: NMT states (SDO and PDOs only where CiA 301 serves them, reset communication
//!   restoring the communication area), the heartbeat it produces (0x1017), the heartbeats it
//!   consumes (0x1016) and what it does when one stops: the error behaviour of 0x1029 and the
//!   abort connection option of 0x6007 (a quick stop by default once set up).
//! * [`pdo`]: PDO mapping as CiA 301 rules it (no change to a valid PDO, only mappable
//!   objects, at most 64 bits), TPDOs on SYNC, RPDOs written into the dictionary.
//! * [`interpreter`]: the binary interpreter on PDO2 (`MO`, `PX`, `TS`, `MP[1..6]`, `PV`,
//!   `PT`, `BG`), with Elmo-like error codes.
//! * [`table`]: the motion table (a 64-row PVT table fed through object 0x2001, a PT table of
//!   up to 1024 points fed two at a time through 0x2002, CiA 402 interpolated-position
//!   set-points through 0x60C1), its ring and pointers.
//! * [`motion`]: tabulated motion with cubic interpolation (linear in interpolated position),
//!   profile position, quick stop at 0x6085, a motor that follows with a lag,
//!   following-error faults, and the emergencies a drive sends (queue low, underflow, faults,
//!   and the error reset when a fault clears).
//!
//! Tabulated motion as the SimplIQ manuals describe it: `MP[1]`/`MP[2]` bound the rows in use
//! (a ring when `MP[3]` bit 0 is set), `MP[3]` bit 1 says running out of rows is the expected
//! end (no emergency), `MP[4]` is the PT period in position-controller samples (4 × `TS` µs),
//! `MP[6]` is the write pointer of the fast-reference objects, and `PV=n`/`PT=n` set the read
//! pointer and arm the next `BG`. PT segments are cubic, with each point's slope taken from its
//! neighbours (zero at the first point of a motion and where no next point has arrived).
//!
//! The test harness may also pull "physical" levers ([`Levers`]: inject a fault, go silent)
//! the way one would on a bench.

mod interpreter;
mod motion;
mod nmt;
mod od;
mod pdo;
mod table;
#[cfg(test)]
mod tests;

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use stride_canbus::{BusError, CanBus, CanFrame, Device, MemNode};
use stride_canopen::ds402::State as DriveState;
use stride_canopen::emcy::Emcy;
use stride_canopen::frame::{CobId, Function, NodeId};
use stride_canopen::nmt::State as NmtState;
use stride_canopen::sdo;
use stride_canopen::sync;

use motion::Motor;
use od::Od;
use table::Table;

/// Settings of a fake drive.
#[derive(Debug, Clone)]
pub struct ElmoConfig {
    /// Node id.
    pub node: NodeId,
    /// Time constant of the motor following its command.
    pub lag: Duration,
    /// Initial following error window (0x6065), counts.
    pub following_error_window: u32,
    /// Rows in the PVT table (`QV`/`QT`).
    pub pvt_rows: u16,
    /// Points in the PT table (`QP`).
    pub pt_points: u16,
    /// Current-loop sampling time `TS`, µs (the position loop runs every 4 × TS).
    pub ts_us: u32,
}

impl ElmoConfig {
    /// Defaults for node `node`.
    pub fn new(node: u8) -> ElmoConfig {
        ElmoConfig {
            node: NodeId::new(node).expect("node id 1..=127"),
            lag: Duration::from_millis(3),
            following_error_window: 20_000,
            pvt_rows: 64,
            pt_points: 1024,
            ts_us: 50,
        }
    }
}

/// Levers a test pulls on the "hardware", outside the bus.
#[derive(Debug, Clone, Default)]
pub struct Levers {
    /// Set to make the drive detect an over-current fault.
    pub fault: Arc<AtomicBool>,
    /// Set to make the drive stop answering (a pulled connector).
    pub silent: Arc<AtomicBool>,
    /// The next this many SDO requests and interpreter commands to the drive are lost on
    /// the wire (a busy bus, a slow gateway): the drive never sees them.
    pub lose_requests: Arc<std::sync::atomic::AtomicU32>,
}

/// On a modelled bus ([`stride_canbus::MemBus::attach`]) the drive steps as on its own thread
/// (every millisecond, and as frames come), on the bus's time.
impl Device for FakeElmo {
    fn step(&mut self, now: Instant, bus: &mut MemNode) {
        FakeElmo::step(self, now, bus);
    }
}

/// What a test can read of a fake drive after it ran (the drive's own view, as a bench
/// instrument would show it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Probe {
    /// The CiA 402 state.
    pub state: DriveState,
    /// The NMT state.
    pub nmt: NmtState,
    /// Motor position, counts.
    pub position: f64,
    /// Motor velocity, counts/s.
    pub velocity: f64,
    /// Heartbeat events: a consumed heartbeat that stopped.
    pub heartbeat_events: u32,
}

/// A fake Elmo drive.
pub struct FakeElmo {
    cfg: ElmoConfig,
    levers: Levers,
    od: Od,
    sdo: sdo::Server,
    nmt: NmtState,
    booted: bool,
    last_heartbeat: Option<Instant>,
    /// Consumed heartbeats: when each watched node was last heard (monitoring starts with
    /// its first heartbeat), and whether its silence was already reported.
    heard: BTreeMap<u8, (Instant, bool)>,
    /// When the consumed heartbeats were last watched (a drive's processor is never held up
    /// as this process may be: silence is judged only over time it watched).
    last_watch: Option<Instant>,
    heartbeat_events: u32,
    drive: DriveState,
    prev_cw: u16,
    table: Table,
    motor: Motor,
    sync_count: u32,
    /// Frames to send once the current step is done.
    outbox: Vec<CanFrame>,
}

impl FakeElmo {
    /// A drive that boots when first stepped.
    pub fn new(cfg: ElmoConfig, levers: Levers) -> FakeElmo {
        FakeElmo {
            levers,
            od: Od::new(cfg.node, cfg.following_error_window),
            sdo: sdo::Server::new(),
            nmt: NmtState::BootUp,
            booted: false,
            last_heartbeat: None,
            heard: BTreeMap::new(),
            last_watch: None,
            heartbeat_events: 0,
            drive: DriveState::NotReadyToSwitchOn,
            prev_cw: 0,
            table: Table::new(cfg.pvt_rows, cfg.pt_points),
            motor: Motor::new(cfg.ts_us),
            sync_count: 0,
            outbox: Vec::new(),
            cfg,
        }
    }

    /// The drive as an instrument sees it.
    pub fn probe(&self) -> Probe {
        Probe {
            state: self.drive,
            nmt: self.nmt,
            position: self.motor.actual,
            velocity: self.motor.velocity,
            heartbeat_events: self.heartbeat_events,
        }
    }

    /// True while the motor moves or is about to: a motion or a profile playing, a quick stop
    /// decelerating, or the motor still settling on its command (more than a count away).
    pub fn moving(&self) -> bool {
        let m = &self.motor;
        m.motion.is_some()
            || m.profile.is_some()
            || self.drive == DriveState::QuickStopActive
            || m.on && (m.commanded - m.actual).abs() > 0.5
    }

    /// Runs the drive on its own thread, stepping every millisecond until `stop` is set.
    pub fn spawn(
        mut self,
        mut bus: impl CanBus + Send + 'static,
        stop: Arc<AtomicBool>,
    ) -> JoinHandle<FakeElmo> {
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                let now = bus.now();
                self.step(now, &mut bus);
                // Wait for traffic or the next millisecond.
                match bus.recv(now + Duration::from_millis(1)) {
                    Ok(f) => {
                        self.on_frame(&f, bus.now());
                        self.flush(&mut bus);
                    }
                    Err(BusError::Timeout) => {}
                    Err(_) => std::thread::sleep(Duration::from_millis(1)),
                }
            }
            self
        })
    }

    /// Handles pending frames and advances time to `now`.
    pub fn step(&mut self, now: Instant, bus: &mut impl CanBus) {
        if self.levers.silent.load(Ordering::Relaxed) {
            while bus.try_recv().ok().flatten().is_some() {}
            self.motor.last_step = Some(now);
            self.outbox.clear();
            return;
        }
        if !self.booted {
            self.boot(now);
        }
        while let Ok(Some(f)) = bus.try_recv() {
            self.on_frame(&f, now);
        }
        self.advance(now);
        self.watch_heartbeats(now);
        self.produce_heartbeat(now);
        self.flush(bus);
    }

    fn flush(&mut self, bus: &mut impl CanBus) {
        for f in self.outbox.drain(..) {
            let _ = bus.send(&f, bus.now() + Duration::from_millis(10));
        }
    }

    fn send(&mut self, f: CanFrame) {
        self.outbox.push(f);
    }

    fn emcy(&mut self, e: Emcy) {
        self.od.set_raw(0x1001, 0, e.register as i64);
        self.send(e.encode());
    }

    fn on_frame(&mut self, f: &CanFrame, now: Instant) {
        if f.is_extended() || self.levers.silent.load(Ordering::Relaxed) {
            return;
        }
        let node = self.cfg.node;
        let id = f.raw_id() as u16;
        match CobId::parse(id) {
            Some(CobId {
                function: Function::Nmt,
                ..
            }) => {
                if let Ok((cmd, target)) = stride_canopen::nmt::decode(f) {
                    if target == 0 || target == node.get() {
                        self.on_nmt(cmd);
                    }
                }
                return;
            }
            Some(CobId {
                function: Function::Heartbeat,
                node: Some(from),
            }) => {
                self.on_heartbeat(from.get(), now);
                return;
            }
            _ => {}
        }
        // CiA 301: in Stopped only NMT and error control are served.
        if self.nmt == NmtState::Stopped {
            return;
        }
        if id == 0x080 {
            if sync::decode(f).is_ok() {
                // A drive samples its motor at the SYNC, not at its last control tick.
                self.advance(now);
                self.on_sync();
            }
            return;
        }
        let request = id == CobId::of(Function::SdoRx, node).raw()
            || (self.nmt == NmtState::Operational
                && id == CobId::of(Function::Rpdo(2), node).raw());
        if request
            && self
                .levers
                .lose_requests
                .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |n| n.checked_sub(1))
                .is_ok()
        {
            return;
        }
        if id == CobId::of(Function::SdoRx, node).raw() {
            self.on_sdo(f, now);
            return;
        }
        if self.nmt != NmtState::Operational {
            return;
        }
        if id == CobId::of(Function::Rpdo(2), node).raw() {
            self.on_interpreter(f.data(), now);
            return;
        }
        self.on_rpdo(id, f.data(), now);
    }

    fn on_sdo(&mut self, f: &CanFrame, now: Instant) {
        let mut server = std::mem::take(&mut self.sdo);
        let resp = server.on_frame(f, &mut od::Served { drive: self, now });
        self.sdo = server;
        if let Some(Ok(frame)) = resp.map(|r| r.encode(self.cfg.node)) {
            self.send(frame);
        }
    }
}
