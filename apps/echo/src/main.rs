//! `stride-echo`: sends every `stride.ping_t` it receives back on the reply channel.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use clap::Parser;
use stride_lcmtypes::stride::PingT;
use stride_node::{Node, NodeArgs};
use stride_ping::PingChannels;

/// Echo stride-ping's probes back, so round trips over the LCM bus can be measured.
///
/// Runs until SIGINT/SIGTERM, or until --count pings were echoed.
#[derive(Parser, Debug)]
#[command(version, about, long_about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    #[command(flatten)]
    channels: PingChannels,
    /// Stop after echoing this many pings (0: never).
    #[arg(long, default_value_t = 0)]
    count: u64,
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let node = Node::start("stride-echo", &cli.node)?;
    let publisher = node.publisher();
    let name = node.name().to_owned();
    let echoed = Arc::new(AtomicU64::new(0));
    let e = echoed.clone();
    let reply = cli.channels.reply_channel.clone();
    let sub = node
        .lcm()
        .subscribe(&cli.channels.channel, move |_, mut m: PingT| {
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
    let count = cli.count;
    node.spin_with(std::time::Duration::from_millis(100), || {
        if count > 0 && echoed.load(Ordering::Relaxed) >= count {
            node.request_shutdown();
        }
        Ok(())
    })?;
    let st = sub.stats();
    println!(
        "stride-echo: echoed {} pings ({} lost on the way in, {} undecodable)",
        echoed.load(Ordering::Relaxed),
        st.lost,
        st.decode_errors
    );
    Ok(())
}
