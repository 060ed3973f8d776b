//! SLCAN (the Lawicel protocol of USB2CAN dongles), as a pure codec.
//!
//! The host writes ASCII commands ending in CR; the dongle answers CR (done) or BEL (error),
//! some commands with a value before the CR, and sends received frames as `t`/`T`/`r`/`R`
//! lines. [`Command`] is what the host sends, [`Message`] what the dongle sends back, and
//! [`LineSplitter`] cuts a byte stream into them, resynchronising after garbage.

use stride_can::CanFrame;

/// Why a line could not be understood.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SlcanError {
    /// The line does not follow the protocol.
    #[error("malformed SLCAN line {line:?}: {reason}")]
    Malformed {
        /// The offending line (without its CR).
        line: String,
        /// What is wrong.
        reason: &'static str,
    },
    /// A frame that SLCAN cannot carry.
    #[error("frame not encodable: {0}")]
    Frame(&'static str),
}

/// The standard bit rates of the `Sn` command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BitRate {
    /// S0: 10 kbit/s.
    K10,
    /// S1: 20 kbit/s.
    K20,
    /// S2: 50 kbit/s.
    K50,
    /// S3: 100 kbit/s.
    K100,
    /// S4: 125 kbit/s.
    K125,
    /// S5: 250 kbit/s.
    K250,
    /// S6: 500 kbit/s.
    K500,
    /// S7: 800 kbit/s (some firmware: 750).
    K800,
    /// S8: 1 Mbit/s.
    M1,
}

impl BitRate {
    const ALL: [BitRate; 9] = [
        BitRate::K10,
        BitRate::K20,
        BitRate::K50,
        BitRate::K100,
        BitRate::K125,
        BitRate::K250,
        BitRate::K500,
        BitRate::K800,
        BitRate::M1,
    ];

    /// The digit after `S`.
    pub fn digit(self) -> u8 {
        Self::ALL.iter().position(|b| *b == self).expect("listed") as u8
    }

    /// Bits per second.
    pub fn bits_per_second(self) -> u32 {
        [
            10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
        ][self.digit() as usize]
    }

    /// The rate with this many bits per second, if standard.
    pub fn from_bits_per_second(bps: u32) -> Option<BitRate> {
        Self::ALL.into_iter().find(|b| b.bits_per_second() == bps)
    }
}

/// A command from the host to the dongle.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Command {
    /// `Sn`: set a standard bit rate (channel closed).
    Speed(BitRate),
    /// `sxxyy`: set the SJA1000 bit timing registers BTR0/BTR1.
    Btr(u8, u8),
    /// `O`: open the channel.
    Open,
    /// `L`: open listen-only.
    Listen,
    /// `C`: close the channel.
    Close,
    /// `t`, `T`, `r`, `R`: transmit a frame.
    Transmit(CanFrame),
    /// `V`: hardware and firmware version.
    Version,
    /// `N`: serial number.
    Serial,
    /// `F`: status flags.
    Flags,
    /// `Zn`: timestamps off (false) or on.
    Timestamps(bool),
}

fn hex(n: u32, digits: usize) -> String {
    format!("{n:0digits$X}")
}

fn frame_line(f: &CanFrame) -> Result<String, SlcanError> {
    let mut s = String::with_capacity(27);
    match (f.is_extended(), f.is_remote()) {
        (false, false) => s.push('t'),
        (true, false) => s.push('T'),
        (false, true) => s.push('r'),
        (true, true) => s.push('R'),
    }
    s += &hex(f.raw_id(), if f.is_extended() { 8 } else { 3 });
    s += &f.dlc().to_string();
    for b in f.data() {
        s += &hex(*b as u32, 2);
    }
    Ok(s)
}

impl Command {
    /// The bytes to write, CR included.
    pub fn encode(&self) -> Result<Vec<u8>, SlcanError> {
        let body = match self {
            Command::Speed(b) => format!("S{}", b.digit()),
            Command::Btr(a, b) => format!("s{a:02X}{b:02X}"),
            Command::Open => "O".into(),
            Command::Listen => "L".into(),
            Command::Close => "C".into(),
            Command::Transmit(f) => frame_line(f)?,
            Command::Version => "V".into(),
            Command::Serial => "N".into(),
            Command::Flags => "F".into(),
            Command::Timestamps(on) => format!("Z{}", *on as u8),
        };
        let mut v = body.into_bytes();
        v.push(b'\r');
        Ok(v)
    }

    /// Reads a command line (without its CR), as a dongle does.
    pub fn parse(line: &[u8]) -> Result<Command, SlcanError> {
        let text = std::str::from_utf8(line).map_err(|_| malformed(line, "not ASCII"))?;
        let bad = |reason| malformed(line, reason);
        let mut chars = text.chars();
        let cmd = chars.next().ok_or_else(|| bad("empty line"))?;
        let rest = chars.as_str();
        Ok(match cmd {
            'S' => {
                let d: usize = rest.parse().map_err(|_| bad("bit rate digit expected"))?;
                Command::Speed(*BitRate::ALL.get(d).ok_or_else(|| bad("bit rate S0..S8"))?)
            }
            's' if rest.len() == 4 => Command::Btr(
                u8::from_str_radix(&rest[..2], 16).map_err(|_| bad("hex BTR0"))?,
                u8::from_str_radix(&rest[2..], 16).map_err(|_| bad("hex BTR1"))?,
            ),
            'O' if rest.is_empty() => Command::Open,
            'L' if rest.is_empty() => Command::Listen,
            'C' if rest.is_empty() => Command::Close,
            'V' if rest.is_empty() => Command::Version,
            'N' if rest.is_empty() => Command::Serial,
            'F' if rest.is_empty() => Command::Flags,
            'Z' if rest == "0" || rest == "1" => Command::Timestamps(rest == "1"),
            't' | 'T' | 'r' | 'R' => Command::Transmit(parse_frame(line)?.0),
            _ => return Err(bad("unknown command")),
        })
    }
}

fn malformed(line: &[u8], reason: &'static str) -> SlcanError {
    SlcanError::Malformed {
        line: String::from_utf8_lossy(line).into_owned(),
        reason,
    }
}

/// Parses a `t`/`T`/`r`/`R` line; returns the frame and the timestamp (ms, when `Z1`).
pub fn parse_frame(line: &[u8]) -> Result<(CanFrame, Option<u16>), SlcanError> {
    let bad = |reason| malformed(line, reason);
    let text = std::str::from_utf8(line).map_err(|_| bad("not ASCII"))?;
    let kind = text.chars().next().ok_or_else(|| bad("empty line"))?;
    let (extended, remote) = match kind {
        't' => (false, false),
        'T' => (true, false),
        'r' => (false, true),
        'R' => (true, true),
        _ => return Err(bad("not a frame")),
    };
    let id_len = if extended { 8 } else { 3 };
    if text.len() < 1 + id_len + 1 {
        return Err(bad("too short"));
    }
    let id = u32::from_str_radix(&text[1..1 + id_len], 16).map_err(|_| bad("hex identifier"))?;
    let dlc = text[1 + id_len..2 + id_len]
        .parse::<usize>()
        .ok()
        .filter(|d| *d <= 8)
        .ok_or_else(|| bad("length 0..8"))?;
    let mut pos = 2 + id_len;
    let mut data = Vec::with_capacity(dlc);
    if !remote {
        if text.len() < pos + 2 * dlc {
            return Err(bad("fewer data bytes than the length says"));
        }
        for i in 0..dlc {
            let b = u8::from_str_radix(&text[pos + 2 * i..pos + 2 * i + 2], 16)
                .map_err(|_| bad("hex data"))?;
            data.push(b);
        }
        pos += 2 * dlc;
    }
    let stamp = match text.len() - pos {
        0 => None,
        4 => Some(u16::from_str_radix(&text[pos..], 16).map_err(|_| bad("hex timestamp"))?),
        _ => return Err(bad("trailing characters")),
    };
    let id_frame = if extended {
        CanFrame::extended(id, &data)
    } else {
        u16::try_from(id)
            .map_err(|_| stride_can::FrameError::BadId(id))
            .and_then(|i| CanFrame::standard(i, &data))
    }
    .map_err(|_| bad("identifier out of range"))?;
    let frame = if remote {
        CanFrame::remote(id_frame.id(), dlc as u8).map_err(|_| bad("length 0..8"))?
    } else {
        id_frame
    };
    Ok((frame, stamp))
}

/// What the dongle sends to the host.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Message {
    /// CR alone: the last command succeeded.
    Ok,
    /// BEL: the last command failed.
    Error,
    /// `z` (a standard frame) or `Z` (an extended one) + CR: a transmit command was queued.
    Transmitted {
        /// True for `Z`, the answer to `T` and `R`.
        extended: bool,
    },
    /// A received frame, with its timestamp in ms when timestamps are on.
    Frame(CanFrame, Option<u16>),
    /// `Vhhff`: hardware and firmware versions.
    Version(String),
    /// `Nxxxx`: serial number.
    Serial(String),
    /// `Fxx`: status flags (bit 0 receive FIFO full, 1 transmit FIFO full, 2 error warning,
    /// 3 data overrun, 5 error passive, 6 arbitration lost, 7 bus error).
    Flags(u8),
}

impl Message {
    /// The bytes a dongle writes for this message (CR or BEL included).
    pub fn encode(&self) -> Result<Vec<u8>, SlcanError> {
        let body = match self {
            Message::Ok => String::new(),
            Message::Error => return Ok(vec![0x07]),
            Message::Transmitted { extended: false } => "z".into(),
            Message::Transmitted { extended: true } => "Z".into(),
            Message::Frame(f, stamp) => {
                let mut s = frame_line(f)?;
                if let Some(t) = stamp {
                    s += &hex(*t as u32, 4);
                }
                s
            }
            Message::Version(v) => format!("V{v}"),
            Message::Serial(n) => format!("N{n}"),
            Message::Flags(f) => format!("F{f:02X}"),
        };
        let mut v = body.into_bytes();
        v.push(b'\r');
        Ok(v)
    }

    /// Reads one dongle line (without its CR); BEL is passed as the one-byte line `[0x07]`.
    pub fn parse(line: &[u8]) -> Result<Message, SlcanError> {
        let bad = |reason| malformed(line, reason);
        match line.first() {
            None => Ok(Message::Ok),
            Some(0x07) => Ok(Message::Error),
            Some(b'z') if line.len() == 1 => Ok(Message::Transmitted { extended: false }),
            Some(b'Z') if line.len() == 1 => Ok(Message::Transmitted { extended: true }),
            Some(b't' | b'T' | b'r' | b'R') => {
                let (f, s) = parse_frame(line)?;
                Ok(Message::Frame(f, s))
            }
            Some(b'V') => Ok(Message::Version(
                String::from_utf8_lossy(&line[1..]).into_owned(),
            )),
            Some(b'N') => Ok(Message::Serial(
                String::from_utf8_lossy(&line[1..]).into_owned(),
            )),
            Some(b'F') if line.len() == 3 => {
                let t = std::str::from_utf8(&line[1..]).map_err(|_| bad("hex flags"))?;
                Ok(Message::Flags(
                    u8::from_str_radix(t, 16).map_err(|_| bad("hex flags"))?,
                ))
            }
            _ => Err(bad("unknown message")),
        }
    }
}

/// Cuts a byte stream into lines at CR (and BEL, which is a line of its own), so that a
/// corrupted line costs only itself. Lines longer than any valid one are dropped.
#[derive(Debug, Default, Clone)]
pub struct LineSplitter {
    buf: Vec<u8>,
    overlong: bool,
    dropped: u64,
}

/// The longest valid line: `T` + 8 + 1 + 16 + 4 (timestamp).
pub const MAX_LINE: usize = 30;

impl LineSplitter {
    /// An empty splitter.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feeds bytes; returns the complete lines (without CR; BEL as `[0x07]`).
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        for &b in bytes {
            match b {
                b'\r' => {
                    if self.overlong {
                        self.dropped += 1;
                        self.overlong = false;
                    } else {
                        out.push(std::mem::take(&mut self.buf));
                    }
                    self.buf.clear();
                }
                0x07 => {
                    if !self.buf.is_empty() || self.overlong {
                        self.dropped += 1;
                    }
                    self.buf.clear();
                    self.overlong = false;
                    out.push(vec![0x07]);
                }
                b'\n' => {}
                _ if self.buf.len() >= MAX_LINE => {
                    self.overlong = true;
                    self.buf.clear();
                }
                _ if !self.overlong => self.buf.push(b),
                _ => {}
            }
        }
        out
    }

    /// Lines dropped for being too long.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_commands() {
        // What `slcand -o -c -s8` writes: C, S8, O.
        let mut wire = Vec::new();
        for c in [Command::Close, Command::Speed(BitRate::M1), Command::Open] {
            wire.extend(c.encode().unwrap());
        }
        assert_eq!(wire, b"C\rS8\rO\r");
        // An SDO read of 0x6041 to node 1.
        let f = CanFrame::standard(0x601, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]).unwrap();
        assert_eq!(
            Command::Transmit(f).encode().unwrap(),
            b"t60184041600000000000\r"
        );
        let e = CanFrame::extended(0x1234567, &[0xde, 0xad]).unwrap();
        assert_eq!(Command::Transmit(e).encode().unwrap(), b"T012345672DEAD\r");
        assert_eq!(Command::Btr(0x00, 0x14).encode().unwrap(), b"s0014\r");
        assert_eq!(Command::Timestamps(true).encode().unwrap(), b"Z1\r");
        for c in [
            Command::Speed(BitRate::K500),
            Command::Btr(3, 0x1c),
            Command::Listen,
            Command::Version,
            Command::Serial,
            Command::Flags,
            Command::Timestamps(false),
            Command::Transmit(e),
        ] {
            let bytes = c.encode().unwrap();
            assert_eq!(Command::parse(&bytes[..bytes.len() - 1]).unwrap(), c);
        }
        assert_eq!(BitRate::from_bits_per_second(500_000), Some(BitRate::K500));
    }

    #[test]
    fn golden_replies() {
        assert_eq!(Message::parse(b"").unwrap(), Message::Ok);
        assert_eq!(Message::parse(&[7]).unwrap(), Message::Error);
        assert_eq!(
            Message::parse(b"V1013").unwrap(),
            Message::Version("1013".into())
        );
        assert_eq!(Message::parse(b"F04").unwrap(), Message::Flags(0x04));
        for extended in [false, true] {
            let m = Message::Transmitted { extended };
            let b = m.encode().unwrap();
            assert_eq!(b, if extended { b"Z\r" } else { b"z\r" });
            assert_eq!(Message::parse(&b[..1]).unwrap(), m);
        }
        let (f, t) = parse_frame(b"t58184B41600037020000").unwrap();
        assert_eq!((f.raw_id(), f.data()[4], t), (0x581, 0x37, None));
        let (f, t) = parse_frame(b"t7051051A2B").unwrap();
        assert_eq!((f.data(), t), (&[0x05][..], Some(0x1a2b)));
        let (r, _) = parse_frame(b"r7051").unwrap();
        assert!(r.is_remote() && r.dlc() == 1);
        let m = Message::Frame(f, Some(0x1a2b));
        assert_eq!(m.encode().unwrap(), b"t7051051A2B\r");
        for bad in [
            &b"t12"[..],
            b"t1239",
            b"t1232AA",
            b"x",
            b"t800000",
            b"T2000000000",
            b"t1230AAAAA",
        ] {
            assert!(
                Message::parse(bad).is_err(),
                "{:?}",
                String::from_utf8_lossy(bad)
            );
        }
    }

    #[test]
    fn splitter_resynchronises() {
        let mut s = LineSplitter::new();
        let mut lines = s.push(b"t12");
        lines.extend(s.push(b"3100\r\x07garbage-garbage-garbage-garbage-garbage\rt1230\r"));
        assert_eq!(lines.len(), 3);
        assert_eq!(lines[0], b"t123100");
        assert_eq!(lines[1], [7]);
        assert_eq!(lines[2], b"t1230");
        assert_eq!(s.dropped(), 1);
    }

    proptest::proptest! {
        #[test]
        fn any_bytes_split_and_parse_without_panic(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..200)) {
            let mut s = LineSplitter::new();
            for line in s.push(&bytes) {
                proptest::prop_assert!(line.len() <= MAX_LINE);
                let _ = Message::parse(&line);
                let _ = Command::parse(&line);
            }
        }

        #[test]
        fn frames_round_trip(id in 0u16..0x800, data in proptest::collection::vec(proptest::num::u8::ANY, 0..=8)) {
            let f = CanFrame::standard(id, &data).unwrap();
            let bytes = Command::Transmit(f).encode().unwrap();
            proptest::prop_assert_eq!(Command::parse(&bytes[..bytes.len() - 1]).unwrap(), Command::Transmit(f));
        }
    }
}
