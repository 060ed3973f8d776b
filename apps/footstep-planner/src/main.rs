//! `stride-footstep-planner`: footstep plans on request, on the LCM bus.

use std::sync::mpsc;
use std::time::Instant;

use anyhow::Context;
use clap::Parser;
use stride_footstep_planner::node::{obstacles_of, plan_request, Reason, Replanner, World};
use stride_footstep_planner::scene::Scene;
use stride_lcmtypes::stride::{FootstepPlanRequestT, FootstepPlanT, NodeStatusT, ObstacleListT};
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
}

struct Job {
    req: FootstepPlanRequestT,
    world: World,
    reason: Reason,
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
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
