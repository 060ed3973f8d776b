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
