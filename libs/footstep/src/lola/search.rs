//! The search: the suggestions around the desired step, the problem (heuristic, costs, the
//! pre-planner's coupling), the weighted A* passes and the anytime loop.

use std::time::Instant;

use super::preplan::{self, preplan, Reduced, Way};
use crate::astar::{self, End, Reached, Space, Successor};
use crate::geom::{v2, wrap, V2};
use crate::grid::{Grid, GRID_DETOUR};
use crate::plan::{anytime, anytime_passes, Foot, PassEnd, Plan, Stats, Status};

use super::settings::{Mode, PrePlanner, Settings};
use super::world::{Thing, World};

/// A node of the search: the stance foot and the other, where it stood before it swung.
#[derive(Debug, Clone, Copy)]
struct Node {
    stance: Foot,
    other: Foot,
}

/// The offsets of the suggestions: (advance, width, turn) steps of (0.10 m, 0.05 m, 0.1 rad).
fn suggestions(reduced: bool) -> Vec<(f64, f64, f64)> {
    let mut pos: Vec<(f64, f64)> = Vec::new();
    for i in -1..=1 {
        for j in -1..=1 {
            pos.push((i as f64, j as f64));
        }
    }
    let outer = [
        (2.0, 0.0),
        (-2.0, 0.0),
        (0.0, 2.0),
        (0.0, -2.0),
        (2.0, 2.0),
        (2.0, -2.0),
        (-2.0, 2.0),
        (-2.0, -2.0),
    ];
    let mut out = Vec::new();
    if reduced {
        for &(i, j) in &pos {
            for t in [-1.0, 0.0, 1.0] {
                out.push((i * 0.10, j * 0.05, t * 0.1));
            }
        }
        // The outer ring without the step straight back, at the desired turn.
        for &(i, j) in outer.iter().filter(|&&(i, j)| !(i < 0.0 && j == 0.0)) {
            out.push((i * 0.10, j * 0.05, 0.0));
        }
    } else {
        pos.extend(outer);
        for &(i, j) in &pos {
            for t in [-2.0, -1.0, 0.0, 1.0, 2.0] {
                out.push((i * 0.10, j * 0.05, t * 0.1));
            }
        }
    }
    out
}

/// Step limits: advance, extra width (outwards), turn.
const LX: (f64, f64) = (-0.2, 0.5);
const LY: (f64, f64) = (-0.05, 0.25);
const PHI: f64 = 0.4;

/// The swing foot's pose after a step of (advance, extra width outwards, turn
/// counter-clockwise) from `stance`: along a circular path, the turn spread over the step.
pub fn place(stance: &Foot, step: (f64, f64, f64), width: f64) -> Foot {
    let (lx, ly, phi) = step;
    let side = if stance.left { -1.0 } else { 1.0 };
    let h = stance.yaw + phi / 2.0;
    let (d, s) = (V2::polar(h), v2(-h.sin(), h.cos()));
    Foot {
        p: stance.p + d * lx + s * (side * (width + ly)),
        z: stance.z,
        yaw: wrap(stance.yaw + phi),
        left: !stance.left,
    }
}

/// The mid-stance point of a foot: half the nominal width towards where the other foot
/// stands.
pub fn mid(f: &Foot, width: f64) -> V2 {
    let side = if f.left { -1.0 } else { 1.0 };
    f.p + v2(-f.yaw.sin(), f.yaw.cos()) * (side * width / 2.0)
}

/// Within this distance of the goal (m) a step straight onto the goal pose is tried.
const GOAL_STEP: f64 = 0.5;

/// The search's heuristic on open floor (no pre-planner coupling): the distance from the
/// feet's midpoint to the goal, with the heading error weighted by `w_theta`, as one
/// Euclidean length (the thesis's Eq. 4.16). The coupled heuristics take the larger of this
/// and the pre-planner's way.
pub fn open_floor_h(s: &Settings, f: &Foot, goal: V2, goal_yaw: f64) -> f64 {
    let m = mid(f, s.robot.width);
    let dth = s.w_theta * wrap(f.yaw - goal_yaw);
    (m.dist(goal).powi(2) + dth * dth).sqrt()
}

struct Problem<'a> {
    world: &'a World,
    s: &'a Settings,
    goal: V2,
    goal_yaw: f64,
    steps: Vec<(f64, f64, f64)>,
    field: Option<Field>,
    way: Option<Way>,
    /// Whether a step onto the goal is tried near it.
    snap: bool,
    /// When the search's budget runs out.
    deadline: Instant,
}

/// The improved pre-planner's distance fields, on one grid.
struct Field {
    grid: Grid,
    /// Distances to the goal around the tall obstacles grown by the margin (the heuristic).
    dist: Vec<f64>,
    /// The same around them grown by the heading margin (the desired heading where there is
    /// room), when that margin is wider and the heading is coupled.
    heading: Option<Vec<f64>>,
    /// Distances from the centre's way (the corridor), if asked.
    corridor: Option<Vec<f64>>,
}

impl Problem<'_> {
    fn h(&self, f: &Foot) -> f64 {
        let m = mid(f, self.s.robot.width);
        let dth = self.s.w_theta * wrap(f.yaw - self.goal_yaw);
        let e = open_floor_h(self.s, f, self.goal, self.goal_yaw);
        if let (Some(w), true) = (&self.way, self.s.couple_heuristic) {
            // Coupling 1 (Eq. 4.18, w⊥ = 0): the way's length from the projection on.
            let (l_g, _, _) = w.project(m);
            return (l_g * l_g + dth * dth).sqrt();
        }
        match &self.field {
            Some(Field {
                grid: g, dist: d, ..
            }) if self.s.couple_heuristic => match g.cell(m) {
                Some((i, j)) if d[j * g.nx + i].is_finite() => {
                    let way = d[j * g.nx + i] / GRID_DETOUR - 1.5 * g.res;
                    e.max((way.max(0.0).powi(2) + dth * dth).sqrt())
                }
                _ => e,
            },
            _ => e,
        }
    }

    /// The desired turn from `f`: towards the pre-planner's way (coupling 3), else none.
    fn desired_turn(&self, f: &Foot) -> f64 {
        let d = self.s.desired.2;
        if !self.s.couple_heading {
            return d;
        }
        let m = mid(f, self.s.robot.width);
        if (self.field.is_some() || self.way.is_some()) && m.dist(self.goal) < 0.5 {
            return (wrap(self.goal_yaw - f.yaw)).clamp(-0.2, 0.2);
        }
        if let Some(w) = &self.way {
            // The way's tangent at the projection.
            let (_, tangent, _) = w.project(m);
            return wrap(tangent - f.yaw).clamp(-0.2, 0.2);
        }
        let Some(Field {
            grid: g,
            dist,
            heading,
            ..
        }) = &self.field
        else {
            return d;
        };
        // Wide of the obstacles where there is room and that way is not much longer, else
        // along the heuristic's way.
        let field = match (heading, g.cell(m)) {
            (Some(wide), Some((i, j)))
                if wide[j * g.nx + i] <= dist[j * g.nx + i] * 1.25 + 0.25 =>
            {
                wide
            }
            _ => dist,
        };
        match g.descent(field, m, 0.6) {
            Some(to) => wrap((to - m).angle() - f.yaw).clamp(-0.2, 0.2),
            None => d,
        }
    }

    /// The steps from `n`: each new foot and the step's cost.
    fn steps(&self, n: &Node, stats: &mut Stats) -> Vec<(Foot, f64)> {
        let s = self.s;
        let (lx0, ly0, _) = s.desired;
        let phi0 = self.desired_turn(&n.stance);
        let mut out = Vec::new();
        for &(dx, dy, dp) in &self.steps {
            if let Some(step) = self.step(n, (lx0 + dx, ly0 + dy, phi0 + dp), phi0, stats) {
                out.push(step);
            }
        }
        // The step onto the goal, when one step can reach it (improved mode).
        if self.snap && mid(&n.stance, s.robot.width).dist(self.goal) < GOAL_STEP {
            let (left, right) = Foot::standing(self.goal, self.goal_yaw, s.robot.width);
            let to = if n.stance.left { right } else { left };
            if let Some(step) = self.step(n, unplace(&n.stance, &to, s.robot.width), phi0, stats) {
                out.push(step);
            }
        }
        out
    }

    /// The step (advance, width, turn) from `n`'s stance with its cost, if the robot can make it.
    fn step(
        &self,
        n: &Node,
        (lx, ly, phi): (f64, f64, f64),
        phi0: f64,
        stats: &mut Stats,
    ) -> Option<(Foot, f64)> {
        let s = self.s;
        let r = &s.robot;
        if !(LX.0..=LX.1).contains(&lx) || !(LY.0..=LY.1).contains(&ly) || phi.abs() > PHI {
            return None;
        }
        stats.generated += 1;
        let mut f = place(&n.stance, (lx, ly, phi), r.width);
        if let (
            Some(dmax),
            Some(Field {
                grid: g,
                corridor: Some(c),
                ..
            }),
        ) = (s.corridor, &self.field)
        {
            if g.cell(mid(&f, r.width))
                .is_none_or(|(i, j)| c[j * g.nx + i] > dmax)
            {
                return None;
            }
        }
        f.z = self.world.foothold(&f, r, stats)?;
        if (f.z - n.stance.z).abs() > r.max_step_height
            || self.world.swing(&n.other, &f, r, stats) > r.h_max
        {
            return None;
        }
        Some((f, step_cost(s, (lx, ly, phi), phi0)))
    }
}

/// The step (advance, width, turn) that [`place`] turns into the foot `to` from `stance`.
pub fn unplace(stance: &Foot, to: &Foot, width: f64) -> (f64, f64, f64) {
    let side = if stance.left { -1.0 } else { 1.0 };
    let phi = wrap(to.yaw - stance.yaw);
    let h = stance.yaw + phi / 2.0;
    let (d, s) = (V2::polar(h), v2(-h.sin(), h.cos()));
    let delta = to.p - stance.p;
    (delta.dot(d), side * delta.dot(s) - width, phi)
}

/// The cost of a step (Eq. 4.8): the desired step's weighted length plus k times the
/// weighted distance of the step from it, the desired turn being `desired_turn`.
pub fn step_cost(s: &Settings, step: (f64, f64, f64), desired_turn: f64) -> f64 {
    let (lx0, ly0, _) = s.desired;
    let (lx, ly, phi) = step;
    let c_des = (lx0 * lx0 + (s.w_theta * desired_turn).powi(2)).sqrt();
    let dev =
        ((lx - lx0).powi(2) + (ly - ly0).powi(2) + (s.w_theta * (phi - desired_turn)).powi(2))
            .sqrt();
    c_des + s.k * dev
}

/// The suggestions' offsets from the desired step (85, or the reduced 34).
pub fn suggestion_count(reduced: bool) -> usize {
    suggestions(reduced).len()
}

/// Steps in place from the start: the fallback when nothing better is found.
fn in_place(right: Foot, left: Foot) -> Vec<Foot> {
    vec![right, left, right, left, right]
}

/// Plans from the robot standing at `start` (feet side by side, the right one to swing first)
/// to the goal pose.
pub fn plan(
    start: V2,
    start_yaw: f64,
    goal: V2,
    goal_yaw: f64,
    world: &World,
    mode: Mode,
    s: &Settings,
) -> Plan {
    let (left, right) = Foot::standing(start, start_yaw, s.robot.width);
    plan_from(left, right, goal, goal_yaw, world, mode, s)
}

/// Plans from the stance foot `stance` with the other foot, `swing`, to step next, to the goal
/// pose. The plan's steps start with `swing` where it stands.
pub fn plan_from(
    stance: Foot,
    swing: Foot,
    goal: V2,
    goal_yaw: f64,
    world: &World,
    mode: Mode,
    s: &Settings,
) -> Plan {
    let t0 = Instant::now();
    let mut stats = Stats::default();
    let r = &s.robot;
    let (mut stance, mut swing) = (stance, swing);
    for f in [&mut stance, &mut swing] {
        match world.foothold(f, r, &mut stats) {
            Some(z) => f.z = z,
            None => {
                return Plan::failed(
                    Status::StartInCollision,
                    "a foot of the start is off the map, across an edge or on an obstacle",
                    stats,
                )
            }
        }
    }
    if !world.in_map(goal) {
        return Plan::failed(Status::GoalOutsideMap, "the goal is outside the map", stats);
    }
    let probe = Foot {
        p: goal,
        z: 0.0,
        yaw: goal_yaw,
        left: true,
    };
    if world.foothold(&probe, r, &mut stats).is_none() {
        return Plan::failed(
            Status::GoalInCollision,
            "no foot can stand at the goal",
            stats,
        );
    }
    let mut pr = problem(world, s, &stance, &swing, goal, goal_yaw, mode);
    stats.prepare = t0.elapsed();
    let t1 = Instant::now();
    pr.deadline = t1 + s.budget;
    let lattice = mode == Mode::Improved;
    let root = Node {
        stance,
        other: swing,
    };
    let mut passes = anytime_passes(lattice, s.scout, &s.weights, s.lattice);
    // Towards a horizon, cost alone does not rank plans: the first plan found stands, the
    // scouting pass's or, when that runs dry, the first fine pass's.
    if s.horizon.is_some() {
        passes.truncate(if lattice && s.scout.is_some() { 2 } else { 1 });
    }
    let start = Reached {
        state: root,
        g: 0.0,
        depth: 0,
        parent: None,
    };
    let mut best = (pr.h(&stance), vec![start], 0usize);
    let horizon = s.horizon.is_some();
    let (found, stopped) = anytime(&passes, &mut stats, t1, |w, cells, _, cap, stats| {
        let astar::Pass {
            end,
            reached,
            nearest,
        } = astar::pass(&pr, root, (w, cells), lattice, cap, best.0, stats);
        match end {
            End::Found(i, status) => {
                return PassEnd::Found {
                    cost: reached[i].g,
                    plan: (reached, i, status),
                    last: horizon,
                }
            }
            End::Exhausted | End::Stopped(_) => {}
        }
        // The node nearest the goal of a pass that found none (not the root).
        if let Some((h, i)) = nearest.filter(|&(_, i)| i != 0) {
            best = (h, reached, i);
        }
        match end {
            End::Stopped(why) => PassEnd::Stopped(why),
            _ => PassEnd::Exhausted,
        }
    });
    let found = found.map(|f| (f.plan.0, f.plan.1, f.plan.2, f.bound));
    let why = match (stopped, &found) {
        (Some(why), _) => why,
        (None, Some((_, _, status, _))) if *status != Status::Ok => "the horizon",
        _ => "no foothold sequence reaches the goal",
    };
    stats.search = t1.elapsed();
    let (nodes, last, status) = match found {
        Some((nodes, i, status, _)) => (nodes, i, status),
        // The deadline: the best partial plan (improved mode), or steps in place.
        None if lattice && best.2 != 0 => (best.1, best.2, Status::Partial),
        None => {
            let steps = in_place(swing, stance);
            return Plan {
                status: Status::Partial,
                detail: format!("{why}: stepping in place"),
                path: vec![(stance.p + swing.p) * 0.5],
                cost: 0.0,
                steps,
                stats,
                bound: None,
            };
        }
    };
    let mut feet = Vec::new();
    let mut at = Some(last);
    while let Some(i) = at {
        feet.push(nodes[i].state.stance);
        at = nodes[i].parent;
    }
    feet.push(swing);
    feet.reverse();
    let path = feet.iter().skip(1).map(|f| mid(f, r.width)).collect();
    Plan {
        status,
        detail: if status == Status::Ok {
            String::new()
        } else {
            why.to_string()
        },
        path,
        cost: nodes[last].g,
        steps: feet,
        stats,
        // No bound: the heuristic (the thesis's Eq. 4.16, the pre-planner's way coupled in)
        // is not a lower bound of the cost to go. A turning step swings the feet's midpoint
        // by half the stance width times the turn, which its cost does not count, and at the
        // goal's tolerance it is not zero (libs/footstep/tests/lola.rs measures both).
        bound: None,
    }
}

/// The search's problem for a search from `stance` and `swing` (with their heights) to the
/// goal pose: the pre-planner's way or distance fields, the suggestions.
fn problem<'a>(
    world: &'a World,
    s: &'a Settings,
    stance: &Foot,
    swing: &Foot,
    goal: V2,
    goal_yaw: f64,
    mode: Mode,
) -> Problem<'a> {
    let r = &s.robot;
    // The 2-D pre-planner: a distance field over the tall obstacles, grown by the margin.
    let coupled = s.couple_heuristic || s.couple_heading || s.corridor.is_some();
    // The thesis's pre-planner: its cheapest way by Eq. 4.17.
    let way = (coupled && s.preplanner == PrePlanner::Thesis)
        .then(|| {
            let (tall, small) = world.reduced(r.h_max);
            let reduced = Reduced {
                tall: &tall,
                small: &small,
                map: world.map,
            };
            let params = preplan::Params {
                l_d: s.desired.0,
                ..Default::default()
            };
            preplan(mid(stance, r.width), goal, &reduced, &params)
                .into_iter()
                .next()
        })
        .flatten();
    // A map too large for a grid has no field (the planner refuses such worlds first).
    let field = (coupled && s.preplanner == PrePlanner::Field)
        .then(|| Grid::flat(world.map.0, world.map.1, 0.05).ok())
        .flatten()
        .map(|mut g| {
            // The reduced map: the obstacles too tall to step over (surfaces' edges are not
            // obstacles here).
            let tall: Vec<&Thing> = world
                .things
                .iter()
                .filter(|t| !t.edge && t.top - t.aabb.mins.z.max(0.0) > r.h_max)
                .collect();
            // Cells within the heading margin hold 1, within the margin 2.
            let near = |p: V2, grow: f64| {
                tall.iter().any(|t| {
                    t.aabb.mins.x - grow <= p.x
                        && p.x <= t.aabb.maxs.x + grow
                        && t.aabb.mins.y - grow <= p.y
                        && p.y <= t.aabb.maxs.y + grow
                        && t.solid.footprint_distance(p) < grow
                })
            };
            let wide = s.couple_heading && s.heading_margin > s.margin;
            if wide {
                g.paint(|p| near(p, s.heading_margin), |_| 1.0);
            }
            g.paint(|p| near(p, s.margin), |_| 2.0);
            let d = g.distance_field(goal, |h| h < 2.0);
            let heading = wide.then(|| g.distance_field(goal, |h| h == 0.0));
            // Coupling 2: the distance from the way the robot's centre would take.
            // (None when the centre has no way: the corridor is then off.)
            let corridor = s.corridor.and_then(|_| {
                let way = g.way(&d, (stance.p + swing.p) * 0.5, f64::INFINITY);
                (!way.is_empty()).then(|| g.distance_from(&way, |_| true))
            });
            Field {
                grid: g,
                dist: d,
                heading,
                corridor,
            }
        });
    Problem {
        world,
        s,
        goal,
        goal_yaw,
        steps: suggestions(s.reduced),
        field,
        way,
        snap: mode == Mode::Improved,
        deadline: Instant::now() + s.budget,
    }
}

/// The search's heuristic and successors for a search from `stance` and `swing` to the goal
/// pose, exposed so that tests can check them against exhaustive searches.
pub struct Probe<'a>(Problem<'a>);

impl<'a> Probe<'a> {
    /// The probe of a search from `stance` and `swing` (their heights looked up) to the goal
    /// pose in `mode`; `None` when a foot of the start has no foothold.
    pub fn new(
        (stance, swing): (Foot, Foot),
        goal: V2,
        goal_yaw: f64,
        world: &'a World,
        mode: Mode,
        s: &'a Settings,
    ) -> Option<Probe<'a>> {
        let mut stats = Stats::default();
        let (mut stance, mut swing) = (stance, swing);
        for f in [&mut stance, &mut swing] {
            f.z = world.foothold(f, &s.robot, &mut stats)?;
        }
        Some(Probe(problem(
            world, s, &stance, &swing, goal, goal_yaw, mode,
        )))
    }

    /// The heuristic of the node whose stance foot is `f`.
    pub fn h(&self, f: &Foot) -> f64 {
        self.0.h(f)
    }

    /// The feet the search steps to from `stance` (the other foot at `other`), each with the
    /// step's cost.
    pub fn successors(&self, stance: Foot, other: Foot) -> Vec<(Foot, f64)> {
        let n = Node { stance, other };
        self.0.steps(&n, &mut Stats::default())
    }

    /// Whether a node whose stance foot is `f` is at the goal (within the tolerances).
    pub fn at_goal(&self, f: &Foot) -> bool {
        let s = self.0.s;
        mid(f, s.robot.width).dist(self.0.goal) < s.tolerance.0
            && wrap(f.yaw - self.0.goal_yaw).abs() < s.tolerance.1
    }
}

impl Space for Problem<'_> {
    type State = Node;
    type Key = (i64, i64, i64, bool);
    type Goal = Status;

    fn h(&self, n: &Node) -> f64 {
        Problem::h(self, &n.stance)
    }

    fn key(&self, n: &Node, cells: (f64, f64)) -> Self::Key {
        let m = mid(&n.stance, self.s.robot.width);
        (
            (m.x / cells.0).round() as i64,
            (m.y / cells.0).round() as i64,
            (wrap(n.stance.yaw) / cells.1.to_radians()).round() as i64,
            n.stance.left,
        )
    }

    /// At the goal (within the tolerances), or at the horizon.
    fn goal(&self, n: &Node, depth: usize) -> Option<Status> {
        let (s, f) = (self.s, &n.stance);
        if mid(f, s.robot.width).dist(self.goal) < s.tolerance.0
            && wrap(f.yaw - self.goal_yaw).abs() < s.tolerance.1
        {
            return Some(Status::Ok);
        }
        s.horizon
            .is_some_and(|k| depth >= k)
            .then_some(Status::Partial)
    }

    fn stop(&self, expansions: u64) -> Option<&'static str> {
        if expansions >= self.s.max_expansions {
            return Some("the expansion cap was reached");
        }
        if expansions.is_multiple_of(16) && self.s.cancel.is_cancelled() {
            return Some("cancelled");
        }
        if expansions.is_multiple_of(16) && Instant::now() > self.deadline {
            return Some("the time budget ran out");
        }
        None
    }

    fn successors(&self, n: &Node, _h: f64, stats: &mut Stats) -> Vec<Successor<Node>> {
        self.steps(n, stats)
            .into_iter()
            .map(|(f, c)| Successor {
                steps: vec![(
                    Node {
                        stance: f,
                        other: n.stance,
                    },
                    c,
                )],
                h: None,
            })
            .collect()
    }
}
