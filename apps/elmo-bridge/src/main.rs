//! `stride-elmo-bridge`: joint trajectories from LCM to Elmo drives on CAN, joint states back.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Instant;

use anyhow::{bail, Context};
use clap::Parser;
use stride_canbus::{CanBus, MemBus};
use stride_elmo::{Event, Master, MasterConfig};
use stride_elmo_bridge::{state_msg, trajectory_from_msg, BridgeConfig, Recovery, Watchdog};
use stride_fakes::elmo::{ElmoConfig, FakeElmo, Levers};
use stride_lcmtypes::stride::{JointTrajectoryT, NodeStatusT};
use stride_node::{load_config, Node, NodeArgs, Stamper, Ticker};

/// Drive Elmo motion controllers over CANopen from LCM joint trajectories.
///
/// At start it brings every configured drive up (identity, heartbeat, PDO mapping verified,
/// CiA 402 enable) and refuses to run otherwise. Trajectories (stride.joint_trajectory_t) are
/// checked against every joint's position, velocity and acceleration limits (a trajectory past
/// a limit is rejected whole and reported, never clipped) and streamed as Elmo PVT rows, Elmo
/// PT points (motion = "pt"), or CiA 402 interpolated position set-points (motion = "ip").
/// Joint states are published at the configured rate. A trajectory that ends in motion is a
/// chunk of a stream: when the next one does not come within stream_timeout_ms, every axis
/// quick-stops (a trajectory ending at rest simply plays to its end). When the bus fails
/// (bus-off, a dongle unplugged) the bridge reports it, drops what was not yet played, and
/// brings the drives up again once the bus answers (retrying with a growing delay); a motion
/// cut off is not resumed. On shutdown the drives are disabled. With bus = "sim" fake drives run in this process; with bus =
/// "lcm:NAME" the CAN bus is reached through a stride-usb2can gateway on the LCM network.
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
    #[cfg(feature = "socketcan")]
    if let Some(iface) = cfg.bus.strip_prefix("socketcan:") {
        let bus = stride_canbus::socketcan::SocketCanBus::open(iface)?;
        return Ok((Box::new(bus), None));
    }
    if let Some(path) = cfg.bus.strip_prefix("slcan:") {
        let bus = stride_canbus::slcan::open_path(path, cfg.bitrate)
            .with_context(|| format!("opening the SLCAN dongle on {path}"))?;
        return Ok((Box::new(bus), None));
    }
    bail!(
        "unknown bus {:?}: use \"sim\" or \"slcan:/dev/ttyACM0\"",
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
    let master_cfg = MasterConfig {
        motion: cfg.motion().map_err(anyhow::Error::msg)?,
        ..Default::default()
    };
    let mut master = Master::new(bus, cfg.joint.clone(), master_cfg)?;
    if let Err(e) = master.bring_up() {
        node.set_health(NodeStatusT::STATE_FAULT, format!("bring-up failed: {e}"));
        tracing::error!(error = %e, "bring-up failed");
        return Err(e.into());
    }
    tracing::info!(
        joints = cfg.joint.len(),
        bus = cfg.bus.as_str(),
        "drives enabled"
    );
    // Listen before saying so: a command sent on seeing RUNNING must not be lost.
    let (_sub, rx) = node.queue::<JointTrajectoryT>(&cfg.trajectory_channel)?;
    node.set_running();

    let publisher = node.publisher();
    let mut stamper = Stamper::new("");
    let mut watchdog = Watchdog::new(cfg.stream_timeout_ms);
    let mut ticker = Ticker::new(cfg.state_rate_hz);
    let mut rejected = 0u64;
    let mut recovery = Recovery::new(cfg.recovery_delay_ms);
    while let Some(now) = ticker.wait(&node)? {
        if recovery.pending() {
            // The drives are down: nothing is loaded until they are up again.
            while let Ok(m) = rx.try_recv() {
                rejected += 1;
                tracing::warn!(
                    rejected,
                    joints = m.joint_names.len(),
                    "trajectory rejected: the drives are down"
                );
            }
            if !recovery.due(now) {
                continue;
            }
            match master.recover() {
                Ok(()) => {
                    recovery.succeeded();
                    tracing::info!("drives up again");
                    node.set_running();
                }
                Err(e) => {
                    recovery.failed(Instant::now());
                    tracing::warn!(error = %e, "drives still down");
                    node.set_health(NodeStatusT::STATE_FAULT, format!("recovering: {e}"));
                    continue;
                }
            }
        }
        while let Ok(m) = rx.try_recv() {
            match master.load(&trajectory_from_msg(&m)) {
                Ok(()) => watchdog.feed(now),
                Err(e) => {
                    rejected += 1;
                    tracing::warn!(error = %e, rejected, "trajectory rejected");
                    node.set_health(
                        NodeStatusT::STATE_DEGRADED,
                        format!("trajectory rejected: {e}"),
                    );
                }
            }
        }
        if let Err(e) = master.pump(now) {
            // Bus-off or a dead interface: report it, then bring the drives up again once the
            // bus answers; the drives stop on their own when their tables run dry.
            tracing::error!(error = %e, "CAN cycle failed");
            node.set_health(
                NodeStatusT::STATE_FAULT,
                format!("CAN: {e}; bringing the drives up again when the bus answers"),
            );
            recovery.failed(now);
            continue;
        }
        for e in master.take_events() {
            match &e {
                Event::Emergency { joint, text, emcy } => {
                    tracing::warn!(joint = joint.as_str(), "emergency: {text}");
                    // Queue-low is routine (a refill request); anything else is published.
                    let routine = matches!(
                        stride_canopen::emcy::ElmoEmcy::from_emcy(emcy),
                        Some(stride_canopen::emcy::ElmoEmcy::QueueLow { .. })
                            | Some(stride_canopen::emcy::ElmoEmcy::MotionTerminated {
                                reason: 1 | 3,
                                ..
                            })
                    );
                    if !routine {
                        node.set_health(
                            NodeStatusT::STATE_DEGRADED,
                            format!("{joint}: emergency {:#06x}: {text}", emcy.code),
                        );
                    }
                }
                Event::HeartbeatLost { joint } => {
                    tracing::error!(joint = joint.as_str(), "heartbeat lost");
                    node.set_health(NodeStatusT::STATE_FAULT, format!("{joint}: heartbeat lost"));
                }
                Event::Rebooted { joint } => {
                    // One axis lost its state: stop them all, then bring them all up again.
                    tracing::error!(
                        joint = joint.as_str(),
                        "drive reset: quick stop, then recovery"
                    );
                    let _ = master.quick_stop();
                    node.set_health(
                        NodeStatusT::STATE_FAULT,
                        format!("{joint}: drive reset; bringing the drives up again"),
                    );
                    recovery.failed(now);
                }
                Event::InterpreterError {
                    joint,
                    command,
                    code,
                } => {
                    tracing::error!(joint = joint.as_str(), command, code, "drive refused");
                    node.set_health(
                        NodeStatusT::STATE_DEGRADED,
                        format!("{joint}: the drive refused {command} (error {code})"),
                    );
                }
            }
        }
        // A move that ends at rest plays out; a stream cut in motion is stopped.
        if watchdog.expired(now, master.idle() || master.ends_at_rest()) {
            tracing::warn!("trajectory stream stopped mid-motion: quick stop");
            master.quick_stop()?;
            node.set_health(
                NodeStatusT::STATE_DEGRADED,
                "trajectory stream stopped: quick stop",
            );
        }
        let msg = state_msg(&master.states(), stamper.stamp());
        if let Err(e) = publisher.publish(&cfg.state_channel, &msg) {
            tracing::warn!(error = %e, "could not publish joint states");
        }
    }
    tracing::info!("disabling the drives");
    master.disable()?;
    if let Some((stop, drives)) = sim {
        stop.store(true, Ordering::Relaxed);
        for d in drives {
            let _ = d.join();
        }
    }
    Ok(())
}
