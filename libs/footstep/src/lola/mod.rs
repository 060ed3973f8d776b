//! LOLA's footstep planner (seed 002 §4, the notes' sections 2, 3 and 8): A* over footholds
//! (x, y, z, yaw, side) on steppable surfaces, a 3-D swing check of the foot and shank
//! swept-sphere model, a 2-D pre-planner coupled to the search, and a deadline.
//!
//! - Footholds: the sole (0.22 × 0.12 m) lies wholly on one surface (its height is the foot's
//!   z) or wholly on the floor (z = 0) and inside the map; a sole across a surface's edge is
//!   refused (the thesis makes edges obstacles; V3). The foot's SSVs keep clear of every
//!   obstacle. Up or down at most `max_step_height`.
//! - Steps: 85 suggestions around the desired step (17 positions: the 3 × 3 ring of ±0.10 m
//!   ahead and ±0.05 m sideways and 8 at twice that, by 5 turns of 0, ±0.1, ±0.2 rad), within
//!   the limits; the reduced set keeps 34. Each maps to the swing foot's pose along a circular
//!   path (the turn spread over the step).
//! - The swing: the foot and shank SSVs swept along the straight line from the old foothold to
//!   the new one at a low reference height, sampled every 5 cm. The highest obstacle they meet
//!   is the step's `h_obst`; over `h_max` the step is refused (P4).
//! - Cost (Eq. 4.6-4.11): the desired step's length plus k = 1.5 times the weighted distance
//!   of the step from the desired one (W = diag(1, 1, 0.2 m/rad)); heuristic: the weighted
//!   distance of the mid-stance point and heading from the goal. Consistent for k ≥ 1.
//! - faithful ([`Mode::Thesis`]): the thesis's search tree (no duplicate detection), its
//!   heuristic, and its 2-D pre-planner ([`preplan`](mod@crate::lola::preplan): seeds shifted to free space, one
//!   way per homotopy class, the cheapest by Eq. 4.17) coupled as heuristic and heading
//!   (couplings 1 and 3); at the budget it falls back to stepping in place.
//! - improved ([`Mode::Improved`]): a scouting pass on a coarse lattice (0.2 m, 15°, weight
//!   2), then duplicate detection on a lattice (0.05 m, 5°, side), the 2-D pre-planner (a
//!   distance field over the tall obstacles, grown by a margin) coupled as heuristic (the
//!   way's length: coupling 1) and as desired heading (the way's direction: coupling 3; where
//!   there is room, the way of a field grown by the wider heading margin), optionally as a
//!   corridor (coupling 2: off by default, it made no plan faster on the shipped scenes), a
//!   step straight onto the goal pose when one step reaches it, an optional horizon (the
//!   thesis's 7 steps; the first plan found stands), and the deadline: at the budget the best
//!   partial plan, or steps in place when none gets nearer.

pub mod preplan;
mod search;
mod settings;
mod world;

pub use search::{
    mid, open_floor_h, place, plan, plan_from, step_cost, suggestion_count, unplace, Probe,
};
pub use settings::{Mode, PrePlanner, Robot, Settings};
pub use world::{World, EDGE_RADIUS};
