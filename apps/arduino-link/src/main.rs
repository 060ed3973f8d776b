//! `stride-arduino-link`: one Arduino Due joint-controller board on LCM.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::Parser;
use stride_arduino_link::{
    imu_msg, state_msgs, Attitude, LinkConfig, ACCEL_COUNTS_PER_G, GYRO_COUNTS_PER_RAD_S,
};
use stride_fakes::due::{DueConfig, DueLevers, FakeDue};
use stride_lcmtypes::stride::{JointCommandT, NodeStatusT};
use stride_link::{JointCommand, Message, Mode};
use stride_link_host::Session;
use stride_node::{load_config, Node, NodeArgs, Stamper, Ticker};
use stride_serial::{Paced, Transport};

/// Drive one Arduino Due joint-controller board (a leg of Archie) from LCM.
///
/// Joint commands (stride.joint_command_t: duty, position, brake or disable) are checked
/// against the configured limits (a command past one is refused whole and reported, never
/// clipped) and sent to the board; heartbeats keep the board's watchdog fed when there are
/// none. The board's joint states go out as stride.arduino_joint_state_t and
/// stride.joint_state_t, its MPU-6050 samples as stride.imu_t with the hip's attitude from a
/// complementary filter, its faults in the node status. At connect it checks the link version
/// in a handshake, waiting out the reset that opening the port causes; when the port vanishes
/// (the cable pulled) it says so, reopens it when it is back, and handshakes again. A joint
/// above current_limit_a is braked. On shutdown every joint is braked.
#[derive(Parser, Debug)]
#[command(version, about, long_about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
}

type Sim = (Arc<AtomicBool>, std::thread::JoinHandle<FakeDue>);

/// Opens the board's line: the serial device, or a fake board on a pty in this process.
fn open(cfg: &LinkConfig, sim: &mut Option<Sim>) -> std::io::Result<Box<dyn Transport>> {
    if cfg.port == "sim" {
        let (host, dev) = stride_serial::pty_pair(cfg.baud)?;
        let stop = Arc::new(AtomicBool::new(false));
        let board = FakeDue::new(DueConfig::default()).spawn(
            Paced::new(dev),
            DueLevers::default(),
            stop.clone(),
        );
        if let Some((old, h)) = sim.replace((stop, board)) {
            old.store(true, Ordering::Relaxed);
            let _ = h.join();
        }
        return Ok(Box::new(host));
    }
    Ok(Box::new(stride_serial::open(&cfg.port, cfg.baud)?))
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let cfg: LinkConfig = load_config(cli.node.config.as_deref())?;
    cfg.check().map_err(anyhow::Error::msg)?;
    let node = Node::start("stride-arduino-link", &cli.node)?;
    let (_sub, rx) = node.queue::<JointCommandT>(&cfg.command_channel)?;
    let publisher = node.publisher();
    let mut stamper = Stamper::new(&cfg.board);
    let mut ticker = Ticker::new(cfg.rate_hz);
    let mut sim: Option<Sim> = None;
    let mut session: Option<Session<Box<dyn Transport>>> = None;
    let mut next_try = Instant::now();
    let mut last_sent = Instant::now();
    let mut last_heard = Instant::now();
    let mut attitude = Attitude::new(cfg.imu_time_constant_s);
    let mut last_imu: Option<u32> = None;
    let mut imu_raw = ([0i16; 3], [0i16; 3]);
    let mut rejected = 0u64;
    let mut braked_by_host = [false; 8];
    let handshake = Duration::from_millis(cfg.handshake_timeout_ms);
    node.set_health(NodeStatusT::STATE_STARTING, "connecting to the board");
    while let Some(now) = ticker.wait(&node)? {
        // Connect (again) when there is no session.
        let Some(s) = session.as_mut() else {
            while rx.try_recv().is_ok() {
                rejected += 1;
            }
            if now < next_try {
                continue;
            }
            next_try = now + Duration::from_millis(cfg.reconnect_ms);
            let mut s = match open(&cfg, &mut sim) {
                Ok(line) => Session::new(line),
                Err(e) => {
                    node.set_health(
                        NodeStatusT::STATE_FAULT,
                        format!("{}: {e}; retrying", cfg.port),
                    );
                    continue;
                }
            };
            match s.handshake(handshake, Duration::from_millis(250)) {
                Ok(b) => {
                    tracing::info!(
                        firmware = b.firmware.as_str(),
                        joints = b.joints,
                        "board connected"
                    );
                    session = Some(s);
                    last_heard = Instant::now();
                    attitude = Attitude::new(cfg.imu_time_constant_s);
                    last_imu = None;
                    node.set_running();
                }
                Err(e) => {
                    tracing::warn!(error = %e, "no board");
                    node.set_health(
                        NodeStatusT::STATE_FAULT,
                        format!("{}: {e}; retrying", cfg.port),
                    );
                }
            }
            continue;
        };
        let mut io_error = None;
        // Commands, checked; heartbeats when there are none.
        while let Ok(c) = rx.try_recv() {
            match cfg.to_board(&c) {
                Ok(joints) => match s.send(&Message::Command(joints)) {
                    Ok(_) => last_sent = now,
                    Err(e) => io_error = Some(e),
                },
                Err(e) => {
                    rejected += 1;
                    tracing::warn!(error = %e, rejected, "command rejected");
                    node.set_health(
                        NodeStatusT::STATE_DEGRADED,
                        format!("command rejected: {e}"),
                    );
                }
            }
        }
        if io_error.is_none()
            && now.saturating_duration_since(last_sent) >= Duration::from_millis(50)
        {
            match s.send(&Message::Heartbeat(node.uptime().as_millis() as u32)) {
                Ok(_) => last_sent = now,
                Err(e) => io_error = Some(e),
            }
        }
        // What the board sent.
        let msgs = match s.receive(Instant::now() + Duration::from_millis(1)) {
            Ok(m) => m,
            Err(e) => {
                io_error = Some(e);
                Vec::new()
            }
        };
        if !msgs.is_empty() {
            last_heard = now;
        } else if io_error.is_none()
            && now.saturating_duration_since(last_heard) > Duration::from_millis(500)
        {
            // The board streams its state at 100 Hz: half a second of silence is a lost link.
            io_error = Some(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                "the board has been silent for 500 ms",
            ));
        }
        let firmware = s.board().map(|b| b.firmware.clone()).unwrap_or_default();
        let lost = (s.stats().lost + s.stats().bad) as i32;
        let mut brake: Vec<JointCommand> = Vec::new();
        for m in msgs {
            match m {
                Message::State { joints, .. } => {
                    let header = stamper.stamp();
                    let (a, j) = state_msgs(&cfg, header, &firmware, &joints, imu_raw, lost);
                    let _ = publisher.publish(&cfg.state_channel, &a);
                    let _ = publisher.publish(&cfg.joint_state_channel, &j);
                    // The host's own current limit.
                    for jc in &cfg.joint {
                        let Some(st) = joints.get(jc.index as usize) else {
                            continue;
                        };
                        let over = st.current as f64 / 1000.0 > cfg.current_limit_a;
                        if over && !braked_by_host[jc.index as usize] {
                            braked_by_host[jc.index as usize] = true;
                            brake.push(JointCommand {
                                joint: jc.index,
                                mode: Mode::Brake,
                                value: 0,
                            });
                            node.set_health(
                                NodeStatusT::STATE_DEGRADED,
                                format!("{}: {} mA over the limit: braked", jc.name, st.current),
                            );
                        } else if !over {
                            braked_by_host[jc.index as usize] = false;
                        }
                    }
                }
                Message::Imu {
                    t_us,
                    accel,
                    temperature,
                    gyro,
                } => {
                    let dt = last_imu.map_or(0.0, |t| t_us.wrapping_sub(t) as f64 * 1e-6);
                    last_imu = Some(t_us);
                    attitude.update(
                        accel.map(|a| a as f64 / ACCEL_COUNTS_PER_G),
                        gyro.map(|g| g as f64 / GYRO_COUNTS_PER_RAD_S),
                        dt,
                    );
                    imu_raw = (accel, gyro);
                    let msg = imu_msg(stamper.stamp(), accel, temperature, gyro, &attitude);
                    let _ = publisher.publish(&cfg.imu_channel, &msg);
                }
                Message::Fault {
                    joint,
                    bits,
                    detail,
                } => {
                    let who = cfg
                        .joint
                        .iter()
                        .find(|j| j.index == joint)
                        .map_or_else(|| "board".to_string(), |j| j.name.clone());
                    let what = [
                        (1, "over-current"),
                        (2, "over-temperature"),
                        (4, "watchdog"),
                        (8, "driver"),
                        (16, "link"),
                    ]
                    .iter()
                    .filter(|(b, _)| bits & b != 0)
                    .map(|(_, n)| *n)
                    .collect::<Vec<_>>()
                    .join(", ");
                    tracing::warn!(
                        who = who.as_str(),
                        what = what.as_str(),
                        detail,
                        "board fault"
                    );
                    node.set_health(
                        NodeStatusT::STATE_DEGRADED,
                        format!("{who}: fault: {what} ({detail})"),
                    );
                }
                Message::Nack { seq, reason } => {
                    tracing::warn!(seq, reason, "the board refused a frame");
                }
                _ => {}
            }
        }
        if !brake.is_empty() {
            if let Err(e) = s.send(&Message::Command(brake)) {
                io_error = Some(e);
            }
        }
        if let Some(e) = io_error {
            tracing::error!(error = %e, "lost the board; reconnecting");
            node.set_health(
                NodeStatusT::STATE_FAULT,
                format!("{}: {e}; reconnecting", cfg.port),
            );
            session = None;
            next_try = Instant::now() + Duration::from_millis(cfg.reconnect_ms);
        }
    }
    if let Some(s) = session.as_mut() {
        tracing::info!("braking every joint");
        let _ = s.send(&cfg.brake_all());
        std::thread::sleep(Duration::from_millis(20));
    }
    if let Some((stop, h)) = sim {
        stop.store(true, Ordering::Relaxed);
        let _ = h.join();
    }
    Ok(())
}
