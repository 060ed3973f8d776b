//! Serial transports for the motor buses (Dynamixel TTL/RS-485, the Arduino link): one trait
//! with deadlines ([`Transport`]), implemented for every `serialport` port (real devices and
//! pseudo-terminals), [`Paced`], which holds writes to the time they take on the wire at a
//! baud rate (so a fake device on a pty answers as slowly as the real one), and [`Buffered`],
//! the same line behind a transmit buffer, as a host's serial driver has.
//!
//! Transports know no protocol: they move bytes, and say when a deadline passed.

use std::collections::VecDeque;
use std::io;
use std::time::{Duration, Instant};

/// A byte stream to a device, read with deadlines.
pub trait Transport: Send {
    /// Writes all of `bytes` (and flushes them out).
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;

    /// Reads what is there into `buf`, waiting until `deadline` for the first byte; `Ok(0)`
    /// when the deadline passed with nothing.
    fn read_until(&mut self, buf: &mut [u8], deadline: Instant) -> io::Result<usize>;

    /// Drops bytes received and not yet read (a late answer must not be taken for the next).
    fn discard_input(&mut self) -> io::Result<()>;

    /// The line's baud rate (wire times are computed from it).
    fn baud(&self) -> u32;
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        (**self).write_all(bytes)
    }
    fn read_until(&mut self, buf: &mut [u8], deadline: Instant) -> io::Result<usize> {
        (**self).read_until(buf, deadline)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        (**self).discard_input()
    }
    fn baud(&self) -> u32 {
        (**self).baud()
    }
}

/// Time on the wire of `bytes` bytes at `baud`, 10 bits a byte (start, 8 data, stop).
pub fn wire_time(bytes: usize, baud: u32) -> Duration {
    Duration::from_nanos((bytes as u64 * 10 * 1_000_000_000) / baud.max(1) as u64)
}

/// A `serialport` port (a device or a pty end) as a [`Transport`].
#[derive(Debug)]
pub struct Port<P: serialport::SerialPort> {
    port: P,
    baud: u32,
}

impl<P: serialport::SerialPort> Port<P> {
    /// Wraps `port`; `baud` is the line's rate (a pty has none of its own).
    pub fn new(port: P, baud: u32) -> Port<P> {
        Port { port, baud }
    }

    /// The port itself.
    pub fn get_mut(&mut self) -> &mut P {
        &mut self.port
    }

    /// Gives the port back.
    pub fn into_inner(self) -> P {
        self.port
    }
}

impl<P: serialport::SerialPort + Send> Transport for Port<P> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.write_all(bytes)?;
        self.port.flush()
    }

    fn read_until(&mut self, buf: &mut [u8], deadline: Instant) -> io::Result<usize> {
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            // serialport's read times out after the port's timeout; a zero timeout polls.
            self.port
                .set_timeout(left.max(Duration::from_micros(100)))
                .map_err(io::Error::other)?;
            match self.port.read(buf) {
                Ok(0) => {}
                Ok(n) => return Ok(n),
                Err(e) if e.kind() == io::ErrorKind::TimedOut => {}
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
            if Instant::now() >= deadline {
                return Ok(0);
            }
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.port
            .clear(serialport::ClearBuffer::Input)
            .map_err(io::Error::other)?;
        // A pty has no input queue to clear in the driver: read what is there.
        let mut sink = [0u8; 256];
        while self.read_until(&mut sink, Instant::now())? > 0 {}
        Ok(())
    }

    fn baud(&self) -> u32 {
        self.baud
    }
}

/// Opens a serial device at `baud` for a motor bus (8N1, no flow control).
pub fn open(path: &str, baud: u32) -> io::Result<Port<serialport::TTYPort>> {
    let port = serialport::new(path, baud)
        .timeout(Duration::from_millis(10))
        .open_native()
        .map_err(|e| io::Error::other(format!("opening {path} at {baud} baud: {e}")))?;
    Ok(Port::new(port, baud))
}

/// A pair of connected pseudo-terminal ends at a nominal `baud`: (host end, device end).
pub fn pty_pair(baud: u32) -> io::Result<(Port<serialport::TTYPort>, Port<serialport::TTYPort>)> {
    let (a, b) = serialport::TTYPort::pair().map_err(io::Error::other)?;
    Ok((Port::new(a, baud), Port::new(b, baud)))
}

/// Holds each write until the bytes would have left a real line at the transport's baud rate
/// (writes queue behind each other as on a UART).
#[derive(Debug)]
pub struct Paced<T: Transport> {
    inner: T,
    line_free: Instant,
}

impl<T: Transport> Paced<T> {
    /// Paces `inner` at its baud rate.
    pub fn new(inner: T) -> Paced<T> {
        Paced {
            inner,
            line_free: Instant::now(),
        }
    }
}

impl<T: Transport> Transport for Paced<T> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        let start = self.line_free.max(Instant::now());
        self.line_free = start + wire_time(bytes.len(), self.inner.baud());
        sleep_until(self.line_free);
        self.inner.write_all(bytes)
    }

    fn read_until(&mut self, buf: &mut [u8], deadline: Instant) -> io::Result<usize> {
        self.inner.read_until(buf, deadline)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.inner.discard_input()
    }

    fn baud(&self) -> u32 {
        self.inner.baud()
    }
}

/// A line paced at its baud rate behind a transmit buffer of `capacity` bytes, as a host's
/// serial driver has (Linux's holds a page): a write returns once its bytes fit in the buffer
/// and they leave back to back, so a host that makes its next frame while one is on the line
/// keeps the line busy. Each write reaches the other end when its last byte would have left
/// the line, as with [`Paced`]: handed over on the next call at or after that time (a read
/// waits for it), and all that is left when the transport is dropped.
#[derive(Debug)]
pub struct Buffered<T: Transport> {
    inner: T,
    capacity: usize,
    line_free: Instant,
    /// Writes not yet handed over, with when they have left the line.
    queue: VecDeque<(Instant, Vec<u8>)>,
    queued: usize,
}

impl<T: Transport> Buffered<T> {
    /// Paces `inner` at its baud rate behind a buffer of `capacity` bytes.
    pub fn new(inner: T, capacity: usize) -> Buffered<T> {
        Buffered {
            inner,
            capacity,
            line_free: Instant::now(),
            queue: VecDeque::new(),
            queued: 0,
        }
    }

    /// Hands over the writes that have left the line by `now`.
    fn deliver(&mut self, now: Instant) -> io::Result<()> {
        while self.queue.front().is_some_and(|(due, _)| *due <= now) {
            let (_, bytes) = self.queue.pop_front().expect("a write");
            self.queued -= bytes.len();
            self.inner.write_all(&bytes)?;
        }
        Ok(())
    }
}

impl<T: Transport> Transport for Buffered<T> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.deliver(Instant::now())?;
        // Room in the buffer: wait for the oldest writes to leave.
        while self.queued + bytes.len() > self.capacity {
            let Some(&(due, _)) = self.queue.front() else {
                break;
            };
            sleep_until(due);
            self.deliver(Instant::now())?;
        }
        let start = self.line_free.max(Instant::now());
        self.line_free = start + wire_time(bytes.len(), self.inner.baud());
        self.queue.push_back((self.line_free, bytes.to_vec()));
        self.queued += bytes.len();
        Ok(())
    }

    fn read_until(&mut self, buf: &mut [u8], deadline: Instant) -> io::Result<usize> {
        loop {
            self.deliver(Instant::now())?;
            // Wake to hand over the next write when its time comes.
            let until = self
                .queue
                .front()
                .map_or(deadline, |&(due, _)| due.min(deadline));
            let n = self.inner.read_until(buf, until)?;
            if n > 0 || Instant::now() >= deadline {
                return Ok(n);
            }
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.inner.discard_input()
    }

    fn baud(&self) -> u32 {
        self.inner.baud()
    }
}

impl<T: Transport> Drop for Buffered<T> {
    fn drop(&mut self) {
        while let Some(&(due, _)) = self.queue.front() {
            sleep_until(due);
            if self.deliver(due).is_err() {
                return;
            }
        }
    }
}

/// Sleeps until `t` (the last stretch spinning, for sub-millisecond accuracy).
pub fn sleep_until(t: Instant) {
    loop {
        let now = Instant::now();
        if now >= t {
            return;
        }
        let left = t - now;
        if left > Duration::from_micros(200) {
            std::thread::sleep(left - Duration::from_micros(150));
        } else {
            std::hint::spin_loop();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pty_moves_bytes_with_deadlines_and_pacing() {
        let (mut host, dev) = pty_pair(115_200).unwrap();
        let mut dev = Paced::new(dev);
        // Nothing there: the deadline passes with 0 bytes.
        let mut buf = [0u8; 64];
        let t = Instant::now();
        assert_eq!(
            host.read_until(&mut buf, t + Duration::from_millis(20))
                .unwrap(),
            0
        );
        assert!(t.elapsed() >= Duration::from_millis(20));
        // 100 bytes at 115 200 baud take 8.7 ms on the wire.
        let t = Instant::now();
        dev.write_all(&[0x55; 100]).unwrap();
        assert!(t.elapsed() >= wire_time(100, 115_200));
        let mut got = 0;
        while got < 100 {
            let n = host
                .read_until(&mut buf, Instant::now() + Duration::from_secs(1))
                .unwrap();
            assert!(n > 0);
            got += n;
        }
        assert_eq!(wire_time(100, 1_000_000), Duration::from_millis(1));
        dev.write_all(&[1, 2, 3]).unwrap();
        std::thread::sleep(Duration::from_millis(5));
        host.discard_input().unwrap();
        assert_eq!(
            host.read_until(&mut buf, Instant::now() + Duration::from_millis(5))
                .unwrap(),
            0
        );
    }

    #[test]
    fn a_buffered_line_sends_back_to_back_and_delivers_at_the_wire_time() {
        let (host, mut dev) = pty_pair(115_200).unwrap();
        let mut buf = [0u8; 512];
        let read_all = |dev: &mut Port<serialport::TTYPort>, want: usize, buf: &mut [u8]| {
            let mut got = 0;
            while got < want {
                let n = dev
                    .read_until(&mut buf[got..], Instant::now() + Duration::from_secs(2))
                    .unwrap();
                assert!(n > 0, "{got} of {want} bytes");
                got += n;
            }
        };
        // Three frames of 100 bytes into a page-sized buffer: the last byte reaches the other
        // end no sooner than three frames' wire time after the first write.
        let mut host = Buffered::new(host, 4096);
        let t = Instant::now();
        for k in 0..3u8 {
            host.write_all(&[k; 100]).unwrap();
        }
        // Nothing has left the line yet: a read on the host's side hands the frames over as
        // their time comes.
        let mut hbuf = [0u8; 8];
        while !host.queue.is_empty() {
            let _ = host.read_until(&mut hbuf, Instant::now() + Duration::from_millis(5));
        }
        read_all(&mut dev, 300, &mut buf);
        assert!(t.elapsed() >= 3 * wire_time(100, 115_200));
        assert!(buf[..100].iter().all(|&b| b == 0) && buf[200..300].iter().all(|&b| b == 2));
        // A buffer of one frame: the second write waits for the first to leave. (The pty's
        // end stays open in `keep` when the transport is dropped.)
        drop(host);
        let (host, mut dev) = pty_pair(115_200).unwrap();
        let keep = host.port.try_clone_native().unwrap();
        let mut host = Buffered::new(host, 100);
        let t = Instant::now();
        host.write_all(&[7; 100]).unwrap();
        host.write_all(&[8; 100]).unwrap();
        assert!(t.elapsed() >= wire_time(100, 115_200));
        // Dropped, it hands over what is left.
        drop(host);
        read_all(&mut dev, 200, &mut buf);
        assert!(buf[100..200].iter().all(|&b| b == 8));
        drop(keep);
    }
}

/// A serial line by name, as configuration gives it: `sim` (a fake device on a pty in this
/// process) or the path of a device (`/dev/ttyUSB0`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LineSpec {
    /// A fake device on a pty, made by the app.
    Sim,
    /// A serial device.
    Device(String),
}

impl std::str::FromStr for LineSpec {
    type Err = String;

    fn from_str(s: &str) -> Result<LineSpec, String> {
        match s {
            "" => Err("the port is empty: give \"sim\" or a device such as /dev/ttyUSB0".into()),
            "sim" => Ok(LineSpec::Sim),
            path => Ok(LineSpec::Device(path.to_owned())),
        }
    }
}

impl std::fmt::Display for LineSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LineSpec::Sim => f.write_str("sim"),
            LineSpec::Device(p) => f.write_str(p),
        }
    }
}

impl<'de> serde::Deserialize<'de> for LineSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<LineSpec, D::Error> {
        String::deserialize(d)?
            .parse()
            .map_err(serde::de::Error::custom)
    }
}

impl LineSpec {
    /// Opens the device at `baud` (a `sim` line is made by its app, with its fake).
    pub fn open_device(&self, baud: u32) -> io::Result<Port<serialport::TTYPort>> {
        match self {
            LineSpec::Device(path) => open(path, baud),
            LineSpec::Sim => Err(io::Error::other("the sim line is not a device")),
        }
    }
}
