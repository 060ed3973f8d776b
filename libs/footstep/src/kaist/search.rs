//! The KAIST footstep search (seed 004, §B.1, §B.4) over footholds (x, y, yaw, side) on an
//! elevation grid.
//!
//! - faithful ([`Mode::Thesis`]): a tree search (no duplicate detection) capped at 2000
//!   expansions, the adaptive action set (per subset, the feasible candidate of least cost of
//!   transport; the full set within 0.6 m of the goal), the thesis's heuristic (Eq. 14), and
//!   optionally its local-minimum penalty (Eq. 15, [`Heuristic::EuclidAnglePenalty`], its
//!   geometry as the notes infer it). Without the penalty the thesis's planner fails at the cap
//!   behind a wall, and so does this one; with this penalty it still does.
//! - improved ([`Mode::Improved`]): A* with duplicate detection on a lattice (0.05 m, 5°,
//!   side) and a closed set, the same actions, an admissible energy bound
//!   ([`kaist::h_improved`]) also taken along the 2-D way around tall cells
//!   ([`Heuristic::Dijkstra2d`]), and an anytime schedule: a scouting pass of weight 2 on a
//!   coarse lattice (half the longest step, 22.5°) for a first plan at once (its heuristic also
//!   charges the turn towards the 2-D way, and it walks straight in strides of up to four
//!   steps where the heuristic sees the way clear: [`Settings::strides`]), then weighted A* with
//!   a decreasing weight (1.5, 1.2, 1) on the fine one, each pass pruned by the best plan so
//!   far, until the budget runs out. The plan reports the weight of the last finished pass as
//!   its bound (none where the 2-D field cannot be a bound: see [`Heuristic::Dijkstra2d`]).
//!   With no plan at the budget, the node nearest the goal by the heuristic comes back as a
//!   partial plan.
//!
//! Feasibility is the thesis's, on the grid (the notes' R-F1, R-F2): a foothold is refused when
//! a cell under the foot is unknown or more than `step_height` above the stance foot; a step is
//! refused when a cell of either swing ellipse (stance to new foot, grown by the sway; old to
//! new foot position) is more than `body_height` above the stance foot.

use std::cell::{Cell, RefCell};
use std::time::{Duration, Instant};

use crate::archie::steps::FOOT;
use crate::astar::{self, trace, End, Reached, Space, Successor};
use crate::geom::{v2, wrap, V2};
use crate::grid::{Grid, GridError, GRID_DETOUR};
use crate::kaist::{self, Action, CostParams, Subset};
use crate::plan::{anytime, anytime_passes, Cancel, Foot, PassEnd, Plan, Stats, Status};
use crate::scene::Scene;

/// Which planner.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// The thesis's tree search and heuristic.
    Thesis,
    /// A* on a lattice with an admissible heuristic, anytime.
    Improved,
}

/// The heuristic (the notes' C.5 names).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Heuristic {
    /// None: uniform-cost search (exact, slow; for tests).
    Zero,
    /// α·m·g·d (Eq. 12).
    Euclid,
    /// Eq. 12 plus the turn, F·Δθ²/N (Eq. 14): the thesis's.
    EuclidAngle,
    /// Eq. 14, and the thesis's local-minimum penalty (Eq. 15) where a tall obstacle lies
    /// ahead (the search's `penalised`). Inadmissible by design.
    EuclidAnglePenalty,
    /// The admissible energy bound ([`kaist::h_improved`]).
    EnergyBound,
    /// The energy bound, also taken over the length of the 2-D way around tall cells (R-S3).
    /// Every node's centre is the middle of a stance-to-swing ellipse, so it keeps clear of
    /// tall cells, as the field's way does; the field is discounted for its grid. A lower
    /// bound up to the corners the straight moves between centres can cut, which the
    /// discount covers.
    Dijkstra2d,
}

/// How candidates become successors (R-A3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ActionSet {
    /// Every feasible candidate.
    FixedFull,
    /// The farthest candidate of each subset, if feasible.
    FixedSmall,
    /// Per subset, the farthest feasible candidate.
    AdaptiveFarthest,
    /// Per subset, the feasible candidate of least cost of transport (the thesis's).
    AdaptiveMinCot,
}

/// The feasibility thresholds (R-F1, R-F2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feasibility {
    /// Highest cell under a foot above the stance foot, m (the thesis's 5 cm).
    pub step_height: f64,
    /// Highest cell in a swing ellipse above the stance foot, m (not in the thesis: 0.15).
    pub body_height: f64,
    /// Growth of the stance-to-swing ellipse along its axis for the lateral sway, m.
    pub sway: f64,
}

impl Default for Feasibility {
    fn default() -> Self {
        Feasibility {
            step_height: 0.05,
            body_height: 0.15,
            sway: 0.05,
        }
    }
}

/// Settings of the search.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Robot and cost.
    pub cost: CostParams,
    /// Goal tolerance on the robot's centre, m.
    pub tolerance: f64,
    /// Within this of the goal, every candidate is expanded, m.
    pub full_set_radius: f64,
    /// Expansion cap (over all passes).
    pub max_expansions: u64,
    /// Time budget (improved mode).
    pub budget: Duration,
    /// Set to stop the search at once (it answers as at its budget).
    pub cancel: Cancel,
    /// The heuristic.
    pub heuristic: Heuristic,
    /// How candidates become successors.
    pub actions: ActionSet,
    /// Feasibility thresholds.
    pub feasibility: Feasibility,
    /// The weights of the passes (improved mode; the last should be 1).
    pub weights: Vec<f64>,
    /// Lattice cell for duplicate detection: position (m) and yaw (degrees).
    pub lattice: (f64, f64),
    /// A coarser lattice (position, yaw degrees) and a weight for a first, scouting pass
    /// (improved mode): its plan comes quickly, without a bound, and prunes the passes after
    /// it.
    pub scout: Option<((f64, f64), f64)>,
    /// The scouting pass also offers the straight step repeated up to this many times as one
    /// successor (a walk whose inner feet are steps of the plan but are never expanded); 1 for
    /// none.
    pub strides: usize,
}

impl Settings {
    /// The defaults for `mode` with `cost` (notes C.1: tolerance 0.1 m, full set within 0.6 m;
    /// the thesis's cap of 2000 and heuristic; in improved mode 200 ms, 200 000 expansions,
    /// the 2-D heuristic, a scouting pass of weight 2 on a lattice of half the longest step and
    /// 22.5°, then the weights 1.5, 1.2, 1 on a lattice of 0.05 m and 5°).
    pub fn new(mode: Mode, cost: CostParams) -> Settings {
        let thesis = mode == Mode::Thesis;
        Settings {
            cost,
            tolerance: 0.10,
            full_set_radius: 0.6,
            max_expansions: if thesis { 2000 } else { 200_000 },
            budget: Duration::from_millis(if thesis { 10_000 } else { 200 }),
            cancel: Cancel::default(),
            heuristic: if thesis {
                Heuristic::EuclidAngle
            } else {
                Heuristic::Dijkstra2d
            },
            actions: ActionSet::AdaptiveMinCot,
            feasibility: Feasibility::default(),
            weights: if thesis {
                vec![1.0]
            } else {
                vec![1.5, 1.2, 1.0]
            },
            lattice: (0.05, 5.0),
            scout: (!thesis).then_some(((cost.l_max / 2.0, 22.5), 2.0)),
            strides: if thesis { 1 } else { 4 },
        }
    }
}

/// The world the search sees: an elevation grid.
#[derive(Debug, Clone)]
pub struct World {
    /// The grid.
    pub grid: Grid,
}

impl World {
    /// The grid of a scene.
    pub fn of(scene: &Scene) -> Result<World, GridError> {
        Ok(World {
            grid: Grid::of_scene(scene)?,
        })
    }

    /// Flat ground over `x` × `y` (0.05 m cells).
    pub fn flat(x: [f64; 2], y: [f64; 2]) -> Result<World, GridError> {
        Ok(World {
            grid: Grid::flat(x, y, 0.05)?,
        })
    }

    /// The height a foot at `f` rests on, if it may stand there with the stance foot at
    /// `reference` (R-F1): every cell under it known and at most `step_height` above.
    pub fn foothold(&self, f: &Foot, reference: f64, feas: &Feasibility) -> Option<f64> {
        // `f64::max` would drop a NaN (unknown) cell: they are refused first.
        let under = self.grid.max_in_rect(f.p, f.yaw, FOOT, 0.0)?;
        let centre = self.grid.height(f.p);
        if under.is_nan() || centre.is_nan() {
            return None;
        }
        let top = under.max(centre);
        (top.is_finite() && top <= reference + feas.step_height).then_some(top)
    }

    /// True when the foot `f` rests where it may (the check of every step of a plan).
    pub fn foot_clear(&self, f: &Foot, feas: &Feasibility) -> bool {
        self.foothold(f, f.z, feas)
            .is_some_and(|z| (z - f.z).abs() < 1e-9)
    }

    /// R-F2: no cell of the two swing ellipses above `body_height` over the stance foot.
    pub fn body_clear(&self, stance: &Foot, old: V2, new: V2, feas: &Feasibility) -> bool {
        let limit = stance.z + feas.body_height;
        // NaN (unknown) compares false: refused.
        let ok = |top: Option<f64>| top.is_some_and(|h| h <= limit);
        ok(self
            .grid
            .max_in_ellipse(stance.p, new, feas.sway, FOOT.0 / 2.0))
            && ok(self
                .grid
                .max_in_ellipse(old, new, FOOT.0 / 2.0, FOOT.1 / 2.0))
    }
}

/// A node of the search: the stance foot and the other, where it stood before it swung.
#[derive(Debug, Clone, Copy)]
struct Node {
    stance: Foot,
    other: Foot,
}

impl Node {
    fn centre(&self) -> V2 {
        (self.stance.p + self.other.p) * 0.5
    }

    fn heading(&self) -> f64 {
        self.stance.yaw + wrap(self.other.yaw - self.stance.yaw) / 2.0
    }
}

/// Places the swing foot by `a` from `stance` (actions are for a left stance; mirrored for a
/// right one). Its height is the stance's until the grid is asked.
pub fn apply(stance: &Foot, a: &Action) -> Foot {
    let (dy, dt) = if stance.left {
        (a.dy, a.dtheta)
    } else {
        (-a.dy, -a.dtheta)
    };
    let dir = V2::polar(stance.yaw);
    let side = v2(-dir.y, dir.x);
    Foot {
        p: stance.p + dir * a.dx + side * dy,
        z: stance.z,
        yaw: wrap(stance.yaw + dt),
        left: !stance.left,
    }
}

/// What a step achieves, for the adaptive choice: metres of advance, radians of turn on the
/// spot, or metres sideways.
fn achieved(a: &Action, p: &CostParams) -> f64 {
    if a.dx > 0.0 {
        a.dx
    } else if a.dtheta != 0.0 {
        a.dtheta.abs()
    } else {
        (a.dy.abs() - p.w_nom).max(1e-6)
    }
}

/// The actions in the order the choice takes them: per subset, least energy per unit of what
/// the step achieves first (the cost of transport per metre of advance; per radian for a turn
/// on the spot, per metre sideways for a sidestep: the thesis leaves the steps without advance
/// open, and least energy alone would always pick the smallest turn), or the farthest first.
fn ordered_actions(p: &CostParams, set: ActionSet) -> Vec<Action> {
    let mut acts = kaist::actions(p);
    match set {
        ActionSet::AdaptiveMinCot | ActionSet::FixedFull => {
            let key = |a: &Action| a.energy_mg(p) / achieved(a, p);
            acts.sort_by(|a, b| key(a).total_cmp(&key(b)));
        }
        ActionSet::AdaptiveFarthest | ActionSet::FixedSmall => {
            acts.sort_by(|a, b| achieved(b, p).total_cmp(&achieved(a, p)));
        }
    }
    acts
}

/// Everything one plan's passes share.
struct Problem<'a> {
    world: &'a World,
    s: &'a Settings,
    acts: Vec<Action>,
    alpha: f64,
    goal: V2,
    field: Option<Vec<f64>>,
    deadline: Instant,
    /// In the scouting pass, which needs no bound, the heuristic also charges the turn towards
    /// the 2-D way.
    scouting: Cell<bool>,
    /// Up to how many steps a straight walk takes as one successor (1: none).
    strides: Cell<usize>,
    /// The 2-D way's direction per cell (NaN: not looked up yet; infinite: none).
    bearings: RefCell<Vec<f64>>,
}

impl<'a> Problem<'a> {
    /// A problem on the fine lattice for looking at single nodes (their heuristic, their
    /// successors) outside a search.
    fn probe(world: &'a World, s: &'a Settings, goal: V2, field: Option<Vec<f64>>) -> Problem<'a> {
        let acts = ordered_actions(&s.cost, s.actions);
        Problem {
            world,
            s,
            alpha: kaist::alpha(&s.cost, &acts),
            acts,
            goal,
            field,
            deadline: Instant::now(),
            scouting: Cell::new(false),
            strides: Cell::new(1),
            bearings: RefCell::new(Vec::new()),
        }
    }

    /// The heuristic of `n`, in energy units.
    fn h(&self, n: &Node) -> f64 {
        let p = &self.s.cost;
        let c = n.centre();
        let (d, bearing) = (c.dist(self.goal), (self.goal - c).angle());
        let (ds, bs) = (n.stance.p.dist(self.goal), (self.goal - n.stance.p).angle());
        let yaw = n.stance.yaw;
        let tol = self.s.tolerance;
        p.mg()
            * match self.s.heuristic {
                Heuristic::Zero => 0.0,
                Heuristic::Euclid => self.alpha * d,
                Heuristic::EuclidAngle => kaist::h_thesis(p, self.alpha, d, n.heading(), bearing),
                Heuristic::EuclidAnglePenalty => self
                    .penalised(n)
                    .unwrap_or_else(|| kaist::h_thesis(p, self.alpha, d, n.heading(), bearing)),
                Heuristic::EnergyBound => kaist::h_improved(p, ds, bs, yaw, d, tol),
                Heuristic::Dijkstra2d => {
                    let e = kaist::h_improved(p, ds, bs, yaw, d, tol);
                    match self.geodesic(n) {
                        // No direction: the best way round may leave either side. The
                        // scouting pass takes the way's.
                        Some(dg) => {
                            let towards = match self.scouting.get() {
                                true => self.way_bearing(c).unwrap_or(yaw),
                                false => yaw,
                            };
                            e.max(kaist::h_improved(p, dg, towards, yaw, d, tol))
                        }
                        None => e,
                    }
                }
            }
    }

    /// The direction of the 2-D way from the cell of `c`: towards where it has come half a
    /// metre nearer the goal.
    fn way_bearing(&self, c: V2) -> Option<f64> {
        let g = &self.world.grid;
        let f = self.field.as_ref()?;
        let (i, j) = g.cell(c)?;
        let k = j * g.nx + i;
        let mut memo = self.bearings.borrow_mut();
        if memo.is_empty() {
            *memo = vec![f64::NAN; g.nx * g.ny];
        }
        if memo[k].is_nan() {
            let from = g.centre(i, j);
            memo[k] = g
                .descent(f, from, 0.5)
                .map_or(f64::INFINITY, |to| (to - from).angle());
        }
        memo[k].is_finite().then_some(memo[k])
    }

    /// A lower bound of the distance from the stance foot of `n` to the goal along any way
    /// its steps can take: the distance field at the robot's centre (which keeps clear of tall
    /// cells, as the field's way does), discounted for the grid (16-neighbour moves overstate
    /// a straight line by up to 2.75 %; the cell adds up to 1.5 cells of offset), less the half
    /// of the feet's separation between the centre and the stance foot.
    fn geodesic(&self, n: &Node) -> Option<f64> {
        let g = &self.world.grid;
        let f = self.field.as_ref()?;
        let (i, j) = g.cell(n.centre())?;
        let d = f[j * g.nx + i];
        d.is_finite()
            .then(|| (d / GRID_DETOUR - 1.5 * g.res - n.stance.p.dist(n.other.p) / 2.0).max(0.0))
    }

    /// The thesis's local-minimum penalty (§2.4, Eq. 15), over m·g, when a tall obstacle lies
    /// ahead of `n`: α·(d₂ + d₃) + F·θ₂²/N₂ + F·θ₃²/N₃, the way to the goal through a point
    /// beside the obstacle. The thesis's figures of it are lost; as the notes infer it: the
    /// look-ahead follows the heading for [`PENALTY_LOOK`] with the body's width (0.5 m); the
    /// detour point is the nearer side of the obstacle, half the body's width past its edge;
    /// a step on the spot is not penalised (the thesis gives those steps a smaller penalty).
    /// `None` when nothing is ahead, or after a step on the spot.
    fn penalised(&self, n: &Node) -> Option<f64> {
        let p = &self.s.cost;
        let g = &self.world.grid;
        let c = n.centre();
        let dir = V2::polar(n.heading());
        let side = v2(-dir.y, dir.x);
        let limit = n.stance.z + self.s.feasibility.body_height;
        let tall = |q: V2| g.height(q) > limit;
        let half = 0.25;
        let step = g.res;
        // The first tall cell ahead within the body's width.
        let hit = (1..=(PENALTY_LOOK / step) as usize).find_map(|k| {
            let t = k as f64 * step;
            let at = c + dir * t;
            [-half, 0.0, half]
                .iter()
                .any(|&o| tall(at + side * o))
                .then_some(t)
        })?;
        if c.dist(self.goal) <= hit {
            return None;
        }
        // The obstacle's extent across the heading at the hit, each way.
        let at = c + dir * (hit + step);
        let reach = |sgn: f64| {
            (0..=(3.0 / step) as usize)
                .map(|k| k as f64 * step)
                .find(|&o| !tall(at + side * (sgn * o)))
        };
        let detour = [1.0, -1.0]
            .iter()
            .filter_map(|&sgn| reach(sgn).map(|o| at + side * (sgn * (o + half))))
            .min_by(|a, b| {
                (c.dist(*a) + a.dist(self.goal)).total_cmp(&(c.dist(*b) + b.dist(self.goal)))
            })?;
        let turn = |from: f64, to: f64| {
            let t = wrap(to - from).abs();
            p.f * t * t / (t / p.yaw_max).ceil().max(1.0)
        };
        let (b2, b3) = ((detour - c).angle(), (self.goal - detour).angle());
        let h = self.alpha * (c.dist(detour) + detour.dist(self.goal))
            + turn(n.heading(), b2)
            + turn(b2, b3);
        // A step on the spot puts the foot beside the other, along the other's heading.
        let on_the_spot = n.stance.p.dist(n.other.p) < p.w_max + 1e-9
            && (n.stance.p - n.other.p).dot(V2::polar(n.other.yaw)).abs() < 1e-9;
        // The thesis gives steps on the spot a smaller penalty: taken as none.
        if on_the_spot {
            return None;
        }
        Some(h)
    }

    /// The steps from `n`: each new foot, the step's energy and its action.
    fn steps(&self, n: &Node, stats: &mut Stats) -> Vec<(Foot, f64, Action)> {
        let s = self.s;
        let p = &s.cost;
        let near = n.centre().dist(self.goal) <= s.full_set_radius;
        let full =
            s.actions == ActionSet::FixedFull || (near && s.actions != ActionSet::FixedSmall);
        let mut out = Vec::new();
        let mut tried: Vec<Subset> = Vec::new();
        let mut taken: Vec<Subset> = Vec::new();
        for a in &self.acts {
            if !full {
                if taken.contains(&a.subset) {
                    continue;
                }
                if s.actions == ActionSet::FixedSmall && tried.contains(&a.subset) {
                    continue;
                }
                tried.push(a.subset);
            }
            stats.generated += 1;
            let Some(f) = self.land(&n.stance, &n.other, apply(&n.stance, a), stats) else {
                continue;
            };
            out.push((f, a.energy_mg(p) * p.mg(), *a));
            if !full {
                taken.push(a.subset);
            }
        }
        out
    }

    /// The foot `f` (placed from `stance`, the other foot at `other`) at the height it rests
    /// on, if it may stand there and the step keeps the body clear (R-F1, R-F2).
    fn land(&self, stance: &Foot, other: &Foot, mut f: Foot, stats: &mut Stats) -> Option<Foot> {
        let feas = &self.s.feasibility;
        stats.collision_queries += 1;
        f.z = self.world.foothold(&f, stance.z, feas)?;
        self.world
            .body_clear(stance, other.p, f.p, feas)
            .then_some(f)
    }

    /// The straight step `a` (taken from `n` to `first`) repeated while the robot can and
    /// comes nearer the goal, up to `strides` steps in all and until it is at the goal: the
    /// feet after `first` with their energies (empty when not one more step is possible).
    fn walk(
        &self,
        first: &Node,
        h_first: f64,
        a: &Action,
        strides: usize,
        stats: &mut Stats,
    ) -> (Vec<(Foot, f64)>, f64) {
        let s = self.s;
        let c = a.energy_mg(&s.cost) * s.cost.mg();
        let mut out = Vec::new();
        let (mut at, mut h_at) = (*first, h_first);
        while out.len() + 1 < strides && at.centre().dist(self.goal) >= s.tolerance {
            // Cheap tests first: nearer the goal, down the heuristic; then the ground.
            let next = Node {
                stance: apply(&at.stance, a),
                other: at.stance,
            };
            stats.generated += 1;
            if next.centre().dist(self.goal) >= at.centre().dist(self.goal) {
                break;
            }
            let h_next = self.h(&next);
            let near = at.centre().dist(self.goal) <= s.full_set_radius;
            if !near && h_next > h_at - WALK_FOLLOWS * c {
                break;
            }
            let Some(f) = self.land(&at.stance, &at.other, next.stance, stats) else {
                break;
            };
            out.push((f, c));
            (at, h_at) = (Node { stance: f, ..next }, h_next);
        }
        (out, h_at)
    }
}

/// A walk goes on only while each step brings the robot nearer the goal and, outside the full
/// set's radius, lowers the heuristic by at least this share of its energy: where the
/// heuristic sees no obstacle in the way.
const WALK_FOLLOWS: f64 = 0.9;

/// How far ahead the local-minimum penalty looks, m (the thesis does not say).
pub const PENALTY_LOOK: f64 = 1.0;

impl Space for Problem<'_> {
    type State = Node;
    type Key = (i64, i64, i64, bool);
    type Goal = ();

    fn h(&self, n: &Node) -> f64 {
        Problem::h(self, n)
    }

    fn key(&self, n: &Node, (cell, yaw_cell): (f64, f64)) -> Self::Key {
        let (f, yaw_cell) = (&n.stance, yaw_cell.to_radians());
        (
            (f.p.x / cell).round() as i64,
            (f.p.y / cell).round() as i64,
            (wrap(f.yaw) / yaw_cell).round() as i64,
            f.left,
        )
    }

    fn goal(&self, n: &Node, _depth: usize) -> Option<()> {
        (n.centre().dist(self.goal) < self.s.tolerance).then_some(())
    }

    fn stop(&self, expansions: u64) -> Option<&'static str> {
        if expansions >= self.s.max_expansions {
            return Some("the expansion cap was reached");
        }
        if expansions.is_multiple_of(64) {
            if self.s.cancel.is_cancelled() {
                return Some("cancelled");
            }
            if Instant::now() > self.deadline {
                return Some("the time budget ran out");
            }
        }
        None
    }

    fn successors(&self, n: &Node, hn: f64, stats: &mut Stats) -> Vec<Successor<Node>> {
        let (s, strides) = (self.s, self.strides.get());
        let mut out = Vec::new();
        let mut walked = false;
        for (f, c, a) in self.steps(n, stats) {
            let first = Node {
                stance: f,
                other: n.stance,
            };
            // The first straight step (the least cost of transport), also walked on for up to
            // `strides` steps as one successor.
            if strides > 1 && a.subset == Subset::Forward && !walked {
                walked = true;
                let h_first = self.h(&first);
                // Only where the step itself goes down the heuristic (by a third as much as a
                // walk's steps must: from feet side by side a step moves the centre half as
                // far, and the heuristic counts its turn and sway), or near the goal, where
                // the heuristic is one step's floor.
                let near = n.centre().dist(self.goal) <= s.full_set_radius;
                let (more, h_end) = if near || h_first <= hn - WALK_FOLLOWS / 3.0 * c {
                    self.walk(&first, h_first, &a, strides, stats)
                } else {
                    (Vec::new(), h_first)
                };
                if !more.is_empty() {
                    // The inner feet of a walk are steps of the plan, never expanded.
                    let mut steps = vec![(first, c)];
                    for (f, c) in more {
                        let other = steps[steps.len() - 1].0.stance;
                        steps.push((Node { stance: f, other }, c));
                    }
                    out.push(Successor {
                        steps,
                        h: Some(h_end),
                    });
                }
                out.push(Successor {
                    steps: vec![(first, c)],
                    h: Some(h_first),
                });
            } else {
                out.push(Successor {
                    steps: vec![(first, c)],
                    h: None,
                });
            }
        }
        out
    }
}

/// The stance feet from the root to `end`.
fn stances(reached: &[Reached<Node>], end: usize) -> Vec<Foot> {
    trace(reached, end).iter().map(|n| n.stance).collect()
}

/// Plans from the robot standing at `start` (feet side by side, the right one to swing first)
/// to `goal` (a position).
pub fn plan(start: V2, start_yaw: f64, goal: V2, world: &World, mode: Mode, s: &Settings) -> Plan {
    let (left, right) = Foot::standing(start, start_yaw, s.cost.w_nom);
    plan_from(left, right, goal, world, mode, s)
}

/// Plans from the stance foot `stance` (where it stands now; its height is looked up) with
/// the other foot, `swing`, to step next, to `goal` (a position). The plan's steps start with
/// `swing` where it stands.
pub fn plan_from(
    stance: Foot,
    swing: Foot,
    goal: V2,
    world: &World,
    mode: Mode,
    s: &Settings,
) -> Plan {
    let t0 = Instant::now();
    let p = &s.cost;
    let mut stats = Stats::default();
    let g = &world.grid;
    if !g.contains(goal) {
        return Plan::failed(Status::GoalOutsideMap, "the goal is outside the map", stats);
    }
    let (mut stance, mut swing) = (stance, swing);
    for f in [&mut stance, &mut swing] {
        stats.collision_queries += 1;
        let under = g.height(f.p);
        match world.foothold(f, under, &s.feasibility) {
            Some(z) => f.z = z,
            None => {
                return Plan::failed(
                    Status::StartInCollision,
                    "a foot of the start is off the map, on unknown ground or on an edge",
                    stats,
                )
            }
        }
    }
    let ground = stance.z.min(swing.z);
    // The goal is in collision when its cell is unknown, or stands more than the body's
    // height above the lowest cell within half a metre (a goal up a flight of low steps is
    // not).
    let at_goal = g.height(goal);
    let around = g
        .cell(goal)
        .map(|_| {
            let r = (0.5 / g.res) as i64;
            let mut low = at_goal;
            for b in -r..=r {
                for a in -r..=r {
                    let h = g.height(goal + v2(a as f64 * g.res, b as f64 * g.res));
                    if !h.is_nan() {
                        low = low.min(h);
                    }
                }
            }
            low
        })
        .unwrap_or(at_goal);
    if at_goal.is_nan() || at_goal > around + s.feasibility.body_height {
        return Plan::failed(
            Status::GoalInCollision,
            "the goal is on an obstacle or on unknown ground",
            stats,
        );
    }
    // The distance field takes the start's ground as the level. Where the terrain climbs in
    // low steps to cells it counts as tall, its way can be longer than the robot's: no bound
    // is claimed there.
    let limit = ground + s.feasibility.body_height;
    let climbs = (0..g.ny).any(|j| {
        (0..g.nx).any(|i| {
            let h = g.h[j * g.nx + i];
            h > limit
                && [(1i64, 0i64), (-1, 0), (0, 1), (0, -1)]
                    .iter()
                    .any(|&(a, b)| {
                        let (x, y) = (i as i64 + a, j as i64 + b);
                        x >= 0 && y >= 0 && (x as usize) < g.nx && (y as usize) < g.ny && {
                            let n = g.h[y as usize * g.nx + x as usize];
                            n > ground + s.feasibility.step_height && n <= limit
                        }
                    })
        })
    });
    let acts = ordered_actions(p, s.actions);
    let alpha = kaist::alpha(p, &acts);
    let field = (s.heuristic == Heuristic::Dijkstra2d).then(|| way_field(world, s, ground, goal));
    let lattice = mode == Mode::Improved;
    stats.prepare = t0.elapsed();
    let t1 = Instant::now();
    let pr = Problem {
        world,
        s,
        acts,
        alpha,
        goal,
        field,
        deadline: t1 + s.budget,
        scouting: Cell::new(false),
        strides: Cell::new(1),
        bearings: RefCell::new(Vec::new()),
    };
    let root = Node {
        stance,
        other: swing,
    };
    let passes = anytime_passes(lattice, s.scout, &s.weights, s.lattice);
    // The best partial plans by the heuristic: the scouting pass's (whose heuristic is not the
    // others') apart.
    let mut best_partial = (f64::INFINITY, vec![stance]);
    let mut best_scout = (f64::INFINITY, vec![stance]);
    let (incumbent, stopped) = anytime(&passes, &mut stats, t1, |w, cells, bounded, cap, stats| {
        // The scouting pass also walks straight in strides, and its heuristic charges the
        // turn towards the 2-D way.
        let scouting = lattice && !bounded;
        pr.scouting.set(scouting);
        let strides = if scouting { s.strides } else { 1 };
        let best = if scouting {
            &mut best_scout
        } else {
            &mut best_partial
        };
        pr.strides.set(strides);
        let astar::Pass {
            end,
            reached,
            nearest,
        } = astar::pass(&pr, root, (w, cells), lattice, cap, best.0, stats);
        if let Some((h, i)) = nearest {
            *best = (h, stances(&reached, i));
        }
        match end {
            End::Found(e, ()) => PassEnd::Found {
                plan: (
                    stances(&reached, e),
                    trace(&reached, e).iter().map(Node::centre).collect(),
                ),
                cost: reached[e].g,
                last: false,
            },
            End::Exhausted => PassEnd::Exhausted,
            End::Stopped(why) => PassEnd::Stopped(why),
        }
    });
    let why = stopped.unwrap_or("no foothold sequence reaches the goal");
    stats.search = t1.elapsed();
    // Of the two partial plans, the one whose end the fine passes' heuristic puts nearer.
    pr.scouting.set(false);
    let h_end = |feet: &[Foot]| match feet {
        [.., other, stance] => pr.h(&Node {
            stance: *stance,
            other: *other,
        }),
        _ => f64::INFINITY,
    };
    if best_scout.1.len() > 1
        && (best_partial.1.len() <= 1 || h_end(&best_scout.1) < h_end(&best_partial.1))
    {
        best_partial = best_scout;
    }
    let admissible = match s.heuristic {
        Heuristic::Zero | Heuristic::EnergyBound => true,
        Heuristic::Dijkstra2d => !climbs,
        _ => false,
    };
    match incumbent.map(|i| (i.cost, i.plan.0, i.plan.1, i.bound)) {
        Some((cost, feet, path, w)) => Plan {
            status: Status::Ok,
            detail: String::new(),
            path,
            cost,
            steps: std::iter::once(swing).chain(feet).collect(),
            stats,
            bound: (lattice && admissible && w.is_finite()).then_some(w),
        },
        None if lattice && best_partial.1.len() > 1 => {
            let feet = best_partial.1;
            let mut path = Vec::new();
            let mut prev = swing;
            for f in &feet {
                path.push((f.p + prev.p) * 0.5);
                prev = *f;
            }
            let mut cost = 0.0;
            let mut steps = vec![swing];
            steps.extend(feet);
            for w in steps.windows(2).skip(1) {
                // The cost of each step, from the action's geometry.
                cost += step_energy(&w[0], &w[1], p);
            }
            Plan {
                status: Status::Partial,
                detail: why.to_string(),
                path,
                cost,
                steps,
                stats,
                bound: None,
            }
        }
        None => Plan::failed(Status::NoPath, why, stats),
    }
}

/// The 2-D distance field to `goal` of [`Heuristic::Dijkstra2d`], for a search whose start
/// stands on `ground`.
fn way_field(world: &World, s: &Settings, ground: f64, goal: V2) -> Vec<f64> {
    let g = &world.grid;
    // Every node's centre is the middle of a stance-to-swing ellipse, which is free of
    // tall cells for FOOT.0 / 2 around it: the field keeps that far from them, less the
    // cells' half-diagonal.
    let limit = ground + s.feasibility.body_height;
    let clear = FOOT.0 / 2.0 - g.res * std::f64::consts::FRAC_1_SQRT_2;
    let mut open = g.clone();
    open.h =
        g.h.iter()
            .map(|&h| if h.is_nan() || h <= limit { 0.0 } else { 1.0 })
            .collect();
    let mut grown = open.clone();
    let r = (clear / g.res).floor() as i64;
    for j in 0..g.ny as i64 {
        for i in 0..g.nx as i64 {
            if open.h[j as usize * g.nx + i as usize] == 0.0 {
                continue;
            }
            for b in -r..=r {
                for a in -r..=r {
                    let (x, y) = (i + a, j + b);
                    if ((a * a + b * b) as f64).sqrt() * g.res <= clear
                        && x >= 0
                        && y >= 0
                        && (x as usize) < g.nx
                        && (y as usize) < g.ny
                    {
                        grown.h[y as usize * g.nx + x as usize] = 1.0;
                    }
                }
            }
        }
    }
    grown.distance_field(goal, |h| h == 0.0)
}

/// The heuristic that the bounded passes of a search from `stance` and `swing` (as for
/// [`plan_from`]) to `goal` give the node whose stance foot is `at`, placed from `other`, in
/// energy units; `None` when a foot of the start has no foothold. Exposed so that tests can
/// check it against exhaustive searches.
pub fn heuristic(
    (stance, swing): (Foot, Foot),
    goal: V2,
    world: &World,
    s: &Settings,
    at: Foot,
    other: Foot,
) -> Option<f64> {
    let mut ground = f64::INFINITY;
    for f in [stance, swing] {
        ground = ground.min(world.foothold(&f, world.grid.height(f.p), &s.feasibility)?);
    }
    let field = (s.heuristic == Heuristic::Dijkstra2d).then(|| way_field(world, s, ground, goal));
    let pr = Problem::probe(world, s, goal, field);
    Some(pr.h(&Node { stance: at, other }))
}

/// The successors the search would make from the stance foot `stance` with the other foot at
/// `other`, towards `goal`: each new foot (with the height it rests on) and the step's energy.
pub fn successors(
    world: &World,
    s: &Settings,
    goal: V2,
    stance: Foot,
    other: Foot,
) -> Vec<(Foot, f64)> {
    let pr = Problem::probe(world, s, goal, None);
    let n = Node { stance, other };
    pr.steps(&n, &mut Stats::default())
        .into_iter()
        .map(|(f, c, _)| (f, c))
        .collect()
}

/// The energy of the step that places `swing` from `stance`.
fn step_energy(stance: &Foot, swing: &Foot, p: &CostParams) -> f64 {
    let dir = V2::polar(stance.yaw);
    let r = swing.p - stance.p;
    let (dx, dy) = (r.dot(dir), r.cross(dir).abs());
    let a = Action {
        dx: if dx.abs() < 1e-9 { 0.0 } else { dx },
        dy,
        dtheta: wrap(swing.yaw - stance.yaw),
        subset: Subset::Forward,
    };
    a.energy_mg(p) * p.mg()
}
