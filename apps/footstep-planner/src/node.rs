//! The logic of the `stride-footstep-planner` node, apart from the bus: turning a request and
//! the world into a `stride.footstep_plan_t`, and deciding when to plan again (a new request,
//! or a world that changed under the current plan), exactly once per change.

use std::time::Duration;

use stride_lcmtypes::stride::{
    FootT, FootstepPlanRequestT, FootstepPlanT, FootstepT, HeaderT, ObstacleListT, ObstacleT,
};

use stride_footstep::archie;
use stride_footstep::archie::steps::StepParams;
use stride_footstep::geom::{v2, Circle, V2};
use stride_footstep::plan::{Cancel, Foot, Plan, Stats, Status};
use stride_footstep::planner::{self, Limits, Request, Which};
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

/// The obstacles of a perception message, as scene obstacles; the whole list is refused when
/// one of them is not made of finite numbers within `reach` m (a NaN centre, an infinite or
/// absurd radius), or when it holds more than `max` obstacles.
pub fn obstacles_of(list: &ObstacleListT, reach: f64, max: usize) -> Result<Vec<Obstacle>, String> {
    if list.obstacles.len() > max {
        return Err(format!(
            "{} obstacles, more than the {max} allowed",
            list.obstacles.len()
        ));
    }
    list.obstacles
        .iter()
        .enumerate()
        .map(|(i, o)| {
            let ob = obstacle_of(o);
            ob.check(reach).map_err(|e| format!("obstacle {i}: {e}"))?;
            if o.radius < 0.0 {
                return Err(format!("obstacle {i}: radius {} is negative", o.radius));
            }
            Ok(ob)
        })
        .collect()
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

/// A plan for `req` in `world` within `limits` (`cancel` stops it): the message, the
/// planner's path and the growth around it that the replanning check uses.
pub fn plan_request(
    req: &FootstepPlanRequestT,
    world: &World,
    limits: &Limits,
    cancel: &Cancel,
) -> (FootstepPlanT, Vec<V2>, f64) {
    let stance = v2(req.stance.x, req.stance.y);
    let swing = v2(req.swing.x, req.swing.y);
    let start = (stance + swing) * 0.5;
    let refuse = |why: String| {
        let plan = Plan::failed(Status::NoPath, why, Stats::default());
        (to_msg(req, &plan, 0, true), Vec::new(), 0.0)
    };
    let which = match Which::try_from(req.planner) {
        Ok(w) => w,
        Err(why) => return refuse(why),
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
    let (mut horizon, mut corridor, mut max_step) = (None, None, None);
    for (name, value) in req.param_names.iter().zip(&req.param_values) {
        match name.as_str() {
            "horizon" if *value >= 1.0 => horizon = Some(*value as usize),
            "corridor" if *value > 0.0 => corridor = Some(*value),
            "max_step" if (0.05..=0.5).contains(value) => max_step = Some(*value),
            _ => {
                return refuse(format!(
                    "parameter {name} = {value} is not known (horizon >= 1 steps, corridor > 0 \
                     m, max_step 0.05 to 0.5 m)"
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
        inflation: None,
        max_step,
    };
    let budget = if req.max_time_us > 0 {
        Duration::from_micros(req.max_time_us as u64)
    } else {
        which.default_budget()
    };
    let plan = planner::plan_within(&r, &world.scene, budget, limits, cancel);
    (
        to_msg(req, &plan, which.standing(), false),
        plan.path.clone(),
        which.replan_inflation(req.faithful),
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
            Status::Refused => FootstepPlanT::STATUS_BAD_REQUEST,
            Status::Cancelled => FootstepPlanT::STATUS_SUPERSEDED,
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
            // Nothing stands between the contacts: the planners keep off obstacles, and the
            // gait clears the higher contact by its own clearance.
            swing_height: 0.0,
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

/// A search to run: the request, the world as it was, why, and the flag that cancels it.
#[derive(Debug, Clone)]
pub struct Job {
    /// The request.
    pub req: FootstepPlanRequestT,
    /// The world to plan in.
    pub world: World,
    /// Why it is planned.
    pub reason: Reason,
    /// Set to stop it.
    pub cancel: Cancel,
}

impl Job {
    /// Who asked: requests with the same `header.frame` come from the same requester.
    pub fn requester(&self) -> &str {
        &self.req.header.frame
    }

    /// The answer to a job that will not be planned (superseded, or the node stopping).
    pub fn superseded(&self, why: &str) -> FootstepPlanT {
        let plan = Plan::failed(Status::Cancelled, why, Stats::default());
        to_msg(&self.req, &plan, 0, false)
    }
}

/// The order searches run in, one at a time: a new request supersedes its requester's
/// waiting one and cancels its running one, so a requester always gets its latest request
/// planned, and every request is answered (the superseded ones with `STATUS_SUPERSEDED`).
/// Other requesters' requests wait their turn, at most `max_waiting` of them; beyond, the
/// oldest waiting is superseded.
#[derive(Debug)]
pub struct Scheduler {
    waiting: std::collections::VecDeque<Job>,
    running: Option<Job>,
    max_waiting: usize,
}

impl Scheduler {
    /// A scheduler keeping at most `max_waiting` jobs waiting (at least 1).
    pub fn new(max_waiting: usize) -> Scheduler {
        Scheduler {
            waiting: Default::default(),
            running: None,
            max_waiting: max_waiting.max(1),
        }
    }

    /// Queues `job`; returns the jobs it supersedes (to be answered), and cancels the running
    /// job of the same requester (its search stops and answers as cancelled).
    pub fn push(&mut self, job: Job) -> Vec<Job> {
        let who = job.requester().to_owned();
        let (mut gone, keep): (Vec<Job>, Vec<Job>) =
            self.waiting.drain(..).partition(|j| j.requester() == who);
        self.waiting = keep.into();
        if let Some(r) = &self.running {
            if r.requester() == who {
                r.cancel.cancel();
            }
        }
        self.waiting.push_back(job);
        while self.waiting.len() > self.max_waiting {
            gone.extend(self.waiting.pop_front());
        }
        gone
    }

    /// The next job to run, when none is running.
    pub fn start_next(&mut self) -> Option<Job> {
        if self.running.is_some() {
            return None;
        }
        self.running = self.waiting.pop_front();
        self.running.clone()
    }

    /// The running job finished.
    pub fn done(&mut self) {
        self.running = None;
    }

    /// True while a job runs.
    pub fn busy(&self) -> bool {
        self.running.is_some()
    }

    /// Stopping: cancels the running job and returns the waiting ones (to be answered).
    pub fn stop(&mut self) -> Vec<Job> {
        if let Some(r) = &self.running {
            r.cancel.cancel();
        }
        self.waiting.drain(..).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_planners_numbers_are_the_messages_constants() {
        let constants = [
            (Which::Archie, FootstepPlanRequestT::PLANNER_ARCHIE),
            (Which::Kaist, FootstepPlanRequestT::PLANNER_KAIST),
            (Which::Lola, FootstepPlanRequestT::PLANNER_LOLA),
        ];
        for (w, id) in constants {
            assert_eq!(w.id(), id);
            assert_eq!(Which::try_from(id), Ok(w));
            assert_eq!(w.to_string().parse::<Which>(), Ok(w));
        }
        assert!(Which::try_from(3)
            .unwrap_err()
            .contains("unknown planner 3"));
        assert!("hexapod".parse::<Which>().is_err());
    }

    fn plan(req: &FootstepPlanRequestT, world: &World) -> (FootstepPlanT, Vec<V2>, f64) {
        plan_request(req, world, &Limits::default(), &Cancel::new())
    }

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
            let (msg, path, _) = plan(
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
        let (msg, _, _) = plan(&request((4.0, 0.0), 9, false), &world());
        assert_eq!(msg.status, FootstepPlanT::STATUS_BAD_REQUEST);
        assert!(msg.detail.contains("unknown planner 9"));
        assert_eq!(msg.num_steps, 3);
        assert!(msg.steps.iter().all(|s| s.is_padding));
        for planner in [
            FootstepPlanRequestT::PLANNER_ARCHIE,
            FootstepPlanRequestT::PLANNER_KAIST,
            FootstepPlanRequestT::PLANNER_LOLA,
        ] {
            let (msg, _, _) = plan(&request((2.0, 0.1), planner, false), &world());
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
            let (msg, _, _) = plan(&r, &World::default());
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
        let (msg, _, _) = plan(&capped, &World::default());
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
                    plan(&request((1.5, 0.0), planner, faithful), &World::default());
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
                // KAIST's anytime search says how good its plan is; the thesis's search gives
                // no bound, nor does LOLA's (its heuristic is no lower bound).
                if faithful || planner == FootstepPlanRequestT::PLANNER_LOLA {
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
        let (_, path, inflation) = plan(&req, &w);
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

    fn job(id: i64, who: &str) -> Job {
        let mut req = request_at(id, 0, v2(0.0, 0.0), 0.0, v2(1.0, 0.0));
        req.header.frame = who.into();
        Job {
            req,
            world: World::default(),
            reason: Reason::Request,
            cancel: Cancel::new(),
        }
    }

    #[test]
    fn a_requesters_new_request_supersedes_its_waiting_one_and_cancels_its_running_one() {
        let mut s = Scheduler::new(4);
        assert!(s.push(job(1, "a")).is_empty());
        let running = s.start_next().unwrap();
        assert_eq!(running.req.request_id, 1);
        assert!(s.push(job(2, "a")).is_empty());
        assert!(
            running.cancel.is_cancelled(),
            "the running search of the same requester"
        );
        assert!(s.push(job(3, "b")).is_empty());
        let gone = s.push(job(4, "a"));
        assert_eq!(
            gone.iter().map(|j| j.req.request_id).collect::<Vec<_>>(),
            [2]
        );
        assert!(s.start_next().is_none(), "one search at a time");
        s.done();
        assert_eq!(
            s.start_next().unwrap().req.request_id,
            3,
            "other requesters keep their turn"
        );
        s.done();
        assert_eq!(s.start_next().unwrap().req.request_id, 4);
        let ans = gone[0].superseded("superseded by request 4");
        assert_eq!(ans.status, FootstepPlanT::STATUS_SUPERSEDED);
        assert_eq!(ans.request_id, 2);
    }

    #[test]
    fn waiting_beyond_the_bound_supersedes_the_oldest_and_stop_returns_the_rest() {
        let mut s = Scheduler::new(2);
        s.push(job(1, "a"));
        s.start_next();
        assert!(s.push(job(2, "b")).is_empty());
        assert!(s.push(job(3, "c")).is_empty());
        let gone = s.push(job(4, "d"));
        assert_eq!(gone[0].req.request_id, 2);
        let left = s.stop();
        assert_eq!(left.len(), 2);
    }

    #[test]
    fn an_obstacle_list_with_a_bad_number_is_refused_whole() {
        let circle = |x: f64, r: f64| ObstacleT {
            kind: ObstacleT::KIND_CIRCLE,
            center: [x, 0.0, 0.0],
            radius: r,
            z_max: 1.0,
            ..Default::default()
        };
        let list = |v: Vec<ObstacleT>| ObstacleListT {
            num_obstacles: v.len() as i32,
            obstacles: v,
            ..Default::default()
        };
        assert!(obstacles_of(&list(vec![circle(2.0, 0.3)]), 1000.0, 10).is_ok());
        for bad in [
            circle(2.0, f64::INFINITY),
            circle(2.0, 1e9),
            circle(f64::NAN, 0.3),
            circle(2.0, -0.3),
        ] {
            let e = obstacles_of(&list(vec![circle(1.0, 0.2), bad]), 1000.0, 10).unwrap_err();
            assert!(e.starts_with("obstacle 1"), "{e}");
        }
        assert!(obstacles_of(&list(vec![circle(1.0, 0.2); 11]), 1000.0, 10).is_err());
    }

    #[test]
    fn a_goal_a_thousand_kilometres_away_is_refused_not_planned() {
        let (msg, path, _) = plan(
            &request_at(1, 0, v2(0.0, 0.0), 0.0, v2(1e6, 0.0)),
            &World::default(),
        );
        assert_eq!(
            msg.status,
            FootstepPlanT::STATUS_BAD_REQUEST,
            "{}",
            msg.detail
        );
        assert!(path.is_empty() && msg.num_steps == 3);
    }
}
