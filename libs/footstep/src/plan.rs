//! What every planner answers.

use std::cmp::Ordering;
use std::sync::atomic::{AtomicBool, Ordering as AtomicOrdering};
use std::sync::Arc;
use std::time::Duration;

use crate::geom::{path_length, V2};

/// How a plan ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Status {
    /// A path (and steps) to the goal.
    Ok,
    /// The budget ran out: the best partial plan so far.
    Partial,
    /// No path exists (or none was found within the search's limits).
    NoPath,
    /// The start is inside an (inflated) obstacle.
    StartInCollision,
    /// The goal is inside an (inflated) obstacle.
    GoalInCollision,
    /// The goal is outside the map.
    GoalOutsideMap,
    /// The request or its world is outside what the planner takes (not finite, too far, too
    /// large): refused before any search.
    Refused,
    /// Cancelled before it finished (a newer request superseded it, or shutdown).
    Cancelled,
}

impl Status {
    /// Its name, for tables and messages.
    pub fn name(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Partial => "partial",
            Status::NoPath => "no path",
            Status::StartInCollision => "start in collision",
            Status::GoalInCollision => "goal in collision",
            Status::GoalOutsideMap => "goal outside map",
            Status::Refused => "refused",
            Status::Cancelled => "cancelled",
        }
    }
}

/// A flag that cancels a running search (checked where the searches check their deadline);
/// clones share it.
#[derive(Debug, Clone, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    /// A flag not set.
    pub fn new() -> Cancel {
        Cancel::default()
    }

    /// Cancels every search holding this flag.
    pub fn cancel(&self) {
        self.0.store(true, AtomicOrdering::Relaxed);
    }

    /// True once cancelled.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(AtomicOrdering::Relaxed)
    }
}

impl PartialEq for Cancel {
    fn eq(&self, o: &Cancel) -> bool {
        Arc::ptr_eq(&self.0, &o.0)
    }
}

/// What a search cost.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stats {
    /// Nodes expanded.
    pub expansions: u64,
    /// Successors generated.
    pub generated: u64,
    /// Collision tests made.
    pub collision_queries: u64,
    /// Time to prepare (graphs, heuristics).
    pub prepare: Duration,
    /// Time to search.
    pub search: Duration,
    /// Time from the start of the search to its first plan (anytime searches improve it
    /// afterwards).
    pub first_plan: Option<Duration>,
    /// Nodes expanded up to the first plan.
    pub first_plan_expansions: Option<u64>,
}

/// A foot placement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Foot {
    /// Position of the foot (its reference point), m.
    pub p: V2,
    /// Height of the ground under it, m.
    pub z: f64,
    /// Heading, rad.
    pub yaw: f64,
    /// True for the left foot.
    pub left: bool,
}

impl Foot {
    /// The two feet of a robot standing with its centre at `centre`, facing `yaw`, feet
    /// `width` apart on the ground: (left, right).
    pub fn standing(centre: V2, yaw: f64, width: f64) -> (Foot, Foot) {
        let side = V2 {
            x: -yaw.sin(),
            y: yaw.cos(),
        } * (width / 2.0);
        let foot = |p: V2, left: bool| Foot {
            p,
            z: 0.0,
            yaw,
            left,
        };
        (foot(centre + side, true), foot(centre - side, false))
    }
}

/// A planner's answer.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// How it ended.
    pub status: Status,
    /// Why, in words (empty when ok).
    pub detail: String,
    /// The path's waypoints, start first.
    pub path: Vec<V2>,
    /// The path's cost (its length for the path planners), m.
    pub cost: f64,
    /// The footsteps, in order.
    pub steps: Vec<Foot>,
    /// What the search cost.
    pub stats: Stats,
    /// The suboptimality bound: the cost is at most this times the optimum on the planner's
    /// graph (1 for an optimal plan; `None` when the planner gives no bound).
    pub bound: Option<f64>,
}

impl Plan {
    /// A plan that failed with `status`.
    pub fn failed(status: Status, detail: impl Into<String>, stats: Stats) -> Plan {
        Plan {
            status,
            detail: detail.into(),
            path: Vec::new(),
            cost: f64::INFINITY,
            steps: Vec::new(),
            stats,
            bound: None,
        }
    }

    /// A path found (its cost its length), with the bound on its cost against the optimum.
    pub fn path(path: Vec<V2>, stats: Stats, bound: Option<f64>) -> Plan {
        Plan {
            status: Status::Ok,
            detail: String::new(),
            cost: path_length(&path),
            path,
            steps: Vec::new(),
            stats,
            bound,
        }
    }
}

/// How one pass of an anytime search ended.
#[derive(Debug)]
pub enum PassEnd<R> {
    /// A plan cheaper than the incumbent, of cost `cost`; `last` ends the search (a horizon
    /// reached: the first plan stands).
    Found {
        /// The plan.
        plan: R,
        /// Its cost.
        cost: f64,
        /// No pass after this one.
        last: bool,
    },
    /// Nothing cheaper than the incumbent within this pass's weight.
    Exhausted,
    /// Stopped by the expansion cap, the budget or a cancel, with why.
    Stopped(&'static str),
}

/// The best plan of an anytime search, its cost, and the weight within which it is proven
/// (infinite when no bounded pass proved it).
#[derive(Debug)]
pub struct Incumbent<R> {
    /// The plan.
    pub plan: R,
    /// Its cost.
    pub cost: f64,
    /// Its suboptimality bound.
    pub bound: f64,
}

/// The one anytime loop of the footstep searches: runs `pass` for each `(weight, lattice
/// cells, bounded)` of `passes` in turn, pruned by the incumbent's cost, and keeps the
/// cheapest plan. A bounded pass that finds nothing cheaper proves the incumbent within its
/// weight, and one that finds nothing at all ends the search (no plan exists); an unbounded
/// (scouting) pass proves nothing. Notes the first plan's time (from `started`) and
/// expansions in `stats`. Returns the incumbent and why the search stopped early, if it did.
pub fn anytime<R>(
    passes: &[(f64, (f64, f64), bool)],
    stats: &mut Stats,
    started: std::time::Instant,
    mut pass: impl FnMut(f64, (f64, f64), bool, f64, &mut Stats) -> PassEnd<R>,
) -> (Option<Incumbent<R>>, Option<&'static str>) {
    let mut best: Option<Incumbent<R>> = None;
    for &(w, cells, bounded) in passes {
        let cap = best.as_ref().map_or(f64::INFINITY, |b| b.cost);
        match pass(w, cells, bounded, cap, stats) {
            PassEnd::Found { plan, cost, last } => {
                stats.first_plan.get_or_insert(started.elapsed());
                stats.first_plan_expansions.get_or_insert(stats.expansions);
                let bound = if bounded { w } else { f64::INFINITY };
                best = Some(Incumbent { plan, cost, bound });
                if last {
                    break;
                }
            }
            PassEnd::Exhausted => match best.as_mut() {
                Some(b) if bounded => b.bound = w,
                Some(_) => {}
                None if bounded => break,
                None => {}
            },
            PassEnd::Stopped(why) => return (best, Some(why)),
        }
    }
    (best, None)
}

/// The passes of a lattice planner, each (weight, lattice cell: position m and yaw degrees,
/// whether its plan is bounded by the weight on the planner's lattice): with duplicate
/// detection (`lattice`), the scouting pass if any (unbounded) and then `weights` on `cells`;
/// without, one tree pass of weight 1.
pub fn anytime_passes(
    lattice: bool,
    scout: Option<((f64, f64), f64)>,
    weights: &[f64],
    cells: (f64, f64),
) -> Vec<(f64, (f64, f64), bool)> {
    if !lattice {
        return vec![(1.0, cells, false)];
    }
    scout
        .map(|(coarse, w)| (w, coarse, false))
        .into_iter()
        .chain(weights.iter().map(|&w| (w, cells, true)))
        .collect()
}

pub use stride_world::Least;

/// An entry of an A* open list (a `BinaryHeap`): least `f` first, then least `h` (the deeper
/// of two equal ones), then the first inserted: deterministic.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Entry {
    /// g + w·h.
    pub f: f64,
    /// h.
    pub h: f64,
    /// Insertion order.
    pub order: u64,
    /// The node.
    pub node: usize,
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, o: &Self) -> Ordering {
        o.f.total_cmp(&self.f)
            .then(o.h.total_cmp(&self.h))
            .then(o.order.cmp(&self.order))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
