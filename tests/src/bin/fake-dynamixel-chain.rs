//! `fake-dynamixel-chain`: a chain of fake Dynamixel servos on a pseudo-terminal, as a
//! process, for the end-to-end tests. Writes the terminal's path to `--pty-file`, answers at
//! the line's baud rate until SIGINT/SIGTERM, then prints which servos still have their
//! torque on.

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use clap::Parser;
use stride_dynamixel::models;
use stride_fakes::dynamixel::{ChainLevers, FakeChain, Fault, Servo};
use stride_serial::{Paced, Port};

/// Fake Dynamixel servos on a pty.
#[derive(Parser, Debug)]
struct Cli {
    /// Where to write the path of the terminal.
    #[arg(long)]
    pty_file: std::path::PathBuf,
    /// Model of every servo.
    #[arg(long, default_value = "AX-12A")]
    model: String,
    /// Ids, FIRST-LAST.
    #[arg(long, default_value = "1-18")]
    ids: String,
    /// Line baud rate.
    #[arg(long, default_value_t = 1_000_000)]
    baud: u32,
    /// Ids left out of the chain.
    #[arg(long, value_delimiter = ',')]
    missing: Vec<u8>,
    /// Ids that overheat.
    #[arg(long, value_delimiter = ',')]
    overheat: Vec<u8>,
    /// ID:MS: a servo that answers MS milliseconds late.
    #[arg(long)]
    late: Vec<String>,
}

fn main() -> anyhow::Result<()> {
    // A device's processor is not held up by the host's load: the fake runs at the
    // real-time priority STRIDE_RT_PRIORITY names, if any.
    if let Err(why) = stride_node::realtime::request_from_env() {
        eprintln!("fake-dynamixel-chain: {why}");
    }
    let cli = Cli::parse();
    let model = models::by_name(&cli.model).ok_or_else(|| anyhow::anyhow!("unknown model"))?;
    let (a, b) = cli
        .ids
        .split_once('-')
        .ok_or_else(|| anyhow::anyhow!("--ids FIRST-LAST"))?;
    let (a, b): (u8, u8) = (a.parse()?, b.parse()?);
    let servos = (a..=b)
        .filter(|i| !cli.missing.contains(i))
        .map(|i| Servo::new(i, model))
        .collect();
    let levers = ChainLevers::default();
    for &id in &cli.overheat {
        levers.set(
            id,
            Fault {
                overheat: true,
                ..Fault::default()
            },
        );
    }
    for l in &cli.late {
        let (id, ms) = l
            .split_once(':')
            .ok_or_else(|| anyhow::anyhow!("--late ID:MS"))?;
        levers.set(
            id.parse()?,
            Fault {
                late: Duration::from_millis(ms.parse()?),
                ..Fault::default()
            },
        );
    }
    let (dev, host_end) = serialport::TTYPort::pair()?;
    let path = serialport::SerialPort::name(&host_end).unwrap_or_default();
    let stop = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGTERM, stop.clone())?;
    signal_hook::flag::register(signal_hook::consts::SIGINT, stop.clone())?;
    let chain = FakeChain::new(model.protocol, servos, levers)
        .at_baud(cli.baud)
        .spawn(Paced::new(Port::new(dev, cli.baud)), stop.clone());
    std::fs::write(&cli.pty_file, &path)?;
    let chain = chain
        .join()
        .map_err(|_| anyhow::anyhow!("the chain panicked"))?;
    let on: Vec<u8> = chain
        .servos()
        .iter()
        .filter(|s| s.torque_on())
        .map(|s| s.id())
        .collect();
    println!("torque on: {on:?}");
    drop(host_end);
    Ok(())
}
