//! The command lines and loops of `stride-ping` and `stride-echo`.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use stride_lcmtypes::stride::PingT;
use stride_node::{outln, Node, NodeArgs, Stamper, Tick};

use crate::{Echo, PingChannels, Tally};

/// Send pings on the LCM bus and measure how long their echoes take to come back.
///
/// Run `stride-echo` somewhere on the same bus first. Only echoes of this process's own pings
/// count, each once (a second echo process or another pinger on the same channels changes
/// nothing but the count of ignored echoes). Prints a summary at the end and exits with
/// status 1 when no echo came back.
#[derive(clap::Parser, Debug)]
#[command(name = "stride-ping", version, about, long_about)]
pub struct PingCli {
    #[command(flatten)]
    node: NodeArgs,
    #[command(flatten)]
    channels: PingChannels,
    /// Pings per second.
    #[arg(long, default_value_t = 10.0)]
    rate: f64,
    /// Number of pings to send (0: until interrupted).
    #[arg(long, default_value_t = 20)]
    count: u64,
    /// Payload bytes per ping (at most 64 MiB).
    #[arg(long, default_value_t = 100, value_parser = payload_size)]
    size: usize,
    /// How long to wait for the last echoes, in seconds.
    #[arg(long, default_value_t = 1.0)]
    linger: f64,
}

stride_node::node_cli!(PingCli);

/// The pinger: sends at its rate, then waits for the last echoes.
pub struct Pinger {
    cli: PingCli,
    tally: Arc<Mutex<Tally>>,
    _sub: lcm::Subscription,
    stamper: Stamper,
    period: Duration,
    next: Instant,
    linger_until: Option<Instant>,
}

fn lock(t: &Mutex<Tally>) -> std::sync::MutexGuard<'_, Tally> {
    t.lock().unwrap_or_else(|p| p.into_inner())
}

impl Pinger {
    /// Checks the flags and listens for echoes.
    pub fn start(node: &Node, cli: PingCli) -> anyhow::Result<Pinger> {
        if !(cli.rate > 0.0 && cli.rate.is_finite()) {
            anyhow::bail!("--rate must be a positive number of pings per second");
        }
        if !(cli.linger >= 0.0 && cli.linger.is_finite()) {
            anyhow::bail!("--linger must be a number of seconds, 0 or more");
        }
        let start_us = lcm::now_utime();
        let token = format!("ping:{}:{start_us}", std::process::id());
        let tally = Arc::new(Mutex::new(Tally::new(token.clone())));
        let t = tally.clone();
        let sub = node
            .lcm()
            .subscribe(&cli.channels.reply_channel, move |info, m: PingT| {
                if let Echo::Own(rtt) = lock(&t).echo(&m, info.recv_utime) {
                    tracing::debug!(
                        seq = m.header.sequence,
                        by = m.echoed_by.as_str(),
                        ?rtt,
                        "echo"
                    );
                }
            })?;
        tracing::info!(
            channel = cli.channels.channel.as_str(),
            rate = cli.rate,
            size = cli.size,
            "pinging"
        );
        Ok(Pinger {
            period: Duration::from_secs_f64(1.0 / cli.rate),
            cli,
            tally,
            _sub: sub,
            stamper: Stamper::new(&token),
            next: Instant::now(),
            linger_until: None,
        })
    }
}

impl Tick for Pinger {
    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        let sent = lock(&self.tally).sent_count();
        if self.cli.count == 0 || sent < self.cli.count {
            if now >= self.next {
                let header = self.stamper.stamp();
                let ping = PingT {
                    sent_utime: header.utime,
                    header,
                    echoed_by: String::new(),
                    payload_size: self.cli.size as i32,
                    payload: vec![0x5a; self.cli.size],
                };
                lock(&self.tally).sent(&ping);
                node.lcm().publish(&self.cli.channels.channel, &ping)?;
                self.next += self.period;
            }
            return Ok(self.next);
        }
        let until = *self
            .linger_until
            .get_or_insert(now + Duration::from_secs_f64(self.cli.linger));
        if now >= until || lock(&self.tally).complete() {
            node.request_shutdown();
        }
        Ok(until.min(now + Duration::from_millis(20)))
    }

    fn stop(self, node: &Node) -> anyhow::Result<()> {
        let summary = lock(&self.tally).summary();
        outln!("stride-ping: {summary}")?;
        if summary.received == 0 {
            anyhow::bail!(
                "no echo came back on {} (is stride-echo running on this bus?)",
                self.cli.channels.reply_channel
            );
        }
        let _ = node;
        Ok(())
    }
}

/// Echo stride-ping's probes back, so round trips over the LCM bus can be measured.
///
/// Runs until SIGINT/SIGTERM, or until --count pings were echoed.
#[derive(clap::Parser, Debug)]
#[command(name = "stride-echo", version, about, long_about)]
pub struct EchoCli {
    #[command(flatten)]
    node: NodeArgs,
    #[command(flatten)]
    channels: PingChannels,
    /// Stop after echoing this many pings (0: never).
    #[arg(long, default_value_t = 0)]
    count: u64,
}

stride_node::node_cli!(EchoCli);

/// The echo: every ping back on the reply channel, from liblcm's handler.
pub struct Echoer {
    echoed: Arc<AtomicU64>,
    count: u64,
    sub: lcm::Subscription,
}

impl Echoer {
    /// Subscribes to the pings.
    pub fn start(node: &Node, cli: &EchoCli) -> anyhow::Result<Echoer> {
        let publisher = node.publisher();
        let name = node.name().to_owned();
        let echoed = Arc::new(AtomicU64::new(0));
        let e = echoed.clone();
        let reply = cli.channels.reply_channel.clone();
        let sub = node
            .lcm()
            .subscribe(&cli.channels.channel, move |_, mut m: PingT| {
                if !m.echoed_by.is_empty() {
                    return; // an echo on the ping channel: never echo an echo
                }
                m.echoed_by.clone_from(&name);
                match publisher.publish(&reply, &m) {
                    Ok(()) => {
                        e.fetch_add(1, Ordering::Relaxed);
                    }
                    Err(err) => tracing::warn!(error = %err, "could not echo"),
                }
            })?;
        tracing::info!(
            channel = cli.channels.channel.as_str(),
            reply = cli.channels.reply_channel.as_str(),
            "echoing"
        );
        Ok(Echoer {
            echoed,
            count: cli.count,
            sub,
        })
    }
}

impl Tick for Echoer {
    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        if self.count > 0 && self.echoed.load(Ordering::Relaxed) >= self.count {
            node.request_shutdown();
        }
        Ok(now + Duration::from_millis(100))
    }

    fn stop(self, _node: &Node) -> anyhow::Result<()> {
        let st = self.sub.stats();
        outln!(
            "stride-echo: echoed {} pings ({} lost on the way in, {} undecodable)",
            self.echoed.load(Ordering::Relaxed),
            st.lost,
            st.decode_errors
        )?;
        Ok(())
    }
}

/// A payload size: at most 64 MiB (liblcm takes messages of up to 256 MB; a ping that size
/// only measures the allocation).
fn payload_size(s: &str) -> Result<usize, String> {
    let n: usize = s.parse().map_err(|e| format!("{e}"))?;
    if n > 64 << 20 {
        return Err(format!("{n} bytes, more than 64 MiB"));
    }
    Ok(n)
}
