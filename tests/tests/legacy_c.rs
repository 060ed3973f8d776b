//! A legacy C controller (liblcm + lcm-gen C types) and the Rust executables on one bus.

use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use lcm::Lcm;
use stride_lcmtypes::stride::{JointCommandT, JointStateT};
use stride_tests::{require_sandbox, udpm_url, Proc};

fn controller(url: &str) -> Proc {
    let mut c = Command::new(env!("STRIDE_LEGACY_CONTROLLER"));
    c.args(["-u", url, "-n", "4", "-r", "100", "-d", "30"]);
    Proc::spawn(c)
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn stride_ping_round_trips_through_the_c_controller() {
    require_sandbox();
    let url = udpm_url(7721);
    let ctl = controller(&url);
    // Ready once it publishes: it subscribes before its loop starts.
    stride_tests::wait_for(
        &url,
        "JOINT_STATE",
        Duration::from_secs(20),
        |_: &JointStateT| true,
    );
    stride_tests::ping_all_echoed(&url, 30, 100);
    let (st, out) = ctl.interrupt();
    assert!(st.success(), "{out}");
    assert!(out.contains("30 pings"), "{out}");
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn rust_commands_move_the_c_controllers_joints() {
    require_sandbox();
    let url = udpm_url(7722);
    let ctl = controller(&url);
    let lcm = Lcm::new(&url).unwrap();
    let states: Arc<Mutex<Vec<JointStateT>>> = Arc::default();
    let s = states.clone();
    let sub = lcm
        .subscribe("JOINT_STATE", move |_, m: JointStateT| {
            s.lock().unwrap().push(m)
        })
        .unwrap();
    let cmd = JointCommandT {
        num_joints: 2,
        names: vec!["joint1".into(), "joint3".into()],
        modes: vec![JointCommandT::MODE_POSITION; 2],
        setpoints: vec![0.3, -0.2],
        velocities: vec![0.0; 2],
        ..Default::default()
    };
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut reached = false;
    while Instant::now() < deadline && !reached {
        lcm.publish("JOINT_COMMAND", &cmd).unwrap();
        lcm.handle_timeout(Duration::from_millis(50)).unwrap();
        reached = states.lock().unwrap().last().is_some_and(|m| {
            (m.positions[1] - 0.3).abs() < 1e-9 && (m.positions[3] + 0.2).abs() < 1e-9
        });
    }
    assert!(
        reached,
        "the C controller never reached the commanded positions"
    );
    let states = states.lock().unwrap();
    let last = states.last().unwrap();
    assert_eq!(last.names, ["joint0", "joint1", "joint2", "joint3"]);
    assert_eq!(last.positions[0], 0.0);
    assert_eq!(sub.stats().decode_errors, 0);
    assert_eq!(
        sub.stats().lost,
        0,
        "sequence numbers from C must be contiguous"
    );
    let (st, out) = ctl.interrupt();
    assert!(st.success(), "{out}");
}
