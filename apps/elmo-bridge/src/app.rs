//! The bridge as an app: its command line, how its bus is opened, and its loop.

use std::time::{Duration, Instant};

use anyhow::Context;
use stride_canbus::{BusSpec, CanBus, MemBus};
use stride_elmo::Master;
use stride_fakes::elmo::{ElmoConfig, FakeElmo, Levers};
use stride_fakes::Sim;
use stride_lcmtypes::stride::{GaitCommandT, JointTrajectoryT, NodeStatusT};
use stride_node::{AppConfig, ConfigUse, Node, NodeArgs, Spaced, Stamper, Throttle, Tick};

use crate::{Bridge, BridgeConfig};

/// Drive Elmo motion controllers over CANopen from LCM joint trajectories.
///
/// At start it brings every configured drive up (identity, heartbeats, PDO mapping verified,
/// CiA 402 enable) and refuses to run otherwise; each drive is set to quick-stop on its own
/// when the bridge's heartbeat stops for drive_watchdog_ms (the bridge killed, a cable
/// pulled). Trajectories (stride.joint_trajectory_t) start at once, at their start_utime (this
/// host's clock), or after what is queued (queue = APPEND); each replaces what is queued of its
/// joints from its start on. The motion every drive will play is checked first, between rows
/// too, with its join from what the joint does at the start: one point past a position,
/// velocity or acceleration limit refuses the whole trajectory (reported with joint, row and
/// figure), never clipped. Rows are streamed lookahead_ms ahead as Elmo PVT rows, PT points
/// (motion = "pt") or CiA 402 interpolated-position set-points (motion = "ip"). A trajectory
/// that ends in motion is a chunk of a stream: when no chunk follows in time, its joints
/// decelerate to a stop within their limits. A drive fault stops every axis; the next valid
/// trajectory enables them again. When the bus fails the drives are brought up again once it
/// answers. Joint states go out at state_rate_hz (idle_state_rate_hz while every joint holds
/// still with nothing queued), the bridge's trajectory status
/// (stride.trajectory_status_t) once a second and on every change. On shutdown the joints
/// decelerate to a stop, then the drives are disabled.
///
/// bus = "sim" runs fake drives in this process; "slcan:/dev/ttyACM0" a USB2CAN dongle;
/// "lcm:NAME" a bus behind a stride-usb2can gateway on the LCM network; "socketcan:can0" a
/// kernel interface (build with --features socketcan). See config/robots/archie-left-leg.toml.
#[derive(clap::Parser, Debug)]
#[command(name = "stride-elmo-bridge", version, about, long_about)]
pub struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    /// The bus, instead of the configuration's `bus` (e.g. lcm:left to reach fake drives in
    /// another process).
    #[arg(long, value_name = "SPEC")]
    pub bus: Option<BusSpec>,
}

stride_node::node_cli!(Cli, realtime);

impl AppConfig for BridgeConfig {
    const USE: ConfigUse = ConfigUse::Required(
        "a robot's joints and bus; see config/robots/, e.g. config/robots/archie-left-leg.toml",
    );
    fn check(&self) -> Result<(), String> {
        BridgeConfig::check(self)
    }
}

/// The fake drives of a `sim` bus, when it is one.
pub type SimDrives = Option<Sim<FakeElmo>>;

/// Opens the bus the configuration names: fake drives in this process for `sim` (returned
/// with their guard), a gateway's bus on the node's LCM instance for `lcm:NAME`, a device
/// otherwise.
pub fn open_bus<'a>(
    cfg: &BridgeConfig,
    lcm: &'a lcm::Lcm,
) -> anyhow::Result<(Box<dyn CanBus + 'a>, SimDrives)> {
    match &cfg.bus {
        BusSpec::Lcm(name) => {
            let bus = stride_can_lcm::LcmBus::new(lcm, name)
                .with_context(|| format!("joining CAN bus {name} over LCM"))?;
            Ok((Box::new(bus), None))
        }
        BusSpec::Sim => {
            let bus = MemBus::new(cfg.bitrate);
            let mut sim = Sim::new();
            for j in &cfg.joint {
                let drive = FakeElmo::new(ElmoConfig::new(j.node), Levers::default());
                sim.add(drive.spawn(bus.node(), sim.flag()));
            }
            Ok((Box::new(bus.node()), Some(sim)))
        }
        device => Ok((
            device
                .open_device(cfg.bitrate)
                .with_context(|| format!("opening bus {device}"))?,
            None,
        )),
    }
}

/// The running bridge: the drives' state machine, its queue of trajectories and what it
/// publishes when.
pub struct ElmoApp<'n> {
    // Dropped in this order: the bridge (its bus) before the fake drives.
    bridge: Bridge<Box<dyn CanBus + 'n>>,
    _sim: Option<Sim<FakeElmo>>,
    sub: lcm::Subscription,
    rx: std::sync::mpsc::Receiver<JointTrajectoryT>,
    stop_sub: lcm::Subscription,
    stops: std::sync::mpsc::Receiver<GaitCommandT>,
    /// Trajectories and stops taken so far (see [`Tick::urgent`]).
    urgent_seen: u64,
    cfg: BridgeConfig,
    throttle: Throttle,
    states: Stamper,
    statuses: Stamper,
    period: Duration,
    idle_period: Duration,
    next_state: Instant,
    /// The status: once a second, and on a change at most every STATUS_GAP.
    status_pace: Spaced,
    /// A change not yet said (it waits for the gap).
    status_pending: bool,
}

/// A change of the status goes out at most this often (a flood of bad trajectories does not
/// become a flood of statuses).
const STATUS_GAP: Duration = Duration::from_millis(20);

impl<'n> ElmoApp<'n> {
    /// Opens the bus, brings the drives up and subscribes; refuses to start otherwise.
    pub fn start(node: &'n Node, cfg: BridgeConfig) -> anyhow::Result<ElmoApp<'n>> {
        node.set_health(NodeStatusT::STATE_STARTING, "bringing up the drives");
        let (bus, sim) = open_bus(&cfg, node.lcm())?;
        let master_cfg = cfg.master().map_err(anyhow::Error::msg)?;
        let mut master = Master::new(bus, cfg.joint.clone(), master_cfg)?;
        if let Err(e) = master.bring_up() {
            node.set_health(NodeStatusT::STATE_FAULT, format!("bring-up failed: {e}"));
            anyhow::bail!("bring-up failed: {e}");
        }
        tracing::info!(joints = cfg.joint.len(), bus = %cfg.bus, "drives enabled");
        let bridge = Bridge::new(master, cfg.recovery_delay_ms);
        // Listen before saying so: a trajectory sent on seeing RUNNING must not be lost.
        let (sub, rx) = node.queue::<JointTrajectoryT>(&cfg.trajectory_channel)?;
        let (stop_sub, stops) = node.queue::<GaitCommandT>(&cfg.stop_channel)?;
        let now = Instant::now();
        Ok(ElmoApp {
            bridge,
            _sim: sim,
            sub,
            rx,
            stop_sub,
            stops,
            urgent_seen: 0,
            period: Duration::from_secs_f64(1.0 / cfg.state_rate_hz),
            idle_period: Duration::from_secs_f64(1.0 / cfg.idle_state_rate_hz),
            cfg,
            throttle: Throttle::new(Duration::from_secs(5)),
            states: Stamper::new(""),
            statuses: Stamper::new(""),
            next_state: now,
            status_pace: Spaced::new(Duration::from_secs(1), STATUS_GAP),
            status_pending: true,
        })
    }
}

impl Tick for ElmoApp<'_> {
    // The drives' frames are taken at the master's own times (its SYNC, a motion's start), as
    // from a serial dongle, whose frames never wake the loop; trajectories and stops at once.
    const WAKE_ON_MESSAGE: bool = false;

    fn urgent(&mut self) -> bool {
        let n = self.sub.stats().received + self.stop_sub.stats().received;
        std::mem::replace(&mut self.urgent_seen, n) != n
    }

    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        while let Ok(c) = self.stops.try_recv() {
            match c.command {
                GaitCommandT::COMMAND_STOP => self.throttle.log(self.bridge.system_stop(&c.reason)),
                GaitCommandT::COMMAND_RESUME => self.throttle.log(self.bridge.resume()),
                _ => {}
            }
        }
        while let Ok(m) = self.rx.try_recv() {
            self.throttle.log(self.bridge.on_trajectory(&m, now));
        }
        self.throttle.log(self.bridge.tick(now));
        let h = self.bridge.health().clone();
        node.set_health(h.state, h.detail);
        let publisher = node.lcm();
        // Idle, the states go out less often; a trajectory brings the full rate back at once.
        let still = self.bridge.still();
        let due = if still {
            self.next_state + (self.idle_period - self.period)
        } else {
            self.next_state
        };
        let mut next_state = due;
        if now >= due {
            self.next_state = if still {
                now + self.period
            } else {
                (self.next_state + self.period).max(now)
            };
            next_state = self.next_state;
            let msg = self.bridge.states(self.states.stamp());
            if let Err(e) = publisher.publish(&self.cfg.state_channel, &msg) {
                tracing::warn!(error = %e, "could not publish joint states");
            }
        }
        self.status_pending |= self.bridge.take_changed();
        if self.status_pace.take(now, self.status_pending) {
            self.status_pending = false;
            let msg = self.bridge.status(self.statuses.stamp(), node.name());
            if let Err(e) = publisher.publish(&self.cfg.trajectory_status_channel, &msg) {
                tracing::warn!(error = %e, "could not publish the trajectory status");
            }
        }
        let status = self
            .status_pace
            .wake(self.status_pending)
            .unwrap_or(now + Duration::from_secs(1));
        Ok(self.bridge.next_wake().min(next_state).min(status))
    }

    fn stop(mut self, _node: &Node) -> anyhow::Result<()> {
        tracing::info!("stopping the joints, then disabling the drives");
        let s = self.bridge.shutdown();
        for e in &s.failed {
            tracing::error!("shutdown: {e}");
        }
        if !s.standstill {
            tracing::warn!(
                "the joints were still moving after {:?}; torque off",
                s.stopping
            );
        }
        Ok(())
    }
}
