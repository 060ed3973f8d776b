//! A fake USB2CAN dongle: speaks SLCAN (Lawicel) on a serial port (a pseudo-terminal in
//! tests) and bridges to a CAN bus, as a real one does: a bit rate by `Sn` or by the BTR
//! registers (`sxxyy`) before it opens, open (`O`) or listen-only (`L`, which receives and
//! never transmits), `z`/`Z` for standard/extended frames queued, BEL for what it refuses
//! (a full transmit queue too, which also sets the transmit-FIFO-full status flag), status
//! flags (`F`, while open, cleared by reading), timestamps (`Z1`).

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use stride_canbus::CanBus;
use stride_slcan::{BitRate, Command, LineSplitter, Message};

/// What the fake dongle counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DongleStats {
    /// Frames passed from the host to the bus.
    pub to_bus: u64,
    /// Frames passed from the bus to the host.
    pub to_host: u64,
    /// Commands refused with BEL.
    pub refused: u64,
    /// Frames refused because the transmit queue was full.
    pub dropped: u64,
}

/// The transmit FIFO was full (status flag bit 1).
pub const FLAG_TX_FULL: u8 = 0x02;

/// How the bit rate was set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Rate {
    Standard(BitRate),
    Registers(u8, u8),
}

/// The channel's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Channel {
    Closed,
    Open,
    ListenOnly,
}

/// A fake dongle between a serial port and a bus.
pub struct FakeDongle<P, B> {
    port: P,
    bus: B,
    rate: Option<Rate>,
    channel: Channel,
    stamps: bool,
    flags: u8,
    split: LineSplitter,
    started: Instant,
    stats: DongleStats,
}

impl<P: Read + Write + Send + 'static, B: CanBus + Send + 'static> FakeDongle<P, B> {
    /// A closed dongle with no bit rate set.
    pub fn new(port: P, bus: B) -> Self {
        FakeDongle {
            port,
            bus,
            rate: None,
            channel: Channel::Closed,
            stamps: false,
            flags: 0,
            split: LineSplitter::new(),
            started: Instant::now(),
            stats: DongleStats::default(),
        }
    }

    fn reply(&mut self, m: Message) {
        if matches!(m, Message::Error) {
            self.stats.refused += 1;
        }
        if let Ok(bytes) = m.encode() {
            let _ = self.port.write_all(&bytes);
        }
    }

    fn on_line(&mut self, line: &[u8]) {
        // An empty line (python-can sends one as it opens) is answered, not refused.
        if line.is_empty() {
            self.reply(Message::Ok);
            return;
        }
        let Ok(cmd) = Command::parse(line) else {
            self.reply(Message::Error);
            return;
        };
        let closed = self.channel == Channel::Closed;
        let answer = match cmd {
            Command::Speed(r) if closed => {
                self.rate = Some(Rate::Standard(r));
                Message::Ok
            }
            Command::Btr(a, b) if closed => {
                self.rate = Some(Rate::Registers(a, b));
                Message::Ok
            }
            Command::Open if closed && self.rate.is_some() => {
                self.channel = Channel::Open;
                Message::Ok
            }
            Command::Listen if closed && self.rate.is_some() => {
                self.channel = Channel::ListenOnly;
                Message::Ok
            }
            Command::Close if !closed => {
                self.channel = Channel::Closed;
                Message::Ok
            }
            Command::Transmit(f) if self.channel == Channel::Open => {
                match self
                    .bus
                    .send(&f, Instant::now() + Duration::from_millis(10))
                {
                    Ok(()) => {
                        self.stats.to_bus += 1;
                        Message::Transmitted {
                            extended: f.is_extended(),
                        }
                    }
                    // The transmit FIFO is full: refused, and the status says so.
                    Err(_) => {
                        self.flags |= FLAG_TX_FULL;
                        self.stats.dropped += 1;
                        Message::Error
                    }
                }
            }
            Command::Version => Message::Version("1013".into()),
            Command::Serial => Message::Serial("F4KE".into()),
            Command::Flags if !closed => Message::Flags(std::mem::take(&mut self.flags)),
            Command::Timestamps(on) if closed => {
                self.stamps = on;
                Message::Ok
            }
            _ => Message::Error,
        };
        self.reply(answer);
    }

    /// Serves until `stop` is set; returns the counters.
    pub fn spawn(mut self, stop: Arc<AtomicBool>) -> JoinHandle<DongleStats> {
        std::thread::spawn(move || {
            let mut buf = [0u8; 256];
            while !stop.load(Ordering::Relaxed) {
                // Host to dongle.
                match self.port.read(&mut buf) {
                    Ok(n) if n > 0 => {
                        for line in self.split.push(&buf[..n]) {
                            if line != [0x07] {
                                self.on_line(&line);
                            }
                        }
                    }
                    _ => {}
                }
                // Bus to host (listen-only receives too).
                while let Ok(Some(f)) = self.bus.try_recv() {
                    if self.channel != Channel::Closed {
                        let stamp = self
                            .stamps
                            .then(|| (self.started.elapsed().as_millis() % 60_000) as u16);
                        self.reply(Message::Frame(f, stamp));
                        self.stats.to_host += 1;
                    }
                }
            }
            self.stats
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::elmo::{ElmoConfig, FakeElmo, Levers};
    use serialport::SerialPort;
    use stride_canbus::slcan::SlcanBus;
    use stride_canbus::{CanFrame, MemBus};
    use stride_canopen::frame::NodeId;
    use stride_canopen::sdo::{ClientRequest, Initiate, ServerResponse};

    /// A dongle on a pty over `bus`, and the host's raw end.
    fn raw(
        bus: &MemBus,
    ) -> (
        serialport::TTYPort,
        Arc<AtomicBool>,
        JoinHandle<DongleStats>,
    ) {
        let (mut host, mut dev) = serialport::TTYPort::pair().expect("pty pair");
        dev.set_timeout(Duration::from_millis(2)).unwrap();
        host.set_timeout(Duration::from_millis(50)).unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let h = FakeDongle::new(dev, bus.node()).spawn(stop.clone());
        (host, stop, h)
    }

    /// Writes `lines` (each with CR) and reads the answers until `n` lines came (or 1 s).
    fn say(host: &mut serialport::TTYPort, lines: &[&str], n: usize) -> Vec<Vec<u8>> {
        for l in lines {
            host.write_all(format!("{l}\r").as_bytes()).unwrap();
        }
        let mut split = LineSplitter::new();
        let mut out = Vec::new();
        let deadline = Instant::now() + Duration::from_secs(1);
        let mut buf = [0u8; 4096];
        while out.len() < n && Instant::now() < deadline {
            if let Ok(k) = host.read(&mut buf) {
                out.extend(split.push(&buf[..k]));
            }
        }
        out
    }

    #[test]
    fn listen_only_does_not_transmit() {
        let bus = MemBus::new(1_000_000);
        let mut other = bus.node();
        let (mut host, stop, h) = raw(&bus);
        let a = say(&mut host, &["S8", "L", "t60184000100000000000"], 3);
        assert_eq!(a, [b"".to_vec(), b"".to_vec(), vec![7]]);
        assert_eq!(
            other.recv(Instant::now() + Duration::from_millis(50)).ok(),
            None
        );
        // It receives, though.
        other
            .send(&CanFrame::standard(0x181, &[1]).unwrap(), Instant::now())
            .unwrap();
        assert_eq!(say(&mut host, &[], 1), [b"t181101".to_vec()]);
        stop.store(true, Ordering::Relaxed);
        assert_eq!(h.join().unwrap().to_bus, 0);
    }

    #[test]
    fn a_bit_rate_set_by_btr_opens() {
        let bus = MemBus::new(1_000_000);
        let (mut host, stop, h) = raw(&bus);
        // BTR0 0x00, BTR1 0x14: 1 Mbit/s on an 8 MHz SJA1000; then open and send.
        let a = say(&mut host, &["s0014", "O", "t1230"], 3);
        assert_eq!(a, [b"".to_vec(), b"".to_vec(), b"z".to_vec()]);
        stop.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }

    #[test]
    fn extended_frames_are_acknowledged_with_capital_z() {
        let bus = MemBus::new(1_000_000);
        let _other = bus.node();
        let (mut host, stop, h) = raw(&bus);
        let a = say(
            &mut host,
            &["S8", "O", "t1230", "T1ABCDE002BEEF", "r6B04", "R1ABCDF003"],
            6,
        );
        let acks: Vec<&[u8]> = a[2..].iter().map(|l| l.as_slice()).collect();
        assert_eq!(acks, [&b"z"[..], b"Z", b"z", b"Z"]);
        stop.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }

    #[test]
    fn a_full_transmit_queue_refuses_with_bel_and_sets_the_flag() {
        // The finding: 200 frames in one write got 200 z while 74 reached the bus. A slow
        // bus keeps the dongle's queue full.
        let bus = MemBus::new(10_000);
        let mut other = bus.node();
        let (mut host, stop, h) = raw(&bus);
        say(&mut host, &["S8", "O"], 2);
        let lines: Vec<String> = (0..200).map(|i| format!("t1231{:02X}", i % 256)).collect();
        let refs: Vec<&str> = lines.iter().map(String::as_str).collect();
        let a = say(&mut host, &refs, 200);
        let ok = a.iter().filter(|l| l.as_slice() == b"z").count();
        let bel = a.iter().filter(|l| l.as_slice() == [7]).count();
        assert_eq!(ok + bel, 200, "{a:?}");
        assert!(bel > 0, "nothing refused");
        // Every acknowledged frame reaches the bus, and only those.
        let mut seen = 0;
        while other
            .recv(Instant::now() + Duration::from_millis(300))
            .is_ok()
        {
            seen += 1;
        }
        assert_eq!(seen, ok);
        // The status says the transmit FIFO was full, and reading clears it.
        assert_eq!(say(&mut host, &["F"], 1), [b"F02".to_vec()]);
        assert_eq!(say(&mut host, &["F"], 1), [b"F00".to_vec()]);
        stop.store(true, Ordering::Relaxed);
        let s = h.join().unwrap();
        assert_eq!((s.to_bus, s.dropped), (ok as u64, bel as u64));
    }

    #[test]
    fn flags_answer_only_while_open_and_an_empty_line_is_no_error() {
        let bus = MemBus::new(1_000_000);
        let (mut host, stop, h) = raw(&bus);
        let a = say(&mut host, &["F", "", "S8", "O", "F"], 5);
        assert_eq!(
            a,
            [
                vec![7],
                b"".to_vec(),
                b"".to_vec(),
                b"".to_vec(),
                b"F00".to_vec()
            ]
        );
        stop.store(true, Ordering::Relaxed);
        assert_eq!(h.join().unwrap().refused, 1);
    }

    #[test]
    fn sdo_through_the_dongle_on_a_pty() {
        let (host_end, dongle_end) = serialport::TTYPort::pair().expect("pty pair");
        let mut dongle_end = dongle_end;
        dongle_end.set_timeout(Duration::from_millis(2)).unwrap();
        let bus = MemBus::new(1_000_000);
        let stop = Arc::new(AtomicBool::new(false));
        let dongle = FakeDongle::new(dongle_end, bus.node()).spawn(stop.clone());
        let mut host = SlcanBus::open(host_end, BitRate::M1, Duration::from_secs(1)).unwrap();
        // The drive powers up once the dongle is open, so its boot-up message is seen.
        let drive =
            FakeElmo::new(ElmoConfig::new(5), Levers::default()).spawn(bus.node(), stop.clone());
        let node = NodeId::new(5).unwrap();
        // Boot-up message of the drive crosses the dongle.
        let deadline = Instant::now() + Duration::from_secs(2);
        let boot = loop {
            let f = host.recv(deadline).unwrap();
            if f.raw_id() == 0x705 {
                break f;
            }
        };
        assert_eq!(boot.data(), [0]);
        let req = ClientRequest::InitiateUpload {
            index: 0x1000,
            sub: 0,
        }
        .encode(node)
        .unwrap();
        host.send(&req, Instant::now() + Duration::from_secs(1))
            .unwrap();
        let resp = loop {
            let f = host.recv(deadline).unwrap();
            if f.raw_id() == 0x585 {
                break ServerResponse::decode(&f).unwrap().1;
            }
        };
        assert_eq!(
            resp,
            ServerResponse::UploadInitiated {
                index: 0x1000,
                sub: 0,
                data: Initiate::Expedited(vec![0x92, 0x01, 0x02, 0x00])
            }
        );
        // The dongle refuses a bit-rate change while open.
        assert!(!host
            .command(&Command::Speed(BitRate::K500), Duration::from_secs(1))
            .unwrap());
        assert_eq!(host.stats().refused, 1);
        stop.store(true, Ordering::Relaxed);
        let stats = dongle.join().unwrap();
        drive.join().unwrap();
        // The dongle also refused the close of its closed channel at open.
        assert!(
            stats.to_bus >= 1 && stats.to_host >= 2 && stats.refused == 2,
            "{stats:?}"
        );
    }
}
