//! The report from logs written here: what a walk's log shows, and what a torn or strange
//! one still gives.

use std::io::Write;

use lcm::{LogWriter, Message};
use stride_lcmtypes::stride::{
    ElevationMapT, FootT, FootstepPlanRequestT, FootstepPlanT, FootstepT, HeaderT, JointStateT,
    JointTrajectoryT, ObstacleListT, ObstacleT, PoseStampedT, PoseT, SimReportT,
};
use stride_report::{html, read_log};

const T0: i64 = 1_800_000_000_000_000;

fn header(utime: i64) -> HeaderT {
    HeaderT {
        utime,
        sequence: 0,
        frame: "world".into(),
    }
}

fn pose(utime: i64, x: f64, y: f64) -> PoseStampedT {
    PoseStampedT {
        header: header(utime),
        child_frame: "pelvis".into(),
        pose: PoseT {
            position: [x, y, 0.4],
            orientation: [1.0, 0.0, 0.0, 0.0],
        },
    }
}

/// A short walk's log: the obstacles and map, a goal, a request and its plan, the body moving
/// 1 m, a joint commanded in two chunks (the second appended) and measured, touch-downs.
fn walk_log(path: &std::path::Path) {
    let mut w = LogWriter::create(path).unwrap();
    let mut put = |t: i64, ch: &str, data: Vec<u8>| {
        w.write(T0 + t, ch, &data).unwrap();
    };
    let obstacles = ObstacleListT {
        header: header(T0),
        num_obstacles: 1,
        obstacles: vec![ObstacleT {
            id: 1,
            kind: ObstacleT::KIND_CIRCLE,
            center: [0.5, 0.5, 0.0],
            radius: 0.2,
            z_min: 0.0,
            z_max: 1.0,
            num_vertices: 0,
            vertices: vec![],
        }],
    };
    put(0, "OBSTACLES", obstacles.encode().unwrap());
    let (nx, ny) = (20, 10);
    let map = ElevationMapT {
        header: header(T0),
        origin_x: -0.5,
        origin_y: -0.5,
        resolution: 0.1,
        nx,
        ny,
        num_cells: nx * ny,
        elevation: (0..nx * ny)
            .map(|i| {
                if i % 7 == 0 {
                    f32::NAN
                } else {
                    (i % 5) as f32 * 0.01
                }
            })
            .collect(),
        variance: vec![0.0; (nx * ny) as usize],
        slope: vec![0.0; (nx * ny) as usize],
        roughness: vec![0.0; (nx * ny) as usize],
        traversability: vec![1.0; (nx * ny) as usize],
    };
    put(1000, "ELEVATION_MAP", map.encode().unwrap());
    put(
        2000,
        "WALK_GOAL",
        pose(T0 + 2000, 1.0, 0.0).encode().unwrap(),
    );
    let foot = |side, x: f64, y: f64| FootT {
        side,
        x,
        y,
        z: 0.0,
        yaw: 0.0,
    };
    let request = FootstepPlanRequestT {
        header: header(T0 + 3000),
        request_id: 7,
        stance: foot(FootT::SIDE_RIGHT, 0.0, -0.1),
        swing: foot(FootT::SIDE_LEFT, 0.0, 0.1),
        goal_x: 1.0,
        ..Default::default()
    };
    put(3000, "FOOTSTEP_PLAN_REQUEST", request.encode().unwrap());
    let steps: Vec<FootstepT> = (1..=4)
        .map(|k| FootstepT {
            step_number: k,
            foot: foot(
                if k % 2 == 1 {
                    FootT::SIDE_LEFT
                } else {
                    FootT::SIDE_RIGHT
                },
                0.25 * k as f64,
                if k % 2 == 1 { 0.1 } else { -0.1 },
            ),
            ..Default::default()
        })
        .collect();
    let plan = FootstepPlanT {
        header: header(T0 + 8000),
        request_id: 7,
        num_steps: steps.len() as i32,
        steps,
        ..Default::default()
    };
    put(8000, "FOOTSTEP_PLAN", plan.encode().unwrap());
    let chunk = |start: i64, append: bool, from: f64| JointTrajectoryT {
        header: header(T0),
        start_utime: start,
        mode: JointTrajectoryT::MODE_PVT,
        queue: if append {
            JointTrajectoryT::QUEUE_APPEND
        } else {
            JointTrajectoryT::QUEUE_REPLACE
        },
        num_joints: 1,
        joint_names: vec!["left_knee".into()],
        num_rows: 11,
        time_from_start: (0..=10).map(|k| k as f64 * 0.1).collect(),
        positions: (0..=10).map(|k| vec![from + 0.01 * k as f64]).collect(),
        velocities: vec![vec![0.1]; 11],
    };
    put(
        10_000,
        "JOINT_TRAJECTORY_LEFT_LEG",
        chunk(T0 + 100_000, false, 0.0).encode().unwrap(),
    );
    put(
        20_000,
        "JOINT_TRAJECTORY_LEFT_LEG",
        chunk(0, true, 0.1).encode().unwrap(),
    );
    for k in 0..=200 {
        let t = 100_000 + k * 10_000;
        let s = k as f64 / 200.0;
        put(
            t,
            "SIM_POSE",
            pose(T0 + t - 500, s, 0.02 * (s * 20.0).sin())
                .encode()
                .unwrap(),
        );
        let state = JointStateT {
            header: header(T0 + t),
            num_joints: 1,
            names: vec!["left_knee".into()],
            positions: vec![0.1 * (t - 100_000) as f64 * 1e-6 - 0.002],
            velocities: vec![0.0],
            currents: vec![0.0],
            temperatures: vec![0.0],
            faults: vec![0],
        };
        put(t + 200, "JOINT_STATE_LEFT_LEG", state.encode().unwrap());
        if k % 50 == 0 {
            let report = SimReportT {
                header: header(T0 + t),
                scene: "test".into(),
                feet: [[s, 0.1, 0.0, 0.0], [s, -0.1, 0.0, 0.0]],
                contact: [true, true],
                anchor: (k / 50 % 2) as i8,
                touchdowns: k / 50,
                ..Default::default()
            };
            put(t + 300, "SIM_REPORT", report.encode().unwrap());
        }
    }
    // A channel of a type nobody here knows.
    put(
        2_200_000,
        "MYSTERY",
        vec![0xde, 0xad, 0xbe, 0xef, 1, 2, 3, 4, 5, 6, 7, 8],
    );
    w.flush().unwrap();
}

#[test]
fn a_walks_log_gives_the_top_view_the_map_the_tracking_and_the_latencies() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("walk.lcmlog");
    walk_log(&log);
    let d = read_log(&log).unwrap();
    assert_eq!(d.obstacles.len(), 1);
    assert_eq!(d.goal, Some([1.0, 0.0]));
    assert_eq!(d.plans.len(), 1);
    assert_eq!(d.plan_latency_ms, vec![5.0]);
    assert_eq!(d.touchdowns.len(), 4);
    assert_eq!(d.trace.len(), 201);
    // The second chunk, appended, starts where the first ended (1.1 s after the first row).
    let rows = &d.commanded["left_knee"];
    assert_eq!(rows.len(), 21);
    assert_eq!(rows.keys().last().copied(), Some(100_000 + 2_000_000));
    // Latency: arrival less the header stamp, 0.5 ms for the poses.
    assert!(d.channels["SIM_POSE"]
        .latency_ms
        .iter()
        .all(|l| (l - 0.5).abs() < 1e-9));
    // The one warning: the unknown channel.
    assert_eq!(d.warnings.len(), 1, "{:?}", d.warnings);
    assert!(d.warnings[0].contains("MYSTERY"));
    let page = html(&d, "walk.lcmlog");
    assert!(page.starts_with("<!DOCTYPE html>"));
    assert!(
        page.contains("data:image/png;base64,iVBORw0KGgo"),
        "the map as a PNG"
    );
    assert!(
        page.matches("<svg").count() >= 4,
        "top view, tracking, histograms"
    );
    assert!(
        page.contains("<td>left_knee</td><td>0.0020</td>"),
        "the knee's error"
    );
    assert!(page.contains("p50 5.0 ms"));
}

#[test]
fn a_torn_log_gives_what_came_before_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("walk.lcmlog");
    walk_log(&log);
    let whole = std::fs::read(&log).unwrap();
    let torn = dir.path().join("torn.lcmlog");
    // Cut in the middle of an event well into the walk.
    std::fs::write(&torn, &whole[..whole.len() * 2 / 3]).unwrap();
    let d = read_log(&torn).unwrap();
    assert!(d.events > 100 && d.trace.len() < 201, "{} events", d.events);
    assert!(
        d.warnings.iter().any(|w| w.contains("torn")),
        "{:?}",
        d.warnings
    );
    let page = html(&d, "torn.lcmlog");
    assert!(page.contains("A partial report") && page.contains("<svg"));
}

#[test]
fn a_log_of_nothing_known_is_a_report_of_warnings_and_no_log_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("odd.lcmlog");
    let mut w = LogWriter::create(&log).unwrap();
    w.write(T0, "NOISE", b"not a message").unwrap();
    w.flush().unwrap();
    drop(w);
    let d = read_log(&log).unwrap();
    assert_eq!(d.events, 1);
    assert!(d.warnings.iter().any(|w| w.contains("NOISE")));
    assert!(d.warnings.iter().any(|w| w.contains("no plans")));
    assert!(html(&d, "odd").contains("Nothing to draw"));
    let e = read_log(&dir.path().join("absent.lcmlog"))
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("cannot read") && !e.contains('\n'), "{e}");
    // Not a log at all: the bytes of a text file.
    let text = dir.path().join("text.lcmlog");
    std::fs::File::create(&text)
        .unwrap()
        .write_all(b"hello, this is not a log\n")
        .unwrap();
    let d = read_log(&text).unwrap();
    assert_eq!(d.events, 0);
    assert!(
        d.warnings.iter().any(|w| w.contains("torn or unreadable")),
        "{:?}",
        d.warnings
    );
}

/// D12 of the reliability findings: stride-report exited 0 with "report of 0 events" for an
/// empty file, random bytes or garbage, and called channels whose payloads were garbage
/// "of types this build does not know"; after one bad header at 30 % of a log it said the log
/// "ends" there, with 70 % unread.
#[test]
fn a_file_with_no_event_is_an_error_and_garbage_on_a_known_channel_does_not_decode() {
    let dir = tempfile::tempdir().unwrap();
    let exe = env!("CARGO_BIN_EXE_stride-report");
    for (name, bytes) in [
        ("empty.lcmlog", Vec::new()),
        (
            "random.lcmlog",
            (0..100_000u32)
                .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
                .collect(),
        ),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        let out = std::process::Command::new(exe)
            .arg(&p)
            .env("RUST_BACKTRACE", "1")
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {err}");
        assert!(err.contains("holds no LCM event"), "{name}: {err}");
        assert!(
            err.lines()
                .all(|l| l.starts_with("stride-report:") || l.starts_with("warning: liblcm")),
            "{name}: {err}"
        );
    }
    // Garbage on a channel of a known type: undecodable messages of that type.
    let log = dir.path().join("garbage.lcmlog");
    walk_log(&log);
    let mut w = LogWriter::append(&log).unwrap();
    w.write(T0 + 99_000_000, "SIM_POSE", b"garbage, not a pose")
        .unwrap();
    w.flush().unwrap();
    drop(w);
    let d = read_log(&log).unwrap();
    assert!(
        d.warnings
            .iter()
            .any(|w| w.contains("SIM_POSE: 1 messages that do not decode as stride.pose_stamped_t")),
        "{:?}",
        d.warnings
    );
    assert!(
        !d.warnings
            .iter()
            .any(|w| w.contains("does not know") && w.contains("SIM_POSE")),
        "{:?}",
        d.warnings
    );
    // A bad header at a third: the rest is said unread, with its share.
    let whole = std::fs::read(&log).unwrap();
    let mut bad = whole.clone();
    let at = bad.len() / 3;
    let sync = bad[at..]
        .windows(4)
        .position(|w| w == [0xED, 0xA1, 0xDA, 0x01])
        .unwrap()
        + at;
    bad[sync + 20..sync + 24].copy_from_slice(&(-16i32).to_be_bytes());
    let cut = dir.path().join("cut.lcmlog");
    std::fs::write(&cut, &bad).unwrap();
    let d = read_log(&cut).unwrap();
    let w = d
        .warnings
        .iter()
        .find(|w| w.contains("could not be read past byte"))
        .unwrap_or_else(|| panic!("{:?}", d.warnings));
    assert!(w.contains("% of the file, unread"), "{w}");
}
