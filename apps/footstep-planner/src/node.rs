//! The logic of the `stride-footstep-planner` node, apart from the bus: turning a request and
//! the world into a `stride.footstep_plan_t`, and deciding when to plan again (a new request,
//! or a world that changed under the current plan), exactly once per change.

use std::time::Duration;

use stride_lcmtypes::stride::{
    FootT, FootstepPlanRequestT, FootstepPlanT, FootstepT, HeaderT, ObstacleListT, ObstacleT,
};

use stride_footstep::archie::steps::StepParams;
use stride_footstep::archie::{self, Params};
use stride_footstep::geom::{v2, Circle, V2};
use stride_footstep::plan::{Foot, Plan, Stats, Status};
use stride_footstep::planner::{self, Request, Which};
use stride_footstep::scene::{Obstacle, Pose, Scene};

/// What the planner knows of the world: a scene of obstacles (and, from a scene file,
/// surfaces and a map), and a version that changes when they do.
#[derive(Debug, Clone, PartialEq)]
pub struct World {
    /// The obstacles, surfaces and map.
    pub scene: Scene,
    /// Bumped by every change.
    pub version: u64,
}

impl Default for World {
    fn default() -> Self {
        World::from_scene(Scene {
            name: "bus".into(),
            description: "obstacles from the bus".into(),
            reference: String::new(),
            start: Pose::default(),
            goal: Pose::default(),
            obstacle: Vec::new(),
            surface: Vec::new(),
            params: None,
            map: None,
            dir: Default::default(),
        })
    }
}

impl World {
    /// A scene file's world.
    pub fn from_scene(scene: Scene) -> World {
        World { scene, version: 0 }
    }

    /// Replaces the obstacles; true (and a new version) when they differ from the present ones.
    pub fn update(&mut self, obstacles: Vec<Obstacle>) -> bool {
        if obstacles == self.scene.obstacle {
            return false;
        }
        self.scene.obstacle = obstacles;
        self.version += 1;
        true
    }

    /// Every obstacle as a circle around its footprint.
    pub fn circles(&self) -> Vec<Circle> {
        self.scene.circles()
    }
}

/// The obstacles of a perception message, as scene obstacles.
pub fn obstacles_of(list: &ObstacleListT) -> Vec<Obstacle> {
    list.obstacles.iter().map(obstacle_of).collect()
}

fn obstacle_of(o: &ObstacleT) -> Obstacle {
    let (base, height) = (o.z_min, Some(o.z_max - o.z_min));
    let v = |k: usize| o.vertices.get(k).copied().unwrap_or(o.center);
    match o.kind {
        ObstacleT::KIND_POLYGON if o.vertices.len() >= 3 => Obstacle::Polygon {
            points: o.vertices.iter().map(|p| [p[0], p[1]]).collect(),
            height,
            base,
        },
        ObstacleT::KIND_SPHERE => Obstacle::Sphere {
            centre: o.center,
            radius: o.radius,
        },
        ObstacleT::KIND_CAPSULE => Obstacle::Capsule {
            a: v(0),
            b: v(1),
            radius: o.radius,
        },
        ObstacleT::KIND_ROUNDED_TRIANGLE if o.vertices.len() >= 3 => Obstacle::RoundedTriangle {
            points: [v(0), v(1), v(2)],
            radius: o.radius,
        },
        _ => Obstacle::Circle {
            x: o.center[0],
            y: o.center[1],
            radius: o.radius,
            height,
            base,
        },
    }
}

/// A plan for `req` in `world`: the message, the planner's path and the growth around it that
/// the replanning check uses.
pub fn plan_request(req: &FootstepPlanRequestT, world: &World) -> (FootstepPlanT, Vec<V2>, f64) {
    let stance = v2(req.stance.x, req.stance.y);
    let swing = v2(req.swing.x, req.swing.y);
    let start = (stance + swing) * 0.5;
    let which = match req.planner {
        FootstepPlanRequestT::PLANNER_ARCHIE => Some(Which::Archie),
        FootstepPlanRequestT::PLANNER_KAIST => Some(Which::Kaist),
        FootstepPlanRequestT::PLANNER_LOLA => Some(Which::Lola),
        _ => None,
    };
    let refuse = |why: String| {
        let plan = Plan::failed(Status::NoPath, why, Stats::default());
        (to_msg(req, &plan, 0, true), Vec::new(), 0.0)
    };
    let Some(which) = which else {
        return refuse(format!(
            "unknown planner {} (PLANNER_ARCHIE, PLANNER_KAIST or PLANNER_LOLA)",
            req.planner
        ));
    };
    let numbers = [
        req.stance.x,
        req.stance.y,
        req.stance.z,
        req.stance.yaw,
        req.swing.x,
        req.swing.y,
        req.swing.z,
        req.swing.yaw,
        req.goal_x,
        req.goal_y,
        req.goal_yaw,
        req.goal_tolerance,
        req.goal_yaw_tolerance,
    ];
    if numbers.iter().any(|v| !v.is_finite()) {
        return refuse("a foot or the goal is not a finite number".into());
    }
    if req.stance.side == req.swing.side {
        return refuse("the stance and swing feet are the same side".into());
    }
    if req.goal_tolerance < 0.0 || req.goal_yaw_tolerance < 0.0 || req.max_expansions < 0 {
        return refuse("a tolerance or the expansion cap is negative".into());
    }
    let (mut horizon, mut corridor) = (None, None);
    for (name, value) in req.param_names.iter().zip(&req.param_values) {
        match name.as_str() {
            "horizon" if *value >= 1.0 => horizon = Some(*value as usize),
            "corridor" if *value > 0.0 => corridor = Some(*value),
            _ => {
                return refuse(format!(
                    "parameter {name} = {value} is not known (horizon >= 1 steps, corridor > 0 m)"
                ))
            }
        }
    }
    let r = Request {
        planner: which,
        faithful: req.faithful,
        start: Pose {
            x: start.x,
            y: start.y,
            yaw: req.stance.yaw,
            z: req.stance.z,
        },
        goal: Pose {
            x: req.goal_x,
            y: req.goal_y,
            yaw: req.goal_yaw,
            z: 0.0,
        },
        horizon,
        feet: Some((foot_of(&req.stance), foot_of(&req.swing))),
        tolerance: (req.goal_tolerance > 0.0).then_some(req.goal_tolerance),
        yaw_tolerance: (req.goal_yaw_tolerance > 0.0).then_some(req.goal_yaw_tolerance),
        max_expansions: (req.max_expansions > 0).then_some(req.max_expansions as u64),
        corridor,
    };
    let budget = if req.max_time_us > 0 {
        Duration::from_micros(req.max_time_us as u64)
    } else {
        match which {
            Which::Lola => Duration::from_millis(400),
            _ => Duration::from_millis(200),
        }
    };
    let plan = planner::plan(&r, &world.scene, budget);
    // The growth the replanning check puts around the path: the planner's own for Archie's,
    // half a foot for the footstep planners (their paths run between the feet).
    let inflation = match which {
        Which::Archie if req.faithful => Params::default().inflation,
        Which::Archie => Params::improved().inflation,
        _ => 0.1,
    };
    // Archie's footsteps list the standing foot, then the steps; the footstep planners list
    // both feet where they stand first.
    let standing = if which == Which::Archie { 1 } else { 2 };
    (
        to_msg(req, &plan, standing, false),
        plan.path.clone(),
        inflation,
    )
}

fn foot_of(f: &FootT) -> Foot {
    Foot {
        p: v2(f.x, f.y),
        z: f.z,
        yaw: f.yaw,
        left: f.side == FootT::SIDE_LEFT,
    }
}

fn foot_msg(f: &Foot) -> FootT {
    FootT {
        side: if f.left {
            FootT::SIDE_LEFT
        } else {
            FootT::SIDE_RIGHT
        },
        x: f.p.x,
        y: f.p.y,
        z: f.z,
        yaw: f.yaw,
    }
}

/// The plan as a message: the steps after the first `standing` feet of the plan (where the
/// feet stand), starting with the request's swing foot, padded with steps in place to at
/// least three; the request's ids echoed.
pub fn to_msg(
    req: &FootstepPlanRequestT,
    plan: &Plan,
    standing: usize,
    bad_request: bool,
) -> FootstepPlanT {
    let status = if bad_request {
        FootstepPlanT::STATUS_BAD_REQUEST
    } else {
        match plan.status {
            Status::Ok => FootstepPlanT::STATUS_OK,
            Status::Partial => FootstepPlanT::STATUS_PARTIAL,
            Status::NoPath => FootstepPlanT::STATUS_NO_PATH,
            Status::StartInCollision => FootstepPlanT::STATUS_START_IN_COLLISION,
            Status::GoalInCollision => FootstepPlanT::STATUS_GOAL_IN_COLLISION,
            Status::GoalOutsideMap => FootstepPlanT::STATUS_GOAL_OUTSIDE_MAP,
        }
    };
    let swing_left = req.swing.side == FootT::SIDE_LEFT;
    let mut feet: Vec<(FootT, bool)> = Vec::new();
    // The plan's first `standing` feet are where the feet stand; the steps follow.
    let mut planned: Vec<FootT> = plan.steps.iter().skip(standing).map(foot_msg).collect();
    if planned
        .first()
        .is_some_and(|f| (f.side == FootT::SIDE_LEFT) != swing_left)
    {
        // The swing foot steps in place first, so the sides keep alternating.
        planned.insert(
            0,
            FootT {
                ..req.swing.clone()
            },
        );
    }
    feet.extend(planned.into_iter().map(|f| (f, false)));
    // Padding: the two feet stepping in place where they end.
    let (mut a, mut b) = match feet.len() {
        0 => (req.swing.clone(), req.stance.clone()),
        1 => (req.stance.clone(), feet[0].0.clone()),
        n => (feet[n - 2].0.clone(), feet[n - 1].0.clone()),
    };
    while feet.len() < 3 {
        feet.push((a.clone(), true));
        std::mem::swap(&mut a, &mut b);
    }
    let steps: Vec<FootstepT> = feet
        .into_iter()
        .enumerate()
        .map(|(k, (foot, is_padding))| FootstepT {
            step_number: req.step_number + 1 + k as i64,
            foot,
            swing_height: 0.05,
            duration: 0.0,
            is_padding,
        })
        .collect();
    FootstepPlanT {
        header: HeaderT::default(),
        request_id: req.request_id,
        step_number: req.step_number,
        status,
        detail: plan.detail.clone(),
        num_steps: steps.len() as i32,
        steps,
        cost: if plan.cost.is_finite() {
            plan.cost
        } else {
            -1.0
        },
        expansions: plan.stats.expansions as i64,
        generated: plan.stats.generated as i64,
        collision_queries: plan.stats.collision_queries as i64,
        prepare_time_us: plan.stats.prepare.as_micros() as i64,
        search_time_us: plan.stats.search.as_micros() as i64,
        // The anytime searches' bound; 0 where a planner gives none.
        suboptimality: plan.bound.unwrap_or(0.0),
    }
}

/// A request for a robot standing with its feet side by side around `start`, facing `yaw`,
/// the left foot to swing first, to `goal`; Archie's planner, improved mode, no budget.
pub fn request_at(
    request_id: i64,
    step_number: i64,
    start: V2,
    yaw: f64,
    goal: V2,
) -> FootstepPlanRequestT {
    let side = v2(-yaw.sin(), yaw.cos()) * StepParams::default().half_stance;
    let foot = |p: V2, s: i8| FootT {
        side: s,
        x: p.x,
        y: p.y,
        z: 0.0,
        yaw,
    };
    FootstepPlanRequestT {
        request_id,
        step_number,
        stance: foot(start - side, FootT::SIDE_RIGHT),
        swing: foot(start + side, FootT::SIDE_LEFT),
        goal_x: goal.x,
        goal_y: goal.y,
        goal_yaw: yaw,
        planner: FootstepPlanRequestT::PLANNER_ARCHIE,
        ..Default::default()
    }
}

/// Why a plan is (re)computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reason {
    /// A new request (a new goal).
    Request,
    /// The world changed under the current plan.
    WorldChanged,
}

/// Decides when to plan: on every new request, and when the world changes so that the current
/// plan's path runs into a (grown) obstacle. Each change gives at most one plan.
#[derive(Debug, Default)]
pub struct Replanner {
    request: Option<FootstepPlanRequestT>,
    /// The path of the current plan, with the growth it was planned with.
    path: Vec<V2>,
    inflation: f64,
    planned_version: u64,
}

impl Replanner {
    /// A new request: plan it.
    pub fn on_request(
        &mut self,
        req: FootstepPlanRequestT,
    ) -> Option<(FootstepPlanRequestT, Reason)> {
        self.request = Some(req.clone());
        Some((req, Reason::Request))
    }

    /// The world changed (to `world`): plan again if the current path now runs into an
    /// obstacle, once for this version.
    pub fn on_world(&mut self, world: &World) -> Option<(FootstepPlanRequestT, Reason)> {
        let req = self.request.clone()?;
        if world.version == self.planned_version {
            return None;
        }
        let grown = archie::inflate(&world.circles(), self.inflation);
        let blocked = self.path.is_empty()
            || self
                .path
                .windows(2)
                .any(|w| grown.iter().any(|c| c.blocks(w[0], w[1])));
        // This version is settled either way: it does not block, or it gets its one replan.
        self.planned_version = world.version;
        blocked.then_some((req, Reason::WorldChanged))
    }

    /// A plan came back for `world_version`: remember its path.
    pub fn planned(&mut self, plan_path: Vec<V2>, inflation: f64, world_version: u64) {
        self.path = plan_path;
        self.inflation = inflation;
        self.planned_version = world_version;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(goal: (f64, f64), planner: i8, faithful: bool) -> FootstepPlanRequestT {
        FootstepPlanRequestT {
            planner,
            faithful,
            ..request_at(7, 40, v2(0.0, 0.0), 0.0, v2(goal.0, goal.1))
        }
    }

    fn circle(x: f64, y: f64, r: f64) -> Obstacle {
        Obstacle::Circle {
            x,
            y,
            radius: r,
            height: Some(1.0),
            base: 0.0,
        }
    }

    fn world() -> World {
        let mut w = World::default();
        w.update(vec![circle(2.0, 0.0, 0.5)]);
        w
    }

    #[test]
    fn plans_echo_the_request_and_alternate_from_the_swing_foot() {
        for faithful in [true, false] {
            let (msg, path, _) = plan_request(
                &request((4.0, 0.0), FootstepPlanRequestT::PLANNER_ARCHIE, faithful),
                &world(),
            );
            assert_eq!(msg.status, FootstepPlanT::STATUS_OK, "{}", msg.detail);
            assert_eq!((msg.request_id, msg.step_number), (7, 40));
            assert!(msg.num_steps >= 3 && msg.steps.len() == msg.num_steps as usize);
            assert_eq!(msg.steps[0].step_number, 41);
            assert_eq!(msg.steps[0].foot.side, FootT::SIDE_LEFT);
            for w in msg.steps.windows(2) {
                assert_ne!(w[0].foot.side, w[1].foot.side);
                assert_eq!(w[1].step_number, w[0].step_number + 1);
            }
            assert_eq!(path.last(), Some(&v2(4.0, 0.0)));
        }
    }

    #[test]
    fn failures_are_statuses_with_steps_in_place() {
        let (msg, _, _) = plan_request(&request((4.0, 0.0), 9, false), &world());
        assert_eq!(msg.status, FootstepPlanT::STATUS_BAD_REQUEST);
        assert!(msg.detail.contains("unknown planner 9"));
        assert_eq!(msg.num_steps, 3);
        assert!(msg.steps.iter().all(|s| s.is_padding));
        for planner in [
            FootstepPlanRequestT::PLANNER_ARCHIE,
            FootstepPlanRequestT::PLANNER_KAIST,
            FootstepPlanRequestT::PLANNER_LOLA,
        ] {
            let (msg, _, _) = plan_request(&request((2.0, 0.1), planner, false), &world());
            assert_eq!(
                msg.status,
                FootstepPlanT::STATUS_GOAL_IN_COLLISION,
                "{planner}"
            );
            assert_eq!(
                msg.steps[0].foot.side,
                FootT::SIDE_LEFT,
                "the swing foot first"
            );
            assert!(msg.num_steps >= 3);
        }
    }

    #[test]
    fn bad_requests_are_refused_with_reasons() {
        let good = request((4.0, 0.0), FootstepPlanRequestT::PLANNER_KAIST, false);
        let refused = |r: FootstepPlanRequestT, why: &str| {
            let (msg, _, _) = plan_request(&r, &World::default());
            assert_eq!(msg.status, FootstepPlanT::STATUS_BAD_REQUEST, "{why}");
            assert!(msg.detail.contains(why), "{}", msg.detail);
            assert!(msg.num_steps >= 3);
        };
        refused(
            FootstepPlanRequestT {
                goal_x: f64::NAN,
                ..good.clone()
            },
            "not a finite number",
        );
        let mut same = good.clone();
        same.swing.side = same.stance.side;
        refused(same, "same side");
        let mut param = good.clone();
        param.num_params = 1;
        param.param_names = vec!["speed".into()];
        param.param_values = vec![2.0];
        refused(param, "parameter speed = 2 is not known");
        // The request's cap is the search's.
        let capped = FootstepPlanRequestT {
            max_expansions: 3,
            ..good
        };
        let (msg, _, _) = plan_request(&capped, &World::default());
        assert!(msg.expansions <= 3 + 1, "{}", msg.expansions);
        assert_ne!(msg.status, FootstepPlanT::STATUS_OK);
    }

    #[test]
    fn every_planner_answers_through_the_node() {
        for planner in [
            FootstepPlanRequestT::PLANNER_KAIST,
            FootstepPlanRequestT::PLANNER_LOLA,
        ] {
            for faithful in [false, true] {
                let (msg, path, _) =
                    plan_request(&request((1.5, 0.0), planner, faithful), &World::default());
                assert_eq!(
                    msg.status,
                    FootstepPlanT::STATUS_OK,
                    "{planner}: {}",
                    msg.detail
                );
                assert!(msg.num_steps >= 3 && !path.is_empty());
                for w in msg.steps.windows(2) {
                    assert_ne!(w[0].foot.side, w[1].foot.side);
                }
                // The anytime search says how good its plan is; the thesis's gives no bound.
                if faithful {
                    assert_eq!(msg.suboptimality, 0.0);
                } else {
                    assert!(msg.suboptimality >= 1.0, "{}", msg.suboptimality);
                }
                // The first step is the swing foot's, forwards: not a step in place.
                let first = &msg.steps[0];
                assert_eq!(first.foot.side, FootT::SIDE_LEFT);
                assert!(
                    !first.is_padding && first.foot.x > 0.05,
                    "{planner}: {first:?}"
                );
            }
        }
    }

    #[test]
    fn replans_once_per_change_that_blocks_the_plan() {
        let mut w = world();
        let mut r = Replanner::default();
        let req = request((4.0, 0.0), FootstepPlanRequestT::PLANNER_ARCHIE, false);
        assert_eq!(r.on_world(&w), None, "no request yet");
        let (req, why) = r.on_request(req).unwrap();
        assert_eq!(why, Reason::Request);
        let (_, path, inflation) = plan_request(&req, &w);
        r.planned(path, inflation, w.version);
        // An obstacle far away: the plan stands.
        let mut far = w.scene.obstacle.clone();
        far.push(circle(0.0, 5.0, 0.5));
        assert!(w.update(far.clone()));
        assert_eq!(r.on_world(&w), None);
        // The same world again: nothing changed.
        assert!(!w.update(far.clone()));
        // One across the path: one replan, not two.
        let mut across = far;
        across.push(circle(3.2, 0.7, 0.4));
        across.push(circle(3.2, -0.7, 0.4));
        assert!(w.update(across));
        assert_eq!(r.on_world(&w).map(|x| x.1), Some(Reason::WorldChanged));
        assert_eq!(r.on_world(&w), None, "once per change");
    }
}
