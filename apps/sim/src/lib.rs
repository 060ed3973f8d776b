//! `stride-sim`, the simulated world, as a library: its configuration, the simulation of one
//! run (the body, the world, the noise, the delayed perception) apart from the bus, and the
//! messages it publishes; the app itself is in [`app`].

pub mod app;

use std::collections::VecDeque;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use stride_kinematics::archie::{ArchieConfig, Leg, Q};
use stride_kinematics::hexapod::Hexapod;
use stride_kinematics::math::{yawed, Frame, Pose};
use stride_lcmtypes::stride::{
    ElevationMapT, FootT, HeaderT, ImuT, JointStateT, ObstacleListT, ObstacleT, OdometryT,
    PoseStampedT, PoseT, SimReportT,
};
use stride_sim::body::{quaternion, yaw_of, Body, BodyConfig, Event};
use stride_sim::hexapod::{HexBody, HexBodyConfig};
use stride_sim::noise::Rng;
use stride_sim::world::{PerceptionNoise, World};
use stride_world::grid::Grid;
use stride_world::scene::{Obstacle, Scene};

/// The robot a simulator moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SimRobot {
    /// Archie, the biped: one stance foot fixed, the ZMP watched.
    #[default]
    Archie,
    /// The hexapod: the feet on the ground fixed, the body level, its static margin watched.
    Hexapod,
}

/// The simulator's file (config/sim-archie.toml, config/sim-hexapod.toml).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    /// The robot (archie unless said).
    #[serde(default)]
    pub robot: SimRobot,
    /// The scene, relative to this file (`--scene` overrides it).
    pub scene: Option<PathBuf>,
    /// The robot's file (config/robots/archie.toml or hexapod.toml), relative to this file.
    pub robot_file: PathBuf,
    /// The seed of every noise: the same seed, the same run.
    #[serde(default)]
    pub seed: u64,
    /// How often the body moves, Hz.
    pub rate_hz: f64,
    /// How often the report goes out, Hz (and at once when something begins).
    pub report_rate_hz: f64,
    /// While the body rests (no joint has moved for [`REST_AFTER`] s), the odometry, the IMU
    /// and the report go out at most this often, Hz; the first motion brings their rates
    /// back at once. Standing robots then cost the bus little.
    #[serde(default = "idle_rate_hz")]
    pub idle_rate_hz: f64,
    /// Where the robot starts (x, y, heading); absent: the scene's start.
    pub start: Option<[f64; 3]>,
    /// The fake devices' true joint positions (stride.joint_state_t, sim-only channels).
    pub true_joint_channels: Vec<String>,
    /// The pelvis's true pose (stride.pose_stamped_t).
    pub pose_channel: String,
    /// The report (stride.sim_report_t).
    pub report_channel: String,
    /// The odometry.
    #[serde(default)]
    pub odometry: OdometryConfig,
    /// The IMU.
    #[serde(default)]
    pub imu: ImuConfig,
    /// Perfect perception of the scene.
    #[serde(default)]
    pub perception: PerceptionConfig,
    /// How Archie's body meets the ground and what counts as wrong.
    #[serde(default)]
    pub body: BodyConfig,
    /// The same for the hexapod's.
    #[serde(default)]
    pub hexapod_body: HexBodyConfig,
    /// Obstacles that appear during the run.
    #[serde(default)]
    pub appear: Vec<Appear>,
}

/// A noisy odometry of the pelvis (stride.odometry_t).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OdometryConfig {
    /// Its channel ("" for none).
    pub channel: String,
    /// Rate, Hz.
    pub rate_hz: f64,
    /// Standard deviation of each position coordinate, m.
    pub position_sigma: f64,
    /// Of the heading, rad.
    pub yaw_sigma: f64,
}

impl Default for OdometryConfig {
    fn default() -> OdometryConfig {
        OdometryConfig {
            channel: "ODOMETRY".into(),
            rate_hz: 100.0,
            position_sigma: 0.002,
            yaw_sigma: 0.002,
        }
    }
}

/// An IMU on the pelvis (stride.imu_t).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuConfig {
    /// Its channel ("" for none).
    pub channel: String,
    /// Rate, Hz.
    pub rate_hz: f64,
    /// Standard deviation of each angular velocity, rad/s.
    pub gyro_sigma: f64,
    /// Of each acceleration, m/s².
    pub accel_sigma: f64,
}

impl Default for ImuConfig {
    fn default() -> ImuConfig {
        ImuConfig {
            channel: "IMU".into(),
            rate_hz: 100.0,
            gyro_sigma: 0.005,
            accel_sigma: 0.05,
        }
    }
}

/// What the mapper would publish, from the scene itself.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PerceptionConfig {
    /// The obstacles (stride.obstacle_list_t; "" for none).
    pub obstacle_channel: String,
    /// The elevation map around the robot (stride.elevation_map_t; "" for none).
    pub map_channel: String,
    /// Rate, Hz.
    pub rate_hz: f64,
    /// Each publication goes out this long after what it shows, s.
    pub delay: f64,
    /// The map's side, centred on the robot, m.
    pub map_size: f64,
    /// The noise.
    pub noise: PerceptionNoise,
}

impl Default for PerceptionConfig {
    fn default() -> PerceptionConfig {
        PerceptionConfig {
            obstacle_channel: "OBSTACLES".into(),
            map_channel: "ELEVATION_MAP".into(),
            rate_hz: 2.0,
            delay: 0.1,
            map_size: 4.0,
            noise: PerceptionNoise::default(),
        }
    }
}

/// A box that appears ahead of the robot once it has touched down so many times (KAIST's
/// obstacle that appears mid-walk): `ahead` m from the pelvis along its heading, or toward a
/// point of the world (`toward`, e.g. the goal: the box is then on the way there whichever
/// way the robot turned to step around the last one). The boxes appear in the order listed.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Appear {
    /// After this many touch-downs.
    pub after_touchdowns: u64,
    /// Its centre this far ahead of the pelvis, m.
    pub ahead: f64,
    /// Ahead toward this point (x, y, m) instead of along the heading.
    pub toward: Option<[f64; 2]>,
    /// Its length (along the direction it appeared in), width and height, m.
    pub size: [f64; 3],
}

impl Appear {
    /// Where the box stands (x, y, yaw) if it appears now: `touchdowns` so far, the pelvis at
    /// (x, y) heading `yaw`. None while it waits.
    pub fn due(&self, touchdowns: u64, pelvis: [f64; 2], yaw: f64) -> Option<[f64; 3]> {
        if touchdowns < self.after_touchdowns {
            return None;
        }
        let dir = match self.toward {
            Some([x, y]) if (x - pelvis[0]).hypot(y - pelvis[1]) > 1e-9 => {
                (y - pelvis[1]).atan2(x - pelvis[0])
            }
            _ => yaw,
        };
        Some([
            pelvis[0] + self.ahead * dir.cos(),
            pelvis[1] + self.ahead * dir.sin(),
            dir,
        ])
    }

    fn check(&self) -> Result<(), String> {
        let finite = |v: &[f64]| v.iter().all(|v| v.is_finite());
        if finite(&[self.ahead])
            && self.size.iter().all(|v| v.is_finite() && *v > 0.0)
            && self.toward.is_none_or(|p| finite(&p))
        {
            Ok(())
        } else {
            Err(format!(
                "appear: a finite distance and point, and a positive size: {self:?}"
            ))
        }
    }
}

fn idle_rate_hz() -> f64 {
    10.0
}

/// A body whose joints have not moved (by more than [`STILL`] rad) for this long, s, rests.
pub const REST_AFTER: f64 = 0.2;
/// The largest change of a joint's true position, rad, that is no motion.
pub const STILL: f64 = 1e-6;

impl SimConfig {
    /// Checks rates, noises and channels.
    pub fn check(&self) -> Result<(), String> {
        let rate = |r: f64| r.is_finite() && r > 0.0 && r <= 1000.0;
        if !rate(self.rate_hz) || !rate(self.report_rate_hz) {
            return Err("rate_hz and report_rate_hz must be in (0, 1000]".into());
        }
        if !rate(self.odometry.rate_hz) || !rate(self.imu.rate_hz) || !rate(self.perception.rate_hz)
        {
            return Err("the odometry's, IMU's and perception's rates must be in (0, 1000]".into());
        }
        if !rate(self.idle_rate_hz) {
            return Err("idle_rate_hz must be in (0, 1000]".into());
        }
        let sigma = |s: f64| s.is_finite() && s >= 0.0;
        let n = &self.perception.noise;
        if ![
            self.odometry.position_sigma,
            self.odometry.yaw_sigma,
            self.imu.gyro_sigma,
            self.imu.accel_sigma,
            n.position,
            n.size,
            n.height,
            self.perception.delay,
        ]
        .into_iter()
        .all(sigma)
        {
            return Err("noises and the perception's delay must be finite and not negative".into());
        }
        if !(self.perception.map_size.is_finite() && self.perception.map_size > 0.0) {
            return Err("perception.map_size must be positive".into());
        }
        // What waits for its delay, and the map each carries, are sized by them.
        if self.perception.delay > 5.0 || self.perception.map_size > 50.0 {
            return Err(format!(
                "perception.delay {} s (at most 5) and perception.map_size {} m (at most 50)",
                self.perception.delay, self.perception.map_size
            ));
        }
        if self.true_joint_channels.is_empty() {
            return Err("true_joint_channels: the fake devices' channels are needed".into());
        }
        for a in &self.appear {
            a.check()?;
        }
        if let Some(s) = self.start {
            if !s.iter().all(|v| v.is_finite()) {
                return Err("start must be finite".into());
            }
        }
        self.body.check()?;
        self.hexapod_body.check()
    }

    /// `p` relative to the configuration file's directory.
    pub fn relative(&self, file: Option<&Path>, p: &Path) -> PathBuf {
        match file.and_then(Path::parent) {
            Some(dir) if p.is_relative() => dir.join(p),
            _ => p.to_path_buf(),
        }
    }
}

/// A scene obstacle as a perception message element.
pub fn obstacle_msg(id: i32, o: &Obstacle) -> ObstacleT {
    let extruded = |base: f64, height: Option<f64>| (base, base + height.unwrap_or(2.0));
    let mut m = ObstacleT {
        id,
        ..Default::default()
    };
    let corners = |m: &mut ObstacleT, pts: Vec<[f64; 3]>| {
        m.num_vertices = pts.len() as i32;
        m.vertices = pts;
    };
    match o {
        Obstacle::Circle {
            x,
            y,
            radius,
            height,
            base,
        } => {
            m.kind = ObstacleT::KIND_CIRCLE;
            m.center = [*x, *y, *base];
            m.radius = *radius;
            (m.z_min, m.z_max) = extruded(*base, *height);
        }
        Obstacle::Box { height, base, .. } | Obstacle::Polygon { height, base, .. } => {
            m.kind = ObstacleT::KIND_POLYGON;
            let poly = o.polygon().unwrap_or_default();
            let n = poly.len().max(1) as f64;
            let c = poly
                .iter()
                .fold([0.0; 2], |a, p| [a[0] + p.x / n, a[1] + p.y / n]);
            m.center = [c[0], c[1], *base];
            corners(&mut m, poly.iter().map(|p| [p.x, p.y, *base]).collect());
            (m.z_min, m.z_max) = extruded(*base, *height);
        }
        Obstacle::Sphere { centre, radius } => {
            m.kind = ObstacleT::KIND_SPHERE;
            m.center = *centre;
            m.radius = *radius;
            (m.z_min, m.z_max) = (centre[2] - radius, centre[2] + radius);
        }
        Obstacle::Capsule { a, b, radius } => {
            m.kind = ObstacleT::KIND_CAPSULE;
            m.center = [0, 1, 2].map(|k| (a[k] + b[k]) / 2.0);
            m.radius = *radius;
            corners(&mut m, vec![*a, *b]);
            (m.z_min, m.z_max) = (o.bottom(), o.top());
        }
        Obstacle::RoundedTriangle { points, radius } => {
            m.kind = ObstacleT::KIND_ROUNDED_TRIANGLE;
            m.center = [0, 1, 2].map(|k| points.iter().map(|p| p[k]).sum::<f64>() / 3.0);
            m.radius = *radius;
            corners(&mut m, points.to_vec());
            (m.z_min, m.z_max) = (o.bottom(), o.top());
        }
    }
    m
}

/// The part of `grid` within `size` m of (x, y), as an elevation map (unknown cells NaN).
pub fn elevation_msg(header: HeaderT, grid: &Grid, x: f64, y: f64, size: f64) -> ElevationMapT {
    let cells = |v: f64, origin: f64, n: usize| -> usize {
        (((v - origin) / grid.res).floor().max(0.0) as usize).min(n)
    };
    let (i0, i1) = (
        cells(x - size / 2.0, grid.origin.x, grid.nx),
        cells(x + size / 2.0, grid.origin.x, grid.nx),
    );
    let (j0, j1) = (
        cells(y - size / 2.0, grid.origin.y, grid.ny),
        cells(y + size / 2.0, grid.origin.y, grid.ny),
    );
    let (nx, ny) = (i1 - i0, j1 - j0);
    let mut elevation = Vec::with_capacity(nx * ny);
    for j in j0..j1 {
        for i in i0..i1 {
            elevation.push(grid.h[j * grid.nx + i] as f32);
        }
    }
    let n = elevation.len();
    let centre = grid.centre(i0, j0);
    ElevationMapT {
        header,
        origin_x: centre.x,
        origin_y: centre.y,
        resolution: grid.res,
        nx: nx as i32,
        ny: ny as i32,
        num_cells: n as i32,
        elevation,
        variance: vec![0.0; n],
        slope: vec![f32::NAN; n],
        roughness: vec![f32::NAN; n],
        traversability: vec![f32::NAN; n],
    }
}

/// A world vector in the frame of `p` (its rotation undone).
fn in_frame(p: &Pose, v: [f64; 3]) -> [f64; 3] {
    p.rotation.inverse_transform_vector(&v.into()).into()
}

fn pose_t(p: &stride_kinematics::math::Pose) -> PoseT {
    PoseT {
        position: p.position(),
        orientation: quaternion(p),
    }
}

/// A robot's model in the simulator: its bodies, the names of its joints (in the order its
/// body takes them) and their last true positions.
enum Model {
    Archie {
        robot: ArchieConfig,
        body: Option<Box<Body>>,
    },
    Hexapod {
        robot: Box<Hexapod>,
        body: Option<Box<HexBody>>,
        /// The body's pose and time at the previous step, for its velocities.
        last: Option<(f64, [f64; 3], f64)>,
        /// The body's linear and angular velocity (world frame), from the last two steps.
        velocity: ([f64; 3], [f64; 3]),
    },
}

/// The robot as the sensors see it: the pose of its body (the pelvis, the hexapod's body),
/// its velocities and acceleration in the world frame.
struct Kin {
    pose: Pose,
    velocity: [f64; 3],
    angular_velocity: [f64; 3],
    acceleration: [f64; 3],
}

/// One simulated run: the world, the body once every joint is known, the noise, the
/// perception on its way.
pub struct Sim {
    /// The configuration.
    pub cfg: SimConfig,
    world: World,
    model: Model,
    rng: Rng,
    start: [f64; 3],
    names: Vec<String>,
    q: Vec<Option<f64>>,
    /// Perception waiting for its delay: when it goes out, and what.
    pending: VecDeque<(f64, ObstacleListT, Option<ElevationMapT>)>,
    /// Words of what began since the last report.
    events: Vec<String>,
    min_margin: f64,
    min_clearance: f64,
    appeared: usize,
    /// The joints at the last step, and when (s) one of them last moved.
    last_q: Vec<f64>,
    moved_at: f64,
}

/// An event of Archie's body, in words.
fn archie_words(e: &Event) -> String {
    match e {
        Event::Touchdown { leg, at } => format!(
            "{} foot down at ({:.3}, {:.3}, {:.3})",
            leg.name(),
            at[0],
            at[1],
            at[2]
        ),
        Event::Collision { part, obstacle, at } => format!(
            "collision: {part} inside obstacle {obstacle} at ({:.3}, {:.3}, {:.3})",
            at[0], at[1], at[2]
        ),
        Event::Fall { zmp, margin } => format!(
            "fall: the ZMP ({:.3}, {:.3}) is {:.3} m outside the support polygon",
            zmp[0], zmp[1], -margin
        ),
        Event::Limit { joint, value } => format!("{joint} at its limit ({value:.3} rad)"),
    }
}

/// A robot the simulator can move.
pub enum Robot {
    /// Archie's robot file.
    Archie(ArchieConfig),
    /// The hexapod's.
    Hexapod(Hexapod),
}

impl Robot {
    /// Loads the robot file of `kind`.
    pub fn load(kind: SimRobot, path: &Path) -> anyhow::Result<Robot> {
        Ok(match kind {
            SimRobot::Archie => Robot::Archie(ArchieConfig::load(path)?),
            SimRobot::Hexapod => Robot::Hexapod(Hexapod::load(path)?),
        })
    }
}

impl Sim {
    /// A run of `scene` with `robot`.
    pub fn new(cfg: SimConfig, scene: Scene, robot: Robot) -> anyhow::Result<Sim> {
        let start = cfg
            .start
            .unwrap_or([scene.start.x, scene.start.y, scene.start.yaw]);
        let world = World::new(scene).map_err(|e| anyhow::anyhow!("the scene's map: {e}"))?;
        let (names, model): (Vec<String>, Model) = match robot {
            Robot::Archie(robot) => (
                [Leg::Left, Leg::Right]
                    .iter()
                    .flat_map(|l| robot.names(*l))
                    .collect(),
                Model::Archie { robot, body: None },
            ),
            Robot::Hexapod(robot) => (
                (1..=6u8)
                    .flat_map(|n| {
                        let leg = robot.leg(n).map_or(String::new(), |l| l.name.clone());
                        ["coxa", "femur", "tibia"].map(move |j| format!("{leg}_{j}"))
                    })
                    .collect(),
                Model::Hexapod {
                    robot: Box::new(robot),
                    body: None,
                    last: None,
                    velocity: ([0.0; 3], [0.0; 3]),
                },
            ),
        };
        Ok(Sim {
            rng: Rng::new(cfg.seed),
            q: vec![None; names.len()],
            names,
            cfg,
            world,
            model,
            start,
            pending: VecDeque::new(),
            events: Vec::new(),
            min_margin: f64::NAN,
            min_clearance: f64::INFINITY,
            appeared: 0,
            last_q: Vec::new(),
            moved_at: f64::NEG_INFINITY,
        })
    }

    /// True when no joint has moved for [`REST_AFTER`] s before the last step at `t` (s):
    /// the body rests (false until every joint is known).
    pub fn resting(&self, t: f64) -> bool {
        !self.last_q.is_empty() && t - self.moved_at >= REST_AFTER
    }

    /// True once every joint was measured and the body stands in the world.
    pub fn ready(&self) -> bool {
        match &self.model {
            Model::Archie { body, .. } => body.is_some(),
            Model::Hexapod { body, .. } => body.is_some(),
        }
    }

    /// Takes true joint positions (names not of the robot's joints, and positions that are
    /// not finite, are ignored).
    pub fn take_joints(&mut self, m: &JointStateT) {
        for (name, p) in m.names.iter().zip(&m.positions) {
            if !p.is_finite() {
                continue;
            }
            if let Some(k) = self.names.iter().position(|n| n == name) {
                self.q[k] = Some(*p);
            }
        }
    }

    /// The joints not measured yet.
    pub fn missing(&self) -> Vec<&str> {
        self.names
            .iter()
            .zip(&self.q)
            .filter(|(_, q)| q.is_none())
            .map(|(n, _)| n.as_str())
            .collect()
    }

    /// Every joint's last true position, in the body's order, once all are known.
    fn joints(&self) -> Option<Vec<f64>> {
        self.q.iter().copied().collect()
    }

    /// The body's pose, velocities and acceleration.
    fn kin(&self) -> Option<Kin> {
        match &self.model {
            Model::Archie { body, .. } => {
                let s = &body.as_ref()?.state;
                let (velocity, angular_velocity, acceleration) = match &s.fitted {
                    Some(f) => (f.velocity, f.angular_velocity, f.acceleration),
                    None => ([0.0; 3], [0.0; 3], [0.0; 3]),
                };
                Some(Kin {
                    pose: s.pelvis,
                    velocity,
                    angular_velocity,
                    acceleration,
                })
            }
            Model::Hexapod { body, velocity, .. } => {
                let (p, yaw) = body.as_ref()?.pose();
                Some(Kin {
                    pose: yawed(p, yaw),
                    velocity: velocity.0,
                    angular_velocity: velocity.1,
                    acceleration: [0.0; 3],
                })
            }
        }
    }

    /// The name of the body's frame.
    fn frame(&self) -> &'static str {
        match self.model {
            Model::Archie { .. } => "pelvis",
            Model::Hexapod { .. } => "body",
        }
    }

    /// Moves the body to the joints last measured, at `t` (s); returns what began, in words
    /// (empty until every joint is known).
    pub fn step(&mut self, t: f64) -> Vec<String> {
        let Some(q) = self.joints() else {
            return Vec::new();
        };
        let moved = self.last_q.len() != q.len()
            || q.iter()
                .zip(&self.last_q)
                .any(|(a, b)| (a - b).abs() > STILL);
        if moved {
            self.moved_at = t;
            self.last_q.clone_from(&q);
        }
        let (mut words, touchdowns) = match &mut self.model {
            Model::Archie { robot, body } => {
                let q: [Q; 2] = [
                    std::array::from_fn(|k| q[k]),
                    std::array::from_fn(|k| q[6 + k]),
                ];
                let body = match body {
                    Some(b) => b,
                    None => body.insert(Box::new(Body::new(
                        robot.clone(),
                        self.cfg.body,
                        self.start,
                        q,
                        &self.world,
                    ))),
                };
                let words: Vec<String> = body
                    .step(t, &q, &self.world)
                    .iter()
                    .map(archie_words)
                    .collect();
                let s = &body.state;
                if let Some(f) = &s.fitted {
                    self.min_margin = if self.min_margin.is_nan() {
                        f.margin
                    } else {
                        self.min_margin.min(f.margin)
                    };
                }
                self.min_clearance = self.min_clearance.min(s.clearance);
                (words, body.counts().touchdowns)
            }
            Model::Hexapod {
                robot,
                body,
                last,
                velocity,
            } => {
                let q: [[f64; 3]; 6] =
                    std::array::from_fn(|l| std::array::from_fn(|j| q[3 * l + j]));
                let body = match body {
                    Some(b) => b,
                    None => {
                        let b = HexBody::new(
                            (**robot).clone(),
                            self.cfg.hexapod_body,
                            self.start,
                            &q,
                            &self.world,
                        )
                        .map_err(|e| anyhow::anyhow!("{e}"));
                        match b {
                            Ok(b) => body.insert(Box::new(b)),
                            Err(e) => return vec![format!("the hexapod cannot stand: {e}")],
                        }
                    }
                };
                let words: Vec<String> = body
                    .step(t, &q, &self.world)
                    .iter()
                    .map(|e| e.to_string())
                    .collect();
                let (p, yaw) = body.pose();
                if let Some((t0, p0, yaw0)) = *last {
                    let dt = t - t0;
                    if dt > 1e-6 {
                        let mut dyaw = yaw - yaw0;
                        dyaw = (dyaw + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                            - std::f64::consts::PI;
                        *velocity = (
                            [0, 1, 2].map(|k| (p[k] - p0[k]) / dt),
                            [0.0, 0.0, dyaw / dt],
                        );
                    }
                }
                *last = Some((t, p, yaw));
                self.min_margin = body.min_margin();
                self.min_clearance = body.min_clearance();
                (words, body.counts().touchdowns)
            }
        };
        // An obstacle due to appear.
        let Some(kin) = self.kin() else {
            return words;
        };
        let (pelvis, yaw) = (kin.pose.position(), yaw_of(&kin.pose));
        while let Some(a) = self.cfg.appear.get(self.appeared).copied() {
            let Some([x, y, yaw]) = a.due(touchdowns, [pelvis[0], pelvis[1]], yaw) else {
                break;
            };
            self.appeared += 1;
            let ob = Obstacle::Box {
                x,
                y,
                yaw,
                length: a.size[0],
                width: a.size[1],
                height: Some(a.size[2]),
                base: 0.0,
            };
            match self.world.add(ob) {
                Ok(()) => words.push(format!(
                    "an obstacle of {:?} m appeared at ({x:.3}, {y:.3})",
                    a.size
                )),
                Err(e) => words.push(format!("an obstacle could not appear: {e}")),
            }
        }
        self.events.extend(words.iter().cloned());
        words
    }

    /// The body's true pose (Archie's pelvis, the hexapod's body).
    pub fn pose_msg(&self, header: HeaderT) -> Option<PoseStampedT> {
        let k = self.kin()?;
        Some(PoseStampedT {
            header,
            child_frame: self.frame().into(),
            pose: pose_t(&k.pose),
        })
    }

    /// The odometry: the true pose with noise, the velocities in the body frame.
    pub fn odometry_msg(&mut self, header: HeaderT) -> Option<OdometryT> {
        let k = self.kin()?;
        let c = &self.cfg.odometry;
        let mut p = pose_t(&k.pose);
        for v in &mut p.position {
            *v += self.rng.normal(c.position_sigma);
        }
        let yaw = yaw_of(&k.pose) + self.rng.normal(c.yaw_sigma);
        p.orientation = [(yaw / 2.0).cos(), 0.0, 0.0, (yaw / 2.0).sin()];
        let mut cov = [0.0; 36];
        for i in 0..3 {
            cov[i * 7] = c.position_sigma.powi(2);
        }
        cov[35] = c.yaw_sigma.powi(2);
        let body_frame = |v| in_frame(&k.pose, v);
        Some(OdometryT {
            header,
            child_frame: self.frame().into(),
            pose: p,
            pose_covariance: cov,
            linear_velocity: body_frame(k.velocity),
            angular_velocity: body_frame(k.angular_velocity),
            twist_covariance: [0.0; 36],
            step_number: -1,
        })
    }

    /// The IMU: the body's orientation, angular velocity and specific force in its frame,
    /// with noise.
    pub fn imu_msg(&mut self, header: HeaderT) -> Option<ImuT> {
        let k = self.kin()?;
        let c = &self.cfg.imu;
        let body_frame = |v| in_frame(&k.pose, v);
        let a = k.acceleration;
        let g = self.cfg.body.g;
        let mut w = body_frame(k.angular_velocity);
        let mut f = body_frame([a[0], a[1], a[2] + g]);
        for v in &mut w {
            *v += self.rng.normal(c.gyro_sigma);
        }
        for v in &mut f {
            *v += self.rng.normal(c.accel_sigma);
        }
        Some(ImuT {
            header,
            orientation: quaternion(&k.pose),
            angular_velocity: w,
            linear_acceleration: f,
            temperature: f32::NAN,
        })
    }

    /// Perception of now, queued to go out after its delay.
    pub fn perceive(&mut self, t: f64, obstacles: HeaderT, map: HeaderT) {
        let n = self.cfg.perception.noise;
        let list: Vec<ObstacleT> = self
            .world
            .perceived_obstacles(&n, &mut self.rng)
            .iter()
            .enumerate()
            .map(|(i, o)| obstacle_msg(i as i32, o))
            .collect();
        let grid = self.world.perceived_elevation(&n, &mut self.rng);
        let at = self
            .kin()
            .map_or([self.start[0], self.start[1], 0.0], |k| k.pose.position());
        let map = elevation_msg(map, &grid, at[0], at[1], self.cfg.perception.map_size);
        self.pending.push_back((
            t + self.cfg.perception.delay,
            ObstacleListT {
                header: obstacles,
                num_obstacles: list.len() as i32,
                obstacles: list,
            },
            Some(map),
        ));
    }

    /// Perception whose delay is over at `t`.
    pub fn perception_due(&mut self, t: f64) -> Vec<(ObstacleListT, Option<ElevationMapT>)> {
        let mut out = Vec::new();
        while self.pending.front().is_some_and(|p| p.0 <= t) {
            let (_, o, m) = self.pending.pop_front().expect("checked");
            out.push((o, m));
        }
        out
    }

    /// The report, with what began since the last one.
    pub fn report_msg(&mut self, header: HeaderT, scene: &str) -> SimReportT {
        let events = std::mem::take(&mut self.events);
        let mut m = SimReportT {
            header,
            scene: scene.into(),
            seed: self.cfg.seed as i64,
            zmp_margin: f64::NAN,
            min_zmp_margin: self.min_margin,
            min_clearance: self.min_clearance,
            num_events: events.len() as i32,
            events,
            ..Default::default()
        };
        match &self.model {
            Model::Archie { body: Some(b), .. } => {
                let s = &b.state;
                let c = b.counts();
                m.feet = s.feet;
                m.contact = s.contact;
                m.anchor = match s.anchor {
                    Leg::Left => FootT::SIDE_LEFT,
                    Leg::Right => FootT::SIDE_RIGHT,
                };
                m.com = s.com;
                m.zmp_margin = s.fitted.map_or(f64::NAN, |f| f.margin);
                m.touchdowns = c.touchdowns as i64;
                m.collisions = c.collisions as i64;
                m.falls = c.falls as i64;
                m.limits = c.limits as i64;
            }
            // Six feet do not fit the report's two: the body's centre stands for the centre
            // of mass, its static margin in the feet's support polygon for the ZMP's.
            Model::Hexapod { body: Some(b), .. } => {
                let c = b.counts();
                m.anchor = -1;
                m.com = b.pose().0;
                m.zmp_margin = b.margin();
                m.touchdowns = c.touchdowns as i64;
                m.collisions = c.collisions as i64;
                m.falls = c.falls as i64;
                m.limits = c.limits as i64;
            }
            _ => {}
        }
        m
    }

    /// True when something began since the last report.
    pub fn has_events(&self) -> bool {
        !self.events.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn archie() -> Sim {
        let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../config"));
        let file = dir.join("sim-archie.toml");
        let cfg: SimConfig = toml::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
        cfg.check().unwrap();
        let scene = Scene::load(&cfg.relative(Some(&file), cfg.scene.as_ref().unwrap())).unwrap();
        let robot = Robot::load(cfg.robot, &cfg.relative(Some(&file), &cfg.robot_file)).unwrap();
        Sim::new(cfg, scene, robot).unwrap()
    }

    fn joints(sim: &Sim, knee: f64) -> JointStateT {
        let n = sim.names.len();
        JointStateT {
            num_joints: n as i32,
            names: sim.names.clone(),
            positions: sim
                .names
                .iter()
                .map(|j| if j.contains("knee") { knee } else { 0.0 })
                .collect(),
            velocities: vec![0.0; n],
            ..Default::default()
        }
    }

    #[test]
    fn a_box_appears_ahead_along_the_heading_or_toward_a_point() {
        let b7 = Appear {
            after_touchdowns: 3,
            ahead: 1.0,
            toward: None,
            size: [0.5, 0.5, 1.8],
        };
        b7.check().unwrap();
        let yaw = std::f64::consts::FRAC_PI_2;
        assert_eq!(b7.due(2, [1.0, 2.0], yaw), None);
        let [x, y, a] = b7.due(3, [1.0, 2.0], yaw).unwrap();
        assert!((x - 1.0).abs() < 1e-12 && (y - 3.0).abs() < 1e-12 && a == yaw);
        // Toward the goal, whichever way the robot faces.
        let on_the_way = Appear {
            toward: Some([11.0, 2.0]),
            ..b7
        };
        let [x, y, a] = on_the_way.due(5, [1.0, 2.0], yaw).unwrap();
        assert!((x - 2.0).abs() < 1e-12 && (y - 2.0).abs() < 1e-12 && a.abs() < 1e-12);
        let bad = Appear {
            toward: Some([f64::NAN, 0.0]),
            ..b7
        };
        assert!(bad.check().is_err());
    }

    #[test]
    fn the_body_rests_once_no_joint_has_moved_for_a_while() {
        let mut sim = archie();
        assert!(!sim.resting(0.0), "nothing measured yet");
        let still = joints(&sim, 0.3);
        let mut t = 0.0;
        while t < REST_AFTER - 0.05 {
            sim.take_joints(&still);
            sim.step(t);
            assert!(!sim.resting(t), "{t}");
            t += 0.01;
        }
        sim.take_joints(&still);
        sim.step(REST_AFTER);
        assert!(sim.resting(REST_AFTER));
        // A joint moves: no longer at rest, at once.
        sim.take_joints(&joints(&sim, 0.3 + 1e-4));
        sim.step(REST_AFTER + 0.01);
        assert!(!sim.resting(REST_AFTER + 0.01));
    }
}
