//! The planner as an app: its command line, the node that answers requests (the searches on
//! their own thread), and `--ask`, the client that sends one request and prints the answer.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::Context;
use stride_footstep::plan::{Cancel, Plan, Stats, Status};
use stride_footstep::planner::{Limits, Which};
use stride_lcmtypes::stride::{
    FootT, FootstepPlanRequestT, FootstepPlanT, NodeStatusT, ObstacleListT,
};
use stride_node::{outln, AppConfig, ConfigUse, Done, Node, NodeArgs, Stamper, Tick, Worker};

use crate::node::{
    obstacles_of, plan_request, request_at, to_msg, Job, Reason, Replanner, Scheduler, World,
};
use stride_footstep::geom::{v2, V2};
use stride_footstep::scene::Scene;

/// Plan footsteps on request.
///
/// Takes stride.footstep_plan_request_t (the feet, the goal, the planner and its mode, a
/// budget) and answers with stride.footstep_plan_t (at least three steps, padded in place when
/// needed; the request's ids and the walking controller's step number echoed; status, cost and
/// search metrics). The world comes from the mapper's stride.obstacle_list_t, or from a scene
/// file (--scene). When the world changes so that the current plan runs into an obstacle, or a
/// new request comes, it plans again, once per change. Searches run beside the bus loop, never
/// in it. Every planner answers, faithful or improved: Archie's (PLANNER_ARCHIE), the KAIST
/// energy A* (PLANNER_KAIST, on an elevation grid made from the world; budget 200 ms unless the
/// request gives one) and LOLA's (PLANNER_LOLA, with the scene's surfaces; 400 ms). An unknown
/// planner is answered with STATUS_BAD_REQUEST, and so is a request beyond the configured
/// limits (--config: goal distance, budget, steps, the world's reach), with the reason; an
/// obstacle list with an obstacle that is not finite or beyond the reach is refused whole.
/// Every request is answered: a newer request from the same requester (header.frame)
/// supersedes its waiting one and cancels its running search, both answered with
/// STATUS_SUPERSEDED; so are the waiting ones at shutdown. A planner that fails on a request
/// answers it and goes on. The node status counts what was planned, superseded, refused and
/// failed.
#[derive(clap::Parser, Debug)]
#[command(name = "stride-footstep-planner", version, about, long_about)]
pub struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    /// Take the obstacles from this scene file instead of the mapper.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Channel of incoming requests.
    #[arg(long, default_value = "FOOTSTEP_PLAN_REQUEST")]
    request_channel: String,
    /// Channel of outgoing plans.
    #[arg(long, default_value = "FOOTSTEP_PLAN")]
    plan_channel: String,
    /// Channel of the mapper's obstacles.
    #[arg(long, default_value = "OBSTACLES")]
    obstacle_channel: String,
    /// Instead of planning, ask the planner running on the bus once: the goal as X,Y (metres)
    /// for a robot standing at the origin facing +x; prints the plan and exits (0 for a plan,
    /// 1 otherwise).
    #[arg(long, value_name = "X,Y", value_parser = parse_goal)]
    pub ask: Option<(f64, f64)>,
    /// With --ask: which planner: archie, kaist or lola.
    #[arg(long, default_value = "archie")]
    planner: Which,
    /// With --ask: the thesis's planner instead of the improved one.
    #[arg(long)]
    faithful: bool,
    /// With --ask: the planner's budget, ms (0: its own).
    #[arg(long, default_value_t = 0)]
    budget_ms: u64,
    /// With --ask: how long to wait for the answer, s.
    #[arg(long, default_value_t = 5.0)]
    wait_s: f64,
}

stride_node::node_cli!(Cli);

fn parse_goal(s: &str) -> Result<(f64, f64), String> {
    let (x, y) = s
        .split_once(',')
        .ok_or_else(|| format!("{s:?}: the goal is X,Y in metres"))?;
    let num = |v: &str| {
        v.trim()
            .parse::<f64>()
            .ok()
            .filter(|n| n.is_finite())
            .ok_or_else(|| format!("{v:?} is not a finite number of metres"))
    };
    Ok((num(x)?, num(y)?))
}

/// The words for a plan's status.
pub fn status_name(status: i8) -> &'static str {
    match status {
        FootstepPlanT::STATUS_OK => "ok",
        FootstepPlanT::STATUS_PARTIAL => "partial",
        FootstepPlanT::STATUS_NO_PATH => "no path",
        FootstepPlanT::STATUS_START_IN_COLLISION => "start in collision",
        FootstepPlanT::STATUS_GOAL_IN_COLLISION => "goal in collision",
        FootstepPlanT::STATUS_GOAL_OUTSIDE_MAP => "goal outside the map",
        _ => "bad request",
    }
}

/// `--ask`: one request out, its answer printed.
pub struct Asker {
    cli: Cli,
    id: i64,
    _sub: lcm::Subscription,
    plans: mpsc::Receiver<FootstepPlanT>,
    until: Instant,
}

impl Asker {
    /// Sends the request.
    pub fn start(node: &Node, cli: Cli) -> anyhow::Result<Asker> {
        let goal = cli.ask.context("--ask X,Y")?;
        if !(cli.wait_s > 0.0 && cli.wait_s.is_finite()) {
            anyhow::bail!("--wait-s must be a positive number of seconds");
        }
        let (sub, plans) = node.queue::<FootstepPlanT>(&cli.plan_channel)?;
        let id = std::process::id() as i64;
        let mut req = request_at(id, 0, v2(0.0, 0.0), 0.0, v2(goal.0, goal.1));
        req.planner = cli.planner.id();
        req.faithful = cli.faithful;
        req.max_time_us = cli.budget_ms.saturating_mul(1000).min(i64::MAX as u64) as i64;
        node.lcm().publish(&cli.request_channel, &req)?;
        Ok(Asker {
            until: Instant::now() + Duration::from_secs_f64(cli.wait_s),
            cli,
            id,
            _sub: sub,
            plans,
        })
    }

    fn print(&self, plan: &FootstepPlanT) -> std::io::Result<()> {
        let detail = if plan.detail.is_empty() {
            String::new()
        } else {
            format!(": {}", plan.detail)
        };
        outln!(
            "{:?} ({}): status {} ({}{detail}), cost {:.3}, {} steps, {} expansions, {} µs",
            self.cli.planner,
            if self.cli.faithful {
                "faithful"
            } else {
                "improved"
            },
            plan.status,
            status_name(plan.status),
            plan.cost,
            plan.num_steps,
            plan.expansions,
            plan.prepare_time_us + plan.search_time_us
        )?;
        for s in &plan.steps {
            outln!(
                "  step {:>3} {} x {:>7.3} y {:>7.3} z {:>6.3} yaw {:>7.2}°{}",
                s.step_number,
                if s.foot.side == FootT::SIDE_LEFT {
                    "L"
                } else {
                    "R"
                },
                s.foot.x,
                s.foot.y,
                s.foot.z,
                s.foot.yaw.to_degrees(),
                if s.is_padding { "  (in place)" } else { "" }
            )?;
        }
        Ok(())
    }
}

impl Tick for Asker {
    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        while let Ok(plan) = self.plans.try_recv() {
            if plan.request_id != self.id {
                continue;
            }
            self.print(&plan)?;
            let ok =
                [FootstepPlanT::STATUS_OK, FootstepPlanT::STATUS_PARTIAL].contains(&plan.status);
            node.exit_with(if ok { 0 } else { 1 });
            return Ok(now);
        }
        if now >= self.until {
            anyhow::bail!(
                "no answer on {} within {} s: is stride-footstep-planner running?",
                self.cli.plan_channel,
                self.cli.wait_s
            );
        }
        Ok(self.until.min(now + Duration::from_millis(10)))
    }
}

/// The planner's TOML configuration: what it takes (requests and worlds beyond are refused
/// with STATUS_BAD_REQUEST and the reason) and how many requests may wait.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlannerConfig {
    /// The farthest the goal may be from the robot, m.
    pub max_goal_distance_m: f64,
    /// The farthest from the origin any number of the world may be (obstacles' coordinates
    /// and sizes, surfaces, map), m.
    pub reach_m: f64,
    /// The most steps a plan may have.
    pub max_steps: usize,
    /// The longest budget a request may ask for, ms.
    pub max_budget_ms: u64,
    /// The most obstacles an obstacle list may hold.
    pub max_obstacles: usize,
    /// Requests of other requesters that may wait while one is planned.
    pub max_waiting: usize,
}

impl Default for PlannerConfig {
    fn default() -> Self {
        let l = Limits::default();
        PlannerConfig {
            max_goal_distance_m: l.max_goal_distance,
            reach_m: l.reach,
            max_steps: l.max_steps,
            max_budget_ms: l.max_budget.as_millis() as u64,
            max_obstacles: 10_000,
            max_waiting: 16,
        }
    }
}

impl PlannerConfig {
    /// The planners' limits.
    pub fn limits(&self) -> Limits {
        Limits {
            max_goal_distance: self.max_goal_distance_m,
            reach: self.reach_m,
            max_steps: self.max_steps,
            max_budget: Duration::from_millis(self.max_budget_ms),
            ..Limits::default()
        }
    }
}

impl AppConfig for PlannerConfig {
    const USE: ConfigUse = ConfigUse::Optional;
    fn defaults() -> Option<Self> {
        Some(PlannerConfig::default())
    }
    fn check(&self) -> Result<(), String> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(self.max_goal_distance_m) || !positive(self.reach_m) {
            return Err("max_goal_distance_m and reach_m must be positive".into());
        }
        if self.max_steps == 0 || self.max_budget_ms == 0 || self.max_waiting == 0 {
            return Err("max_steps, max_budget_ms and max_waiting must be positive".into());
        }
        Ok(())
    }
}

/// A search's answer: the plan, the path it followed and its inflation.
type Answer = (FootstepPlanT, Vec<V2>, f64);

/// The search thread, running the planners (or another search in a test) on each job.
fn search_thread(
    limits: Limits,
    search: fn(&FootstepPlanRequestT, &World, &Limits, &Cancel) -> Answer,
) -> std::io::Result<Worker<Job, Answer>> {
    Worker::spawn("search", move |job: &Job| {
        search(&job.req, &job.world, &limits, &job.cancel)
    })
}

/// What the node has answered, for its status.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    /// Plans answered after a search.
    pub planned: u64,
    /// Requests answered as superseded.
    pub superseded: u64,
    /// Requests or worlds refused (beyond the limits, malformed).
    pub refused: u64,
    /// Searches that failed (a panic in a planner), answered with STATUS_BAD_REQUEST.
    pub failed: u64,
    /// Times the search thread was started again.
    pub restarts: u64,
}

/// The node: requests and the world in, jobs to the search thread one at a time, plans out.
pub struct PlannerApp {
    cli: Cli,
    cfg: PlannerConfig,
    world: World,
    _subs: [lcm::Subscription; 2],
    requests: mpsc::Receiver<FootstepPlanRequestT>,
    obstacles: mpsc::Receiver<ObstacleListT>,
    worker: Worker<Job, Answer>,
    scheduler: Scheduler,
    stamper: Stamper,
    replanner: Replanner,
    counts: Counts,
    last_problem: String,
}

impl PlannerApp {
    /// Loads the scene, subscribes and starts the search thread.
    pub fn start(node: &Node, cli: Cli, cfg: PlannerConfig) -> anyhow::Result<PlannerApp> {
        let world = match &cli.scene {
            Some(path) => World::from_scene(
                Scene::load(path).with_context(|| format!("loading {}", path.display()))?,
            ),
            None => World::default(),
        };
        let (req_sub, requests) = node.queue::<FootstepPlanRequestT>(&cli.request_channel)?;
        // A burst of requests waits for the loop rather than being dropped: each is answered.
        req_sub.set_queue_capacity(10_000)?;
        let (obs_sub, obstacles) = node.queue::<ObstacleListT>(&cli.obstacle_channel)?;
        let worker = search_thread(cfg.limits(), plan_request)?;
        Ok(PlannerApp {
            scheduler: Scheduler::new(cfg.max_waiting),
            cli,
            cfg,
            world,
            _subs: [req_sub, obs_sub],
            requests,
            obstacles,
            worker,
            stamper: Stamper::new("world"),
            replanner: Replanner::default(),
            counts: Counts::default(),
            last_problem: String::new(),
        })
    }

    /// What it has answered so far.
    pub fn counts(&self) -> Counts {
        Counts {
            restarts: self.worker.restarts(),
            ..self.counts
        }
    }

    fn publish(&mut self, node: &Node, mut msg: FootstepPlanT) {
        msg.header = self.stamper.stamp();
        if let Err(e) = node.lcm().publish(&self.cli.plan_channel, &msg) {
            tracing::warn!(error = %e, "could not publish the plan");
        }
    }

    fn supersede(&mut self, node: &Node, gone: Vec<Job>, why: &str) {
        for j in gone {
            self.counts.superseded += 1;
            let msg = j.superseded(why);
            self.publish(node, msg);
        }
    }

    fn queue(&mut self, node: &Node, req: FootstepPlanRequestT, reason: Reason) {
        let job = Job {
            req,
            world: self.world.clone(),
            reason,
            cancel: Cancel::new(),
        };
        let id = job.req.request_id;
        let gone = self.scheduler.push(job);
        self.supersede(node, gone, &format!("superseded by request {id}"));
    }

    /// Hands the next job to the search thread (started again if it died).
    fn dispatch(&mut self) -> anyhow::Result<()> {
        if let Some(job) = self.scheduler.start_next() {
            // The scheduler starts a job only when none runs: nothing waits in the thread.
            let _ = self.worker.offer(job)?;
        }
        Ok(())
    }

    fn answer(&mut self, node: &Node, Done { job, out, took }: Done<Job, Answer>) {
        self.scheduler.done();
        let mut msg = match out {
            Ok((msg, path, inflation)) => {
                if msg.status != FootstepPlanT::STATUS_SUPERSEDED {
                    self.replanner.planned(path, inflation, job.world.version);
                }
                msg
            }
            Err(panic) => {
                self.counts.failed += 1;
                let why = format!("the planner failed on this request ({panic})");
                let plan = Plan::failed(Status::Refused, why, Stats::default());
                to_msg(&job.req, &plan, 0, true)
            }
        };
        match msg.status {
            FootstepPlanT::STATUS_SUPERSEDED => {
                self.counts.superseded += 1;
                msg.detail = "superseded while planning".into();
            }
            FootstepPlanT::STATUS_BAD_REQUEST => self.counts.refused += 1,
            _ => self.counts.planned += 1,
        }
        tracing::info!(
            request = msg.request_id,
            reason = ?job.reason,
            status = msg.status,
            steps = msg.num_steps,
            micros = took.as_micros() as u64,
            "plan"
        );
        if ![FootstepPlanT::STATUS_OK, FootstepPlanT::STATUS_SUPERSEDED].contains(&msg.status) {
            self.last_problem = format!("request {}: {}", msg.request_id, msg.detail);
        }
        self.publish(node, msg);
    }

    fn report(&self, node: &Node) {
        let c = self.counts();
        let counts = format!(
            "planned {}, superseded {}, refused {}, failed {}, search restarts {}",
            c.planned, c.superseded, c.refused, c.failed, c.restarts
        );
        if self.last_problem.is_empty() {
            node.set_health(NodeStatusT::STATE_RUNNING, counts);
        } else {
            node.set_health(
                NodeStatusT::STATE_DEGRADED,
                format!("{}; {counts}", self.last_problem),
            );
        }
    }
}

impl Tick for PlannerApp {
    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        while let Ok(req) = self.requests.try_recv() {
            if let Some((req, reason)) = self.replanner.on_request(req) {
                self.queue(node, req, reason);
            }
        }
        while let Ok(list) = self.obstacles.try_recv() {
            if self.cli.scene.is_some() {
                continue; // the scene is the world
            }
            match obstacles_of(&list, self.cfg.reach_m, self.cfg.max_obstacles) {
                Ok(obstacles) => {
                    if self.world.update(obstacles) {
                        if let Some((req, reason)) = self.replanner.on_world(&self.world) {
                            self.queue(node, req, reason);
                        }
                    }
                }
                Err(why) => {
                    self.counts.refused += 1;
                    tracing::warn!("obstacle list refused, the world kept as it was: {why}");
                    self.last_problem = format!("obstacle list refused: {why}");
                }
            }
        }
        while let Some(done) = self.worker.try_recv()? {
            self.answer(node, done);
        }
        self.dispatch()?;
        self.report(node);
        // A search under way is looked for every millisecond (its plan goes out at once);
        // idle, only messages (and the health's refresh each second) wake the planner.
        Ok(now
            + if self.scheduler.busy() {
                Duration::from_millis(1)
            } else {
                Duration::from_secs(1)
            })
    }

    fn stop(mut self, node: &Node) -> anyhow::Result<()> {
        // The running search is cancelled; every request still waiting is answered.
        let waiting = self.scheduler.stop();
        self.supersede(node, waiting, "the planner is shutting down");
        let (last, _) = self.worker.stop(Duration::from_secs(5));
        if let Some(done) = last {
            self.answer(node, done);
        }
        let c = self.counts();
        tracing::info!(
            planned = c.planned,
            superseded = c.superseded,
            refused = c.refused,
            failed = c.failed,
            "planner stopped"
        );
        Ok(())
    }
}

/// The whole program: `--ask` or the node.
pub fn run(node: &Node, cli: Cli, cfg: PlannerConfig) -> anyhow::Result<ExitCode> {
    if cli.ask.is_some() {
        node.run(Asker::start(node, cli)?)
    } else {
        node.run(PlannerApp::start(node, cli, cfg)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job(id: i64) -> Job {
        Job {
            req: request_at(id, 0, v2(0.0, 0.0), 0.0, v2(1.0, 0.0)),
            world: World::default(),
            reason: Reason::Request,
            cancel: Cancel::new(),
        }
    }

    fn panics_on_odd(
        req: &FootstepPlanRequestT,
        world: &World,
        limits: &Limits,
        cancel: &Cancel,
    ) -> Answer {
        if req.request_id % 2 == 1 {
            panic!("a planner bug on request {}", req.request_id);
        }
        plan_request(req, world, limits, cancel)
    }

    #[test]
    fn a_search_that_panics_is_answered_and_the_thread_goes_on() {
        let mut worker = search_thread(Limits::default(), panics_on_odd).unwrap();
        for id in [1, 2, 3, 4] {
            worker.offer(job(id)).unwrap();
            let d = worker
                .recv_timeout(Duration::from_secs(10))
                .unwrap()
                .unwrap();
            match d.job.req.request_id % 2 {
                1 => assert!(
                    d.out.as_ref().is_err_and(|e| e.contains("a planner bug")),
                    "{:?}",
                    d.out
                ),
                _ => assert_eq!(d.out.as_ref().unwrap().0.status, FootstepPlanT::STATUS_OK),
            }
        }
        let (last, waiting) = worker.stop(Duration::from_secs(1));
        assert!(last.is_none() && waiting.is_none());
    }
}
