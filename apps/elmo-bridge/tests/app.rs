//! The bridge's state machine in this process, on `memq://` and its fake drives: what
//! `stride-elmo-bridge` runs, driven tick by tick.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use stride_elmo_bridge::{BridgeConfig, ElmoApp};
use stride_lcmtypes::stride::{JointStateT, JointTrajectoryT};
use stride_node::{Node, NodeArgs, Tick};

fn config() -> BridgeConfig {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../config/robots/archie-left-leg.toml"
    ))
    .unwrap();
    toml::from_str(&text).unwrap()
}

/// A minimum-jerk move of joint `joint` from 0 to `to` in `secs`, rows 10 ms apart.
fn move_to(names: &[String], joint: usize, to: f64, secs: f64) -> JointTrajectoryT {
    let mut goal = vec![0.0; names.len()];
    goal[joint] = to;
    let m = stride_limits::moves::min_jerk(&vec![0.0; names.len()], &goal, secs, 0.01);
    JointTrajectoryT {
        mode: JointTrajectoryT::MODE_PVT,
        queue: JointTrajectoryT::QUEUE_REPLACE,
        num_joints: names.len() as i32,
        joint_names: names.to_vec(),
        num_rows: m.times.len() as i32,
        positions: m.positions,
        velocities: m.velocities,
        time_from_start: m.times,
        ..Default::default()
    }
}

/// Ticks `app` as the frame does (handling the node's messages between ticks) for `d`.
fn drive(node: &Node, app: &mut ElmoApp<'_>, d: Duration) {
    let end = Instant::now() + d;
    let mut wake = Instant::now();
    while Instant::now() < end {
        let wait = wake
            .saturating_duration_since(Instant::now())
            .min(end.saturating_duration_since(Instant::now()));
        node.lcm().handle_timeout(wait).unwrap();
        wake = app.tick(node, Instant::now()).unwrap();
    }
}

#[test]
fn the_app_brings_up_its_drives_plays_a_trajectory_and_stops_them() {
    let args = NodeArgs {
        lcm_url: "memq://".into(),
        ..Default::default()
    };
    let node = Node::start("elmo-app-test", &args).unwrap();
    let cfg = config();
    let names: Vec<String> = cfg.joint.iter().map(|j| j.name.clone()).collect();
    let knee = names.iter().position(|n| n == "left_knee").unwrap();
    let latest: Arc<Mutex<Option<JointStateT>>> = Arc::default();
    let l = latest.clone();
    let _states = node
        .lcm()
        .subscribe(&cfg.state_channel, move |_, m: JointStateT| {
            *l.lock().unwrap() = Some(m)
        })
        .unwrap();
    let channel = cfg.trajectory_channel.clone();
    let mut app = ElmoApp::start(&node, cfg).unwrap();
    drive(&node, &mut app, Duration::from_millis(200));
    assert!(latest.lock().unwrap().is_some(), "no joint states");
    node.lcm()
        .publish(&channel, &move_to(&names, knee, 0.3, 0.5))
        .unwrap();
    drive(&node, &mut app, Duration::from_millis(1000));
    let s = latest.lock().unwrap().clone().unwrap();
    assert!((s.positions[knee] - 0.3).abs() < 0.01, "{:?}", s.positions);
    // Stopping decelerates, then disables the drives; the fakes stop with the app.
    app.stop(&node).unwrap();
}
