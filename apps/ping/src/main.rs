//! `stride-ping`: publishes `stride.ping_t` at a fixed rate and reports the round trips of the
//! echoes `stride-echo` sends back.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::bail;
use clap::Parser;
use stride_lcmtypes::stride::PingT;
use stride_node::{Node, NodeArgs, Stamper};
use stride_ping::PingChannels;

/// Send pings on the LCM bus and measure how long their echoes take to come back.
///
/// Run `stride-echo` somewhere on the same bus first. Prints a summary at the end and exits
/// with status 1 when no echo came back.
#[derive(Parser, Debug)]
#[command(version, about, long_about)]
struct Cli {
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
    /// Payload bytes per ping.
    #[arg(long, default_value_t = 100)]
    size: usize,
    /// How long to wait for the last echoes, in seconds.
    #[arg(long, default_value_t = 1.0)]
    linger: f64,
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    if !(cli.rate > 0.0 && cli.rate.is_finite()) {
        bail!("--rate must be a positive number of pings per second");
    }
    let node = Node::start("stride-ping", &cli.node)?;
    let rtts = Arc::new(Mutex::new(Vec::new()));
    let r = rtts.clone();
    let _sub = node
        .lcm()
        .subscribe(&cli.channels.reply_channel, move |info, m: PingT| {
            if m.echoed_by.is_empty() {
                return;
            }
            let rtt = (info.recv_utime - m.sent_utime).max(0) as u64;
            tracing::debug!(
                seq = m.header.sequence,
                by = m.echoed_by.as_str(),
                rtt_us = rtt,
                "echo"
            );
            r.lock().unwrap().push(Duration::from_micros(rtt));
        })?;
    let period = Duration::from_secs_f64(1.0 / cli.rate);
    let mut stamper = Stamper::new("");
    let mut sent = 0u64;
    let mut next = Instant::now();
    node.set_running();
    tracing::info!(
        channel = cli.channels.channel.as_str(),
        rate = cli.rate,
        size = cli.size,
        "pinging"
    );
    while node.running() && (cli.count == 0 || sent < cli.count) {
        let now = Instant::now();
        if now >= next {
            let header = stamper.stamp();
            let ping = PingT {
                sent_utime: header.utime,
                header,
                echoed_by: String::new(),
                payload_size: cli.size as i32,
                payload: vec![0x5a; cli.size],
            };
            node.lcm().publish(&cli.channels.channel, &ping)?;
            sent += 1;
            next += period;
        } else {
            node.lcm().handle_timeout(next - now)?;
        }
    }
    let deadline = Instant::now() + Duration::from_secs_f64(cli.linger.max(0.0));
    while node.running() && Instant::now() < deadline {
        if rtts.lock().unwrap().len() as u64 >= sent {
            break;
        }
        node.lcm().handle_timeout(Duration::from_millis(20))?;
    }
    let summary = stride_ping::summarize(sent, rtts.lock().unwrap().clone());
    println!("stride-ping: {summary}");
    if summary.received == 0 {
        bail!(
            "no echo came back on {} (is stride-echo running on this bus?)",
            cli.channels.reply_channel
        );
    }
    Ok(())
}
