//! `stride-footstep-planner`: footstep plans on request, on the LCM bus.

use std::sync::mpsc;
use std::time::Instant;

use anyhow::Context;
use clap::Parser;
use stride_footstep_planner::geom::v2;
use stride_footstep_planner::node::{
    obstacles_of, plan_request, request_at, Reason, Replanner, World,
};
use stride_footstep_planner::scene::Scene;
use stride_lcmtypes::stride::{
    FootT, FootstepPlanRequestT, FootstepPlanT, NodeStatusT, ObstacleListT,
};
use stride_node::{Node, NodeArgs, Stamper, Ticker};

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
#[derive(Parser, Debug)]
#[command(version, about, long_about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    /// Take the obstacles from this scene file instead of the mapper.
    #[arg(long)]
    scene: Option<std::path::PathBuf>,
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
    ask: Option<(f64, f64)>,
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
    let num = |v: &str| v.trim().parse::<f64>().map_err(|e| format!("{v:?}: {e}"));
    Ok((num(x)?, num(y)?))
}

/// --ask: one request, the answer printed.
fn ask(cli: &Cli, goal: (f64, f64)) -> anyhow::Result<()> {
    let node = Node::start("stride-footstep-ask", &cli.node)?;
    let (_sub, plans) = node.queue::<FootstepPlanT>(&cli.plan_channel)?;
    let id = std::process::id() as i64;
    let mut req = request_at(id, 0, v2(0.0, 0.0), 0.0, v2(goal.0, goal.1));
    req.planner = match cli.planner {
        Which::Archie => FootstepPlanRequestT::PLANNER_ARCHIE,
        Which::Kaist => FootstepPlanRequestT::PLANNER_KAIST,
        Which::Lola => FootstepPlanRequestT::PLANNER_LOLA,
    };
    req.faithful = cli.faithful;
    req.max_time_us = (cli.budget_ms * 1000) as i64;
    node.publisher().publish(&cli.request_channel, &req)?;
    let until = Instant::now() + std::time::Duration::from_secs_f64(cli.wait_s);
    let mut ticker = Ticker::new(100.0);
    while Instant::now() < until && ticker.wait(&node)?.is_some() {
        while let Ok(plan) = plans.try_recv() {
            if plan.request_id != id {
                continue;
            }
            let status = match plan.status {
                FootstepPlanT::STATUS_OK => "ok",
                FootstepPlanT::STATUS_PARTIAL => "partial",
                FootstepPlanT::STATUS_NO_PATH => "no path",
                FootstepPlanT::STATUS_START_IN_COLLISION => "start in collision",
                FootstepPlanT::STATUS_GOAL_IN_COLLISION => "goal in collision",
                FootstepPlanT::STATUS_GOAL_OUTSIDE_MAP => "goal outside the map",
                _ => "bad request",
            };
            let detail = if plan.detail.is_empty() {
                String::new()
            } else {
                format!(": {}", plan.detail)
            };
            println!(
                "{:?} ({}): status {} ({status}{detail}), cost {:.3}, {} steps, {} expansions, {} µs",
                cli.planner,
                if cli.faithful { "faithful" } else { "improved" },
                plan.status,
                plan.cost,
                plan.num_steps,
                plan.expansions,
                plan.prepare_time_us + plan.search_time_us
            );
            for s in &plan.steps {
                println!(
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
                );
            }
            let ok =
                [FootstepPlanT::STATUS_OK, FootstepPlanT::STATUS_PARTIAL].contains(&plan.status);
            std::process::exit(if ok { 0 } else { 1 });
        }
    }
    anyhow::bail!(
        "no answer on {} within {} s: is stride-footstep-planner running?",
        cli.plan_channel,
        cli.wait_s
    )
}

struct Job {
    req: FootstepPlanRequestT,
    world: World,
    reason: Reason,
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    if let Some(goal) = cli.ask {
        return ask(&cli, goal);
    }
    let mut world = match &cli.scene {
        Some(path) => World::from_scene(
            Scene::load(path).with_context(|| format!("loading {}", path.display()))?,
        ),
        None => World::default(),
    };
    let node = Node::start("stride-footstep-planner", &cli.node)?;
    let (_req_sub, requests) = node.queue::<FootstepPlanRequestT>(&cli.request_channel)?;
    let (_obs_sub, obstacles) = node.queue::<ObstacleListT>(&cli.obstacle_channel)?;
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
                if done
                    .send((
                        msg,
                        path,
                        inflation,
                        job.world.version,
                        job.reason,
                        t.elapsed(),
                    ))
                    .is_err()
                {
                    break;
                }
            }
        })?;
    let publisher = node.publisher();
    let mut stamper = Stamper::new("world");
    let mut replanner = Replanner::default();
    let mut ticker = Ticker::new(200.0);
    node.set_running();
    while let Some(_now) = ticker.wait(&node)? {
        while let Ok(req) = requests.try_recv() {
            if let Some((req, reason)) = replanner.on_request(req) {
                let _ = jobs.send(Job {
                    req,
                    world: world.clone(),
                    reason,
                });
            }
        }
        while let Ok(list) = obstacles.try_recv() {
            if cli.scene.is_some() {
                continue; // the scene is the world
            }
            if world.update(obstacles_of(&list)) {
                if let Some((req, reason)) = replanner.on_world(&world) {
                    let _ = jobs.send(Job {
                        req,
                        world: world.clone(),
                        reason,
                    });
                }
            }
        }
        while let Ok((mut msg, path, inflation, version, reason, took)) = results.try_recv() {
            replanner.planned(path, inflation, version);
            msg.header = stamper.stamp();
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
            if let Err(e) = publisher.publish(&cli.plan_channel, &msg) {
                tracing::warn!(error = %e, "could not publish the plan");
            }
        }
    }
    drop(jobs);
    let _ = worker.join();
    Ok(())
}
