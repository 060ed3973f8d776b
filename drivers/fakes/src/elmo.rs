//! A fake Elmo CANopen drive: NMT with heartbeat, an object dictionary behind an SDO server,
//! PDO mapping, the CiA 402 state machine, the binary interpreter on PDO2, a 64-row PVT table
//! fed through object 0x2001 and played with cubic interpolation, a motor that follows with a
//! lag, following-error faults and emergencies (queue low, underflow, faults).
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
use stride_canopen::elmo::{Command as Interp, PvtRow, Reply, Value};
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
    /// Rows in the PVT table.
    pub pvt_rows: u16,
}

impl ElmoConfig {
    /// Defaults for node `node`.
    pub fn new(node: u8) -> ElmoConfig {
        ElmoConfig {
            node: NodeId::new(node).expect("node id 1..=127"),
            lag: Duration::from_millis(3),
            following_error_window: 20_000,
            pvt_rows: 64,
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
    // PVT table and motion.
    table: Vec<PvtRow>,
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
    /// Speed of the command while decelerating in quick stop, counts/s.
    qs_velocity: f64,
}

#[derive(Debug, Clone, Copy)]
struct Segment {
    from: PvtRow,
    to: PvtRow,
    elapsed: f64,
    /// DS402 linear interpolation (mode 7, sub-mode 0) instead of PVT's cubic.
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
                cfg.pvt_rows as usize
            ],
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
        put(0x6065, 0, Rw, le(self.cfg.following_error_window as i64, 4));
        // Quick stop deceleration, counts/s².
        put(0x6085, 0, Rw, le(2_000_000, 4));
        put(ds402::IP_SUBMODE, 0, Rw, le(0, 2));
        put(ds402::IP_PERIOD, 1, Rw, vec![10]);
        put(ds402::IP_PERIOD, 2, Rw, vec![(-3i8) as u8]);
        put(ds402::IP_DATA, 1, Rw, le(0, 4));
        put(stride_canopen::elmo::PVT_OBJECT, 0, Wo, le(0, 8));
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
                let resp = self.on_sdo(req);
                if let Ok(frame) = resp.encode(node) {
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
        // A PVT row mapped as one 64-bit object.
        if cfg.entries.len() == 1
            && cfg.entries[0].index == stride_canopen::elmo::PVT_OBJECT
            && data.len() == 8
        {
            let mut b = [0u8; 8];
            b.copy_from_slice(data);
            self.push_row(PvtRow::from_bytes(&b), bus);
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

    fn push_row(&mut self, row: PvtRow, bus: &mut impl CanBus) {
        let rows = self.cfg.pvt_rows as u64;
        if self.written - self.executed >= rows {
            let e = ElmoEmcy::QueueFull {
                index: (self.written % rows) as u16 + 1,
            }
            .to_emcy(self.cfg.node);
            self.emcy(bus, e);
            return;
        }
        self.table[(self.written % rows) as usize] = row;
        self.written += 1;
        self.set_raw(0x2f11, 0, (self.written % rows) as i64 + 1);
        if self.written - self.executed > 2 {
            self.queue_low_sent = false;
        }
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
                }
                // Interpolated position mode: bit 4 ("enable interpolation") starts the buffer.
                let ip_mode = self.get_u(ds402::MODES_OF_OPERATION, 0) as i8 == 7;
                let enabled = self.drive == DriveState::OperationEnabled;
                if ip_mode && enabled && cw & 0x10 != 0 && self.prev_ip_bit_clear() {
                    self.begin_motion(Instant::now());
                }
                self.ip_bit = cw & 0x10 != 0;
            }
            (ds402::MODES_OF_OPERATION, 0) => {
                self.set_raw(ds402::MODES_DISPLAY, 0, data[0] as i8 as i64)
            }
            (stride_canopen::elmo::PVT_OBJECT, 0) => {
                let mut b = [0u8; 8];
                b.copy_from_slice(data);
                self.push_row(PvtRow::from_bytes(&b), bus);
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
        let mut sw = self.drive.statusword_bits() | 0x0200; // remote
        if self.motion.is_none() && (self.commanded - self.actual).abs() < 1.0 {
            sw |= 0x0400; // target reached
        }
        self.set_raw(ds402::STATUSWORD, 0, sw as i64);
        self.set_raw(ds402::POSITION_ACTUAL, 0, self.actual.round() as i64);
        self.set_raw(ds402::VELOCITY_ACTUAL, 0, self.velocity.round() as i64);
        self.set_raw(
            ds402::FOLLOWING_ERROR,
            0,
            (self.commanded - self.actual).round() as i64,
        );
    }

    fn on_sdo(&mut self, req: ClientRequest) -> ServerResponse {
        // The bus is not needed for SDO side effects except PVT rows; they queue EMCYs later.
        let mut sink = NoBus;
        match req {
            ClientRequest::InitiateUpload { index, sub } => {
                let Some(e) = self.od.get(&(index, sub)) else {
                    return ServerResponse::Abort {
                        index,
                        sub,
                        code: AbortCode::NO_OBJECT,
                    };
                };
                if e.access == Access::Wo {
                    return ServerResponse::Abort {
                        index,
                        sub,
                        code: AbortCode::WRITE_ONLY,
                    };
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
                    return transfer_abort(AbortCode::BAD_COMMAND);
                };
                if toggle != up.toggle {
                    self.upload = None;
                    return transfer_abort(AbortCode::TOGGLE);
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
                    return transfer_abort(AbortCode::BAD_COMMAND);
                };
                if toggle != dl.toggle {
                    self.download = None;
                    return transfer_abort(AbortCode::TOGGLE);
                }
                dl.toggle = !dl.toggle;
                dl.data.extend_from_slice(&data);
                if last {
                    let dl = self.download.take().expect("in progress");
                    if let Some(code) = self.write_object(dl.index, dl.sub, &dl.data, &mut sink) {
                        return ServerResponse::Abort {
                            index: dl.index,
                            sub: dl.sub,
                            code,
                        };
                    }
                }
                ServerResponse::DownloadSegmentAck { toggle }
            }
            ClientRequest::Abort { .. } => {
                self.upload = None;
                self.download = None;
                transfer_abort(AbortCode::GENERAL)
            }
        }
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
            (b"MP", _) | (b"PV", _) => Ok(Value::Int(value(cmd.value))),
            (b"BG", _) => {
                if self.drive != DriveState::OperationEnabled {
                    Err(21) // "motor must be on"
                } else if self.written == self.executed {
                    Err(7)
                } else {
                    self.begin_motion(now);
                    Ok(Value::Int(0))
                }
            }
            _ => Err(2), // unknown command
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

    fn begin_motion(&mut self, now: Instant) {
        let rows = self.cfg.pvt_rows as u64;
        if self.written - self.executed < 2 {
            return;
        }
        let from = self.table[(self.executed % rows) as usize];
        let to = self.table[((self.executed + 1) % rows) as usize];
        self.commanded = from.position as f64;
        let linear = self.get_u(ds402::MODES_OF_OPERATION, 0) as i8 == 7
            && self.get_u(ds402::IP_SUBMODE, 0) as i16 == 0;
        self.motion = Some(Segment {
            from,
            to,
            elapsed: 0.0,
            linear,
        });
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
            let rows = self.cfg.pvt_rows as u64;
            loop {
                let t = seg.from.time_ms as f64 / 1000.0;
                if seg.elapsed < t {
                    break;
                }
                seg.elapsed -= t;
                self.executed += 1;
                self.set_raw(0x2f12, 0, (self.executed % rows) as i64 + 1);
                let pending = self.written - self.executed;
                if pending < 2 {
                    // Underflow: the read pointer reached the write pointer.
                    self.commanded = seg.to.position as f64;
                    self.motion = None;
                    let e = ElmoEmcy::MotionTerminated {
                        write: (self.written % rows) as u16 + 1,
                        reason: 3,
                    }
                    .to_emcy(self.cfg.node);
                    self.emcy(bus, e);
                    break;
                }
                if pending <= 4 && !self.queue_low_sent {
                    self.queue_low_sent = true;
                    let e = ElmoEmcy::QueueLow {
                        write: (self.written % rows) as u16 + 1,
                        read: (self.executed % rows) as u16 + 1,
                    }
                    .to_emcy(self.cfg.node);
                    self.emcy(bus, e);
                }
                seg.from = seg.to;
                seg.to = self.table[((self.executed + 1) % rows) as usize];
            }
            if self.motion.is_some() {
                self.commanded = hermite(&seg);
                self.motion = Some(seg);
            }
        }
        // Quick stop: the command decelerates to a stop at 0x6085, then holds.
        if self.drive == DriveState::QuickStopActive && dt > 0.0 {
            let decel = self.get_u(0x6085, 0).max(1) as f64;
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
        let window = self.get_u(0x6065, 0) as f64;
        if self.motor_on && (self.commanded - self.actual).abs() > window {
            self.fault(bus, 0x8611); // following error
        }
        self.update_status();
    }

    fn fault(&mut self, bus: &mut impl CanBus, code: u16) {
        self.drive = DriveState::Fault;
        self.motor_on = false;
        self.motion = None;
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

/// An abort of the segmented transfer in progress (or of none), as this fake reports it.
fn transfer_abort(code: AbortCode) -> ServerResponse {
    ServerResponse::Abort {
        index: 0,
        sub: 0,
        code,
    }
}

/// Cubic Hermite interpolation between two PVT rows (velocities in counts/s), or linear
/// interpolation in DS402 interpolated position mode.
fn hermite(seg: &Segment) -> f64 {
    let t_total = seg.from.time_ms as f64 / 1000.0;
    let s = (seg.elapsed / t_total).clamp(0.0, 1.0);
    let (p0, p1) = (seg.from.position as f64, seg.to.position as f64);
    if seg.linear {
        return p0 + (p1 - p0) * s;
    }
    let (m0, m1) = (
        seg.from.velocity as f64 * t_total,
        seg.to.velocity as f64 * t_total,
    );
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
            let bg = Interp::set(b"BG", 0, Value::Int(0)).encode(node).unwrap();
            self.bus.send(&bg, Instant::now()).unwrap();
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
        host.bus
            .send(&nmt::encode(nmt::Command::Start, 3), Instant::now())
            .unwrap();
        for cw in [0x06u16, 0x07, 0x0f] {
            host.sdo_write(0x6040, 0, cw.to_le_bytes().to_vec())
                .unwrap();
        }
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
        host.bus
            .send(&nmt::encode(nmt::Command::Start, 0), Instant::now())
            .unwrap();
        for cw in [0x06u16, 0x0f] {
            host.sdo_write(0x6040, 0, cw.to_le_bytes().to_vec())
                .unwrap();
        }
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
    fn quick_stop_decelerates_then_holds() {
        let (mut host, stop, _, h) = start();
        host.bus
            .send(&nmt::encode(nmt::Command::Start, 3), Instant::now())
            .unwrap();
        for cw in [0x06u16, 0x0f] {
            host.sdo_write(0x6040, 0, cw.to_le_bytes().to_vec())
                .unwrap();
        }
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
