//! The walking controller as an app: its command line, its subscriptions and its loop. The
//! messages it takes go to the gait's decisions ([`crate::gait`]) and what those say goes out.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use stride_gait::walker::StepCounter;
use stride_lcmtypes::stride::{
    FootstepPlanT, GaitCommandT, ImuT, JointStateT, NodeStatusT, OdometryT, PoseStampedT,
    TrajectoryStatusT,
};
use stride_node::{AppConfig, ConfigUse, Node, NodeArgs, Period, Spaced, Stamper, Tick};

use crate::gait::{Body, Gait, Phase, PLAN_QUEUE};
use crate::group::Group;
use crate::{
    command_msg, counter_msg, trajectory_msg, BridgeWatch, GaitConfig, GoalConfig, Robot,
    ROW_PERIOD,
};

/// The walking controller.
///
/// Archie: takes footstep plans (stride.footstep_plan_t) in step with a replanning planner:
/// it publishes its step counter (stride.step_counter_t), takes the newest plan whose echoed
/// step number is the step under way, steps in place while the plan for the next step is
/// late, stands at the goal, and brings its feet together and stands when no valid plan comes
/// for a while or on a stop command (stride.gait_command_t). Each plan becomes a COM, ZMP and
/// swing pattern (ZMP preview control, the ZMP a centimetre inside the soles, step times
/// stretched where needed) and joint trajectories through the legs' kinematics, checked
/// against the joints' position, speed and acceleration limits: a plan that fails anywhere is
/// refused whole, with its reason in the gait's status (stride.trajectory_status_t) and a
/// counter. The joints go out as PVT trajectory chunks (stride-elmo-bridge) and position
/// set-points (stride-arduino-link). Before the first step the joints are brought from where
/// they are measured to the standing pose; a joint further from the pattern than a tolerance
/// stops the walk and says so.
///
/// The hexapod: walks straight ahead (tripod or wave gait) and the sensing lift on command,
/// each servo's goal and moving speed every control period (stride-dynamixel-bridge).
///
/// See config/gait-archie.toml and config/gait-hexapod.toml.
#[derive(clap::Parser, Debug)]
#[command(name = "stride-gait", version, about, long_about)]
pub struct Cli {
    #[command(flatten)]
    node: NodeArgs,
}

stride_node::node_cli!(Cli, realtime, 1);

impl Cli {
    /// The configuration file given.
    pub fn config_file(&self) -> Option<&Path> {
        self.node.config.as_deref()
    }
}

impl AppConfig for GaitConfig {
    const USE: ConfigUse = ConfigUse::Required(
        "the robot and its joints' channels; see config/gait-archie.toml, config/gait-hexapod.toml",
    );
    fn check(&self) -> Result<(), String> {
        GaitConfig::check(self)
    }
}

/// The running gait: its subscriptions and what paces what it sends.
pub struct GaitApp {
    gait: Gait,
    /// Archie's footstep plans.
    plans: Option<(lcm::Subscription, Receiver<FootstepPlanT>)>,
    commands: Receiver<GaitCommandT>,
    commands_sub: lcm::Subscription,
    stops: Receiver<GaitCommandT>,
    stops_sub: lcm::Subscription,
    goals: Option<(lcm::Subscription, Receiver<PoseStampedT>)>,
    imu: Option<(lcm::Subscription, Receiver<ImuT>)>,
    /// The pelvis's measured pose, which corrects the gait's frame in the world.
    odometry: Option<(lcm::Subscription, Receiver<OdometryT>)>,
    /// Walker time 0: the node's start.
    t0: Instant,
    period: Period,
    counter_period: Period,
    /// The period of what does not change (see `GaitConfig::idle_rate_hz`).
    idle: Duration,
    /// The step counter last sent, and when.
    last_counter: Option<(StepCounter, Instant)>,
    /// Each group's set-point last sent, and when.
    last_set: Vec<Option<(Vec<f64>, Instant)>>,
    /// [`GaitApp::urgent_count`] when last asked.
    urgent_seen: u64,
    status_pace: Spaced,
    counter_stamper: Stamper,
    status_stamper: Stamper,
}

/// The loop's period while the robot stands with nothing to do.
const IDLE_TICK: Duration = Duration::from_millis(20);

/// The gait's status goes out on a change at most this often (a reason whose figure changes
/// every tick does not flood the bus).
const STATUS_GAP: Duration = Duration::from_millis(50);

impl GaitApp {
    /// Loads the robot, builds the gait and subscribes.
    pub fn start(
        node: &Node,
        cfg: GaitConfig,
        config_file: Option<&Path>,
    ) -> anyhow::Result<GaitApp> {
        let (body, groups) = crate::gait::body(&cfg, config_file)?;
        let plans = match body {
            Body::Archie { .. } => {
                let (sub, rx) = node.queue::<FootstepPlanT>(&cfg.plan_channel)?;
                // A burst of plans waits for the loop in liblcm's queue (its default, 30,
                // drops the rest of a burst while a tick makes a pattern): every plan is
                // counted, taken, refused or dropped, never lost unseen.
                sub.set_queue_capacity(PLAN_QUEUE)?;
                Some((sub, rx))
            }
            Body::Hexapod { .. } => None,
        };
        let groups = groups
            .into_iter()
            .map(|(name, joints, ch)| -> anyhow::Result<Group> {
                Ok(Group {
                    trajectory_stamper: Stamper::new(""),
                    command_stamper: Stamper::new(""),
                    speeds: BTreeMap::new(),
                    bridge: match &ch.status {
                        Some(c) => Some(node.queue::<TrajectoryStatusT>(c)?),
                        None => None,
                    },
                    bridge_watch: BridgeWatch::default(),
                    states: match &ch.state {
                        Some(c) => Some(node.queue::<JointStateT>(c)?),
                        None => None,
                    },
                    name,
                    joints,
                    trajectory: ch.trajectory.clone(),
                    command: ch.command.clone(),
                    measured: BTreeMap::new(),
                })
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        let (csub, crx) = node.queue::<GaitCommandT>(&cfg.command_channel)?;
        let (ssub, srx) = node.queue::<GaitCommandT>(&cfg.stop_channel)?;
        let goals = match (&cfg.goal, cfg.robot) {
            (Some(g), Robot::Archie) => Some(node.queue::<PoseStampedT>(&g.channel)?),
            _ => None,
        };
        let imu = match &cfg.imu_channel {
            Some(c) => Some(node.queue::<ImuT>(c)?),
            None => None,
        };
        let odometry = match (&cfg.goal, cfg.robot) {
            (
                Some(GoalConfig {
                    odometry_channel: Some(c),
                    ..
                }),
                Robot::Archie,
            ) => Some(node.queue::<OdometryT>(c)?),
            _ => None,
        };
        node.set_health(
            NodeStatusT::STATE_STARTING,
            "waiting for the joints' states",
        );
        Ok(GaitApp {
            period: Period::hz(cfg.rate_hz),
            counter_period: Period::hz(cfg.step_counter_rate_hz),
            idle: Duration::from_secs_f64(1.0 / cfg.idle_rate_hz),
            last_counter: None,
            last_set: vec![None; groups.len()],
            urgent_seen: 0,
            status_pace: Spaced::new(Duration::from_secs(1), STATUS_GAP),
            counter_stamper: Stamper::new(""),
            status_stamper: Stamper::new(""),
            gait: Gait::new(cfg, body, groups, node.name()),
            plans,
            commands: crx,
            commands_sub: csub,
            stops: srx,
            stops_sub: ssub,
            goals,
            imu,
            odometry,
            t0: Instant::now(),
        })
    }

    /// Walker time of `now`, s.
    fn time(&self, now: Instant) -> f64 {
        now.saturating_duration_since(self.t0).as_secs_f64()
    }

    /// Sets the health the gait gave and sends the plan requests it made.
    fn say(&mut self, node: &Node) -> anyhow::Result<()> {
        for (state, why) in self.gait.health_out.drain(..) {
            node.set_health(state, why);
        }
        for (ch, m) in self.gait.requests_out.drain(..) {
            node.publisher().publish(&ch, &m)?;
        }
        Ok(())
    }

    /// Sends the trajectory bridges the next chunks.
    fn stream(&mut self, node: &Node, t: f64) -> anyhow::Result<()> {
        let gait = &mut self.gait;
        let n = ((gait.cfg.chunk / ROW_PERIOD).round() as usize).max(2);
        while let Some((i0, i1, append)) = gait.stream.next_chunk(t, gait.cfg.lookahead, n) {
            let rows = &gait.stream.rows;
            for g in 0..gait.groups.len() {
                let Some(ch) = gait.groups[g].trajectory.clone() else {
                    continue;
                };
                let k = gait.group_index(g);
                let header = gait.groups[g].trajectory_stamper.stamp();
                let m = trajectory_msg(
                    header,
                    &gait.groups[g].joints,
                    &rows.times[i0..=i1],
                    &rows.pos[k][i0..=i1],
                    &rows.vel[k][i0..=i1],
                    gait.utime0 + (rows.times[i0] * 1e6).round() as i64,
                    append,
                );
                node.publisher().publish(&ch, &m)?;
            }
        }
        Ok(())
    }

    /// Sends the set-point bridges the joints of now.
    fn set_points(&mut self, node: &Node, t: f64) -> anyhow::Result<()> {
        let gait = &mut self.gait;
        if !matches!(gait.phase, Phase::Ready | Phase::Posing(_)) {
            return Ok(());
        }
        for g in 0..gait.groups.len() {
            let Some(ch) = gait.groups[g].command.clone() else {
                continue;
            };
            let (p, v) = gait.stream.rows.at(gait.group_index(g), t);
            // Holding (the same set-point, at rest): only at the idle rate.
            let now = Instant::now();
            if let Some((last, at)) = &self.last_set[g] {
                if *last == p && v.iter().all(|v| *v == 0.0) && now < *at + self.idle {
                    continue;
                }
            }
            self.last_set[g] = Some((p.clone(), now));
            let header = gait.groups[g].command_stamper.stamp();
            let m = command_msg(header, &gait.groups[g].joints, &p, &v);
            node.publisher().publish(&ch, &m)?;
        }
        Ok(())
    }

    /// Publishes the status when it changed or is due.
    fn publish_status(&mut self, node: &Node, now: Instant) -> anyhow::Result<()> {
        let g = &mut self.gait;
        let urgent = std::mem::take(&mut g.status_urgent);
        if self.status_pace.take(now, g.status_changed) || urgent {
            g.status_changed = false;
            g.status.header = self.status_stamper.stamp();
            node.publisher().publish(&g.cfg.status_channel, &g.status)?;
        }
        Ok(())
    }

    /// Messages taken so far on the subscriptions that tick the gait at once: plans, commands,
    /// stops and goals.
    fn urgent_count(&self) -> u64 {
        let received = |s: &Option<(lcm::Subscription, _)>| -> u64 {
            s.as_ref().map_or(0, |(s, _)| s.stats().received)
        };
        received(&self.plans)
            + self.commands_sub.stats().received
            + self.stops_sub.stats().received
            + self.goals.as_ref().map_or(0, |(s, _)| s.stats().received)
    }
}

impl Tick for GaitApp {
    const WAKE_ON_MESSAGE: bool = false;

    fn urgent(&mut self) -> bool {
        let n = self.urgent_count();
        std::mem::replace(&mut self.urgent_seen, n) != n
    }

    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        let t = self.time(now);
        // The periodic work (set-points) only on the period's ticks: messages tick the gait
        // too, and a flood of them must not multiply what goes to the drives.
        let periodic = self.period.due(now);
        let gait = &mut self.gait;
        for g in &mut gait.groups {
            g.take_states(t, gait.utime0);
        }
        if let Some((_, rx)) = &self.imu {
            gait.take_imu(rx);
        }
        if let Some((_, rx)) = &self.odometry {
            gait.take_odometry(rx);
        }
        let commands = self
            .commands
            .try_iter()
            .chain(self.stops.try_iter())
            .collect();
        gait.take_commands(commands, t);
        gait.turn(t, self.plans.as_ref().map(|(_, rx)| rx));
        self.say(node)?;
        // A plan taken or refused is said before its first rows go out.
        self.publish_status(node, now)?;
        self.gait.hexapod_done(t);
        let goals = self
            .goals
            .as_ref()
            .map_or_else(Vec::new, |(_, rx)| rx.try_iter().collect());
        self.gait.pursue(t, goals);
        self.say(node)?;
        self.stream(node, t)?;
        if periodic {
            self.set_points(node, t)?;
        }
        if self.counter_period.due(now) {
            self.counter_period.next(now);
            if let Some((c, standing)) = self.gait.counter(t) {
                // Standing, unchanged: only at the idle rate (walking, at its rate, between
                // steps too: the counter is the gait's pulse).
                let same = standing
                    && self
                        .last_counter
                        .is_some_and(|(last, at)| last == c && now < at + self.idle);
                if !same {
                    self.last_counter = Some((c, now));
                    let m = counter_msg(self.counter_stamper.stamp(), &c);
                    node.publisher()
                        .publish(&self.gait.cfg.step_counter_channel, &m)?;
                }
            }
        }
        self.publish_status(node, now)?;
        // Standing with nothing to do (no goal, every row played), the loop slows to 50 Hz:
        // a command waits at most 20 ms.
        let next = self.period.next(now);
        Ok(if self.gait.idle(t) {
            next.max(now + IDLE_TICK)
        } else {
            next
        })
    }

    fn stop(mut self, node: &Node) -> anyhow::Result<()> {
        // A walk under way ends in a stand first (at most 10 s): the feet together, the COM
        // at rest, every row of it sent. Then the bridges hold the joints where the stream
        // ends (the Elmo bridge decelerates a chunk that ends in motion; the set-point bridges
        // hold).
        if !self.gait.come_to_stand(self.time(Instant::now())) {
            return Ok(());
        }
        let until = Instant::now() + Duration::from_secs(10);
        loop {
            let now = Instant::now();
            if self.gait.stood(self.time(now)) || now >= until {
                break;
            }
            let next = self.tick(node, now)?;
            let _ = node
                .lcm()
                .handle_timeout(next.saturating_duration_since(Instant::now()));
        }
        Ok(())
    }
}
