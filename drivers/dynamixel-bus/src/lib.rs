//! The host side of a Dynamixel bus, generic over the serial [`Transport`]: each transaction
//! waits no longer than the wire time of what goes out and comes back, plus the servos' return
//! delays and a margin for the USB adapter; a lost reply is asked for again a bounded number
//! of times; a late reply is dropped rather than taken for the next one.

use std::time::{Duration, Instant};

use stride_dynamixel::{v1, v2, CodecError, Instruction, Protocol, Split, SplitStats, Status};
use stride_serial::{wire_time, Transport};

/// Why a transaction failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BusError {
    /// The serial line failed.
    #[error("serial line: {0}")]
    Io(String),
    /// No (whole, good) answer by the deadline, after every retry.
    #[error("servo {id}: no answer to {what} within {waited:?} ({tries} tries)")]
    Timeout {
        /// The servo.
        id: u8,
        /// The instruction.
        what: &'static str,
        /// The deadline of one try.
        waited: Duration,
        /// Tries made.
        tries: u32,
    },
    /// The instruction cannot be sent in this protocol.
    #[error("{0}")]
    Codec(#[from] CodecError),
    /// The servo refused the instruction (2.0 error number, or 1.0 instruction error bits).
    #[error("servo {id}: {what}")]
    Refused {
        /// The servo.
        id: u8,
        /// What it said.
        what: String,
    },
}

/// Settings of a bus.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BusConfig {
    /// The protocol of every servo on the bus.
    pub protocol: Protocol,
    /// The servos' return delay time (what the bridge sets; 0 is best).
    pub return_delay: Duration,
    /// Added to every deadline: the USB adapter's latency and the host's scheduling.
    pub margin: Duration,
    /// Tries after the first when a reply is lost.
    pub retries: u32,
}

impl BusConfig {
    /// Defaults for `protocol`: the factory return delay (500 µs), 3 ms of margin, 2 retries.
    pub fn new(protocol: Protocol) -> BusConfig {
        BusConfig {
            protocol,
            return_delay: Duration::from_micros(500),
            margin: Duration::from_millis(3),
            retries: 2,
        }
    }
}

/// Counters of a bus.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BusStats {
    /// Instruction packets sent (retries included).
    pub sent: u64,
    /// Tries that ended without every answer.
    pub timeouts: u64,
    /// Tries repeated.
    pub retries: u64,
    /// What the splitter dropped.
    pub split: SplitStats,
    /// Answers from servos not asked (late answers to an earlier try, or noise).
    pub unexpected: u64,
    /// Bytes dropped after a transaction that gave up, before the next (late answers).
    pub stale_bytes: u64,
}

/// One servo's answer in a multi-servo read.
pub type Reply = Result<Status, BusError>;

/// A Dynamixel bus on a serial transport.
pub struct Bus<T: Transport> {
    line: T,
    cfg: BusConfig,
    s1: v1::Splitter,
    s2: v2::Splitter,
    stats: BusStats,
    /// Tries each servo did not answer in time, by id.
    missed: [u32; 256],
    /// The last transaction gave up on an answer, which may still come: its tries.
    stale: Option<Tries>,
}

/// How long a transaction's tries took.
#[derive(Debug, Clone, Copy)]
struct Tries {
    per_try: Duration,
    tries: u32,
}

impl<T: Transport> std::fmt::Debug for Bus<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus")
            .field("cfg", &self.cfg)
            .field("stats", &self.stats())
            .finish()
    }
}

fn name(ins: &Instruction) -> &'static str {
    match ins {
        Instruction::Ping => "ping",
        Instruction::Read { .. } => "read",
        Instruction::Write { .. } => "write",
        Instruction::RegWrite { .. } => "reg write",
        Instruction::Action => "action",
        Instruction::FactoryReset { .. } => "factory reset",
        Instruction::Reboot => "reboot",
        Instruction::Clear { .. } => "clear",
        Instruction::SyncRead { .. } => "sync read",
        Instruction::FastSyncRead { .. } => "fast sync read",
        Instruction::SyncWrite { .. } => "sync write",
        Instruction::BulkRead { .. } => "bulk read",
        Instruction::BulkWrite { .. } => "bulk write",
        Instruction::FastBulkRead { .. } => "fast bulk read",
    }
}

impl<T: Transport> Bus<T> {
    /// A bus on `line`.
    pub fn new(line: T, cfg: BusConfig) -> Bus<T> {
        Bus {
            line,
            cfg,
            s1: v1::Splitter::new(),
            s2: v2::Splitter::new(),
            stats: BusStats::default(),
            missed: [0; 256],
            stale: None,
        }
    }

    /// Puts the bus on another line (the port came back after it vanished): what the old
    /// line held is dropped.
    pub fn replace_line(&mut self, line: T) {
        self.line = line;
        self.s1.clear();
        self.s2.clear();
        self.stale = None;
    }

    /// The settings.
    pub fn config(&self) -> &BusConfig {
        &self.cfg
    }

    /// Changes the expected return delay (after writing it to the servos).
    pub fn set_return_delay(&mut self, d: Duration) {
        self.cfg.return_delay = d;
    }

    /// Tries servo `id` did not answer in time, since the start (answers that came on a retry
    /// count their lost tries).
    pub fn missed(&self, id: u8) -> u32 {
        self.missed[id as usize]
    }

    /// Counters so far.
    pub fn stats(&self) -> BusStats {
        let split = match self.cfg.protocol {
            Protocol::V1 => self.s1.stats(),
            Protocol::V2 => self.s2.stats(),
        };
        BusStats {
            split,
            ..self.stats
        }
    }

    fn encode(&self, id: u8, ins: &Instruction) -> Result<Vec<u8>, BusError> {
        Ok(match self.cfg.protocol {
            Protocol::V1 => v1::encode_instruction(id, ins)?,
            Protocol::V2 => v2::encode_instruction(id, ins)?,
        })
    }

    /// The deadline of one try: the bytes out and back on the wire, a return delay per
    /// answer, and the margin.
    pub fn budget(&self, out_bytes: usize, in_bytes: usize, answers: usize) -> Duration {
        let baud = self.line.baud();
        wire_time(out_bytes + in_bytes, baud)
            + self.cfg.return_delay * answers as u32
            + self.cfg.margin
    }

    /// Status packet size carrying `params` bytes.
    fn status_len(&self, params: usize) -> usize {
        match self.cfg.protocol {
            Protocol::V1 => 6 + params,
            Protocol::V2 => 11 + params,
        }
    }

    /// The next good packet, or `None` when `deadline` passes.
    fn next_packet(&mut self, deadline: Instant) -> Result<Option<Vec<u8>>, BusError> {
        loop {
            let item = match self.cfg.protocol {
                Protocol::V1 => self.s1.next_item(),
                Protocol::V2 => self.s2.next_item(),
            };
            match item {
                Some(Split::Packet(p)) => return Ok(Some(p)),
                Some(Split::Skipped { .. }) => continue,
                None => {}
            }
            let mut buf = [0u8; 512];
            let n = self
                .line
                .read_until(&mut buf, deadline)
                .map_err(|e| BusError::Io(e.to_string()))?;
            if n == 0 {
                return Ok(None);
            }
            match self.cfg.protocol {
                Protocol::V1 => self.s1.push(&buf[..n]),
                Protocol::V2 => self.s2.push(&buf[..n]),
            }
        }
    }

    /// Sends `ins` to `id` and collects the status packets of `expect` (ids in answer order,
    /// with their parameter sizes), trying again while some are missing. Servos that never
    /// answered get [`BusError::Timeout`]; fast reads come back split per servo.
    pub fn transact(
        &mut self,
        id: u8,
        ins: &Instruction,
        expect: &[(u8, usize)],
    ) -> Result<Vec<Reply>, BusError> {
        let bytes = self.encode(id, ins)?;
        let fast = matches!(
            ins,
            Instruction::FastSyncRead { .. } | Instruction::FastBulkRead { .. }
        );
        let in_bytes = if fast {
            11 + expect.iter().map(|(_, n)| n + 4).sum::<usize>()
        } else {
            expect.iter().map(|(_, n)| self.status_len(*n)).sum()
        };
        let budget = self.budget(bytes.len(), in_bytes, expect.len());
        let mut got: Vec<Option<Status>> = vec![None; expect.len()];
        let mut tries = 0;
        // What arrives late from the last transaction is not taken for this one: its tries'
        // answers (one try's time apart) are let in and dropped until the line has been quiet
        // for a try's time and the margin, at most as long as all its tries took.
        if let Some(took) = self.stale.take() {
            self.forget();
            let window = took.per_try + self.cfg.margin;
            let give_up = Instant::now() + took.per_try * took.tries + self.cfg.margin;
            let mut buf = [0u8; 512];
            loop {
                let quiet = (Instant::now() + window).min(give_up);
                match self.line.read_until(&mut buf, quiet) {
                    Ok(n) if n > 0 && Instant::now() < give_up => {
                        self.stats.stale_bytes += n as u64;
                    }
                    _ => break,
                }
            }
        }
        loop {
            tries += 1;
            self.stats.sent += 1;
            self.line
                .write_all(&bytes)
                .map_err(|e| BusError::Io(e.to_string()))?;
            if expect.is_empty() {
                return Ok(Vec::new());
            }
            let deadline = Instant::now() + budget;
            while got.iter().any(Option::is_none) {
                let Some(p) = self.next_packet(deadline)? else {
                    break;
                };
                if fast {
                    let lengths: Vec<usize> = expect.iter().map(|(_, n)| *n).collect();
                    match v2::decode_fast_status(&p, &lengths) {
                        Ok(all) if all.iter().zip(expect).all(|(s, (i, _))| s.id == *i) => {
                            got = all.into_iter().map(Some).collect();
                        }
                        _ => self.stats.unexpected += 1,
                    }
                    continue;
                }
                let status = match self.cfg.protocol {
                    Protocol::V1 => v1::decode_status(&p),
                    Protocol::V2 => v2::decode_status(&p),
                };
                let Ok(s) = status else {
                    self.stats.unexpected += 1;
                    continue;
                };
                // Each answer is taken by the first expected servo of that id still missing
                // and of the right size; anything else is a late or stray answer.
                match expect
                    .iter()
                    .zip(got.iter_mut())
                    .find(|((i, n), g)| *i == s.id && g.is_none() && (s.params.len() == *n))
                {
                    Some((_, g)) => *g = Some(s),
                    None => self.stats.unexpected += 1,
                }
            }
            // A fast read that did not come back cannot say whose answer broke it: it is
            // counted for the bus, not for a servo.
            for ((i, _), g) in expect.iter().zip(&got) {
                if g.is_none() && !fast {
                    self.missed[*i as usize] += 1;
                }
            }
            if got.iter().all(Option::is_some) || tries > self.cfg.retries {
                break;
            }
            self.stats.timeouts += 1;
            self.stats.retries += 1;
            self.forget();
        }
        if got.iter().any(Option::is_none) {
            self.stats.timeouts += 1;
            self.stale = Some(Tries {
                per_try: budget,
                tries,
            });
        }
        Ok(got
            .into_iter()
            .zip(expect)
            .map(|(g, (i, _))| {
                g.ok_or(BusError::Timeout {
                    id: *i,
                    what: name(ins),
                    waited: budget,
                    tries,
                })
            })
            .collect())
    }

    /// Drops whatever the line and the splitter hold.
    fn forget(&mut self) {
        let _ = self.line.discard_input();
        match self.cfg.protocol {
            Protocol::V1 => self.s1.clear(),
            Protocol::V2 => self.s2.clear(),
        }
    }

    fn one(&mut self, id: u8, ins: &Instruction, params: usize) -> Result<Status, BusError> {
        let s = self
            .transact(id, ins, &[(id, params)])?
            .pop()
            .expect("one answer expected")?;
        self.refused(&s)?;
        Ok(s)
    }

    /// An error when the status says the servo refused the instruction (2.0: any error
    /// number; 1.0: range, checksum, instruction or angle limit bits).
    pub fn refused(&self, s: &Status) -> Result<(), BusError> {
        let what = match self.cfg.protocol {
            Protocol::V2 => v2::StatusError(s.error).error().map(str::to_owned),
            Protocol::V1 => {
                let bad = s.error
                    & (v1::ErrorBits::RANGE
                        | v1::ErrorBits::CHECKSUM
                        | v1::ErrorBits::INSTRUCTION
                        | v1::ErrorBits::ANGLE_LIMIT);
                (bad != 0).then(|| v1::ErrorBits(bad).names().join(", "))
            }
        };
        match what {
            Some(what) => Err(BusError::Refused { id: s.id, what }),
            None => Ok(()),
        }
    }

    /// Pings `id`; the model number when it answers (2.0 ping reports it; on 1.0 it is read).
    pub fn ping(&mut self, id: u8) -> Result<u16, BusError> {
        match self.cfg.protocol {
            Protocol::V2 => {
                let s = self.one(id, &Instruction::Ping, 3)?;
                Ok(u16::from_le_bytes([s.params[0], s.params[1]]))
            }
            Protocol::V1 => {
                self.one(id, &Instruction::Ping, 0)?;
                let d = self.read(id, 0, 2)?;
                Ok(u16::from_le_bytes([d[0], d[1]]))
            }
        }
    }

    /// Reads `length` bytes of `id`'s control table at `address`.
    pub fn read(&mut self, id: u8, address: u16, length: u16) -> Result<Vec<u8>, BusError> {
        Ok(self
            .one(id, &Instruction::Read { address, length }, length as usize)?
            .params)
    }

    /// Writes `data` to `id`'s control table at `address` and waits for the status.
    pub fn write(&mut self, id: u8, address: u16, data: &[u8]) -> Result<(), BusError> {
        let ins = Instruction::Write {
            address,
            data: data.to_vec(),
        };
        self.one(id, &ins, 0).map(|_| ())
    }

    /// One sync write (no answers).
    pub fn sync_write(
        &mut self,
        address: u16,
        length: u16,
        data: Vec<(u8, Vec<u8>)>,
    ) -> Result<(), BusError> {
        let ins = Instruction::SyncWrite {
            address,
            length,
            data,
        };
        self.transact(stride_dynamixel::BROADCAST, &ins, &[])
            .map(|_| ())
    }

    /// Reads the same item of many servos: 2.0 sync read (`fast`: fast sync read), 1.0 bulk
    /// read when `bulk` (MX series), else one read per servo.
    pub fn read_many(
        &mut self,
        address: u16,
        length: u16,
        ids: &[u8],
        how: ReadMany,
    ) -> Result<Vec<Reply>, BusError> {
        let expect: Vec<(u8, usize)> = ids.iter().map(|&i| (i, length as usize)).collect();
        let b = stride_dynamixel::BROADCAST;
        match how {
            ReadMany::Sync => {
                let ins = Instruction::SyncRead {
                    address,
                    length,
                    ids: ids.to_vec(),
                };
                self.transact(b, &ins, &expect)
            }
            ReadMany::FastSync => {
                let ins = Instruction::FastSyncRead {
                    address,
                    length,
                    ids: ids.to_vec(),
                };
                self.transact(b, &ins, &expect)
            }
            ReadMany::Bulk => {
                let ins = Instruction::BulkRead {
                    reads: ids.iter().map(|&i| (i, address, length)).collect(),
                };
                self.transact(b, &ins, &expect)
            }
            ReadMany::OneByOne => Ok(ids
                .iter()
                .map(|&i| {
                    let ins = Instruction::Read { address, length };
                    self.transact(i, &ins, &[(i, length as usize)])
                        .map(|mut v| v.pop().expect("one answer"))
                        .unwrap_or_else(Err)
                })
                .collect()),
        }
    }

    /// Which servos of `ids` answer a ping, with their model numbers. Each ping waits its wire
    /// time plus `wait` (a scan is no hurry: give slow adapters their time), and is asked once
    /// more before the servo is taken for absent.
    pub fn scan(&mut self, ids: impl IntoIterator<Item = u8>, wait: Duration) -> Vec<(u8, u16)> {
        let saved = self.cfg;
        self.cfg.margin = wait;
        self.cfg.retries = 1;
        let found = ids
            .into_iter()
            .filter_map(|i| self.ping(i).ok().map(|m| (i, m)))
            .collect();
        self.cfg = saved;
        found
    }
}

/// How [`Bus::read_many`] reads many servos.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReadMany {
    /// 2.0 sync read: one instruction, one status packet per servo.
    Sync,
    /// 2.0 fast sync read: one instruction, one packet for all.
    FastSync,
    /// 1.0 bulk read (MX series): one instruction, one status packet per servo.
    Bulk,
    /// One read instruction per servo (AX series on 1.0).
    OneByOne,
}
