//! `stride-usb2can`: a CAN interface on the LCM bus.

use std::io::Write;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use clap::Parser;
use stride_can::dump;
use stride_can_lcm::{batch, frame_to_msg, msg_to_frame, now_us, rx_channel, tx_channel};
use stride_canbus::{BusError, CanBus};
use stride_lcmtypes::stride::{CanFrameBatchT, NodeStatusT};
use stride_node::{Node, NodeArgs, Stamper};
use stride_usb2can::{status_channel, status_msg, GatewayStats, SendQueue};

/// Put a CAN interface on the LCM bus, both directions.
///
/// Frames seen on the wire are published as stride.can_frame_batch_t on CAN_<NAME>_RX; frames
/// published on CAN_<NAME>_TX are sent on the wire, in order, through a bounded queue: when it
/// is full new frames are dropped, and a frame that waited longer than --max-age-ms is dropped
/// rather than sent late. Every drop is counted, and the counters go out once a second as
/// stride.can_bus_status_t on CAN_<NAME>_STATUS. So a CAN bus on this machine can be used, and
/// sniffed, from any machine of the LCM network (stride-elmo-bridge with bus = "lcm:NAME").
#[derive(Parser, Debug)]
#[command(version, about, long_about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    /// The interface: slcan:/dev/ttyACM0 (a USB2CAN dongle speaking SLCAN), or socketcan:can0
    /// (a kernel interface; needs the build feature `socketcan`).
    #[arg(long)]
    device: String,
    /// Bus name in the LCM channels (CAN_<NAME>_RX / _TX / _STATUS).
    #[arg(long, default_value = "can0")]
    bus_name: String,
    /// CAN bit rate.
    #[arg(long, default_value_t = 1_000_000)]
    bitrate: u32,
    /// Frames from LCM that may wait for the wire; more are dropped (and counted).
    #[arg(long, default_value_t = 1000)]
    queue: usize,
    /// The oldest a frame from LCM may be when its turn comes, ms; older ones are dropped.
    #[arg(long, default_value_t = 100)]
    max_age_ms: u64,
    /// Also write every frame, both directions, to this file in candump -L format.
    #[arg(long)]
    candump: Option<PathBuf>,
    /// Seconds between statistics lines in the log.
    #[arg(long, default_value_t = 5.0)]
    stats_every: f64,
}

fn open(device: &str, bitrate: u32) -> anyhow::Result<Box<dyn CanBus + Send>> {
    if let Some(iface) = device.strip_prefix("socketcan:") {
        #[cfg(feature = "socketcan")]
        return Ok(Box::new(stride_canbus::socketcan::SocketCanBus::open(
            iface,
        )?));
        #[cfg(not(feature = "socketcan"))]
        bail!("socketcan:{iface}: this build has no SocketCAN backend (build with --features socketcan)");
    }
    if let Some(path) = device.strip_prefix("slcan:") {
        let bus = stride_canbus::slcan::open_path(path, bitrate)
            .with_context(|| format!("opening the SLCAN dongle on {path}"))?;
        return Ok(Box::new(bus));
    }
    bail!("unknown device {device:?}: use slcan:/dev/ttyACM0 or socketcan:can0")
}

/// The longest the loop spends on one direction before it turns to the other.
const SLICE: Duration = Duration::from_millis(1);

/// What the LCM callback and the loop share.
struct Shared {
    queue: SendQueue,
    stats: GatewayStats,
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
    let shared = Arc::new(Mutex::new(Shared {
        queue: SendQueue::new(cli.queue, Duration::from_millis(cli.max_age_ms)),
        stats: GatewayStats::default(),
    }));
    let s = shared.clone();
    let sub = node
        .lcm()
        .subscribe(&tx_channel(&cli.bus_name), move |_, m: CanFrameBatchT| {
            let now = Instant::now();
            let mut g = s.lock().unwrap_or_else(|p| p.into_inner());
            let Shared { queue, stats } = &mut *g;
            for e in &m.frames {
                match msg_to_frame(e) {
                    Ok(f) => {
                        queue.push(f, now, stats);
                    }
                    Err(why) => {
                        stats.invalid += 1;
                        tracing::warn!(invalid = stats.invalid, "frame refused: {why}");
                    }
                }
            }
        })?;
    // Batches wait in liblcm's queue between turns of the loop.
    sub.set_queue_capacity(1000)?;
    let rx_chan = rx_channel(&cli.bus_name);
    let status_chan = status_channel(&cli.bus_name);
    let publisher = node.publisher();
    let mut stamper = Stamper::new("");
    let mut status_stamper = Stamper::new("");
    let mut last_stats = (Instant::now(), GatewayStats::default());
    let mut last_status = Instant::now() - Duration::from_secs(1);
    node.set_running();
    tracing::info!(
        device = cli.device.as_str(),
        rx = rx_chan.as_str(),
        "gateway up"
    );
    while node.running() {
        // Everything LCM has (a bounded number of batches); wait for more only when no frame
        // is waiting to be sent.
        let waiting = !shared
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .queue
            .is_empty();
        let mut wait = if waiting { Duration::ZERO } else { SLICE };
        for _ in 0..64 {
            if !node.lcm().handle_timeout(wait)? {
                break;
            }
            wait = Duration::ZERO;
        }
        // LCM to the wire, oldest first, for one slice of time (so the wire's frames and LCM's
        // new ones are taken in between, and a frame's age counts from when it arrived); what
        // the interface cannot take yet waits its turn.
        let slice_end = Instant::now() + SLICE;
        loop {
            let now = Instant::now();
            if now >= slice_end {
                break;
            }
            let mut g = shared.lock().unwrap_or_else(|p| p.into_inner());
            let Shared { queue, stats } = &mut *g;
            let Some(f) = queue.next(now, stats) else {
                break;
            };
            match bus.send(&f, now + Duration::from_millis(5)) {
                Ok(()) => {
                    stats.to_wire += 1;
                    queue.sent();
                    if let Some(d) = dump.as_mut() {
                        let _ = writeln!(d, "{}", dump::format(now_us(), &cli.bus_name, &f));
                    }
                }
                Err(BusError::TxQueueFull | BusError::Timeout) => break,
                Err(BusError::BusOff) => {
                    stats.bus_off += 1;
                    node.set_health(NodeStatusT::STATE_FAULT, "bus off");
                    break;
                }
                Err(e) => {
                    stats.send_errors += 1;
                    queue.sent();
                    tracing::warn!(error = %e, "frame not sent");
                }
            }
        }
        // The wire to LCM, batched; while frames wait to be sent, only what has arrived.
        let mut frames = Vec::new();
        let waiting = !shared
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .queue
            .is_empty();
        let deadline = Instant::now() + if waiting { Duration::ZERO } else { SLICE };
        loop {
            match bus.recv(deadline) {
                Ok(f) => {
                    if let Some(d) = dump.as_mut() {
                        let _ = writeln!(d, "{}", dump::format(now_us(), &cli.bus_name, &f));
                    }
                    frames.push(frame_to_msg(&f, now_us()));
                    if frames.len() >= stride_can_lcm::BATCH {
                        break;
                    }
                }
                Err(BusError::Timeout) => break,
                Err(BusError::BusOff) => {
                    shared
                        .lock()
                        .unwrap_or_else(|p| p.into_inner())
                        .stats
                        .bus_off += 1;
                    node.set_health(NodeStatusT::STATE_FAULT, "bus off");
                    break;
                }
                Err(e) => return Err(e).context("reading the interface"),
            }
        }
        if !frames.is_empty() {
            shared
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .stats
                .from_wire += frames.len() as u64;
            publisher.publish(&rx_chan, &batch(&cli.bus_name, stamper.stamp(), &frames))?;
        }
        if last_status.elapsed() >= Duration::from_secs(1) {
            last_status = Instant::now();
            let g = shared.lock().unwrap_or_else(|p| p.into_inner());
            let msg = status_msg(
                status_stamper.stamp(),
                &cli.bus_name,
                &cli.device,
                &g.stats,
                &g.queue,
            );
            drop(g);
            if let Err(e) = publisher.publish(&status_chan, &msg) {
                tracing::warn!(error = %e, "could not publish the bus status");
            }
        }
        let elapsed = last_stats.0.elapsed().as_secs_f64();
        if elapsed >= cli.stats_every {
            let s = shared.lock().unwrap_or_else(|p| p.into_inner()).stats;
            tracing::info!("{}", s.summary(&last_stats.1, elapsed));
            last_stats = (Instant::now(), s);
        }
    }
    if let Some(mut d) = dump {
        let _ = d.flush();
    }
    let s = shared.lock().unwrap_or_else(|p| p.into_inner()).stats;
    println!(
        "stride-usb2can: {} frames from the wire, {} to the wire, {} dropped ({} queue full, {} stale, {} invalid), {} send errors, {} bus-off",
        s.from_wire,
        s.to_wire,
        s.dropped(),
        s.dropped_queue_full,
        s.dropped_stale,
        s.invalid,
        s.send_errors,
        s.bus_off
    );
    Ok(())
}
