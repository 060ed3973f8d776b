//! The gateway as an app: its command line and its loop, which takes turns between the LCM
//! side and the wire so that neither starves the other.

use std::io::Write;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use lcm::now_utime;
use stride_can::{dump, CanFrame};
use stride_can_lcm::{batch, frame_to_msg, rx_channel, tx_channel};
use stride_canbus::{BusError, BusSpec, CanBus};
use stride_lcmtypes::stride::{CanFrameBatchT, NodeStatusT};
use stride_node::{outln, Node, NodeArgs, Note, Stamper, Throttle, Tick};

use crate::{status_channel, Gateway, GatewayStats, SendQueue, TurnEnd};

/// Put a CAN interface on the LCM bus, both directions.
///
/// Frames seen on the wire are published as stride.can_frame_batch_t on CAN_<NAME>_RX; frames
/// published on CAN_<NAME>_TX are sent on the wire, in order, through a bounded queue: when it
/// is full new frames are dropped, and a frame that waited longer than --max-age-ms is dropped
/// rather than sent late. Every drop is counted, and the counters go out once a second as
/// stride.can_bus_status_t on CAN_<NAME>_STATUS. So a CAN bus on this machine can be used, and
/// sniffed, from any machine of the LCM network (stride-elmo-bridge with bus = "lcm:NAME").
#[derive(clap::Parser, Debug)]
#[command(name = "stride-usb2can", version, about, long_about)]
pub struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    /// The interface: slcan:/dev/ttyACM0 (a USB2CAN dongle speaking SLCAN), or socketcan:can0
    /// (a kernel interface; needs the build feature `socketcan`).
    #[arg(long)]
    device: BusSpec,
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

stride_node::node_cli!(Cli, realtime);

/// The longest the loop spends on one direction before it turns to the other.
const SLICE: Duration = Duration::from_millis(1);

fn lock(g: &Mutex<Gateway>) -> std::sync::MutexGuard<'_, Gateway> {
    g.lock().unwrap_or_else(|p| p.into_inner())
}

/// The running gateway.
pub struct GatewayApp {
    cli: Cli,
    bus: Box<dyn CanBus + Send>,
    gateway: Arc<Mutex<Gateway>>,
    _sub: lcm::Subscription,
    dump: Option<std::io::BufWriter<std::fs::File>>,
    rx_chan: String,
    status_chan: String,
    stamper: Stamper,
    status_stamper: Stamper,
    send_log: Throttle,
    last_stats: (Instant, GatewayStats),
    last_status: Instant,
}

impl GatewayApp {
    /// Opens the interface and the dump file, and subscribes to the frames to send.
    pub fn start(node: &Node, cli: Cli) -> anyhow::Result<GatewayApp> {
        if matches!(cli.device, BusSpec::Sim | BusSpec::Lcm(_)) {
            anyhow::bail!(
                "--device {}: the gateway needs an interface, slcan:/dev/ttyACM0 or socketcan:can0",
                cli.device
            );
        }
        if !(cli.stats_every > 0.0 && cli.stats_every.is_finite()) {
            anyhow::bail!("--stats-every must be a positive number of seconds");
        }
        let bus = cli
            .device
            .open_device(cli.bitrate)
            .with_context(|| format!("opening {}", cli.device))?;
        let dump = match &cli.candump {
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
                // A frame's age counts from when liblcm received its batch, or from its
                // sender's stamp before that.
                let waited = Duration::from_micros(
                    now_utime().saturating_sub(info.recv_utime).max(0) as u64,
                );
                let arrived = Instant::now()
                    .checked_sub(waited)
                    .unwrap_or_else(Instant::now);
                let bad = lock(&g).take(&m.frames, arrived, info.recv_utime);
                refused_log.log(
                    bad.iter()
                        .map(|why| Note::Warn(format!("frame refused: {why}"))),
                );
            },
        )?;
        // Batches wait in liblcm's queue between turns of the loop (beyond it they are lost,
        // and counted in the node's status).
        sub.set_queue_capacity(1000)?;
        let rx_chan = rx_channel(&cli.bus_name);
        tracing::info!(device = %cli.device, rx = rx_chan.as_str(), "gateway up");
        Ok(GatewayApp {
            status_chan: status_channel(&cli.bus_name),
            rx_chan,
            cli,
            bus,
            gateway,
            _sub: sub,
            dump,
            stamper: Stamper::new(""),
            status_stamper: Stamper::new(""),
            send_log: Throttle::new(Duration::from_secs(1)),
            last_stats: (Instant::now(), GatewayStats::default()),
            last_status: Instant::now() - Duration::from_secs(1),
        })
    }

    fn log_frame(&mut self, f: &CanFrame) {
        if let Some(d) = self.dump.as_mut() {
            let _ = writeln!(d, "{}", dump::format(now_utime(), &self.cli.bus_name, f));
        }
    }
}

impl Tick for GatewayApp {
    fn tick(&mut self, node: &Node, _now: Instant) -> anyhow::Result<Instant> {
        // The queue to the wire, for one slice of time, so that the wire's frames and LCM's
        // new ones are taken in between.
        let was_off = lock(&self.gateway).is_bus_off();
        let turn = lock(&self.gateway).send(&mut *self.bus, Instant::now() + SLICE);
        for f in &turn.sent {
            self.log_frame(f);
        }
        for (_, e) in &turn.failed {
            self.send_log
                .log([Note::Warn(format!("frame not sent: {e}"))]);
        }
        if turn.bus_off {
            node.set_health(NodeStatusT::STATE_FAULT, "bus off");
        }
        // True while frames wait that the interface would take now: then nothing waits for
        // more, on the wire or on LCM.
        let hurry = turn.end == TurnEnd::Slice;
        // The wire to LCM, batched; in a hurry, only what has arrived.
        let mut frames = Vec::new();
        let deadline = Instant::now() + if hurry { Duration::ZERO } else { SLICE };
        loop {
            match self.bus.recv(deadline) {
                Ok(f) => {
                    self.log_frame(&f);
                    frames.push(frame_to_msg(&f, now_utime()));
                    if frames.len() >= stride_can_lcm::BATCH {
                        break;
                    }
                }
                Err(BusError::Timeout) => break,
                Err(BusError::BusOff) => {
                    if lock(&self.gateway).on_bus_off() {
                        node.set_health(NodeStatusT::STATE_FAULT, "bus off");
                    }
                    break;
                }
                Err(e) => return Err(e).context("reading the interface"),
            }
        }
        let mut g = lock(&self.gateway);
        g.on_received(frames.len());
        if was_off && !g.is_bus_off() {
            node.set_health(NodeStatusT::STATE_RUNNING, "");
        }
        let lcm = node.lcm();
        if !frames.is_empty() {
            let msg = batch(&self.cli.bus_name, self.stamper.stamp(), &frames);
            lcm.publish(&self.rx_chan, &msg)?;
        }
        if self.last_status.elapsed() >= Duration::from_secs(1) {
            self.last_status = Instant::now();
            let msg = g.status(
                self.status_stamper.stamp(),
                &self.cli.bus_name,
                &self.cli.device.to_string(),
            );
            if let Err(e) = lcm.publish(&self.status_chan, &msg) {
                tracing::warn!(error = %e, "could not publish the bus status");
            }
        }
        let elapsed = self.last_stats.0.elapsed().as_secs_f64();
        if elapsed >= self.cli.stats_every {
            tracing::info!("{}", g.stats.summary(&self.last_stats.1, elapsed));
            self.last_stats = (Instant::now(), g.stats);
        }
        // LCM next: at once in a hurry, else after waiting up to a slice for its messages.
        let now = Instant::now();
        Ok(if hurry { now } else { now + SLICE })
    }

    fn stop(mut self, _node: &Node) -> anyhow::Result<()> {
        if let Some(mut d) = self.dump.take() {
            let _ = d.flush();
        }
        let s = lock(&self.gateway).stats;
        outln!(
            "stride-usb2can: {} frames from the wire, {} to the wire, {} dropped ({} queue full, {} stale, {} invalid), {} send errors, {} bus-off",
            s.from_wire,
            s.to_wire,
            s.dropped(),
            s.dropped_queue_full,
            s.dropped_stale,
            s.invalid,
            s.send_errors,
            s.bus_off
        )?;
        Ok(())
    }
}
