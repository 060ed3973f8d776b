//! The simulated world as an app: its command line and its loop.

use std::path::PathBuf;
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use anyhow::Context;
use stride_lcmtypes::stride::{JointStateT, NodeStatusT};
use stride_node::{AppConfig, ConfigUse, Node, NodeArgs, Paced, Period, Stamper, Tick};
use stride_world::scene::Scene;

use crate::{Robot, Sim, SimConfig};

/// The simulated world.
///
/// Loads a scene and the robot's file (Archie, or the hexapod with robot = "hexapod"), reads
/// the true joint positions the fake devices publish on sim-only channels (the fake Elmo
/// drives, the Dynamixel bridge's fake servos), and moves the body kinematically. Archie: the
/// stance foot stays where it stands, a foot the joints push into the ground takes over, set
/// down on the scene's surface. The hexapod: the feet on the ground stay where they stand,
/// the body level on its lowest feet, a foot that comes down touches down. Publishes the
/// body's true pose (SIM_POSE), a noisy odometry and IMU, perfect perception of the scene with
/// noise and delay (the obstacles and an elevation map around the robot, on the mapper's
/// channels) and a report (SIM_REPORT): the feet, the smallest ZMP margin (the hexapod's:
/// static) and clearance, collisions with an obstacle, falls (the whole body's ZMP of its point
/// masses, or the hexapod's body centre, outside the support polygon) and joints at their
/// limits. The same seed gives the same noise.
///
/// See config/sim-archie.toml and config/sim-hexapod.toml.
#[derive(clap::Parser, Debug)]
#[command(name = "stride-sim", version, about, long_about)]
pub struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    /// The scene (config/scenes/...), instead of the configuration's.
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,
    /// The seed of every noise, instead of the configuration's.
    #[arg(long, value_name = "N")]
    pub seed: Option<u64>,
}

stride_node::node_cli!(Cli);

impl AppConfig for SimConfig {
    const USE: ConfigUse =
        ConfigUse::Required("the scene and the robot; see config/sim-archie.toml");
    fn check(&self) -> Result<(), String> {
        SimConfig::check(self)
    }
}

/// The running simulator.
pub struct SimApp {
    sim: Sim,
    /// The configuration (the run's copy is the simulation's).
    cfg: SimConfig,
    scene: String,
    _subs: Vec<lcm::Subscription>,
    joints: Vec<Receiver<JointStateT>>,
    t0: Instant,
    /// The wall clock at `t0`, µs.
    utime0: i64,
    /// The time of the last measurement the body moved to, s.
    last_step: f64,
    /// Which channels brought a measurement since the body last moved.
    fresh: Vec<bool>,
    period: Period,
    odometry: Paced,
    imu: Paced,
    perception: Period,
    report: Paced,
    stamps: [Stamper; 6],
    ready: bool,
}

impl SimApp {
    /// Loads the scene and the robot, and subscribes.
    pub fn start(node: &Node, mut cfg: SimConfig, cli: &Cli) -> anyhow::Result<SimApp> {
        let file = cli.node.config.as_deref();
        let scene_path = match (&cli.scene, &cfg.scene) {
            (Some(s), _) => s.clone(),
            (None, Some(s)) => cfg.relative(file, s),
            (None, None) => {
                anyhow::bail!("no scene: give --scene FILE or scene in the configuration")
            }
        };
        let scene =
            // The scene's error names its file already ("scene PATH: why", once).
            Scene::load(&scene_path).map_err(|e| anyhow::anyhow!("scene {e}"))?;
        let robot_path = cfg.relative(file, &cfg.robot_file);
        let robot = Robot::load(cfg.robot, &robot_path)
            .with_context(|| format!("robot file {}", robot_path.display()))?;
        if let Some(seed) = cli.seed {
            cfg.seed = seed;
        }
        let mut subs = Vec::new();
        let mut joints = Vec::new();
        for ch in &cfg.true_joint_channels {
            let (s, r) = node.queue::<JointStateT>(ch)?;
            subs.push(s);
            joints.push(r);
        }
        node.set_health(NodeStatusT::STATE_STARTING, "waiting for the true joints");
        tracing::info!(scene = %scene.name, seed = cfg.seed, "simulating");
        let fresh = vec![false; joints.len()];
        Ok(SimApp {
            period: Period::hz(cfg.rate_hz),
            odometry: Paced::hz(cfg.odometry.rate_hz, cfg.idle_rate_hz),
            imu: Paced::hz(cfg.imu.rate_hz, cfg.idle_rate_hz),
            perception: Period::hz(cfg.perception.rate_hz),
            report: Paced::hz(cfg.report_rate_hz, cfg.idle_rate_hz),
            scene: scene.name.clone(),
            sim: Sim::new(cfg.clone(), scene, robot)?,
            cfg,
            _subs: subs,
            joints,
            t0: Instant::now(),
            utime0: lcm::now_utime(),
            last_step: f64::NEG_INFINITY,
            fresh,
            stamps: std::array::from_fn(|_| Stamper::new("world")),
            ready: false,
        })
    }
}

impl Tick for SimApp {
    const WAKE_ON_MESSAGE: bool = false;

    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        let t = now.saturating_duration_since(self.t0).as_secs_f64();
        // Each measurement moves the body at its own time (its header's), in order: the fit of
        // the COM's acceleration needs the times the joints were where they were, not when
        // the messages were read.
        // The body moves once every channel has a newer measurement (the legs' drives publish
        // apart): a sample of the whole robot at one time, not one leg's fresh and the
        // other's stale.
        let mut msgs: Vec<(usize, JointStateT)> = self
            .joints
            .iter()
            .enumerate()
            .flat_map(|(k, rx)| rx.try_iter().map(move |m| (k, m)))
            .collect();
        msgs.sort_by_key(|(_, m)| m.header.utime);
        let mut moved = false;
        for (k, m) in msgs {
            self.sim.take_joints(&m);
            self.fresh[k] = true;
            if self.fresh.iter().all(|f| *f) {
                self.fresh.iter_mut().for_each(|f| *f = false);
                let at = (m.header.utime - self.utime0) as f64 * 1e-6;
                if at > self.last_step {
                    self.last_step = at;
                    moved = true;
                    for e in self.sim.step(at) {
                        tracing::info!("{e}");
                    }
                }
            }
        }
        let p = node.publisher();
        if !self.sim.ready() {
            if t > 5.0 {
                node.set_health(
                    NodeStatusT::STATE_STARTING,
                    format!("waiting for the true joints: {:?}", self.sim.missing()),
                );
            }
            return Ok(self.period.next(now));
        }
        if !self.ready {
            self.ready = true;
            node.set_running();
        }
        let cfg = &self.cfg;
        // The true pose goes out with each move of the body (as often as the drives' true
        // positions come: every 10 ms walking, less often standing).
        if moved {
            if let Some(m) = self.sim.pose_msg(self.stamps[0].stamp()) {
                p.publish(&cfg.pose_channel, &m)?;
            }
        }
        // At rest, the sensors and the report at the idle rate.
        let rest = self.sim.resting(self.last_step);
        if !cfg.odometry.channel.is_empty() && self.odometry.take(now, rest) {
            if let Some(m) = self.sim.odometry_msg(self.stamps[1].stamp()) {
                p.publish(&cfg.odometry.channel, &m)?;
            }
        }
        if !cfg.imu.channel.is_empty() && self.imu.take(now, rest) {
            if let Some(m) = self.sim.imu_msg(self.stamps[2].stamp()) {
                p.publish(&cfg.imu.channel, &m)?;
            }
        }
        if self.perception.due(now) {
            self.perception.next(now);
            let (a, b) = (self.stamps[3].stamp(), self.stamps[4].stamp());
            self.sim.perceive(t, a, b);
        }
        for (obstacles, map) in self.sim.perception_due(t) {
            if !cfg.perception.obstacle_channel.is_empty() {
                p.publish(&cfg.perception.obstacle_channel, &obstacles)?;
            }
            if let (Some(m), false) = (map, cfg.perception.map_channel.is_empty()) {
                p.publish(&cfg.perception.map_channel, &m)?;
            }
        }
        if self.report.take(now, rest) || self.sim.has_events() {
            let m = self.sim.report_msg(self.stamps[5].stamp(), &self.scene);
            p.publish(&cfg.report_channel, &m)?;
        }
        // A body at rest (no new joint sample) is looked at every 20 ms, the sensors' pace.
        let next = self.period.next(now);
        Ok(if moved {
            next
        } else {
            next.max(now + Duration::from_millis(20))
        })
    }
}
