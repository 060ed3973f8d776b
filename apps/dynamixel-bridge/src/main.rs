//! `stride-dynamixel-bridge`: LCM joint commands to a chain of Dynamixel servos, joint states
//! and servo health back.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, Context};
use clap::Parser;
use stride_dynamixel::{models, Protocol};
use stride_dynamixel_bridge::{health, joint_state, Bridge, BridgeConfig};
use stride_dynamixel_bus::{Bus, BusConfig};
use stride_dynamixel_chain::Chain;
use stride_fakes::dynamixel::{ChainLevers, FakeChain, Servo};
use stride_lcmtypes::stride::{JointCommandT, NodeStatusT};
use stride_node::{load_config, Node, NodeArgs, Stamper, Throttle, Ticker};
use stride_serial::{Paced, Transport};

/// Drive a chain of Dynamixel servos (Protocol 1.0 or 2.0) from LCM joint commands.
///
/// At start it pings every configured servo, checks each is the configured model, sets its
/// return delay time, position limits (from the joint limits), speed limit and, on Protocol
/// 2.0 servos, the bus watchdog (bus_watchdog_ms: the servos stop on their own when the bridge
/// stops talking; AX-12A and other 1.0 servos have none), and turns the torque on; it refuses
/// to run otherwise, naming the servo. Each cycle it writes every goal in one sync write and
/// reads every servo's position, speed, load or current, voltage and temperature (fast sync
/// read on 2.0; bulk read on 1.0 MX chains; one read per servo on AX chains), and publishes
/// joint states and servo health. A lost reply is asked for again within a deadline computed
/// from the wire time. Commands with a joint named twice, or beyond a joint's position or
/// velocity limit, are refused whole and reported, never clipped. When commands stop for
/// hold_timeout_ms the servos hold where they are. When the port vanishes (the adapter
/// unplugged) the bridge says so once, tries to open it again with a doubling delay, and when
/// it is back brings the servos up again, holding where they stand. On shutdown the torque
/// goes off.
///
/// With --scan it lists what answers on the bus and exits. With port = "sim" the servos are
/// fakes in this process. See config/robots/hexapod-dynamixel.toml.
#[derive(Parser, Debug)]
#[command(version, about, long_about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    /// List the servos that answer on the bus (ids 0..=252, or --scan-ids) and exit.
    #[arg(long)]
    scan: bool,
    /// Ids to scan, as FIRST-LAST.
    #[arg(long, default_value = "0-252", value_parser = parse_range)]
    scan_ids: (u8, u8),
    /// How long each ping may wait beyond its wire time, ms.
    #[arg(long, default_value_t = 5)]
    scan_wait_ms: u64,
}

fn parse_range(s: &str) -> Result<(u8, u8), String> {
    let (a, b) = s.split_once('-').ok_or("FIRST-LAST, e.g. 1-18")?;
    let (a, b) = (
        a.trim().parse::<u8>().map_err(|e| e.to_string())?,
        b.trim().parse::<u8>().map_err(|e| e.to_string())?,
    );
    if a > b || b > 252 {
        return Err("ids run from 0 to 252, FIRST <= LAST".into());
    }
    Ok((a, b))
}

type Sim = (Arc<AtomicBool>, std::thread::JoinHandle<FakeChain>);

/// The line to the servos: a serial device, or fake servos on a pty in this process.
fn open_line(
    cfg: &BridgeConfig,
    protocol: Protocol,
) -> anyhow::Result<(Box<dyn Transport>, Option<Sim>)> {
    if cfg.port == "sim" {
        let (host, dev) = stride_serial::pty_pair(cfg.baud)?;
        let servos = cfg
            .servo
            .iter()
            .filter_map(|s| models::by_name(&s.model).map(|m| Servo::new(s.id, m)))
            .collect();
        let stop = Arc::new(AtomicBool::new(false));
        let chain = FakeChain::new(protocol, servos, ChainLevers::default())
            .at_baud(cfg.baud)
            .spawn(Paced::new(dev), stop.clone());
        return Ok((Box::new(host), Some((stop, chain))));
    }
    let line = stride_serial::open(&cfg.port, cfg.baud)
        .with_context(|| format!("opening the servo line {}", cfg.port))?;
    Ok((Box::new(line), None))
}

fn scan(cli: &Cli, cfg: &BridgeConfig, protocol: Protocol) -> anyhow::Result<()> {
    let (line, sim) = open_line(cfg, protocol)?;
    let mut bus = Bus::new(line, BusConfig::new(protocol));
    let (a, b) = cli.scan_ids;
    let found = bus.scan(a..=b, Duration::from_millis(cli.scan_wait_ms));
    println!(
        "{} servo(s) on {} at {} baud (Protocol {:?}):",
        found.len(),
        cfg.port,
        cfg.baud,
        protocol
    );
    for (id, number) in found {
        let model = models::by_number(number).map_or("unknown model", |m| m.name.as_str());
        let joint = cfg
            .servo
            .iter()
            .find(|s| s.id == id)
            .map_or(String::new(), |s| format!("  (configured: {})", s.name));
        println!("  id {id:3}  model {number:5}  {model}{joint}");
    }
    if let Some((stop, h)) = sim {
        stop.store(true, Ordering::Relaxed);
        let _ = h.join();
    }
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let cfg: BridgeConfig = load_config(cli.node.config.as_deref())?;
    let protocol = cfg.check().map_err(anyhow::Error::msg)?;
    if cli.scan {
        stride_node::init_logging(&cli.node.log_level);
        return scan(&cli, &cfg, protocol);
    }
    let node = Node::start("stride-dynamixel-bridge", &cli.node)?;
    node.set_health(NodeStatusT::STATE_STARTING, "checking the servos");
    let (line, sim) = open_line(&cfg, protocol)?;
    let mut chain = Chain::new(line, cfg.chain()).map_err(anyhow::Error::msg)?;
    if let Err(e) = chain.bring_up() {
        node.set_health(NodeStatusT::STATE_FAULT, format!("refusing to start: {e}"));
        bail!("refusing to start: {e}");
    }
    tracing::info!(
        servos = cfg.servo.len(),
        port = cfg.port.as_str(),
        "servos ready, torque on"
    );
    let mut bridge = Bridge::new(chain, cfg.reconnect_ms);
    // Listen before saying so: a command sent on seeing RUNNING must not be lost.
    let (_sub, rx) = node.queue::<JointCommandT>(&cfg.command_channel)?;
    node.set_running();
    let publisher = node.publisher();
    let mut throttle = Throttle::new(Duration::from_secs(5));
    let mut stamper = Stamper::new("");
    let mut ticker = Ticker::new(cfg.rate_hz);
    while let Some(now) = ticker.wait(&node)? {
        while let Ok(m) = rx.try_recv() {
            throttle.log(bridge.on_command(&m, now));
        }
        let reopen = || -> std::io::Result<Box<dyn Transport>> {
            Ok(Box::new(stride_serial::open(&cfg.port, cfg.baud)?))
        };
        throttle.log(bridge.tick(now, reopen));
        let (state, detail) = bridge.health();
        node.set_health(state, detail);
        if !bridge.up() {
            continue;
        }
        let header = stamper.stamp();
        let states = joint_state(bridge.chain(), header.clone());
        if let Err(e) = publisher.publish(&cfg.state_channel, &states) {
            tracing::warn!(error = %e, "could not publish joint states");
        }
        let _ = publisher.publish(
            &cfg.health_channel,
            &health(bridge.chain(), &cfg.port, header),
        );
    }
    tracing::info!("torque off");
    if let Err(e) = bridge.torque_off() {
        tracing::error!("could not turn the torque off: {e}");
    }
    if let Some((stop, h)) = sim {
        stop.store(true, Ordering::Relaxed);
        let _ = h.join();
    }
    Ok(())
}
