//! The host side of a session with one of Archie's Arduino joint-controller boards (the
//! protocol is `stride-link`'s), over any serial [`Transport`]: the handshake (sent
//! again until the board answers, which covers the reset that opening its port causes), frames
//! out with the host's sequence numbers, and the board's messages in.

use std::io;
use std::time::{Duration, Instant};

use stride_serial::Transport;

use stride_link::{BoardInfo, Decoder, DecoderStats, Frame, Message, MAJOR, MINOR};

/// Why a session failed.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// The line failed (the port vanished, for one).
    #[error("serial line: {0}")]
    Io(#[from] io::Error),
    /// No HELLO_ACK in time.
    #[error("the board did not answer the handshake within {0:?}")]
    NoAnswer(Duration),
    /// The board speaks another major version.
    #[error("the board speaks link version {major}.{minor}, this host {MAJOR}.{MINOR}")]
    Version {
        /// Its major version.
        major: u8,
        /// Its minor version.
        minor: u8,
    },
}

/// A session with one board.
pub struct Session<T: Transport> {
    line: T,
    dec: Decoder,
    seq: u8,
    board: Option<BoardInfo>,
    nonce: u32,
    inbox: Vec<Message>,
}

impl<T: Transport> std::fmt::Debug for Session<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session")
            .field("board", &self.board)
            .field("stats", &self.dec.stats())
            .finish()
    }
}

impl<T: Transport> Session<T> {
    /// A session on `line` (no handshake yet).
    pub fn new(line: T) -> Session<T> {
        let nonce = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(1, |d| d.subsec_nanos() ^ d.as_secs() as u32);
        Session {
            line,
            dec: Decoder::new(),
            seq: 0,
            board: None,
            nonce,
            inbox: Vec::new(),
        }
    }

    /// The board, once the handshake is done.
    pub fn board(&self) -> Option<&BoardInfo> {
        self.board.as_ref()
    }

    /// Frames received, dropped and lost so far.
    pub fn stats(&self) -> DecoderStats {
        self.dec.stats()
    }

    /// Sends `m` with the next sequence number; returns that number.
    pub fn send(&mut self, m: &Message) -> io::Result<u8> {
        let seq = self.seq;
        self.seq = self.seq.wrapping_add(1);
        let bytes = m.frame(seq).encode().map_err(io::Error::other)?;
        self.line.write_all(&bytes)?;
        Ok(seq)
    }

    /// Sends HELLO (again every `every`) until the board's HELLO_ACK with our nonce, or
    /// `timeout`. Messages of the old session received meanwhile are dropped.
    pub fn handshake(
        &mut self,
        timeout: Duration,
        every: Duration,
    ) -> Result<BoardInfo, SessionError> {
        let deadline = Instant::now() + timeout;
        self.nonce = self.nonce.wrapping_add(1);
        self.board = None;
        self.seq = 0;
        while Instant::now() < deadline {
            self.send(&Message::Hello {
                major: MAJOR,
                minor: MINOR,
                nonce: self.nonce,
            })?;
            let until = (Instant::now() + every).min(deadline);
            while Instant::now() < until {
                for m in self.receive(until)? {
                    match m {
                        Message::HelloAck(b) if b.nonce == self.nonce => {
                            if b.major != MAJOR {
                                return Err(SessionError::Version {
                                    major: b.major,
                                    minor: b.minor,
                                });
                            }
                            self.dec.reset_sequence();
                            self.inbox.clear();
                            self.board = Some(b.clone());
                            return Ok(b);
                        }
                        Message::Nack {
                            reason: stride_link::nack::VERSION,
                            ..
                        } => {
                            return Err(SessionError::Version { major: 0, minor: 0 });
                        }
                        _ => {}
                    }
                }
            }
        }
        Err(SessionError::NoAnswer(timeout))
    }

    /// The board's messages that arrive until `deadline` (returns at the first batch).
    pub fn receive(&mut self, deadline: Instant) -> io::Result<Vec<Message>> {
        if !self.inbox.is_empty() {
            return Ok(std::mem::take(&mut self.inbox));
        }
        let mut buf = [0u8; 1024];
        loop {
            let n = self.line.read_until(&mut buf, deadline)?;
            if n == 0 {
                return Ok(Vec::new());
            }
            let msgs: Vec<Message> = self
                .dec
                .push(&buf[..n])
                .into_iter()
                .filter_map(|r| r.ok().and_then(|f: Frame| Message::parse(&f).ok()))
                .collect();
            if !msgs.is_empty() || Instant::now() >= deadline {
                return Ok(msgs);
            }
        }
    }
}

/// What a board master watches and when it acts.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardConfig {
    /// A heartbeat goes out when no command has for this long (the board brakes its joints
    /// when neither comes within its own watchdog).
    pub heartbeat: Duration,
    /// This long without a frame from the board (it streams its state at 100 Hz) is a lost
    /// link.
    pub silence: Duration,
    /// A joint drawing more current than this (A) is braked by the host, once until it draws
    /// less again.
    pub current_limit_a: f64,
    /// The joints (board indices) the host watches.
    pub joints: Vec<u8>,
}

impl Default for BoardConfig {
    /// A 50 ms heartbeat, 500 ms of silence, 6 A.
    fn default() -> Self {
        BoardConfig {
            heartbeat: Duration::from_millis(50),
            silence: Duration::from_millis(500),
            current_limit_a: 6.0,
            joints: (0..8).collect(),
        }
    }
}

/// What the board said, or what the host did, in one turn.
#[derive(Debug, Clone, PartialEq)]
pub enum BoardEvent {
    /// A message from the board (states, IMU samples, faults, refusals).
    Message(Message),
    /// The host braked a joint drawing `current_a` over the limit.
    Braked {
        /// Board index.
        joint: u8,
        /// What it drew, A.
        current_a: f64,
    },
}

/// The master of one board, peer of the Elmo drives' `Master` and the Dynamixel `Chain`: a
/// session after its handshake, commands out, a heartbeat when no command went out, the
/// board's silence taken as a lost link, and the host's own current brake.
pub struct Board<T: Transport> {
    session: Session<T>,
    cfg: BoardConfig,
    last_sent: Instant,
    last_heard: Instant,
    braked: [bool; 8],
}

impl<T: Transport> Board<T> {
    /// The handshake on `line` (HELLO again every `every`, up to `timeout`), then the master.
    pub fn connect(
        line: T,
        cfg: BoardConfig,
        timeout: Duration,
        every: Duration,
    ) -> Result<(Board<T>, BoardInfo), SessionError> {
        let mut session = Session::new(line);
        let info = session.handshake(timeout, every)?;
        let now = Instant::now();
        Ok((
            Board {
                session,
                cfg,
                last_sent: now,
                last_heard: now,
                braked: [false; 8],
            },
            info,
        ))
    }

    /// The board, as its handshake described it.
    pub fn info(&self) -> Option<&BoardInfo> {
        self.session.board()
    }

    /// Frames received, dropped and lost so far.
    pub fn stats(&self) -> DecoderStats {
        self.session.stats()
    }

    /// Sends checked set-points at `now`.
    pub fn command(
        &mut self,
        joints: Vec<stride_link::JointCommand>,
        now: Instant,
    ) -> io::Result<()> {
        self.session.send(&Message::Command(joints))?;
        self.last_sent = now;
        Ok(())
    }

    /// One turn at `now` (`uptime_ms` the heartbeat's count): a heartbeat if no command went
    /// out for [`BoardConfig::heartbeat`], the board's frames until `until`, the host's brake
    /// on joints over the current limit. An error for a failed line or a silent board (the
    /// session is then lost).
    pub fn pump(
        &mut self,
        now: Instant,
        uptime_ms: u32,
        until: Instant,
    ) -> io::Result<Vec<BoardEvent>> {
        if now.saturating_duration_since(self.last_sent) >= self.cfg.heartbeat {
            self.session.send(&Message::Heartbeat(uptime_ms))?;
            self.last_sent = now;
        }
        let msgs = self.session.receive(until)?;
        if !msgs.is_empty() {
            self.last_heard = now;
        } else if now.saturating_duration_since(self.last_heard) > self.cfg.silence {
            return Err(io::Error::new(
                io::ErrorKind::TimedOut,
                format!("the board has been silent for {:?}", self.cfg.silence),
            ));
        }
        let mut events = Vec::with_capacity(msgs.len());
        let mut brake = Vec::new();
        for m in msgs {
            let mut braked = Vec::new();
            if let Message::State { joints, .. } = &m {
                for &i in &self.cfg.joints {
                    let Some(st) = joints.get(i as usize) else {
                        continue;
                    };
                    let slot = &mut self.braked[i as usize % 8];
                    let over = st.current_a() > self.cfg.current_limit_a;
                    if over && !*slot {
                        *slot = true;
                        brake.push(stride_link::JointCommand::brake(i));
                        braked.push(BoardEvent::Braked {
                            joint: i,
                            current_a: st.current_a(),
                        });
                    } else if !over {
                        *slot = false;
                    }
                }
            }
            events.push(BoardEvent::Message(m));
            events.append(&mut braked);
        }
        if !brake.is_empty() {
            self.session.send(&Message::Command(brake))?;
        }
        Ok(events)
    }
}
