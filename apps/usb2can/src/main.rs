//! `stride-usb2can`: a CAN interface on the LCM bus.

use std::io::Write;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use clap::Parser;
use stride_can::{dump, CanFrame};
use stride_can_lcm::{batch, frame_to_msg, now_us, rx_channel, tx_channel};
use stride_canbus::{BusError, CanBus};
use stride_lcmtypes::stride::{CanFrameBatchT, NodeStatusT};
use stride_node::{Node, NodeArgs, Note, Stamper, Throttle};
use stride_usb2can::{status_channel, Gateway, GatewayStats, SendQueue, TurnEnd};

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

fn lock(g: &Mutex<Gateway>) -> std::sync::MutexGuard<'_, Gateway> {
    g.lock().unwrap_or_else(|p| p.into_inner())
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
    let gateway = Arc::new(Mutex::new(Gateway::new(SendQueue::new(
        cli.queue,
        Duration::from_millis(cli.max_age_ms),
    ))));
    let g = gateway.clone();
    let mut refused_log = Throttle::new(Duration::from_secs(1));
    let sub = node.lcm().subscribe(
        &tx_channel(&cli.bus_name),
        move |info: &lcm::RecvInfo<'_>, m: CanFrameBatchT| {
            // A frame's age counts from when liblcm received its batch.
            let waited =
                Duration::from_micros(now_us().saturating_sub(info.recv_utime).max(0) as u64);
            let arrived = Instant::now()
                .checked_sub(waited)
                .unwrap_or_else(Instant::now);
            let bad = lock(&g).take(&m.frames, arrived);
            refused_log.log(
                bad.iter()
                    .map(|why| Note::Warn(format!("frame refused: {why}"))),
            );
        },
    )?;
    // Batches wait in liblcm's queue between turns of the loop (beyond it they are lost, and
    // counted in the node's status).
    sub.set_queue_capacity(1000)?;
    let rx_chan = rx_channel(&cli.bus_name);
    let status_chan = status_channel(&cli.bus_name);
    let publisher = node.publisher();
    let mut stamper = Stamper::new("");
    let mut status_stamper = Stamper::new("");
    let mut send_log = Throttle::new(Duration::from_secs(1));
    let mut last_stats = (Instant::now(), GatewayStats::default());
    let mut last_status = Instant::now() - Duration::from_secs(1);
    let mut log_frame = |f: &CanFrame| {
        if let Some(d) = dump.as_mut() {
            let _ = writeln!(d, "{}", dump::format(now_us(), &cli.bus_name, f));
        }
    };
    node.set_running();
    tracing::info!(
        device = cli.device.as_str(),
        rx = rx_chan.as_str(),
        "gateway up"
    );
    // True while frames wait that the interface would take now: then nothing waits for more.
    let mut hurry = false;
    while node.running() {
        // LCM to the queue: everything liblcm has; wait for more only when not in a hurry.
        if hurry || node.lcm().handle_timeout(SLICE)? {
            node.lcm().handle_pending()?;
        }
        // The queue to the wire, for one slice of time, so that the wire's frames and LCM's
        // new ones are taken in between.
        let was_off = lock(&gateway).is_bus_off();
        let turn = lock(&gateway).send(&mut *bus, Instant::now() + SLICE);
        turn.sent.iter().for_each(&mut log_frame);
        for (_, e) in &turn.failed {
            send_log.log([Note::Warn(format!("frame not sent: {e}"))]);
        }
        if turn.bus_off {
            node.set_health(NodeStatusT::STATE_FAULT, "bus off");
        }
        hurry = turn.end == TurnEnd::Slice;
        // The wire to LCM, batched; in a hurry, only what has arrived.
        let mut frames = Vec::new();
        let deadline = Instant::now() + if hurry { Duration::ZERO } else { SLICE };
        loop {
            match bus.recv(deadline) {
                Ok(f) => {
                    log_frame(&f);
                    frames.push(frame_to_msg(&f, now_us()));
                    if frames.len() >= stride_can_lcm::BATCH {
                        break;
                    }
                }
                Err(BusError::Timeout) => break,
                Err(BusError::BusOff) => {
                    if lock(&gateway).on_bus_off() {
                        node.set_health(NodeStatusT::STATE_FAULT, "bus off");
                    }
                    break;
                }
                Err(e) => return Err(e).context("reading the interface"),
            }
        }
        let mut g = lock(&gateway);
        g.on_received(frames.len());
        if was_off && !g.is_bus_off() {
            node.set_health(NodeStatusT::STATE_RUNNING, "");
        }
        if !frames.is_empty() {
            publisher.publish(&rx_chan, &batch(&cli.bus_name, stamper.stamp(), &frames))?;
        }
        if last_status.elapsed() >= Duration::from_secs(1) {
            last_status = Instant::now();
            let msg = g.status(status_stamper.stamp(), &cli.bus_name, &cli.device);
            if let Err(e) = publisher.publish(&status_chan, &msg) {
                tracing::warn!(error = %e, "could not publish the bus status");
            }
        }
        let elapsed = last_stats.0.elapsed().as_secs_f64();
        if elapsed >= cli.stats_every {
            tracing::info!("{}", g.stats.summary(&last_stats.1, elapsed));
            last_stats = (Instant::now(), g.stats);
        }
    }
    if let Some(mut d) = dump {
        let _ = d.flush();
    }
    let s = lock(&gateway).stats;
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
