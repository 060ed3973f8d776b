//! A fake Elmo CANopen drive: NMT with heartbeat, an object dictionary behind an SDO server,
//! PDO mapping, the CiA 402 state machine, the binary interpreter on PDO2, tabulated motion
//! (a 64-row PVT table fed through object 0x2001, a PT table of up to 1024 points fed two at a
//! time through 0x2002, both set up with `MP[1..6]`, `PV=n`/`PT=n` and `BG`, played with cubic
//! interpolation), CiA 402 interpolated position, a motor that follows with a lag,
//! following-error faults and emergencies (queue low, underflow, faults).
//!
//! Tabulated motion as the SimplIQ manuals describe it: `MP[1]`/`MP[2]` bound the rows in use
//! (a ring when `MP[3]` bit 0 is set), `MP[3]` bit 1 says running out of rows is the expected
//! end (no emergency), `MP[4]` is the PT period in position-controller samples (4 × `TS` µs),
//! `MP[6]` is the write pointer of the fast-reference objects, and `PV=n`/`PT=n` set the read
//! pointer and arm the next `BG`. PT segments are cubic, with each point's slope taken from its
//! neighbours (zero at the first point of a motion and where no next point has arrived).
//!
//! It only talks through its [`CanBus`]; the test harness may also pull "physical" levers
//! ([`Levers`]: inject a fault, go silent) the way one would on a bench.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use stride_canbus::{BusError, CanBus, CanFrame};
use stride_canopen::ds402::{self, State as DriveState};
use stride_canopen::elmo::{Command as Interp, PvtRow, Reply, Value, PT_OBJECT, PVT_OBJECT};
use stride_canopen::emcy::{ElmoEmcy, Emcy};
use stride_canopen::frame::{CobId, Function, NodeId};
use stride_canopen::nmt::{self, State as NmtState};
use stride_canopen::sdo::{AbortCode, ClientRequest, Initiate, ServerResponse};
use stride_canopen::{heartbeat, pdo, sync};

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
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Access {
    Ro,
    Rw,
    Wo,
}

struct Entry {
    access: Access,
    value: Vec<u8>,
}

struct SegmentedUpload {
    index: u16,
    sub: u8,
    data: Vec<u8>,
    toggle: bool,
}

struct SegmentedDownload {
    index: u16,
    sub: u8,
    data: Vec<u8>,
    toggle: bool,
}

/// A fake Elmo drive.
pub struct FakeElmo {
    cfg: ElmoConfig,
    levers: Levers,
    od: BTreeMap<(u16, u8), Entry>,
    nmt: NmtState,
    drive: DriveState,
    prev_cw: u16,
    upload: Option<SegmentedUpload>,
    download: Option<SegmentedDownload>,
    // Tabulated motion: the table (PVT rows, PT points, IP set-points), MP[1..=6], what the
    // next BG starts and what is playing.
    table: Vec<PvtRow>,
    mp: [i32; 7],
    armed: Option<Table>,
    playing: Table,
    /// Rows counted when the playing motion started (PT: the first point has zero slope).
    motion_start: u64,
    ts_us: u32,
    written: u64,
    executed: u64,
    queue_low_sent: bool,
    motion: Option<Segment>,
    motor_on: bool,
    commanded: f64,
    actual: f64,
    velocity: f64,
    // Timing.
    last_step: Option<Instant>,
    last_heartbeat: Option<Instant>,
    sync_count: u32,
    booted: bool,
    ip_bit: bool,
    /// Profile position: the move under way, and the set-point acknowledge (statusword bit 12).
    profile: Option<Profile>,
    setpoint_ack: bool,
    /// Speed of the command while decelerating in quick stop, counts/s.
    qs_velocity: f64,
}

/// A profile-position move: a trapezoid (or triangle) of velocity from `from` to `to`.
#[derive(Debug, Clone, Copy)]
struct Profile {
    from: f64,
    to: f64,
    /// Cruise velocity, acceleration and deceleration (counts/s, counts/s²), positive.
    v: f64,
    a: f64,
    d: f64,
    elapsed: f64,
}

impl Profile {
    /// Position at the elapsed time, and whether the move is over.
    fn position(&self) -> (f64, bool) {
        let dist = (self.to - self.from).abs();
        let sign = (self.to - self.from).signum();
        // The peak velocity: cruise, or lower when the move is too short to reach it.
        let peak = self
            .v
            .min((2.0 * dist * self.a * self.d / (self.a + self.d)).sqrt());
        if peak <= 0.0 {
            return (self.to, true);
        }
        let (ta, td) = (peak / self.a, peak / self.d);
        let tc =
            (dist - peak * peak / (2.0 * self.a) - peak * peak / (2.0 * self.d)).max(0.0) / peak;
        let t = self.elapsed;
        let s = if t < ta {
            self.a * t * t / 2.0
        } else if t < ta + tc {
            peak * ta / 2.0 + peak * (t - ta)
        } else if t < ta + tc + td {
            let u = ta + tc + td - t;
            dist - self.d * u * u / 2.0
        } else {
            return (self.to, true);
        };
        (self.from + sign * s, false)
    }
}

/// The kinds of tabulated motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Table {
    /// Elmo PVT (0x2001 rows, `PV=n`).
    Pvt,
    /// Elmo PT (0x2002 points, `PT=n`).
    Pt,
    /// CiA 402 interpolated position (0x60C1 set-points, controlword bit 4), linear.
    Ip,
}

/// The segment being played: a cubic from (p0, v0) to (p1, v1), or a line.
#[derive(Debug, Clone, Copy)]
struct Segment {
    p0: f64,
    v0: f64,
    p1: f64,
    v1: f64,
    /// Seconds the segment lasts.
    duration: f64,
    elapsed: f64,
    linear: bool,
}

fn le(v: i64, bytes: usize) -> Vec<u8> {
    v.to_le_bytes()[..bytes].to_vec()
}

impl FakeElmo {
    /// A drive that boots when first stepped.
    pub fn new(cfg: ElmoConfig, levers: Levers) -> FakeElmo {
        let mut d = FakeElmo {
            levers,
            od: BTreeMap::new(),
            nmt: NmtState::BootUp,
            drive: DriveState::NotReadyToSwitchOn,
            prev_cw: 0,
            upload: None,
            download: None,
            table: vec![
                PvtRow {
                    position: 0,
                    velocity: 0,
                    time_ms: 1
                };
                cfg.pvt_rows.max(cfg.pt_points).max(1) as usize
            ],
            mp: [0, 1, cfg.pvt_rows as i32, 0, 1, 0, 1],
            armed: None,
            playing: Table::Pvt,
            motion_start: 0,
            ts_us: cfg.ts_us,
            written: 0,
            executed: 0,
            queue_low_sent: false,
            motion: None,
            motor_on: false,
            commanded: 0.0,
            actual: 0.0,
            velocity: 0.0,
            last_step: None,
            last_heartbeat: None,
            sync_count: 0,
            booted: false,
            ip_bit: false,
            profile: None,
            setpoint_ack: false,
            qs_velocity: 0.0,
            cfg,
        };
        d.reset_od();
        d
    }

    fn reset_od(&mut self) {
        use Access::*;
        let node = self.cfg.node;
        let mut od = BTreeMap::new();
        let mut put = |i: u16, s: u8, a: Access, v: Vec<u8>| {
            od.insert(
                (i, s),
                Entry {
                    access: a,
                    value: v,
                },
            );
        };
        put(0x1000, 0, Ro, le(0x0002_0192, 4));
        put(0x1001, 0, Ro, vec![0]);
        put(0x1008, 0, Ro, b"Elmo Gold Twitter (fake)".to_vec());
        put(0x1017, 0, Rw, le(0, 2));
        put(0x1018, 1, Ro, le(0x9a, 4));
        for n in 1..=4u8 {
            let i = (n - 1) as u16;
            let rx = CobId::of(Function::Rpdo(n), node).raw() as i64;
            let tx = CobId::of(Function::Tpdo(n), node).raw() as i64;
            put(0x1400 + i, 1, Rw, le(rx, 4));
            put(0x1400 + i, 2, Rw, vec![255]);
            put(
                0x1800 + i,
                1,
                Rw,
                le(tx | if n > 2 { 0x8000_0000 } else { 0 }, 4),
            );
            put(0x1800 + i, 2, Rw, vec![if n == 1 { 1 } else { 255 }]);
            put(0x1600 + i, 0, Rw, vec![0]);
            put(0x1a00 + i, 0, Rw, vec![0]);
            for s in 1..=8 {
                put(0x1600 + i, s, Rw, le(0, 4));
                put(0x1a00 + i, s, Rw, le(0, 4));
            }
        }
        // RPDO1 = controlword, TPDO1 = statusword + actual position (Elmo-like defaults).
        put(0x1600, 0, Rw, vec![1]);
        put(0x1600, 1, Rw, le(0x6040_0010, 4));
        put(0x1a00, 0, Rw, vec![2]);
        put(0x1a00, 1, Rw, le(0x6041_0010, 4));
        put(0x1a00, 2, Rw, le(0x6064_0020, 4));
        put(ds402::CONTROLWORD, 0, Rw, le(0, 2));
        put(ds402::STATUSWORD, 0, Ro, le(0, 2));
        put(ds402::MODES_OF_OPERATION, 0, Rw, vec![0]);
        put(ds402::MODES_DISPLAY, 0, Ro, vec![0]);
        put(ds402::POSITION_ACTUAL, 0, Ro, le(0, 4));
        put(ds402::VELOCITY_ACTUAL, 0, Ro, le(0, 4));
        put(ds402::TARGET_POSITION, 0, Rw, le(0, 4));
        put(ds402::FOLLOWING_ERROR, 0, Ro, le(0, 4));
        put(
            ds402::FOLLOWING_ERROR_WINDOW,
            0,
            Rw,
            le(self.cfg.following_error_window as i64, 4),
        );
        put(ds402::QUICK_STOP_DECELERATION, 0, Rw, le(2_000_000, 4));
        put(ds402::PROFILE_VELOCITY, 0, Rw, le(100_000, 4));
        put(ds402::PROFILE_ACCELERATION, 0, Rw, le(1_000_000, 4));
        put(ds402::PROFILE_DECELERATION, 0, Rw, le(1_000_000, 4));
        put(ds402::IP_SUBMODE, 0, Rw, le(0, 2));
        put(ds402::IP_PERIOD, 1, Rw, vec![10]);
        put(ds402::IP_PERIOD, 2, Rw, vec![(-3i8) as u8]);
        put(ds402::IP_DATA, 1, Rw, le(0, 4));
        put(PVT_OBJECT, 0, Wo, le(0, 8));
        put(PT_OBJECT, 0, Wo, le(0, 8));
        put(0x2f11, 0, Ro, le(1, 2));
        put(0x2f12, 0, Ro, le(1, 2));
        self.od = od;
    }

    fn get_u(&self, i: u16, s: u8) -> u64 {
        let v = &self.od[&(i, s)].value;
        let mut b = [0u8; 8];
        b[..v.len().min(8)].copy_from_slice(&v[..v.len().min(8)]);
        u64::from_le_bytes(b)
    }

    fn set_raw(&mut self, i: u16, s: u8, v: i64) {
        if let Some(e) = self.od.get_mut(&(i, s)) {
            let n = e.value.len();
            e.value = le(v, n);
        }
    }

    /// Runs the drive on its own thread, stepping every millisecond until `stop` is set.
    pub fn spawn(
        mut self,
        mut bus: impl CanBus + Send + 'static,
        stop: Arc<AtomicBool>,
    ) -> JoinHandle<FakeElmo> {
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                let now = Instant::now();
                self.step(now, &mut bus);
                // Wait for traffic or the next millisecond.
                match bus.recv(now + Duration::from_millis(1)) {
                    Ok(f) => self.on_frame(&f, Instant::now(), &mut bus),
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
            self.last_step = Some(now);
            return;
        }
        if !self.booted {
            self.booted = true;
            self.nmt = NmtState::BootUp;
            self.send(bus, heartbeat::encode(self.cfg.node, NmtState::BootUp));
            self.nmt = NmtState::PreOperational;
            self.drive = ds402::next_state(DriveState::NotReadyToSwitchOn, 0, 0);
            self.last_heartbeat = Some(now);
        }
        while let Ok(Some(f)) = bus.try_recv() {
            self.on_frame(&f, now, bus);
        }
        self.advance(now, bus);
        let period = self.get_u(0x1017, 0);
        if period > 0
            && self
                .last_heartbeat
                .is_none_or(|t| now >= t + Duration::from_millis(period))
        {
            self.last_heartbeat = Some(now);
            self.send(bus, heartbeat::encode(self.cfg.node, self.nmt));
        }
    }

    fn send(&self, bus: &mut impl CanBus, f: CanFrame) {
        let _ = bus.send(&f, Instant::now() + Duration::from_millis(10));
    }

    fn emcy(&mut self, bus: &mut impl CanBus, e: Emcy) {
        self.set_raw(0x1001, 0, e.register as i64);
        self.send(bus, e.encode());
    }

    fn on_frame(&mut self, f: &CanFrame, now: Instant, bus: &mut impl CanBus) {
        if f.is_extended() || self.levers.silent.load(Ordering::Relaxed) {
            return;
        }
        let node = self.cfg.node;
        let id = f.raw_id() as u16;
        if id == 0 {
            if let Ok((cmd, target)) = nmt::decode(f) {
                if target == 0 || target == node.get() {
                    self.on_nmt(cmd);
                }
            }
            return;
        }
        if id == 0x080 {
            if sync::decode(f).is_ok() {
                self.on_sync(bus);
            }
            return;
        }
        if id == CobId::of(Function::SdoRx, node).raw() {
            if let Ok((_, req)) = ClientRequest::decode(f) {
                if let Some(Ok(frame)) = self.on_sdo(req).map(|r| r.encode(node)) {
                    self.send(bus, frame);
                }
            }
            return;
        }
        if self.nmt != NmtState::Operational {
            return;
        }
        if id == CobId::of(Function::Rpdo(2), node).raw() {
            self.on_interpreter(f.data(), now, bus);
            return;
        }
        for n in [1u8, 3, 4] {
            let i = (n - 1) as u16;
            let cob = self.get_u(0x1400 + i, 1) as u32;
            if cob & 0x8000_0000 == 0 && cob & 0x7ff == id as u32 {
                self.on_rpdo(0x1600 + i, f.data(), bus);
            }
        }
    }

    fn on_nmt(&mut self, cmd: nmt::Command) {
        match cmd {
            nmt::Command::ResetNode => {
                self.reset_od();
                self.booted = false;
                self.motion = None;
                self.mp = [0, 1, self.cfg.pvt_rows as i32, 0, 1, 0, 1];
                self.written = 0;
                self.executed = 0;
                self.armed = None;
                self.ts_us = self.cfg.ts_us;
                self.motor_on = false;
                self.drive = DriveState::NotReadyToSwitchOn;
            }
            nmt::Command::ResetCommunication => self.booted = false,
            c => self.nmt = self.nmt.after(c),
        }
    }

    fn on_sync(&mut self, bus: &mut impl CanBus) {
        if self.nmt != NmtState::Operational {
            return;
        }
        self.sync_count = self.sync_count.wrapping_add(1);
        for n in [1u8, 3, 4] {
            let i = (n - 1) as u16;
            let cob = self.get_u(0x1800 + i, 1) as u32;
            let kind = self.get_u(0x1800 + i, 2) as u32;
            if cob & 0x8000_0000 != 0
                || !(1..=240).contains(&kind)
                || !self.sync_count.is_multiple_of(kind)
            {
                continue;
            }
            let cfg = self.mapping(pdo::Direction::Transmit, n);
            let values: Vec<u64> = cfg
                .entries
                .iter()
                .map(|e| {
                    self.od
                        .get(&(e.index, e.sub))
                        .map_or(0, |_| self.get_u(e.index, e.sub))
                })
                .collect();
            if let Ok(frame) = CanFrame::standard((cob & 0x7ff) as u16, &cfg.pack(&values)) {
                self.send(bus, frame);
            }
        }
    }

    fn mapping(&self, direction: pdo::Direction, n: u8) -> pdo::PdoConfig {
        let base = match direction {
            pdo::Direction::Receive => 0x1600,
            pdo::Direction::Transmit => 0x1a00,
        } + (n - 1) as u16;
        let count = self.get_u(base, 0) as u8;
        pdo::PdoConfig {
            direction,
            number: n,
            transmission: 1,
            entries: (1..=count.min(8))
                .map(|s| pdo::MapEntry::from_u32(self.get_u(base, s) as u32))
                .collect(),
        }
    }

    fn on_rpdo(&mut self, map_index: u16, data: &[u8], bus: &mut impl CanBus) {
        let n = (map_index - 0x1600 + 1) as u8;
        let cfg = self.mapping(pdo::Direction::Receive, n);
        let Some(values) = cfg.unpack(data) else {
            self.emcy(
                bus,
                Emcy {
                    node: self.cfg.node,
                    code: 0x8210,
                    register: 0x11,
                    manufacturer: [0; 5],
                },
            );
            return;
        };
        // A PVT row or two PT points, mapped as one 64-bit object.
        if cfg.entries.len() == 1
            && [PVT_OBJECT, PT_OBJECT].contains(&cfg.entries[0].index)
            && data.len() == 8
        {
            self.write_object(cfg.entries[0].index, 0, data, bus);
            return;
        }
        for (e, v) in cfg.entries.iter().zip(values) {
            self.write_object(
                e.index,
                e.sub,
                &v.to_le_bytes()[..(e.bits as usize).div_ceil(8)],
                bus,
            );
        }
    }

    /// Rows of the table in use: `MP[1]..=MP[2]`.
    fn ring(&self) -> u64 {
        (self.mp[2] as i64 - self.mp[1] as i64 + 1).clamp(1, self.table.len() as i64) as u64
    }

    /// The 1-based table index of the `count`-th row written.
    fn index_of(&self, count: u64) -> u16 {
        (self.mp[1].max(1) as u64 + count % self.ring()) as u16
    }

    fn row_at(&self, count: u64) -> PvtRow {
        self.table[(count % self.ring()) as usize]
    }

    fn push_row(&mut self, row: PvtRow, bus: &mut impl CanBus) {
        if self.written - self.executed >= self.ring() {
            let e = ElmoEmcy::QueueFull {
                index: self.index_of(self.written),
            }
            .to_emcy(self.cfg.node);
            self.emcy(bus, e);
            return;
        }
        let slot = (self.written % self.ring()) as usize;
        self.table[slot] = row;
        self.written += 1;
        self.update_pointers();
        if self.written - self.executed > 2 {
            self.queue_low_sent = false;
        }
    }

    /// Publishes the write and read pointers (0x2F11, 0x2F12; `MP[6]` is the write pointer).
    fn update_pointers(&mut self) {
        let (w, r) = (self.index_of(self.written), self.index_of(self.executed));
        self.set_raw(0x2f11, 0, w as i64);
        self.set_raw(0x2f12, 0, r as i64);
        self.mp[6] = w as i32;
    }

    /// `MP[6]=n`: the next row written lands at table index `n`; the table is emptied.
    fn set_write_pointer(&mut self, n: i32) -> Result<(), u32> {
        if !(self.mp[1]..=self.mp[2]).contains(&n) {
            return Err(ERR_OUT_OF_RANGE);
        }
        let ring = self.ring();
        let base = self.written + ring - self.written % ring;
        self.written = base + (n - self.mp[1]) as u64;
        self.executed = self.written;
        self.update_pointers();
        Ok(())
    }

    /// `PV=n` / `PT=n`: the read pointer moves to table index `n` (rows between it and the
    /// write pointer are what the next `BG` plays).
    fn set_read_pointer(&mut self, n: i32) -> Result<(), u32> {
        if !(self.mp[1]..=self.mp[2]).contains(&n) {
            return Err(ERR_OUT_OF_RANGE);
        }
        let ring = self.ring();
        let ws = self.written % ring;
        let target = (n - self.mp[1]) as u64;
        let mut back = (ws + ring - target) % ring;
        if back == 0 && self.written - self.executed == ring {
            back = ring;
        }
        self.executed = self.written.checked_sub(back).ok_or(ERR_OUT_OF_RANGE)?;
        self.update_pointers();
        Ok(())
    }

    /// Writes an object from the bus (SDO or RPDO); the side effects of the drive happen here.
    fn write_object(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
        bus: &mut impl CanBus,
    ) -> Option<AbortCode> {
        let Some(e) = self.od.get_mut(&(index, sub)) else {
            return Some(if self.od.keys().any(|(i, _)| *i == index) {
                AbortCode::NO_SUBINDEX
            } else {
                AbortCode::NO_OBJECT
            });
        };
        if e.access == Access::Ro {
            return Some(AbortCode::READ_ONLY);
        }
        if index != 0x1008 && data.len() != e.value.len() {
            return Some(AbortCode::LENGTH_MISMATCH);
        }
        e.value = data.to_vec();
        match (index, sub) {
            (ds402::CONTROLWORD, 0) => {
                let cw = u16::from_le_bytes([data[0], data[1]]);
                let before = self.drive;
                self.drive = ds402::next_state(self.drive, self.prev_cw, cw);
                self.prev_cw = cw;
                if self.drive == DriveState::SwitchOnDisabled && before == DriveState::Fault {
                    self.set_raw(0x1001, 0, 0);
                    self.levers.fault.store(false, Ordering::Relaxed);
                }
                if self.drive == DriveState::QuickStopActive
                    && before != DriveState::QuickStopActive
                {
                    // Decelerate from the present speed (0x6085), then hold.
                    self.qs_velocity = self.velocity;
                }
                self.motor_on = matches!(
                    self.drive,
                    DriveState::OperationEnabled | DriveState::QuickStopActive
                );
                if self.drive != DriveState::OperationEnabled {
                    self.motion = None;
                    self.profile = None;
                }
                let mode = self.get_u(ds402::MODES_OF_OPERATION, 0) as i8;
                let enabled = self.drive == DriveState::OperationEnabled;
                let rising = cw & 0x10 != 0 && self.prev_ip_bit_clear();
                // Interpolated position mode: bit 4 ("enable interpolation") starts the buffer.
                if mode == 7 && enabled && rising {
                    self.begin_motion(Table::Ip, Instant::now());
                }
                // Profile position: bit 4 rising hands over a set-point (bit 6: relative),
                // acknowledged in statusword bit 12 until bit 4 falls. This fake takes every
                // set-point at once, as if bit 5 ("change set immediately") were set.
                if mode == 1 && enabled && rising {
                    let target = self.get_u(ds402::TARGET_POSITION, 0) as u32 as i32 as f64;
                    let to = if cw & 0x40 != 0 {
                        self.profile.map_or(self.commanded, |p| p.to) + target
                    } else {
                        target
                    };
                    let rate = |i| (self.get_u(i, 0) as u32).max(1) as f64;
                    self.profile = Some(Profile {
                        from: self.commanded,
                        to,
                        v: rate(ds402::PROFILE_VELOCITY),
                        a: rate(ds402::PROFILE_ACCELERATION),
                        d: rate(ds402::PROFILE_DECELERATION),
                        elapsed: 0.0,
                    });
                    self.setpoint_ack = true;
                }
                if cw & 0x10 == 0 {
                    self.setpoint_ack = false;
                }
                self.ip_bit = cw & 0x10 != 0;
            }
            (ds402::MODES_OF_OPERATION, 0) => {
                self.set_raw(ds402::MODES_DISPLAY, 0, data[0] as i8 as i64)
            }
            (PVT_OBJECT, 0) => {
                let mut b = [0u8; 8];
                b.copy_from_slice(data);
                self.push_row(PvtRow::from_bytes(&b), bus);
            }
            (PT_OBJECT, 0) => {
                for pair in data.chunks_exact(4) {
                    let position = i32::from_le_bytes([pair[0], pair[1], pair[2], pair[3]]);
                    let row = PvtRow {
                        position,
                        velocity: 0,
                        time_ms: 0,
                    };
                    self.push_row(row, bus);
                }
            }
            (ds402::IP_DATA, 1) => {
                // A linear interpolation set-point: one row of the fixed period (0x60C2, ms).
                let position = i32::from_le_bytes([data[0], data[1], data[2], data[3]]);
                let period = self.get_u(ds402::IP_PERIOD, 1).clamp(1, 255) as u8;
                self.push_row(
                    PvtRow {
                        position,
                        velocity: 0,
                        time_ms: period,
                    },
                    bus,
                );
            }
            _ => {}
        }
        self.update_status();
        None
    }

    fn update_status(&mut self) {
        let mode = self.get_u(ds402::MODES_OF_OPERATION, 0) as i8;
        let status = ds402::ModeStatus {
            target_reached: self.motion.is_none()
                && self.profile.is_none()
                && (self.commanded - self.actual).abs() < 1.0,
            internal_limit: false,
            // Profile position: set-point acknowledged; interpolated position: active.
            mode_bit: match mode {
                1 => self.setpoint_ack,
                7 => self.motion.is_some_and(|_| self.playing == Table::Ip),
                _ => false,
            },
            following_error: false,
        };
        let sw = self.drive.statusword_bits() | 0x0200 /* remote */ | status.statusword_bits();
        self.set_raw(ds402::STATUSWORD, 0, sw as i64);
        self.set_raw(ds402::POSITION_ACTUAL, 0, self.actual.round() as i64);
        self.set_raw(ds402::VELOCITY_ACTUAL, 0, self.velocity.round() as i64);
        self.set_raw(
            ds402::FOLLOWING_ERROR,
            0,
            (self.commanded - self.actual).round() as i64,
        );
    }

    /// Ends the segmented transfer in progress with an abort naming its object (index 0, sub 0
    /// when none is in progress).
    fn transfer_abort(&mut self, code: AbortCode) -> ServerResponse {
        let (index, sub) = match (self.upload.take(), self.download.take()) {
            (Some(up), _) => (up.index, up.sub),
            (None, Some(dl)) => (dl.index, dl.sub),
            (None, None) => (0, 0),
        };
        ServerResponse::Abort { index, sub, code }
    }

    /// Serves one SDO request; `None` when nothing is to be answered (a client's abort).
    fn on_sdo(&mut self, req: ClientRequest) -> Option<ServerResponse> {
        // The bus is not needed for SDO side effects except PVT rows; they queue EMCYs later.
        let mut sink = NoBus;
        Some(match req {
            ClientRequest::InitiateUpload { index, sub } => {
                let Some(e) = self.od.get(&(index, sub)) else {
                    return Some(ServerResponse::Abort {
                        index,
                        sub,
                        code: AbortCode::NO_OBJECT,
                    });
                };
                if e.access == Access::Wo {
                    return Some(ServerResponse::Abort {
                        index,
                        sub,
                        code: AbortCode::WRITE_ONLY,
                    });
                }
                let v = e.value.clone();
                if v.len() <= 4 && !v.is_empty() {
                    ServerResponse::UploadInitiated {
                        index,
                        sub,
                        data: Initiate::Expedited(v),
                    }
                } else {
                    let size = v.len() as u32;
                    self.upload = Some(SegmentedUpload {
                        index,
                        sub,
                        data: v,
                        toggle: false,
                    });
                    ServerResponse::UploadInitiated {
                        index,
                        sub,
                        data: Initiate::Segmented(Some(size)),
                    }
                }
            }
            ClientRequest::UploadSegment { toggle } => {
                let Some(up) = self.upload.as_mut() else {
                    return Some(self.transfer_abort(AbortCode::BAD_COMMAND));
                };
                if toggle != up.toggle {
                    return Some(self.transfer_abort(AbortCode::TOGGLE));
                }
                up.toggle = !up.toggle;
                let n = up.data.len().min(7);
                let chunk: Vec<u8> = up.data.drain(..n).collect();
                let last = up.data.is_empty();
                if last {
                    self.upload = None;
                }
                ServerResponse::UploadSegment {
                    toggle,
                    data: chunk,
                    last,
                }
            }
            ClientRequest::InitiateDownload { index, sub, data } => match data {
                Initiate::Expedited(bytes) => {
                    match self.write_object(index, sub, &bytes, &mut sink) {
                        None => ServerResponse::DownloadInitiated { index, sub },
                        Some(code) => ServerResponse::Abort { index, sub, code },
                    }
                }
                Initiate::Segmented(_) => {
                    self.download = Some(SegmentedDownload {
                        index,
                        sub,
                        data: Vec::new(),
                        toggle: false,
                    });
                    ServerResponse::DownloadInitiated { index, sub }
                }
            },
            ClientRequest::DownloadSegment { toggle, data, last } => {
                let Some(dl) = self.download.as_mut() else {
                    return Some(self.transfer_abort(AbortCode::BAD_COMMAND));
                };
                if toggle != dl.toggle {
                    return Some(self.transfer_abort(AbortCode::TOGGLE));
                }
                dl.toggle = !dl.toggle;
                dl.data.extend_from_slice(&data);
                if last {
                    let dl = self.download.take().expect("in progress");
                    if let Some(code) = self.write_object(dl.index, dl.sub, &dl.data, &mut sink) {
                        return Some(ServerResponse::Abort {
                            index: dl.index,
                            sub: dl.sub,
                            code,
                        });
                    }
                }
                ServerResponse::DownloadSegmentAck { toggle }
            }
            // The client gave up: the transfer ends, and CiA 301 has no answer to an abort.
            ClientRequest::Abort { .. } => {
                self.upload = None;
                self.download = None;
                return None;
            }
        })
    }

    fn on_interpreter(&mut self, data: &[u8], now: Instant, bus: &mut impl CanBus) {
        let Ok(cmd) = Interp::decode(data) else {
            return;
        };
        let value = |v: Option<Value>| match v {
            Some(Value::Int(i)) => i,
            Some(Value::Float(f)) => f as i32,
            None => 0,
        };
        let result: Result<Value, u32> = match (&cmd.name, cmd.value) {
            (b"MO", None) => Ok(Value::Int(self.motor_on as i32)),
            (b"MO", Some(v)) => {
                let on = value(Some(v)) == 1;
                let cw = if on { 0x000f } else { 0x0006 };
                let mut sink = NoBus;
                // MO=1 walks the drive to operation enabled, MO=0 disables it.
                for _ in 0..3 {
                    let target = if on {
                        DriveState::OperationEnabled
                    } else {
                        DriveState::ReadyToSwitchOn
                    };
                    if self.drive == target {
                        break;
                    }
                    let c = ds402::step_towards(self.drive, target).map_or(cw, |c| c.controlword());
                    self.write_object(ds402::CONTROLWORD, 0, &c.to_le_bytes(), &mut sink);
                }
                Ok(Value::Int(self.motor_on as i32))
            }
            (b"PX", None) => Ok(Value::Int(self.actual.round() as i32)),
            (b"TS", None) => Ok(Value::Int(self.ts_us as i32)),
            (b"TS", Some(_)) if self.motor_on => Err(ERR_MOTOR_ON),
            (b"TS", Some(v)) => match value(Some(v)) {
                t @ 25..=1000 => {
                    self.ts_us = t as u32;
                    Ok(Value::Int(t))
                }
                _ => Err(ERR_OUT_OF_RANGE),
            },
            (b"MP", _) if !(1..=6).contains(&cmd.index) => Err(ERR_BAD_INDEX),
            (b"MP", None) => Ok(Value::Int(self.mp[cmd.index as usize])),
            (b"MP", Some(_)) if self.motion.is_some() => Err(ERR_MOVING),
            (b"MP", Some(v)) => self.set_mp(cmd.index as usize, value(Some(v))),
            (b"PV", None) | (b"PT", None) => Ok(Value::Int(self.index_of(self.executed) as i32)),
            (b"PV", Some(_)) | (b"PT", Some(_)) if self.motion.is_some() => Err(ERR_MOVING),
            (b"PV", Some(_)) if self.mp[2] > self.cfg.pvt_rows as i32 => Err(ERR_OUT_OF_RANGE),
            (name @ (b"PV" | b"PT"), Some(v)) => {
                let n = value(Some(v));
                self.set_read_pointer(n).map(|()| {
                    self.armed = Some(if name == b"PV" { Table::Pvt } else { Table::Pt });
                    Value::Int(n)
                })
            }
            (b"BG", _) => {
                if self.drive != DriveState::OperationEnabled {
                    Err(ERR_MOTOR_OFF)
                } else if let Some(kind) = self.armed {
                    if self.written - self.executed < 2 {
                        Err(ERR_EMPTY)
                    } else {
                        self.begin_motion(kind, now);
                        Ok(Value::Int(0))
                    }
                } else {
                    Err(ERR_NO_MODE)
                }
            }
            _ => Err(ERR_UNKNOWN),
        };
        let reply = Reply {
            name: cmd.name,
            index: cmd.index,
            result,
        };
        if let Ok(f) = CanFrame::standard(
            CobId::of(Function::Tpdo(2), self.cfg.node).raw(),
            &reply.bytes(),
        ) {
            self.send(bus, f);
        }
    }

    fn prev_ip_bit_clear(&self) -> bool {
        !self.ip_bit
    }

    /// `MP[i]=v`, checked: the bounds must lie in the table, `MP[4]` is 1..=65535 samples.
    fn set_mp(&mut self, i: usize, v: i32) -> Result<Value, u32> {
        let max = self.table.len() as i32;
        let ok = match i {
            1 => (1..=self.mp[2]).contains(&v),
            2 => (self.mp[1]..=max).contains(&v),
            3 => (0..=3).contains(&v),
            4 => (1..=65535).contains(&v),
            5 => true,
            _ => return self.set_write_pointer(v).map(|()| Value::Int(v)),
        };
        if !ok {
            return Err(ERR_OUT_OF_RANGE);
        }
        self.mp[i] = v;
        if i <= 2 {
            // New bounds: the table restarts empty at MP[1].
            self.written = 0;
            self.executed = 0;
            self.update_pointers();
        }
        Ok(Value::Int(v))
    }

    /// The PT period: `MP[4]` position-controller samples of 4 × `TS` µs.
    fn pt_period(&self) -> f64 {
        self.mp[4].max(1) as f64 * 4.0 * self.ts_us as f64 * 1e-6
    }

    /// The segment that starts at the `executed`-th row of the playing table.
    fn segment(&self, elapsed: f64) -> Segment {
        let (from, to) = (self.row_at(self.executed), self.row_at(self.executed + 1));
        let (p0, p1) = (from.position as f64, to.position as f64);
        match self.playing {
            Table::Pvt | Table::Ip => Segment {
                p0,
                v0: from.velocity as f64,
                p1,
                v1: to.velocity as f64,
                duration: from.time_ms.max(1) as f64 / 1000.0,
                elapsed,
                linear: self.playing == Table::Ip,
            },
            Table::Pt => {
                // Slopes from the neighbours: zero at the motion's first point, and where the
                // point after `to` has not arrived.
                let t = self.pt_period();
                let v0 = if self.executed > self.motion_start {
                    (p1 - self.row_at(self.executed - 1).position as f64) / (2.0 * t)
                } else {
                    0.0
                };
                let v1 = if self.written - self.executed >= 3 {
                    (self.row_at(self.executed + 2).position as f64 - p0) / (2.0 * t)
                } else {
                    0.0
                };
                Segment {
                    p0,
                    v0,
                    p1,
                    v1,
                    duration: t,
                    elapsed,
                    linear: false,
                }
            }
        }
    }

    fn begin_motion(&mut self, kind: Table, now: Instant) {
        if self.written - self.executed < 2 {
            return;
        }
        self.playing = kind;
        self.motion_start = self.executed;
        let seg = self.segment(0.0);
        self.commanded = seg.p0;
        self.motion = Some(seg);
        self.last_step = Some(now);
    }

    fn advance(&mut self, now: Instant, bus: &mut impl CanBus) {
        let dt = self
            .last_step
            .map_or(0.0, |t| now.saturating_duration_since(t).as_secs_f64());
        self.last_step = Some(now);
        if self.levers.fault.load(Ordering::Relaxed) && self.drive != DriveState::Fault {
            self.fault(bus, 0x2310); // over-current
        }
        if let Some(mut seg) = self.motion {
            seg.elapsed += dt;
            loop {
                if seg.elapsed < seg.duration {
                    break;
                }
                let elapsed = seg.elapsed - seg.duration;
                self.executed += 1;
                self.update_pointers();
                let pending = self.written - self.executed;
                // Without MP[3] bit 0 the table is not a ring: the motion ends at MP[2].
                let table_end = self.playing != Table::Ip
                    && self.mp[3] & 1 == 0
                    && self.index_of(self.executed) as i32 == self.mp[2];
                if pending < 2 || table_end {
                    // The read pointer reached the write pointer (underflow) or the table's
                    // end: the motion ends at the last point; unexpected ends are reported.
                    self.commanded = seg.p1;
                    self.motion = None;
                    let expected = self.playing != Table::Ip && self.mp[3] & 2 != 0;
                    if !expected {
                        let e = ElmoEmcy::MotionTerminated {
                            write: self.index_of(self.written),
                            reason: 3,
                        }
                        .to_emcy(self.cfg.node);
                        self.emcy(bus, e);
                    }
                    break;
                }
                if pending <= 4 && !self.queue_low_sent {
                    self.queue_low_sent = true;
                    let e = ElmoEmcy::QueueLow {
                        write: self.index_of(self.written),
                        read: self.index_of(self.executed),
                    }
                    .to_emcy(self.cfg.node);
                    self.emcy(bus, e);
                }
                seg = self.segment(elapsed);
            }
            if self.motion.is_some() {
                self.commanded = interpolate(&seg);
                self.motion = Some(seg);
            }
        }
        // Profile position: the command follows the trapezoid.
        if let Some(mut p) = self.profile {
            p.elapsed += dt;
            let (position, done) = p.position();
            self.commanded = position;
            self.profile = (!done).then_some(p);
        }
        // Quick stop: the command decelerates to a stop at 0x6085, then holds.
        if self.drive == DriveState::QuickStopActive && dt > 0.0 {
            let decel = self.get_u(ds402::QUICK_STOP_DECELERATION, 0).max(1) as f64;
            let dv = decel * dt;
            self.qs_velocity = if self.qs_velocity.abs() <= dv {
                0.0
            } else {
                self.qs_velocity - dv * self.qs_velocity.signum()
            };
            self.commanded += self.qs_velocity * dt;
        }
        // The motor follows its command with a first-order lag.
        if self.motor_on && dt > 0.0 {
            let a = 1.0 - (-dt / self.cfg.lag.as_secs_f64()).exp();
            let before = self.actual;
            self.actual += (self.commanded - self.actual) * a;
            self.velocity = (self.actual - before) / dt;
        } else {
            self.velocity = 0.0;
        }
        let window = self.get_u(ds402::FOLLOWING_ERROR_WINDOW, 0) as f64;
        if self.motor_on && (self.commanded - self.actual).abs() > window {
            self.fault(bus, 0x8611); // following error
        }
        self.update_status();
    }

    fn fault(&mut self, bus: &mut impl CanBus, code: u16) {
        self.drive = DriveState::Fault;
        self.motor_on = false;
        self.motion = None;
        self.profile = None;
        self.update_status();
        let e = Emcy {
            node: self.cfg.node,
            code,
            register: 0x81,
            manufacturer: [0; 5],
        };
        self.emcy(bus, e);
    }
}

// Interpreter error codes of this fake (a real drive's `EC` list numbers them its own way).
/// Unknown command.
const ERR_UNKNOWN: u32 = 2;
/// `BG` with no rows to play.
const ERR_EMPTY: u32 = 7;
/// `BG` while the motor is off.
const ERR_MOTOR_OFF: u32 = 21;
/// A value or table index out of range.
const ERR_OUT_OF_RANGE: u32 = 22;
/// `BG` with no tabulated motion armed (`PV=n` or `PT=n` first).
const ERR_NO_MODE: u32 = 23;
/// A motion parameter changed while a motion plays.
const ERR_MOVING: u32 = 24;
/// `TS` changed while the motor is on.
const ERR_MOTOR_ON: u32 = 25;
/// An array index outside the command's range.
const ERR_BAD_INDEX: u32 = 26;

/// The segment's position at its elapsed time: cubic Hermite (slopes in counts/s), or a line
/// in CiA 402 interpolated position mode.
fn interpolate(seg: &Segment) -> f64 {
    let s = (seg.elapsed / seg.duration).clamp(0.0, 1.0);
    let (p0, p1) = (seg.p0, seg.p1);
    if seg.linear {
        return p0 + (p1 - p0) * s;
    }
    let (m0, m1) = (seg.v0 * seg.duration, seg.v1 * seg.duration);
    let s2 = s * s;
    let s3 = s2 * s;
    (2.0 * s3 - 3.0 * s2 + 1.0) * p0
        + (s3 - 2.0 * s2 + s) * m0
        + (-2.0 * s3 + 3.0 * s2) * p1
        + (s3 - s2) * m1
}

/// A bus that drops what is sent (for side effects of SDO writes, whose EMCYs are not needed).
struct NoBus;

impl CanBus for NoBus {
    fn send(&mut self, _: &CanFrame, _: Instant) -> Result<(), BusError> {
        Ok(())
    }
    fn recv(&mut self, _: Instant) -> Result<CanFrame, BusError> {
        Err(BusError::Timeout)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use stride_canbus::MemBus;
    use stride_canopen::sdo::{Download, Step, Upload};

    struct Host {
        bus: stride_canbus::MemNode,
        node: NodeId,
    }

    impl Host {
        fn recv_until(&mut self, mut want: impl FnMut(&CanFrame) -> bool) -> CanFrame {
            let deadline = Instant::now() + Duration::from_secs(2);
            loop {
                let f = self.bus.recv(deadline).expect("frame before the deadline");
                if want(&f) {
                    return f;
                }
            }
        }

        fn sdo_write(&mut self, index: u16, sub: u8, data: Vec<u8>) -> Result<(), AbortCode> {
            let mut dl = Download::new(index, sub, data);
            let mut req = dl.start();
            loop {
                self.bus
                    .send(&req.encode(self.node).unwrap(), Instant::now())
                    .unwrap();
                let sdo_tx = CobId::of(Function::SdoTx, self.node).raw() as u32;
                let f = self.recv_until(|f| f.raw_id() == sdo_tx);
                let (_, resp) = ServerResponse::decode(&f).unwrap();
                match dl.on_response(&resp) {
                    Ok(Step::Send(r)) => req = r,
                    Ok(Step::Done(_)) => return Ok(()),
                    Err(stride_canopen::sdo::SdoError::Aborted { code, .. }) => return Err(code),
                    Err(e) => panic!("{e}"),
                }
            }
        }

        /// Maps RPDO3 to the PVT object, streams a ramp of `rows` + 1 rows (`step` counts
        /// apart, 10 ms each, at `velocity` counts/s) and starts it with `BG`.
        fn stream_ramp(&mut self, rows: i32, step: i32, velocity: i32) {
            let node = self.node;
            let cfg = pdo::PdoConfig {
                direction: pdo::Direction::Receive,
                number: 3,
                transmission: 255,
                entries: vec![pdo::MapEntry {
                    index: 0x2001,
                    sub: 0,
                    bits: 64,
                }],
            };
            for (i, s, v) in cfg.sdo_writes(node) {
                self.sdo_write(i, s, v).unwrap();
            }
            for k in 0..=rows {
                let row = PvtRow {
                    position: step * k,
                    velocity,
                    time_ms: 10,
                };
                let f = CanFrame::standard(cfg.cob_id(node), &row.bytes().unwrap()).unwrap();
                self.bus.send(&f, Instant::now()).unwrap();
            }
            assert_eq!(
                self.interp(Interp::set(b"PV", 0, Value::Int(1))),
                Ok(Value::Int(1))
            );
            let bg = Interp::set(b"BG", 0, Value::Int(0)).encode(node).unwrap();
            self.bus.send(&bg, Instant::now()).unwrap();
        }

        /// One interpreter exchange over PDO2.
        fn interp(&mut self, cmd: Interp) -> Result<Value, u32> {
            self.bus
                .send(&cmd.encode(self.node).unwrap(), Instant::now())
                .unwrap();
            let tpdo2 = CobId::of(Function::Tpdo(2), self.node).raw() as u32;
            let f = self.recv_until(|f| f.raw_id() == tpdo2);
            let reply = Reply::decode(f.data()).unwrap();
            assert_eq!((reply.name, reply.index), (cmd.name, cmd.index));
            reply.result
        }

        /// NMT start, then the controlword walk to operation enabled.
        fn enable(&mut self) {
            self.bus
                .send(&nmt::encode(nmt::Command::Start, 0), Instant::now())
                .unwrap();
            for cw in [0x06u16, 0x07, 0x0f] {
                self.sdo_write(0x6040, 0, cw.to_le_bytes().to_vec())
                    .unwrap();
            }
        }

        fn position(&mut self) -> i32 {
            let p = self.sdo_read(0x6064, 0).unwrap();
            i32::from_le_bytes([p[0], p[1], p[2], p[3]])
        }

        fn sdo_read(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode> {
            let mut up = Upload::new(index, sub, 256);
            let mut req = up.start();
            loop {
                self.bus
                    .send(&req.encode(self.node).unwrap(), Instant::now())
                    .unwrap();
                let sdo_tx = CobId::of(Function::SdoTx, self.node).raw() as u32;
                let f = self.recv_until(|f| f.raw_id() == sdo_tx);
                let (_, resp) = ServerResponse::decode(&f).unwrap();
                match up.on_response(&resp) {
                    Ok(Step::Send(r)) => req = r,
                    Ok(Step::Done(d)) => return Ok(d),
                    Err(stride_canopen::sdo::SdoError::Aborted { code, .. }) => return Err(code),
                    Err(e) => panic!("{e}"),
                }
            }
        }
    }

    fn start() -> (Host, Arc<AtomicBool>, Levers, JoinHandle<FakeElmo>) {
        let bus = MemBus::new(1_000_000);
        let host_node = bus.node();
        let levers = Levers::default();
        let stop = Arc::new(AtomicBool::new(false));
        let drive = FakeElmo::new(ElmoConfig::new(3), levers.clone());
        let h = drive.spawn(bus.node(), stop.clone());
        let mut host = Host {
            bus: host_node,
            node: NodeId::new(3).unwrap(),
        };
        // Boot-up message first.
        let f = host.recv_until(|f| f.raw_id() == 0x703);
        assert_eq!(f.data(), [0x00]);
        (host, stop, levers, h)
    }

    #[test]
    fn sdo_server_reads_writes_and_aborts() {
        let (mut host, stop, _, h) = start();
        assert_eq!(host.sdo_read(0x1000, 0).unwrap(), [0x92, 0x01, 0x02, 0x00]);
        assert_eq!(
            host.sdo_read(0x1008, 0).unwrap(),
            b"Elmo Gold Twitter (fake)"
        );
        assert_eq!(host.sdo_read(0x2222, 0), Err(AbortCode::NO_OBJECT));
        assert_eq!(
            host.sdo_write(0x6041, 0, vec![0, 0]),
            Err(AbortCode::READ_ONLY)
        );
        assert_eq!(
            host.sdo_write(0x6040, 0, vec![6]),
            Err(AbortCode::LENGTH_MISMATCH)
        );
        host.sdo_write(0x1017, 0, 100u16.to_le_bytes().to_vec())
            .unwrap();
        let hb = host.recv_until(|f| f.raw_id() == 0x703);
        assert_eq!(hb.data(), [0x7f]); // pre-operational
        stop.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }

    #[test]
    fn ds402_enable_pvt_motion_and_underflow() {
        let (mut host, stop, _, h) = start();
        // Operational, then shutdown / switch on / enable through the controlword.
        host.enable();
        let sw = host.sdo_read(0x6041, 0).unwrap();
        assert_eq!(
            DriveState::from_statusword(u16::from_le_bytes([sw[0], sw[1]])),
            DriveState::OperationEnabled
        );
        // Map RPDO3 to the PVT object, then stream 10 rows of a ramp to 1000 counts.
        host.stream_ramp(10, 100, 10_000);
        let r = host.recv_until(|f| f.raw_id() == 0x283);
        assert_eq!(Reply::decode(r.data()).unwrap().result, Ok(Value::Int(0)));
        // The queue runs low, then dry: both are announced by EMCY.
        let low = host.recv_until(|f| f.raw_id() == 0x083);
        let e = ElmoEmcy::from_emcy(&Emcy::decode(&low).unwrap()).unwrap();
        assert!(matches!(e, ElmoEmcy::QueueLow { .. }), "{e}");
        let end = host.recv_until(|f| f.raw_id() == 0x083);
        let e = ElmoEmcy::from_emcy(&Emcy::decode(&end).unwrap()).unwrap();
        assert!(
            matches!(e, ElmoEmcy::MotionTerminated { reason: 3, .. }),
            "{e}"
        );
        std::thread::sleep(Duration::from_millis(50));
        let p = host.sdo_read(0x6064, 0).unwrap();
        let pos = i32::from_le_bytes([p[0], p[1], p[2], p[3]]);
        assert!((pos - 1000).abs() <= 2, "position {pos}");
        stop.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }

    #[test]
    fn a_fault_is_reported_and_reset() {
        let (mut host, stop, levers, h) = start();
        host.enable();
        levers.fault.store(true, Ordering::Relaxed);
        let f = host.recv_until(|f| f.raw_id() == 0x083);
        let e = Emcy::decode(&f).unwrap();
        assert_eq!((e.code, e.describe().as_str()), (0x2310, "current"));
        let sw = host.sdo_read(0x6041, 0).unwrap();
        assert_eq!(
            DriveState::from_statusword(u16::from_le_bytes([sw[0], sw[1]])),
            DriveState::Fault
        );
        host.sdo_write(0x6040, 0, 0x80u16.to_le_bytes().to_vec())
            .unwrap();
        let sw = host.sdo_read(0x6041, 0).unwrap();
        assert_eq!(
            DriveState::from_statusword(u16::from_le_bytes([sw[0], sw[1]])),
            DriveState::SwitchOnDisabled
        );
        // A silent drive answers nothing.
        levers.silent.store(true, Ordering::Relaxed);
        let req = ClientRequest::InitiateUpload {
            index: 0x1000,
            sub: 0,
        }
        .encode(host.node)
        .unwrap();
        host.bus.send(&req, Instant::now()).unwrap();
        assert_eq!(
            host.bus.recv(Instant::now() + Duration::from_millis(100)),
            Err(BusError::Timeout)
        );
        stop.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }

    #[test]
    fn pt_table_plays_a_point_every_mp4_samples() {
        let (mut host, stop, _, h) = start();
        host.enable();
        // RPDO4 carries PT data: two points per frame.
        let cfg = pdo::PdoConfig {
            direction: pdo::Direction::Receive,
            number: 4,
            transmission: 255,
            entries: vec![pdo::MapEntry {
                index: PT_OBJECT,
                sub: 0,
                bits: 64,
            }],
        };
        for (i, s, v) in cfg.sdo_writes(host.node) {
            host.sdo_write(i, s, v).unwrap();
        }
        // TS = 50 µs, so the position loop runs every 200 µs and MP[4] = 50 is 10 ms a point.
        assert_eq!(host.interp(Interp::get(b"TS", 0)), Ok(Value::Int(50)));
        for (i, v) in [(1, 1), (2, 256), (3, 3), (4, 50), (6, 1)] {
            assert_eq!(
                host.interp(Interp::set(b"MP", i, Value::Int(v))),
                Ok(Value::Int(v))
            );
        }
        // A ramp to 2000 counts in 20 segments, then the last point again (the end at rest).
        let points: Vec<i32> = (0..=20).map(|k| k * 100).chain([2000]).collect();
        for pair in points.chunks(2) {
            let f = CanFrame::standard(
                cfg.cob_id(host.node),
                &stride_canopen::elmo::pt_bytes(pair[0], pair[1]),
            )
            .unwrap();
            host.bus.send(&f, Instant::now()).unwrap();
        }
        assert_eq!(
            host.interp(Interp::set(b"PT", 0, Value::Int(1))),
            Ok(Value::Int(1))
        );
        let t0 = Instant::now();
        assert_eq!(
            host.interp(Interp::set(b"BG", 0, Value::Int(0))),
            Ok(Value::Int(0))
        );
        let mut mid = None;
        while host.position() < 1995 {
            assert!(
                t0.elapsed() < Duration::from_secs(3),
                "the PT motion stalled"
            );
            if mid.is_none() && t0.elapsed() >= Duration::from_millis(60) {
                mid = Some(host.position());
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        // 20 segments of 10 ms cannot end sooner than 200 ms; it passed through the middle.
        assert!(
            t0.elapsed() >= Duration::from_millis(195),
            "{:?}",
            t0.elapsed()
        );
        assert!(mid.is_some_and(|p| p > 0 && p < 2000), "{mid:?}");
        // MP[3] bit 1: running out of points is the expected end, so no emergency came.
        assert!(
            host.bus
                .try_recv()
                .unwrap()
                .is_none_or(|f| f.raw_id() != 0x083),
            "unexpected emergency"
        );
        stop.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }

    #[test]
    fn interpreter_refuses_what_a_drive_refuses() {
        let (mut host, stop, _, h) = start();
        host.bus
            .send(&nmt::encode(nmt::Command::Start, 0), Instant::now())
            .unwrap();
        let bg = Interp::set(b"BG", 0, Value::Int(0));
        assert_eq!(host.interp(bg), Err(ERR_MOTOR_OFF));
        for cw in [0x06u16, 0x07, 0x0f] {
            host.sdo_write(0x6040, 0, cw.to_le_bytes().to_vec())
                .unwrap();
        }
        assert_eq!(host.interp(bg), Err(ERR_NO_MODE));
        assert_eq!(
            host.interp(Interp::set(b"PV", 0, Value::Int(1))),
            Ok(Value::Int(1))
        );
        assert_eq!(host.interp(bg), Err(ERR_EMPTY));
        // PVT rows live in 64 rows; PV beyond the bounds, MP[7], TS with the motor on: refused.
        assert_eq!(
            host.interp(Interp::set(b"PV", 0, Value::Int(65))),
            Err(ERR_OUT_OF_RANGE)
        );
        assert_eq!(host.interp(Interp::get(b"MP", 7)), Err(ERR_BAD_INDEX));
        assert_eq!(
            host.interp(Interp::set(b"TS", 0, Value::Int(100))),
            Err(ERR_MOTOR_ON)
        );
        assert_eq!(host.interp(Interp::get(b"XQ", 0)), Err(ERR_UNKNOWN));
        stop.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }

    #[test]
    fn sdo_aborts_name_the_transfer_and_client_aborts_get_no_answer() {
        let (mut host, stop, _, h) = start();
        let sdo_tx = CobId::of(Function::SdoTx, host.node).raw() as u32;
        let send = |host: &mut Host, req: ClientRequest| {
            host.bus
                .send(&req.encode(host.node).unwrap(), Instant::now())
                .unwrap();
        };
        let start_upload = |host: &mut Host| {
            send(
                host,
                ClientRequest::InitiateUpload {
                    index: 0x1008,
                    sub: 0,
                },
            );
            host.recv_until(|f| f.raw_id() == sdo_tx);
        };
        // A segmented upload of 0x1008, then a segment request with the wrong toggle.
        start_upload(&mut host);
        send(&mut host, ClientRequest::UploadSegment { toggle: true });
        let f = host.recv_until(|f| f.raw_id() == sdo_tx);
        assert_eq!(
            ServerResponse::decode(&f).unwrap().1,
            ServerResponse::Abort {
                index: 0x1008,
                sub: 0,
                code: AbortCode::TOGGLE
            }
        );
        // A client's abort ends a transfer without an answer.
        start_upload(&mut host);
        send(
            &mut host,
            ClientRequest::Abort {
                index: 0x1008,
                sub: 0,
                code: AbortCode::GENERAL,
            },
        );
        let deadline = Instant::now() + Duration::from_millis(100);
        while let Ok(f) = host.bus.recv(deadline) {
            assert_ne!(f.raw_id(), sdo_tx, "answered an abort");
        }
        // The next segment request finds no transfer.
        send(&mut host, ClientRequest::UploadSegment { toggle: false });
        let f = host.recv_until(|f| f.raw_id() == sdo_tx);
        assert!(matches!(
            ServerResponse::decode(&f).unwrap().1,
            ServerResponse::Abort {
                code: AbortCode::BAD_COMMAND,
                ..
            }
        ));
        stop.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }

    #[test]
    fn profile_position_handshake_and_trapezoid() {
        let (mut host, stop, _, h) = start();
        host.enable();
        let status = |host: &mut Host| {
            let sw = host.sdo_read(0x6041, 0).unwrap();
            ds402::ModeStatus::from_statusword(u16::from_le_bytes([sw[0], sw[1]]))
        };
        // 20 000 counts at 100 000 counts/s, accelerating and braking at 1 000 000 counts/s²:
        // 0.1 s cruising plus 0.1 s of ramps, 0.3 s in all.
        let mv = ds402::ProfileMove {
            target: 20_000,
            velocity: 100_000,
            acceleration: 1_000_000,
            deceleration: 1_000_000,
            relative: false,
            immediately: true,
        };
        for (i, s, v) in mv.writes() {
            host.sdo_write(i, s, v).unwrap();
        }
        let t0 = Instant::now();
        host.sdo_write(0x6040, 0, mv.controlword(true).to_le_bytes().to_vec())
            .unwrap();
        let st = status(&mut host);
        assert!(st.mode_bit && !st.target_reached, "{st:?}");
        host.sdo_write(0x6040, 0, mv.controlword(false).to_le_bytes().to_vec())
            .unwrap();
        assert!(!status(&mut host).mode_bit, "acknowledge stays up");
        while !status(&mut host).target_reached {
            assert!(t0.elapsed() < Duration::from_secs(3), "never reached");
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(
            t0.elapsed() >= Duration::from_millis(290),
            "{:?}",
            t0.elapsed()
        );
        assert!((host.position() - 20_000).abs() <= 1);
        // A relative set-point goes on from there.
        let back = ds402::ProfileMove {
            target: -5_000,
            relative: true,
            ..mv
        };
        for (i, s, v) in back.writes() {
            host.sdo_write(i, s, v).unwrap();
        }
        host.sdo_write(0x6040, 0, back.controlword(true).to_le_bytes().to_vec())
            .unwrap();
        host.sdo_write(0x6040, 0, back.controlword(false).to_le_bytes().to_vec())
            .unwrap();
        while !status(&mut host).target_reached {
            assert!(t0.elapsed() < Duration::from_secs(5), "never reached");
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!((host.position() - 15_000).abs() <= 1);
        stop.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }

    #[test]
    fn quick_stop_decelerates_then_holds() {
        let (mut host, stop, _, h) = start();
        host.enable();
        // A slow deceleration makes the stopping distance visible: 100 000 counts/s².
        host.sdo_write(0x6085, 0, 100_000u32.to_le_bytes().to_vec())
            .unwrap();
        // A steady 20 000 counts/s ramp for 0.5 s.
        host.stream_ramp(50, 200, 20_000);
        std::thread::sleep(Duration::from_millis(150));
        let pos = |host: &mut Host| {
            let p = host.sdo_read(0x6064, 0).unwrap();
            i32::from_le_bytes([p[0], p[1], p[2], p[3]])
        };
        host.sdo_write(0x6040, 0, 0x02u16.to_le_bytes().to_vec())
            .unwrap();
        let at_stop = pos(&mut host);
        std::thread::sleep(Duration::from_millis(400));
        let held = pos(&mut host);
        std::thread::sleep(Duration::from_millis(100));
        // v²/2a = 20 000² / 200 000 = 2000 counts of braking distance, then it holds.
        assert!(held - at_stop > 1000, "stopped dead: {at_stop} -> {held}");
        assert!(held < 200 * 50, "did not stop: {held}");
        assert!((pos(&mut host) - held).abs() <= 2, "did not hold");
        stop.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }
}
