//! Footstep planning for stride: the scene a planner works in ([`scene`]), plane geometry
//! ([`geom`]), Archie's planner ([`archie`]: the thesis's tangent binary tree, faithfully, and
//! an exact shortest path over the same inflated circles), and footsteps along a path
//! ([`steps`]: the thesis's computation, faithfully, and an improved one). Every planner answers
//! with a [`plan::Plan`]: its status, its path and steps, and what the search cost. [`node`] is
//! the logic of the LCM node (`stride-footstep-planner`).

pub mod app;
pub mod archie;
pub mod geom;
pub mod grid;
pub mod kaist;
pub mod kaist_search;
pub mod lola;
pub mod node;
pub mod plan;
pub mod planner;
pub mod preplan;
pub mod scene;
pub mod ssv;
pub mod steps;
pub mod svg;
