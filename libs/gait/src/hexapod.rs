//! The hexapod's gaits: a walk is a sequence of configurations (the body's pose and the six
//! feet on the ground, world frame) joined by transitions in which some legs swing while the
//! body moves.
//!
//! - The thesis's wave ("pentapod") gait: one leg swings at a time while the body moves, five
//!   feet on the ground; it executes foothold plans (one leg's foothold changes from one
//!   configuration to the next) and, on flat ground, a straight walk with the legs in the
//!   order rear to front, alternating sides (5, 6, 1, 4, 3, 2: the thesis names no order).
//! - A tripod gait for flat ground (not in the thesis): legs {1, 3, 5} and {2, 4, 6} swing in
//!   turn, duty factor 0.5.
//! - The sensing lift: the body rises 0.07 m with all six feet down, so that the camera sees
//!   further (the thesis's scan pose), and comes down again.
//!
//! Every control period each servo gets its goal and the moving speed that brings it there
//! by the period's end (all joints arrive together); every sample is solved by the legs'
//! inverse kinematics and checked against Table 3.2's limits and the servos' speed, and the
//! body's centre of mass keeps a static stability margin in the polygon of the feet on the
//! ground. A walk that breaks any of these is refused whole.

use serde::Deserialize;
use stride_kinematics::hexapod::Hexapod;

use crate::support::{hull, margin, P2};
use crate::swing::{Spline, SwingConfig, SwingPath};
use crate::GaitError;

/// The body's pose in the world: x, y, z (m) and yaw (rad).
pub type BodyPose = [f64; 4];

/// The body and the six feet (world frame, m), legs in the order of their numbers 1 to 6.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HexConfig {
    /// The body's pose.
    pub body: BodyPose,
    /// The feet.
    pub feet: [[f64; 3]; 6],
}

/// The hexapod gait's parameters.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HexGaitConfig {
    /// The control period, s (the servo bridge's).
    pub period: f64,
    /// The standing foot: its distance from the coxa axis along the leg, m.
    pub reach: f64,
    /// The body's height above the feet (the coxa axes above the ground), m.
    pub height: f64,
    /// Tripod: the stride (the body's advance per half cycle), m.
    pub stride: f64,
    /// Tripod: the cycle's period, s.
    pub cycle: f64,
    /// Wave gait: one leg's swing, s.
    pub wave_swing: f64,
    /// How high a swing clears the ground (or the terrain it crosses), m.
    pub swing_height: f64,
    /// The sensing lift, m.
    pub sensing_lift: f64,
    /// The feet's reach for the sensing lift (lifted, the legs reach less far), m.
    pub sensing_reach: f64,
    /// The sensing lift's duration each way, s.
    pub sensing_time: f64,
    /// The smallest static stability margin, m.
    pub min_margin: f64,
    /// The centre of mass, body frame, m.
    pub com: [f64; 3],
    /// The servos' top speed, rad/s (the AX-12A's 59 rpm at 12 V).
    pub max_speed: f64,
}

impl Default for HexGaitConfig {
    fn default() -> HexGaitConfig {
        HexGaitConfig {
            period: 0.02,
            reach: 0.195,
            height: 0.08,
            stride: 0.04,
            cycle: 1.0,
            wave_swing: 0.5,
            swing_height: 0.02,
            sensing_lift: 0.07,
            sensing_reach: 0.175,
            sensing_time: 1.0,
            min_margin: 0.02,
            com: [0.0, 0.0, 0.0],
            max_speed: 59.0 * std::f64::consts::TAU / 60.0,
        }
    }
}

/// One control period's set-points for the 18 servos.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HexRow {
    /// Time from the walk's start, s.
    pub t: f64,
    /// Servo angles about their centres (o + a), degrees, legs 1 to 6: coxa, femur, tibia.
    pub servo_deg: [[f64; 3]; 6],
    /// Raw AX-12A goal positions.
    pub raw: [[u16; 3]; 6],
    /// The speed that brings each servo from the previous row's angle to this one within
    /// the period, rad/s (0 in the first row).
    pub speed: [[f64; 3]; 6],
    /// The same as the AX-12A's moving speed register (about 0.111 rpm a unit, at least 1:
    /// 0 would mean no speed control at all).
    pub moving_speed: [[u16; 3]; 6],
    /// The static stability margin, m.
    pub margin: f64,
}

/// The AX-12A's moving speed unit, rad/s (0.111 rpm).
pub const SPEED_UNIT: f64 = 0.111 * std::f64::consts::TAU / 60.0;

/// A transition: the legs that swing (numbers 1 to 6), and how long it takes.
#[derive(Debug, Clone, PartialEq)]
pub struct Transition {
    /// The legs that swing.
    pub swing: Vec<u8>,
    /// Its duration, s.
    pub duration: f64,
}

fn rotz(yaw: f64, v: [f64; 3]) -> [f64; 3] {
    let (s, c) = yaw.sin_cos();
    [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]
}

/// A point of the body frame in the world.
pub fn to_world(body: &BodyPose, p: [f64; 3]) -> [f64; 3] {
    let r = rotz(body[3], p);
    [body[0] + r[0], body[1] + r[1], body[2] + r[2]]
}

/// A point of the world in the body frame.
pub fn to_body(body: &BodyPose, p: [f64; 3]) -> [f64; 3] {
    rotz(-body[3], [p[0] - body[0], p[1] - body[1], p[2] - body[2]])
}

/// The hexapod's gaits over its kinematics.
#[derive(Debug, Clone)]
pub struct HexGait {
    /// The legs.
    pub robot: Hexapod,
    /// The gait's parameters.
    pub cfg: HexGaitConfig,
}

impl HexGait {
    /// The gait of `robot`.
    pub fn new(robot: Hexapod, cfg: HexGaitConfig) -> Result<HexGait, GaitError> {
        let pos = [
            cfg.period,
            cfg.reach,
            cfg.height,
            cfg.cycle,
            cfg.wave_swing,
            cfg.sensing_time,
            cfg.max_speed,
        ];
        let finite = cfg.swing_height.is_finite() && cfg.min_margin.is_finite();
        // A stride sizes a walk's cycles: a positive one, at least a centimetre.
        let stride = cfg.stride.is_finite() && cfg.stride >= 0.01;
        if !(pos.iter().all(|v| v.is_finite() && *v > 0.0) && finite && stride) {
            return Err(GaitError::Parameter(format!(
                "hexapod gait: positive periods, reach, height and speed and a stride of at \
                 least 0.01 m wanted: {cfg:?}"
            )));
        }
        Ok(HexGait { robot, cfg })
    }

    /// Leg `n`'s standing foot, body frame.
    pub fn home(&self, n: u8) -> [f64; 3] {
        let leg = self.robot.leg(n).expect("legs 1 to 6");
        Hexapod::to_body(leg, [self.cfg.reach, 0.0, -self.cfg.height])
    }

    /// Standing with the body at `body` (its z is the ground's height; the body stands
    /// `height` above it).
    pub fn standing(&self, body: BodyPose) -> HexConfig {
        let up = [body[0], body[1], body[2] + self.cfg.height, body[3]];
        HexConfig {
            body: up,
            feet: std::array::from_fn(|i| to_world(&up, self.home(i as u8 + 1))),
        }
    }

    /// A tripod walk from standing at `from` over `distance` m straight ahead (the body's
    /// heading), in whole strides, back to standing.
    pub fn tripod(&self, from: &HexConfig, distance: f64) -> (Vec<HexConfig>, Vec<Transition>) {
        let s = self.cfg.stride;
        let n = (distance.abs() / s).ceil().max(1.0) as usize;
        let step = distance / n as f64;
        let dir = rotz(from.body[3], [1.0, 0.0, 0.0]);
        let body_at = |k: f64| -> BodyPose {
            [
                from.body[0] + dir[0] * step * k,
                from.body[1] + dir[1] * step * k,
                from.body[2],
                from.body[3],
            ]
        };
        let groups: [Vec<u8>; 2] = [vec![1, 3, 5], vec![2, 4, 6]];
        let mut configs = vec![*from];
        let mut trans = Vec::new();
        let mut cur = *from;
        // Half cycle k: the body goes from body_at(k) to body_at(k + 1); the swinging
        // group lands where it stands centred for the next stance (half a stride ahead of
        // home under the next body), the last two halves bring every foot home.
        let halves = n + 1;
        for k in 0..halves {
            let g = &groups[k % 2];
            let b = body_at(((k + 1).min(n)) as f64);
            let ahead = if k + 1 >= n { 0.0 } else { 0.5 };
            let target_body = body_at(((k + 1) as f64 + ahead).min(n as f64));
            let mut next = cur;
            next.body = b;
            for &leg in g {
                next.feet[leg as usize - 1] = to_world(&target_body, self.home(leg));
            }
            configs.push(next);
            trans.push(Transition {
                swing: g.clone(),
                duration: self.cfg.cycle / 2.0,
            });
            cur = next;
        }
        (configs, trans)
    }

    /// A wave (pentapod) walk from standing at `from` over `distance` m straight ahead: the
    /// legs one at a time, rear to front and alternating sides (5, 6, 1, 4, 3, 2), each
    /// stepping a stride while the body advances a sixth of it.
    pub fn wave(&self, from: &HexConfig, distance: f64) -> (Vec<HexConfig>, Vec<Transition>) {
        const ORDER: [u8; 6] = [5, 6, 1, 4, 3, 2];
        let s = self.cfg.stride;
        let cycles = (distance.abs() / s).ceil().max(1.0) as usize;
        let stride = distance / cycles as f64;
        let dir = rotz(from.body[3], [1.0, 0.0, 0.0]);
        let mut configs = vec![*from];
        let mut trans = Vec::new();
        let mut cur = *from;
        for c in 0..cycles {
            for (i, &leg) in ORDER.iter().enumerate() {
                let k = (c * 6 + i + 1) as f64 / 6.0;
                let mut next = cur;
                next.body = [
                    from.body[0] + dir[0] * stride * k,
                    from.body[1] + dir[1] * stride * k,
                    from.body[2],
                    from.body[3],
                ];
                let done = (c + 1) as f64;
                let landing = [
                    from.body[0] + dir[0] * stride * done,
                    from.body[1] + dir[1] * stride * done,
                    from.body[2],
                    from.body[3],
                ];
                next.feet[leg as usize - 1] = to_world(&landing, self.home(leg));
                configs.push(next);
                trans.push(Transition {
                    swing: vec![leg],
                    duration: self.cfg.wave_swing,
                });
                cur = next;
            }
        }
        (configs, trans)
    }

    /// The sensing lift from standing at `from`: the legs step in to the sensing reach one at
    /// a time (a leg lifted that far up reaches less far out), the body rises by the
    /// configured lift with every foot down, comes down again, and the legs step back out.
    pub fn sensing_lift(&self, from: &HexConfig) -> (Vec<HexConfig>, Vec<Transition>) {
        const ORDER: [u8; 6] = [5, 6, 1, 4, 3, 2];
        let mut configs = vec![*from];
        let mut trans = Vec::new();
        let mut cur = *from;
        let step = |leg: u8, reach: f64| {
            let l = self.robot.leg(leg).expect("legs 1 to 6");
            to_world(
                &from.body,
                Hexapod::to_body(l, [reach, 0.0, -self.cfg.height]),
            )
        };
        for &leg in &ORDER {
            cur.feet[leg as usize - 1] = step(leg, self.cfg.sensing_reach);
            configs.push(cur);
            trans.push(Transition {
                swing: vec![leg],
                duration: self.cfg.wave_swing,
            });
        }
        let mut up = cur;
        up.body[2] += self.cfg.sensing_lift;
        let hold = Transition {
            swing: Vec::new(),
            duration: self.cfg.sensing_time,
        };
        configs.push(up);
        trans.push(hold.clone());
        configs.push(cur);
        trans.push(hold);
        for &leg in &ORDER {
            cur.feet[leg as usize - 1] = step(leg, self.cfg.reach);
            configs.push(cur);
            trans.push(Transition {
                swing: vec![leg],
                duration: self.cfg.wave_swing,
            });
        }
        (configs, trans)
    }

    /// A foothold plan's configurations, checked to change one foot at a time (the thesis's
    /// pentapod gait): the transitions that execute them.
    pub fn foothold_plan(&self, configs: &[HexConfig]) -> Result<Vec<Transition>, GaitError> {
        configs
            .windows(2)
            .enumerate()
            .map(|(i, w)| {
                let moved: Vec<u8> = (0..6)
                    .filter(|&k| {
                        let (a, b) = (w[0].feet[k], w[1].feet[k]);
                        (a[0] - b[0]).hypot(a[1] - b[1]).hypot(a[2] - b[2]) > 1e-9
                    })
                    .map(|k| k as u8 + 1)
                    .collect();
                if moved.len() > 1 {
                    return Err(GaitError::Plan(format!(
                        "foothold plan: configurations {i} and {} move legs {moved:?}: one at a \
                         time",
                        i + 1
                    )));
                }
                Ok(Transition {
                    swing: moved,
                    duration: self.cfg.wave_swing,
                })
            })
            .collect()
    }

    /// The rows of a walk through `configs` joined by `trans`, every control period, checked:
    /// each foot reachable within the servos' limits, every speed within the servos' top
    /// speed, the static stability margin kept. `terrain` is the highest ground a swing
    /// crosses (None: the higher of its ends).
    pub fn rows(
        &self,
        configs: &[HexConfig],
        trans: &[Transition],
        terrain: Option<&dyn Fn([f64; 3], [f64; 3]) -> f64>,
    ) -> Result<Vec<HexRow>, GaitError> {
        if configs.len() != trans.len() + 1 || configs.is_empty() {
            return Err(GaitError::Plan(
                "a walk needs one more configuration than transitions".into(),
            ));
        }
        let dt = self.cfg.period;
        let mut times = vec![0.0];
        for t in trans {
            if !(t.duration.is_finite() && t.duration > 0.0) {
                return Err(GaitError::Plan(
                    "a transition needs a positive duration".into(),
                ));
            }
            times.push(times.last().unwrap() + t.duration);
        }
        // The body along a C² spline through the configurations, at rest at both ends.
        let body: Vec<Spline> = (0..4)
            .map(|k| {
                let pts: Vec<f64> = configs.iter().map(|c| c.body[k]).collect();
                if times.len() >= 3 {
                    Spline::at_rest(&times, &pts)
                } else {
                    // One transition: a spline needs three knots; halfway is the middle.
                    let mid = [times[0], times[1] / 2.0, times[1]];
                    Spline::at_rest(&mid, &[pts[0], (pts[0] + pts[1]) / 2.0, pts[1]])
                }
            })
            .collect::<Result<_, _>>()?;
        let swing_cfg = SwingConfig {
            clearance: self.cfg.swing_height,
            ..SwingConfig::default()
        };
        let mut swings: Vec<Vec<(u8, SwingPath)>> = Vec::with_capacity(trans.len());
        for (i, t) in trans.iter().enumerate() {
            let mut v = Vec::new();
            for &leg in &t.swing {
                let k = leg as usize - 1;
                let (a, b) = (configs[i].feet[k], configs[i + 1].feet[k]);
                let over = terrain.map_or(a[2].max(b[2]), |f| f(a, b));
                let path = SwingPath::new(
                    [a[0], a[1], a[2], 0.0],
                    [b[0], b[1], b[2], 0.0],
                    over,
                    t.duration,
                    &swing_cfg,
                )?;
                v.push((leg, path));
            }
            swings.push(v);
        }
        let end = *times.last().unwrap();
        let ticks = (end / dt).ceil() as usize;
        let mut rows: Vec<HexRow> = Vec::with_capacity(ticks + 1);
        for k in 0..=ticks {
            let t = (k as f64 * dt).min(end);
            let i = times.partition_point(|&x| x <= t).clamp(1, trans.len()) - 1;
            let b: BodyPose = std::array::from_fn(|a| body[a].eval(t)[0]);
            let mut feet = configs[i].feet;
            let mut down = [true; 6];
            for (leg, path) in &swings[i] {
                let p = path.at(t - times[i])[0];
                feet[*leg as usize - 1] = [p[0], p[1], p[2]];
                down[*leg as usize - 1] = t <= times[i] || t >= times[i + 1];
            }
            let row = self.row(t, &b, &feet, &down, rows.last())?;
            rows.push(row);
        }
        Ok(rows)
    }

    /// One row: the feet solved under the body, checked.
    fn row(
        &self,
        t: f64,
        body: &BodyPose,
        feet: &[[f64; 3]; 6],
        down: &[bool; 6],
        prev: Option<&HexRow>,
    ) -> Result<HexRow, GaitError> {
        let at = |e: String| GaitError::Plan(format!("at {t:.3} s: {e}"));
        let mut servo_deg = [[0.0; 3]; 6];
        let mut raw = [[0; 3]; 6];
        for n in 1..=6u8 {
            let s = self
                .robot
                .solve(n, to_body(body, feet[n as usize - 1]))
                .map_err(|e| at(format!("leg {n}: {e}")))?;
            servo_deg[n as usize - 1] = s.servo_deg;
            raw[n as usize - 1] = s.raw;
        }
        let mut speed = [[0.0; 3]; 6];
        let mut moving_speed = [[1; 3]; 6];
        if let Some(p) = prev {
            let dt = t - p.t;
            if dt > 0.0 {
                for l in 0..6 {
                    for j in 0..3 {
                        let v = (servo_deg[l][j] - p.servo_deg[l][j]).to_radians().abs() / dt;
                        if v > self.cfg.max_speed {
                            return Err(at(format!(
                                "leg {} servo {j}: {v:.2} rad/s beyond the servos' {:.2}",
                                l + 1,
                                self.cfg.max_speed
                            )));
                        }
                        speed[l][j] = v;
                        moving_speed[l][j] = ((v / SPEED_UNIT).ceil() as u16).clamp(1, 1023);
                    }
                }
            }
        }
        let com = to_world(body, self.cfg.com);
        let ground: Vec<P2> = (0..6)
            .filter(|&k| down[k])
            .map(|k| [feet[k][0], feet[k][1]])
            .collect();
        let m = margin(&hull(&ground), [com[0], com[1]]);
        if m.is_nan() || m < self.cfg.min_margin {
            return Err(at(format!(
                "the centre of mass is {m:.4} m inside the feet's polygon (at least {} m wanted)",
                self.cfg.min_margin
            )));
        }
        Ok(HexRow {
            t,
            servo_deg,
            raw,
            speed,
            moving_speed,
            margin: m,
        })
    }
}
