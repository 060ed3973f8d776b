//! One interface to the three planners: [`plan`] takes a [`Request`] (which planner, which
//! mode, the robot's start, the goal), the world (a [`Scene`]: obstacles, surfaces, map) and a
//! time budget, and answers with a [`Plan`].

use std::time::Duration;

use crate::archie::steps::{self, StepParams};
use crate::archie::{self, headings, Params};
use crate::grid::Grid;
use crate::kaist::search as kaist_search;
use crate::kaist::CostParams;
use crate::lola;
use crate::plan::{Cancel, Foot, Plan, Stats, Status};
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
    /// Archie's planner: the growth of the obstacles (m), if not its mode's own (the improved
    /// search on the thesis's growth compares the searches alone).
    pub inflation: Option<f64>,
    /// Archie's planner: the longest advance per step (m), if not the thesis's 0.3 m (the
    /// walking controller's own limit).
    pub max_step: Option<f64>,
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

impl Which {
    /// The three, in the order of their numbers.
    pub const ALL: [Which; 3] = [Which::Archie, Which::Kaist, Which::Lola];

    /// The planner's name: "archie", "kaist" or "lola" (configuration, command lines).
    pub fn name(self) -> &'static str {
        match self {
            Which::Archie => "archie",
            Which::Kaist => "kaist",
            Which::Lola => "lola",
        }
    }

    /// The planner's number: the `PLANNER_*` constants of stride.footstep_plan_request_t
    /// (ARCHIE 0, KAIST 1, LOLA 2).
    pub fn id(self) -> i8 {
        match self {
            Which::Archie => 0,
            Which::Kaist => 1,
            Which::Lola => 2,
        }
    }
}

impl std::fmt::Display for Which {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Which {
    type Err = String;

    fn from_str(s: &str) -> Result<Which, String> {
        Which::ALL
            .into_iter()
            .find(|w| w.name() == s)
            .ok_or_else(|| format!("unknown planner {s:?}: one of \"archie\", \"kaist\", \"lola\""))
    }
}

impl TryFrom<i8> for Which {
    type Error = String;

    fn try_from(id: i8) -> Result<Which, String> {
        Which::ALL
            .into_iter()
            .find(|w| w.id() == id)
            .ok_or_else(|| {
                format!(
                    "unknown planner {id} (PLANNER_ARCHIE 0, PLANNER_KAIST 1 or PLANNER_LOLA 2)"
                )
            })
    }
}

impl From<Which> for i8 {
    fn from(w: Which) -> i8 {
        w.id()
    }
}

impl Which {
    /// The planner's own budget, when a request gives none: LOLA's 400 ms (the thesis's
    /// navigation cycle), 200 ms for the others (Archie's planners take far less).
    pub fn default_budget(self) -> Duration {
        match self {
            Which::Lola => Duration::from_millis(400),
            _ => Duration::from_millis(200),
        }
    }

    /// Archie's planner's settings in a mode (the thesis's growth in faithful mode, the
    /// footprint-safe one otherwise), with `inflation` instead of the mode's own if given.
    pub fn archie_params(faithful: bool, inflation: Option<f64>) -> Params {
        let mut p = if faithful {
            Params::default()
        } else {
            Params::improved()
        };
        if let Some(i) = inflation {
            p.inflation = i;
        }
        p
    }

    /// The growth around a plan's path within which a new obstacle makes it replan: the
    /// planner's own obstacle growth for Archie's, half a foot for the footstep planners
    /// (their paths run between the feet).
    pub fn replan_inflation(self, faithful: bool) -> f64 {
        match self {
            Which::Archie => Which::archie_params(faithful, None).inflation,
            _ => 0.1,
        }
    }

    /// How many feet a plan lists first where they stand: Archie's lists the standing foot,
    /// the footstep planners both feet.
    pub fn standing(self) -> usize {
        if self == Which::Archie {
            1
        } else {
            2
        }
    }
}

/// What a planner takes: requests and worlds beyond these are refused ([`Status::Refused`])
/// before any search, so a glitch (an infinite radius, a goal a thousand kilometres away)
/// cannot exhaust the memory or the time of the process.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// The farthest the goal may be from the start, m.
    pub max_goal_distance: f64,
    /// The farthest any number of the world (obstacles, surfaces, map) may be from the
    /// origin, m; sizes at most this too.
    pub reach: f64,
    /// The most steps a plan may have.
    pub max_steps: usize,
    /// The longest budget a request may ask for.
    pub max_budget: Duration,
    /// The most expansions a request may ask a search for (each holds its successors: the
    /// search's memory grows with them).
    pub max_expansions: u64,
    /// The most obstacles Archie's planners take (the tangent graph grows with their square,
    /// its search with their cube).
    pub max_archie_obstacles: usize,
}

impl Default for Limits {
    /// 50 m to the goal, a world within 1 km, 1000 steps, a budget of 10 s, 2 million
    /// expansions, 500 obstacles for Archie's planners.
    fn default() -> Limits {
        Limits {
            max_goal_distance: 50.0,
            reach: 1000.0,
            max_steps: 1000,
            max_budget: Duration::from_secs(10),
            max_expansions: 2_000_000,
            max_archie_obstacles: 500,
        }
    }
}

impl Limits {
    /// Checks the request and its world against the limits; the error says what is beyond.
    pub fn check(&self, req: &Request, world: &Scene, budget: Duration) -> Result<(), String> {
        let numbers = [
            req.start.x,
            req.start.y,
            req.start.yaw,
            req.goal.x,
            req.goal.y,
        ];
        if numbers.iter().any(|v| !v.is_finite()) {
            return Err("the start or the goal is not a finite number".into());
        }
        let d = req.start.p().dist(req.goal.p());
        if d > self.max_goal_distance {
            // Short, whatever the figure (a goal at 1e300 m is not printed in 300 digits).
            let far = if d < 1e6 {
                format!("{d:.1}")
            } else {
                format!("{d:.3e}")
            };
            return Err(format!(
                "the goal is {far} m away, beyond the {} m a plan may reach",
                self.max_goal_distance
            ));
        }
        if budget > self.max_budget {
            return Err(format!(
                "a budget of {:?} is longer than the {:?} allowed",
                budget, self.max_budget
            ));
        }
        if let Some(n) = req.max_expansions.filter(|n| *n > self.max_expansions) {
            return Err(format!(
                "{n} expansions asked, more than the {} allowed",
                self.max_expansions
            ));
        }
        world.check_reach(self.reach)?;
        if req.planner == Which::Archie && world.obstacle.len() > self.max_archie_obstacles {
            return Err(format!(
                "{} obstacles, more than the {} Archie's planners take",
                world.obstacle.len(),
                self.max_archie_obstacles
            ));
        }
        if req.planner != Which::Archie {
            // The footstep planners map the world's extent (with the start and goal) onto a
            // grid: refuse what would not fit before allocating it.
            let (x, y, res) = Grid::extent_of(&scene_for(world, req));
            let cells = Grid::cells_for(x, y, res);
            if cells.is_nan() || cells > Grid::MAX_CELLS as f64 {
                return Err(format!(
                    "the world's map would have {cells:.0} cells, more than the {} allowed",
                    Grid::MAX_CELLS
                ));
            }
        }
        Ok(())
    }
}

/// Plans `req` in `world` (a scene: its obstacles, surfaces and map; its own start and goal
/// are not used) within `budget` (Archie's planners are far below any budget and
/// take none), with the default [`Limits`] and no cancelling.
pub fn plan(req: &Request, world: &Scene, budget: Duration) -> Plan {
    plan_within(req, world, budget, &Limits::default(), &Cancel::new())
}

/// [`plan`] within `limits` (a request or world beyond them is refused, and so is a plan of
/// more steps than they allow); `cancel` stops a running search ([`Status::Cancelled`]).
pub fn plan_within(
    req: &Request,
    world: &Scene,
    budget: Duration,
    limits: &Limits,
    cancel: &Cancel,
) -> Plan {
    if let Err(why) = limits.check(req, world, budget) {
        return Plan::failed(Status::Refused, why, Stats::default());
    }
    let mut plan = search(req, world, budget, cancel);
    if cancel.is_cancelled() {
        plan.status = Status::Cancelled;
        plan.detail = "cancelled before it finished".into();
    } else if plan.steps.len() > limits.max_steps {
        let why = format!(
            "the plan has {} steps, more than the {} allowed",
            plan.steps.len(),
            limits.max_steps
        );
        return Plan::failed(Status::Refused, why, plan.stats);
    }
    plan
}

fn search(req: &Request, world: &Scene, budget: Duration, cancel: &Cancel) -> Plan {
    let (start, goal) = (req.start.p(), req.goal.p());
    match req.planner {
        Which::Archie => {
            let circles = world.circles();
            let mut sp = StepParams::default();
            if let Some(m) = req.max_step {
                sp.max_step = m;
            }
            let params = Which::archie_params(req.faithful, req.inflation);
            if req.faithful {
                let mut p = archie::plan_tree(start, goal, &circles, &params).0;
                if p.status == Status::Ok {
                    p.steps =
                        steps::faithful(&p.path, &headings(&p.path, req.start.yaw), &sp, true);
                }
                p
            } else {
                // Walking on (the feet known): from the stance foot's hip, the point of the
                // last plan's path it stepped to, so that a plan replanned at every step goes
                // on along the same path (from the centre between the feet it would start a
                // chord's depth inside a margin it hugs, and step short of the last plan).
                let start = match req.feet {
                    Some((stance, _)) => steps::hip(&stance, sp.half_stance),
                    None => start,
                };
                let mut p = archie::plan_exact(start, goal, &circles, &params);
                if p.status == Status::Ok {
                    let swing_left = req.feet.map(|(_, swing)| swing.left);
                    p.steps = steps::improved_from(&p.path, req.start.yaw, &sp, swing_left);
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
            s.cancel = cancel.clone();
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
            s.cancel = cancel.clone();
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
        inflation: None,
        max_step: None,
    }
}
