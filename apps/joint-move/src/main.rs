//! `stride-joint-move`: move joints smoothly from where they are to where you say.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use clap::Parser;
use stride_lcmtypes::stride::{JointCommandT, JointStateT, JointTrajectoryT};
use stride_node::{Node, NodeArgs, Stamper};

/// Move joints with a minimum-jerk profile: reads their positions from the joint states, then
/// publishes one PVT trajectory (stride.joint_trajectory_t) to the target. The bridge checks
/// it against the joints' limits before anything moves.
///
/// Example: stride-joint-move --move left_knee=0.8 --move left_hip_pitch=-0.4 --seconds 1.5
#[derive(Parser, Debug)]
#[command(version, about, long_about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    /// JOINT=RADIANS, once per joint to move.
    #[arg(long = "move", value_name = "JOINT=RAD", required = true)]
    moves: Vec<String>,
    /// Duration of the move, seconds.
    #[arg(long, default_value_t = 1.0)]
    seconds: f64,
    /// Joint states to read the start from.
    #[arg(long, default_value = "JOINT_STATE_LEFT_LEG")]
    state_channel: String,
    /// Where to publish the trajectory.
    #[arg(long, default_value = "JOINT_TRAJECTORY_LEFT_LEG")]
    trajectory_channel: String,
    /// Instead of one trajectory, stream the move as position commands
    /// (stride.joint_command_t, a row every 10 ms) on this channel: for bridges that take
    /// set-points, such as stride-dynamixel-bridge and stride-arduino-link.
    #[arg(long)]
    command_channel: Option<String>,
    /// Wait for the joints to arrive (within --tolerance) before exiting, at most this long (s).
    #[arg(long, default_value_t = 5.0)]
    wait: f64,
    /// How close counts as arrived, rad.
    #[arg(long, default_value_t = 1e-3)]
    tolerance: f64,
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let mut names = Vec::new();
    let mut targets = Vec::new();
    for m in &cli.moves {
        let (name, value) = m
            .split_once('=')
            .with_context(|| format!("{m:?} is not JOINT=RAD"))?;
        names.push(name.to_owned());
        targets.push(
            value
                .parse::<f64>()
                .with_context(|| format!("{value:?} is not a number"))?,
        );
    }
    if cli.seconds.is_nan() || cli.seconds <= 0.0 {
        bail!("--seconds must be positive");
    }
    let node = Node::start("stride-joint-move", &cli.node)?;
    let latest: Arc<Mutex<Option<JointStateT>>> = Arc::default();
    let l = latest.clone();
    let _sub = node
        .lcm()
        .subscribe(&cli.state_channel, move |_, m: JointStateT| {
            *l.lock().unwrap() = Some(m);
        })?;
    let deadline = Instant::now() + Duration::from_secs(5);
    while latest.lock().unwrap().is_none() {
        if Instant::now() > deadline {
            bail!(
                "no joint states on {} (is the bridge running?)",
                cli.state_channel
            );
        }
        node.lcm().handle_timeout(Duration::from_millis(50))?;
    }
    let state = latest.lock().unwrap().clone().expect("seen");
    let from: Vec<f64> = names
        .iter()
        .map(|n| {
            state
                .names
                .iter()
                .position(|x| x == n)
                .map(|i| state.positions[i])
                .with_context(|| format!("joint {n} is not in {}", cli.state_channel))
        })
        .collect::<anyhow::Result<_>>()?;
    let traj: JointTrajectoryT = stride_joint_move::min_jerk(
        &names,
        &from,
        &targets,
        cli.seconds,
        0.01,
        Stamper::new("").stamp(),
    );
    if let Some(channel) = &cli.command_channel {
        // The rows as set-points at their times.
        let mut stamper = Stamper::new("");
        let t0 = Instant::now();
        for r in 0..traj.num_rows as usize {
            let at = t0 + Duration::from_secs_f64(traj.time_from_start[r]);
            while Instant::now() < at {
                node.lcm().handle_timeout(at - Instant::now())?;
            }
            let cmd = JointCommandT {
                header: stamper.stamp(),
                num_joints: names.len() as i32,
                names: names.clone(),
                modes: vec![JointCommandT::MODE_POSITION; names.len()],
                setpoints: traj.positions[r].clone(),
                velocities: traj.velocities[r].clone(),
            };
            node.lcm().publish(channel, &cmd)?;
        }
        println!(
            "stride-joint-move: {} set-points to {channel}",
            traj.num_rows
        );
    } else {
        node.lcm().publish(&cli.trajectory_channel, &traj)?;
        println!(
            "stride-joint-move: {} rows to {}",
            traj.num_rows, cli.trajectory_channel
        );
    }
    let deadline = Instant::now() + Duration::from_secs_f64(cli.wait.max(0.0));
    while Instant::now() < deadline && node.running() {
        node.lcm().handle_timeout(Duration::from_millis(50))?;
        let s = latest.lock().unwrap().clone().expect("seen");
        let arrived = names.iter().zip(&targets).all(|(n, t)| {
            s.names
                .iter()
                .position(|x| x == n)
                .is_some_and(|i| (s.positions[i] - t).abs() < cli.tolerance)
        });
        if arrived {
            println!("stride-joint-move: arrived");
            return Ok(());
        }
    }
    bail!("the joints did not arrive within {} s", cli.wait)
}
