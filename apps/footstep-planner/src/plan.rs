//! What every planner answers.

use std::time::Duration;

use crate::geom::V2;

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
        }
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
}

/// A foot placement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Foot {
    /// Position of the foot (its reference point), m.
    pub p: V2,
    /// Heading, rad.
    pub yaw: f64,
    /// True for the left foot.
    pub left: bool,
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
        }
    }
}
