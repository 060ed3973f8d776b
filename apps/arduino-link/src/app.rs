//! The link as an app: its command line and its loop, a state machine that connects (again
//! when the port comes back), feeds the board's watchdog and turns its frames into messages.

use std::time::{Duration, Instant};

use stride_fakes::due::{DueConfig, DueLevers, FakeDue};
use stride_fakes::Sim;
use stride_lcmtypes::stride::{JointCommandT, JointStateT, NodeStatusT};
use stride_link::Message;
use stride_link_host::{Board, BoardConfig, BoardEvent};
use stride_node::{AppConfig, ConfigUse, Node, NodeArgs, Period, Stamper, Tick};
use stride_serial::{LineSpec, Paced, Transport};

use crate::{imu, imu_msg, state_msgs, Attitude, LinkConfig};

/// Drive one Arduino Due joint-controller board (a leg of Archie) from LCM.
///
/// Joint commands (stride.joint_command_t: duty, position, brake or disable) are checked
/// against the configured limits (a command past one is refused whole and reported, never
/// clipped) and sent to the board; heartbeats keep the board's watchdog fed when there are
/// none. The board's joint states go out as stride.arduino_joint_state_t and
/// stride.joint_state_t, its MPU-6050 samples as stride.imu_t with the hip's attitude from a
/// complementary filter, its faults in the node status. At connect it checks the link version
/// in a handshake, waiting out the reset that opening the port causes; when the port vanishes
/// (the cable pulled) it says so, reopens it when it is back, and handshakes again. A joint
/// above current_limit_a is braked. On shutdown every joint is braked. See
/// config/robots/archie-arduino-left-leg.toml.
#[derive(clap::Parser, Debug)]
#[command(name = "stride-arduino-link", version, about, long_about)]
pub struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    /// With port = "sim": publish the fake board's true joint positions (rad) on this
    /// sim-only channel each cycle, for the simulated world.
    #[arg(long, value_name = "CHANNEL")]
    pub true_state_channel: Option<String>,
}

stride_node::node_cli!(Cli, realtime);

impl AppConfig for LinkConfig {
    const USE: ConfigUse = ConfigUse::Required(
        "the board's port and joints; see config/robots/, e.g. config/robots/archie-arduino-left-leg.toml",
    );
    fn check(&self) -> Result<(), String> {
        LinkConfig::check(self)
    }
}

/// The running link: connected to the board or trying to be.
pub struct ArduinoApp {
    // Dropped in this order: the board's session (its line) before the fake board.
    board: Option<Board<Box<dyn Transport>>>,
    sim: Option<Sim<FakeDue>>,
    _sub: lcm::Subscription,
    rx: std::sync::mpsc::Receiver<JointCommandT>,
    cfg: LinkConfig,
    stamper: Stamper,
    period: Period,
    next_try: Instant,
    attitude: Attitude,
    last_imu: Option<u32>,
    imu_raw: ([i16; 3], [i16; 3]),
    rejected: u64,
    /// The last reason the board could not be reached, said once on the console.
    last_failure: String,
    /// The fake board's levers (its true positions) and where they go
    /// (`--true-state-channel`).
    truth: Option<(DueLevers, String, Stamper)>,
}

impl ArduinoApp {
    /// Subscribes; the board is connected on the first tick.
    pub fn start(node: &Node, cfg: LinkConfig, cli: &Cli) -> anyhow::Result<ArduinoApp> {
        if cli.true_state_channel.is_some() && cfg.port != LineSpec::Sim {
            anyhow::bail!("--true-state-channel needs port = \"sim\" (a fake board to measure)");
        }
        let (sub, rx) = node.queue::<JointCommandT>(&cfg.command_channel)?;
        node.set_health(NodeStatusT::STATE_STARTING, "connecting to the board");
        let now = Instant::now();
        Ok(ArduinoApp {
            board: None,
            sim: None,
            _sub: sub,
            rx,
            stamper: Stamper::new(&cfg.board),
            period: Period::hz(cfg.rate_hz),
            next_try: now,
            attitude: Attitude::new(cfg.imu_time_constant_s),
            last_imu: None,
            imu_raw: ([0; 3], [0; 3]),
            rejected: 0,
            last_failure: String::new(),
            truth: cli
                .true_state_channel
                .clone()
                .map(|c| (DueLevers::default(), c, Stamper::new(&cfg.board))),
            cfg,
        })
    }

    /// Opens the board's line: the serial device, or a fake board on a pty in this process.
    fn open(&mut self) -> std::io::Result<Box<dyn Transport>> {
        if self.cfg.port == LineSpec::Sim {
            let (host, dev) = stride_serial::pty_pair(self.cfg.baud)?;
            self.board = None;
            let mut sim = Sim::new();
            let board = FakeDue::new(DueConfig::default());
            let levers = self
                .truth
                .as_ref()
                .map_or_else(DueLevers::default, |t| t.0.clone());
            sim.add(board.spawn(Paced::new(dev), levers, sim.flag()));
            self.sim = Some(sim);
            return Ok(Box::new(host));
        }
        Ok(Box::new(self.cfg.port.open_device(self.cfg.baud)?))
    }

    fn unreachable(&mut self, node: &Node, why: String) {
        let detail = format!("{}: {why}; retrying", self.cfg.port);
        if why != self.last_failure {
            tracing::warn!("{detail} every {} ms", self.cfg.reconnect_ms);
            self.last_failure = why;
        }
        node.set_health(NodeStatusT::STATE_FAULT, detail);
    }

    fn connect(&mut self, node: &Node, now: Instant) {
        while self.rx.try_recv().is_ok() {
            self.rejected += 1;
        }
        if now < self.next_try {
            return;
        }
        self.next_try = now + Duration::from_millis(self.cfg.reconnect_ms);
        let line = match self.open() {
            Ok(line) => line,
            Err(e) => return self.unreachable(node, e.to_string()),
        };
        let handshake = Duration::from_millis(self.cfg.handshake_timeout_ms);
        let watch = BoardConfig {
            current_limit_a: self.cfg.current_limit_a,
            joints: self.cfg.joint.iter().map(|j| j.index).collect(),
            ..BoardConfig::default()
        };
        match Board::connect(line, watch, handshake, Duration::from_millis(250)) {
            Ok((board, b)) => {
                tracing::info!(
                    firmware = b.firmware.as_str(),
                    joints = b.joints,
                    "board connected"
                );
                self.board = Some(board);
                self.attitude = Attitude::new(self.cfg.imu_time_constant_s);
                self.last_imu = None;
                self.last_failure.clear();
                node.set_running();
            }
            Err(e) => self.unreachable(node, e.to_string()),
        }
    }

    /// One turn with the board: commands (or a heartbeat) out, its frames in. An I/O error
    /// (or a silent board) loses the session.
    fn serve(&mut self, node: &Node, now: Instant) -> Result<(), std::io::Error> {
        let Some(board) = self.board.as_mut() else {
            return Ok(());
        };
        // Commands, checked.
        while let Ok(c) = self.rx.try_recv() {
            match self.cfg.to_board(&c) {
                Ok(joints) => board.command(joints, now)?,
                Err(e) => {
                    self.rejected += 1;
                    tracing::warn!(error = %e, rejected = self.rejected, "command rejected");
                    node.set_health(
                        NodeStatusT::STATE_DEGRADED,
                        format!("command rejected: {e}"),
                    );
                }
            }
        }
        let uptime = node.uptime().as_millis() as u32;
        let events = board.pump(now, uptime, Instant::now() + Duration::from_millis(1))?;
        let firmware = board.info().map(|b| b.firmware.clone()).unwrap_or_default();
        let lost = (board.stats().lost + board.stats().bad) as i32;
        let lcm = node.lcm();
        for e in events {
            let m = match e {
                BoardEvent::Message(m) => m,
                BoardEvent::Braked { joint, current_a } => {
                    let who = self.joint_name(joint);
                    node.set_health(
                        NodeStatusT::STATE_DEGRADED,
                        format!("{who}: {:.0} mA over the limit: braked", current_a * 1000.0),
                    );
                    continue;
                }
            };
            match m {
                Message::State { joints, .. } => {
                    let header = self.stamper.stamp();
                    let (a, j) =
                        state_msgs(&self.cfg, header, &firmware, &joints, self.imu_raw, lost);
                    let _ = lcm.publish(&self.cfg.state_channel, &a);
                    let _ = lcm.publish(&self.cfg.joint_state_channel, &j);
                }
                Message::Imu {
                    t_us,
                    accel,
                    temperature,
                    gyro,
                } => {
                    let dt = self
                        .last_imu
                        .map_or(0.0, |t| t_us.wrapping_sub(t) as f64 * 1e-6);
                    self.last_imu = Some(t_us);
                    self.attitude
                        .update(imu::accel_g(accel), imu::gyro_rad_s(gyro), dt);
                    self.imu_raw = (accel, gyro);
                    let msg = imu_msg(
                        self.stamper.stamp(),
                        accel,
                        temperature,
                        gyro,
                        &self.attitude,
                    );
                    let _ = lcm.publish(&self.cfg.imu_channel, &msg);
                }
                Message::Fault {
                    joint,
                    bits,
                    detail,
                } => {
                    let who = self.joint_name(joint);
                    let what = stride_link::fault::names(bits);
                    tracing::warn!(
                        who = who.as_str(),
                        what = what.as_str(),
                        detail,
                        "board fault"
                    );
                    node.set_health(
                        NodeStatusT::STATE_DEGRADED,
                        format!("{who}: fault: {what} ({detail})"),
                    );
                }
                Message::Nack { seq, reason } => {
                    tracing::warn!(seq, reason, "the board refused a frame");
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// The configured name of board joint `index`, or "board".
    fn joint_name(&self, index: u8) -> String {
        self.cfg
            .joint
            .iter()
            .find(|j| j.index == index)
            .map_or_else(|| "board".to_string(), |j| j.name.clone())
    }
}

impl Tick for ArduinoApp {
    const WAKE_ON_MESSAGE: bool = false;

    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        if self.board.is_none() {
            self.connect(node, now);
        } else if let Err(e) = self.serve(node, now) {
            tracing::error!(error = %e, "lost the board; reconnecting");
            node.set_health(
                NodeStatusT::STATE_FAULT,
                format!("{}: {e}; reconnecting", self.cfg.port),
            );
            self.board = None;
            self.next_try = Instant::now() + Duration::from_millis(self.cfg.reconnect_ms);
        }
        if let (Some((levers, channel, stamper)), Some(_)) = (&mut self.truth, &self.sim) {
            let mut m = JointStateT {
                header: stamper.stamp(),
                ..Default::default()
            };
            for j in &self.cfg.joint {
                m.names.push(j.name.clone());
                m.positions.push(levers.position(j.index as usize));
                m.velocities.push(f64::NAN);
                m.currents.push(f64::NAN);
                m.temperatures.push(f32::NAN);
                m.faults.push(0);
            }
            m.num_joints = m.names.len() as i32;
            if let Err(e) = node.lcm().publish(channel, &m) {
                tracing::warn!(error = %e, "could not publish the true joint positions");
            }
        }
        Ok(self.period.next(now))
    }

    fn stop(mut self, _node: &Node) -> anyhow::Result<()> {
        if let Some(b) = self.board.as_mut() {
            tracing::info!("braking every joint");
            let _ = b.command(self.cfg.brake_all(), Instant::now());
            std::thread::sleep(Duration::from_millis(20));
        }
        Ok(())
    }
}
