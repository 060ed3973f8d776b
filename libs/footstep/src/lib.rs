//! Footstep planning for stride, with no bus and no I/O: three planners behind one interface
//! ([`planner::plan`]), each answering with a [`plan::Plan`] (its status, path and steps, and
//! what the search cost):
//!
//! - [`archie`]: Archie's path planner (the thesis's tangent binary tree, faithfully, and an
//!   exact shortest path over the same inflated circles) and its footsteps along the path
//!   ([`archie::steps`]: the thesis's computation, faithfully, and an improved one);
//! - [`kaist`]: the KAIST energy A* over footholds on an elevation grid (its cost model here,
//!   the search in [`kaist::search`]);
//! - [`lola`]: LOLA's footstep A* over steppable surfaces with a 3-D swing check, coupled to
//!   its 2-D pre-planner ([`lola::preplan`](mod@lola::preplan)).
//!
//! [`svg`] draws a plan. The world they plan in is `stride-world`'s, re-exported here.

pub mod archie;
mod astar;
pub mod kaist;
pub mod lola;
pub mod plan;
pub mod planner;
pub mod svg;

pub use stride_world::{geom, grid, scene, ssv};
