//! `stride-fake-elmo`: the fake Elmo drives of a bridge's configuration, each a CANopen node
//! as the real drive is (boot-up, SDO, PDOs, CiA 402, PVT tables, heartbeat consumer), on a
//! CAN bus carried over LCM: the frames published on `CAN_<BUS>_TX` go onto the bus, what the
//! drives send comes out on `CAN_<BUS>_RX`, as a stride-usb2can gateway in front of real
//! drives does. So stride-elmo-bridge with `--bus lcm:<BUS>` drives them from its own
//! process, and anyone can sniff the bus. The drives' true joint positions (the motors'
//! positions through the joints' gears, as an instrument on the robot would measure them) go
//! out on a sim-only channel for the simulated world.

use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use lcm::now_utime;
use stride_can_lcm::{batch, frame_to_msg, msg_to_frame, rx_channel, tx_channel};
use stride_canbus::{CanBus, MemBus, MemNode};
use stride_elmo_bridge::BridgeConfig;
use stride_fakes::elmo::{ElmoConfig, FakeElmo, Levers};
use stride_lcmtypes::stride::{CanFrameBatchT, JointStateT};
use stride_node::{Node, NodeArgs, Stamper, Tick};

/// Fake Elmo drives on a CAN bus carried over LCM.
///
/// Runs one fake drive for each joint of a stride-elmo-bridge configuration (its node id,
/// counts per revolution and gear ratio) on CAN bus BUS carried over LCM (CAN_<BUS>_TX in,
/// CAN_<BUS>_RX out), and publishes the drives' true joint positions on --true-state-channel.
/// Start it, then stride-elmo-bridge --config FILE --bus lcm:BUS.
#[derive(clap::Parser, Debug)]
#[command(name = "stride-fake-elmo", version, about, long_about)]
pub struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    /// The bus's name in the LCM channels (CAN_<BUS>_TX / _RX).
    #[arg(long, value_name = "BUS")]
    pub bus_name: String,
    /// Where the drives' true joint positions go (stride.joint_state_t).
    #[arg(long, value_name = "CHANNEL")]
    pub true_state_channel: String,
    /// Rate of the true joint positions while a drive moves, Hz.
    #[arg(long, default_value_t = 100.0, value_name = "HZ")]
    pub rate: f64,
    /// Rate of the true joint positions while every drive holds still, Hz (the drives then
    /// step every 20 ms between the frames they answer, not every millisecond).
    #[arg(long, default_value_t = 10.0, value_name = "HZ")]
    pub idle_rate: f64,
}

stride_node::node_cli!(Cli, realtime);

/// The running drives.
pub struct Rig {
    bus_name: String,
    rx: String,
    channel: String,
    _sub: lcm::Subscription,
    tx: Receiver<CanFrameBatchT>,
    gateway: MemNode,
    drives: Vec<(FakeElmo, MemNode, String, f64)>,
    /// The true positions' periods, moving and idle, and when they last went out.
    period: Duration,
    idle: Duration,
    last_state: Option<Instant>,
    frames: Stamper,
    states: Stamper,
}

impl Rig {
    /// Powers the drives up on the bus and subscribes to its frames.
    pub fn start(node: &Node, cfg: &BridgeConfig, cli: &Cli) -> anyhow::Result<Rig> {
        if !(cli.rate.is_finite() && cli.rate > 0.0 && cli.rate <= 1000.0) {
            anyhow::bail!("--rate must be in (0, 1000] Hz");
        }
        if !(cli.idle_rate.is_finite() && cli.idle_rate > 0.0 && cli.idle_rate <= cli.rate) {
            anyhow::bail!("--idle-rate must be in (0, --rate] Hz");
        }
        let bus = MemBus::new(cfg.bitrate);
        let drives = cfg
            .joint
            .iter()
            .map(|j| {
                (
                    FakeElmo::new(ElmoConfig::new(j.node), Levers::default()),
                    bus.node(),
                    j.name.clone(),
                    j.counts_per_rad(),
                )
            })
            .collect();
        let (sub, tx) = node.queue::<CanFrameBatchT>(&tx_channel(&cli.bus_name))?;
        sub.set_queue_capacity(1000)?;
        node.set_running();
        tracing::info!(
            bus = cli.bus_name.as_str(),
            drives = cfg.joint.len(),
            "fake drives powered up"
        );
        Ok(Rig {
            bus_name: cli.bus_name.clone(),
            rx: rx_channel(&cli.bus_name),
            channel: cli.true_state_channel.clone(),
            _sub: sub,
            tx,
            gateway: bus.node(),
            drives,
            period: Duration::from_secs_f64(1.0 / cli.rate),
            idle: Duration::from_secs_f64(1.0 / cli.idle_rate),
            last_state: None,
            frames: Stamper::new(""),
            states: Stamper::new(""),
        })
    }

    /// The drives' true joint positions and velocities.
    pub fn state(&mut self) -> JointStateT {
        let n = self.drives.len();
        let mut m = JointStateT {
            header: self.states.stamp(),
            num_joints: n as i32,
            currents: vec![f64::NAN; n],
            temperatures: vec![f32::NAN; n],
            faults: vec![0; n],
            ..Default::default()
        };
        for (d, _, name, k) in &self.drives {
            let p = d.probe();
            m.names.push(name.clone());
            m.positions.push(p.position / k);
            m.velocities.push(p.velocity / k);
        }
        m
    }
}

impl Tick for Rig {
    const WAKE_ON_MESSAGE: bool = true;

    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        let deadline = now + Duration::from_millis(5);
        while let Ok(b) = self.tx.try_recv() {
            for f in b.frames.iter().filter_map(|f| msg_to_frame(f).ok()) {
                let _ = self.gateway.send(&f, deadline);
            }
        }
        for (d, bus, _, _) in &mut self.drives {
            d.step(now, bus);
        }
        let mut out = Vec::new();
        while let Ok(Some(f)) = self.gateway.try_recv() {
            out.push(frame_to_msg(&f, now_utime()));
        }
        let p = node.publisher();
        for chunk in out.chunks(stride_can_lcm::BATCH) {
            p.publish(&self.rx, &batch(&self.bus_name, self.frames.stamp(), chunk))?;
        }
        let moving = self.drives.iter().any(|(d, ..)| d.moving());
        let every = if moving { self.period } else { self.idle };
        if self.last_state.is_none_or(|at| now >= at + every) {
            self.last_state = Some(now);
            let m = self.state();
            p.publish(&self.channel, &m)?;
        }
        Ok(now + Duration::from_millis(if moving { 1 } else { 20 }))
    }
}
