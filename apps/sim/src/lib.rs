//! `stride-sim`, the simulated world, as a library: its configuration, the simulation of one
//! run (the body, the world, the noise, the delayed perception) apart from the bus, and the
//! messages it publishes; the app itself is in [`app`].

pub mod app;

use std::collections::VecDeque;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use stride_kinematics::archie::{ArchieConfig, Leg, Q};
use stride_lcmtypes::stride::{
    ElevationMapT, FootT, HeaderT, ImuT, JointStateT, ObstacleListT, ObstacleT, OdometryT,
    PoseStampedT, PoseT, SimReportT,
};
use stride_sim::body::{quaternion, yaw_of, Body, BodyConfig, Event};
use stride_sim::noise::Rng;
use stride_sim::world::{PerceptionNoise, World};
use stride_world::grid::Grid;
use stride_world::scene::{Obstacle, Scene};

/// The simulator's file (config/sim-archie.toml).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    /// The scene, relative to this file (`--scene` overrides it).
    pub scene: Option<PathBuf>,
    /// Archie's robot file, relative to this file.
    pub robot_file: PathBuf,
    /// The seed of every noise: the same seed, the same run.
    #[serde(default)]
    pub seed: u64,
    /// How often the body moves, Hz.
    pub rate_hz: f64,
    /// How often the report goes out, Hz (and at once when something begins).
    pub report_rate_hz: f64,
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
    /// How the body meets the ground and what counts as wrong.
    #[serde(default)]
    pub body: BodyConfig,
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
/// obstacle that appears mid-walk).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Appear {
    /// After this many touch-downs.
    pub after_touchdowns: u64,
    /// Its centre this far ahead of the pelvis, along the heading, m.
    pub ahead: f64,
    /// Its length (along the heading), width and height, m.
    pub size: [f64; 3],
}

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
        if self.true_joint_channels.is_empty() {
            return Err("true_joint_channels: the fake devices' channels are needed".into());
        }
        for a in &self.appear {
            if !(a.ahead.is_finite() && a.size.iter().all(|v| v.is_finite() && *v > 0.0)) {
                return Err(format!(
                    "appear: a finite distance and a positive size: {a:?}"
                ));
            }
        }
        if let Some(s) = self.start {
            if !s.iter().all(|v| v.is_finite()) {
                return Err("start must be finite".into());
            }
        }
        self.body.check()
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

/// A world vector in the frame whose axes are the columns of `r`.
fn in_frame(r: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| (0..3).map(|k| r[k][i] * v[k]).sum())
}

fn pose_t(p: &stride_kinematics::math::Pose) -> PoseT {
    PoseT {
        position: p.p,
        orientation: quaternion(&p.r),
    }
}

/// One simulated run: the world, the body once every joint is known, the noise, the
/// perception on its way.
pub struct Sim {
    /// The configuration.
    pub cfg: SimConfig,
    world: World,
    robot: ArchieConfig,
    body: Option<Body>,
    rng: Rng,
    start: [f64; 3],
    names: [[String; 6]; 2],
    q: [[Option<f64>; 6]; 2],
    /// Perception waiting for its delay: when it goes out, and what.
    pending: VecDeque<(f64, ObstacleListT, Option<ElevationMapT>)>,
    /// Words of what began since the last report.
    events: Vec<String>,
    min_margin: f64,
    min_clearance: f64,
    appeared: usize,
}

impl Sim {
    /// A run of `scene` with `robot`.
    pub fn new(cfg: SimConfig, scene: Scene, robot: ArchieConfig) -> anyhow::Result<Sim> {
        let start = cfg
            .start
            .unwrap_or([scene.start.x, scene.start.y, scene.start.yaw]);
        let world = World::new(scene).map_err(|e| anyhow::anyhow!("the scene's map: {e}"))?;
        Ok(Sim {
            rng: Rng::new(cfg.seed),
            names: [robot.names(Leg::Left), robot.names(Leg::Right)],
            cfg,
            world,
            robot,
            body: None,
            start,
            q: [[None; 6]; 2],
            pending: VecDeque::new(),
            events: Vec::new(),
            min_margin: f64::NAN,
            min_clearance: f64::INFINITY,
            appeared: 0,
        })
    }

    /// The body, once every joint was measured.
    pub fn body(&self) -> Option<&Body> {
        self.body.as_ref()
    }

    /// Takes true joint positions (names not of Archie's legs, and positions that are not
    /// finite, are ignored).
    pub fn take_joints(&mut self, m: &JointStateT) {
        for (name, p) in m.names.iter().zip(&m.positions) {
            if !p.is_finite() {
                continue;
            }
            for leg in 0..2 {
                if let Some(k) = self.names[leg].iter().position(|n| n == name) {
                    self.q[leg][k] = Some(*p);
                }
            }
        }
    }

    /// The joints not measured yet.
    pub fn missing(&self) -> Vec<&str> {
        (0..2)
            .flat_map(|l| (0..6).map(move |k| (l, k)))
            .filter(|&(l, k)| self.q[l][k].is_none())
            .map(|(l, k)| self.names[l][k].as_str())
            .collect()
    }

    fn joints(&self) -> Option<[Q; 2]> {
        let leg = |l: usize| -> Option<Q> {
            let mut q = [0.0; 6];
            for (k, v) in q.iter_mut().enumerate() {
                *v = self.q[l][k]?;
            }
            Some(q)
        };
        Some([leg(0)?, leg(1)?])
    }

    /// Moves the body to the joints last measured, at `t` (s); returns what began, in words
    /// (empty until every joint is known).
    pub fn step(&mut self, t: f64) -> Vec<String> {
        let Some(q) = self.joints() else {
            return Vec::new();
        };
        let body = match &mut self.body {
            Some(b) => b,
            None => {
                let b = Body::new(
                    self.robot.clone(),
                    self.cfg.body,
                    self.start,
                    q,
                    &self.world,
                );
                self.body.insert(b)
            }
        };
        let mut words: Vec<String> = body
            .step(t, &q, &self.world)
            .iter()
            .map(|e| match e {
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
                Event::Limit { joint, value } => {
                    format!("{joint} at its limit ({value:.3} rad)")
                }
            })
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
        // An obstacle due to appear.
        let touchdowns = body.counts().touchdowns;
        let (pelvis, yaw) = (s.pelvis.p, yaw_of(&s.pelvis));
        while let Some(a) = self.cfg.appear.get(self.appeared).copied() {
            if touchdowns < a.after_touchdowns {
                break;
            }
            self.appeared += 1;
            let (x, y) = (
                pelvis[0] + a.ahead * yaw.cos(),
                pelvis[1] + a.ahead * yaw.sin(),
            );
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

    /// The pelvis's true pose.
    pub fn pose_msg(&self, header: HeaderT) -> Option<PoseStampedT> {
        let b = self.body.as_ref()?;
        Some(PoseStampedT {
            header,
            child_frame: "pelvis".into(),
            pose: pose_t(&b.state.pelvis),
        })
    }

    /// The odometry: the true pose with noise, the fitted velocity in the body frame.
    pub fn odometry_msg(&mut self, header: HeaderT) -> Option<OdometryT> {
        let b = self.body.as_ref()?;
        let s = &b.state;
        let c = &self.cfg.odometry;
        let mut p = pose_t(&s.pelvis);
        for v in &mut p.position {
            *v += self.rng.normal(c.position_sigma);
        }
        let yaw = yaw_of(&s.pelvis) + self.rng.normal(c.yaw_sigma);
        p.orientation = [(yaw / 2.0).cos(), 0.0, 0.0, (yaw / 2.0).sin()];
        let mut cov = [0.0; 36];
        for k in 0..3 {
            cov[k * 7] = c.position_sigma.powi(2);
        }
        cov[35] = c.yaw_sigma.powi(2);
        let body_frame = |v| in_frame(&s.pelvis.r, v);
        let (lin, ang) = match &s.fitted {
            Some(f) => (body_frame(f.velocity), body_frame(f.angular_velocity)),
            None => ([0.0; 3], [0.0; 3]),
        };
        Some(OdometryT {
            header,
            child_frame: "pelvis".into(),
            pose: p,
            pose_covariance: cov,
            linear_velocity: lin,
            angular_velocity: ang,
            twist_covariance: [0.0; 36],
            step_number: -1,
        })
    }

    /// The IMU: the pelvis's orientation, angular velocity and specific force in its frame,
    /// with noise.
    pub fn imu_msg(&mut self, header: HeaderT) -> Option<ImuT> {
        let b = self.body.as_ref()?;
        let s = &b.state;
        let c = &self.cfg.imu;
        let r = &s.pelvis.r;
        let body_frame = |v| in_frame(r, v);
        let (w, a) = match &s.fitted {
            Some(f) => (f.angular_velocity, f.acceleration),
            None => ([0.0; 3], [0.0; 3]),
        };
        let g = self.cfg.body.g;
        let mut w = body_frame(w);
        let mut f = body_frame([a[0], a[1], a[2] + g]);
        for v in &mut w {
            *v += self.rng.normal(c.gyro_sigma);
        }
        for v in &mut f {
            *v += self.rng.normal(c.accel_sigma);
        }
        Some(ImuT {
            header,
            orientation: quaternion(r),
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
            .body
            .as_ref()
            .map_or([self.start[0], self.start[1], 0.0], |b| b.state.pelvis.p);
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
        if let Some(b) = &self.body {
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
        m
    }

    /// True when something began since the last report.
    pub fn has_events(&self) -> bool {
        !self.events.is_empty()
    }
}
