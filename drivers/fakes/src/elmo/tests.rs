use super::interpreter::{
    ERR_BAD_INDEX, ERR_EMPTY, ERR_MOTOR_OFF, ERR_MOTOR_ON, ERR_NO_MODE, ERR_UNKNOWN,
};
use super::table::ERR_OUT_OF_RANGE;
use super::*;
use stride_canbus::{Attached, MemBus};
use stride_canopen::ds402;
use stride_canopen::elmo::{Command as Interp, PvtRow, Reply, Value, PT_OBJECT};
use stride_canopen::emcy::ElmoEmcy;
use stride_canopen::heartbeat::ConsumerEntry;
use stride_canopen::nmt;
use stride_canopen::pdo;
use stride_canopen::sdo::{AbortCode, ClientRequest, SdoError, ServerResponse};
use stride_canopen_host::{exchange, ignore, sdo_read, sdo_write, HostError};

struct Host {
    bus: stride_canbus::MemNode,
    node: NodeId,
}

const T: Duration = Duration::from_secs(2);

fn code(e: HostError) -> AbortCode {
    match e {
        HostError::Sdo(SdoError::Aborted { code, .. }) => code,
        e => panic!("not an abort: {e}"),
    }
}

impl Host {
    /// The bus's (modelled) time.
    fn now(&self) -> Instant {
        self.bus.now()
    }

    /// Lets `d` pass (the drive goes on).
    fn wait(&mut self, d: Duration) {
        let t = self.now() + d;
        self.bus.wait_until(t);
    }

    fn recv_until(&mut self, mut want: impl FnMut(&CanFrame) -> bool) -> CanFrame {
        let deadline = self.now() + T;
        loop {
            let f = self.bus.recv(deadline).expect("frame before the deadline");
            if want(&f) {
                return f;
            }
        }
    }

    fn sdo_write(&mut self, index: u16, sub: u8, data: Vec<u8>) -> Result<(), AbortCode> {
        sdo_write(&mut self.bus, self.node, index, sub, data, T, &mut ignore).map_err(code)
    }

    fn sdo_read(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode> {
        sdo_read(&mut self.bus, self.node, index, sub, T, &mut ignore).map_err(code)
    }

    /// One interpreter exchange over PDO2.
    fn interp(&mut self, cmd: Interp) -> Result<Value, u32> {
        let tpdo2 = CobId::of(Function::Tpdo(2), self.node).raw() as u32;
        let f = cmd.encode(self.node).unwrap();
        let deadline = self.now() + T;
        let reply = exchange(
            &mut self.bus,
            &f,
            deadline,
            |f| (f.raw_id() == tpdo2).then(|| Reply::decode(f.data()).unwrap()),
            &mut ignore,
        )
        .unwrap();
        assert_eq!((reply.name, reply.index), (cmd.name, cmd.index));
        reply.result
    }

    /// NMT start, then the controlword walk to operation enabled.
    fn enable(&mut self) {
        self.bus
            .send(&nmt::encode(nmt::Command::Start, 0), self.now())
            .unwrap();
        for cw in [0x06u16, 0x07, 0x0f] {
            self.sdo_write(0x6040, 0, cw.to_le_bytes().to_vec())
                .unwrap();
        }
    }

    fn state(&mut self) -> DriveState {
        let sw = self.sdo_read(0x6041, 0).unwrap();
        DriveState::from_statusword(u16::from_le_bytes([sw[0], sw[1]]))
    }

    fn position(&mut self) -> i32 {
        let p = self.sdo_read(0x6064, 0).unwrap();
        i32::from_le_bytes([p[0], p[1], p[2], p[3]])
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
            self.bus
                .send(&row.frame(cfg.cob_id(node)).unwrap(), self.now())
                .unwrap();
        }
        assert_eq!(
            self.interp(Interp::set(b"PV", 0, Value::Int(1))),
            Ok(Value::Int(1))
        );
        let bg = Interp::set(b"BG", 0, Value::Int(0)).encode(node).unwrap();
        self.bus.send(&bg, self.now()).unwrap();
    }
}

/// A fake drive (node 3) and a host on a bus on modelled time: the drive steps every
/// millisecond of it as the host waits, however the machine schedules the test.
fn start() -> (Host, Levers, Attached<FakeElmo>) {
    let bus = MemBus::modelled(1_000_000);
    let host_node = bus.node();
    let levers = Levers::default();
    let drive = FakeElmo::new(ElmoConfig::new(3), levers.clone());
    let h = bus.attach(drive, Duration::from_millis(1));
    let mut host = Host {
        bus: host_node,
        node: NodeId::new(3).unwrap(),
    };
    // Boot-up message first.
    let f = host.recv_until(|f| f.raw_id() == 0x703);
    assert_eq!(f.data(), [0x00]);
    (host, levers, h)
}

/// What the drive shows at the end.
fn finish(h: Attached<FakeElmo>) -> Probe {
    h.lock().unwrap().probe()
}

#[test]
fn sdo_server_reads_writes_and_aborts() {
    let (mut host, _, h) = start();
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
    assert_eq!(host.sdo_read(0x2001, 0), Err(AbortCode::WRITE_ONLY));
    host.sdo_write(0x1017, 0, 100u16.to_le_bytes().to_vec())
        .unwrap();
    let hb = host.recv_until(|f| f.raw_id() == 0x703);
    assert_eq!(hb.data(), [0x7f]); // pre-operational
    finish(h);
}

#[test]
fn an_absent_sub_index_aborts_with_no_sub_index() {
    let (mut host, _, h) = start();
    // 0x1018 exists with subs 0..=4: sub 9 is an absent sub-index, not an absent object.
    assert_eq!(host.sdo_read(0x1018, 9), Err(AbortCode::NO_SUBINDEX));
    assert_eq!(host.sdo_read(0x1800, 3), Err(AbortCode::NO_SUBINDEX));
    assert_eq!(
        host.sdo_write(0x6040, 1, vec![0, 0]),
        Err(AbortCode::NO_SUBINDEX)
    );
    finish(h);
}

#[test]
fn every_record_answers_its_highest_sub_index() {
    let (mut host, _, h) = start();
    assert_eq!(host.sdo_read(0x1018, 0).unwrap(), [4]);
    for i in 0..4 {
        assert_eq!(
            host.sdo_read(0x1400 + i, 0).unwrap(),
            [2],
            "{:#x}",
            0x1400 + i
        );
        assert_eq!(
            host.sdo_read(0x1800 + i, 0).unwrap(),
            [2],
            "{:#x}",
            0x1800 + i
        );
    }
    assert_eq!(host.sdo_read(0x1016, 0).unwrap(), [1]);
    assert_eq!(host.sdo_read(0x1029, 0).unwrap(), [1]);
    // The sub 0 of a record is read only.
    assert_eq!(
        host.sdo_write(0x1018, 0, vec![5]),
        Err(AbortCode::READ_ONLY)
    );
    finish(h);
}

#[test]
fn a_block_transfer_is_refused_with_bad_command() {
    let (mut host, _, h) = start();
    let sdo_tx = CobId::of(Function::SdoTx, host.node).raw() as u32;
    for download in [false, true] {
        let req = ClientRequest::Block {
            download,
            index: 0x1008,
            sub: 0,
        };
        host.bus
            .send(&req.encode(host.node).unwrap(), host.now())
            .unwrap();
        let f = host.recv_until(|f| f.raw_id() == sdo_tx);
        assert_eq!(
            ServerResponse::decode(&f).unwrap().1,
            ServerResponse::Abort {
                index: 0x1008,
                sub: 0,
                code: AbortCode::BAD_COMMAND
            }
        );
    }
    finish(h);
}

#[test]
fn sdo_is_not_served_in_stopped() {
    let (mut host, _, h) = start();
    host.bus
        .send(&nmt::encode(nmt::Command::Stop, 3), host.now())
        .unwrap();
    let e = sdo_read(
        &mut host.bus,
        host.node,
        0x1000,
        0,
        Duration::from_millis(100),
        &mut ignore,
    );
    assert_eq!(e, Err(HostError::NoAnswer));
    // NMT still works: pre-operational serves SDO again.
    host.bus
        .send(
            &nmt::encode(nmt::Command::EnterPreOperational, 3),
            host.now(),
        )
        .unwrap();
    assert_eq!(host.sdo_read(0x1000, 0).unwrap(), [0x92, 0x01, 0x02, 0x00]);
    finish(h);
}

#[test]
fn reset_communication_restores_the_communication_area() {
    let (mut host, _, h) = start();
    host.sdo_write(0x1017, 0, 100u16.to_le_bytes().to_vec())
        .unwrap();
    host.sdo_write(0x6065, 0, 1234u32.to_le_bytes().to_vec())
        .unwrap();
    host.bus
        .send(
            &nmt::encode(nmt::Command::ResetCommunication, 3),
            host.now(),
        )
        .unwrap();
    let boot = host.recv_until(|f| f.raw_id() == 0x703 && f.data() == [0]);
    assert_eq!(boot.data(), [0]);
    assert_eq!(host.sdo_read(0x1017, 0).unwrap(), [0, 0]);
    // The application area keeps its values.
    assert_eq!(host.sdo_read(0x6065, 0).unwrap(), 1234u32.to_le_bytes());
    finish(h);
}

#[test]
fn a_cleared_fault_sends_the_error_reset_emcy() {
    let (mut host, levers, h) = start();
    host.enable();
    levers.fault.store(true, Ordering::Relaxed);
    let f = host.recv_until(|f| f.raw_id() == 0x083);
    let e = Emcy::decode(&f).unwrap();
    assert_eq!((e.code, e.describe().as_str()), (0x2310, "current"));
    assert_eq!(host.state(), DriveState::Fault);
    assert_eq!(host.sdo_read(0x1001, 0).unwrap(), [0x81]);
    // The reset's EMCY comes before the SDO answer: keep what arrives meanwhile.
    let mut seen = Vec::new();
    let mut keep = |_: &mut stride_canbus::MemNode, f: Option<&CanFrame>| seen.extend(f.copied());
    sdo_write(
        &mut host.bus,
        host.node,
        0x6040,
        0,
        vec![0x80, 0],
        T,
        &mut keep,
    )
    .unwrap();
    let f = seen
        .iter()
        .chain(
            std::iter::from_fn(|| host.bus.try_recv().unwrap())
                .collect::<Vec<_>>()
                .iter(),
        )
        .find(|f| f.raw_id() == 0x083)
        .copied()
        .expect("an EMCY after the fault reset");
    let e = Emcy::decode(&f).unwrap();
    assert_eq!((e.code, e.register), (Emcy::ERROR_RESET, 0));
    assert_eq!(host.state(), DriveState::SwitchOnDisabled);
    assert_eq!(host.sdo_read(0x1001, 0).unwrap(), [0]);
    // A silent drive answers nothing.
    levers.silent.store(true, Ordering::Relaxed);
    let e = sdo_read(
        &mut host.bus,
        host.node,
        0x1000,
        0,
        Duration::from_millis(100),
        &mut ignore,
    );
    assert_eq!(e, Err(HostError::NoAnswer));
    finish(h);
}

#[test]
fn pdo_mapping_follows_the_cia_301_rules() {
    let (mut host, _, h) = start();
    let entry = |i: u32| i.to_le_bytes().to_vec();
    // TPDO1 is valid: neither its mapping nor its COB-ID changes.
    assert_eq!(
        host.sdo_write(0x1a00, 1, entry(0x2222_0010)),
        Err(AbortCode::DEVICE_STATE)
    );
    assert_eq!(
        host.sdo_write(0x1800, 1, entry(0x185)),
        Err(AbortCode::INVALID_VALUE)
    );
    // Invalidated, but with its entries still counted: the entries do not change either.
    host.sdo_write(0x1800, 1, entry(0x8000_0183)).unwrap();
    assert_eq!(
        host.sdo_write(0x1a00, 1, entry(0x6041_0010)),
        Err(AbortCode::DEVICE_STATE)
    );
    host.sdo_write(0x1a00, 0, vec![0]).unwrap();
    // Only existing, mappable objects, at their own length, 64 bits at most.
    assert_eq!(
        host.sdo_write(0x1a00, 1, entry(0x2222_0010)),
        Err(AbortCode::NO_OBJECT)
    );
    assert_eq!(
        host.sdo_write(0x1a00, 1, entry(0x1008_0020)),
        Err(AbortCode::NOT_MAPPABLE)
    );
    assert_eq!(
        host.sdo_write(0x1a00, 1, entry(0x6041_0020)),
        Err(AbortCode::NOT_MAPPABLE)
    );
    for (s, e) in [(1, 0x6041_0010), (2, 0x6064_0020), (3, 0x606c_0020)] {
        host.sdo_write(0x1a00, s, entry(e)).unwrap();
    }
    assert_eq!(
        host.sdo_write(0x1a00, 0, vec![3]),
        Err(AbortCode::PDO_TOO_LONG)
    );
    host.sdo_write(0x1a00, 0, vec![2]).unwrap();
    // A new COB-ID is taken while the PDO is invalid, and it becomes valid with it.
    host.sdo_write(0x1800, 1, entry(0x185)).unwrap();
    // The host's own order (PdoConfig::sdo_writes) passes these rules.
    let cfg = pdo::PdoConfig {
        direction: pdo::Direction::Transmit,
        number: 3,
        transmission: 1,
        entries: vec![pdo::MapEntry {
            index: ds402::VELOCITY_ACTUAL,
            sub: 0,
            bits: 32,
        }],
    };
    for (i, s, v) in cfg.sdo_writes(host.node) {
        host.sdo_write(i, s, v).unwrap();
    }
    finish(h);
}

#[test]
fn a_drive_whose_master_heartbeat_stops_quick_stops() {
    let (mut host, _, h) = start();
    // Watch node 127 with a 50 ms consumer time; quick stop when it stops.
    let entry = ConsumerEntry {
        node: 127,
        time_ms: 50,
    };
    host.sdo_write(0x1016, 1, entry.to_u32().to_le_bytes().to_vec())
        .unwrap();
    host.sdo_write(0x6007, 0, 3i16.to_le_bytes().to_vec())
        .unwrap();
    host.sdo_write(0x6085, 0, 200_000u32.to_le_bytes().to_vec())
        .unwrap();
    host.enable();
    let master = NodeId::new(127).unwrap();
    let beat = |host: &mut Host| {
        host.bus
            .send(
                &stride_canopen::heartbeat::encode(master, nmt::State::Operational),
                host.now(),
            )
            .unwrap()
    };
    beat(&mut host);
    // A 0.6 s ramp at 20 000 counts/s, the master beating every 20 ms.
    host.stream_ramp(60, 200, 20_000);
    for _ in 0..10 {
        host.wait(Duration::from_millis(20));
        beat(&mut host);
    }
    assert_eq!(host.state(), DriveState::OperationEnabled);
    // The master dies: within the consumer time the drive reports it and stops itself.
    let t0 = host.now();
    let f = host.recv_until(|f| {
        f.raw_id() == 0x083 && Emcy::decode(f).unwrap().code == Emcy::HEARTBEAT_ERROR
    });
    assert!(
        (host.now() - t0) < Duration::from_millis(100),
        "{:?}",
        (host.now() - t0)
    );
    assert_eq!(Emcy::decode(&f).unwrap().register, 0x11);
    assert_eq!(host.state(), DriveState::QuickStopActive);
    let at_stop = host.position();
    host.wait(Duration::from_millis(300));
    let held = host.position();
    host.wait(Duration::from_millis(50));
    // 20 000² / (2 × 200 000) = 1000 counts of braking, then it holds.
    assert!((held - at_stop) < 1500, "{at_stop} -> {held}");
    assert_eq!(host.position(), held);
    // Its NMT state followed 0x1029:1 (pre-operational): heartbeat 0x7F.
    host.sdo_write(0x1017, 0, 10u16.to_le_bytes().to_vec())
        .unwrap();
    let hb = host.recv_until(|f| f.raw_id() == 0x703);
    assert_eq!(hb.data(), [0x7f]);
    let d = finish(h);
    assert_eq!(d.heartbeat_events, 1);
}

#[test]
fn ds402_enable_pvt_motion_and_underflow() {
    let (mut host, _, h) = start();
    host.enable();
    assert_eq!(host.state(), DriveState::OperationEnabled);
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
    host.wait(Duration::from_millis(50));
    let pos = host.position();
    assert!((pos - 1000).abs() <= 2, "position {pos}");
    finish(h);
}

#[test]
fn pt_table_plays_a_point_every_mp4_samples() {
    let (mut host, _, h) = start();
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
        let f = stride_canopen::elmo::pt_frame(cfg.cob_id(host.node), pair[0], pair[1]);
        host.bus.send(&f, host.now()).unwrap();
    }
    assert_eq!(
        host.interp(Interp::set(b"PT", 0, Value::Int(1))),
        Ok(Value::Int(1))
    );
    let t0 = host.now();
    assert_eq!(
        host.interp(Interp::set(b"BG", 0, Value::Int(0))),
        Ok(Value::Int(0))
    );
    let mut mid = None;
    while host.position() < 1995 {
        assert!(
            (host.now() - t0) < Duration::from_secs(3),
            "the PT motion stalled"
        );
        if mid.is_none() && (host.now() - t0) >= Duration::from_millis(60) {
            mid = Some(host.position());
        }
        host.wait(Duration::from_millis(5));
    }
    // 20 segments of 10 ms cannot end sooner than 200 ms; it passed through the middle.
    assert!(
        (host.now() - t0) >= Duration::from_millis(195),
        "{:?}",
        (host.now() - t0)
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
    finish(h);
}

#[test]
fn interpreter_refuses_what_a_drive_refuses() {
    let (mut host, _, h) = start();
    host.bus
        .send(&nmt::encode(nmt::Command::Start, 0), host.now())
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
    finish(h);
}

#[test]
fn sdo_aborts_name_the_transfer_and_client_aborts_get_no_answer() {
    let (mut host, _, h) = start();
    let sdo_tx = CobId::of(Function::SdoTx, host.node).raw() as u32;
    let send = |host: &mut Host, req: ClientRequest| {
        host.bus
            .send(&req.encode(host.node).unwrap(), host.now())
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
    let deadline = host.now() + Duration::from_millis(100);
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
    // A command specifier CiA 301 does not define (7, 0xE0) ends a transfer, naming it.
    start_upload(&mut host);
    let sdo_rx = CobId::of(Function::SdoRx, host.node).raw();
    let unknown = CanFrame::standard(sdo_rx, &[0xe0, 0, 0, 0, 0, 0, 0, 0]).unwrap();
    host.bus.send(&unknown, host.now()).unwrap();
    let f = host.recv_until(|f| f.raw_id() == sdo_tx);
    assert_eq!(
        ServerResponse::decode(&f).unwrap().1,
        ServerResponse::Abort {
            index: 0x1008,
            sub: 0,
            code: AbortCode::BAD_COMMAND
        }
    );
    finish(h);
}

#[test]
fn profile_position_handshake_and_trapezoid() {
    let (mut host, _, h) = start();
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
    let t0 = host.now();
    host.sdo_write(0x6040, 0, mv.controlword(true).to_le_bytes().to_vec())
        .unwrap();
    let st = status(&mut host);
    assert!(st.mode_bit && !st.target_reached, "{st:?}");
    host.sdo_write(0x6040, 0, mv.controlword(false).to_le_bytes().to_vec())
        .unwrap();
    assert!(!status(&mut host).mode_bit, "acknowledge stays up");
    while !status(&mut host).target_reached {
        assert!((host.now() - t0) < Duration::from_secs(3), "never reached");
        host.wait(Duration::from_millis(5));
    }
    assert!(
        (host.now() - t0) >= Duration::from_millis(290),
        "{:?}",
        (host.now() - t0)
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
        assert!((host.now() - t0) < Duration::from_secs(5), "never reached");
        host.wait(Duration::from_millis(5));
    }
    assert!((host.position() - 15_000).abs() <= 1);
    finish(h);
}

#[test]
fn quick_stop_decelerates_then_holds() {
    let (mut host, _, h) = start();
    host.enable();
    // A slow deceleration makes the stopping distance visible: 100 000 counts/s².
    host.sdo_write(0x6085, 0, 100_000u32.to_le_bytes().to_vec())
        .unwrap();
    // A steady 20 000 counts/s ramp for 0.5 s.
    host.stream_ramp(50, 200, 20_000);
    host.wait(Duration::from_millis(150));
    host.sdo_write(0x6040, 0, 0x02u16.to_le_bytes().to_vec())
        .unwrap();
    let at_stop = host.position();
    host.wait(Duration::from_millis(400));
    let held = host.position();
    host.wait(Duration::from_millis(100));
    // v²/2a = 20 000² / 200 000 = 2000 counts of braking distance, then it holds.
    assert!(held - at_stop > 1000, "stopped dead: {at_stop} -> {held}");
    assert!(held < 200 * 50, "did not stop: {held}");
    assert!((host.position() - held).abs() <= 2, "did not hold");
    finish(h);
}
