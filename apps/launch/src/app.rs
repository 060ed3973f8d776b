//! The commands of `stride`: launch (a deputy), status, goal, stop, resume, shutdown.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use anyhow::Context;
use stride_lcmtypes::stride::{
    GaitCommandT, LaunchConsoleT, LaunchOrderT, LaunchStatusT, NodeStatusT, PoseStampedT, PoseT,
};
use stride_node::{Launch, NoConfig, Node, NodeArgs, Spaced, Stamper, Tick};

use crate::profile::Profile;
use crate::supervise::{state_word, Note, Supervisor};

/// Run the robot: launch a profile's apps, watch them, command the robot.
///
/// `stride launch PROFILE` runs the apps of a launch profile (config/launch/*.toml) that
/// belong on this host (--host NAME; without it every app runs here), each in its own process
/// group, started once what it depends on publishes a RUNNING heartbeat, its console lines
/// tagged, written to a log file per app and forwarded over LCM (STRIDE_CONSOLE), restarted by
/// its policy with backoff and a cap. An app whose heartbeats stop for 3 s is marked lost; a
/// critical app (the gait, a bridge) that dies or goes silent triggers a system stop
/// (STRIDE_STOP) that the gait and the bridges obey until `stride resume`. Ctrl-C (or `stride
/// shutdown`) stops the apps stage by stage: the gait first (it brings the robot to a stand),
/// then the bridges (decelerate, then disable), then the rest; SIGINT, then SIGTERM, then
/// SIGKILL. --sim swaps the hardware for the fakes and the simulated world. The deputy's
/// report (STRIDE_LAUNCH_STATUS, 1 Hz) lets `stride status` on any host show the whole robot.
#[derive(clap::Parser, Debug)]
#[command(name = "stride", version, about, long_about)]
pub struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    #[command(subcommand)]
    command: Command,
}

stride_node::node_cli!(Cli);

#[derive(clap::Subcommand, Debug)]
enum Command {
    /// Run a profile's apps on this host (its deputy).
    Launch {
        /// The profile: a name in config/launch/ (archie, archie-split, hexapod) or a file.
        profile: String,
        /// Run only the apps of this host (default: every app, here).
        #[arg(long, value_name = "NAME")]
        host: Option<String>,
        /// Simulated hardware: the fakes and the simulated world instead of the devices.
        #[arg(long)]
        sim: bool,
        /// Where each app's log file goes.
        #[arg(long, value_name = "DIR", default_value = "out/launch")]
        log_dir: PathBuf,
        /// Check the profile, print what would run, and exit.
        #[arg(long)]
        check: bool,
    },
    /// Show every launched app on every host, from the deputies' reports and the heartbeats.
    Status {
        /// How long to listen, s.
        #[arg(long, default_value_t = 2.0, value_name = "S")]
        wait: f64,
    },
    /// Send the robot a goal to walk to.
    Goal {
        /// X,Y in metres, or X,Y,YAW with the heading in radians.
        #[arg(value_name = "X,Y[,YAW]", allow_hyphen_values = true)]
        goal: String,
        /// The gait's goal channel.
        #[arg(long, default_value = "WALK_GOAL")]
        channel: String,
    },
    /// Send a goal and follow the walk to its end: prints a summary (goal reached, steps,
    /// smallest clearance, collisions, falls, tracking error, CPU per app) and exits non-zero
    /// when the goal was not reached in time, or (in simulation) the true pose is not within
    /// the tolerance, or a foot hit an obstacle, or the robot fell.
    Walk {
        /// X,Y in metres, or X,Y,YAW with the heading in radians.
        #[arg(value_name = "X,Y[,YAW]", allow_hyphen_values = true)]
        goal: String,
        /// The longest the walk may take, s.
        #[arg(long, default_value_t = 150.0, value_name = "S")]
        timeout: f64,
        /// How close the true position must end to the goal, m.
        #[arg(long, default_value_t = 0.2, value_name = "M")]
        tolerance: f64,
        /// The gait's goal channel.
        #[arg(long, default_value = "WALK_GOAL")]
        channel: String,
        /// The joint trajectories whose rows are compared with the measured positions.
        #[arg(
            long,
            value_delimiter = ',',
            default_value = "JOINT_TRAJECTORY_LEFT_LEG,JOINT_TRAJECTORY_RIGHT_LEG"
        )]
        trajectories: Vec<String>,
        /// The measured joint states.
        #[arg(
            long,
            value_delimiter = ',',
            default_value = "JOINT_STATE_LEFT_LEG,JOINT_STATE_RIGHT_LEG"
        )]
        states: Vec<String>,
    },
    /// Walk a distance straight ahead with a gait that takes walk commands (the hexapod's
    /// stride-gait), and follow it: prints a summary (the walk taken, its time, the servos'
    /// tracking of their set-points) and exits non-zero when the gait refuses or stops the
    /// walk, or it does not end in time.
    Step {
        /// The distance, m.
        #[arg(allow_hyphen_values = true)]
        distance: f64,
        /// The gait: "tripod" (three legs swing at a time; flat ground) or "wave" (one leg at
        /// a time).
        #[arg(long, default_value = "tripod")]
        gait: String,
        /// The longest the walk may take, s.
        #[arg(long, default_value_t = 60.0, value_name = "S")]
        timeout: f64,
        /// The set-points compared with the measured positions.
        #[arg(long, default_value = "HEXAPOD_JOINT_COMMAND")]
        commands: String,
        /// The measured joint states.
        #[arg(long, default_value = "HEXAPOD_JOINT_STATE")]
        states: String,
    },
    /// Stop walking: the gait brings the robot to a stand, drops its goal and takes no plan
    /// until `stride resume` (after which it stands until it is sent a goal).
    Stop {
        /// Why (for the logs).
        #[arg(default_value = "operator")]
        reason: String,
    },
    /// The system stop: every bridge quick-stops its axes and holds, the gait stops, until
    /// `stride resume` (what the launcher does when a critical app dies).
    Estop {
        /// Why (for the logs).
        #[arg(default_value = "operator")]
        reason: String,
    },
    /// Let the robot move again after a stop or a system stop: it stands until it is sent a
    /// goal (the one it walked to before the stop is dropped).
    Resume,
    /// Order the deputies of a profile to shut down (the same ordered shutdown as Ctrl-C).
    Shutdown {
        /// The profile's name.
        profile: String,
        /// Only this host's deputy.
        #[arg(long, value_name = "NAME")]
        host: Option<String>,
    },
}

const STOP_CHANNEL: &str = "STRIDE_STOP";
const GAIT_CHANNEL: &str = "GAIT_COMMAND";
const STATUS_CHANNEL: &str = "STRIDE_LAUNCH_STATUS";
const ORDER_CHANNEL: &str = "STRIDE_LAUNCH_ORDER";

/// Finds a profile: a file as given, else `config/launch/NAME.toml` from the working
/// directory, else from the repository the program was built in.
pub fn profile_path(name: &str) -> Option<PathBuf> {
    let given = PathBuf::from(name);
    if given.is_file() {
        return Some(given);
    }
    let file = format!("{name}.toml");
    let mut roots = vec![PathBuf::from(".")];
    if let Some(dir) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        roots.push(dir.join("../.."));
    }
    roots
        .into_iter()
        .map(|r| r.join("config/launch").join(&file))
        .find(|p| p.is_file())
}

/// Runs the command.
pub fn run(l: Launch<Cli, NoConfig>) -> anyhow::Result<ExitCode> {
    match &l.cli.command {
        Command::Launch {
            profile,
            host,
            sim,
            log_dir,
            check,
        } => {
            let path = profile_path(profile).with_context(|| {
                format!("no profile {profile:?} (a file, or a name in config/launch/)")
            })?;
            let bin = std::env::current_exe()
                .ok()
                .and_then(|e| e.parent().map(Path::to_path_buf));
            let p = Profile::load(&path, *sim, bin.as_deref()).map_err(anyhow::Error::msg)?;
            if let Some(h) = host {
                if !p.hosts().contains(h) {
                    anyhow::bail!(
                        "profile {} has no app on host {h:?} (its hosts: {})",
                        p.name,
                        p.hosts().into_iter().collect::<Vec<_>>().join(", ")
                    );
                }
            }
            if *check {
                let mut out = std::io::stdout().lock();
                writeln!(
                    out,
                    "profile {} ({}): {}",
                    p.name,
                    if *sim { "simulated" } else { "hardware" },
                    p.file.description
                )?;
                for a in p
                    .apps
                    .iter()
                    .filter(|a| host.as_ref().is_none_or(|h| &a.host == h))
                {
                    writeln!(
                        out,
                        "  {:<16} on {:<8} {}{} {}",
                        a.name,
                        a.host,
                        if a.critical { "critical " } else { "" },
                        a.program.display(),
                        a.args.join(" ")
                    )?;
                    if let Some(l) = &a.local {
                        writeln!(
                            out,
                            "  {:<16} local bus {}: {}",
                            "",
                            l.url,
                            l.channels.join(",")
                        )?;
                    }
                }
                return Ok(ExitCode::SUCCESS);
            }
            let node = l.start_as(&format!(
                "stride-launch-{}",
                host.as_deref().unwrap_or("all")
            ))?;
            let mut deputy = Deputy::start(&node, p, host.clone(), log_dir.clone())?;
            // `stride --log-level warn launch ...` reaches the apps (RUST_LOG does by itself).
            deputy.sup.set_log_level(&l.cli.node.log_level);
            node.run(deputy)
        }
        Command::Status { wait } => status(&l, *wait),
        Command::Goal { goal, channel } => {
            let msg = goal_msg(goal)?;
            let node = l.start_as("stride-goal")?;
            node.lcm().publish(channel, &msg)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Walk {
            goal,
            timeout,
            tolerance,
            channel,
            trajectories,
            states,
        } => walk(
            &l,
            goal,
            *timeout,
            *tolerance,
            channel,
            trajectories,
            states,
        ),
        Command::Step {
            distance,
            gait,
            timeout,
            commands,
            states,
        } => step(&l, *distance, gait, *timeout, commands, states),
        Command::Stop { reason } => {
            command(&l, &[GAIT_CHANNEL], GaitCommandT::COMMAND_STOP, reason)
        }
        Command::Estop { reason } => {
            command(&l, &[STOP_CHANNEL], GaitCommandT::COMMAND_STOP, reason)
        }
        Command::Resume => command(
            &l,
            &[STOP_CHANNEL, GAIT_CHANNEL],
            GaitCommandT::COMMAND_RESUME,
            "operator",
        ),
        Command::Shutdown { profile, host } => {
            let node = l.start_as("stride-shutdown")?;
            let msg = LaunchOrderT {
                header: Stamper::new("").stamp(),
                profile: profile.clone(),
                host: host.clone().unwrap_or_default(),
                order: LaunchOrderT::ORDER_SHUTDOWN,
                app: String::new(),
            };
            node.lcm().publish(ORDER_CHANNEL, &msg)?;
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// A goal message from "X,Y" or "X,Y,YAW".
pub fn goal_msg(goal: &str) -> anyhow::Result<PoseStampedT> {
    let v: Vec<f64> = goal
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()
        .filter(|v: &Vec<f64>| (2..=3).contains(&v.len()) && v.iter().all(|x| x.is_finite()))
        .with_context(|| format!("{goal:?}: the goal is X,Y or X,Y,YAW in metres and radians"))?;
    let yaw = v.get(2).copied().unwrap_or(0.0);
    Ok(PoseStampedT {
        header: Stamper::new("world").stamp(),
        child_frame: if v.len() == 3 {
            "goal".into()
        } else {
            "goal_any_heading".into()
        },
        pose: PoseT {
            position: [v[0], v[1], 0.0],
            orientation: [(yaw / 2.0).cos(), 0.0, 0.0, (yaw / 2.0).sin()],
        },
    })
}

/// `stride step`: a walk command, followed to its end.
fn step(
    l: &Launch<Cli, NoConfig>,
    distance: f64,
    gait: &str,
    timeout: f64,
    commands: &str,
    states: &str,
) -> anyhow::Result<ExitCode> {
    use crate::walk::Tracking;
    use stride_lcmtypes::stride::{JointCommandT, JointStateT, TrajectoryStatusT};
    let gait_id = match gait {
        "tripod" => GaitCommandT::GAIT_TRIPOD,
        "wave" => GaitCommandT::GAIT_WAVE,
        other => anyhow::bail!("--gait {other:?}: \"tripod\" or \"wave\""),
    };
    if !(distance.is_finite() && timeout.is_finite() && timeout > 0.0) {
        anyhow::bail!("the distance must be a number and --timeout positive");
    }
    let node = l.start_as("stride-step")?;
    let (s1, status) = node.queue::<TrajectoryStatusT>("GAIT_STATUS")?;
    let (s2, sent) = node.queue::<JointCommandT>(commands)?;
    let (s3, measured) = node.queue::<JointStateT>(states)?;
    let (s4, health) =
        node.queue::<stride_lcmtypes::stride::NodeStatusT>(stride_node::STATUS_CHANNEL)?;
    for s in [&s1, &s2, &s3, &s4] {
        s.set_queue_capacity(10_000)?;
    }
    // The simulated world, when one runs: the body's true pose and its report.
    let (_s5, poses) = node.queue::<PoseStampedT>("SIM_POSE")?;
    let (_s6, reports) = node.queue::<stride_lcmtypes::stride::SimReportT>("SIM_REPORT")?;
    let mut pose0: Option<PoseStampedT> = None;
    let mut pose: Option<PoseStampedT> = None;
    let mut report = None;
    // The gait takes a walk once it stands ready: its heartbeat says RUNNING.
    let mut ready = false;
    let started = Instant::now();
    let deadline = started + Duration::from_secs_f64(timeout);
    let mut tracking = Tracking::default();
    let mut last: Option<TrajectoryStatusT> = None;
    let mut accepted0 = None::<i64>;
    let mut refused0 = None::<i64>;
    let mut sent_at = None::<Instant>;
    let mut moving_since = None::<Instant>;
    let mut verdict: Option<Result<String, String>> = None;
    let mut refusal: Option<String> = None;
    while verdict.is_none() && Instant::now() < deadline {
        node.lcm().handle_timeout(Duration::from_millis(20))?;
        for m in status.try_iter() {
            accepted0.get_or_insert(m.accepted);
            refused0.get_or_insert(m.refused);
            if sent_at.is_some() {
                if Some(m.refused) > refused0 {
                    // Not yet standing ready (it moves into its pose first), or refused for
                    // good: asked again every second until the time is up.
                    refused0 = Some(m.refused);
                    refusal = Some(m.last_refusal.clone());
                    sent_at = sent_at.map(|t| t - Duration::from_secs(2));
                } else if m.state == TrajectoryStatusT::STATE_STOPPED {
                    verdict = Some(Err(format!("the gait stopped: {}", m.reason)));
                } else if m.state == TrajectoryStatusT::STATE_MOVING && Some(m.accepted) > accepted0
                {
                    moving_since.get_or_insert_with(Instant::now);
                } else if m.state == TrajectoryStatusT::STATE_IDLE && moving_since.is_some() {
                    verdict = Some(Ok(m.reason.clone()));
                }
            }
            last = Some(m);
        }
        if let Some(g) = &last {
            ready |= health.try_iter().any(|h| {
                h.node == g.node && h.state == stride_lcmtypes::stride::NodeStatusT::STATE_RUNNING
            });
        }
        // The command once the gait stands ready, and again while it has not started to move.
        if ready
            && moving_since.is_none()
            && sent_at.is_none_or(|t| t.elapsed() > Duration::from_secs(3))
        {
            let m = GaitCommandT {
                header: Stamper::new("").stamp(),
                command: GaitCommandT::COMMAND_WALK,
                gait: gait_id,
                distance,
                reason: "stride step".into(),
            };
            node.lcm().publish(GAIT_CHANNEL, &m)?;
            sent_at = Some(Instant::now());
        }
        for m in sent.try_iter() {
            tracking.set_point(&m);
        }
        for m in measured.try_iter() {
            tracking.measured(&m);
        }
        for m in poses.try_iter() {
            if moving_since.is_none() {
                pose0 = Some(m.clone());
            }
            pose = Some(m);
        }
        if let Some(r) = reports.try_iter().last() {
            report = Some(r);
        }
    }
    let secs = moving_since.map_or(0.0, |t| t.elapsed().as_secs_f64());
    let sim = pose0.zip(pose).map(|(a, b)| {
        let r = report.unwrap_or_default();
        let (p0, p1) = (a.pose.position, b.pose.position);
        let q = a.pose.orientation;
        let yaw =
            (2.0 * (q[0] * q[3] + q[1] * q[2])).atan2(1.0 - 2.0 * (q[2] * q[2] + q[3] * q[3]));
        let (dx, dy) = (p1[0] - p0[0], p1[1] - p0[1]);
        let ahead = dx * yaw.cos() + dy * yaw.sin();
        let off = ahead - distance;
        let ok =
            off.abs() <= (0.25 * distance.abs()).max(0.05) && r.falls == 0 && r.collisions == 0;
        let text = format!(
            "the simulated body moved {ahead:.3} m ahead ({:.3} m asked; ({dx:+.3}, {dy:+.3}) m in \
             the world), smallest static margin {:.3} m, falls {}, collisions {}, joints at a \
             limit {}",
            distance, r.min_zmp_margin, r.falls, r.collisions, r.limits
        );
        (ok, text)
    });
    let (ok, what) = match verdict {
        Some(Ok(_)) => (
            sim.as_ref().is_none_or(|(ok, _)| *ok),
            format!(
                "the walk of {distance} m ({gait} gait) played to its end in {secs:.1} s{}",
                match &sim {
                    Some((_, text)) => format!("; {text}"),
                    None => " (the servos' tracking below; no simulated body measures the \
                              distance)"
                        .to_string(),
                }
            ),
        ),
        Some(Err(why)) => (false, why),
        None if last.is_none() => (false, "no gait heard on GAIT_STATUS".into()),
        None if !ready => (
            false,
            format!("the gait was not ready to walk within {timeout} s"),
        ),
        None if moving_since.is_none() => (
            false,
            format!(
                "the gait did not take the walk within {timeout} s{}",
                refusal.map_or(String::new(), |r| format!(" (it said: {r})"))
            ),
        ),
        None => (false, format!("the walk did not end within {timeout} s")),
    };
    let mut out = std::io::stdout().lock();
    writeln!(out, "{what}")?;
    writeln!(
        out,
        "servo tracking (set-points against measured positions): max {:.4} rad ({}), rms {:.4} rad over {} samples",
        tracking.max.0,
        if tracking.max.1.is_empty() { "-" } else { &tracking.max.1 },
        tracking.rms(),
        tracking.samples
    )?;
    Ok(if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

#[allow(clippy::too_many_arguments)]
fn walk(
    l: &Launch<Cli, NoConfig>,
    goal: &str,
    timeout: f64,
    tolerance: f64,
    channel: &str,
    trajectories: &[String],
    states: &[String],
) -> anyhow::Result<ExitCode> {
    use crate::walk::Walk;
    use stride_lcmtypes::stride::{
        JointStateT, JointTrajectoryT, SimReportT, StepCounterT, TrajectoryStatusT,
    };
    if !(timeout.is_finite() && timeout > 0.0 && tolerance.is_finite() && tolerance > 0.0) {
        anyhow::bail!("--timeout and --tolerance must be positive");
    }
    let msg = goal_msg(goal)?;
    let target = [msg.pose.position[0], msg.pose.position[1]];
    let node = l.start_as("stride-walk")?;
    let mut subs = Vec::new();
    let (s, gait) = node.queue::<TrajectoryStatusT>("GAIT_STATUS")?;
    subs.push(s);
    let (s, counters) = node.queue::<StepCounterT>("STEP_COUNTER")?;
    subs.push(s);
    let (s, poses) = node.queue::<PoseStampedT>("SIM_POSE")?;
    subs.push(s);
    let (s, reports) = node.queue::<SimReportT>("SIM_REPORT")?;
    subs.push(s);
    let (s, launches) = node.queue::<LaunchStatusT>(STATUS_CHANNEL)?;
    subs.push(s);
    let (s, beats) = node.queue::<NodeStatusT>(stride_node::STATUS_CHANNEL)?;
    subs.push(s);
    let mut traj = Vec::new();
    for c in trajectories {
        let (s, r) = node.queue::<JointTrajectoryT>(c)?;
        subs.push(s);
        traj.push(r);
    }
    let mut meas = Vec::new();
    for c in states {
        let (s, r) = node.queue::<JointStateT>(c)?;
        subs.push(s);
        meas.push(r);
    }
    // A walk's worth of rows and states between two turns of the loop.
    for s in &subs {
        s.set_queue_capacity(10_000)?;
    }
    let started = Instant::now();
    let deadline = started + Duration::from_secs_f64(timeout);
    let mut w = Walk::default();
    let mut sent_at = None::<Instant>;
    let mut accepted0 = None::<i64>;
    let goal_text = format!("goal ({}, {})", short(target[0]), short(target[1]));
    let reached_text = format!("{goal_text} reached");
    let dropped_text = format!("{goal_text} dropped: ");
    while Instant::now() < deadline
        && !node
            .shutdown_flag()
            .load(std::sync::atomic::Ordering::Relaxed)
    {
        node.lcm().handle_timeout(Duration::from_millis(20))?;
        for m in gait.try_iter() {
            if accepted0.is_none() {
                accepted0 = Some(m.accepted);
            }
            if sent_at.is_some() && m.reason == reached_text {
                w.reached = true;
            }
            if sent_at.is_some() && m.reason.starts_with(&dropped_text) {
                w.dropped = Some(m.reason.clone());
            }
            if sent_at.is_some() && m.state == TrajectoryStatusT::STATE_STOPPED {
                w.stopped = Some(if m.recovery.is_empty() {
                    m.reason.clone()
                } else {
                    format!("{} (to go on: {})", m.reason, m.recovery)
                });
            }
            // A restarted gait's counts start afresh: taken is judged against its own.
            if w.gait.as_ref().is_some_and(|g| m.accepted < g.accepted) {
                accepted0 = Some(m.accepted.min(accepted0.unwrap_or(0)));
            }
            w.gait_status(m);
        }
        // The gait's heartbeat: a fault or a stalled loop ends the walk, said as such.
        let gait_node = w.gait.as_ref().map(|g| g.node.clone());
        for b in beats.try_iter() {
            if Some(&b.node) != gait_node.as_ref() {
                continue;
            }
            match b.state {
                NodeStatusT::STATE_FAULT | NodeStatusT::STATE_STALLED => {
                    w.fault = Some(format!("{} ({})", b.detail, node_state_word(b.state)))
                }
                _ => w.fault = None,
            }
        }
        if w.fault.is_some() && sent_at.is_some_and(|t| t.elapsed() > Duration::from_secs(1)) {
            break;
        }
        // The goal: once the gait is heard, and again while no plan is taken for 3 s.
        let taken = w
            .gait
            .as_ref()
            .is_some_and(|g| Some(g.accepted) > accepted0);
        if w.gait.is_some()
            && !taken
            && sent_at.is_none_or(|t| t.elapsed() > Duration::from_secs(3))
        {
            let mut m = msg.clone();
            m.header = Stamper::new("world").stamp();
            node.lcm().publish(channel, &m)?;
            sent_at = Some(Instant::now());
        }
        for c in counters.try_iter() {
            if sent_at.is_some() {
                w.counter(&c);
            }
        }
        if let Some(p) = poses.try_iter().last() {
            w.pose = Some(p);
        }
        if let Some(r) = reports.try_iter().last() {
            w.report = Some(r);
        }
        for s in launches.try_iter() {
            if sent_at.is_some() {
                w.launch(&s);
            }
        }
        for r in &traj {
            for m in r.try_iter() {
                let at = m.header.utime;
                w.tracking.trajectory(&m, at);
            }
        }
        for r in &meas {
            for m in r.try_iter() {
                w.tracking.measured(&m);
            }
        }
        if w.reached || w.stopped.is_some() || w.dropped.is_some() {
            // The last reports.
            let until = Instant::now() + Duration::from_millis(300);
            while Instant::now() < until {
                node.lcm().handle_timeout(Duration::from_millis(20))?;
            }
            if let Some(p) = poses.try_iter().last() {
                w.pose = Some(p);
            }
            if let Some(r) = reports.try_iter().last() {
                w.report = Some(r);
            }
            break;
        }
    }
    let (lines, ok) = w.summary(target, tolerance, started.elapsed().as_secs_f64());
    let mut out = std::io::stdout().lock();
    for line in lines {
        writeln!(out, "{line}")?;
    }
    if w.gait.is_none() {
        writeln!(
            out,
            "no gait status was heard: is stride-gait running on this bus?"
        )?;
    } else if sent_at.is_none() {
        writeln!(out, "the goal was not sent")?;
    }
    Ok(if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn command(
    l: &Launch<Cli, NoConfig>,
    channels: &[&str],
    command: i8,
    reason: &str,
) -> anyhow::Result<ExitCode> {
    let node = l.start_as("stride-stop")?;
    let msg = GaitCommandT {
        header: Stamper::new("").stamp(),
        command,
        reason: reason.to_string(),
        ..Default::default()
    };
    for ch in channels {
        node.lcm().publish(ch, &msg)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// The system stop message.
pub fn stop_msg(header: stride_lcmtypes::stride::HeaderT, reason: &str) -> GaitCommandT {
    GaitCommandT {
        header,
        command: GaitCommandT::COMMAND_STOP,
        reason: reason.to_string(),
        ..Default::default()
    }
}

fn status(l: &Launch<Cli, NoConfig>, wait: f64) -> anyhow::Result<ExitCode> {
    if !(wait.is_finite() && wait > 0.0) {
        anyhow::bail!("--wait must be a positive number of seconds");
    }
    let node = l.start_as("stride-status")?;
    let (_a, launches) = node.queue::<LaunchStatusT>(STATUS_CHANNEL)?;
    let (_b, beats) = node.queue::<NodeStatusT>(stride_node::STATUS_CHANNEL)?;
    let until = Instant::now() + Duration::from_secs_f64(wait);
    while Instant::now() < until {
        node.lcm().handle_timeout(Duration::from_millis(50))?;
    }
    let mut hosts: std::collections::BTreeMap<(String, String), LaunchStatusT> = Default::default();
    for s in launches.try_iter() {
        hosts.insert((s.profile.clone(), s.host.clone()), s);
    }
    let mut nodes: std::collections::BTreeMap<String, NodeStatusT> = Default::default();
    for b in beats.try_iter() {
        nodes.insert(b.node.clone(), b);
    }
    let mut out = std::io::stdout().lock();
    if hosts.is_empty() {
        writeln!(out, "no deputy reported within {wait} s")?;
    }
    let mut under: std::collections::BTreeSet<String> = Default::default();
    for ((profile, host), s) in &hosts {
        writeln!(
            out,
            "{profile} on {host} (deputy pid {}){}",
            s.pid,
            if s.stopping { ", shutting down" } else { "" }
        )?;
        writeln!(
            out,
            "  {:<16} {:<9} {:>7} {:>8} {:>9} {:>6} {:>8} {:>8} {:>8}  detail",
            "app", "state", "pid", "restarts", "heartbeat", "cpu %", "mem MB", "pub/s", "recv/s"
        )?;
        for a in &s.apps {
            under.insert(a.name.clone());
            writeln!(
                out,
                "  {:<16} {:<9} {:>7} {:>8} {:>9} {:>6.1} {:>8.1} {:>8.1} {:>8.1}  {}{}",
                a.name,
                state_word(a.state),
                a.pid,
                a.restarts,
                if a.heartbeat_age < 0.0 {
                    "-".to_string()
                } else {
                    format!("{:.1} s", a.heartbeat_age)
                },
                a.cpu * 100.0,
                a.memory as f64 / 1e6,
                a.publish_rate,
                a.receive_rate,
                if a.critical { "critical; " } else { "" },
                a.detail
            )?;
        }
    }
    let others: Vec<&NodeStatusT> = nodes
        .values()
        .filter(|n| !under.contains(&n.node) && !n.node.starts_with("stride-status"))
        .collect();
    if !others.is_empty() {
        writeln!(out, "nodes not under a deputy:")?;
        for n in others {
            writeln!(
                out,
                "  {:<24} on {:<12} pid {:>7} {} {}",
                n.node,
                n.host,
                n.pid,
                node_state_word(n.state),
                n.detail
            )?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// A deputy: one host's apps of a profile.
pub struct Deputy {
    /// The apps it supervises.
    pub sup: Supervisor,
    host: Option<String>,
    _subs: Vec<lcm::Subscription>,
    beats: Receiver<NodeStatusT>,
    orders: Receiver<LaunchOrderT>,
    stops: Receiver<GaitCommandT>,
    status: Spaced,
    status_stamp: Stamper,
    console_stamp: Stamper,
    /// The system stop's headers: one sequence however often it is sent.
    stop_stamp: Stamper,
    /// The system stop in force (re-sent every second, so a restarted app hears it), and
    /// when it was last sent.
    stop: Option<(String, Instant)>,
    changed: bool,
}

impl Deputy {
    /// Subscribes and starts supervising.
    pub fn start(
        node: &Node,
        profile: Profile,
        host: Option<String>,
        log_dir: PathBuf,
    ) -> anyhow::Result<Deputy> {
        let ch = profile.file.channels.clone();
        let (a, beats) = node.queue::<NodeStatusT>(&ch.heartbeat)?;
        let (b, orders) = node.queue::<LaunchOrderT>(&ch.order)?;
        let (c, stops) = node.queue::<GaitCommandT>(&ch.stop)?;
        a.set_queue_capacity(10_000)?;
        let dir = log_dir.join(&profile.name);
        tracing::info!(
            profile = profile.name.as_str(),
            host = host.as_deref().unwrap_or("all"),
            logs = %dir.display(),
            "launching"
        );
        node.set_running();
        Ok(Deputy {
            sup: Supervisor::new(profile, host.as_deref(), Some(dir)),
            host,
            _subs: vec![a, b, c],
            beats,
            orders,
            stops,
            status: Spaced::new(Duration::from_secs(1), Duration::from_millis(100)),
            status_stamp: Stamper::new(""),
            stop_stamp: Stamper::new(""),
            console_stamp: Stamper::new(""),
            stop: None,
            changed: true,
        })
    }

    fn mine(&self, o: &LaunchOrderT) -> bool {
        o.profile == self.sup.profile().name
            && (o.host.is_empty() || self.host.as_deref().is_none_or(|h| h == o.host))
    }

    /// One turn of the deputy's work.
    fn turn(&mut self, node: &Node, now: Instant) -> anyhow::Result<()> {
        for b in self.beats.try_iter() {
            self.sup.heartbeat(b, now);
        }
        let orders: Vec<LaunchOrderT> = self.orders.try_iter().filter(|o| self.mine(o)).collect();
        for o in &orders {
            match o.order {
                LaunchOrderT::ORDER_SHUTDOWN => {
                    tracing::info!("shutdown ordered");
                    self.sup.begin_shutdown(now);
                }
                LaunchOrderT::ORDER_STOP => {
                    self.sup.stop_app(&o.app, now);
                }
                LaunchOrderT::ORDER_START => {
                    self.sup.start_app(&o.app);
                }
                LaunchOrderT::ORDER_RESTART => {
                    self.sup.stop_app(&o.app, now);
                    self.sup.start_app(&o.app);
                }
                other => tracing::warn!("unknown order {other}"),
            }
            self.changed = true;
        }
        for s in self.stops.try_iter() {
            if s.command == GaitCommandT::COMMAND_RESUME && self.stop.is_some() {
                tracing::info!("system stop lifted");
                self.stop = None;
            }
        }
        let p = node.publisher();
        let ch = self.sup.profile().file.channels.clone();
        for n in self.sup.step(now) {
            match n {
                Note::SystemStop(why) => {
                    tracing::error!("system stop: {why}");
                    p.publish(&ch.stop, &stop_msg(self.stop_stamp.stamp(), &why))?;
                    self.stop = Some((why, now));
                }
                Note::Changed { .. } => self.changed = true,
            }
        }
        if let Some((why, at)) = &mut self.stop {
            if now.saturating_duration_since(*at) >= Duration::from_secs(1) {
                *at = now;
                p.publish(&ch.stop, &stop_msg(self.stop_stamp.stamp(), why))?;
            }
        }
        // Console lines: tagged on stdout, forwarded per app.
        let lines = self.sup.lines();
        let mut out = std::io::stdout().lock();
        let mut batches: Vec<LaunchConsoleT> = Vec::new();
        for l in &lines {
            let _ = writeln!(out, "[{}] {}", l.app, l.text);
            match batches
                .iter_mut()
                .find(|b| b.app == l.app && b.stream == l.stream)
            {
                Some(b) => b.lines.push(l.text.clone()),
                None => batches.push(LaunchConsoleT {
                    host: hostname(),
                    app: l.app.clone(),
                    stream: l.stream,
                    lines: vec![l.text.clone()],
                    ..Default::default()
                }),
            }
        }
        drop(out);
        for mut b in batches {
            b.header = self.console_stamp.stamp();
            b.num_lines = b.lines.len() as i32;
            p.publish(&ch.console, &b)?;
        }
        if self.status.take(now, self.changed) {
            self.changed = false;
            let apps = self.sup.report(now);
            let msg = LaunchStatusT {
                header: self.status_stamp.stamp(),
                profile: self.sup.profile().name.clone(),
                host: self.host.clone().unwrap_or_else(hostname),
                pid: std::process::id() as i32,
                stopping: self.sup.shutting_down(),
                num_apps: apps.len() as i32,
                apps,
            };
            p.publish(&ch.status, &msg)?;
        }
        Ok(())
    }
}

/// The name of a node's heartbeat state.
pub fn node_state_word(s: i8) -> &'static str {
    match s {
        NodeStatusT::STATE_STARTING => "starting",
        NodeStatusT::STATE_RUNNING => "running",
        NodeStatusT::STATE_DEGRADED => "degraded",
        NodeStatusT::STATE_FAULT => "FAULT",
        NodeStatusT::STATE_STOPPING => "stopping",
        NodeStatusT::STATE_STALLED => "STALLED",
        _ => "?",
    }
}

/// A figure, short whatever its size (three decimals, or an exponent beyond a million): as
/// the gait prints a goal.
fn short(x: f64) -> String {
    if x.is_finite() && x.abs() < 1e6 {
        format!("{x:.3}")
    } else {
        format!("{x:.3e}")
    }
}

fn hostname() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|s| s.trim().to_string())
        .unwrap_or_default()
}

impl Tick for Deputy {
    const WAKE_ON_MESSAGE: bool = false;

    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        self.turn(node, now)?;
        if self.sup.shutting_down() && self.sup.all_down() {
            tracing::info!("every app stopped");
            node.request_shutdown();
        }
        Ok(now + Duration::from_millis(50))
    }

    fn stop(mut self, node: &Node) -> anyhow::Result<()> {
        // The ordered shutdown: the node's loop has ended (Ctrl-C, an order); the apps are
        // stopped stage by stage while the deputy keeps reporting.
        self.sup.begin_shutdown(Instant::now());
        while !self.sup.all_down() {
            let _ = node.lcm().handle_timeout(Duration::from_millis(50));
            self.turn(node, Instant::now())?;
        }
        self.changed = true;
        self.turn(node, Instant::now())?;
        Ok(())
    }
}
