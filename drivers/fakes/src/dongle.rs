//! A fake USB2CAN dongle: speaks SLCAN on a serial port (a pseudo-terminal in tests) and
//! bridges to a CAN bus, refusing what a real dongle refuses.

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
}

/// A fake dongle between a serial port and a bus.
pub struct FakeDongle<P, B> {
    port: P,
    bus: B,
    rate: Option<BitRate>,
    open: bool,
    stamps: bool,
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
            open: false,
            stamps: false,
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
        let Ok(cmd) = Command::parse(line) else {
            self.reply(Message::Error);
            return;
        };
        let ok = match cmd {
            Command::Speed(r) if !self.open => {
                self.rate = Some(r);
                Some(Message::Ok)
            }
            Command::Btr(..) if !self.open => Some(Message::Ok),
            Command::Open | Command::Listen if !self.open && self.rate.is_some() => {
                self.open = true;
                Some(Message::Ok)
            }
            Command::Close if self.open => {
                self.open = false;
                Some(Message::Ok)
            }
            Command::Transmit(f) if self.open => {
                let _ = self
                    .bus
                    .send(&f, Instant::now() + Duration::from_millis(10));
                self.stats.to_bus += 1;
                Some(Message::Transmitted)
            }
            Command::Version => Some(Message::Version("1013".into())),
            Command::Serial => Some(Message::Serial("F4KE".into())),
            Command::Flags => Some(Message::Flags(0)),
            Command::Timestamps(on) if !self.open => {
                self.stamps = on;
                Some(Message::Ok)
            }
            _ => None,
        };
        self.reply(ok.unwrap_or(Message::Error));
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
                // Bus to host.
                while let Ok(Some(f)) = self.bus.try_recv() {
                    if self.open {
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
    use stride_canbus::MemBus;
    use stride_canopen::frame::NodeId;
    use stride_canopen::sdo::{ClientRequest, Initiate, ServerResponse};

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
