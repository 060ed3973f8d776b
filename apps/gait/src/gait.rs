//! The gait's decisions, on the messages' contents and walker time, with no bus: its phases
//! (waiting for the joints, the move into the standing pose, walking, halted, fault), the
//! plans it takes or refuses, the goal it walks to and the plan requests that asks for, the
//! commands and the bridges' stops, and the status that says it all. The app ([`crate::app`])
//! takes the messages, hands them here and sends what comes out.

use std::sync::mpsc::Receiver;
use std::time::Duration;

use anyhow::Context;
use stride_gait::archie::Joints;
use stride_gait::controller::{switch_time, Controller};
use stride_gait::hexapod::{HexConfig, HexGait};
use stride_gait::rows::{Rows, Stream};
use stride_gait::short;
use stride_gait::swing::Place;
use stride_gait::walker::{Plan, StepCounter, Walker};
use stride_kinematics::archie::{ArchieConfig, Leg};
use stride_kinematics::hexapod::Hexapod;
use stride_lcmtypes::stride::{
    FootstepPlanRequestT, FootstepPlanT, GaitCommandT, ImuT, NodeStatusT, OdometryT, PoseStampedT,
    TrajectoryStatusT,
};
use stride_node::{Stamper, Throttle};

use crate::group::Group;
use crate::{
    at_goal, feet_after, goal_of, odometry_pelvis, pelvis_at, plan_of, request_msg, stand_from,
    Anchor, Asking, BridgeStop, Channels, GaitConfig, Goal, Robot,
};

/// A goal being walked to: the last request's step and time.
#[derive(Debug, Clone, Copy)]
struct Pursuit {
    goal: Goal,
    step: Option<i64>,
    sent: f64,
}

/// What the gait is doing.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Phase {
    /// Waiting for the joints' states, since then.
    Waiting(f64),
    /// Moving into the standing pose, until then.
    Posing(f64),
    /// Walking or standing on patterns.
    Ready,
    /// The drives stopped under the walk (see [`Halt`]): nothing goes out until the gait may
    /// stand the robot up again from where its joints are.
    Halted,
    /// Stopped for good, and why.
    Fault(String),
}

/// The walk stopped under the gait: a bridge stopped its drives (an emergency, the system
/// stop, its stream run dry) or a joint left the pattern. What the gait sent no longer says
/// where the joints are: it stands the robot up from where they come to rest, into the
/// standing pose, and only then takes goals again.
#[derive(Debug, Clone, PartialEq)]
struct Halt {
    why: String,
    /// At once (a stream run dry: the gait's own lateness, nothing wrong with the drives);
    /// otherwise only after a resume command.
    auto: bool,
}

// One body per app, made once: its size does not matter.
#[allow(clippy::large_enum_variant)]
pub(crate) enum Body {
    Archie {
        /// The walker and the legs.
        ctl: Controller,
    },
    Hexapod {
        gait: Box<HexGait>,
        /// Where the robot stands when the walk under way ends.
        at: HexConfig,
    },
}

/// The gait's state, and what it has to say.
pub(crate) struct Gait {
    pub(crate) cfg: GaitConfig,
    pub(crate) body: Body,
    pub(crate) groups: Vec<Group>,
    /// The goal being walked to.
    goal: Option<Pursuit>,
    /// What the status says of the goal ("walking to ...", "... reached").
    goal_note: String,
    request_stamper: Stamper,
    requests: i64,
    /// A plan came for a step already under way at its switch (the planner's replan when the
    /// world changed comes at any time of a step): ask at once for the step that will be.
    ask_again: bool,
    /// The step the last plan taken was asked for.
    taken_echo: Option<i64>,
    attitude: Option<[f64; 2]>,
    /// The gait's frame in the world, corrected by the pelvis's measured pose.
    anchor: Anchor,
    /// Odometry estimates not believed (too far from the anchor).
    odometry_dropped: u64,
    /// Walker time 0 on the system clock.
    pub(crate) utime0: i64,
    pub(crate) phase: Phase,
    /// Why the drives stopped under the walk, while the gait waits to stand up again.
    halt: Option<Halt>,
    /// A resume came since the halt.
    resumed: bool,
    /// Where the feet stand once the robot is brought into its pose after a halt.
    restand: Option<[Place; 2]>,
    /// Standing up after a halt, and why it halted (said when the move into the pose begins).
    standing_up: Option<String>,
    /// The first odometry sets the anchor (a gait restarted mid-walk stands where its frame
    /// says nothing of); later ones correct it.
    anchored: bool,
    /// The last plan request sent.
    last_request: Option<i64>,
    /// The last plan taken, as it came (the step it answers, its steps).
    last_taken: Option<(i64, Vec<stride_lcmtypes::stride::FootstepT>)>,
    /// Refusals' log lines, thinned (a flood of bad plans does not flood the log).
    refusal_log: Throttle,
    /// The rows being played and how far they went to the trajectory bridges.
    pub(crate) stream: Stream,
    /// The status, whether it changed since it went out, and whether it goes out at once
    /// whatever the gap (a plan taken).
    pub(crate) status: TrajectoryStatusT,
    pub(crate) status_changed: bool,
    pub(crate) status_urgent: bool,
    /// The node's health to set (state, why), in order.
    pub(crate) health_out: Vec<(i8, String)>,
    /// Plan requests to send (channel, request), in order.
    pub(crate) requests_out: Vec<(String, FootstepPlanRequestT)>,
}

/// Plans that may wait in liblcm's queue for the gait's loop.
pub(crate) const PLAN_QUEUE: usize = 10_000;

/// The longest walk one command may ask of the hexapod, m.
const MAX_WALK: f64 = 20.0;

/// How the gait comes back from a halt, as its status says.
const HALT_AUTO: &str =
    "automatic: once the joints rest, the gait brings them into the standing pose from where they stand";
const HALT_RESUME: &str = "stride resume (a resume command): the gait then brings the joints into the standing pose from where they stand";

/// Rows of the pattern are made this far (s) beyond the stream's reach when they were not
/// made with it (see `Gait::make_rows`).
const MAKE_AHEAD: f64 = 0.5;

/// A group of joints as configured: its name, its joints, its channels.
pub(crate) type GroupOf<'a> = (String, Vec<String>, &'a Channels);

/// Loads the robot and builds its gait: the body, and its groups of joints (name, joints,
/// channels) as configured.
pub(crate) fn body<'a>(
    cfg: &'a GaitConfig,
    config_file: Option<&std::path::Path>,
) -> anyhow::Result<(Body, Vec<GroupOf<'a>>)> {
    let robot_path = cfg.robot_path(config_file);
    let (body, groups) = match cfg.robot {
        Robot::Archie => {
            let robot = ArchieConfig::load(&robot_path)
                .with_context(|| format!("robot file {}", robot_path.display()))?;
            let (legs, gen) = crate::archie_gait(cfg, robot.clone()).map_err(anyhow::Error::msg)?;
            let [x, y, yaw] = cfg.start;
            let w = cfg.walker.stance_width / 2.0;
            let (s, c) = yaw.sin_cos();
            let left = [x - s * w, y + c * w, 0.0, yaw];
            let right = [x + s * w, y - c * w, 0.0, yaw];
            let walker = Walker::new(gen, cfg.walker, 0.0, left, right, 0)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            // The standing pose must be within the legs' reach and limits (a COM height
            // set by hand, the thesis's 0.72 m, is not).
            let joints = legs
                .joints_until(walker.pattern(), f64::INFINITY)
                .map_err(|e| {
                    anyhow::anyhow!(
                    "the gait's standing pose (COM {:.3} m high) is out of the legs' reach: {e}",
                    legs.z_c
                )
                })?;
            let mut groups = Vec::new();
            for leg in [Leg::Left, Leg::Right] {
                if let Some(ch) = cfg.joints.get(leg.name()) {
                    groups.push((leg.name().to_string(), robot.names(leg).to_vec(), ch));
                }
            }
            (
                Body::Archie {
                    ctl: Controller {
                        legs,
                        walker,
                        joints,
                        switch_ahead: cfg.walker.switch_ahead,
                        decide_within: cfg.chunk,
                    },
                },
                groups,
            )
        }
        Robot::Hexapod => {
            let robot = Hexapod::load(&robot_path)
                .with_context(|| format!("robot file {}", robot_path.display()))?;
            let names: Vec<String> = (1..=6u8)
                .flat_map(|n| {
                    let leg = robot.leg(n).expect("six legs").name.clone();
                    ["coxa", "femur", "tibia"].map(move |j| format!("{leg}_{j}"))
                })
                .collect();
            let gait = HexGait::new(robot, cfg.hexapod).map_err(|e| anyhow::anyhow!("{e}"))?;
            let [x, y, yaw] = cfg.start;
            let at = gait.standing([x, y, 0.0, yaw]);
            let ch = cfg.joints.get("all").expect("checked: the hexapod's group");
            (
                Body::Hexapod {
                    gait: Box::new(gait),
                    at,
                },
                vec![("all".to_string(), names, ch)],
            )
        }
    };
    Ok((body, groups))
}

impl Gait {
    /// The gait of `body`, its joints in `groups`, waiting for their states; `node` names it
    /// in its status.
    pub(crate) fn new(cfg: GaitConfig, body: Body, groups: Vec<Group>, node: &str) -> Gait {
        let stand = standing_rows(&body, groups.len());
        Gait {
            status: TrajectoryStatusT {
                node: node.to_string(),
                state: TrajectoryStatusT::STATE_IDLE,
                last_refused_sequence: -1,
                last_accepted_sequence: -1,
                ..Default::default()
            },
            status_changed: true,
            status_urgent: false,
            cfg,
            body,
            groups,
            goal: None,
            goal_note: String::new(),
            request_stamper: Stamper::new("world"),
            requests: 0,
            ask_again: false,
            taken_echo: None,
            attitude: None,
            anchor: Anchor::default(),
            odometry_dropped: 0,
            utime0: lcm::now_utime(),
            phase: Phase::Waiting(0.0),
            halt: None,
            resumed: false,
            restand: None,
            standing_up: None,
            anchored: false,
            last_request: None,
            last_taken: None,
            refusal_log: Throttle::new(Duration::from_secs(1)),
            stream: Stream::quiet(stand),
            health_out: Vec::new(),
            requests_out: Vec::new(),
        }
    }

    fn health(&mut self, state: i8, why: impl Into<String>) {
        self.health_out.push((state, why.into()));
    }

    /// One turn of the loop at walker time `t`, the inputs taken: a bridge that stopped its
    /// drives (an emergency, the system stop, its stream run dry) stops the walk; the phase
    /// goes on (Archie's plans taken from `plans` while walking on patterns, counted and
    /// dropped otherwise).
    pub(crate) fn turn(&mut self, t: f64, plans: Option<&Receiver<FootstepPlanT>>) {
        // Nothing more goes out after a stop, and the robot stands up again from where its
        // joints are (at once after a dry stream, else after a resume).
        let stops: Vec<BridgeStop> = self
            .groups
            .iter_mut()
            .filter_map(|g| g.bridge_stopped())
            .collect();
        if !stops.is_empty() {
            let auto = stops.iter().all(|s| s.dry);
            let why: Vec<String> = stops.into_iter().map(|s| s.why).collect();
            self.halt(t, why.join("; "), auto);
        }
        match self.phase.clone() {
            Phase::Waiting(since) => self.wait(t, since),
            Phase::Posing(until) if t >= until => self.ready(t),
            Phase::Posing(_) => {}
            Phase::Ready => {
                if let Some(rx) = plans {
                    self.walk(t, rx)
                }
            }
            Phase::Halted => self.halted(t),
            Phase::Fault(_) => {}
        }
        // Not walking on patterns: plans are not for now (counted, never left to pile up).
        if let (false, Some(rx)) = (self.phase == Phase::Ready, plans) {
            let n = rx.try_iter().count() as i64;
            if n > 0 {
                self.status.dropped += n;
                self.status_changed = true;
            }
        }
    }

    /// The hexapod's walk is over once its rows are.
    pub(crate) fn hexapod_done(&mut self, t: f64) {
        if matches!(self.body, Body::Hexapod { .. })
            && self.status.state == TrajectoryStatusT::STATE_MOVING
            && t >= self.stream.rows.end()
        {
            self.set_status(TrajectoryStatusT::STATE_IDLE, "walk done");
        }
    }

    /// Archie's step counter at `t`, and whether the walker stands.
    pub(crate) fn counter(&self, t: f64) -> Option<(StepCounter, bool)> {
        match &self.body {
            Body::Archie {
                ctl: Controller { walker, .. },
            } => Some((walker.counter(t), walker.standing(t))),
            Body::Hexapod { .. } => None,
        }
    }

    /// Standing with nothing to do: ready, no goal, every row played, the walker standing.
    pub(crate) fn idle(&self, t: f64) -> bool {
        self.phase == Phase::Ready
            && self.goal.is_none()
            && t >= self.stream.rows.end()
            && match &self.body {
                Body::Archie {
                    ctl: Controller { walker, .. },
                } => walker.standing(t),
                Body::Hexapod { .. } => true,
            }
    }

    /// Shutting down at `t`: a walk under way ends in a stand (the feet together, the COM at
    /// rest), its rows streamed; false when there is no walk to end (or no stand from here).
    pub(crate) fn come_to_stand(&mut self, t: f64) -> bool {
        let stream_end = self.stream.end_sent(t);
        let Body::Archie {
            ctl: Controller { walker, legs, .. },
        } = &mut self.body
        else {
            return false;
        };
        if self.phase != Phase::Ready || walker.standing(t) {
            return false;
        }
        walker.stop(switch_time(
            walker,
            t,
            self.cfg.walker.switch_ahead,
            stream_end,
        ));
        match legs.joints_until(walker.pattern(), f64::INFINITY) {
            Ok(j) => self.adopt(j, t),
            Err(e) => {
                tracing::error!("no stand from here: {e}");
                return false;
            }
        }
        tracing::info!("shutting down: coming to a stand");
        self.goal = None;
        true
    }

    /// The stand of [`Gait::come_to_stand`] reached (every row of it played), or no longer
    /// walking on patterns.
    pub(crate) fn stood(&self, t: f64) -> bool {
        let standing = match &self.body {
            Body::Archie {
                ctl: Controller { walker, .. },
            } => walker.standing(t) && t >= self.stream.rows.end(),
            Body::Hexapod { .. } => true,
        };
        standing || self.phase != Phase::Ready
    }

    /// The groups' rows in the walker's pattern's joint order (Archie: left, right; the rows
    /// hold both legs whichever groups are configured).
    pub(crate) fn group_index(&self, g: usize) -> usize {
        match self.body {
            Body::Archie { .. } => {
                if self.groups[g].name == "left" {
                    0
                } else {
                    1
                }
            }
            Body::Hexapod { .. } => 0,
        }
    }

    pub(crate) fn set_status(&mut self, state: i8, reason: impl Into<String>) {
        let reason = reason.into();
        if self.status.state != state || self.status.reason != reason {
            self.status.state = state;
            self.status.reason = reason;
            self.status_changed = true;
        }
    }

    pub(crate) fn refused(&mut self, why: String) {
        self.refusal_log
            .log([stride_node::Note::Warn(format!("plan refused: {why}"))]);
        self.status.refused += 1;
        self.status.last_refusal = why;
        self.status_changed = true;
    }

    /// Plays the walker's new pattern at walker time `t`. One that starts ahead (a plan
    /// taken, a stand: the walker switches beyond what was sent) replaces from its start. One
    /// that starts in the past kept what was sent (a plan refused with nothing to change):
    /// the stream goes on from the last row sent, or, standing quiet, stays quiet.
    pub(crate) fn adopt(&mut self, plan: Joints, t: f64) {
        let stab = self.stabiliser_now();
        if let Body::Archie {
            ctl: Controller { walker, joints, .. },
            ..
        } = &mut self.body
        {
            let rows = Rows::of_plan(walker.pattern().timeline.start, &plan.plan, stab);
            if !self.stream.adopt(rows, t) {
                tracing::warn!("a pattern that starts in the past and does not continue what was sent: not streamed");
            }
            *joints = plan;
        }
    }

    fn stabiliser_now(&self) -> [f64; 2] {
        match self.attitude {
            Some(a) => self.cfg.stabiliser.correction(a),
            None => [0.0; 2],
        }
    }

    /// Takes the pelvis's measured poses: each moves the anchor a share of the way to where
    /// it puts the pattern's pelvis at that time.
    pub(crate) fn take_odometry(&mut self, rx: &Receiver<OdometryT>) {
        let Some(cfg) = &self.cfg.goal else {
            return;
        };
        let Body::Archie {
            ctl: Controller { walker, joints, .. },
            ..
        } = &self.body
        else {
            return;
        };
        let start = walker.pattern().timeline.start;
        for m in rx.try_iter() {
            let t = (m.header.utime - self.utime0) as f64 * 1e-6;
            // Before the pattern now played, or not made of numbers: nothing to compare.
            let (Some(gait), Some(world)) =
                (pelvis_at(&joints.plan, start, t), odometry_pelvis(&m))
            else {
                continue;
            };
            let est = Anchor::between(world, gait);
            // The first estimate places the frame (a gait restarted where the robot was left
            // knows nothing of where that is); later ones correct it a share at a time.
            if !self.anchored {
                // Only once the robot stands in the pose the pattern has (not while it moves
                // into it from elsewhere).
                if self.phase != Phase::Ready {
                    continue;
                }
                self.anchored = true;
                self.anchor = est;
                continue;
            }
            let off = est.distance(&self.anchor, [gait[0], gait[1]]);
            if off > cfg.odometry_max_jump {
                self.odometry_dropped += 1;
                if self.odometry_dropped.is_power_of_two() {
                    tracing::warn!(
                        "the odometry puts the pelvis {off:.3} m from where the gait has it \
                         (at most {} m believed): dropped ({} so far)",
                        cfg.odometry_max_jump,
                        self.odometry_dropped
                    );
                }
                continue;
            }
            self.anchor = self.anchor.toward(&est, cfg.odometry_gain);
        }
    }

    /// Takes the IMU's messages: the pelvis's attitude for the stabiliser.
    pub(crate) fn take_imu(&mut self, rx: &Receiver<ImuT>) {
        for m in rx.try_iter() {
            if let Some(a) = crate::Stabiliser::attitude(&m) {
                self.attitude = Some(a);
            }
        }
    }

    /// Takes the commands (and the system stops), in order.
    pub(crate) fn take_commands(&mut self, commands: Vec<GaitCommandT>, t: f64) {
        for c in commands {
            let stream_end = self.stream.end_sent(t);
            match (c.command, &mut self.body) {
                (
                    GaitCommandT::COMMAND_STOP,
                    Body::Archie {
                        ctl: Controller { walker, legs, .. },
                        ..
                    },
                ) => {
                    // The system stop is sent again every second while it holds: said once.
                    if walker.is_stopped() {
                        tracing::debug!("stop: {}", c.reason);
                        continue;
                    }
                    tracing::info!("stop: {}", c.reason);
                    walker.stop(switch_time(
                        walker,
                        t,
                        self.cfg.walker.switch_ahead,
                        stream_end,
                    ));
                    // The walk ends here: a resume stands until a goal is sent (the robot
                    // never walks off on its own after a stop).
                    if let Some(p) = self.goal.take() {
                        tracing::info!("goal ({}, {}) dropped", short(p.goal.x), short(p.goal.y));
                        self.goal_note.clear();
                    }
                    // Walking on patterns: the stand is streamed (halted or not yet standing
                    // in the pose, nothing goes out).
                    if self.phase == Phase::Ready {
                        match legs.joints_until(walker.pattern(), f64::INFINITY) {
                            Ok(j) => self.adopt(j, t),
                            Err(e) => self.fault(format!("stopping: {e}")),
                        }
                    }
                    if self.halt.is_none() {
                        self.set_status(
                            TrajectoryStatusT::STATE_STOPPED,
                            format!("stopped by command: {}", c.reason),
                        );
                        self.status.recovery = "a resume command (stride.gait_command_t)".into();
                    }
                }
                (
                    GaitCommandT::COMMAND_RESUME,
                    Body::Archie {
                        ctl: Controller { walker, .. },
                        ..
                    },
                ) => {
                    walker.resume();
                    self.resumed = true;
                    if self.halt.is_none() {
                        self.status.recovery.clear();
                        self.set_status(TrajectoryStatusT::STATE_IDLE, "");
                    }
                }
                (GaitCommandT::COMMAND_STOP, Body::Hexapod { .. }) => {
                    // Hold where the servos are now.
                    let q: Vec<Vec<f64>> = (0..self.groups.len())
                        .map(|g| self.stream.rows.at(self.group_index(g), t).0)
                        .collect();
                    self.stream.rows = Rows::hold(t, &q);
                    self.set_status(
                        TrajectoryStatusT::STATE_STOPPED,
                        format!("stopped by command: {}", c.reason),
                    );
                }
                (GaitCommandT::COMMAND_RESUME, Body::Hexapod { .. }) => {
                    self.set_status(TrajectoryStatusT::STATE_IDLE, "");
                }
                (
                    GaitCommandT::COMMAND_WALK | GaitCommandT::COMMAND_SENSE,
                    Body::Hexapod { gait, at },
                ) => {
                    if self.phase != Phase::Ready || t < self.stream.rows.end() {
                        self.refused(format!(
                            "command {}: the hexapod is not standing ready",
                            c.command
                        ));
                        continue;
                    }
                    // A walk's length sizes its rows: at most MAX_WALK at a time.
                    if c.command == GaitCommandT::COMMAND_WALK
                        && (c.distance.is_nan() || c.distance.abs() > MAX_WALK)
                    {
                        self.refused(format!(
                            "walk: {} m is more than the {MAX_WALK} m a walk command may ask",
                            short(c.distance)
                        ));
                        continue;
                    }
                    let (configs, trans) = match (c.command, c.gait) {
                        (GaitCommandT::COMMAND_SENSE, _) => gait.sensing_lift(at),
                        (_, GaitCommandT::GAIT_WAVE) if c.distance.is_finite() => {
                            gait.wave(at, c.distance)
                        }
                        (_, GaitCommandT::GAIT_TRIPOD) if c.distance.is_finite() => {
                            gait.tripod(at, c.distance)
                        }
                        _ => {
                            self.refused(format!(
                                "walk: gait {} over {} m is not a walk",
                                c.gait, c.distance
                            ));
                            continue;
                        }
                    };
                    match gait.rows(&configs, &trans, None) {
                        Ok(rows) => {
                            *at = *configs.last().expect("a walk has configurations");
                            self.stream.rows = Rows::hexapod(t + self.cfg.lookahead, &rows);
                            self.status.accepted += 1;
                            self.set_status(TrajectoryStatusT::STATE_MOVING, "");
                        }
                        Err(e) => self.refused(e.to_string()),
                    }
                }
                (other, _) => tracing::warn!("command {other} is not for this robot"),
            }
        }
    }

    /// Stops for good: nothing more goes to the bridges (a trajectory bridge decelerates its
    /// joints to a stop at the end of what it was sent), and the status says why.
    fn fault(&mut self, why: String) {
        tracing::error!("{why}");
        self.stream.silence();
        self.health(NodeStatusT::STATE_FAULT, why.clone());
        self.set_status(TrajectoryStatusT::STATE_STOPPED, why.clone());
        self.phase = Phase::Fault(why);
    }

    /// The drives stopped under the walk (see [`Halt`]): nothing more goes out, the goal is
    /// dropped, and the status says why and how the gait comes back. A second stop meanwhile
    /// keeps the first reason (one that waits for a resume wins).
    fn halt(&mut self, t: f64, why: String, auto: bool) {
        if matches!(self.phase, Phase::Fault(_)) {
            return;
        }
        if let Some(h) = &mut self.halt {
            h.auto &= auto;
            if !h.auto {
                self.status.recovery = HALT_RESUME.into();
            }
            return;
        }
        tracing::warn!("{why}: the walk stops");
        self.last_taken = None;
        if let Body::Archie {
            ctl: Controller { walker, .. },
            ..
        } = &self.body
        {
            self.restand = Some(stand_from(
                &walker.pattern().timeline,
                t,
                self.cfg.walker.stance_width,
            ));
        }
        if let Some(p) = self.goal.take() {
            tracing::info!("goal ({}, {}) dropped", short(p.goal.x), short(p.goal.y));
            self.goal_note.clear();
        }
        self.stream.silence();
        self.phase = Phase::Halted;
        self.resumed = false;
        self.status.recovery = if auto { HALT_AUTO } else { HALT_RESUME }.into();
        self.set_status(TrajectoryStatusT::STATE_STOPPED, why.clone());
        self.health(NodeStatusT::STATE_DEGRADED, why.clone());
        self.halt = Some(Halt { why, auto });
    }

    /// Halted: once it may (at once after a dry stream, else after a resume, and never while
    /// stopped by a command), the gait stands the robot up from where its joints are: a
    /// walker standing where the feet will be, its step counter going on, then the move into
    /// the standing pose from the measured joints once they rest.
    fn halted(&mut self, t: f64) {
        let Some(h) = &self.halt else {
            return;
        };
        let stopped = match &self.body {
            Body::Archie {
                ctl: Controller { walker, .. },
                ..
            } => walker.is_stopped(),
            Body::Hexapod { .. } => false,
        };
        if !(h.auto || self.resumed) || stopped {
            return;
        }
        let why = h.why.clone();
        if let Body::Archie { ctl } = &mut self.body {
            let feet = self
                .restand
                .take()
                .unwrap_or(ctl.walker.pattern().timeline.feet_end);
            if let Err(e) = ctl.stand(self.cfg.walker, t, feet) {
                return self.fault(format!("no standing pose after a stop: {e}"));
            }
        }
        self.stream
            .hold(standing_rows(&self.body, self.groups.len()));
        self.halt = None;
        self.resumed = false;
        tracing::info!("standing up from where the joints are once they rest, after: {why}");
        // The status says STOPPED until the move into the pose begins (a status that turned
        // back at once might never be seen: changes are spaced).
        self.standing_up = Some(why);
        self.health(NodeStatusT::STATE_STARTING, "standing up after a stop");
        self.phase = Phase::Waiting(t);
    }

    /// Waits for the joints' states, then starts from where they are.
    fn wait(&mut self, t: f64, since: f64) {
        if !self.groups.iter().all(|g| g.all_measured(t)) {
            if t - since > 5.0 {
                let missing: Vec<&str> = self
                    .groups
                    .iter()
                    .filter(|g| !g.all_measured(t))
                    .map(|g| g.name.as_str())
                    .collect();
                self.fault(format!("no joint states from {missing:?} for 5 s"));
            }
            return;
        }
        // A motion starts from rest (after a stop the joints still decelerate a while).
        if !self.groups.iter().all(Group::still) {
            return;
        }
        let stand: Vec<Vec<f64>> = (0..self.groups.len())
            .map(|g| {
                self.stream
                    .rows
                    .at(self.group_index(g), self.stream.rows.times[0])
                    .0
            })
            .collect();
        let off = self
            .groups
            .iter()
            .zip(&stand)
            .filter_map(|(g, q)| g.off(|_| Some(q.clone()), t))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        match off {
            Some((d, joint)) if d > self.cfg.pose_tolerance => self.fault(format!(
                "{joint} is {d:.3} rad from the standing pose (at most {} rad is moved): \
                     bring the robot near it",
                self.cfg.pose_tolerance
            )),
            Some((d, _)) if d > self.cfg.start_tolerance => {
                // Into the standing pose from where the joints are.
                let from: Vec<Vec<f64>> = self
                    .groups
                    .iter()
                    .zip(&stand)
                    .map(|(g, q)| {
                        g.joints
                            .iter()
                            .zip(q)
                            .map(|(n, s)| g.position(n).unwrap_or(*s))
                            .collect()
                    })
                    .collect();
                let mut rows = Rows::move_to(
                    t + self.cfg.lookahead,
                    &from,
                    &stand,
                    self.cfg.pose_speed,
                    1.0,
                    0.01,
                );
                // Rows are per pattern group; Archie's hold both legs.
                if let Body::Archie { .. } = self.body {
                    let mut full = vec![Vec::new(), Vec::new()];
                    for (g, p) in rows.pos.drain(..).enumerate() {
                        full[self.group_index(g)] = p;
                    }
                    let mut fullv = vec![Vec::new(), Vec::new()];
                    for (g, v) in rows.vel.drain(..).enumerate() {
                        fullv[self.group_index(g)] = v;
                    }
                    for (k, r) in full.iter_mut().enumerate() {
                        if r.is_empty() {
                            *r = vec![self.stream.rows.pos[k][0].clone(); rows.times.len()];
                            fullv[k] = vec![vec![0.0; 6]; rows.times.len()];
                        }
                    }
                    rows.pos = full;
                    rows.vel = fullv;
                }
                let until = rows.end() + 0.2;
                tracing::info!(
                    "moving into the standing pose over {:.1} s (a joint {d:.3} rad away)",
                    until - t
                );
                self.health(NodeStatusT::STATE_RUNNING, "moving into the standing pose");
                self.stream.play(rows);
                self.phase = Phase::Posing(until);
                self.say_standing_up();
            }
            _ => {
                self.say_standing_up();
                self.ready(t);
            }
        }
    }

    /// After a halt, the status says the robot stands up (the move into the pose begins).
    fn say_standing_up(&mut self) {
        if let Some(why) = self.standing_up.take() {
            self.status.recovery.clear();
            self.set_status(
                TrajectoryStatusT::STATE_IDLE,
                format!("standing up from where the joints are (after: {why})"),
            );
        }
    }

    /// Standing in the pose: the walker starts now.
    fn ready(&mut self, t: f64) {
        if let Body::Archie { ctl } = &mut self.body {
            let feet = ctl.walker.pattern().timeline.feet_start;
            if let Err(e) = ctl.stand(self.cfg.walker, t, feet) {
                return self.fault(e);
            }
        }
        let mut stand = standing_rows(&self.body, self.groups.len());
        if let Body::Hexapod { .. } = self.body {
            stand.times = vec![t];
        }
        self.stream.hold(stand);
        self.phase = Phase::Ready;
        self.health(NodeStatusT::STATE_RUNNING, "");
        tracing::info!("standing, ready");
    }

    /// Takes plans and keeps the walk going (Archie).
    fn walk(&mut self, t: f64, plans: &Receiver<FootstepPlanT>) {
        let stream_end = self.stream.end_sent(t);
        let Body::Archie { ctl } = &mut self.body else {
            return;
        };
        let mut refusals = Vec::new();
        let mut unreachable = None;
        let mut parsed = Vec::new();
        while let Ok(msg) = plans.try_recv() {
            // The planner found no way (beyond its reach, no way round the obstacles).
            let none = matches!(
                msg.status,
                FootstepPlanT::STATUS_NO_PATH
                    | FootstepPlanT::STATUS_START_IN_COLLISION
                    | FootstepPlanT::STATUS_GOAL_IN_COLLISION
                    | FootstepPlanT::STATUS_GOAL_OUTSIDE_MAP
                    | FootstepPlanT::STATUS_BAD_REQUEST
            );
            match msg.status {
                FootstepPlanT::STATUS_OK | FootstepPlanT::STATUS_PARTIAL => {}
                // A request answered by a newer one's plan: nothing to take.
                FootstepPlanT::STATUS_SUPERSEDED => {
                    self.status.dropped += 1;
                    continue;
                }
                // The walk to the goal ends, with the planner's reason, when it answers the
                // last request so.
                _ if none && Some(msg.request_id) == self.last_request => {
                    self.status.dropped += 1;
                    unreachable = Some(msg.detail.clone());
                    continue;
                }
                // An answer to an older request, or a search that ran out of time (the
                // request goes again): not a plan, not a refusal.
                _ if none || msg.status == FootstepPlanT::STATUS_TIMEOUT => {
                    self.status.dropped += 1;
                    continue;
                }
                _ => {}
            }
            // The plan taken for this step, again (a copy, a planner that answers twice
            // alike): it would change nothing.
            if self
                .last_taken
                .as_ref()
                .is_some_and(|(n, steps)| *n == msg.step_number && *steps == msg.steps)
            {
                self.status.dropped += 1;
                continue;
            }
            match plan_of(&msg) {
                // The world's footsteps in the gait's frame.
                Ok(mut p) => {
                    for s in &mut p.steps {
                        s.place = self.anchor.to_gait(s.place);
                    }
                    parsed.push((p, msg));
                }
                Err(why) => refusals.push(why),
            }
        }
        let (offered, msgs): (Vec<Plan>, Vec<FootstepPlanT>) = parsed.into_iter().unzip();
        let began = std::time::Instant::now();
        let intake = ctl.take(&offered, t, stream_end);
        let took = began.elapsed();
        if took > std::time::Duration::from_millis(100) {
            tracing::warn!(
                "{} plans offered, {} taken, the walker's own change {}: {} ms to make their \
                 patterns and joints",
                offered.len(),
                intake.taken,
                intake.changed,
                took.as_millis()
            );
        }
        if let Some(e) = &intake.stand_beyond {
            tracing::error!("the walker's stand is beyond the legs ({e}): the rows made go on");
        }
        self.status.dropped += intake.dropped as i64;
        refusals.extend(intake.refusals);
        let (taken, late, walker_changed, adopt) =
            (intake.taken, intake.late, intake.changed, intake.adopt);
        let taken_echo = intake.taken_echo.map(|(echo, _)| echo);
        let last_taken = intake
            .taken_echo
            .map(|(_, i)| (msgs[i].step_number, msgs[i].steps.clone()));
        let walker = &ctl.walker;
        let standing = walker.standing(t);
        let stopped = walker.is_stopped();
        if let Some(why) = unreachable {
            self.drop_goal(format!("the planner cannot reach it: {why}"));
        }
        self.ask_again |= late;
        self.taken_echo = taken_echo.or(self.taken_echo);
        // The plan a copy of which would change nothing: the one just taken, while the
        // walker's pattern is still its own (not once the walker changed it by itself).
        if last_taken.is_some() {
            self.last_taken = last_taken;
        } else if walker_changed || stopped {
            self.last_taken = None;
        }
        for why in refusals {
            self.refused(why);
        }
        if taken > 0 {
            self.status.accepted += taken as i64;
            self.status_changed = true;
            // A plan taken is said before its first rows go out, whatever the gap (at most
            // one a tick: one plan is made into a pattern a tick).
            self.status_urgent = true;
        }
        if let Some(j) = adopt {
            self.adopt(j, t);
        }
        self.make_rows(t);
        if !stopped {
            let note = self.goal_note.clone();
            self.set_status(
                if standing {
                    TrajectoryStatusT::STATE_IDLE
                } else {
                    TrajectoryStatusT::STATE_MOVING
                },
                note,
            );
        }
        self.track(t);
    }

    /// Makes the rows of the walker's pattern that the stream comes near and were not made
    /// with it (a plan's pattern is made as far as it can play before a newer plan or the
    /// stop replaces it: this holds should neither come in time). Rows beyond the legs end
    /// the walk in a stand, from the end of those made.
    fn make_rows(&mut self, t: f64) {
        let need = t + self.cfg.lookahead + self.cfg.chunk + MAKE_AHEAD;
        let stream_end = self.stream.end_sent(t);
        let Body::Archie { ctl, .. } = &mut self.body else {
            return;
        };
        if ctl.joints.complete() || self.stream.rows.end() >= need {
            return;
        }
        match ctl.extend(need + MAKE_AHEAD) {
            Ok(()) => self.stream.rows.extend(&ctl.joints.plan),
            Err(e) => {
                let why = format!("the pattern's later rows are beyond the legs ({e})");
                match ctl.halt(t, stream_end, &why) {
                    Ok(j) => self.adopt(j, t),
                    Err(e) => tracing::error!(
                        "the walker's stand is beyond the legs ({e}): the rows made go on"
                    ),
                }
                self.refused(why);
            }
        }
    }

    /// Takes goals, and asks the planner for the way there at every step (Archie).
    pub(crate) fn pursue(&mut self, t: f64, goals: Vec<PoseStampedT>) {
        for m in goals {
            match goal_of(&m) {
                Some(g) => {
                    tracing::info!("goal ({}, {})", short(g.x), short(g.y));
                    self.goal_note = format!("walking to ({}, {})", short(g.x), short(g.y));
                    self.goal = Some(Pursuit {
                        goal: g,
                        step: None,
                        sent: f64::NEG_INFINITY,
                    });
                }
                None => self.refused("a goal that is not made of finite numbers".into()),
            }
        }
        let stream_end = self.stream.end_sent(t);
        let ask_again = std::mem::take(&mut self.ask_again);
        let (
            Body::Archie {
                ctl: Controller { walker, .. },
                ..
            },
            Some(cfg),
        ) = (&mut self.body, &self.cfg.goal)
        else {
            return;
        };
        let Some(p) = &mut self.goal else {
            return;
        };
        if walker.is_stopped() || self.phase != Phase::Ready {
            return;
        }
        let switch = self.cfg.walker.switch_ahead;
        let (step, due) = Asking {
            now: walker.counter(t).number,
            at_switch: walker
                .counter(switch_time(walker, t, switch, stream_end) + switch)
                .number,
            asked: p.step.map(|s| (s, p.sent)),
            taken: self.taken_echo,
            late: ask_again,
        }
        .next(t, cfg.resend);
        let (feet, next) = feet_after(&walker.pattern().timeline, step);
        // Where they stand in the world.
        let feet = feet.map(|f| self.anchor.to_world(f));
        if at_goal(&feet, &p.goal, cfg) {
            // There once the step under way lands: no more requests; the walk's last plan
            // ends it standing (its closing step, then the planner's padding in place).
            if !walker.standing(t) {
                let _ = walker.finish_plan();
                return;
            }
            tracing::info!("goal ({}, {}) reached", short(p.goal.x), short(p.goal.y));
            self.goal_note = format!("goal ({}, {}) reached", short(p.goal.x), short(p.goal.y));
            self.status.reason = self.goal_note.clone();
            self.status_changed = true;
            self.goal = None;
            return;
        }
        if due {
            p.step = Some(step);
            p.sent = t;
            self.requests += 1;
            let m = request_msg(
                self.request_stamper.stamp(),
                self.requests,
                step,
                feet,
                next,
                &p.goal,
                cfg,
            );
            self.last_request = Some(self.requests);
            self.requests_out.push((cfg.request_channel.clone(), m));
        }
    }

    /// Ends the walk to the goal: it is dropped, and the status says why (until a goal is sent
    /// again).
    fn drop_goal(&mut self, why: String) {
        if let Some(p) = self.goal.take() {
            let note = format!(
                "goal ({}, {}) dropped: {why}",
                short(p.goal.x),
                short(p.goal.y)
            );
            tracing::warn!("{note}");
            self.goal_note = note.clone();
            self.status.reason = note;
            self.status_changed = true;
        }
    }

    /// A joint further from the pattern than the tolerance stops the walk.
    fn track(&mut self, t: f64) {
        if self.stream.is_quiet() {
            return;
        }
        let (lag, first) = (self.cfg.track_lag, self.stream.rows.times[0]);
        let worst = (0..self.groups.len())
            .filter_map(|g| {
                let k = self.group_index(g);
                // Each measurement against the rows of its own time (the bridges' lag
                // behind).
                self.groups[g].off(
                    |at| (at - lag >= first).then(|| self.stream.rows.at(k, at - lag).0),
                    t,
                )
            })
            .max_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((d, joint)) = worst {
            if d > self.cfg.track_tolerance {
                // The joints are not where the rows have them: nothing more of the pattern
                // goes out (the bridges end what they have at rest), and the robot stands up
                // from where they come to rest after a resume.
                let why = format!(
                    "{joint} is {d:.3} rad from where the pattern has it (at most {}): stopped",
                    self.cfg.track_tolerance
                );
                self.halt(t, why, false);
            }
        }
    }
}

/// The rows of standing still (Archie's walker's pattern, the hexapod's stance), held.
pub(crate) fn standing_rows(body: &Body, groups: usize) -> Rows {
    match body {
        Body::Archie {
            ctl: Controller { joints, walker, .. },
            ..
        } => {
            let mut r = Rows::of_plan(walker.pattern().timeline.start, &joints.plan, [0.0; 2]);
            r.pos.truncate(groups.max(2));
            r
        }
        Body::Hexapod { gait, at } => {
            let t = stride_gait::hexapod::Transition {
                swing: Vec::new(),
                duration: gait.cfg.period,
            };
            match gait.rows(&[*at, *at], &[t], None) {
                Ok(rows) => Rows::hexapod(0.0, &rows[..1]),
                Err(_) => Rows::hold(0.0, &[vec![0.0; 18]]),
            }
        }
    }
}
