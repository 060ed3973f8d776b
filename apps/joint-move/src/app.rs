//! The command line and the loop of `stride-joint-move`: wait for the joints' states, send
//! the move, wait for the joints to arrive, and say why not when a bridge refused it.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use stride_lcmtypes::stride::{JointCommandT, JointStateT, JointTrajectoryT, NodeStatusT};
use stride_node::{outln, Node, NodeArgs, Stamper, Tick};

/// Move joints with a minimum-jerk profile: reads their positions from the joint states, then
/// publishes one PVT trajectory (stride.joint_trajectory_t) to the target. The bridge checks
/// it against the joints' limits before anything moves; when it refuses, the bridge's reason
/// (from its node status) is printed.
///
/// Example: stride-joint-move --move left_knee=0.8 --move left_hip_pitch=-0.4 --seconds 1.5
#[derive(clap::Parser, Debug)]
#[command(name = "stride-joint-move", version, about, long_about)]
pub struct Cli {
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

stride_node::node_cli!(Cli);

/// Parses `JOINT=RAD` moves: each joint once, each target a finite number.
pub fn parse_moves(moves: &[String]) -> anyhow::Result<(Vec<String>, Vec<f64>)> {
    let mut names: Vec<String> = Vec::new();
    let mut targets = Vec::new();
    for m in moves {
        let (name, value) = m
            .split_once('=')
            .with_context(|| format!("{m:?} is not JOINT=RAD"))?;
        let v = value
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .with_context(|| format!("{m:?}: {value:?} is not a finite number of radians"))?;
        if names.iter().any(|n| n == name) {
            anyhow::bail!("joint {name} is named twice");
        }
        names.push(name.to_owned());
        targets.push(v);
    }
    Ok((names, targets))
}

enum Phase {
    /// Waiting for the first joint states, until then.
    States(Instant),
    /// Streaming set-points: the next row, and when the stream started.
    Streaming(usize, Instant),
    /// Waiting for the joints to arrive, until then.
    Arriving(Instant),
}

/// The client's state machine.
pub struct Mover {
    cli: Cli,
    names: Vec<String>,
    targets: Vec<f64>,
    latest: Arc<Mutex<Option<JointStateT>>>,
    /// What other nodes said that was not "running", since the move went out.
    complaints: Arc<Mutex<Vec<String>>>,
    _subs: [lcm::Subscription; 2],
    traj: Option<JointTrajectoryT>,
    stamper: Stamper,
    phase: Phase,
}

impl Mover {
    /// Checks the command line and listens for joint states and node statuses.
    pub fn start(node: &Node, cli: Cli) -> anyhow::Result<Mover> {
        let (names, targets) = parse_moves(&cli.moves)?;
        if !(cli.seconds > 0.0 && cli.seconds <= 600.0) {
            anyhow::bail!("--seconds must be positive, at most 600");
        }
        let latest: Arc<Mutex<Option<JointStateT>>> = Arc::default();
        let l = latest.clone();
        let states = node
            .lcm()
            .subscribe(&cli.state_channel, move |_, m: JointStateT| {
                *l.lock().unwrap_or_else(|p| p.into_inner()) = Some(m);
            })?;
        let complaints: Arc<Mutex<Vec<String>>> = Arc::default();
        let (c, me) = (complaints.clone(), node.name().to_owned());
        let statuses =
            node.lcm()
                .subscribe(&cli.node.status_channel, move |_, s: NodeStatusT| {
                    let bad = s.state != NodeStatusT::STATE_RUNNING && s.node != me;
                    let mut c = c.lock().unwrap_or_else(|p| p.into_inner());
                    let line = format!("{}: {}", s.node, s.detail);
                    if bad && !s.detail.is_empty() && !c.contains(&line) {
                        c.push(line);
                    }
                })?;
        Ok(Mover {
            phase: Phase::States(Instant::now() + Duration::from_secs(5)),
            cli,
            names,
            targets,
            latest,
            complaints,
            _subs: [states, statuses],
            traj: None,
            stamper: Stamper::new(""),
        })
    }

    fn state(&self) -> Option<JointStateT> {
        self.latest
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }

    fn arrived(&self) -> bool {
        self.state().is_some_and(|s| {
            self.names.iter().zip(&self.targets).all(|(n, t)| {
                s.names
                    .iter()
                    .position(|x| x == n)
                    .is_some_and(|i| (s.positions[i] - t).abs() < self.cli.tolerance)
            })
        })
    }

    /// The move from the joints' present positions.
    fn plan(&mut self, state: &JointStateT) -> anyhow::Result<JointTrajectoryT> {
        let from: Vec<f64> = self
            .names
            .iter()
            .map(|n| {
                state
                    .names
                    .iter()
                    .position(|x| x == n)
                    .map(|i| state.positions[i])
                    .with_context(|| format!("joint {n} is not in {}", self.cli.state_channel))
            })
            .collect::<anyhow::Result<_>>()?;
        Ok(crate::min_jerk(
            &self.names,
            &from,
            &self.targets,
            self.cli.seconds,
            0.01,
            self.stamper.stamp(),
        ))
    }

    fn sent(&mut self, now: Instant) {
        self.complaints
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clear();
        self.phase = Phase::Arriving(now + Duration::from_secs_f64(self.cli.wait.max(0.0)));
    }
}

impl Tick for Mover {
    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        match self.phase {
            Phase::States(until) => {
                let Some(state) = self.state() else {
                    if now > until {
                        anyhow::bail!(
                            "no joint states on {} (is the bridge running?)",
                            self.cli.state_channel
                        );
                    }
                    return Ok(now + Duration::from_millis(50));
                };
                let traj = self.plan(&state)?;
                if self.cli.command_channel.is_some() {
                    self.traj = Some(traj);
                    self.phase = Phase::Streaming(0, now);
                    return Ok(now);
                }
                node.lcm().publish(&self.cli.trajectory_channel, &traj)?;
                outln!(
                    "stride-joint-move: {} rows to {}",
                    traj.num_rows,
                    self.cli.trajectory_channel
                )?;
                self.sent(now);
                Ok(now + Duration::from_millis(50))
            }
            Phase::Streaming(row, t0) => {
                let (Some(traj), Some(channel)) = (&self.traj, &self.cli.command_channel) else {
                    unreachable!("streaming without a trajectory")
                };
                if row >= traj.num_rows as usize {
                    outln!(
                        "stride-joint-move: {} set-points to {channel}",
                        traj.num_rows
                    )?;
                    self.sent(now);
                    return Ok(now + Duration::from_millis(50));
                }
                let at = t0 + Duration::from_secs_f64(traj.time_from_start[row]);
                if now < at {
                    return Ok(at);
                }
                let cmd = JointCommandT {
                    header: self.stamper.stamp(),
                    num_joints: self.names.len() as i32,
                    names: self.names.clone(),
                    modes: vec![JointCommandT::MODE_POSITION; self.names.len()],
                    setpoints: traj.positions[row].clone(),
                    velocities: traj.velocities[row].clone(),
                };
                node.lcm().publish(channel, &cmd)?;
                self.phase = Phase::Streaming(row + 1, t0);
                Ok(now)
            }
            Phase::Arriving(until) => {
                if self.arrived() {
                    outln!("stride-joint-move: arrived")?;
                    node.request_shutdown();
                } else if now >= until {
                    let said = self
                        .complaints
                        .lock()
                        .unwrap_or_else(|p| p.into_inner())
                        .join("; ");
                    if said.is_empty() {
                        anyhow::bail!("the joints did not arrive within {} s", self.cli.wait);
                    }
                    anyhow::bail!(
                        "the joints did not arrive within {} s; {said}",
                        self.cli.wait
                    );
                }
                Ok(now + Duration::from_millis(50))
            }
        }
    }
}
