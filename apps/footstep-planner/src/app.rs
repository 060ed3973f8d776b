//! The planner as an app: its command line, the node that answers requests (the searches on
//! their own thread), and `--ask`, the client that sends one request and prints the answer.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::Context;
use stride_lcmtypes::stride::{
    FootT, FootstepPlanRequestT, FootstepPlanT, NodeStatusT, ObstacleListT,
};
use stride_node::{outln, Node, NodeArgs, Stamper, Tick};

use crate::node::{obstacles_of, plan_request, request_at, Reason, Replanner, World};
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
/// planner is answered with STATUS_BAD_REQUEST.
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
    /// With --ask: which planner.
    #[arg(long, value_enum, default_value = "archie")]
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

/// The planners, as --planner names them.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Which {
    /// Archie's path planner (seed 000).
    Archie,
    /// The KAIST energy A* (seed 004).
    Kaist,
    /// LOLA's footstep A* (seed 002).
    Lola,
}

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
        req.planner = match cli.planner {
            Which::Archie => FootstepPlanRequestT::PLANNER_ARCHIE,
            Which::Kaist => FootstepPlanRequestT::PLANNER_KAIST,
            Which::Lola => FootstepPlanRequestT::PLANNER_LOLA,
        };
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

struct Job {
    req: FootstepPlanRequestT,
    world: World,
    reason: Reason,
}

type Done = (FootstepPlanT, Vec<V2>, f64, u64, Reason, Duration);

/// The node: requests and the world in, jobs to the search thread, plans out.
pub struct PlannerApp {
    cli: Cli,
    world: World,
    _subs: [lcm::Subscription; 2],
    requests: mpsc::Receiver<FootstepPlanRequestT>,
    obstacles: mpsc::Receiver<ObstacleListT>,
    jobs: Option<mpsc::Sender<Job>>,
    results: mpsc::Receiver<Done>,
    worker: Option<std::thread::JoinHandle<()>>,
    stamper: Stamper,
    replanner: Replanner,
}

impl PlannerApp {
    /// Loads the scene, subscribes and starts the search thread.
    pub fn start(node: &Node, cli: Cli) -> anyhow::Result<PlannerApp> {
        let world = match &cli.scene {
            Some(path) => World::from_scene(
                Scene::load(path).with_context(|| format!("loading {}", path.display()))?,
            ),
            None => World::default(),
        };
        let (req_sub, requests) = node.queue::<FootstepPlanRequestT>(&cli.request_channel)?;
        let (obs_sub, obstacles) = node.queue::<ObstacleListT>(&cli.obstacle_channel)?;
        // The searches run on their own thread; only the latest job waiting is worth doing.
        let (jobs, job_rx) = mpsc::channel::<Job>();
        let (done, results) = mpsc::channel();
        let worker = std::thread::Builder::new()
            .name("search".into())
            .spawn(move || {
                while let Ok(mut job) = job_rx.recv() {
                    while let Ok(newer) = job_rx.try_recv() {
                        job = newer;
                    }
                    let t = Instant::now();
                    let (msg, path, inflation) = plan_request(&job.req, &job.world);
                    let out = (
                        msg,
                        path,
                        inflation,
                        job.world.version,
                        job.reason,
                        t.elapsed(),
                    );
                    if done.send(out).is_err() {
                        break;
                    }
                }
            })?;
        Ok(PlannerApp {
            cli,
            world,
            _subs: [req_sub, obs_sub],
            requests,
            obstacles,
            jobs: Some(jobs),
            results,
            worker: Some(worker),
            stamper: Stamper::new("world"),
            replanner: Replanner::default(),
        })
    }

    fn send(&self, req: FootstepPlanRequestT, reason: Reason) {
        if let Some(jobs) = &self.jobs {
            let _ = jobs.send(Job {
                req,
                world: self.world.clone(),
                reason,
            });
        }
    }
}

impl Tick for PlannerApp {
    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        while let Ok(req) = self.requests.try_recv() {
            if let Some((req, reason)) = self.replanner.on_request(req) {
                self.send(req, reason);
            }
        }
        while let Ok(list) = self.obstacles.try_recv() {
            if self.cli.scene.is_some() {
                continue; // the scene is the world
            }
            if self.world.update(obstacles_of(&list)) {
                if let Some((req, reason)) = self.replanner.on_world(&self.world) {
                    self.send(req, reason);
                }
            }
        }
        while let Ok((mut msg, path, inflation, version, reason, took)) = self.results.try_recv() {
            self.replanner.planned(path, inflation, version);
            msg.header = self.stamper.stamp();
            tracing::info!(
                request = msg.request_id,
                ?reason,
                status = msg.status,
                steps = msg.num_steps,
                micros = took.as_micros() as u64,
                "plan"
            );
            if msg.status != FootstepPlanT::STATUS_OK {
                node.set_health(
                    NodeStatusT::STATE_DEGRADED,
                    format!("request {}: {}", msg.request_id, msg.detail),
                );
            } else {
                node.set_running();
            }
            if let Err(e) = node.lcm().publish(&self.cli.plan_channel, &msg) {
                tracing::warn!(error = %e, "could not publish the plan");
            }
        }
        Ok(now + Duration::from_millis(5))
    }

    fn stop(mut self, _node: &Node) -> anyhow::Result<()> {
        drop(self.jobs.take());
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
        Ok(())
    }
}

/// The whole program: `--ask` or the node.
pub fn run(node: &Node, cli: Cli) -> anyhow::Result<ExitCode> {
    if cli.ask.is_some() {
        node.run(Asker::start(node, cli)?)
    } else {
        node.run(PlannerApp::start(node, cli)?)
    }
}
