//! The bus against fake servo chains on a pseudo-terminal, paced at the line's baud rate.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use stride_dynamixel::{models, v1, v2};
use stride_dynamixel_bus::{Bus, BusConfig, BusError, ReadMany};
use stride_fakes::dynamixel::{ChainLevers, FakeChain, Fault, Servo};
use stride_serial::{pty_pair, Paced, Port};

struct Rig {
    bus: Bus<Port<serialport::TTYPort>>,
    levers: ChainLevers,
    stop: Arc<AtomicBool>,
    chain: Option<JoinHandle<FakeChain>>,
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.chain.take() {
            let _ = h.join();
        }
    }
}

fn rig(model: &str, ids: impl IntoIterator<Item = u8>, baud: u32) -> Rig {
    let model = models::by_name(model).unwrap();
    let (host, dev) = pty_pair(baud).unwrap();
    let levers = ChainLevers::default();
    let stop = Arc::new(AtomicBool::new(false));
    let servos = ids.into_iter().map(|i| Servo::new(i, model)).collect();
    let chain =
        FakeChain::new(model.protocol, servos, levers.clone()).spawn(Paced::new(dev), stop.clone());
    // A pty and a fake thread on a loaded test machine are slower to answer than a servo:
    // a wide margin (the deadlines' logic is the same).
    let cfg = BusConfig {
        margin: Duration::from_millis(25),
        ..BusConfig::new(model.protocol)
    };
    Rig {
        bus: Bus::new(host, cfg),
        levers,
        stop,
        chain: Some(chain),
    }
}

#[test]
fn protocol_1_chain_of_ax12a() {
    let mut r = rig("AX-12A", 1..=18, 1_000_000);
    let found = r.bus.scan(1..=20, Duration::from_millis(20));
    assert_eq!(found.len(), 18);
    assert!(found.iter().all(|&(_, m)| m == 12));
    // Torque on, goals by one sync write, then the positions one by one.
    let ids: Vec<u8> = (1..=18).collect();
    r.bus
        .sync_write(24, 1, ids.iter().map(|&i| (i, vec![1])).collect())
        .unwrap();
    r.bus
        .sync_write(
            30,
            2,
            ids.iter()
                .map(|&i| (i, 600u16.to_le_bytes().to_vec()))
                .collect(),
        )
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let replies = r.bus.read_many(36, 2, &ids, ReadMany::OneByOne).unwrap();
    for rep in replies {
        let s = rep.unwrap();
        assert_eq!(
            u16::from_le_bytes([s.params[0], s.params[1]]),
            600,
            "servo {}",
            s.id
        );
    }
    // A goal past the angle limit is refused with the angle limit bit.
    r.bus.write(5, 30, &1023u16.to_le_bytes()).unwrap(); // within the factory limits
    r.bus.write(5, 8, &900u16.to_le_bytes()).unwrap(); // CCW angle limit: 900
    let e = r.bus.write(5, 30, &950u16.to_le_bytes()).unwrap_err();
    assert!(
        matches!(&e, BusError::Refused { id: 5, what } if what.contains("angle limit")),
        "{e}"
    );
}

#[test]
fn protocol_2_chain_of_xm430_fast_sync_read() {
    let mut r = rig("XM430-W350", 1..=12, 4_000_000);
    assert_eq!(r.bus.ping(3).unwrap(), 1020);
    let ids: Vec<u8> = (1..=12).collect();
    for how in [ReadMany::Sync, ReadMany::FastSync] {
        let replies = r.bus.read_many(132, 4, &ids, how).unwrap();
        assert_eq!(replies.len(), 12);
        for (rep, id) in replies.iter().zip(&ids) {
            let s = rep.as_ref().unwrap();
            assert_eq!((s.id, s.params.len()), (*id, 4));
            assert_eq!(u32::from_le_bytes(s.params[..4].try_into().unwrap()), 2048);
        }
    }
    // EEPROM with the torque on, and a goal past the position limit: refused.
    r.bus.write(2, 64, &[1]).unwrap();
    let e = r.bus.write(2, 48, &3000u32.to_le_bytes()).unwrap_err();
    assert!(
        matches!(&e, BusError::Refused { what, .. } if what == "access error"),
        "{e}"
    );
    let e = r.bus.write(2, 116, &5000u32.to_le_bytes()).unwrap_err();
    assert!(
        matches!(&e, BusError::Refused { what, .. } if what == "data limit error"),
        "{e}"
    );
    assert_eq!(v2::StatusError(0x86).error(), Some("data limit error"));
}

#[test]
fn missing_late_and_overheating_servos() {
    let mut r = rig("XM430-W350", 1..=4, 1_000_000);
    let cfg = *r.bus.config();
    // A silent servo: bounded retries, then a timeout that names it; the others answer.
    r.levers.set(
        3,
        Fault {
            silent: true,
            ..Fault::default()
        },
    );
    let replies = r
        .bus
        .read_many(132, 4, &[1, 2, 3, 4], ReadMany::Sync)
        .unwrap();
    assert!(
        matches!(
            replies[2],
            Err(BusError::Timeout { id: 3, tries, .. }) if tries == cfg.retries + 1
        ),
        "{:?}",
        replies[2]
    );
    assert!(replies[0].is_ok() && replies[1].is_ok() && replies[3].is_ok());
    assert!(r.bus.stats().retries >= 2);
    // A servo that answers later than the deadline: its late answer is not taken for the next.
    r.levers.clear(3);
    r.levers.set(
        2,
        Fault {
            late: Duration::from_millis(120),
            ..Fault::default()
        },
    );
    assert!(r.bus.read(2, 132, 4).is_err());
    r.levers.clear(2);
    std::thread::sleep(Duration::from_millis(40));
    assert_eq!(
        r.bus.read(1, 7, 1).unwrap(),
        [1],
        "a stale answer was taken"
    );
    // Nor for the next read of the same servo and size, when every try's answer comes after
    // the transaction gave up (the tries take about 80 ms here), even while the next starts.
    std::thread::sleep(Duration::from_millis(200));
    r.bus.write(2, 108, &[77, 0, 0, 0]).unwrap();
    r.levers.set(
        2,
        Fault {
            late: Duration::from_millis(100),
            ..Fault::default()
        },
    );
    let got = r.bus.read(2, 132, 4);
    assert!(got.is_err(), "{got:?}");
    r.levers.clear(2);
    std::thread::sleep(Duration::from_millis(40));
    assert_eq!(
        r.bus.read(2, 108, 4).unwrap(),
        [77, 0, 0, 0],
        "a stale answer was taken"
    );
    // Overheating: the alert bit on every status, the hardware error status says why, and
    // the shutdown turned the torque off.
    r.bus.write(4, 64, &[1]).unwrap();
    r.levers.set(
        4,
        Fault {
            overheat: true,
            ..Fault::default()
        },
    );
    std::thread::sleep(Duration::from_millis(20));
    let s = r
        .bus
        .transact(
            4,
            &stride_dynamixel::Instruction::Read {
                address: 70,
                length: 1,
            },
            &[(4, 1)],
        )
        .unwrap()
        .pop()
        .unwrap()
        .unwrap();
    assert!(v2::StatusError(s.error).alert());
    assert_eq!(v2::HardwareError(s.params[0]).names(), ["overheating"]);
    assert_eq!(r.bus.read(4, 64, 1).unwrap(), [0]);
}

#[test]
fn protocol_1_errors_and_bulk_read() {
    let mut r = rig("MX-64", 1..=3, 1_000_000);
    let replies = r.bus.read_many(36, 2, &[1, 2, 3], ReadMany::Bulk).unwrap();
    assert!(replies
        .iter()
        .all(|x| x.as_ref().is_ok_and(|s| s.params == 2048u16.to_le_bytes())));
    r.levers.set(
        2,
        Fault {
            overload: true,
            voltage: Some(4.0),
            ..Fault::default()
        },
    );
    std::thread::sleep(Duration::from_millis(20));
    let s = r
        .bus
        .transact(2, &stride_dynamixel::Instruction::Ping, &[(2, 0)])
        .unwrap()
        .pop()
        .unwrap()
        .unwrap();
    assert_eq!(
        v1::ErrorBits(s.error).names(),
        ["input voltage", "overload"]
    );
}
