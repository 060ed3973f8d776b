//! stride-elmo-bridge as a process: six simulated Elmo drives of Archie's left leg driven from
//! LCM, joint states back, limits, the stream watchdog and shutdown.

use std::path::PathBuf;
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use lcm::Lcm;
use stride_lcmtypes::stride::{JointStateT, JointTrajectoryT, NodeStatusT};
use stride_tests::{bin, in_sandbox, udpm_url, Proc};

const JOINTS: [&str; 6] = [
    "left_hip_yaw",
    "left_hip_roll",
    "left_hip_pitch",
    "left_knee",
    "left_ankle_pitch",
    "left_ankle_roll",
];

fn config() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../config/robots/archie-left-leg.toml")
}

/// True when every joint of `s` is within its configured tolerance of `want`.
fn within_tolerance(s: &JointStateT, want: &[f64]) -> bool {
    let cfg: stride_elmo_bridge::BridgeConfig =
        toml::from_str(&std::fs::read_to_string(config()).unwrap()).unwrap();
    s.names == JOINTS
        && s.positions
            .iter()
            .zip(want)
            .zip(&cfg.joint)
            .all(|((p, q), j)| (p - q).abs() < j.tolerance)
}

/// A smooth move from 0 to `amp` (scaled per joint; the knee only bends forward) in `secs`.
fn trajectory(secs: f64, amp: f64) -> JointTrajectoryT {
    let dt = 0.01;
    let rows = (secs / dt) as usize + 1;
    let scale = [0.2, 0.2, -0.5, 1.0, 0.4, 0.2];
    let s = |t: f64| (1.0 - (std::f64::consts::PI * t / secs).cos()) / 2.0;
    let ds = |t: f64| std::f64::consts::PI / secs * (std::f64::consts::PI * t / secs).sin() / 2.0;
    JointTrajectoryT {
        mode: JointTrajectoryT::MODE_PVT,
        num_joints: 6,
        joint_names: JOINTS.iter().map(|s| s.to_string()).collect(),
        num_rows: rows as i32,
        time_from_start: (0..rows).map(|r| r as f64 * dt).collect(),
        positions: (0..rows)
            .map(|r| scale.iter().map(|k| k * amp * s(r as f64 * dt)).collect())
            .collect(),
        velocities: (0..rows)
            .map(|r| scale.iter().map(|k| k * amp * ds(r as f64 * dt)).collect())
            .collect(),
        ..Default::default()
    }
}

struct Watch {
    states: Arc<Mutex<Vec<JointStateT>>>,
    status: Arc<Mutex<Vec<NodeStatusT>>>,
    _subs: Vec<lcm::Subscription>,
}

fn watch(lcm: &Lcm) -> Watch {
    let states = Arc::new(Mutex::new(Vec::new()));
    let status = Arc::new(Mutex::new(Vec::new()));
    let (s1, s2) = (states.clone(), status.clone());
    let subs = vec![
        lcm.subscribe("JOINT_STATE_LEFT_LEG", move |_, m: JointStateT| {
            s1.lock().unwrap().push(m)
        })
        .unwrap(),
        lcm.subscribe("STRIDE_STATUS", move |_, m: NodeStatusT| {
            s2.lock().unwrap().push(m)
        })
        .unwrap(),
    ];
    Watch {
        states,
        status,
        _subs: subs,
    }
}

fn wait_for(lcm: &Lcm, secs: u64, done: impl FnMut() -> bool) -> bool {
    stride_tests::handle_until(lcm, Duration::from_secs(secs), done)
}

fn start_bridge(url: &str) -> Proc {
    start_bridge_with(url, &config())
}

fn start_bridge_with(url: &str, config: &std::path::Path) -> Proc {
    let mut c = Command::new(bin("stride-elmo-bridge"));
    c.args(["--lcm-url", url, "--log-level", "warn", "--config"])
        .arg(config);
    Proc::spawn(c)
}

#[test]
fn a_trajectory_reaches_the_drives_and_states_come_back() {
    if !in_sandbox() {
        return;
    }
    let url = udpm_url(7751);
    let lcm = Lcm::new(&url).unwrap();
    let w = watch(&lcm);
    let bridge = start_bridge(&url);
    assert!(
        wait_for(&lcm, 10, || w
            .status
            .lock()
            .unwrap()
            .iter()
            .any(|s| s.state == NodeStatusT::STATE_RUNNING)),
        "the bridge never reported running"
    );
    // Within limits, shorter than the stream timeout: it plays to the end.
    let t = trajectory(0.4, 0.5);
    lcm.publish("JOINT_TRAJECTORY_LEFT_LEG", &t).unwrap();
    let last = t.positions.last().unwrap().clone();
    let reached = wait_for(&lcm, 10, || {
        w.states
            .lock()
            .unwrap()
            .last()
            .is_some_and(|s| within_tolerance(s, &last))
    });
    assert!(
        reached,
        "joints did not reach {last:?}: {:?}",
        w.states.lock().unwrap().last()
    );

    // Past the knee's limit: refused whole, reported, nothing moves (the refused trajectory
    // starts at zero, so playing any of it would show).
    let mut bad = trajectory(0.4, 0.5);
    bad.positions[20][3] = 3.0;
    lcm.publish("JOINT_TRAJECTORY_LEFT_LEG", &bad).unwrap();
    assert!(wait_for(&lcm, 5, || w.status.lock().unwrap().iter().any(
        |s| s.state == NodeStatusT::STATE_DEGRADED && s.detail.contains("trajectory rejected")
    )));
    wait_for(&lcm, 1, || false);
    let after = w.states.lock().unwrap().last().unwrap().positions.clone();
    assert!(
        last.iter().zip(&after).all(|(a, b)| (a - b).abs() < 2e-3),
        "moved: {after:?} vs {last:?}"
    );

    let (st, out) = bridge.interrupt();
    assert!(st.success(), "{out}");
    assert!(wait_for(&lcm, 5, || w
        .status
        .lock()
        .unwrap()
        .iter()
        .any(|s| s.state == NodeStatusT::STATE_STOPPING)));
}

#[test]
fn a_stream_that_stops_mid_motion_quick_stops_the_axes() {
    if !in_sandbox() {
        return;
    }
    let url = udpm_url(7752);
    let lcm = Lcm::new(&url).unwrap();
    let w = watch(&lcm);
    let bridge = start_bridge(&url);
    assert!(wait_for(&lcm, 10, || w
        .status
        .lock()
        .unwrap()
        .iter()
        .any(|s| s.state == NodeStatusT::STATE_RUNNING)));
    // The first 0.6 s of a 2 s move, a chunk that ends in motion, then silence: after the
    // stream timeout the axes quick-stop.
    let mut t = trajectory(2.0, 0.5);
    t.num_rows = 61;
    t.time_from_start.truncate(61);
    t.positions.truncate(61);
    t.velocities.truncate(61);
    lcm.publish("JOINT_TRAJECTORY_LEFT_LEG", &t).unwrap();
    let t_full = trajectory(2.0, 0.5);
    assert!(wait_for(&lcm, 5, || w
        .status
        .lock()
        .unwrap()
        .iter()
        .any(|s| s.detail.contains("quick stop"))));
    std::thread::sleep(Duration::from_millis(300));
    wait_for(&lcm, 1, || false);
    let knee = w.states.lock().unwrap().last().unwrap().positions[3];
    let end = t_full.positions.last().unwrap()[3];
    assert!(
        knee < end - 0.05,
        "the knee should have stopped short of {end}: {knee}"
    );
    let (st, out) = bridge.interrupt();
    assert!(st.success(), "{out}");
}

#[test]
fn the_whole_chain_bridge_lcm_gateway_pty_dongle_drives() {
    if !in_sandbox() {
        return;
    }
    let url = udpm_url(7753);
    let dir = tempfile::tempdir().unwrap();
    // Fake dongle + six fake drives, on a pseudo-terminal.
    let pty_file = dir.path().join("pty");
    let rig = {
        let mut c = Command::new(bin("fake-can-rig"));
        c.arg("--pty-file").arg(&pty_file);
        Proc::spawn(c)
    };
    let t0 = Instant::now();
    while !pty_file.exists() && t0.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(10));
    }
    let pty = std::fs::read_to_string(&pty_file).unwrap();
    // The gateway puts the dongle's bus on LCM.
    let dump = dir.path().join("candump.log");
    let gateway = {
        let mut c = Command::new(bin("stride-usb2can"));
        c.args([
            "--lcm-url",
            &url,
            "--log-level",
            "warn",
            "--bus-name",
            "left_leg",
        ])
        .arg("--device")
        .arg(format!("slcan:{pty}"))
        .arg("--candump")
        .arg(&dump);
        Proc::spawn(c)
    };
    // The bridge reaches the drives through LCM.
    // Every frame crosses LCM, the gateway and the serial line: allow the stream more time.
    let text = std::fs::read_to_string(config())
        .unwrap()
        .replace("bus = \"sim\"", "bus = \"lcm:left_leg\"")
        .replace("stream_timeout_ms = 500", "stream_timeout_ms = 5000");
    let cfg = dir.path().join("leg.toml");
    std::fs::write(&cfg, text).unwrap();
    let lcm = Lcm::new(&url).unwrap();
    let w = watch(&lcm);
    std::thread::sleep(Duration::from_millis(500));
    let bridge = start_bridge_with(&url, &cfg);
    assert!(
        wait_for(&lcm, 20, || w.status.lock().unwrap().iter().any(|s| s.node
            == "stride-elmo-bridge"
            && s.state == NodeStatusT::STATE_RUNNING)),
        "the bridge never came up through the chain"
    );
    let t = trajectory(0.4, 0.5);
    lcm.publish("JOINT_TRAJECTORY_LEFT_LEG", &t).unwrap();
    let last = t.positions.last().unwrap().clone();
    assert!(
        wait_for(&lcm, 15, || w
            .states
            .lock()
            .unwrap()
            .last()
            .is_some_and(|s| within_tolerance(s, &last))),
        "joints did not reach the end through the chain: {:?}",
        w.states.lock().unwrap().last()
    );
    // A drive in fault: its emergency is published in the bridge's status.
    rig.signal(libc::SIGUSR1);
    assert!(
        wait_for(&lcm, 5, || w
            .status
            .lock()
            .unwrap()
            .iter()
            .any(|s| s.node == "stride-elmo-bridge"
                && s.detail.contains("left_hip_yaw: emergency 0x2310"))),
        "the fault was not published"
    );
    let (st, out) = bridge.interrupt();
    assert!(st.success(), "{out}");
    let (st, out) = gateway.interrupt();
    assert!(st.success(), "{out}");
    assert!(out.contains("frames from the wire"), "{out}");
    drop(rig);
    let dump = std::fs::read_to_string(&dump).unwrap();
    assert!(
        dump.lines().any(|l| l.contains(" left_leg 601#40")),
        "no SDO read to node 1 in the candump log"
    );
    assert!(dump.lines().count() > 100);
}
