//! The hexapod's body, moved kinematically from its 18 joints' true positions.
//!
//! No dynamics: the body goes where its legs take it. Each leg's foot is where the legs'
//! forward kinematics ([`Hexapod::foot`]) put it in the body frame (x forward, y left, z up,
//! origin at the body's centre; legs 1 lf, 2 rf, 3 rm, 4 rr, 5 lr, 6 lm). The body stays
//! level (no roll, no pitch: its pose is a position and a yaw) and rests on its lowest feet:
//! its height is the lowest that keeps every foot out of the ground (on flat ground, the
//! lowest foot on it). A foot on the ground is anchored where it touched down; the body's
//! x, y and yaw are the rigid motion that best holds the anchored feet on their anchors (a
//! least-squares fit, so feet that the joints slide against each other do not move the body
//! by more than their mean). Each state gives the body's pose, the feet and their contacts,
//! the static stability margin of the body's centre in the support polygon, and what went
//! wrong: a foot inside an obstacle, the body outside its support (a fall), a joint at its
//! limit.
//!
//! Joint values are radians, each the servo angle about its centre (Table 3.1's o + a)
//! `.to_radians()`, as the rest of the system carries them; legs in the order of their
//! numbers 1 to 6, joints coxa, femur, tibia.

use std::fmt;

use serde::Deserialize;
use stride_gait::support::{hull, margin, P2};
use stride_kinematics::hexapod::Hexapod;

use crate::world::World;
use crate::V3;

/// The joints' names, in the order of a leg's joints.
pub const HEX_JOINTS: [&str; 3] = ["coxa", "femur", "tibia"];

/// How the hexapod's body meets the ground and what counts as wrong.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HexBodyConfig {
    /// A foot this close above the ground touches it, m.
    pub contact: f64,
    /// A foot on the ground leaves it only once this far above it, m (at least `contact`:
    /// a foot that hovers at the contact height does not flicker on and off).
    pub release: f64,
    /// The body's centre this far outside the support polygon is a fall, m ...
    pub fall_margin: f64,
    /// ... once it has stayed out this long, s (0: at once).
    pub fall_time: f64,
    /// A joint this close to its position limit (Table 3.2) is at it, rad.
    pub limit_margin: f64,
}

impl Default for HexBodyConfig {
    fn default() -> HexBodyConfig {
        HexBodyConfig {
            contact: 0.003,
            release: 0.006,
            fall_margin: 0.0,
            fall_time: 0.1,
            limit_margin: 0.001,
        }
    }
}

impl HexBodyConfig {
    /// Checks the numbers.
    pub fn check(&self) -> Result<(), String> {
        let ok = [self.contact, self.limit_margin, self.fall_time]
            .iter()
            .all(|v| v.is_finite() && *v >= 0.0)
            && self.release.is_finite()
            && self.release >= self.contact
            && self.fall_margin.is_finite();
        if ok {
            Ok(())
        } else {
            Err(format!(
                "the hexapod body's contact, limit margin and fall time must be finite and not \
                 negative, the release at least the contact, the fall margin finite: {self:?}"
            ))
        }
    }
}

/// Something the hexapod's body did that a run should know of. Each is reported when it
/// begins.
#[derive(Debug, Clone, PartialEq)]
pub enum HexEvent {
    /// A foot touched down.
    Touchdown {
        /// The leg's number, 1 to 6.
        leg: u8,
        /// Where the foot came down, m.
        at: V3,
    },
    /// A foot went into an obstacle.
    Collision {
        /// The leg's number, 1 to 6.
        leg: u8,
        /// The obstacle's index in the scene.
        obstacle: usize,
        /// Where the foot was, m.
        at: V3,
    },
    /// The body's centre left the support polygon (by more than the fall margin, for the
    /// fall time).
    Fall {
        /// Where the body's centre was (x, y), m.
        at: P2,
        /// Its margin in the support polygon (negative: outside), m.
        margin: f64,
    },
    /// A joint reached its position limit.
    Limit {
        /// The leg's number, 1 to 6.
        leg: u8,
        /// The joint: "coxa", "femur" or "tibia".
        joint: &'static str,
        /// Its angle, rad.
        value: f64,
    },
}

impl fmt::Display for HexEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HexEvent::Touchdown { leg, at } => write!(
                f,
                "leg {leg} touched down at ({:.3}, {:.3}, {:.3}) m",
                at[0], at[1], at[2]
            ),
            HexEvent::Collision { leg, obstacle, at } => write!(
                f,
                "leg {leg}'s foot went into obstacle {obstacle} at ({:.3}, {:.3}, {:.3}) m",
                at[0], at[1], at[2]
            ),
            HexEvent::Fall { at, margin } => write!(
                f,
                "fall: the body's centre at ({:.3}, {:.3}) m is {:.3} m outside its support",
                at[0], at[1], -margin
            ),
            HexEvent::Limit { leg, joint, value } => write!(
                f,
                "leg {leg}'s {joint} at its limit: {value:.4} rad ({:.2}°)",
                value.to_degrees()
            ),
        }
    }
}

/// What the hexapod body's counters hold.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct HexCounts {
    /// Touch-downs.
    pub touchdowns: u64,
    /// Collisions begun (a foot entering an obstacle).
    pub collisions: u64,
    /// Falls begun.
    pub falls: u64,
    /// Joints that reached a limit.
    pub limits: u64,
}

/// The hexapod's body in a world.
#[derive(Debug, Clone)]
pub struct HexBody {
    robot: Hexapod,
    cfg: HexBodyConfig,
    /// The body's centre in the world, m.
    position: V3,
    /// The body's heading, rad (continuous: not wrapped to ±π).
    yaw: f64,
    /// Each foot in the world, m.
    feet: [V3; 6],
    /// Each foot's anchor (world x, y) while it is on the ground.
    anchors: [Option<P2>; 6],
    /// The obstacle each foot is in.
    colliding: [Option<usize>; 6],
    /// Each joint at its limit.
    at_limit: [[bool; 3]; 6],
    margin: f64,
    min_margin: f64,
    min_clearance: f64,
    /// Since when the body's centre has been beyond the fall margin, s.
    out_since: Option<f64>,
    falling: bool,
    counts: HexCounts,
    t: f64,
}

fn rotate(yaw: f64, p: P2) -> P2 {
    let (s, c) = yaw.sin_cos();
    [c * p[0] - s * p[1], s * p[0] + c * p[1]]
}

/// The rigid motion (x, y, yaw) that maps the body-frame points `b` onto the world points
/// `a` best (least squares); `yaw0` for points that fix no heading (all in one place).
fn fit(b: &[P2], a: &[P2], yaw0: f64) -> (P2, f64) {
    let n = b.len() as f64;
    let mean = |v: &[P2]| {
        let s = v.iter().fold([0.0, 0.0], |s, p| [s[0] + p[0], s[1] + p[1]]);
        [s[0] / n, s[1] / n]
    };
    let (cb, ca) = (mean(b), mean(a));
    let (mut cross, mut dot, mut spread) = (0.0, 0.0, 0.0);
    for (p, q) in b.iter().zip(a) {
        let u = [p[0] - cb[0], p[1] - cb[1]];
        let v = [q[0] - ca[0], q[1] - ca[1]];
        cross += u[0] * v[1] - u[1] * v[0];
        dot += u[0] * v[0] + u[1] * v[1];
        spread += u[0] * u[0] + u[1] * u[1];
    }
    let yaw = if spread > 1e-12 {
        let y = cross.atan2(dot);
        // The turn nearest the last heading: the yaw stays continuous.
        let tau = std::f64::consts::TAU;
        yaw0 + (y - yaw0 + std::f64::consts::PI).rem_euclid(tau) - std::f64::consts::PI
    } else {
        yaw0
    };
    let r = rotate(yaw, cb);
    ([ca[0] - r[0], ca[1] - r[1]], yaw)
}

impl HexBody {
    /// The body standing at `start` (x, y, yaw) with its joints at `q` (rad, legs 1 to 6):
    /// level, as low as its feet let it (on flat ground, the lowest foot on it); the feet
    /// within [`HexBodyConfig::contact`] of the ground are on it, anchored where they stand.
    /// An error for a configuration that does not check, or a start or joints not finite.
    pub fn new(
        robot: Hexapod,
        cfg: HexBodyConfig,
        start: [f64; 3],
        q: &[[f64; 3]; 6],
        world: &World,
    ) -> Result<HexBody, String> {
        cfg.check()?;
        if !start.iter().all(|v| v.is_finite()) {
            return Err(format!("the hexapod's start must be finite: {start:?}"));
        }
        let mut body = HexBody {
            robot,
            cfg,
            position: [start[0], start[1], 0.0],
            yaw: start[2],
            feet: [[0.0; 3]; 6],
            anchors: [None; 6],
            colliding: [None; 6],
            at_limit: [[false; 3]; 6],
            margin: f64::NEG_INFINITY,
            min_margin: f64::INFINITY,
            min_clearance: f64::INFINITY,
            out_since: None,
            falling: false,
            counts: HexCounts::default(),
            t: f64::NAN,
        };
        let b = body.body_feet(q)?;
        let [x, y, yaw] = start;
        let z = body.height(&b, [x, y], yaw, world);
        body.position = [x, y, z];
        body.feet = body.world_feet(&b);
        for (i, f) in body.feet.iter().enumerate() {
            if f[2] - world.ground(f[0], f[1]) <= cfg.contact {
                body.anchors[i] = Some([f[0], f[1]]);
            }
        }
        body.margin = body.support_margin();
        body.min_margin = body.margin;
        body.min_clearance = body.clearance(world);
        Ok(body)
    }

    /// Each foot in the body frame for joints `q` (rad); an error for joints not finite.
    fn body_feet(&self, q: &[[f64; 3]; 6]) -> Result<[V3; 6], String> {
        if !q.iter().flatten().all(|v| v.is_finite()) {
            return Err(format!("the hexapod's joints must be finite: {q:?}"));
        }
        let mut b = [[0.0; 3]; 6];
        for (i, f) in b.iter_mut().enumerate() {
            *f = self
                .robot
                .foot(i as u8 + 1, q[i].map(f64::to_degrees))
                .map_err(|e| e.to_string())?;
        }
        Ok(b)
    }

    /// The level body's height at (x, y, yaw): the lowest that keeps every foot `b` (body
    /// frame) out of the ground under it.
    fn height(&self, b: &[V3; 6], p: P2, yaw: f64, world: &World) -> f64 {
        b.iter()
            .map(|f| {
                let r = rotate(yaw, [f[0], f[1]]);
                world.ground(p[0] + r[0], p[1] + r[1]) - f[2]
            })
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// The feet `b` (body frame) in the world at the body's pose.
    fn world_feet(&self, b: &[V3; 6]) -> [V3; 6] {
        b.map(|f| {
            let r = rotate(self.yaw, [f[0], f[1]]);
            [
                self.position[0] + r[0],
                self.position[1] + r[1],
                self.position[2] + f[2],
            ]
        })
    }

    /// The body centre's margin in the convex hull of the feet on the ground (see
    /// [`HexBody::margin`]).
    fn support_margin(&self) -> f64 {
        let on: Vec<P2> = (0..6)
            .filter(|&i| self.anchors[i].is_some())
            .map(|i| [self.feet[i][0], self.feet[i][1]])
            .collect();
        margin(&hull(&on), [self.position[0], self.position[1]])
    }

    /// The feet's smallest clearance from an obstacle now.
    fn clearance(&self, world: &World) -> f64 {
        self.feet
            .iter()
            .map(|f| world.clearance(*f))
            .fold(f64::INFINITY, f64::min)
    }

    /// Moves the body to the joints `q` (rad, legs 1 to 6, each coxa, femur, tibia) at time
    /// `t`, s; returns what began. Joints that are not finite leave the body where it is
    /// (only the time moves on).
    ///
    /// The feet that were on the ground and are still within [`HexBodyConfig::release`] of
    /// it keep their anchors; two or more of them fix the body's x, y and yaw (the
    /// least-squares rigid fit of their body-frame x, y onto their anchors), fewer leave
    /// them as they were. The body's height is then the lowest that keeps every foot out
    /// of the ground. Feet that were off the ground and are now within
    /// [`HexBodyConfig::contact`] of it touch down, anchored where they are; the others on
    /// it beyond the release height lift off.
    pub fn step(&mut self, t: f64, q: &[[f64; 3]; 6], world: &World) -> Vec<HexEvent> {
        let mut events = Vec::new();
        self.t = t;
        let Ok(b) = self.body_feet(q) else {
            return events;
        };
        // Which feet keep their anchors: their heights with the body as it was, set on its
        // feet at its new height.
        let p0 = [self.position[0], self.position[1]];
        let z0 = self.height(&b, p0, self.yaw, world);
        let was: [bool; 6] = self.anchors.map(|a| a.is_some());
        let mut kept = [false; 6];
        for i in 0..6 {
            let r = rotate(self.yaw, [b[i][0], b[i][1]]);
            let (x, y) = (p0[0] + r[0], p0[1] + r[1]);
            kept[i] = was[i] && z0 + b[i][2] - world.ground(x, y) <= self.cfg.release;
        }
        let (from, to): (Vec<P2>, Vec<P2>) = (0..6)
            .filter_map(|i| {
                let a = self.anchors[i].filter(|_| kept[i])?;
                Some(([b[i][0], b[i][1]], a))
            })
            .unzip();
        if from.len() >= 2 {
            let (p, yaw) = fit(&from, &to, self.yaw);
            self.position[0] = p[0];
            self.position[1] = p[1];
            self.yaw = yaw;
        }
        self.position[2] = self.height(&b, [self.position[0], self.position[1]], self.yaw, world);
        self.feet = self.world_feet(&b);
        for i in 0..6 {
            let f = self.feet[i];
            if was[i] && !kept[i] {
                self.anchors[i] = None;
            } else if !was[i] && f[2] - world.ground(f[0], f[1]) <= self.cfg.contact {
                self.anchors[i] = Some([f[0], f[1]]);
                self.counts.touchdowns += 1;
                events.push(HexEvent::Touchdown {
                    leg: i as u8 + 1,
                    at: f,
                });
            }
        }
        self.collisions(world, &mut events);
        self.limits(q, &mut events);
        self.margin = self.support_margin();
        self.min_margin = self.min_margin.min(self.margin);
        self.falls(&mut events);
        events
    }

    /// Reports the feet that went into an obstacle; keeps the smallest clearance.
    fn collisions(&mut self, world: &World, events: &mut Vec<HexEvent>) {
        for (i, f) in self.feet.iter().enumerate() {
            let now = world.obstacle_at(*f);
            if let Some(obstacle) = now {
                if self.colliding[i] != now {
                    self.counts.collisions += 1;
                    events.push(HexEvent::Collision {
                        leg: i as u8 + 1,
                        obstacle,
                        at: *f,
                    });
                }
            }
            self.colliding[i] = now;
        }
        self.min_clearance = self.min_clearance.min(self.clearance(world));
    }

    /// Reports the joints that reached a limit of Table 3.2 (within the limit margin).
    fn limits(&mut self, q: &[[f64; 3]; 6], events: &mut Vec<HexEvent>) {
        let m = self.cfg.limit_margin;
        for (i, leg_q) in q.iter().enumerate() {
            let Some(leg) = self.robot.leg(i as u8 + 1) else {
                continue;
            };
            for (j, &v) in leg_q.iter().enumerate() {
                let [lo, hi] = leg.limits_deg[j].map(f64::to_radians);
                let at = v <= lo + m || v >= hi - m;
                if at && !self.at_limit[i][j] {
                    self.counts.limits += 1;
                    events.push(HexEvent::Limit {
                        leg: i as u8 + 1,
                        joint: HEX_JOINTS[j],
                        value: v,
                    });
                }
                self.at_limit[i][j] = at;
            }
        }
    }

    /// Reports a fall: the margin below minus the fall margin for the fall time.
    fn falls(&mut self, events: &mut Vec<HexEvent>) {
        if self.margin >= -self.cfg.fall_margin || self.t.is_nan() {
            self.out_since = None;
            self.falling = false;
            return;
        }
        let since = *self.out_since.get_or_insert(self.t);
        // (A hair of slack for times summed in steps.)
        if !self.falling && self.t - since >= self.cfg.fall_time - 1e-9 {
            self.falling = true;
            self.counts.falls += 1;
            events.push(HexEvent::Fall {
                at: [self.position[0], self.position[1]],
                margin: self.margin,
            });
        }
    }

    /// The body's centre in the world (m) and its yaw (rad, continuous: not wrapped to
    /// ±π). The body is level: no roll, no pitch.
    pub fn pose(&self) -> (V3, f64) {
        (self.position, self.yaw)
    }

    /// Each foot in the world (legs 1 to 6), m.
    pub fn feet(&self) -> [V3; 6] {
        self.feet
    }

    /// Each foot on the ground (legs 1 to 6).
    pub fn contact(&self) -> [bool; 6] {
        self.anchors.map(|a| a.is_some())
    }

    /// The static stability margin now: the signed distance (m) of the body's centre (taken
    /// for the centre of mass) from the convex hull of the feet on the ground, positive
    /// inside. With two feet on the ground (or several in a line) minus its distance from
    /// the segment between them, with one minus its distance from that foot, with none
    /// negative infinity.
    pub fn margin(&self) -> f64 {
        self.margin
    }

    /// The counters so far.
    pub fn counts(&self) -> HexCounts {
        self.counts
    }

    /// The smallest margin so far (the standing start's included), m.
    pub fn min_margin(&self) -> f64 {
        self.min_margin
    }

    /// The feet's smallest clearance from an obstacle so far (the standing start's
    /// included; see [`World::clearance`]), m: infinite with no obstacle.
    pub fn min_clearance(&self) -> f64 {
        self.min_clearance
    }

    /// The time of the last step, s: NaN before the first.
    pub fn time(&self) -> f64 {
        self.t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use stride_world::scene::Scene;

    /// The gait's stand (config/gait-hexapod.toml): each foot 0.195 m out from its coxa
    /// axis, the axes 0.08 m above the ground.
    const REACH: f64 = 0.195;
    const HEIGHT: f64 = 0.08;
    const TRIPOD: [usize; 3] = [1, 3, 5];
    const STANCE: [usize; 3] = [2, 4, 6];

    fn robot() -> Hexapod {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/robots/hexapod.toml"
        );
        Hexapod::load(std::path::Path::new(path)).unwrap()
    }

    fn world(obstacles: &str) -> World {
        let text = format!(
            "name = \"t\"\nstart = {{ x = 0.0, y = 0.0 }}\ngoal = {{ x = 2.0, y = 0.0 }}\n\
             [map]\nx = [-1.0, 3.0]\ny = [-1.0, 1.0]\n{obstacles}"
        );
        World::new(Scene::parse(&text, std::path::Path::new(".")).unwrap()).unwrap()
    }

    /// Each leg's standing foot, body frame.
    fn stand(r: &Hexapod) -> [V3; 6] {
        std::array::from_fn(|i| {
            Hexapod::to_body(r.leg(i as u8 + 1).unwrap(), [REACH, 0.0, -HEIGHT])
        })
    }

    /// The joints (rad) that put the feet at `feet` (body frame).
    /// The body standing with every foot at `home`, its centre at `start`.
    fn at_home(r: &Hexapod, w: &World, home: &[V3; 6], start: [f64; 3]) -> HexBody {
        HexBody::new(
            r.clone(),
            HexBodyConfig::default(),
            start,
            &joints(r, home),
            w,
        )
        .unwrap()
    }

    fn joints(r: &Hexapod, feet: &[V3; 6]) -> [[f64; 3]; 6] {
        std::array::from_fn(|i| {
            r.solve(i as u8 + 1, feet[i])
                .unwrap()
                .servo_deg
                .map(f64::to_radians)
        })
    }

    /// `feet` with the legs numbered in `legs` moved by `d` (body frame).
    fn moved(feet: &[V3; 6], legs: &[usize], d: V3) -> [V3; 6] {
        let mut f = *feet;
        for &n in legs {
            for k in 0..3 {
                f[n - 1][k] += d[k];
            }
        }
        f
    }

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn the_config_checks_its_numbers() {
        assert!(HexBodyConfig::default().check().is_ok());
        let bad = HexBodyConfig {
            release: 0.001,
            ..HexBodyConfig::default()
        };
        assert!(bad.check().is_err());
        let cfg: HexBodyConfig = toml::from_str("fall_time = 0.2").unwrap();
        assert_eq!(cfg.fall_time, 0.2);
        assert_eq!(cfg.contact, 0.003);
        assert!(toml::from_str::<HexBodyConfig>("takeover = 0.1").is_err());
    }

    #[test]
    fn the_stand_puts_all_six_feet_on_the_ground_and_the_body_at_its_height() {
        let r = robot();
        let w = world("");
        let q = joints(&r, &stand(&r));
        let mut body = HexBody::new(r, HexBodyConfig::default(), [0.5, 0.2, 0.3], &q, &w).unwrap();
        assert_eq!(body.contact(), [true; 6]);
        let (p, yaw) = body.pose();
        assert!(close(p[0], 0.5, 1e-12) && close(p[1], 0.2, 1e-12), "{p:?}");
        assert!(close(p[2], HEIGHT, 1e-9), "{p:?}");
        assert!(close(yaw, 0.3, 1e-12));
        assert!(body.feet().iter().all(|f| f[2].abs() < 1e-9));
        assert!(body.margin() > 0.1, "{}", body.margin());
        assert!(body.time().is_nan());
        for k in 0..20 {
            let events = body.step(k as f64 * 0.02, &q, &w);
            assert!(events.is_empty(), "{events:?}");
        }
        let (p1, yaw1) = body.pose();
        assert!((0..3).all(|k| close(p1[k], p[k], 1e-12)) && close(yaw1, yaw, 1e-12));
        assert_eq!(body.counts(), HexCounts::default());
        assert_eq!(body.min_clearance(), f64::INFINITY);
        assert!(close(body.time(), 0.38, 1e-12));
    }

    #[test]
    fn a_tripod_walks_the_body_forward_and_the_swing_feet_land_where_they_come_down() {
        let r = robot();
        let w = world("");
        let home = stand(&r);
        let yaw0 = 0.3;
        let mut body = at_home(&r, &w, &home, [0.5, 0.2, yaw0]);
        let start = body.feet();
        let mut events = Vec::new();
        let mut t = 0.0;
        let mut go = |body: &mut HexBody, feet: &[V3; 6], events: &mut Vec<HexEvent>| {
            events.extend(body.step(t, &joints(&r, feet), &w));
            t += 0.02;
        };
        // Legs 1, 3 and 5 lift 3 cm: the body stays, on a stable tripod.
        let n = 12;
        for k in 1..=n {
            let h = 0.03 * k as f64 / n as f64;
            go(
                &mut body,
                &moved(&home, &TRIPOD, [0.0, 0.0, h]),
                &mut events,
            );
            // On the ground until past the release height.
            let up = h > HexBodyConfig::default().release + 1e-12;
            assert_eq!(body.contact()[0], !up, "at {h}");
            let (p, yaw) = body.pose();
            assert!(close(p[0], 0.5, 1e-12) && close(p[1], 0.2, 1e-12) && close(yaw, yaw0, 1e-12));
            assert!(close(p[2], HEIGHT, 1e-9));
            assert!(body.margin() > 0.05, "{}", body.margin());
        }
        assert_eq!(body.contact(), [false, true, false, true, false, true]);
        assert!(events.is_empty(), "a stable tripod: {events:?}");
        // The stance feet move 2 cm back, the swing feet 2 cm ahead (in the air).
        let mut feet = home;
        for k in 1..=n {
            let s = k as f64 / n as f64;
            feet = moved(&home, &STANCE, [-0.02 * s, 0.0, 0.0]);
            feet = moved(&feet, &TRIPOD, [0.02 * s, 0.0, 0.03]);
            go(&mut body, &feet, &mut events);
        }
        let (p, yaw) = body.pose();
        let ahead = rotate(yaw0, [0.02, 0.0]);
        assert!(
            close(p[0], 0.5 + ahead[0], 1e-9) && close(p[1], 0.2 + ahead[1], 1e-9),
            "{p:?}"
        );
        assert!(close(yaw, yaw0, 1e-9) && close(p[2], HEIGHT, 1e-9));
        // The stance feet did not move in the world.
        for leg in STANCE {
            assert!((0..3).all(|k| close(body.feet()[leg - 1][k], start[leg - 1][k], 1e-9)));
        }
        assert!(events.is_empty(), "{events:?}");
        // The swing feet come down: 4 cm ahead of where they lifted.
        for k in 1..=n {
            let h = 0.03 * (1.0 - k as f64 / n as f64);
            let f = moved(&feet, &TRIPOD, [0.0, 0.0, h - 0.03]);
            go(&mut body, &f, &mut events);
        }
        assert_eq!(body.contact(), [true; 6]);
        let step = rotate(yaw0, [0.04, 0.0]);
        let downs: Vec<(u8, V3)> = events
            .iter()
            .filter_map(|e| match e {
                HexEvent::Touchdown { leg, at } => Some((*leg, *at)),
                _ => None,
            })
            .collect();
        assert_eq!(downs.len(), 3, "{events:?}");
        for (leg, at) in downs {
            assert!(TRIPOD.contains(&(leg as usize)));
            let s = start[leg as usize - 1];
            // Touched down at the contact height, right over where it now stands.
            assert!(at[2] > 0.0 && at[2] <= 0.003 + 1e-12, "{at:?}");
            let f = body.feet()[leg as usize - 1];
            assert!(close(at[0], s[0] + step[0], 1e-9) && close(at[1], s[1] + step[1], 1e-9));
            assert!(close(f[0], at[0], 1e-12) && close(f[1], at[1], 1e-12) && f[2].abs() < 1e-9);
        }
        assert_eq!(body.counts().touchdowns, 3);
        assert_eq!(
            body.counts().falls + body.counts().collisions + body.counts().limits,
            0
        );
        assert!(body.min_margin() > 0.05);
        // Another stance phase on all six now: the body holds still.
        let (p1, _) = body.pose();
        go(
            &mut body,
            &moved(&feet, &TRIPOD, [0.0, 0.0, -0.03]),
            &mut events,
        );
        assert!((0..3).all(|k| close(body.pose().0[k], p1[k], 1e-12)));
    }

    #[test]
    fn a_turn_of_the_stance_feet_turns_the_body() {
        let r = robot();
        let w = world("");
        let home = stand(&r);
        let mut body = at_home(&r, &w, &home, [0.0, 0.0, 0.0]);
        let lifted = moved(&home, &TRIPOD, [0.0, 0.0, 0.03]);
        body.step(0.0, &joints(&r, &lifted), &w);
        // The stance feet turn 8° clockwise about the body's centre (body frame): the body
        // turns 8° counter-clockwise over them.
        let turn = 8f64.to_radians();
        let mut events = Vec::new();
        let n = 10;
        for k in 1..=n {
            let a = -turn * k as f64 / n as f64;
            let mut f = lifted;
            for leg in STANCE {
                let g = rotate(a, [home[leg - 1][0], home[leg - 1][1]]);
                f[leg - 1] = [g[0], g[1], home[leg - 1][2]];
            }
            events.extend(body.step(k as f64 * 0.02, &joints(&r, &f), &w));
        }
        let (p, yaw) = body.pose();
        assert!(close(yaw, turn, 1e-9), "{yaw}");
        assert!(p[0].abs() < 1e-9 && p[1].abs() < 1e-9 && close(p[2], HEIGHT, 1e-9));
        assert!(events.is_empty(), "{events:?}");
        // A turn past ±π stays continuous.
        assert!(close(
            fit(
                &[[1.0, 0.0], [-1.0, 0.0]],
                &[[-1.0, -0.01], [1.0, 0.01]],
                3.1
            )
            .1,
            3.1516,
            1e-3
        ));
    }

    #[test]
    fn a_body_over_two_feet_falls_after_the_fall_time() {
        let r = robot();
        let w = world("");
        let home = stand(&r);
        let mut body = at_home(&r, &w, &home, [0.0, 0.0, 0.0]);
        // Only the front feet (legs 1 and 2) stay down: the body's centre is 0.258 m behind
        // the segment between them.
        let q = joints(&r, &moved(&home, &[3, 4, 5, 6], [0.0, 0.0, 0.03]));
        let mut falls = Vec::new();
        for k in 0..20 {
            let t = k as f64 * 0.02;
            let events = body.step(t, &q, &w);
            assert_eq!(body.contact(), [true, true, false, false, false, false]);
            if events.iter().any(|e| matches!(e, HexEvent::Fall { .. })) {
                falls.push(t);
            }
        }
        assert!(body.margin() < -0.2, "{}", body.margin());
        assert_eq!(falls.len(), 1, "reported once while it lasts");
        assert!(close(falls[0], 0.1, 1e-9), "after the fall time: {falls:?}");
        assert_eq!(body.counts().falls, 1);
        assert!(close(body.min_margin(), body.margin(), 1e-12));
        let fall = HexEvent::Fall {
            at: [0.0, 0.0],
            margin: body.margin(),
        };
        assert!(fall.to_string().contains("outside its support"));
    }

    #[test]
    fn a_foot_in_an_obstacle_and_a_joint_at_its_limit_are_reported_once() {
        let r = robot();
        // A low box around where leg 1's foot comes down 4 cm further ahead.
        let home = stand(&r);
        let f1 = home[0];
        let w = world(&format!(
            "[[obstacle]]\nshape = \"box\"\nx = {}\ny = {}\nlength = 0.03\nwidth = 0.03\n\
             height = 0.02\n",
            f1[0] + 0.04,
            f1[1]
        ));
        let mut body = at_home(&r, &w, &home, [0.0, 0.0, 0.0]);
        assert!(body.min_clearance() > 0.0 && body.min_clearance().is_finite());
        let mut events = Vec::new();
        let mut t = 0.0;
        let plan = [
            moved(&home, &[1], [0.0, 0.0, 0.04]),
            moved(&home, &[1], [0.04, 0.0, 0.04]),
            moved(&home, &[1], [0.04, 0.0, 0.01]),
            moved(&home, &[1], [0.04, 0.0, 0.005]),
            moved(&home, &[1], [0.04, 0.0, 0.0]),
        ];
        for f in &plan {
            events.extend(body.step(t, &joints(&r, f), &w));
            t += 0.02;
        }
        let hits: Vec<_> = events
            .iter()
            .filter(|e| {
                matches!(
                    e,
                    HexEvent::Collision {
                        leg: 1,
                        obstacle: 0,
                        ..
                    }
                )
            })
            .collect();
        assert_eq!(hits.len(), 1, "{events:?}");
        assert_eq!(body.counts().collisions, 1);
        assert_eq!(body.min_clearance(), 0.0);
        // Leg 1's coxa at its lower limit, twice: one report.
        let mut q = joints(&r, &home);
        q[0][0] = (-80f64).to_radians();
        for _ in 0..2 {
            events.extend(body.step(t, &q, &w));
            t += 0.02;
        }
        let limits: Vec<_> = events
            .iter()
            .filter(|e| matches!(e, HexEvent::Limit { .. }))
            .collect();
        assert_eq!(limits.len(), 1, "{events:?}");
        assert!(matches!(
            limits[0],
            HexEvent::Limit {
                leg: 1,
                joint: "coxa",
                ..
            }
        ));
        assert_eq!(body.counts().limits, 1);
        assert!(limits[0].to_string().contains("leg 1's coxa"));
    }

    #[test]
    fn joints_not_finite_are_refused_or_ignored() {
        let r = robot();
        let w = world("");
        let mut q = joints(&r, &stand(&r));
        let good = q;
        q[2][1] = f64::NAN;
        assert!(HexBody::new(r.clone(), HexBodyConfig::default(), [0.0; 3], &q, &w).is_err());
        let mut body = HexBody::new(r, HexBodyConfig::default(), [0.0; 3], &good, &w).unwrap();
        let before = body.feet();
        assert!(body.step(0.0, &q, &w).is_empty());
        assert_eq!(body.feet(), before);
        assert_eq!(body.time(), 0.0);
    }
}
