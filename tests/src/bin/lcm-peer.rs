//! `lcm-peer`: a test peer on the LCM bus, used by the cross-process tests.

use std::time::Duration;

use clap::{Parser, Subcommand};
use lcm::Lcm;

/// Test peer: echoes raw messages back, so another process can check what crossed the bus.
#[derive(Parser, Debug)]
struct Cli {
    /// LCM URL.
    #[arg(long)]
    lcm_url: String,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Republishes every message of CHANNEL unchanged on REPLY; exits after COUNT messages.
    Echo {
        /// Channel to listen on.
        #[arg(long)]
        channel: String,
        /// Channel to answer on.
        #[arg(long)]
        reply: String,
        /// Messages to echo before exiting.
        #[arg(long, default_value_t = 1)]
        count: u64,
    },
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let lcm = Lcm::new(&cli.lcm_url)?;
    match cli.cmd {
        Cmd::Echo {
            channel,
            reply,
            count,
        } => {
            let p = lcm.publisher();
            let sub = lcm.subscribe_raw(&channel, move |_, data| {
                p.publish_raw(&reply, data).expect("echo publish");
            })?;
            let deadline = std::time::Instant::now() + Duration::from_secs(60);
            while sub.stats().received < count && std::time::Instant::now() < deadline {
                lcm.handle_timeout(Duration::from_millis(100))?;
            }
            println!("echoed {}", sub.stats().received);
        }
    }
    Ok(())
}
