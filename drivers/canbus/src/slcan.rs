//! A USB2CAN dongle speaking SLCAN (Lawicel) on a serial port, as a [`CanBus`].

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use stride_slcan::{BitRate, Command, LineSplitter, Message};

use crate::{BusError, CanBus, CanFrame};

/// Counters of an SLCAN link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SlcanStats {
    /// Frames sent.
    pub sent: u64,
    /// Frames received.
    pub received: u64,
    /// Lines that did not parse (noise on the line).
    pub malformed: u64,
    /// Commands the dongle refused (BEL).
    pub refused: u64,
    /// Frames whose acknowledgment came after their send's deadline (the frame was written
    /// to the dongle: a busy machine or dongle answers late, and the answer is matched to
    /// its frame when it comes).
    pub late: u64,
}

/// Opens the dongle on the serial device `path` (e.g. `/dev/ttyACM0`) at `bits_per_second`.
pub fn open_path(
    path: &str,
    bits_per_second: u32,
) -> Result<SlcanBus<serialport::TTYPort>, BusError> {
    let rate = BitRate::from_bits_per_second(bits_per_second)
        .ok_or_else(|| BusError::Device(format!("{bits_per_second} bit/s is not an SLCAN rate")))?;
    // USB dongles ignore the serial speed; real UARTs want the fastest they can do.
    let port = serialport::new(path, 115_200)
        .timeout(Duration::from_millis(10))
        .open_native()
        .map_err(|e| BusError::Device(format!("opening {path}: {e}")))?;
    SlcanBus::open(port, rate, Duration::from_secs(1))
}

/// A dongle on a serial port, opened at a bit rate.
pub struct SlcanBus<P: serialport::SerialPort> {
    port: P,
    split: LineSplitter,
    frames: VecDeque<CanFrame>,
    replies: VecDeque<Message>,
    /// Frames written whose answer has not been taken yet: the next answers are theirs.
    unanswered: usize,
    stats: SlcanStats,
}

impl<P: serialport::SerialPort> std::fmt::Debug for SlcanBus<P> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SlcanBus")
            .field("stats", &self.stats)
            .finish()
    }
}

fn io(e: std::io::Error) -> BusError {
    BusError::Device(e.to_string())
}

impl<P: serialport::SerialPort> SlcanBus<P> {
    /// Closes the channel (in case it was open), sets the bit rate and opens it, as
    /// `slcand -o -c -s8` does; each step must be acknowledged within `timeout`.
    pub fn open(port: P, rate: BitRate, timeout: Duration) -> Result<SlcanBus<P>, BusError> {
        let mut bus = SlcanBus {
            port,
            split: LineSplitter::new(),
            frames: VecDeque::new(),
            replies: VecDeque::new(),
            unanswered: 0,
            stats: SlcanStats::default(),
        };
        // A close on a closed channel may be refused: only the answer matters, not its value.
        bus.command(&Command::Close, timeout)?;
        for c in [Command::Speed(rate), Command::Open] {
            if !bus.command(&c, timeout)? {
                return Err(BusError::Device(format!("dongle refused {c:?}")));
            }
        }
        // Counters start with the open link (the close of a closed channel is refused).
        bus.stats = SlcanStats::default();
        Ok(bus)
    }

    /// Counters so far.
    pub fn stats(&self) -> SlcanStats {
        self.stats
    }

    /// Sends a command and waits for its answer: true for CR, false for BEL. The answers
    /// still owed to frames sent before are taken first, in order.
    pub fn command(&mut self, c: &Command, timeout: Duration) -> Result<bool, BusError> {
        let bytes = c.encode().map_err(|e| BusError::Device(e.to_string()))?;
        let deadline = Instant::now() + timeout;
        while self.unanswered > 0 {
            self.take_owed();
            if self.unanswered == 0 {
                break;
            }
            if Instant::now() >= deadline {
                return Err(BusError::Timeout);
            }
            self.pump(deadline)?;
        }
        self.port.write_all(&bytes).map_err(io)?;
        self.port.flush().map_err(io)?;
        loop {
            if let Some(m) = self.replies.pop_front() {
                return Ok(self.answer(m));
            }
            if Instant::now() >= deadline {
                return Err(BusError::Timeout);
            }
            self.pump(deadline)?;
        }
    }

    /// An answer: true for CR (or a transmit's acknowledgment), false for BEL (counted).
    fn answer(&mut self, m: Message) -> bool {
        if m == Message::Error {
            self.stats.refused += 1;
            return false;
        }
        true
    }

    /// Takes the answers already in that frames sent before are owed (a refusal counted).
    fn take_owed(&mut self) {
        while self.unanswered > 0 {
            let Some(m) = self.replies.pop_front() else {
                return;
            };
            self.unanswered -= 1;
            self.answer(m);
        }
    }

    /// Reads what the port has (waiting at most until `deadline`) and sorts it into frames
    /// and replies.
    fn pump(&mut self, deadline: Instant) -> Result<(), BusError> {
        let wait = deadline
            .saturating_duration_since(Instant::now())
            .max(Duration::from_millis(1));
        self.port
            .set_timeout(wait)
            .map_err(|e| BusError::Device(e.to_string()))?;
        let mut buf = [0u8; 256];
        let n = match self.port.read(&mut buf) {
            Ok(n) => n,
            // A timeout, or a signal (the caller checks its shutdown flag): nothing read.
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut | std::io::ErrorKind::Interrupted
                ) =>
            {
                0
            }
            Err(e) => return Err(io(e)),
        };
        for line in self.split.push(&buf[..n]) {
            match Message::parse(&line) {
                Ok(Message::Frame(f, _)) => {
                    self.stats.received += 1;
                    self.frames.push_back(f);
                }
                Ok(m) => self.replies.push_back(m),
                Err(_) => self.stats.malformed += 1,
            }
        }
        Ok(())
    }
}

impl<P: serialport::SerialPort> CanBus for SlcanBus<P> {
    /// Writes the frame and waits until `deadline` for the dongle's answer: a refusal
    /// (BEL, its queue full) is [`BusError::TxQueueFull`]. An answer that has not come by
    /// then is owed: the frame went to the dongle, it counts as sent (and late), and its
    /// answer is taken when it comes, before any later one.
    fn send(&mut self, frame: &CanFrame, deadline: Instant) -> Result<(), BusError> {
        self.take_owed();
        let bytes = Command::Transmit(*frame)
            .encode()
            .map_err(|e| BusError::Device(e.to_string()))?;
        self.port.write_all(&bytes).map_err(io)?;
        self.port.flush().map_err(io)?;
        self.unanswered += 1;
        let deadline = deadline.max(Instant::now() + Duration::from_millis(1));
        loop {
            if let Some(m) = self.replies.pop_front() {
                self.unanswered -= 1;
                let ok = self.answer(m);
                if self.unanswered == 0 {
                    if !ok {
                        return Err(BusError::TxQueueFull);
                    }
                    self.stats.sent += 1;
                    return Ok(());
                }
                continue;
            }
            if Instant::now() >= deadline {
                self.stats.sent += 1;
                self.stats.late += 1;
                return Ok(());
            }
            self.pump(deadline)?;
        }
    }

    fn recv(&mut self, deadline: Instant) -> Result<CanFrame, BusError> {
        loop {
            if let Some(f) = self.frames.pop_front() {
                return Ok(f);
            }
            if Instant::now() >= deadline {
                return Err(BusError::Timeout);
            }
            self.pump(deadline)?;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn a_late_acknowledgment_is_matched_to_its_frame_not_the_next_command() {
        // Under load the dongle's "z" came after the send's deadline: the frame was counted
        // as failed (though the dongle had it), and its late answer was taken for the next
        // command's. A late answer is owed to its frame and taken in order.
        let (host_end, mut dongle) = serialport::TTYPort::pair().expect("pty pair");
        // The dongle's answers to close, speed and open, already on the line.
        dongle.write_all(b"\r\r\r").unwrap();
        let mut host = SlcanBus::open(host_end, BitRate::M1, Duration::from_secs(1)).unwrap();
        let f = CanFrame::standard(0x123, &[1, 2]).unwrap();
        // No answer within the deadline: sent, and late.
        host.send(&f, Instant::now() + Duration::from_millis(5))
            .unwrap();
        assert_eq!((host.stats().sent, host.stats().late), (1, 1));
        // The late answer, then the next frame's: each to its own.
        dongle.write_all(b"z\rz\r").unwrap();
        host.send(&f, Instant::now() + Duration::from_secs(1))
            .unwrap();
        assert_eq!(host.stats().sent, 2);
        // A refused command is refused, not answered by a frame's "z".
        dongle.write_all(&[7]).unwrap();
        assert!(!host
            .command(&Command::Speed(BitRate::K500), Duration::from_secs(1))
            .unwrap());
        assert_eq!((host.stats().refused, host.stats().late), (1, 1));
    }
}
