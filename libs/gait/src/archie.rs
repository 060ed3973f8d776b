//! Archie's joint trajectories from a pattern: at every row the pelvis (its centre the cart
//! of the cart-table model, at z_c above the ground, upright, headed between the feet) and
//! both soles are solved by the legs' inverse kinematics; the rows' velocities are the
//! positions' central differences. Every row and the motion between rows (the cubic a PVT
//! drive plays) is checked against the joints' position, velocity and acceleration limits
//! with the bridges' own check ([`stride_limits::curve::beyond`]); a pattern that breaks one
//! anywhere is refused whole.
//!
//! The default COM height comes from the legs ([`default_z_c`]): the highest the pelvis
//! centre stands over the double support of the longest step with the knees bent at least a
//! little, less a margin. The thesis's 0.72 m is above anything the legs reach (the pelvis
//! centre stands at most 0.679 m high with straight legs).

use serde::Deserialize;
use stride_kinematics::archie::{self, ArchieConfig, Leg, LegPoints, Q};
use stride_kinematics::math::{at, yawed, Frame, Pose, V3};
use stride_limits::curve::{beyond, hermite_within, Bounds, Cubic};

use crate::pattern::{Body, Pattern};
use crate::support::P2;
use crate::swing::Place;
use crate::GaitError;

/// How the COM height is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeightConfig {
    /// The longest step the height must serve (the feet this far apart along x), m.
    pub step_length: f64,
    /// The feet's spacing across, m.
    pub stance_width: f64,
    /// The least knee bend over the step, rad (away from the straight knee's singularity).
    pub knee_min: f64,
    /// Taken off the highest height, m.
    pub margin: f64,
    /// Every joint this far inside its limits in those poses, rad (room for the swing, the
    /// pelvis carrying the whole body's COM, and the COM's sway past the feet).
    pub joint_margin: f64,
}

impl Default for HeightConfig {
    fn default() -> HeightConfig {
        HeightConfig {
            step_length: 0.25,
            stance_width: 0.2,
            knee_min: 0.4,
            margin: 0.01,
            joint_margin: 0.1,
        }
    }
}

/// The COM height from the legs: [`archie::max_pelvis_height`] over the configured step with
/// the pelvis over the soles' ZMP points (`zmp_ahead` of their centres), the knees bent at
/// least `knee_min` and every joint `joint_margin` inside its limits, less the margin.
pub fn default_z_c(robot: &ArchieConfig, h: &HeightConfig, zmp_ahead: f64) -> f64 {
    let ahead = robot.foot.centre_ahead + zmp_ahead;
    let m = h.joint_margin;
    let fits = |_: Leg, q: &Q| {
        q[3] >= h.knee_min
            && robot
                .joint
                .iter()
                .zip(q)
                .all(|(j, &v)| v >= j.min + m && v <= j.max - m)
    };
    archie::max_pelvis_height(&robot.links, h.step_length, h.stance_width, ahead, fits) - h.margin
}

/// Between the rows whose whole-body ZMP [`Body::zmp_offset`] works out, s: the offset
/// changes over a swing's lift-off and landing (a tenth of a second and more); rows every
/// 10 ms moved the ZMP it gives by under half a millimetre, at twice the cost.
pub const OFFSET_PERIOD: f64 = 0.02;

/// The joints' first guess for a pattern's first row: the knees bent.
const REST: [Q; 2] = [[0.0, 0.0, 0.0, 0.3, -0.15, 0.0]; 2];

/// One leg's rows.
#[derive(Debug, Clone, PartialEq)]
pub struct LegRows {
    /// The joints' names, e.g. "left_knee".
    pub names: [String; 6],
    /// Positions, rad, a row each.
    pub positions: Vec<Q>,
    /// Velocities, rad/s.
    pub velocities: Vec<Q>,
}

/// Both legs' joint trajectories, rows every period from the pattern's start.
#[derive(Debug, Clone, PartialEq)]
pub struct JointPlan {
    /// Seconds from the pattern's start to each row.
    pub times: Vec<f64>,
    /// The pelvis at each row (world frame).
    pub pelvis: Vec<Pose>,
    /// The left leg.
    pub left: LegRows,
    /// The right leg.
    pub right: LegRows,
}

/// A pattern's joint trajectories made up to some time ([`ArchieGait::joints_until`]).
#[derive(Debug, Clone)]
pub struct Joints {
    /// The rows made and checked so far.
    pub plan: JointPlan,
    made: Made,
}

/// Where making a pattern's rows stands: every row's positions made so far (one or two more
/// than the plan keeps: its last velocities need them) and the solver's guesses for the next.
#[derive(Debug, Clone)]
struct Made {
    /// The pattern's samples that are rows.
    ks: Vec<usize>,
    times: Vec<f64>,
    pelvis: Vec<Pose>,
    pos: Vec<[Q; 2]>,
    near: [Q; 2],
    offset: V3,
    seen: Vec<V3>,
}

impl Joints {
    /// Every row of the pattern is made.
    pub fn complete(&self) -> bool {
        self.plan.times.len() == self.made.ks.len()
    }
}

fn truncate_plan(p: &mut JointPlan, n: usize) {
    p.times.truncate(n);
    p.pelvis.truncate(n);
    for rows in [&mut p.left, &mut p.right] {
        rows.positions.truncate(n);
        rows.velocities.truncate(n);
    }
}

/// Archie's joints over patterns.
#[derive(Debug, Clone)]
pub struct ArchieGait {
    /// The robot.
    pub robot: ArchieConfig,
    /// The COM's height above the ground, m.
    pub z_c: f64,
    /// Between rows, s.
    pub row_period: f64,
    /// The pattern's COM is the whole robot's (the pelvis placed so that the point masses'
    /// centre follows it); otherwise the pelvis centre's (the thesis's "joint 6 is the COM").
    pub whole_body: bool,
    /// Whole body: the pelvis's place less the COM's standing, the first guess of [`place`].
    ///
    /// [`place`]: ArchieGait::place
    pub offset: V3,
    /// Whole body: how far the COM moves per metre the pelvis moves (each axis, standing),
    /// the step of [`place`]'s search.
    ///
    /// [`place`]: ArchieGait::place
    pub gain: V3,
}

impl ArchieGait {
    /// The gait of `robot` with the COM height from its legs ([`default_z_c`]): the pelvis
    /// centre's height, or (`whole_body`) the whole robot's COM's standing with its pelvis
    /// there, over the soles' ZMP points (`zmp_ahead` of their centres). An error when the
    /// robot cannot stand there within its joints' limits.
    pub fn new(
        robot: ArchieConfig,
        height: &HeightConfig,
        zmp_ahead: f64,
        row_period: f64,
        whole_body: bool,
    ) -> Result<ArchieGait, GaitError> {
        let pelvis_z = default_z_c(&robot, height, zmp_ahead);
        let mut g = ArchieGait {
            robot,
            z_c: pelvis_z,
            row_period,
            whole_body: false,
            offset: [0.0; 3],
            gain: [1.0; 3],
        };
        let w = height.stance_width / 2.0;
        let feet = [[-zmp_ahead, w, 0.0, 0.0], [-zmp_ahead, -w, 0.0, 0.0]];
        let pelvis = at([0.0, 0.0, pelvis_z]);
        let q = g
            .solve(&pelvis, &feet, &[[0.0, 0.0, 0.0, 0.3, -0.15, 0.0]; 2])
            .map_err(|e| {
                GaitError::Plan(format!(
                    "Archie cannot stand with its pelvis {pelvis_z:.3} m high (the height its \
                     legs allow a {} m step): {e}",
                    height.step_length
                ))
            })?;
        if whole_body {
            let com = g.com_of(&pelvis, &q);
            g.z_c = com[2];
            g.offset = [-com[0], -com[1], pelvis_z - com[2]];
            g.whole_body = true;
            for d in 0..3 {
                let mut p = pelvis.position();
                p[d] += 1e-4;
                let moved = at(p);
                if let Ok(qm) = g.reach(&moved, &feet, &q) {
                    let c = g.com_of(&moved, &qm);
                    let k = (c[d] - com[d]) / 1e-4;
                    if k.is_finite() && k > 0.1 {
                        g.gain[d] = k;
                    }
                }
            }
        }
        Ok(g)
    }

    /// The whole robot's centre of mass for a pelvis pose and the legs' joints.
    pub fn com_of(&self, pelvis: &Pose, q: &[Q; 2]) -> V3 {
        let points = [Leg::Left, Leg::Right].map(|leg| {
            let k = if leg == Leg::Left { 0 } else { 1 };
            archie::fk_points(&self.robot.links, leg, &q[k]).1
        });
        self.com_of_points(pelvis, &points)
    }

    /// The whole robot's centre of mass for a pelvis pose and the legs' points.
    fn com_of_points(&self, pelvis: &Pose, points: &[LegPoints; 2]) -> V3 {
        let mut sum = [0.0; 3];
        for (mass, p) in self.point_masses(pelvis, points) {
            for d in 0..3 {
                sum[d] += mass * p[d];
            }
        }
        let total = self.robot.mass.total();
        sum.map(|v| v / total)
    }

    /// The robot's point masses (world): the pelvis's at its centre, a thigh's and a shank's
    /// at their middles, a foot's at the ankle roll axis.
    fn point_masses(&self, pelvis: &Pose, points: &[LegPoints; 2]) -> [(f64, V3); 7] {
        let m = &self.robot.mass;
        let w = |a: &V3| pelvis.apply(a);
        let mid = |a: &V3, b: &V3| {
            w(&[
                (a[0] + b[0]) / 2.0,
                (a[1] + b[1]) / 2.0,
                (a[2] + b[2]) / 2.0,
            ])
        };
        let [l, r] = points;
        [
            (m.pelvis, pelvis.position()),
            (m.thigh, mid(&l[0], &l[1])),
            (m.shank, mid(&l[1], &l[2])),
            (m.foot, w(&l[3])),
            (m.thigh, mid(&r[0], &r[1])),
            (m.shank, mid(&r[1], &r[2])),
            (m.foot, w(&r[3])),
        ]
    }

    /// The pelvis and joints that put the COM at `com` (world) with the feet at `feet`: the
    /// pelvis centre there, or (whole body) the pelvis moved until the point masses' centre
    /// is there to 0.3 µm (`offset`: the pelvis's place less the COM's, kept from row to
    /// row, its first guess a cubic through the last four rows'): the rows' second
    /// differences, and so their ZMP, carry that error over a row period squared (0.01 mm
    /// moved the ZMP by up to 2 cm at 10 ms; 0.3 µm by about half a millimetre).
    fn place(
        &self,
        com: V3,
        yaw: f64,
        feet: &[Place; 2],
        near: &[Q; 2],
        offset: &mut V3,
    ) -> Result<(Pose, [Q; 2], [LegPoints; 2]), GaitError> {
        if !self.whole_body {
            let pelvis = yawed(com, yaw);
            let (q, points) = self.reach_points(&pelvis, feet, near)?;
            self.check_limits(&q)?;
            return Ok((pelvis, q, points));
        }
        let mut q = *near;
        for _ in 0..20 {
            let pelvis = yawed(
                [com[0] + offset[0], com[1] + offset[1], com[2] + offset[2]],
                yaw,
            );
            let (qn, points) = self.reach_points(&pelvis, feet, &q)?;
            q = qn;
            let now = self.com_of_points(&pelvis, &points);
            let err = [com[0] - now[0], com[1] - now[1], com[2] - now[2]];
            // The COM moves by about `gain` of the pelvis's move: the offset for the next
            // try (or, once this one is close enough, the next row's guess) corrected so.
            for d in 0..3 {
                offset[d] += err[d] / self.gain[d];
            }
            if err.iter().all(|e| e.abs() < 3e-7) {
                self.check_limits(&q)?;
                return Ok((pelvis, q, points));
            }
        }
        Err(GaitError::Plan(
            "the pelvis that puts the whole robot's COM on the pattern was not found".into(),
        ))
    }

    /// The joints of both legs for a pelvis pose and two soles (their centres' places),
    /// checked against the joints' position limits.
    pub fn solve(
        &self,
        pelvis: &Pose,
        feet: &[Place; 2],
        near: &[Q; 2],
    ) -> Result<[Q; 2], GaitError> {
        let q = self.reach(pelvis, feet, near)?;
        self.check_limits(&q)?;
        Ok(q)
    }

    fn check_limits(&self, q: &[Q; 2]) -> Result<(), GaitError> {
        for (k, leg) in [Leg::Left, Leg::Right].into_iter().enumerate() {
            self.robot
                .check_q(leg, &q[k])
                .map_err(|e| GaitError::Plan(e.to_string()))?;
        }
        Ok(())
    }

    /// [`ArchieGait::solve`] without the limits.
    fn reach(&self, pelvis: &Pose, feet: &[Place; 2], near: &[Q; 2]) -> Result<[Q; 2], GaitError> {
        self.reach_points(pelvis, feet, near).map(|(q, _)| q)
    }

    /// [`ArchieGait::reach`], with the legs' points.
    fn reach_points(
        &self,
        pelvis: &Pose,
        feet: &[Place; 2],
        near: &[Q; 2],
    ) -> Result<([Q; 2], [LegPoints; 2]), GaitError> {
        let mut out = [[0.0; 6]; 2];
        let mut points = [[[0.0; 3]; 5]; 2];
        let inv = pelvis.inverse();
        for (k, leg) in [Leg::Left, Leg::Right].into_iter().enumerate() {
            let f = feet[k];
            let sole = inv * self.robot.sole_frame([f[0], f[1], f[2]], f[3]);
            (out[k], points[k]) = archie::solve_points(&self.robot.links, leg, &sole, &near[k])
                .map_err(|e| GaitError::Plan(e.to_string()))?;
        }
        Ok((out, points))
    }

    /// The pattern's COM at a sample (z_c above the ground under it: the feet's ground
    /// heights, the support's in single support) and the pelvis's heading (between the feet).
    pub fn com_at(&self, pat: &Pattern, k: usize) -> (V3, f64) {
        let s = &pat.samples[k];
        let ground = pat.timeline.ground(s.t);
        let feet = [s.feet[0][0], s.feet[1][0]];
        let c = s.com.com()[0];
        let (sy, cy) = (
            feet[0][3].sin() + feet[1][3].sin(),
            feet[0][3].cos() + feet[1][3].cos(),
        );
        ([c[0], c[1], self.z_c + ground], sy.atan2(cy))
    }

    /// The pelvis, joints and legs' points of sample `k`'s row: the COM placed from the
    /// offset that went on as it went over the last four rows (`seen`, newest first: a
    /// cubic through them; before there are four, the last one found: a pattern that
    /// starts mid-walk starts from an offset unlike the standing one, and extrapolating from
    /// that would throw the first guess far off), `near` the joints' first guess.
    fn place_row(
        &self,
        pat: &Pattern,
        k: usize,
        near: &[Q; 2],
        offset: &mut V3,
        seen: &mut Vec<V3>,
    ) -> Result<(Pose, [Q; 2], [LegPoints; 2]), GaitError> {
        let s = &pat.samples[k];
        let feet = [s.feet[0][0], s.feet[1][0]];
        let (com, yaw) = self.com_at(pat, k);
        if let [a, b, c, e] = seen[..] {
            for d in 0..3 {
                offset[d] = 4.0 * a[d] - 6.0 * b[d] + 4.0 * c[d] - e[d];
            }
        } else if let Some(a) = seen.first() {
            *offset = *a;
        }
        let placed = self
            .place(com, yaw, &feet, near, offset)
            .map_err(|e| GaitError::Plan(format!("at {:.3} s: {e}", s.t - pat.timeline.start)))?;
        seen.insert(0, *offset);
        seen.truncate(4);
        Ok(placed)
    }

    /// The joint trajectories of a pattern, checked (see the module).
    pub fn joints(&self, pat: &Pattern) -> Result<JointPlan, GaitError> {
        Ok(self.joints_until(pat, f64::INFINITY)?.plan)
    }

    /// The joint trajectories of a pattern's start, checked, up to the first row at or after
    /// `until` (the pattern's time, s); [`ArchieGait::extend`] makes the rest, row for row what
    /// [`ArchieGait::joints`] makes. A plan's later rows, which a newer plan replaces before
    /// they play, then cost nothing.
    pub fn joints_until(&self, pat: &Pattern, until: f64) -> Result<Joints, GaitError> {
        let stride = ((self.row_period / pat.dt).round() as usize).max(1);
        let ks: Vec<usize> = (0..pat.samples.len()).step_by(stride).collect();
        let n = ks.len();
        let mut j = Joints {
            plan: JointPlan {
                times: Vec::with_capacity(n),
                pelvis: Vec::with_capacity(n),
                left: LegRows {
                    names: self.robot.names(Leg::Left),
                    positions: Vec::with_capacity(n),
                    velocities: Vec::with_capacity(n),
                },
                right: LegRows {
                    names: self.robot.names(Leg::Right),
                    positions: Vec::with_capacity(n),
                    velocities: Vec::with_capacity(n),
                },
            },
            made: Made {
                ks,
                times: Vec::with_capacity(n),
                pelvis: Vec::with_capacity(n),
                pos: Vec::with_capacity(n),
                near: REST,
                offset: self.offset,
                seen: Vec::with_capacity(5),
            },
        };
        self.extend(pat, &mut j, until)?;
        Ok(j)
    }

    /// Makes and checks `j`'s rows of `pat` (the pattern it was begun on) up to the first at
    /// or after `until`; an error leaves `j` as it was.
    pub fn extend(&self, pat: &Pattern, j: &mut Joints, until: f64) -> Result<(), GaitError> {
        if j.complete() {
            return Ok(());
        }
        let m = &mut j.made;
        let total = m.ks.len();
        if total == 0 {
            return Ok(());
        }
        // The rows kept: through the first at or after `until` (all, at the end); their
        // velocities need the positions of one more row, and the first's of two more.
        let first_after = m.ks[..]
            .partition_point(|&k| pat.samples[k].t < until)
            .min(total - 1);
        let keep = (first_after + 1).max(j.plan.times.len());
        let need = if keep == total {
            total
        } else {
            (keep + 1).max(3).min(total)
        };
        let before = (m.pos.len(), j.plan.times.len());
        let undo = |m: &mut Made, j_plan: &mut JointPlan| {
            m.times.truncate(before.0);
            m.pelvis.truncate(before.0);
            m.pos.truncate(before.0);
            truncate_plan(j_plan, before.1);
        };
        let saved = (m.near, m.offset, m.seen.clone());
        for i in m.pos.len()..need {
            let k = m.ks[i];
            let placed = self.place_row(pat, k, &m.near, &mut m.offset, &mut m.seen);
            let (pelvis, q, _) = match placed {
                Ok(r) => r,
                Err(e) => {
                    (m.near, m.offset, m.seen) = saved;
                    undo(m, &mut j.plan);
                    return Err(e);
                }
            };
            let s = &pat.samples[k];
            m.near = q;
            m.pos.push(q);
            m.pelvis.push(pelvis);
            m.times.push(s.t - pat.timeline.start);
        }
        // Velocities: central differences; one-sided (second order) at the ends, which a
        // pattern from standing has at rest and a pattern replacing another in motion.
        let (pos, times) = (&m.pos, &m.times);
        let n = pos.len();
        let d = |i: usize, l: usize, jt: usize| -> f64 {
            let p = |k: usize| pos[k][l][jt];
            if n < 3 {
                0.0
            } else if i == 0 {
                (-3.0 * p(0) + 4.0 * p(1) - p(2)) / (times[2] - times[0])
            } else if i + 1 == n {
                (3.0 * p(n - 1) - 4.0 * p(n - 2) + p(n - 3)) / (times[n - 1] - times[n - 3])
            } else {
                (p(i + 1) - p(i - 1)) / (times[i + 1] - times[i - 1])
            }
        };
        let plan = &mut j.plan;
        for i in plan.times.len()..keep {
            plan.times.push(times[i]);
            plan.pelvis.push(m.pelvis[i]);
            plan.left.positions.push(pos[i][0]);
            plan.right.positions.push(pos[i][1]);
            // A pattern ends standing: its last row at rest (the settled COM's creep, under a
            // millimetre a second, ends there), so a drive playing it ends its motion rather
            // than stopping a stream.
            let v: [Q; 2] = if i + 1 == total {
                [[0.0; 6]; 2]
            } else {
                std::array::from_fn(|l| std::array::from_fn(|jt| d(i, l, jt)))
            };
            plan.left.velocities.push(v[0]);
            plan.right.velocities.push(v[1]);
        }
        if let Err(e) = self.check_from(plan, before.1.saturating_sub(1)) {
            (m.near, m.offset, m.seen) = saved;
            undo(m, plan);
            return Err(e);
        }
        Ok(())
    }

    /// Checks every row and the cubic between rows of both legs against the joints' limits.
    pub fn check(&self, plan: &JointPlan) -> Result<(), GaitError> {
        self.check_from(plan, 0)
    }

    /// [`ArchieGait::check`] from row `first` on.
    fn check_from(&self, plan: &JointPlan, first: usize) -> Result<(), GaitError> {
        for rows in [&plan.left, &plan.right] {
            for (j, spec) in self.robot.joint.iter().enumerate() {
                let b = Bounds {
                    min: spec.min,
                    max: spec.max,
                    v: spec.max_velocity,
                    a: spec.max_acceleration,
                };
                for i in first..plan.times.len().saturating_sub(1) {
                    let (t0, t1) = (plan.times[i], plan.times[i + 1]);
                    let (p0, v0) = (rows.positions[i][j], rows.velocities[i][j]);
                    let (p1, v1) = (rows.positions[i + 1][j], rows.velocities[i + 1][j]);
                    if hermite_within(p0, v0, p1, v1, t1 - t0, &b) {
                        continue;
                    }
                    let c = Cubic::hermite(
                        rows.positions[i][j],
                        rows.velocities[i][j],
                        rows.positions[i + 1][j],
                        rows.velocities[i + 1][j],
                        t1 - t0,
                    );
                    let e = c.extremes();
                    if let Some(what) = beyond(&e, e.a, &b, t0) {
                        return Err(GaitError::Limit(format!(
                            "row {}, joint {}: {what}",
                            i + 1,
                            rows.names[j]
                        )));
                    }
                }
            }
        }
        Ok(())
    }
}

impl Body for ArchieGait {
    /// Every row's point masses placed as the joints would put them (the pelvis placed as for
    /// the joint rows), their accelerations by second differences
    /// (one-sided, second order, at the end rows), and the whole body's ZMP
    /// p = Σ m (x (z̈ + g) − z ẍ) / Σ m (z̈ + g) (the links' own rotational inertia left out),
    /// less the cart-table ZMP, taken linearly between rows to the samples. The rows here are
    /// 20 ms apart ([`OFFSET_PERIOD`]). Rows stop at the first the legs cannot take (the
    /// joints' check refuses it), zero after.
    fn zmp_offset(&self, pat: &Pattern, g: f64) -> Vec<P2> {
        let mut out = vec![[0.0; 2]; pat.samples.len()];
        let stride = ((OFFSET_PERIOD / pat.dt).round() as usize).max(1);
        let (mut near, mut offset, mut seen) = (REST, self.offset, Vec::with_capacity(5));
        let mut rows: Vec<(usize, [(f64, V3); 7])> = Vec::new();
        for k in (0..pat.samples.len()).step_by(stride) {
            let Ok((pelvis, q, points)) = self.place_row(pat, k, &near, &mut offset, &mut seen)
            else {
                break;
            };
            near = q;
            rows.push((k, self.point_masses(&pelvis, &points)));
        }
        let n = rows.len();
        if n < 4 {
            return out;
        }
        let mut at_rows = Vec::with_capacity(n);
        // Second differences, second-order one-sided at the ends (the rows are evenly
        // spaced): a pattern that starts mid-walk starts in motion.
        let h = pat.samples[rows[1].0].t - pat.samples[rows[0].0].t;
        let at = |r: usize, m: usize, d: usize| rows[r].1[m].1[d];
        for (i, (k, masses)) in rows.iter().enumerate() {
            let (mut num_x, mut num_y, mut den) = (0.0, 0.0, 0.0);
            for (m, &(mass, p)) in masses.iter().enumerate() {
                let acc: V3 = std::array::from_fn(|d| {
                    let v = |r: usize| at(r, m, d);
                    if i == 0 {
                        (2.0 * v(0) - 5.0 * v(1) + 4.0 * v(2) - v(3)) / (h * h)
                    } else if i + 1 == n {
                        (2.0 * v(n - 1) - 5.0 * v(n - 2) + 4.0 * v(n - 3) - v(n - 4)) / (h * h)
                    } else {
                        (v(i - 1) - 2.0 * v(i) + v(i + 1)) / (h * h)
                    }
                });
                let w = mass * (acc[2] + g);
                num_x += p[0] * w - mass * p[2] * acc[0];
                num_y += p[1] * w - mass * p[2] * acc[1];
                den += w;
            }
            let cart = pat.samples[*k].zmp;
            at_rows.push([num_x / den - cart[0], num_y / den - cart[1]]);
        }
        let last = rows[n - 1].0;
        for (k, o) in out.iter_mut().enumerate().take(last + 1) {
            let (i, f) = (k / stride, (k % stride) as f64 / stride as f64);
            let b = at_rows[(i + 1).min(n - 1)];
            *o = std::array::from_fn(|d| at_rows[i][d] * (1.0 - f) + b[d] * f);
        }
        out
    }
}
