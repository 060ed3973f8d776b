//! One interface to the three planners: [`plan`] takes a [`Request`] (which planner, which
//! mode, the robot's start, the goal), the world (a [`Scene`]: obstacles, surfaces, map) and a
//! time budget, and answers with a [`Plan`].

use std::time::Duration;

use crate::archie::steps::{self, StepParams};
use crate::archie::{self, headings, Params};
use crate::kaist::search as kaist_search;
use crate::kaist::CostParams;
use crate::lola;
use crate::plan::{Foot, Plan, Stats, Status};
use crate::scene::{Pose, Scene};

/// The planners.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Which {
    /// Archie's path planner and footsteps (seed 000).
    Archie,
    /// The KAIST energy A* (seed 004).
    Kaist,
    /// LOLA's 3-D footstep A* (seed 002).
    Lola,
}

/// What to plan.
#[derive(Debug, Clone, PartialEq)]
pub struct Request {
    /// Which planner.
    pub planner: Which,
    /// The thesis's planner (with its defects) instead of the improved one.
    pub faithful: bool,
    /// The robot's centre between its feet, and its heading.
    pub start: Pose,
    /// The goal (its heading counts for LOLA's planner only).
    pub goal: Pose,
    /// Steps at most (a receding horizon; LOLA's planner), if set.
    pub horizon: Option<usize>,
    /// Where the feet are, if known: the stance foot and the one to step next (the footstep
    /// planners start from them; otherwise from the feet side by side at `start`, the right
    /// one to step first).
    pub feet: Option<(Foot, Foot)>,
    /// How near the goal counts as arrived (m), if not the planner's own.
    pub tolerance: Option<f64>,
    /// How near the goal's heading counts (rad; LOLA's planner), if not its own.
    pub yaw_tolerance: Option<f64>,
    /// Expansions at most, if not the planner's own cap.
    pub max_expansions: Option<u64>,
    /// LOLA's coupling 2: the corridor around the pre-planner's way (m), if wanted.
    pub corridor: Option<f64>,
}

/// The scene with the request's start and goal (so a map made from the scene's extent holds
/// them).
fn scene_for(world: &Scene, req: &Request) -> Scene {
    Scene {
        start: req.start,
        goal: req.goal,
        ..world.clone()
    }
}

/// Plans `req` in `world` (a scene: its obstacles, surfaces and map; its own start and goal
/// are not used) within `budget` (Archie's planners are far below any budget and
/// take none).
pub fn plan(req: &Request, world: &Scene, budget: Duration) -> Plan {
    let (start, goal) = (req.start.p(), req.goal.p());
    match req.planner {
        Which::Archie => {
            let circles = world.circles();
            let sp = StepParams::default();
            if req.faithful {
                let mut p = archie::plan_tree(start, goal, &circles, &Params::default()).0;
                if p.status == Status::Ok {
                    p.steps =
                        steps::faithful(&p.path, &headings(&p.path, req.start.yaw), &sp, true);
                }
                p
            } else {
                let mut p = archie::plan_exact(start, goal, &circles, &Params::improved());
                if p.status == Status::Ok {
                    p.steps = steps::improved(&p.path, req.start.yaw, &sp);
                }
                p
            }
        }
        Which::Kaist => {
            let scene = scene_for(world, req);
            let cost = match CostParams::of_scene(&scene) {
                Ok(c) => c,
                Err(e) => return Plan::failed(Status::NoPath, e, Stats::default()),
            };
            let w = match kaist_search::World::of(&scene) {
                Ok(w) => w,
                Err(e) => return Plan::failed(Status::NoPath, e.to_string(), Stats::default()),
            };
            let mode = if req.faithful {
                kaist_search::Mode::Thesis
            } else {
                kaist_search::Mode::Improved
            };
            let mut s = kaist_search::Settings::new(mode, cost);
            s.budget = budget;
            if let Some(t) = req.tolerance {
                s.tolerance = t;
            }
            if let Some(n) = req.max_expansions {
                s.max_expansions = n;
            }
            let (stance, swing) = req
                .feet
                .unwrap_or_else(|| Foot::standing(start, req.start.yaw, s.cost.w_nom));
            kaist_search::plan_from(stance, swing, goal, &w, mode, &s)
        }
        Which::Lola => {
            let w = lola::World::of(&scene_for(world, req));
            let mode = if req.faithful {
                lola::Mode::Thesis
            } else {
                lola::Mode::Improved
            };
            let mut s = lola::Settings::new(mode);
            s.budget = budget;
            s.horizon = req.horizon;
            s.corridor = req.corridor.or(s.corridor);
            if let Some(t) = req.tolerance {
                s.tolerance.0 = t;
            }
            if let Some(t) = req.yaw_tolerance {
                s.tolerance.1 = t;
            }
            if let Some(n) = req.max_expansions {
                s.max_expansions = n;
            }
            let (stance, swing) = req
                .feet
                .unwrap_or_else(|| Foot::standing(start, req.start.yaw, s.robot.width));
            lola::plan_from(stance, swing, goal, req.goal.yaw, &w, mode, &s)
        }
    }
}

/// The planner for a scene by its name's prefix (`kaist-`, `lola-`; Archie's otherwise).
pub fn for_scene(scene: &Scene) -> Which {
    if scene.name.starts_with("kaist") {
        Which::Kaist
    } else if scene.name.starts_with("lola") {
        Which::Lola
    } else {
        Which::Archie
    }
}

/// The request a scene makes of its planner.
pub fn scene_request(scene: &Scene, faithful: bool) -> Request {
    Request {
        planner: for_scene(scene),
        faithful,
        start: scene.start,
        goal: scene.goal,
        horizon: None,
        feet: None,
        tolerance: None,
        yaw_tolerance: None,
        max_expansions: None,
        corridor: None,
    }
}
