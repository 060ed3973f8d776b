//! What the footstep planners' tests share: exhaustive searches that share none of the
//! planners' own search.

#![allow(dead_code)]

use stride_footstep::geom::V2;
use stride_footstep::kaist::search::{successors, Settings, World};
use stride_footstep::plan::{Foot, Least};

/// A plain Dijkstra over the planner's successors (its lattice of candidate steps and its
/// feasibility checks, asked with the real goal) with the lattice's duplicate detection and
/// no heuristic, no weights, no scouting, no strides and no cap: the least cost of bringing the
/// centre within the tolerance of `goal` from the robot standing at `start` (the right foot
/// to swing first, as the planner's `plan`). Shares none of the planner's search.
pub fn dijkstra(world: &World, s: &Settings, start: V2, yaw: f64, goal: V2) -> Option<(f64, u64)> {
    use std::collections::{BinaryHeap, HashMap};
    let (cell, yaw_cell) = (s.lattice.0, s.lattice.1.to_radians());
    let key = |f: &Foot| {
        (
            (f.p.x / cell).round() as i64,
            (f.p.y / cell).round() as i64,
            (stride_footstep::geom::wrap(f.yaw) / yaw_cell).round() as i64,
            f.left,
        )
    };
    let (mut left, mut right) = Foot::standing(start, yaw, s.cost.w_nom);
    for f in [&mut left, &mut right] {
        f.z = world.foothold(f, world.grid.height(f.p), &s.feasibility)?;
    }
    let mut states = vec![(left, right)];
    let mut best = HashMap::from([(key(&left), 0.0)]);
    let mut heap = BinaryHeap::from([Least(0.0, 0)]);
    let mut expanded = 0u64;
    while let Some(Least(g, i)) = heap.pop() {
        let (stance, other) = states[i];
        if best.get(&key(&stance)).is_some_and(|&b| g > b) {
            continue;
        }
        if ((stance.p + other.p) * 0.5).dist(goal) < s.tolerance {
            return Some((g, expanded));
        }
        expanded += 1;
        for (f, c) in successors(world, s, goal, stance, other) {
            let c = g + c;
            if best.get(&key(&f)).is_none_or(|&b| c < b) {
                best.insert(key(&f), c);
                states.push((f, stance));
                heap.push(Least(c, states.len() - 1));
            }
        }
    }
    None
}
