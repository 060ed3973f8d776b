//! Dynamixel servos as pure codecs: Protocol 1.0 ([`v1`]) and 2.0 ([`v2`]) instruction and
//! status packets, both sides (host and servo), splitters that find packets in a byte stream
//! and resynchronise after garbage, and the control tables of the servo models as data
//! ([`models`]). No I/O: transports and the bridge live elsewhere.

pub mod models;
pub mod v1;
pub mod v2;

/// The broadcast id: every servo obeys, none answers (except to sync and bulk reads).
pub const BROADCAST: u8 = 0xfe;

/// The two Dynamixel protocols.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Deserialize, serde::Serialize)]
pub enum Protocol {
    /// Protocol 1.0: 8-bit addresses and lengths, additive checksum (AX, RX, MX with 1.0
    /// firmware).
    #[serde(rename = "1.0")]
    V1,
    /// Protocol 2.0: 16-bit addresses and lengths, CRC-16, byte stuffing (X, MX with 2.0
    /// firmware, P).
    #[serde(rename = "2.0")]
    V2,
}

/// An instruction to one servo or to many (the id travels beside it).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum Instruction {
    /// Is anyone there (and, in 2.0, which model and firmware)?
    Ping,
    /// Read `length` bytes of the control table from `address`.
    Read {
        /// Start address.
        address: u16,
        /// Bytes to read.
        length: u16,
    },
    /// Write `data` to the control table at `address`.
    Write {
        /// Start address.
        address: u16,
        /// Bytes to write.
        data: Vec<u8>,
    },
    /// Write, but only apply at the next [`Instruction::Action`].
    RegWrite {
        /// Start address.
        address: u16,
        /// Bytes to write.
        data: Vec<u8>,
    },
    /// Apply the registered writes.
    Action,
    /// Back to factory settings (2.0: `option` 0xFF all, 0x01 all but id, 0x02 all but id
    /// and baud rate; 1.0 has no option and sends none).
    FactoryReset {
        /// What to keep (2.0).
        option: u8,
    },
    /// Restart the servo.
    Reboot,
    /// 2.0: clear the multi-turn position or errors (`option` 0x01 position, 0x02 errors).
    Clear {
        /// What to clear.
        option: u8,
    },
    /// 2.0: read the same item from many servos; each answers with its own status packet.
    SyncRead {
        /// Start address.
        address: u16,
        /// Bytes per servo.
        length: u16,
        /// The servos, in the order they answer.
        ids: Vec<u8>,
    },
    /// 2.0: like [`Instruction::SyncRead`], answered with one packet for all.
    FastSyncRead {
        /// Start address.
        address: u16,
        /// Bytes per servo.
        length: u16,
        /// The servos, in the order they answer.
        ids: Vec<u8>,
    },
    /// Write the same item to many servos in one packet (always broadcast).
    SyncWrite {
        /// Start address.
        address: u16,
        /// Bytes per servo.
        length: u16,
        /// Each servo's id and its `length` bytes.
        data: Vec<(u8, Vec<u8>)>,
    },
    /// Read a different item from each servo; each answers with its own status packet.
    BulkRead {
        /// (id, address, length) per servo, in the order they answer.
        reads: Vec<(u8, u16, u16)>,
    },
    /// 2.0: write a different item to each servo.
    BulkWrite {
        /// (id, address, data) per servo.
        writes: Vec<(u8, u16, Vec<u8>)>,
    },
    /// 2.0: like [`Instruction::BulkRead`], answered with one packet for all.
    FastBulkRead {
        /// (id, address, length) per servo, in the order they answer.
        reads: Vec<(u8, u16, u16)>,
    },
}

/// A status packet: a servo's answer.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Status {
    /// The answering servo.
    pub id: u8,
    /// The error byte (1.0: [`v1::ErrorBits`]; 2.0: [`v2::StatusError`]).
    pub error: u8,
    /// The parameters (read data; 2.0 ping: model number and firmware).
    pub params: Vec<u8>,
}

/// Why bytes are not a packet, or a packet cannot be encoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CodecError {
    /// The bytes end before the packet does.
    #[error("truncated packet: {have} of {need} bytes")]
    Truncated {
        /// Bytes available.
        have: usize,
        /// Bytes the header announces.
        need: usize,
    },
    /// No packet header at the start.
    #[error("no packet header")]
    NoHeader,
    /// The checksum or CRC does not match.
    #[error("bad checksum: got {got:#06x}, computed {want:#06x}")]
    Checksum {
        /// In the packet.
        got: u16,
        /// Over its bytes.
        want: u16,
    },
    /// The length field is impossible.
    #[error("bad length {0}")]
    Length(usize),
    /// An instruction code this protocol does not have.
    #[error("unknown instruction {0:#04x}")]
    UnknownInstruction(u8),
    /// The parameters do not fit the instruction.
    #[error("bad parameters for instruction {instruction:#04x}: {why}")]
    Parameters {
        /// Instruction code.
        instruction: u8,
        /// What is wrong.
        why: &'static str,
    },
    /// The instruction or its values cannot be expressed in this protocol.
    #[error("{0}")]
    Unsupported(&'static str),
}

/// The result of feeding bytes to a splitter, one item at a time.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Split {
    /// A whole packet whose checksum holds, as it was on the wire (2.0: still stuffed).
    Packet(Vec<u8>),
    /// Bytes that were not part of any good packet (skipped), and why.
    Skipped {
        /// How many bytes were dropped.
        bytes: usize,
        /// Why: a bad checksum, an impossible length, or bytes before a header.
        error: CodecError,
        /// The id of a whole packet whose checksum failed (a servo of that id answers it
        /// with a checksum or CRC error).
        id: Option<u8>,
    },
}

/// What a splitter needs to know of a protocol's framing.
pub trait Framing {
    /// Bytes of the header up to and including the length field.
    const HEAD: usize;
    /// True when a header starts at `buf[i]` (`buf` holds at least `HEAD` bytes from `i`).
    fn header_at(buf: &[u8], i: usize) -> bool;
    /// The whole packet's length from its head, or `None` when the length is impossible.
    fn packet_len(head: &[u8]) -> Option<usize>;
    /// Checks a whole packet (header, length, checksum).
    fn check(packet: &[u8]) -> Result<(), CodecError>;
    /// The id of a packet whose header is at its start.
    fn id(packet: &[u8]) -> u8;
}

/// Finds packets in a byte stream: bytes before a header, and packets whose checksum fails,
/// are skipped (and counted), and the search goes on from the byte after the bad packet's
/// header, so a good packet hidden in garbage is not lost. While a packet is incomplete, a
/// whole good packet found after it wins (the first was garbage, or cut short).
#[derive(Debug)]
pub struct Splitter<F: Framing> {
    buf: Vec<u8>,
    stats: SplitStats,
    framing: std::marker::PhantomData<F>,
}

impl<F: Framing> Default for Splitter<F> {
    fn default() -> Self {
        Splitter {
            buf: Vec::new(),
            stats: SplitStats::default(),
            framing: std::marker::PhantomData,
        }
    }
}

impl<F: Framing> Splitter<F> {
    /// An empty splitter.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// Counters so far.
    pub fn stats(&self) -> SplitStats {
        self.stats
    }

    /// Bytes held, waiting for the rest of a packet.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }

    /// Drops what is held (after a timeout: a late reply must not be taken for the next).
    pub fn clear(&mut self) {
        self.buf.clear();
    }

    /// The next packet or skipped run, or `None` until more bytes arrive.
    pub fn next_item(&mut self) -> Option<Split> {
        let heads = self.buf.len().saturating_sub(F::HEAD - 1);
        let Some(start) = (0..heads).find(|&i| F::header_at(&self.buf, i)) else {
            // Keep the last bytes: they may begin a header.
            let drop = heads;
            return (drop > 0).then(|| self.skip(drop, CodecError::NoHeader));
        };
        if start > 0 {
            return Some(self.skip(start, CodecError::NoHeader));
        }
        let Some(need) = F::packet_len(&self.buf) else {
            return Some(self.skip(1, CodecError::Length(self.buf.len())));
        };
        if self.buf.len() < need {
            return self
                .later_packet()
                .map(|at| self.skip(at, CodecError::Truncated { have: at, need }));
        }
        match F::check(&self.buf[..need]) {
            Ok(()) => {
                self.stats.packets += 1;
                Some(Split::Packet(self.buf.drain(..need).collect()))
            }
            Err(e) => {
                self.stats.checksum_errors += 1;
                let id = F::id(&self.buf);
                let mut skipped = self.skip(1, e);
                if let Split::Skipped { id: at, .. } = &mut skipped {
                    *at = Some(id);
                }
                Some(skipped)
            }
        }
    }

    /// Where the first whole packet with a good checksum starts after position 0, if any.
    fn later_packet(&self) -> Option<usize> {
        let heads = self.buf.len().saturating_sub(F::HEAD - 1);
        (1..heads).find(|&i| {
            F::header_at(&self.buf, i)
                && F::packet_len(&self.buf[i..]).is_some_and(|need| {
                    self.buf.len() >= i + need && F::check(&self.buf[i..i + need]).is_ok()
                })
        })
    }

    fn skip(&mut self, n: usize, error: CodecError) -> Split {
        self.buf.drain(..n);
        self.stats.skipped_bytes += n as u64;
        Split::Skipped {
            bytes: n,
            error,
            id: None,
        }
    }
}

/// The names of the bits of `value` that `table` names.
pub(crate) fn bit_names(value: u8, table: &[(u8, &'static str)]) -> Vec<&'static str> {
    table
        .iter()
        .filter(|(b, _)| value & b != 0)
        .map(|(_, n)| *n)
        .collect()
}

/// Counters a splitter keeps (for the bridge's health report).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SplitStats {
    /// Good packets.
    pub packets: u64,
    /// Bytes skipped.
    pub skipped_bytes: u64,
    /// Packets dropped for a bad checksum.
    pub checksum_errors: u64,
}

/// Little-endian u16 from two bytes.
pub(crate) fn le16(b: &[u8]) -> u16 {
    u16::from_le_bytes([b[0], b[1]])
}

/// Time on the wire of `bytes` bytes at `baud` (10 bits a byte: start, 8 data, stop).
pub fn wire_time(bytes: usize, baud: u32) -> std::time::Duration {
    std::time::Duration::from_nanos((bytes as u64 * 10 * 1_000_000_000) / baud.max(1) as u64)
}

/// Bytes from hex pairs separated by spaces, as the manuals print packets (tests).
#[cfg(test)]
fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap())
        .collect()
}
