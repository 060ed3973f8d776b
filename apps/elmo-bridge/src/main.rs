//! `stride-elmo-bridge`: joint trajectories from LCM to Elmo drives on CAN, joint states back.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use clap::Parser;
use stride_canbus::{CanBus, MemBus};
use stride_elmo::Master;
use stride_elmo_bridge::{Bridge, BridgeConfig};
use stride_fakes::elmo::{ElmoConfig, FakeElmo, Levers};
use stride_lcmtypes::stride::{JointTrajectoryT, NodeStatusT};
use stride_node::{load_config, Node, NodeArgs, Stamper, Throttle};

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
/// answers. Joint states go out at state_rate_hz, the bridge's trajectory status
/// (stride.trajectory_status_t) once a second and on every change. On shutdown the joints
/// decelerate to a stop, then the drives are disabled.
///
/// bus = "sim" runs fake drives in this process; "slcan:/dev/ttyACM0" a USB2CAN dongle;
/// "lcm:NAME" a bus behind a stride-usb2can gateway on the LCM network; "socketcan:can0" a
/// kernel interface (build with --features socketcan). See config/robots/archie-left-leg.toml.
#[derive(Parser, Debug)]
#[command(version, about, long_about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
}

type Sim = (Arc<AtomicBool>, Vec<JoinHandle<FakeElmo>>);

fn open_bus<'a>(
    cfg: &BridgeConfig,
    lcm: &'a lcm::Lcm,
) -> anyhow::Result<(Box<dyn CanBus + 'a>, Option<Sim>)> {
    if let Some(name) = cfg.bus.strip_prefix("lcm:") {
        let bus = stride_can_lcm::LcmBus::new(lcm, name)
            .with_context(|| format!("joining CAN bus {name} over LCM"))?;
        return Ok((Box::new(bus), None));
    }
    if cfg.bus == "sim" {
        let bus = MemBus::new(cfg.bitrate);
        let stop = Arc::new(AtomicBool::new(false));
        let drives = cfg
            .joint
            .iter()
            .map(|j| {
                FakeElmo::new(ElmoConfig::new(j.node), Levers::default())
                    .spawn(bus.node(), stop.clone())
            })
            .collect();
        return Ok((Box::new(bus.node()), Some((stop, drives))));
    }
    if let Some(iface) = cfg.bus.strip_prefix("socketcan:") {
        #[cfg(feature = "socketcan")]
        return Ok((
            Box::new(stride_canbus::socketcan::SocketCanBus::open(iface)?),
            None,
        ));
        #[cfg(not(feature = "socketcan"))]
        bail!("bus socketcan:{iface}: this build has no SocketCAN backend (build with --features socketcan)");
    }
    if let Some(path) = cfg.bus.strip_prefix("slcan:") {
        let bus = stride_canbus::slcan::open_path(path, cfg.bitrate)
            .with_context(|| format!("opening the SLCAN dongle on {path}"))?;
        return Ok((Box::new(bus), None));
    }
    bail!(
        "unknown bus {:?}: use \"sim\", \"slcan:/dev/ttyACM0\", \"lcm:NAME\" or \"socketcan:can0\"",
        cfg.bus
    )
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let cfg: BridgeConfig = load_config(cli.node.config.as_deref())?;
    cfg.check().map_err(anyhow::Error::msg)?;
    let node = Node::start("stride-elmo-bridge", &cli.node)?;
    node.set_health(NodeStatusT::STATE_STARTING, "bringing up the drives");
    let (bus, sim) = open_bus(&cfg, node.lcm())?;
    let master_cfg = cfg.master().map_err(anyhow::Error::msg)?;
    let mut master = Master::new(bus, cfg.joint.clone(), master_cfg)?;
    if let Err(e) = master.bring_up() {
        node.set_health(NodeStatusT::STATE_FAULT, format!("bring-up failed: {e}"));
        bail!("bring-up failed: {e}");
    }
    tracing::info!(
        joints = cfg.joint.len(),
        bus = cfg.bus.as_str(),
        "drives enabled"
    );
    let mut bridge = Bridge::new(master, cfg.recovery_delay_ms);
    // Listen before saying so: a trajectory sent on seeing RUNNING must not be lost.
    let (_sub, rx) = node.queue::<JointTrajectoryT>(&cfg.trajectory_channel)?;
    node.set_running();
    let publisher = node.publisher();
    let mut throttle = Throttle::new(Duration::from_secs(5));
    let (mut states, mut statuses) = (Stamper::new(""), Stamper::new(""));
    let period = Duration::from_secs_f64(1.0 / cfg.state_rate_hz);
    let (mut next_state, mut next_status) = (Instant::now(), Instant::now());
    while node.running() {
        let wake = bridge.next_wake().min(next_state).min(next_status);
        if node
            .lcm()
            .handle_timeout(wake.saturating_duration_since(Instant::now()))?
        {
            node.lcm().handle_pending()?;
        }
        let now = Instant::now();
        while let Ok(m) = rx.try_recv() {
            throttle.log(bridge.on_trajectory(&m, now));
        }
        throttle.log(bridge.tick(now));
        let h = bridge.health().clone();
        node.set_health(h.state, h.detail);
        if now >= next_state {
            next_state = (next_state + period).max(now);
            if let Err(e) = publisher.publish(&cfg.state_channel, &bridge.states(states.stamp())) {
                tracing::warn!(error = %e, "could not publish joint states");
            }
        }
        if bridge.take_changed() || now >= next_status {
            next_status = now + Duration::from_secs(1);
            let msg = bridge.status(statuses.stamp(), node.name());
            if let Err(e) = publisher.publish(&cfg.trajectory_status_channel, &msg) {
                tracing::warn!(error = %e, "could not publish the trajectory status");
            }
        }
    }
    tracing::info!("stopping the joints, then disabling the drives");
    let s = bridge.shutdown();
    for e in &s.failed {
        tracing::error!("shutdown: {e}");
    }
    if !s.standstill {
        tracing::warn!(
            "the joints were still moving after {:?}; torque off",
            s.stopping
        );
    }
    drop(bridge);
    if let Some((stop, drives)) = sim {
        stop.store(true, Ordering::Relaxed);
        for d in drives {
            let _ = d.join();
        }
    }
    Ok(())
}
