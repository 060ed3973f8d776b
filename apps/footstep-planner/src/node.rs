//! The logic of the `stride-footstep-planner` node, apart from the bus: turning a request and
//! the world into a `stride.footstep_plan_t`, and deciding when to plan again (a new request,
//! or a world that changed under the current plan), exactly once per change.

use std::time::Duration;

use stride_lcmtypes::stride::{
    FootT, FootstepPlanRequestT, FootstepPlanT, FootstepT, HeaderT, ObstacleListT, ObstacleT,
};

use crate::archie::{self, headings, Params};
use crate::geom::{v2, Circle, V2};
use crate::plan::{Foot, Plan, Stats, Status};
use crate::steps::{self, StepParams};

/// What the planner knows of the world: circles around the obstacles, and a version that
/// changes when they do.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct World {
    /// Obstacles (not grown).
    pub circles: Vec<Circle>,
    /// Bumped by every change.
    pub version: u64,
}

impl World {
    /// Replaces the obstacles; true (and a new version) when they differ from the present ones.
    pub fn update(&mut self, circles: Vec<Circle>) -> bool {
        if circles == self.circles {
            return false;
        }
        self.circles = circles;
        self.version += 1;
        true
    }
}

/// The obstacles of a perception message as circles (polygons and LOLA's primitives by the
/// circle around their footprint).
pub fn circles_of(list: &ObstacleListT) -> Vec<Circle> {
    list.obstacles.iter().map(circle_of).collect()
}

fn circle_of(o: &ObstacleT) -> Circle {
    let c = v2(o.center[0], o.center[1]);
    if o.kind == ObstacleT::KIND_CIRCLE || o.kind == ObstacleT::KIND_SPHERE || o.vertices.is_empty()
    {
        return Circle { c, r: o.radius };
    }
    let pts: Vec<V2> = o.vertices.iter().map(|v| v2(v[0], v[1])).collect();
    let centre = pts
        .iter()
        .fold(v2(0.0, 0.0), |a, &p| a + p * (1.0 / pts.len() as f64));
    let r = pts.iter().map(|p| p.dist(centre)).fold(0.0, f64::max) + o.radius.max(0.0);
    Circle { c: centre, r }
}

/// A plan for `req` in `world`: the message, the planner's path and the growth it used.
pub fn plan_request(req: &FootstepPlanRequestT, world: &World) -> (FootstepPlanT, Vec<V2>, f64) {
    let stance = v2(req.stance.x, req.stance.y);
    let swing = v2(req.swing.x, req.swing.y);
    let start = (stance + swing) * 0.5;
    let start_yaw = req.stance.yaw;
    let goal = v2(req.goal_x, req.goal_y);
    let mut params = if req.faithful {
        Params::default()
    } else {
        Params::improved()
    };
    if req.max_time_us > 0 {
        params.budget = Duration::from_micros(req.max_time_us as u64);
    }
    let plan = if req.planner != FootstepPlanRequestT::PLANNER_ARCHIE {
        Plan::failed(
            Status::NoPath,
            "only Archie's planner (PLANNER_ARCHIE) is built; KAIST and LOLA are not yet",
            Stats::default(),
        )
    } else if req.faithful {
        let mut p = archie::plan_tree(start, goal, &world.circles, &params).0;
        if p.status == Status::Ok {
            p.steps = steps::faithful(
                &p.path,
                &headings(&p.path, start_yaw),
                &StepParams::default(),
                true,
            );
        }
        p
    } else {
        let mut p = archie::plan_exact(start, goal, &world.circles, &params);
        if p.status == Status::Ok {
            p.steps = steps::improved(&p.path, start_yaw, &StepParams::default());
        }
        p
    };
    let bad_request = req.planner != FootstepPlanRequestT::PLANNER_ARCHIE;
    (
        to_msg(req, &plan, bad_request),
        plan.path.clone(),
        params.inflation,
    )
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
        z: 0.0,
        yaw: f.yaw,
    }
}

/// The plan as a message: the steps after the standing foot, starting with the request's
/// swing foot, padded with steps in place to at least three; the request's ids echoed.
pub fn to_msg(req: &FootstepPlanRequestT, plan: &Plan, bad_request: bool) -> FootstepPlanT {
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
    // The planners' first foot is the standing (right) one; the steps follow.
    let mut planned: Vec<FootT> = plan.steps.iter().skip(1).map(foot_msg).collect();
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
        suboptimality: 1.0,
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
        let grown = archie::inflate(&world.circles, self.inflation);
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

    fn world() -> World {
        let mut w = World::default();
        w.update(vec![Circle {
            c: v2(2.0, 0.0),
            r: 0.5,
        }]);
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
        let (msg, _, _) = plan_request(
            &request((4.0, 0.0), FootstepPlanRequestT::PLANNER_KAIST, false),
            &world(),
        );
        assert_eq!(msg.status, FootstepPlanT::STATUS_BAD_REQUEST);
        assert!(msg.detail.contains("only Archie"));
        assert_eq!(msg.num_steps, 3);
        assert!(msg.steps.iter().all(|s| s.is_padding));
        let (msg, _, _) = plan_request(
            &request((2.0, 0.1), FootstepPlanRequestT::PLANNER_ARCHIE, false),
            &world(),
        );
        assert_eq!(msg.status, FootstepPlanT::STATUS_GOAL_IN_COLLISION);
        assert_eq!(
            msg.steps[0].foot.side,
            FootT::SIDE_LEFT,
            "the swing foot first"
        );
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
        let mut far = w.circles.clone();
        far.push(Circle {
            c: v2(0.0, 5.0),
            r: 0.5,
        });
        assert!(w.update(far.clone()));
        assert_eq!(r.on_world(&w), None);
        // The same world again: nothing changed.
        assert!(!w.update(far.clone()));
        // One across the path: one replan, not two.
        let mut across = far;
        across.push(Circle {
            c: v2(3.2, 0.7),
            r: 0.4,
        });
        across.push(Circle {
            c: v2(3.2, -0.7),
            r: 0.4,
        });
        assert!(w.update(across));
        assert_eq!(r.on_world(&w).map(|x| x.1), Some(Reason::WorldChanged));
        assert_eq!(r.on_world(&w), None, "once per change");
    }
}
