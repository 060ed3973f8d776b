//! The fake servos against what ROBOTIS's e-manuals say a servo does, byte by byte: reboots,
//! factory resets, bad packets, partial writes, registered writes, the baud-rate item. Each
//! test guards one way the fake used to differ from a servo.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use stride_dynamixel::{models, v1, v2, Instruction, Protocol, Split, BROADCAST};
use stride_fakes::dynamixel::{ChainLevers, FakeChain, Servo};
use stride_serial::{pty_pair, Paced, Port, Transport};

struct Raw {
    line: Port<serialport::TTYPort>,
    protocol: Protocol,
    stop: Arc<AtomicBool>,
    chain: Option<JoinHandle<FakeChain>>,
}

impl Drop for Raw {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.chain.take() {
            let _ = h.join();
        }
    }
}

fn chain(model: &str, ids: impl IntoIterator<Item = u8>) -> Raw {
    let model = models::by_name(model).unwrap();
    let (host, dev) = pty_pair(1_000_000).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let servos = ids.into_iter().map(|i| Servo::new(i, model)).collect();
    let chain = FakeChain::new(model.protocol, servos, ChainLevers::default())
        .at_baud(1_000_000)
        .spawn(Paced::new(dev), stop.clone());
    Raw {
        line: host,
        protocol: model.protocol,
        stop,
        chain: Some(chain),
    }
}

impl Raw {
    /// Sends `bytes` and returns the status packets that come back within 100 ms.
    fn raw(&mut self, bytes: &[u8]) -> Vec<stride_dynamixel::Status> {
        self.line.write_all(bytes).unwrap();
        let deadline = Instant::now() + Duration::from_millis(100);
        let mut buf = [0u8; 512];
        let (mut s1, mut s2) = (v1::Splitter::new(), v2::Splitter::new());
        let mut out = Vec::new();
        while Instant::now() < deadline {
            let n = self.line.read_until(&mut buf, deadline).unwrap_or(0);
            s1.push(&buf[..n]);
            s2.push(&buf[..n]);
            let items: Vec<Split> = match self.protocol {
                Protocol::V1 => std::iter::from_fn(|| s1.next_item()).collect(),
                Protocol::V2 => std::iter::from_fn(|| s2.next_item()).collect(),
            };
            for i in items {
                if let Split::Packet(p) = i {
                    out.push(match self.protocol {
                        Protocol::V1 => v1::decode_status(&p).unwrap(),
                        Protocol::V2 => v2::decode_status(&p).unwrap(),
                    });
                }
            }
        }
        out
    }

    fn packet(&self, id: u8, ins: &Instruction) -> Vec<u8> {
        match self.protocol {
            Protocol::V1 => v1::encode_instruction(id, ins).unwrap(),
            Protocol::V2 => v2::encode_instruction(id, ins).unwrap(),
        }
    }

    /// Sends an instruction; its one status packet.
    fn ask(&mut self, id: u8, ins: Instruction) -> Option<stride_dynamixel::Status> {
        let p = self.packet(id, &ins);
        self.raw(&p).into_iter().next()
    }

    fn read(&mut self, id: u8, address: u16, length: u16) -> Vec<u8> {
        self.ask(id, Instruction::Read { address, length })
            .expect("an answer")
            .params
    }

    fn write(&mut self, id: u8, address: u16, data: &[u8]) -> u8 {
        self.ask(
            id,
            Instruction::Write {
                address,
                data: data.to_vec(),
            },
        )
        .expect("an answer")
        .error
    }
}

#[test]
fn a_reboot_keeps_the_eeprom() {
    // Protocol 1.0: return delay and CCW limit written, then the raw reboot of id 6.
    let mut r = chain("AX-12A", 1..=6);
    assert_eq!(r.write(6, 5, &[10]), 0);
    assert_eq!(r.write(6, 8, &900u16.to_le_bytes()), 0);
    assert_eq!(r.write(6, 24, &[1]), 0);
    let answer = r.raw(&[0xff, 0xff, 0x06, 0x02, 0x08, 0xef]);
    assert_eq!(answer.len(), 1);
    assert_eq!(r.read(6, 5, 1), [10]);
    assert_eq!(r.read(6, 8, 2), 900u16.to_le_bytes());
    // The RAM is back to power-on: the torque off.
    assert_eq!(r.read(6, 24, 1), [0]);
    // Protocol 2.0 alike.
    let mut r = chain("XM430-W350", 1..=3);
    assert_eq!(r.write(2, 9, &[10]), 0);
    assert_eq!(r.write(2, 48, &3000u32.to_le_bytes()), 0);
    assert!(r.ask(2, Instruction::Reboot).is_some());
    assert_eq!(r.read(2, 9, 1), [10]);
    assert_eq!(r.read(2, 48, 4), 3000u32.to_le_bytes());
}

#[test]
fn a_factory_reset_keeps_what_its_option_says() {
    let mut r = chain("XM430-W350", 4..=6);
    for id in 4..=6 {
        assert_eq!(r.write(id, 9, &[10]), 0);
    }
    // 0x02: all but the id and the baud rate.
    assert!(r
        .ask(4, Instruction::FactoryReset { option: 0x02 })
        .is_some());
    assert_eq!(r.read(4, 9, 1), [250]);
    assert_eq!(r.read(4, 8, 1), [3]);
    // 0x01: all but the id (the baud rate back to 57600, item value 1).
    assert!(r
        .ask(5, Instruction::FactoryReset { option: 0x01 })
        .is_some());
    assert_eq!(r.read(5, 8, 1), [1]);
    // 0xFF: all, the id too: servo 6 answers as 1.
    assert!(r
        .ask(6, Instruction::FactoryReset { option: 0xff })
        .is_some());
    assert!(r.ask(6, Instruction::Ping).is_none());
    assert!(r.ask(1, Instruction::Ping).is_some());
    // Protocol 1.0 has no option: a reset makes the servo id 1.
    let mut r = chain("AX-12A", [18]);
    assert!(r
        .ask(18, Instruction::FactoryReset { option: 0xff })
        .is_some());
    assert!(r.ask(18, Instruction::Ping).is_none());
    assert!(r.ask(1, Instruction::Ping).is_some());
}

#[test]
fn a_broadcast_reset_of_everything_is_ignored() {
    let mut r = chain("XM430-W350", 1..=3);
    for id in 1..=3 {
        assert_eq!(r.write(id, 9, &[10]), 0);
    }
    let p = r.packet(BROADCAST, &Instruction::FactoryReset { option: 0xff });
    assert!(r.raw(&p).is_empty());
    for id in 1..=3 {
        assert_eq!(r.read(id, 9, 1), [10], "servo {id}");
    }
    // A broadcast reset that keeps the ids is done by every servo.
    let p = r.packet(BROADCAST, &Instruction::FactoryReset { option: 0x02 });
    r.raw(&p);
    for id in 1..=3 {
        assert_eq!(r.read(id, 9, 1), [250], "servo {id}");
    }
}

#[test]
fn bad_packets_get_the_status_the_protocol_defines() {
    // 2.0: a ping with a bad CRC, error 3; an unknown instruction, error 2.
    let mut r = chain("XM430-W350", 1..=3);
    let s = r.raw(&[0xff, 0xff, 0xfd, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4f]);
    assert_eq!((s.len(), s[0].id, s[0].error & 0x7f), (1, 1, 3), "{s:?}");
    let unknown = v2::frame(2, 0x7f, &[]);
    let s = r.raw(&unknown);
    assert_eq!((s.len(), s[0].id, s[0].error & 0x7f), (1, 2, 2), "{s:?}");
    // 1.0: a bad checksum sets the checksum bit; an unknown instruction the instruction bit.
    let mut r = chain("AX-12A", 1..=7);
    let s = r.raw(&[0xff, 0xff, 0x07, 0x02, 0x01, 0x00]);
    assert_eq!((s.len(), s[0].id), (1, 7), "{s:?}");
    assert_eq!(
        s[0].error & v1::ErrorBits::CHECKSUM,
        v1::ErrorBits::CHECKSUM
    );
    let body = [0x05u8, 0x02, 0x7f];
    let sum = !body.iter().fold(0u8, |a, b| a.wrapping_add(*b));
    let s = r.raw(&[0xff, 0xff, body[0], body[1], body[2], sum]);
    assert_eq!((s.len(), s[0].id), (1, 5), "{s:?}");
    assert_eq!(
        s[0].error & v1::ErrorBits::INSTRUCTION,
        v1::ErrorBits::INSTRUCTION
    );
}

#[test]
fn a_write_shorter_than_its_item_is_refused() {
    // 2.0's data length error: 2 bytes into the 4-byte goal position.
    let mut r = chain("XM430-W350", 1..=1);
    let goal = r.read(1, 116, 4);
    assert_eq!(r.write(1, 116, &100u16.to_le_bytes()) & 0x7f, 5);
    assert_eq!(r.read(1, 116, 4), goal, "the goal changed");
    assert_eq!(r.write(1, 116, &100u32.to_le_bytes()) & 0x7f, 0);
}

#[test]
fn a_registered_write_is_registered() {
    let mut r = chain("AX-12A", 1..=3);
    let reg = Instruction::RegWrite {
        address: 30,
        data: 544u16.to_le_bytes().to_vec(),
    };
    assert!(r.ask(3, reg).is_some());
    assert_eq!(r.read(3, 44, 1), [1]);
    let p = r.packet(BROADCAST, &Instruction::Action);
    r.raw(&p);
    assert_eq!(r.read(3, 44, 1), [0]);
    assert_eq!(r.read(3, 30, 2), 544u16.to_le_bytes());
}

#[test]
fn the_baud_rate_item_says_the_lines_rate() {
    let mut r = chain("XM430-W350", 1..=1);
    assert_eq!(r.read(1, 8, 1), [3]);
    let mut r = chain("AX-12A", 1..=1);
    assert_eq!(r.read(1, 4, 1), [1]);
}
