//! Archie's body, moved kinematically from its joints' true positions.
//!
//! One foot, the anchor, stays where it stands on the ground. The pelvis is where the anchor
//! leg's forward kinematics put it, the other foot where its own leg puts it from there. When
//! the joints would push the other foot into the ground (by more than [`BodyConfig::takeover`]),
//! that foot has touched down and carries the weight: it becomes the anchor, set down level on
//! the surface under it. No dynamics: the body goes where the joints take it, so what the
//! body reports is what the joints did, and a fall is told by the whole body's ZMP (the point
//! masses of the robot file, each one's acceleration fitted) leaving the support polygon.

use std::collections::VecDeque;

use serde::Deserialize;
use stride_gait::support::{self, Pose2, Sole, P2};
use stride_kinematics::archie::{self, ArchieConfig, Leg, JOINTS, Q};
use stride_kinematics::math::{yawed, Frame, Matrix3, Pose, UnitQuaternion, Vector3};

use crate::world::World;
use crate::V3;

/// How the body meets the ground and what counts as wrong.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BodyConfig {
    /// A sole this close above the ground touches it, m.
    pub contact: f64,
    /// A sole that touches the ground leaves it only once this far above it, m: setting the
    /// other foot down with its tilt (the joints' tracking error) lifts it a few millimetres
    /// that its joints did not.
    pub release: f64,
    /// A sole the joints push this far into the ground takes over as the anchor, m.
    pub takeover: f64,
    /// Gravity, m/s².
    pub g: f64,
    /// The COM's velocity and acceleration (and the pelvis's, for the IMU) are fitted over
    /// this window, s; they, and the ZMP, are those of its middle.
    pub window: f64,
    /// The ZMP this far outside the support polygon is a fall, m ...
    pub fall_margin: f64,
    /// ... once it has stayed out this long, s (0: at once). The support polygon comes from
    /// the soles' heights, and a sole a few millimetres either side of the contact height
    /// for a sample or two makes the ZMP jump out of it and back, where no robot topples.
    pub fall_time: f64,
    /// A joint this close to its position limit is at it, rad.
    pub limit_margin: f64,
    /// Points checked along each shank (knee to ankle) for collisions.
    pub shank_points: usize,
}

impl Default for BodyConfig {
    fn default() -> BodyConfig {
        BodyConfig {
            contact: 0.002,
            release: 0.006,
            takeover: 0.001,
            g: 9.80665,
            window: 0.1,
            fall_margin: 0.0,
            fall_time: 0.0,
            limit_margin: 0.001,
            shank_points: 5,
        }
    }
}

impl BodyConfig {
    /// Checks the numbers.
    pub fn check(&self) -> Result<(), String> {
        let ok = [self.contact, self.takeover, self.window, self.limit_margin]
            .iter()
            .all(|v| v.is_finite() && *v >= 0.0)
            && self.release.is_finite()
            && self.release >= self.contact
            && self.g.is_finite()
            && self.g > 0.0
            && self.window > 0.0
            && self.fall_margin.is_finite()
            && self.fall_time.is_finite()
            && self.fall_time >= 0.0
            // The body's history and the shank's checks are sized by these.
            && self.window <= 2.0
            && (2..=100).contains(&self.shank_points);
        if ok {
            Ok(())
        } else {
            Err(format!(
                "the body's contact, takeover, window and limit margin must be finite and not \
                 negative (window positive, at most 2 s), the release at least the contact, \
                 gravity positive, 2 to 100 shank points: {self:?}"
            ))
        }
    }
}

/// Something the body did that a run should know of. Each is reported when it begins.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A foot touched down and took the weight.
    Touchdown {
        /// The foot.
        leg: Leg,
        /// Its sole's centre, m.
        at: V3,
    },
    /// A foot or shank went into an obstacle.
    Collision {
        /// "left_foot", "right_shank", ...
        part: String,
        /// The obstacle's index in the scene.
        obstacle: usize,
        /// Where, m.
        at: V3,
    },
    /// The ZMP left the support polygon.
    Fall {
        /// Where the ZMP was, m.
        zmp: P2,
        /// Its margin in the polygon (negative: outside), m.
        margin: f64,
    },
    /// A joint reached its position limit.
    Limit {
        /// The joint, e.g. "left_knee".
        joint: String,
        /// Its angle, rad.
        value: f64,
    },
}

/// What the body's counters hold.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    /// Touch-downs.
    pub touchdowns: u64,
    /// Collisions begun.
    pub collisions: u64,
    /// Falls begun (the ZMP left the polygon).
    pub falls: u64,
    /// Joints that reached a limit.
    pub limits: u64,
}

/// The body at one instant.
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    /// Time, s.
    pub t: f64,
    /// The pelvis centre's pose in the world.
    pub pelvis: Pose,
    /// Each sole's centre (left, right), m, and heading, rad.
    pub feet: [[f64; 4]; 2],
    /// Each foot on the ground.
    pub contact: [bool; 2],
    /// The foot that carries the weight.
    pub anchor: Leg,
    /// The whole robot's centre of mass, m.
    pub com: V3,
    /// The smallest horizontal distance of a foot or shank from an obstacle now, m.
    pub clearance: f64,
    /// Fitted at the window's middle (`t - window / 2`): the pelvis's velocity and
    /// acceleration, m/s and m/s², its angular velocity, rad/s (world frame), the COM's
    /// whole body's ZMP (its point masses') and its margin in the support polygon of then, m.
    pub fitted: Option<Fitted>,
}

/// Figures fitted over the body's window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fitted {
    /// The window's middle, s.
    pub t: f64,
    /// The pelvis's velocity, m/s.
    pub velocity: V3,
    /// The pelvis's acceleration, m/s².
    pub acceleration: V3,
    /// The pelvis's angular velocity, rad/s.
    pub angular_velocity: V3,
    /// The ZMP, m.
    pub zmp: P2,
    /// Its margin in the support polygon (negative: outside), m.
    pub margin: f64,
}

struct Sample {
    t: f64,
    /// The point masses (kg, world position).
    masses: [(f64, V3); 7],
    pelvis: Pose,
    ground: f64,
    polygon: Vec<P2>,
}

/// Archie's body in a world.
pub struct Body {
    robot: ArchieConfig,
    cfg: BodyConfig,
    anchor: Leg,
    /// The anchor's sole frame in the world.
    anchor_pose: Pose,
    /// Where the body was set down (x, y, heading).
    start: [f64; 3],
    /// A foot has lifted since: the body stands on its own.
    lifted: bool,
    history: VecDeque<Sample>,
    colliding: Vec<(String, usize)>,
    at_limit: Vec<String>,
    falling: bool,
    /// Since when the ZMP has been beyond the fall margin, s.
    out_since: Option<f64>,
    counts: Counts,
    /// The last state.
    pub state: State,
}

fn idx(leg: Leg) -> usize {
    match leg {
        Leg::Left => 0,
        Leg::Right => 1,
    }
}

fn other(leg: Leg) -> Leg {
    match leg {
        Leg::Left => Leg::Right,
        Leg::Right => Leg::Left,
    }
}

/// The heading of a frame.
pub fn yaw_of(p: &Pose) -> f64 {
    p.yaw()
}

/// The unit quaternion (w, x, y, z) of a pose's rotation.
pub fn quaternion(p: &Pose) -> [f64; 4] {
    let q = UnitQuaternion::from_rotation_matrix(&p.rotation);
    [q.w, q.i, q.j, q.k]
}

/// The centre of point masses.
fn centre(masses: &[(f64, V3)]) -> V3 {
    let total: f64 = masses.iter().map(|m| m.0).sum();
    [0, 1, 2].map(|k| masses.iter().map(|(m, p)| m * p[k]).sum::<f64>() / total)
}

/// Least-squares quadratic through `(t, v)` about `tm`: value, slope and second derivative.
fn quadratic(ts: &[f64], vs: &[f64], tm: f64) -> [f64; 3] {
    // Normal equations of v = a + b·s + c·s², s = t - tm.
    let mut m = Matrix3::<f64>::zeros();
    let mut y = Vector3::<f64>::zeros();
    for (&t, &v) in ts.iter().zip(vs) {
        let s = t - tm;
        let p = Vector3::new(1.0, s, s * s);
        m += p * p.transpose();
        y += p * v;
    }
    let out = m.lu().solve(&y).unwrap_or(Vector3::repeat(f64::NAN));
    [out[0], out[1], 2.0 * out[2]]
}

impl Body {
    /// The body standing at `start` (x, y, heading: the point between its feet) with its
    /// joints at `q` (left, right): the lower sole on the ground under it. Until a foot first
    /// lifts, the body stays centred there (the robot being set down from its frame while its
    /// joints move into their pose: the feet slide into place).
    pub fn new(
        robot: ArchieConfig,
        cfg: BodyConfig,
        start: [f64; 3],
        q: [Q; 2],
        world: &World,
    ) -> Body {
        let mut body = Body {
            cfg,
            anchor: Leg::Left,
            anchor_pose: Pose::identity(),
            start,
            lifted: false,
            history: VecDeque::new(),
            colliding: Vec::new(),
            at_limit: Vec::new(),
            falling: false,
            out_since: None,
            counts: Counts::default(),
            state: State {
                t: f64::NAN,
                pelvis: Pose::identity(),
                feet: [[0.0; 4]; 2],
                contact: [true; 2],
                anchor: Leg::Left,
                com: [0.0; 3],
                clearance: f64::INFINITY,
                fitted: None,
            },
            robot,
        };
        body.place(&q, world);
        let _ = body.step(f64::NAN, &q, world);
        body.history.clear();
        body
    }

    /// Sets the body down centred on its start: the lower sole on the ground.
    fn place(&mut self, q: &[Q; 2], world: &World) {
        let [x, y, yaw] = self.start;
        let pelvis0 = yawed([0.0; 3], yaw);
        let soles = [Leg::Left, Leg::Right]
            .map(|leg| pelvis0 * archie::fk(&self.robot.links, leg, &q[idx(leg)]));
        let centres = soles.map(|s| self.centre(&s));
        let anchor = if centres[1][2] < centres[0][2] {
            Leg::Right
        } else {
            Leg::Left
        };
        let mid = [
            (centres[0][0] + centres[1][0]) / 2.0,
            (centres[0][1] + centres[1][1]) / 2.0,
        ];
        let a = centres[idx(anchor)];
        let ground = world.ground(a[0] - mid[0] + x, a[1] - mid[1] + y);
        let shift = [x - mid[0], y - mid[1], ground - a[2]];
        let s = soles[idx(anchor)];
        self.anchor = anchor;
        let p = s.position();
        self.anchor_pose = yawed(
            [p[0] + shift[0], p[1] + shift[1], p[2] + shift[2]],
            yaw_of(&s),
        );
    }

    /// The counters so far.
    pub fn counts(&self) -> Counts {
        self.counts
    }

    /// The sole frames (left, right) in the world for the pelvis at `pelvis`.
    fn soles(&self, pelvis: &Pose, q: &[Q; 2]) -> [Pose; 2] {
        [Leg::Left, Leg::Right].map(|leg| pelvis * archie::fk(&self.robot.links, leg, &q[idx(leg)]))
    }

    fn centre(&self, sole: &Pose) -> V3 {
        sole.apply(&[self.robot.foot.centre_ahead, 0.0, 0.0])
    }

    /// The sole `sole` turned flat (its heading kept) and set on the highest ground under its
    /// corners.
    fn flat(&self, sole: &Pose, world: &World) -> Pose {
        let p = sole.position();
        let level = yawed([p[0], p[1], 0.0], yaw_of(sole));
        let ground = self
            .corners()
            .iter()
            .map(|c| {
                let q = level.apply(c);
                world.ground(q[0], q[1])
            })
            .fold(f64::NEG_INFINITY, f64::max);
        yawed([p[0], p[1], ground], yaw_of(sole))
    }

    /// The sole's four corners in its frame, on its face.
    fn corners(&self) -> [V3; 4] {
        let (l, w) = (self.robot.foot.length / 2.0, self.robot.foot.width / 2.0);
        let b = self.robot.foot.centre_ahead;
        [[l, w], [-l, w], [-l, -w], [l, -w]].map(|c| [b + c[0], c[1], 0.0])
    }

    /// The height of a sole above the ground: its lowest corner's.
    fn clearance(&self, sole: &Pose, world: &World) -> f64 {
        self.corners()
            .iter()
            .map(|c| {
                let p = sole.apply(c);
                p[2] - world.ground(p[0], p[1])
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Moves the body to the joints `q` (left, right; [`JOINTS`] order) at time `t`, s;
    /// returns what began.
    pub fn step(&mut self, t: f64, q: &[Q; 2], world: &World) -> Vec<Event> {
        let mut events = Vec::new();
        if !self.lifted {
            self.place(q, world);
        }
        let mut pelvis = self.anchor_pose
            * archie::fk(&self.robot.links, self.anchor, &q[idx(self.anchor)]).inverse();
        let mut soles = self.soles(&pelvis, q);
        let o = other(self.anchor);
        let h = self.clearance(&soles[idx(o)], world);
        if h < -self.cfg.takeover {
            // The other foot is down and carries the robot: it stands where it came down,
            // flat on the ground under it. A sole that lands tilted by the joints' tracking
            // error is turned flat by the ground, and the body with it; keeping its tilt
            // instead added every landing's tilt to the body's (2 degrees after a hundred
            // steps), until a landing foot stayed millimetres above the ground while the
            // gait had already put the weight on it.
            self.anchor = o;
            self.anchor_pose = self.flat(&soles[idx(o)], world);
            let before = pelvis;
            pelvis = self.anchor_pose * archie::fk(&self.robot.links, o, &q[idx(o)]).inverse();
            // Setting the foot down moved the whole body by a rigid step (a millimetre, a
            // tilt of the sole): the window's past moves with it, so the fitted motion (and
            // the ZMP) sees no jump that the joints did not make.
            let step = pelvis * before.inverse();
            for h in &mut self.history {
                for (_, p) in &mut h.masses {
                    *p = step.apply(p);
                }
                h.pelvis = step * h.pelvis;
            }
            soles = self.soles(&pelvis, q);
            if !t.is_nan() {
                self.counts.touchdowns += 1;
                events.push(Event::Touchdown {
                    leg: o,
                    at: self.centre(&soles[idx(o)]),
                });
            }
        }
        let was = self.state.contact;
        let contact = [0, 1].map(|k| {
            let within = if was[k] {
                self.cfg.release
            } else {
                self.cfg.contact
            };
            k == idx(self.anchor) || self.clearance(&soles[k], world) <= within
        });
        if !contact[0] || !contact[1] {
            self.lifted = true;
        }
        let feet = [0, 1].map(|k| {
            let c = self.centre(&soles[k]);
            [c[0], c[1], c[2], yaw_of(&soles[k])]
        });
        let masses = self.masses(&pelvis, q);
        let com = centre(&masses);
        let mut clearance = f64::INFINITY;
        if !t.is_nan() {
            clearance = self.collisions(&pelvis, q, world, &mut events);
            self.limits(q, &mut events);
        }
        let sole = Sole {
            length: self.robot.foot.length,
            width: self.robot.foot.width,
        };
        let on: Vec<Pose2> = (0..2)
            .filter(|&k| contact[k])
            .map(|k| Pose2 {
                p: [feet[k][0], feet[k][1]],
                yaw: feet[k][3],
            })
            .collect();
        let anchor_ground = feet[idx(self.anchor)][2];
        self.history.push_back(Sample {
            t,
            masses,
            pelvis,
            ground: anchor_ground,
            polygon: support::polygon(&sole, &on),
        });
        while self
            .history
            .front()
            .is_some_and(|s| s.t < t - self.cfg.window)
        {
            self.history.pop_front();
        }
        let fitted = self.fit();
        if let Some(f) = &fitted {
            let out = f.margin < -self.cfg.fall_margin;
            // A fall: out for fall_time on end (the fitted ZMP of the middle of the window).
            let since = *self.out_since.get_or_insert(f.t);
            if !out {
                self.out_since = None;
                self.falling = false;
            } else if !self.falling && f.t - since >= self.cfg.fall_time {
                self.falling = true;
                self.counts.falls += 1;
                events.push(Event::Fall {
                    zmp: f.zmp,
                    margin: f.margin,
                });
            }
        }
        self.state = State {
            t,
            pelvis,
            feet,
            contact,
            anchor: self.anchor,
            com,
            clearance,
            fitted,
        };
        events
    }

    /// The robot's point masses: the pelvis's at its centre, each thigh's and shank's at its
    /// middle, each foot's at the ankle roll axis. Computed here from the robot file, not by
    /// the gait's code: the simulated world grades the gait's patterns.
    fn masses(&self, pelvis: &Pose, q: &[Q; 2]) -> [(f64, V3); 7] {
        let m = &self.robot.mass;
        let mut out = [(m.pelvis, pelvis.position()); 7];
        for leg in [Leg::Left, Leg::Right] {
            let (_, p) = archie::fk_points(&self.robot.links, leg, &q[idx(leg)]);
            let mid = |a: &V3, b: &V3| [0, 1, 2].map(|k| (a[k] + b[k]) / 2.0);
            for (j, (mass, point)) in [
                (m.thigh, mid(&p[0], &p[1])),
                (m.shank, mid(&p[1], &p[2])),
                (m.foot, p[3]),
            ]
            .into_iter()
            .enumerate()
            {
                out[1 + 3 * idx(leg) + j] = (mass, pelvis.apply(&point));
            }
        }
        out
    }

    /// Reports the feet and shanks that went into an obstacle; returns their smallest
    /// clearance.
    fn collisions(
        &mut self,
        pelvis: &Pose,
        q: &[Q; 2],
        world: &World,
        events: &mut Vec<Event>,
    ) -> f64 {
        let mut now = Vec::new();
        let mut clearance = f64::INFINITY;
        let (l, w) = (self.robot.foot.length / 2.0, self.robot.foot.width / 2.0);
        let b = self.robot.foot.centre_ahead;
        for leg in [Leg::Left, Leg::Right] {
            let (sole, p) = archie::fk_points(&self.robot.links, leg, &q[idx(leg)]);
            let n = self.cfg.shank_points;
            let shank = (0..n).map(|i| {
                let s = i as f64 / (n - 1) as f64;
                pelvis.apply(&[0, 1, 2].map(|k| p[1][k] + s * (p[2][k] - p[1][k])))
            });
            // The sole's corners and centre, just above its face.
            let foot = [[0.0, 0.0], [l, w], [-l, w], [-l, -w], [l, -w]]
                .map(|c| (pelvis * sole).apply(&[b + c[0], c[1], 0.005]));
            for (part, points) in [
                ("shank", shank.collect::<Vec<_>>()),
                ("foot", foot.to_vec()),
            ] {
                let name = format!("{}_{part}", leg.name());
                for p in &points {
                    clearance = clearance.min(world.clearance(*p));
                }
                if let Some((ob, at)) = points
                    .iter()
                    .find_map(|p| world.obstacle_at(*p).map(|o| (o, *p)))
                {
                    if !self.colliding.iter().any(|(n, o)| *n == name && *o == ob) {
                        self.counts.collisions += 1;
                        events.push(Event::Collision {
                            part: name.clone(),
                            obstacle: ob,
                            at,
                        });
                    }
                    now.push((name, ob));
                }
            }
        }
        self.colliding = now;
        clearance
    }

    fn limits(&mut self, q: &[Q; 2], events: &mut Vec<Event>) {
        let mut now = Vec::new();
        for leg in [Leg::Left, Leg::Right] {
            for (k, spec) in self.robot.joint.iter().enumerate() {
                let v = q[idx(leg)][k];
                let m = self.cfg.limit_margin;
                if v <= spec.min + m || v >= spec.max - m {
                    let joint = format!("{}_{}", leg.name(), JOINTS[k]);
                    if !self.at_limit.contains(&joint) {
                        self.counts.limits += 1;
                        events.push(Event::Limit {
                            joint: joint.clone(),
                            value: v,
                        });
                    }
                    now.push(joint);
                }
            }
        }
        self.at_limit = now;
    }

    /// The window's fit, once it spans most of the window.
    fn fit(&self) -> Option<Fitted> {
        let (first, last) = (self.history.front()?, self.history.back()?);
        if self.history.len() < 5 || last.t - first.t < 0.8 * self.cfg.window {
            return None;
        }
        let tm = (first.t + last.t) / 2.0;
        let ts: Vec<f64> = self.history.iter().map(|s| s.t).collect();
        let fit = |f: &dyn Fn(&Sample) -> f64| {
            let vs: Vec<f64> = self.history.iter().map(f).collect();
            quadratic(&ts, &vs, tm)
        };
        let pel = [0, 1, 2].map(|k| fit(&|s: &Sample| s.pelvis.translation.vector[k]));
        let mid = self
            .history
            .iter()
            .min_by(|a, b| (a.t - tm).abs().total_cmp(&(b.t - tm).abs()))?;
        // The whole body's ZMP on the ground: each point mass's position and acceleration
        // fitted, p = Σ m (x (z̈ + g) − (z − ground) ẍ) / Σ m (z̈ + g).
        let (mut num, mut den) = ([0.0; 2], 0.0);
        for j in 0..mid.masses.len() {
            let mass = mid.masses[j].0;
            let f = [0, 1, 2].map(|k| fit(&|s: &Sample| s.masses[j].1[k]));
            let w = mass * (f[2][2] + self.cfg.g);
            for k in 0..2 {
                num[k] += f[k][0] * w - mass * (f[2][0] - mid.ground) * f[k][2];
            }
            den += w;
        }
        let zmp = num.map(|v| v / den);
        // Angular velocity from the rotation across the window: R_last · R_firstᵀ.
        let dr = (last.pelvis.rotation * first.pelvis.rotation.inverse()).into_inner();
        let dt = last.t - first.t;
        let w = [
            (dr[(2, 1)] - dr[(1, 2)]) / 2.0 / dt,
            (dr[(0, 2)] - dr[(2, 0)]) / 2.0 / dt,
            (dr[(1, 0)] - dr[(0, 1)]) / 2.0 / dt,
        ];
        Some(Fitted {
            t: tm,
            velocity: pel.map(|f| f[1]),
            acceleration: pel.map(|f| f[2]),
            angular_velocity: w,
            zmp,
            margin: support::margin(&mid.polygon, zmp),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use stride_kinematics::math::{pose, rx, ry};
    use stride_world::scene::Scene;

    fn robot() -> ArchieConfig {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/robots/archie.toml"
        );
        ArchieConfig::load(std::path::Path::new(path)).unwrap()
    }

    fn world(obstacles: &str) -> World {
        let text = format!(
            "name = \"t\"\nstart = {{ x = 0.0, y = 0.0 }}\ngoal = {{ x = 2.0, y = 0.0 }}\n\
             [map]\nx = [-1.0, 3.0]\ny = [-1.0, 1.0]\n{obstacles}"
        );
        World::new(Scene::parse(&text, std::path::Path::new(".")).unwrap()).unwrap()
    }

    /// Joints that put each sole at `feet` (sole centres, level) under a pelvis at `pelvis`.
    fn joints(r: &ArchieConfig, pelvis: [f64; 3], feet: [[f64; 3]; 2]) -> [Q; 2] {
        let p = yawed(pelvis, 0.0);
        [Leg::Left, Leg::Right].map(|leg| {
            let sole = p.inverse() * r.sole_frame(feet[idx(leg)], 0.0);
            archie::ik(&r.links, leg, &sole).unwrap()
        })
    }

    #[test]
    fn a_step_moves_the_body_on_the_stance_foot_and_lands_the_swing_foot() {
        // The pelvis shifts over the right foot, the left foot lifts, swings 0.2 m ahead and
        // lands: the right foot never moves, the left lands where its joints put it, the
        // pelvis is where the legs hold it, and the touch-down is reported.
        let r = robot();
        let w = world("");
        let z = 0.6;
        let q0 = joints(&r, [0.0, 0.0, z], [[0.0, 0.1, 0.0], [0.0, -0.1, 0.0]]);
        let mut body = Body::new(r.clone(), BodyConfig::default(), [0.0, 0.0, 0.0], q0, &w);
        let start = body.state.feet[1];
        assert!(
            (start[1] + 0.1).abs() < 1e-9 && start[2].abs() < 1e-9,
            "{start:?}"
        );
        let mut events = Vec::new();
        let n = 200;
        // Set down centred on the start; from the first lift on, the right foot stays and the
        // rest goes where the joints put it from there.
        let mut right0 = None;
        let mut was = true;
        for i in 0..=n {
            let s = i as f64 / n as f64;
            let lift = 0.05 * (std::f64::consts::PI * s).sin();
            let left = [0.2 * s, 0.1, lift];
            let pelvis = [0.1 * s, -0.05 * (std::f64::consts::PI * s).sin(), z];
            let q = joints(&r, pelvis, [left, [0.0, -0.1, 0.0]]);
            events.extend(body.step(i as f64 * 0.01, &q, &w));
            let right = body.state.feet[1];
            // Touching within `contact` (2 mm) of the ground; on it, until `release` (6 mm).
            let within = if was { 0.006 } else { 0.002 };
            assert_eq!(
                body.state.contact[0],
                lift <= within,
                "the left foot at {s}"
            );
            was = body.state.contact[0];
            if right0.is_none() && body.state.contact[0] {
                continue;
            }
            let r0 = *right0.get_or_insert(right);
            assert!((0..3).all(|k| (right[k] - r0[k]).abs() < 1e-9));
            // (Set down centred under the moving pelvis: about 4 mm off by the time the left
            // foot leaves the ground, 6 mm up.)
            assert!((r0[0]).abs() < 5e-3 && (r0[1] + 0.1).abs() < 1e-9 && r0[2].abs() < 1e-9);
            let off = [r0[0], r0[1] + 0.1, r0[2]];
            let p = body.state.pelvis.position();
            assert!(
                (0..3).all(|k| (p[k] - pelvis[k] - off[k]).abs() < 1e-9),
                "{p:?}"
            );
        }
        // Weight onto the left foot: the right lifts a little, the left takes over.
        let q = joints(&r, [0.1, 0.0, z], [[0.2, 0.1, 0.0], [0.0, -0.1, 0.01]]);
        events.extend(body.step(2.02, &q, &w));
        assert_eq!(body.state.anchor, Leg::Left);
        assert!(events
            .iter()
            .any(|e| matches!(e, Event::Touchdown { leg: Leg::Left, .. })));
        assert_eq!(body.counts().collisions + body.counts().limits, 0);
    }

    #[test]
    fn a_foot_on_the_ground_leaves_it_only_past_the_release_height() {
        // The finding: walking case 7, a foot set down with its small tilt lifted the other
        // 3 mm, past the 2 mm contact height: the sim saw a single support 0.1 s early, the
        // ZMP 0.18 m outside it, and reported a fall at every other step.
        let r = robot();
        let w = world("");
        let z = 0.6;
        let q = |h: f64| joints(&r, [0.0, -0.05, z], [[0.0, 0.1, h], [0.0, -0.1, 0.0]]);
        let mut body = Body::new(
            r.clone(),
            BodyConfig::default(),
            [0.0, 0.0, 0.0],
            q(0.0),
            &w,
        );
        let mut contact = Vec::new();
        for (i, h) in [0.0, 0.004, 0.008, 0.004, 0.001].into_iter().enumerate() {
            body.step(i as f64 * 0.01, &q(h), &w);
            contact.push(body.state.contact[0]);
        }
        assert_eq!(contact, [true, true, false, false, true]);
    }

    #[test]
    fn a_body_walking_in_place_does_not_add_up_the_tilts_its_feet_land_with() {
        // The finding: the demo's 100 s walk ended with the pelvis tilted 31 mrad in roll and
        // 23 in pitch, a little more at every landing, until a landing foot stayed above the
        // 2 mm contact height while the gait had put the weight on it: 14 falls. Here each
        // foot lands tilted 4 mrad in roll and 3 in pitch (its joints lag), then its joints
        // catch up; after 60 steps the body leans no more than after one.
        let r = robot();
        let w = world("");
        let z = 0.6;
        let feet = |leg: Leg| if leg == Leg::Left { 0.1 } else { -0.1 };
        let q = |swing: Leg, h: f64, tilt: f64| -> [Q; 2] {
            let p = yawed([0.0, 0.0, z], 0.0);
            [Leg::Left, Leg::Right].map(|leg| {
                let mut sole = r.sole_frame([0.0, feet(leg), 0.0], 0.0);
                if leg == swing {
                    sole *= pose(rx(4e-3 * tilt) * ry(-3e-3 * tilt), [0.0, 0.0, h]);
                }
                archie::ik(&r.links, leg, &(p.inverse() * sole)).unwrap()
            })
        };
        let mut body = Body::new(
            r.clone(),
            BodyConfig::default(),
            [0.0, 0.0, 0.0],
            q(Leg::Left, 0.0, 0.0),
            &w,
        );
        let lean = |b: &Body| b.state.pelvis.rotation[(2, 2)].clamp(-1.0, 1.0).acos();
        let mut t = 0.0;
        let mut leans = Vec::new();
        for step in 0..60 {
            let swing = if step % 2 == 0 { Leg::Right } else { Leg::Left };
            // Up 2 cm and down, tilting on the way, 2 mm into the ground at the end.
            for i in 0..=20 {
                let s = i as f64 / 20.0;
                let h = 0.02 * (std::f64::consts::PI * s).sin() - 0.002 * s;
                body.step(t, &q(swing, h, s), &w);
                t += 0.01;
            }
            assert_eq!(
                body.state.anchor, swing,
                "step {step}: the landed foot carries"
            );
            // The joints catch up: both soles level under the pelvis again.
            for _ in 0..10 {
                body.step(t, &q(swing, 0.0, 0.0), &w);
                t += 0.01;
            }
            leans.push(lean(&body));
        }
        assert_eq!(body.counts().touchdowns, 60);
        let worst = leans.iter().fold(0.0f64, |a, &b| a.max(b));
        assert!(worst < 1e-3, "the body leans {worst} rad: {leans:?}");
        let sole = body.state.feet[idx(body.state.anchor)];
        assert!(sole[2].abs() < 1e-9, "the carrying sole at {sole:?}");
    }

    #[test]
    fn a_fall_is_the_zmp_out_for_the_fall_time_not_a_flicker_of_the_support() {
        // The pelvis between the feet: inside the double support, 5 cm beside the right sole.
        // The left sole rises 1 cm for `up` samples and comes down again: the support is the
        // right sole alone meanwhile, and the ZMP beside it.
        let r = robot();
        let w = world("");
        let z = 0.6;
        let falls = |fall_time: f64, up: usize| {
            let cfg = BodyConfig {
                fall_time,
                ..BodyConfig::default()
            };
            let q = |h: f64| joints(&r, [0.0, 0.0, z], [[0.0, 0.1, h], [0.0, -0.1, 0.0]]);
            let mut body = Body::new(r.clone(), cfg, [0.0, 0.0, 0.0], q(0.0), &w);
            let mut t = 0.0;
            for k in 0..(30 + up + 30) {
                let h = if (30..30 + up).contains(&k) {
                    0.01
                } else {
                    0.0
                };
                body.step(t, &q(h), &w);
                t += 0.01;
            }
            body.counts().falls
        };
        assert_eq!(falls(0.0, 3), 1, "at once, the flicker is a fall");
        assert_eq!(falls(0.1, 3), 0, "30 ms on one foot");
        assert_eq!(falls(0.1, 40), 1, "0.4 s on one foot");
    }

    #[test]
    fn a_foot_in_an_obstacle_a_joint_at_its_limit_and_a_zmp_off_the_sole_are_reported() {
        let r = robot();
        let w = world(
            "[[obstacle]]\nshape = \"box\"\nx = 0.35\ny = 0.1\nlength = 0.1\nwidth = 0.3\nheight = 0.1\n",
        );
        let z = 0.6;
        let q0 = joints(&r, [0.0, 0.0, z], [[0.0, 0.1, 0.0], [0.0, -0.1, 0.0]]);
        let mut body = Body::new(r.clone(), BodyConfig::default(), [0.0, 0.0, 0.0], q0, &w);
        let mut events = Vec::new();
        // The left foot slides 0.3 m ahead at 5 cm: into the box.
        for i in 0..=100 {
            let s = i as f64 / 100.0;
            let q = joints(&r, [0.0, -0.1, z], [[0.3 * s, 0.1, 0.05], [0.0, -0.1, 0.0]]);
            events.extend(body.step(i as f64 * 0.01, &q, &w));
        }
        assert!(
            events.iter().any(
                |e| matches!(e, Event::Collision { part, obstacle: 0, .. } if part == "left_foot")
            ),
            "{events:?}"
        );
        assert_eq!(body.counts().collisions, 1, "reported once while it lasts");
        // The pelvis jerks sideways far past the right sole: the ZMP leaves it.
        let mut t = 1.01;
        for i in 0..30 {
            let y = -0.1 + 0.2 * ((i as f64) / 30.0).powi(2) * if i % 2 == 0 { 1.0 } else { -1.0 };
            let q = joints(&r, [0.0, y, z], [[0.0, 0.1, 0.05], [0.0, -0.1, 0.0]]);
            events.extend(body.step(t, &q, &w));
            t += 0.01;
        }
        assert!(body.counts().falls >= 1, "{events:?}");
        // A knee beyond its range.
        let mut q = q0;
        q[0][3] = r.joint[3].max;
        events.extend(body.step(t, &q, &w));
        assert!(events
            .iter()
            .any(|e| matches!(e, Event::Limit { joint, .. } if joint == "left_knee")));
    }

    #[test]
    fn the_fit_gives_a_still_bodys_zmp_under_its_com() {
        let r = robot();
        let w = world("");
        let q0 = joints(&r, [0.0, 0.0, 0.6], [[0.0, 0.1, 0.0], [0.0, -0.1, 0.0]]);
        let mut body = Body::new(r, BodyConfig::default(), [0.5, 0.2, 0.0], q0, &w);
        for i in 0..20 {
            body.step(i as f64 * 0.01, &q0, &w);
        }
        let f = body.state.fitted.expect("a full window");
        let c = body.state.com;
        assert!((f.zmp[0] - c[0]).abs() < 1e-9 && (f.zmp[1] - c[1]).abs() < 1e-9);
        assert!(f.margin > 0.0 && f.velocity.iter().all(|v| v.abs() < 1e-9));
        assert!(
            (c[0] - 0.5).abs() < 0.1 && (c[1] - 0.2).abs() < 1e-9,
            "{c:?}"
        );
        let q = quaternion(&body.state.pelvis);
        assert!((q[0] - 1.0).abs() < 1e-12);
    }
}
