//! Per-channel statistics: events, bytes, rate, bandwidth, type.

use std::collections::BTreeMap;

/// What one channel of a log holds.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelSummary {
    /// The channel.
    pub channel: String,
    /// Events on it.
    pub count: u64,
    /// Payload bytes on it.
    pub bytes: u64,
    /// First and last timestamps, µs since the epoch.
    pub first_utime: i64,
    /// Last timestamp.
    pub last_utime: i64,
    /// The LCM type, recognised by fingerprint ("?" when unknown, several joined by "|").
    pub type_name: String,
}

impl ChannelSummary {
    /// Mean bandwidth over the channel's own span, bytes per second.
    pub fn bytes_per_s(&self) -> f64 {
        let span = (self.last_utime - self.first_utime) as f64 / 1e6;
        if self.count < 2 || span <= 0.0 {
            0.0
        } else {
            self.bytes as f64 * (self.count - 1) as f64 / self.count as f64 / span
        }
    }

    /// Mean rate over the channel's own span, in Hz (0 for fewer than two events).
    pub fn rate_hz(&self) -> f64 {
        let span = (self.last_utime - self.first_utime) as f64 / 1e6;
        if self.count < 2 || span <= 0.0 {
            0.0
        } else {
            (self.count - 1) as f64 / span
        }
    }
}

/// Names the type of a message from its first 8 bytes.
pub fn type_of(data: &[u8]) -> String {
    if data == b"lcm self test" {
        return "(liblcm self-test)".into();
    }
    let Some(fp) = data.get(..8) else {
        return "?".into();
    };
    let fp = u64::from_be_bytes(fp.try_into().expect("8 bytes"));
    match stride_lcmtypes::type_name_for_fingerprint(fp) {
        Some(n) => n.to_owned(),
        None => format!("? {fp:016x}"),
    }
}

/// Accumulates per-channel statistics, message by message.
#[derive(Debug, Default, Clone)]
pub struct Summary {
    channels: BTreeMap<String, ChannelSummary>,
}

impl Summary {
    /// An empty summary.
    pub fn new() -> Self {
        Self::default()
    }

    /// Counts one message received at `utime` (µs).
    pub fn add(&mut self, channel: &str, utime: i64, data: &[u8]) {
        let ty = type_of(data);
        let s = match self.channels.get_mut(channel) {
            Some(s) => s,
            None => self
                .channels
                .entry(channel.to_owned())
                .or_insert(ChannelSummary {
                    channel: channel.to_owned(),
                    count: 0,
                    bytes: 0,
                    first_utime: utime,
                    last_utime: utime,
                    type_name: ty.clone(),
                }),
        };
        s.count += 1;
        s.bytes += data.len() as u64;
        s.first_utime = s.first_utime.min(utime);
        s.last_utime = s.last_utime.max(utime);
        if !s.type_name.split('|').any(|t| t == ty) {
            s.type_name = format!("{}|{ty}", s.type_name);
        }
    }

    /// The channels, sorted by name.
    pub fn rows(&self) -> Vec<ChannelSummary> {
        self.channels.values().cloned().collect()
    }
}

/// Summarises log events, sorted by channel name.
pub fn summarize(events: impl IntoIterator<Item = lcm::LogEvent>) -> Vec<ChannelSummary> {
    let mut s = Summary::new();
    for ev in events {
        s.add(&ev.channel, ev.timestamp, &ev.data);
    }
    s.rows()
}

/// Renders a summary as an aligned text table.
pub fn render_table(rows: &[ChannelSummary]) -> String {
    let w = rows
        .iter()
        .map(|r| r.channel.len())
        .max()
        .unwrap_or(0)
        .max(24);
    let mut out = format!(
        "{:<w$} {:>8} {:>12} {:>9} {:>10}  {}\n",
        "channel", "events", "bytes", "rate Hz", "kB/s", "type"
    );
    for r in rows {
        out += &format!(
            "{:<w$} {:>8} {:>12} {:>9.2} {:>10.2}  {}\n",
            r.channel,
            r.count,
            r.bytes,
            r.rate_hz(),
            r.bytes_per_s() / 1e3,
            r.type_name
        );
    }
    let total: u64 = rows.iter().map(|r| r.count).sum();
    let bytes: u64 = rows.iter().map(|r| r.bytes).sum();
    out += &format!("{:<w$} {:>8} {:>12}\n", "total", total, bytes);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use lcm::{LogEvent, Message};
    use stride_lcmtypes::stride::PingT;

    #[test]
    fn summary_counts_and_types() {
        let ping = PingT::default().encode().unwrap();
        let ev = |n, t, ch: &str, data: &[u8]| LogEvent {
            number: n,
            timestamp: t,
            channel: ch.into(),
            data: data.to_vec(),
        };
        let rows = summarize(vec![
            ev(0, 1_000_000, "PING", &ping),
            ev(1, 1_500_000, "X", b"short"),
            ev(2, 2_000_000, "PING", &ping),
            ev(3, 3_000_000, "PING", &ping),
        ]);
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[0].channel, "PING");
        assert_eq!(rows[0].count, 3);
        assert_eq!(rows[0].type_name, "stride.ping_t");
        assert!((rows[0].rate_hz() - 1.0).abs() < 1e-9);
        assert_eq!(rows[1].type_name, "?");
        assert!(render_table(&rows).contains("total"));
    }
}
