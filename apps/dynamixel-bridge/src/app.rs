//! The bridge as an app: its command line, its line to the servos, its loop and `--scan`.

use std::time::{Duration, Instant};

use anyhow::Context;
use stride_dynamixel::{models, Protocol};
use stride_dynamixel_bus::{Bus, BusConfig};
use stride_dynamixel_chain::Chain;
use stride_fakes::dynamixel::{ChainLevers, ChainProbe, FakeChain, Servo};
use stride_fakes::Sim;
use stride_lcmtypes::stride::{JointCommandT, JointStateT, NodeStatusT};
use stride_node::{outln, AppConfig, ConfigUse, Node, NodeArgs, Period, Stamper, Throttle, Tick};
use stride_serial::{LineSpec, Paced, Transport};

use crate::{health, joint_state, Bridge, BridgeConfig};

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
#[derive(clap::Parser, Debug)]
#[command(name = "stride-dynamixel-bridge", version, about, long_about)]
pub struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    /// List the servos that answer on the bus (ids 0..=252, or --scan-ids) and exit.
    #[arg(long)]
    pub scan: bool,
    /// Ids to scan, as FIRST-LAST.
    #[arg(long, default_value = "0-252", value_parser = parse_range)]
    pub scan_ids: (u8, u8),
    /// How long each ping may wait beyond its wire time, ms.
    #[arg(long, default_value_t = 5)]
    pub scan_wait_ms: u64,
    /// With port = "sim": publish the fake servos' true joint positions (rad, as the bridge
    /// converts counts) on this sim-only channel each cycle, for the simulated world.
    #[arg(long, value_name = "CHANNEL")]
    pub true_state_channel: Option<String>,
}

stride_node::node_cli!(Cli, realtime);

impl AppConfig for BridgeConfig {
    const USE: ConfigUse = ConfigUse::Required(
        "the servos and their line; see config/robots/, e.g. config/robots/hexapod-dynamixel.toml",
    );
    fn check(&self) -> Result<(), String> {
        BridgeConfig::check(self).map(drop)
    }
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

/// The fake servos of a `sim` line, when it is one, and their true positions.
pub type SimServos = Option<(Sim<FakeChain>, ChainProbe)>;

/// The line to the servos: the serial device, or fake servos on a pty in this process
/// (returned with their guard).
pub fn open_line(
    cfg: &BridgeConfig,
    protocol: Protocol,
) -> anyhow::Result<(Box<dyn Transport>, SimServos)> {
    if cfg.port == LineSpec::Sim {
        let (host, dev) = stride_serial::pty_pair(cfg.baud)?;
        let servos = cfg
            .servo
            .iter()
            .filter_map(|s| models::by_name(&s.model).map(|m| Servo::new(s.id, m)))
            .collect();
        let mut sim = Sim::new();
        let chain = FakeChain::new(protocol, servos, ChainLevers::default()).at_baud(cfg.baud);
        let probe = chain.probe();
        sim.add(chain.spawn(Paced::new(dev), sim.flag()));
        return Ok((Box::new(host), Some((sim, probe))));
    }
    let line = cfg
        .port
        .open_device(cfg.baud)
        .with_context(|| format!("opening the servo line {}", cfg.port))?;
    Ok((Box::new(line), None))
}

/// The fake servos' true joint positions (`positions`: id to counts, fractional), converted
/// as the bridge converts what it reads; a servo not moved yet is left out.
pub fn true_state(
    cfg: &BridgeConfig,
    positions: &std::collections::BTreeMap<u8, f64>,
    header: stride_lcmtypes::stride::HeaderT,
) -> JointStateT {
    let mut m = JointStateT {
        header,
        ..Default::default()
    };
    for s in &cfg.servo {
        let (Some(model), Some(c)) = (models::by_name(&s.model), positions.get(&s.id)) else {
            continue;
        };
        let rad = s.direction as f64 * (c - model.center() as f64) * model.rad_per_count()
            + s.zero_offset;
        m.names.push(s.name.clone());
        m.positions.push(rad);
        m.velocities.push(f64::NAN);
        m.currents.push(f64::NAN);
        m.temperatures.push(f32::NAN);
        m.faults.push(0);
    }
    m.num_joints = m.names.len() as i32;
    m
}

/// `--scan`: lists what answers on the line.
pub fn scan(cli: &Cli, cfg: &BridgeConfig) -> anyhow::Result<()> {
    let protocol = cfg.check().map_err(anyhow::Error::msg)?;
    let (line, _sim) = open_line(cfg, protocol)?;
    let mut bus = Bus::new(line, BusConfig::new(protocol));
    let (a, b) = cli.scan_ids;
    let found = bus.scan(a..=b, Duration::from_millis(cli.scan_wait_ms));
    outln!(
        "{} servo(s) on {} at {} baud (Protocol {:?}):",
        found.len(),
        cfg.port,
        cfg.baud,
        protocol
    )?;
    for (id, number) in found {
        let model = models::by_number(number).map_or("unknown model", |m| m.name.as_str());
        let joint = cfg
            .servo
            .iter()
            .find(|s| s.id == id)
            .map_or(String::new(), |s| format!("  (configured: {})", s.name));
        outln!("  id {id:3}  model {number:5}  {model}{joint}")?;
    }
    Ok(())
}

/// The running bridge: the chain's state machine and what it publishes each cycle.
pub struct DynamixelApp {
    // Dropped in this order: the bridge (its line) before the fake servos.
    bridge: Bridge<Box<dyn Transport>>,
    _sim: Option<Sim<FakeChain>>,
    /// The fake servos' true positions and where they go (`--true-state-channel`).
    truth: Option<(ChainProbe, String)>,
    _sub: lcm::Subscription,
    rx: std::sync::mpsc::Receiver<JointCommandT>,
    cfg: BridgeConfig,
    port: String,
    throttle: Throttle,
    stamper: Stamper,
    period: Period,
}

impl DynamixelApp {
    /// Opens the line, brings the servos up and subscribes; refuses to start otherwise.
    pub fn start(node: &Node, cfg: BridgeConfig, cli: &Cli) -> anyhow::Result<DynamixelApp> {
        let protocol = cfg.check().map_err(anyhow::Error::msg)?;
        if cli.true_state_channel.is_some() && cfg.port != LineSpec::Sim {
            anyhow::bail!("--true-state-channel needs port = \"sim\" (fake servos to measure)");
        }
        node.set_health(NodeStatusT::STATE_STARTING, "checking the servos");
        let (line, sim) = open_line(&cfg, protocol)?;
        let (sim, truth) = match sim {
            Some((sim, probe)) => (
                Some(sim),
                cli.true_state_channel.clone().map(|c| (probe, c)),
            ),
            None => (None, None),
        };
        let mut chain = Chain::new(line, cfg.chain()).map_err(anyhow::Error::msg)?;
        if let Err(e) = chain.bring_up() {
            node.set_health(NodeStatusT::STATE_FAULT, format!("refusing to start: {e}"));
            anyhow::bail!("refusing to start: {e}");
        }
        tracing::info!(servos = cfg.servo.len(), port = %cfg.port, "servos ready, torque on");
        // Listen before saying so: a command sent on seeing RUNNING must not be lost.
        let (sub, rx) = node.queue::<JointCommandT>(&cfg.command_channel)?;
        Ok(DynamixelApp {
            bridge: Bridge::new(chain, cfg.reconnect_ms),
            _sim: sim,
            truth,
            _sub: sub,
            rx,
            port: cfg.port.to_string(),
            period: Period::hz(cfg.rate_hz),
            cfg,
            throttle: Throttle::new(Duration::from_secs(5)),
            stamper: Stamper::new(""),
        })
    }
}

impl Tick for DynamixelApp {
    const WAKE_ON_MESSAGE: bool = false;

    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        while let Ok(m) = self.rx.try_recv() {
            self.throttle.log(self.bridge.on_command(&m, now));
        }
        let (port, baud) = (&self.cfg.port, self.cfg.baud);
        let reopen =
            || -> std::io::Result<Box<dyn Transport>> { Ok(Box::new(port.open_device(baud)?)) };
        self.throttle.log(self.bridge.tick(now, reopen));
        let (state, detail) = self.bridge.health();
        node.set_health(state, detail);
        if self.bridge.up() {
            let header = self.stamper.stamp();
            let states = joint_state(self.bridge.chain(), header.clone());
            if let Err(e) = node.lcm().publish(&self.cfg.state_channel, &states) {
                tracing::warn!(error = %e, "could not publish joint states");
            }
            let h = health(self.bridge.chain(), &self.port, header);
            let _ = node.lcm().publish(&self.cfg.health_channel, &h);
        }
        if let Some((probe, channel)) = &self.truth {
            let m = true_state(&self.cfg, &probe.positions(), self.stamper.stamp());
            if let Err(e) = node.lcm().publish(channel, &m) {
                tracing::warn!(error = %e, "could not publish the true joint positions");
            }
        }
        Ok(self.period.next(now))
    }

    fn stop(mut self, _node: &Node) -> anyhow::Result<()> {
        tracing::info!("torque off");
        if let Err(e) = self.bridge.torque_off() {
            tracing::error!("could not turn the torque off: {e}");
        }
        Ok(())
    }
}
