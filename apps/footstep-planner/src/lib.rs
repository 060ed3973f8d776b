//! The `stride-footstep-planner` node: its command line and loop ([`app`]), and the logic
//! between the bus and the planners of `stride-footstep` ([`node`]: a request and the world
//! into a `stride.footstep_plan_t`, and when to plan again).

pub mod app;
pub mod node;
