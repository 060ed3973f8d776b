//! The Java side of the LCM tools (lcm-spy's world): the jar `scripts/spy` builds from the
//! stride .lcm files decodes what our Rust code publishes.

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use lcm::Lcm;
use stride_lcmtypes::stride::{HeaderT, JointTrajectoryT, NodeStatusT, PingT};
use stride_tests::{require_sandbox, udpm_url};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn java_types_decode_messages_published_from_rust() {
    require_sandbox();
    let out = Command::new("bash")
        .arg(root().join("scripts/spy"))
        .arg("--build-only")
        .output()
        .expect("running scripts/spy");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let jar = String::from_utf8(out.stdout).unwrap().trim().to_owned();
    let dir = tempfile::tempdir().unwrap();
    let cp = format!("/usr/share/java/lcm.jar:{jar}");
    let st = Command::new("javac")
        .args(["-nowarn", "-cp", &cp, "-d"])
        .arg(dir.path())
        .arg(root().join("tests/java/StrideDecode.java"))
        .status()
        .expect("javac");
    assert!(st.success());

    let url = udpm_url(7731);
    let mut java = Command::new("java")
        .arg("-Djava.net.preferIPv4Stack=true")
        .arg("-cp")
        .arg(format!("{cp}:{}", dir.path().display()))
        .args(["StrideDecode", &url])
        .stdout(Stdio::piped())
        .spawn()
        .expect("java");

    let lcm = Lcm::new(&url).unwrap();
    let ping = PingT {
        header: HeaderT {
            utime: 1,
            sequence: 42,
            frame: "map".into(),
        },
        payload_size: 5,
        payload: vec![1, 2, 3, 4, 250],
        ..Default::default()
    };
    let status = NodeStatusT {
        node: "rust-node".into(),
        state: NodeStatusT::STATE_DEGRADED,
        detail: "from rust".into(),
        ..Default::default()
    };
    let traj = JointTrajectoryT {
        mode: JointTrajectoryT::MODE_PVT,
        num_joints: 3,
        joint_names: vec!["hip".into(), "knee".into(), "ankle".into()],
        num_rows: 2,
        time_from_start: vec![0.0, 0.5],
        positions: vec![vec![0.0; 3], vec![0.1, 0.2, 0.75]],
        velocities: vec![vec![0.0; 3]; 2],
        ..Default::default()
    };
    // Java needs a moment to start and subscribe: publish until it has seen all three.
    let deadline = Instant::now() + Duration::from_secs(30);
    let status_code = loop {
        lcm.publish("JAVA_CHECK_PING", &ping).unwrap();
        lcm.publish("JAVA_CHECK_STATUS", &status).unwrap();
        lcm.publish("JAVA_CHECK_TRAJ", &traj).unwrap();
        std::thread::sleep(Duration::from_millis(100));
        if let Some(code) = java.try_wait().unwrap() {
            break code;
        }
        if Instant::now() > deadline {
            let _ = java.kill();
            panic!("the Java decoder did not finish");
        }
    };
    let out = java.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(status_code.success(), "{text}");
    assert!(
        text.contains("ping_t sequence=42 frame=map payload_size=5 last_byte=250"),
        "{text}"
    );
    assert!(
        text.contains("node_status_t node=rust-node state=2 detail=from rust"),
        "{text}"
    );
    assert!(
        text.contains("joint_trajectory_t joints=hip,knee,ankle rows=2 positions[1][2]=0.75"),
        "{text}"
    );
}
