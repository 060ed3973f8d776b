//! `stride-ping` and `stride-echo`: their command lines and loops ([`Pinger`], [`Echoer`]),
//! the matching of echoes to the pings this process sent ([`Tally`]) and round-trip
//! statistics.

mod app;

pub use app::{EchoCli, Echoer, PingCli, Pinger};

use std::collections::HashMap;
use std::time::Duration;

use stride_lcmtypes::stride::PingT;

/// What an echo is to the pinger that receives it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Echo {
    /// The first echo of one of its own pings, after this round trip.
    Own(Duration),
    /// A further echo of a ping already answered (a second echo process).
    Duplicate,
    /// Not one of its pings (another pinger's, or a probe it never sent).
    Foreign,
}

/// The pings one pinger sent, told apart from everyone else's by a token in their header's
/// `frame` (`ping:<pid>:<start µs>`) and their sequence number; each is counted once.
#[derive(Debug, Clone)]
pub struct Tally {
    token: String,
    /// Sent and not yet answered: sequence number to send time (µs).
    waiting: HashMap<i64, i64>,
    answered: std::collections::HashSet<i64>,
    rtts: Vec<Duration>,
    duplicates: u64,
    foreign: u64,
    sent: u64,
}

impl Tally {
    /// A tally whose pings carry `token`.
    pub fn new(token: impl Into<String>) -> Tally {
        Tally {
            token: token.into(),
            waiting: HashMap::new(),
            answered: Default::default(),
            rtts: Vec::new(),
            duplicates: 0,
            foreign: 0,
            sent: 0,
        }
    }

    /// The token this pinger's pings carry.
    pub fn token(&self) -> &str {
        &self.token
    }

    /// Notes a ping as sent.
    pub fn sent(&mut self, ping: &PingT) {
        self.sent += 1;
        self.waiting.insert(ping.header.sequence, ping.sent_utime);
    }

    /// Takes an echo received at `recv_utime` (µs).
    pub fn echo(&mut self, m: &PingT, recv_utime: i64) -> Echo {
        if m.echoed_by.is_empty() || m.header.frame != self.token {
            self.foreign += 1;
            return Echo::Foreign;
        }
        let seq = m.header.sequence;
        match self.waiting.remove(&seq) {
            Some(sent) if sent == m.sent_utime => {
                self.answered.insert(seq);
                let rtt = Duration::from_micros(recv_utime.saturating_sub(sent).max(0) as u64);
                self.rtts.push(rtt);
                Echo::Own(rtt)
            }
            Some(sent) => {
                self.waiting.insert(seq, sent);
                self.foreign += 1;
                Echo::Foreign
            }
            None if self.answered.contains(&seq) => {
                self.duplicates += 1;
                Echo::Duplicate
            }
            None => {
                self.foreign += 1;
                Echo::Foreign
            }
        }
    }

    /// Pings sent so far.
    pub fn sent_count(&self) -> u64 {
        self.sent
    }

    /// True when every ping sent has its echo.
    pub fn complete(&self) -> bool {
        self.waiting.is_empty()
    }

    /// The statistics so far.
    pub fn summary(&self) -> Summary {
        let mut s = summarize(self.sent, self.rtts.clone());
        s.duplicates = self.duplicates;
        s.foreign = self.foreign;
        s
    }
}

/// The two channels of a ping and its echo (`--channel`, `--reply-channel`).
#[derive(clap::Args, Debug, Clone, PartialEq, Eq)]
pub struct PingChannels {
    /// Channel the pings travel on.
    #[arg(long, default_value = "STRIDE_PING")]
    pub channel: String,
    /// Channel the echoes travel on.
    #[arg(long, default_value = "STRIDE_PING_ECHO")]
    pub reply_channel: String,
}

/// Latency percentiles of a set of round trips.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    /// Pings sent.
    pub sent: u64,
    /// Echoes received.
    pub received: u64,
    /// Median round trip.
    pub p50: Duration,
    /// 90th percentile.
    pub p90: Duration,
    /// 99th percentile.
    pub p99: Duration,
    /// Largest round trip.
    pub max: Duration,
    /// Further echoes of pings already answered (more than one echo process).
    pub duplicates: u64,
    /// Echoes of other pingers' pings, not counted.
    pub foreign: u64,
}

/// Nearest-rank percentile `p` (0..=100) of sorted samples; zero when empty.
pub fn percentile(sorted: &[Duration], p: f64) -> Duration {
    if sorted.is_empty() {
        return Duration::ZERO;
    }
    let rank = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// Summarises round-trip samples.
pub fn summarize(sent: u64, mut rtts: Vec<Duration>) -> Summary {
    rtts.sort_unstable();
    Summary {
        sent,
        received: rtts.len() as u64,
        p50: percentile(&rtts, 50.0),
        p90: percentile(&rtts, 90.0),
        p99: percentile(&rtts, 99.0),
        max: rtts.last().copied().unwrap_or_default(),
        duplicates: 0,
        foreign: 0,
    }
}

impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let us = |d: Duration| d.as_secs_f64() * 1e6;
        write!(
            f,
            "{} sent, {} echoed ({} lost); round trip p50 {:.0} µs, p90 {:.0} µs, p99 {:.0} µs, max {:.0} µs",
            self.sent,
            self.received,
            self.sent.saturating_sub(self.received),
            us(self.p50),
            us(self.p90),
            us(self.p99),
            us(self.max)
        )?;
        if self.duplicates > 0 || self.foreign > 0 {
            write!(
                f,
                "; {} duplicate echoes, {} of other pings ignored",
                self.duplicates, self.foreign
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let v: Vec<Duration> = (1..=100).map(Duration::from_micros).collect();
        let s = summarize(100, v);
        assert_eq!(s.p50, Duration::from_micros(50));
        assert_eq!(s.p99, Duration::from_micros(99));
        assert_eq!(s.max, Duration::from_micros(100));
        assert_eq!(percentile(&[], 50.0), Duration::ZERO);
        assert!(s.to_string().contains("0 lost"));
    }

    fn ping(token: &str, seq: i64, sent: i64, by: &str) -> PingT {
        PingT {
            header: stride_lcmtypes::stride::HeaderT {
                utime: sent,
                sequence: seq,
                frame: token.into(),
            },
            sent_utime: sent,
            echoed_by: by.into(),
            payload_size: 0,
            payload: vec![],
        }
    }

    #[test]
    fn two_echoers_and_another_pinger_count_once() {
        let mut t = Tally::new("ping:1:0");
        for seq in 0..20 {
            t.sent(&ping("ping:1:0", seq, 1000 + seq, ""));
        }
        for seq in 0..20 {
            for by in ["echo-a", "echo-b"] {
                t.echo(&ping("ping:1:0", seq, 1000 + seq, by), 1100 + seq);
            }
            // Another pinger's ping with the same sequence number, echoed.
            assert_eq!(
                t.echo(&ping("ping:2:0", seq, 1000 + seq, "echo-a"), 1100 + seq),
                Echo::Foreign
            );
        }
        let s = t.summary();
        assert_eq!((s.sent, s.received), (20, 20));
        assert_eq!((s.duplicates, s.foreign), (20, 20));
        assert_eq!(s.p50, Duration::from_micros(100));
        assert!(t.complete());
        // The ping itself, heard on the echo channel unechoed, is no echo.
        assert_eq!(t.echo(&ping("ping:1:0", 3, 1003, ""), 0), Echo::Foreign);
    }
}
