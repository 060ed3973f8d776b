//! stride-arduino-link as a process against the fake Due board process on a pty: commands and
//! states, the hip attitude, a refused command, the board's watchdog when the host stalls, the
//! cable pulled and plugged back, and the brakes on shutdown.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use lcm::Lcm;
use stride_lcmtypes::stride::{
    ArduinoJointStateT, ImuT, JointCommandT, JointStateT, NodeStatusT, PoseStampedT,
};
use stride_tests::{bin, handle_until, on_bus, require_sandbox, udpm_url, Proc};

fn config(dir: &Path, link: &Path) -> PathBuf {
    let text = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../config/robots/archie-arduino-left-leg.toml"),
    )
    .unwrap()
    .replace("port = \"sim\"", &format!("port = \"{}\"", link.display()));
    let path = dir.join("left.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn duty(joint: &str, d: f64) -> JointCommandT {
    JointCommandT {
        num_joints: 1,
        names: vec![joint.into()],
        modes: vec![JointCommandT::MODE_DUTY],
        setpoints: vec![d],
        velocities: vec![0.0],
        ..Default::default()
    }
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn a_leg_board_through_its_link() {
    require_sandbox();
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("due-left");
    let mut c = Command::new(bin("fake-due"));
    // The board spends 1.5 s in its boot loader after each plug-in, as a Due does.
    c.arg("--link")
        .arg(&link)
        .args(["--tilt", "0.2,-0.1", "--boot-ms", "1500"]);
    let board = Proc::spawn(c);
    let t0 = Instant::now();
    while !link.exists() && t0.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(10));
    }
    let url = udpm_url(7771);
    let lcm = Lcm::new(&url).unwrap();
    let states = Arc::new(Mutex::new(Vec::<ArduinoJointStateT>::new()));
    let imu = Arc::new(Mutex::new(Vec::<ImuT>::new()));
    let status = Arc::new(Mutex::new(Vec::<NodeStatusT>::new()));
    let (s1, s2, s3) = (states.clone(), imu.clone(), status.clone());
    let _subs = [
        lcm.subscribe(
            "ARCHIE_LEFT_LEG_ARDUINO",
            move |_, m: ArduinoJointStateT| s1.lock().unwrap().push(m),
        )
        .unwrap(),
        lcm.subscribe("ARCHIE_LEFT_HIP_IMU", move |_, m: ImuT| {
            s2.lock().unwrap().push(m)
        })
        .unwrap(),
        lcm.subscribe("STRIDE_STATUS", move |_, m: NodeStatusT| {
            s3.lock().unwrap().push(m)
        })
        .unwrap(),
    ];
    let mut c = Command::new(bin("stride-arduino-link"));
    c.args(["--lcm-url", &url, "--log-level", "warn", "--config"])
        .arg(config(dir.path(), &link));
    let app = Proc::spawn(c);
    let running = |st: &Arc<Mutex<Vec<NodeStatusT>>>| {
        st.lock()
            .unwrap()
            .last()
            .is_some_and(|s| s.state == NodeStatusT::STATE_RUNNING)
    };
    assert!(
        handle_until(&lcm, Duration::from_secs(10), || running(&status)),
        "never connected"
    );
    // Sends the knee `d` until the last state passes `check`.
    let drive = |d: f64, check: &dyn Fn(&ArduinoJointStateT) -> bool| {
        handle_until(&lcm, Duration::from_secs(5), || {
            lcm.publish("ARCHIE_LEFT_LEG_COMMAND", &duty("left_knee", d))
                .unwrap();
            std::thread::sleep(Duration::from_millis(20));
            states.lock().unwrap().last().is_some_and(check)
        })
    };
    // A duty command drives the knee; the state says so (its position the board does not read
    // yet: the plant's, printed when the cable is pulled, is checked below).
    let moved = drive(0.4, &|s| (s.duty[3] - 0.4).abs() < 1e-3 && !s.brake[3]);
    assert!(moved, "{:?}", states.lock().unwrap().last());
    // The hip attitude converges to the board's tilt.
    let attitude = || {
        let q = imu.lock().unwrap().last()?.orientation;
        let roll =
            (2.0 * (q[0] * q[1] + q[2] * q[3])).atan2(1.0 - 2.0 * (q[1] * q[1] + q[2] * q[2]));
        let pitch = (2.0 * (q[0] * q[2] - q[3] * q[1])).asin();
        Some((roll, pitch))
    };
    let converged = handle_until(&lcm, Duration::from_secs(3), || {
        attitude()
            .is_some_and(|(roll, pitch)| (roll - 0.2).abs() < 0.02 && (pitch + 0.1).abs() < 0.02)
    });
    assert!(converged, "roll, pitch: {:?}", attitude());
    // Past a joint's duty limit: refused and reported.
    lcm.publish("ARCHIE_LEFT_LEG_COMMAND", &duty("left_knee", 0.95))
        .unwrap();
    assert!(handle_until(&lcm, Duration::from_secs(3), || status
        .lock()
        .unwrap()
        .iter()
        .any(|s| s.detail.contains("command rejected"))));
    // The host stalls: the board's watchdog brakes and says so.
    app.signal(libc::SIGSTOP);
    std::thread::sleep(Duration::from_millis(400));
    app.signal(libc::SIGCONT);
    assert!(handle_until(&lcm, Duration::from_secs(3), || states
        .lock()
        .unwrap()
        .iter()
        .any(|s| s.brake[3]
            && s.faults[3] as i32
                & ArduinoJointStateT::FAULT_WATCHDOG as i32
                != 0)));
    // The cable comes out and goes back in: reported, then connected again.
    status.lock().unwrap().clear();
    board.signal(libc::SIGUSR1);
    assert!(handle_until(&lcm, Duration::from_secs(5), || status
        .lock()
        .unwrap()
        .iter()
        .any(|s| s.state == NodeStatusT::STATE_FAULT)));
    assert!(
        handle_until(&lcm, Duration::from_secs(10), || running(&status)),
        "never reconnected"
    );
    // Driving again, then shut down: the app brakes every joint on its way out.
    states.lock().unwrap().clear();
    assert!(drive(0.3, &|s| !s.brake[3] && s.duty[3] > 0.29));
    let (st, _) = app.interrupt();
    assert!(st.success());
    let (_, out) = board.interrupt();
    assert!(
        out.contains("braked: [true, true, true, true, true, true]"),
        "{out}"
    );
    // The knee had turned under the first board's duty (0.4, 2 rad/s, for at least the 100 ms
    // of the watchdog before it braked) before the cable came out.
    let knee = out
        .lines()
        .find_map(|l| l.strip_prefix("unplugged; positions: ["))
        .and_then(|l| l.trim_end_matches(']').split(", ").nth(3))
        .and_then(|p| p.parse::<f64>().ok());
    assert!(knee.is_some_and(|p| p > 0.05), "{out}");
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn the_simulated_world_stands_archie_on_its_arduino_boards_true_positions() {
    // Archie's legs on its Arduino boards (fake Dues in each link's process): each link
    // publishes its board's true joint positions on a sim-only channel, and the simulated
    // world stands the body on them and moves it as a driven knee turns.
    require_sandbox();
    let dir = tempfile::tempdir().unwrap();
    let url = udpm_url(7772);
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let truth = |leg: &str| format!("SIM_JOINT_STATE_ARDUINO_{}_LEG", leg.to_uppercase());
    let links: Vec<Proc> = ["left", "right"]
        .iter()
        .map(|leg| {
            let mut c = on_bus("stride-arduino-link", &url);
            c.arg("--name")
                .arg(format!("arduino-{leg}"))
                .arg("--config")
                .arg(repo.join(format!("config/robots/archie-arduino-{leg}-leg.toml")))
                .args(["--true-state-channel", &truth(leg)]);
            Proc::spawn(c)
        })
        .collect();
    // The shipped simulated world, reading the boards' channels instead of the drives'.
    let mut sim: toml::Table =
        toml::from_str(&std::fs::read_to_string(repo.join("config/sim-archie.toml")).unwrap())
            .unwrap();
    for key in ["scene", "robot_file"] {
        let p = repo.join("config").join(sim[key].as_str().unwrap());
        sim.insert(key.into(), p.display().to_string().into());
    }
    sim.insert(
        "true_joint_channels".into(),
        toml::Value::Array(vec![truth("left").into(), truth("right").into()]),
    );
    let sim_file = dir.path().join("sim.toml");
    std::fs::write(&sim_file, toml::to_string(&sim).unwrap()).unwrap();
    let lcm = Lcm::new(&url).unwrap();
    let knees = Arc::new(Mutex::new(Vec::<f64>::new()));
    let poses = Arc::new(Mutex::new(Vec::<[f64; 3]>::new()));
    let (k, p) = (knees.clone(), poses.clone());
    let _subs = [
        lcm.subscribe(&truth("left"), move |_, m: JointStateT| {
            assert_eq!(m.names.len(), 6);
            assert!(m.positions.iter().all(|p| p.is_finite()));
            let i = m.names.iter().position(|n| n == "left_knee").unwrap();
            k.lock().unwrap().push(m.positions[i]);
        })
        .unwrap(),
        lcm.subscribe("SIM_POSE", move |_, m: PoseStampedT| {
            p.lock().unwrap().push(m.pose.position);
        })
        .unwrap(),
    ];
    let mut c = on_bus("stride-sim", &url);
    c.arg("--config").arg(&sim_file);
    let world = Proc::spawn(c);
    assert!(
        handle_until(&lcm, Duration::from_secs(15), || !poses
            .lock()
            .unwrap()
            .is_empty()),
        "the simulated world never stood the body on the boards' joints"
    );
    let first = *poses.lock().unwrap().last().unwrap();
    let knee0 = *knees.lock().unwrap().last().unwrap();
    // The left knee driven (duty 0.4, as in the link's test above): its true position turns,
    // and the simulated body moves with it.
    let moved = handle_until(&lcm, Duration::from_secs(5), || {
        lcm.publish("ARCHIE_LEFT_LEG_COMMAND", &duty("left_knee", 0.4))
            .unwrap();
        std::thread::sleep(Duration::from_millis(20));
        let knee = *knees.lock().unwrap().last().unwrap();
        let pose = *poses.lock().unwrap().last().unwrap();
        let d = (0..3)
            .map(|i| (pose[i] - first[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        (knee - knee0).abs() > 0.05 && d > 0.001
    });
    assert!(
        moved,
        "knee {knee0} -> {:?}, pelvis {first:?} -> {:?}",
        knees.lock().unwrap().last(),
        poses.lock().unwrap().last()
    );
    let (st, _) = world.interrupt();
    assert!(st.success());
    for l in links {
        let (st, _) = l.interrupt();
        assert!(st.success());
    }
}
