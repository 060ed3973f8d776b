//! Round-trip statistics for `stride-ping`, and the channel flags it shares with
//! `stride-echo`.

use std::time::Duration;

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
        )
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
}
