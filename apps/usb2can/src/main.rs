//! `stride-usb2can`: a CAN interface on the LCM bus.

use std::io::Write;
use std::path::PathBuf;
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use clap::Parser;
use stride_canbus::lcm::{batch, frame_to_msg, msg_to_frame, rx_channel, tx_channel};
use stride_canbus::{BusError, CanBus, CanFrame};
use stride_lcmtypes::stride::{CanFrameBatchT, NodeStatusT};
use stride_node::{Node, NodeArgs, Stamper};
use stride_usb2can::{candump_line, GatewayStats};

/// Put a CAN interface on the LCM bus, both directions.
///
/// Frames seen on the wire are published as stride.can_frame_batch_t on CAN_<NAME>_RX; frames
/// published on CAN_<NAME>_TX are sent on the wire. So a CAN bus on this machine can be used,
/// and sniffed, from any machine of the LCM network (stride-elmo-bridge with bus = "lcm:NAME").
#[derive(Parser, Debug)]
#[command(version, about, long_about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    /// The interface: slcan:/dev/ttyACM0 (a USB2CAN dongle speaking SLCAN), or socketcan:can0
    /// (a kernel interface; needs the build feature `socketcan`).
    #[arg(long)]
    device: String,
    /// Bus name in the LCM channels (CAN_<NAME>_RX / _TX).
    #[arg(long, default_value = "can0")]
    bus_name: String,
    /// CAN bit rate.
    #[arg(long, default_value_t = 1_000_000)]
    bitrate: u32,
    /// Also write every frame, both directions, to this file in candump -L format.
    #[arg(long)]
    candump: Option<PathBuf>,
    /// Seconds between statistics lines in the log.
    #[arg(long, default_value_t = 5.0)]
    stats_every: f64,
}

fn open(device: &str, bitrate: u32) -> anyhow::Result<Box<dyn CanBus + Send>> {
    #[cfg(feature = "socketcan")]
    if let Some(iface) = device.strip_prefix("socketcan:") {
        return Ok(Box::new(stride_canbus::socketcan::SocketCanBus::open(
            iface,
        )?));
    }
    if let Some(path) = device.strip_prefix("slcan:") {
        let bus = stride_canbus::slcan::open_path(path, bitrate)
            .with_context(|| format!("opening the SLCAN dongle on {path}"))?;
        return Ok(Box::new(bus));
    }
    bail!("unknown device {device:?}: use slcan:/dev/ttyACM0")
}

fn now_us() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as i64)
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let node = Node::start("stride-usb2can", &cli.node)?;
    let mut bus = open(&cli.device, cli.bitrate)?;
    let mut dump = match &cli.candump {
        Some(p) => Some(std::io::BufWriter::new(
            std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))?,
        )),
        None => None,
    };
    let (tx, rx) = mpsc::channel::<CanFrame>();
    let sub = node
        .lcm()
        .subscribe(&tx_channel(&cli.bus_name), move |_, m: CanFrameBatchT| {
            for f in m.frames.iter().filter_map(msg_to_frame) {
                let _ = tx.send(f);
            }
        })?;
    // A master may send a burst (a table of PVT rows): keep every frame, in order.
    sub.set_queue_capacity(100_000)?;
    let rx_chan = rx_channel(&cli.bus_name);
    let publisher = node.publisher();
    let stats = Arc::new(Mutex::new(GatewayStats::default()));
    let mut stamper = Stamper::new("");
    let mut last_stats = (Instant::now(), GatewayStats::default());
    node.set_running();
    tracing::info!(
        device = cli.device.as_str(),
        rx = rx_chan.as_str(),
        "gateway up"
    );
    while node.running() {
        node.lcm().handle_timeout(Duration::from_millis(1))?;
        // LCM to the wire.
        while let Ok(f) = rx.try_recv() {
            let mut s = stats.lock().unwrap();
            match bus.send(&f, Instant::now() + Duration::from_millis(50)) {
                Ok(()) => s.to_wire += 1,
                Err(BusError::BusOff) => s.bus_off += 1,
                Err(e) => {
                    s.send_errors += 1;
                    tracing::warn!(error = %e, "frame not sent");
                }
            }
            if let Some(d) = dump.as_mut() {
                let _ = writeln!(d, "{}", candump_line(now_us(), &cli.bus_name, &f));
            }
        }
        // The wire to LCM, batched.
        let mut frames = Vec::new();
        let deadline = Instant::now() + Duration::from_millis(1);
        loop {
            match bus.recv(deadline) {
                Ok(f) => {
                    if let Some(d) = dump.as_mut() {
                        let _ = writeln!(d, "{}", candump_line(now_us(), &cli.bus_name, &f));
                    }
                    frames.push(frame_to_msg(&f, now_us()));
                    if frames.len() >= 64 {
                        break;
                    }
                }
                Err(BusError::Timeout) => break,
                Err(BusError::BusOff) => {
                    stats.lock().unwrap().bus_off += 1;
                    node.set_health(NodeStatusT::STATE_FAULT, "bus off");
                    break;
                }
                Err(e) => return Err(e).context("reading the interface"),
            }
        }
        if !frames.is_empty() {
            stats.lock().unwrap().from_wire += frames.len() as u64;
            publisher.publish(&rx_chan, &batch(&cli.bus_name, stamper.stamp(), &frames))?;
        }
        let elapsed = last_stats.0.elapsed().as_secs_f64();
        if elapsed >= cli.stats_every {
            let s = *stats.lock().unwrap();
            tracing::info!("{}", s.summary(&last_stats.1, elapsed));
            last_stats = (Instant::now(), s);
        }
    }
    if let Some(mut d) = dump {
        let _ = d.flush();
    }
    let s = *stats.lock().unwrap();
    println!(
        "stride-usb2can: {} frames from the wire, {} to the wire, {} send errors, {} bus-off",
        s.from_wire, s.to_wire, s.send_errors, s.bus_off
    );
    Ok(())
}
