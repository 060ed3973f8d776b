//! The robot walks, in closed loop: `stride launch archie --sim` runs each part of Archie's
//! simulated robot as its own process (the fake Elmo drives of each leg on a CAN bus carried
//! over LCM, both legs' Elmo bridges, the gait, the footstep planner, the simulated world),
//! and `stride walk` sends a goal, follows the walk and judges it by the simulated world's
//! true pose and reports.

use std::path::{Path, PathBuf};
use std::time::Duration;

use lcm::{now_utime, Message};
use stride_lcmtypes::stride::SimReportT;
use stride_tests::{on_bus, require_sandbox, udpm_url, Proc};

fn repo(p: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(p)
}

/// The shipped Archie profile and simulator configuration, on `url`, in `dir`: the scene
/// `scene` (TOML text), and the simulator's extra lines `sim_extra` (e.g. an obstacle that
/// appears).
fn setup(dir: &Path, url: &str, scene: &str, sim_extra: &str) -> PathBuf {
    setup_profile("archie", dir, url, scene, sim_extra)
}

/// [`setup`] for the shipped profile `name`.
fn setup_profile(name: &str, dir: &Path, url: &str, scene: &str, sim_extra: &str) -> PathBuf {
    let launch = dir.join("config/launch");
    std::fs::create_dir_all(&launch).unwrap();
    std::fs::write(dir.join("config/scene.toml"), scene).unwrap();
    let mut sim: toml::Table =
        toml::from_str(&std::fs::read_to_string(repo("config/sim-archie.toml")).unwrap()).unwrap();
    sim.insert("scene".into(), "scene.toml".into());
    sim.insert(
        "robot_file".into(),
        repo("config/robots/archie.toml")
            .to_string_lossy()
            .into_owned()
            .into(),
    );
    let extra: toml::Table = toml::from_str(sim_extra).unwrap();
    sim.extend(extra);
    std::fs::write(dir.join("config/sim.toml"), toml::to_string(&sim).unwrap()).unwrap();
    let sim_file = dir.join("config/sim.toml");
    profile_on(name, url, &launch.join("walk.toml"), |config| {
        if config.ends_with("sim-archie.toml") {
            sim_file.clone()
        } else {
            repo("config/launch").join(config)
        }
    })
}

/// The shipped launch profile `name` on `url`, written to `to`: each app's configuration
/// where `config_of` puts it (from the profile's own relative path), its console at warn.
fn profile_on(name: &str, url: &str, to: &Path, config_of: impl Fn(&str) -> PathBuf) -> PathBuf {
    let file = repo("config/launch").join(format!("{name}.toml"));
    let mut profile: toml::Table = toml::from_str(&std::fs::read_to_string(file).unwrap()).unwrap();
    profile.insert("lcm_url".into(), url.into());
    for app in profile["app"].as_array_mut().unwrap() {
        let app = app.as_table_mut().unwrap();
        let path = config_of(app["config"].as_str().unwrap());
        app.insert("config".into(), path.to_string_lossy().into_owned().into());
        let mut args = app
            .get("args")
            .cloned()
            .unwrap_or(toml::Value::Array(vec![]));
        args.as_array_mut()
            .unwrap()
            .extend(["--log-level".into(), "warn".into()]);
        app.insert("args".into(), args);
    }
    std::fs::write(to, toml::to_string(&profile).unwrap()).unwrap();
    to.to_path_buf()
}

fn launch(profile: &Path, url: &str, dir: &Path) -> Proc {
    let mut c = on_bus("stride", url);
    c.arg("launch")
        .arg(profile)
        .args(["--sim", "--log-dir"])
        .arg(dir.join("logs"));
    Proc::spawn(c)
}

/// `stride walk` to `goal`: its exit status and summary.
fn walk(url: &str, goal: &str, timeout: f64) -> (bool, String) {
    let mut c = on_bus("stride", url);
    c.args(["walk", goal, "--timeout"]).arg(timeout.to_string());
    outcome(c)
}

/// Runs `c` to its end: whether it succeeded, and its output (stdout, then stderr).
fn outcome(mut c: std::process::Command) -> (bool, String) {
    let out = c.output().unwrap();
    (
        out.status.success(),
        format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
    )
}

fn number_after(text: &str, label: &str) -> f64 {
    let i = text
        .find(label)
        .unwrap_or_else(|| panic!("{label:?} in {text}"))
        + label.len();
    text[i..]
        .trim_start()
        .split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
        .next()
        .unwrap()
        .parse()
        .unwrap_or_else(|_| panic!("a number after {label:?} in {text}"))
}

const FLAT: &str = r#"
name = "flat"
start = { x = 0.0, y = 0.0 }
goal = { x = 1.0, y = 0.0 }
[map]
x = [-1.0, 4.0]
y = [-2.0, 2.0]
"#;

/// One walk at a time: each runs seven processes, two at once would share the machine's cores
/// and judge the load rather than the walk.
static ONE_WALK: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Launches the simulated Archie on `port` in `scene` (with the simulator's `sim_extra`),
/// walks to `goal` within `timeout` s and shuts down: the walk's summary, once the walk's own
/// verdict (goal reached, no collision, no fall), no collision said in so many words and the
/// launcher's clean shutdown are checked.
fn walk_in_closed_loop(
    port: u16,
    scene: &str,
    sim_extra: &str,
    goal: &str,
    timeout: f64,
) -> String {
    require_sandbox();
    let _one = ONE_WALK.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let url = udpm_url(port);
    let profile = setup(dir.path(), &url, scene, sim_extra);
    let launcher = launch(&profile, &url, dir.path());
    let (ok, summary) = walk(&url, goal, timeout);
    let (st, out) = launcher.interrupt();
    eprintln!("{summary}");
    assert!(ok, "{summary}\n{out}");
    assert!(summary.contains("reached"), "{summary}");
    assert!(summary.contains("collisions 0;"), "{summary}");
    assert!(st.success(), "the launcher's shutdown: {out}");
    summary
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn archie_walks_a_metre_to_its_goal_in_closed_loop_on_to_a_second_and_not_by_itself_after_a_stop() {
    // The ZMP of the measured motion moves with the drives' lag, more on a loaded machine (up
    // to about 7 cm seen): the fall threshold is widened here; what this test guards is the
    // loop (goal, plans at every step, rows, drives, body) reaching the goal without a
    // collision. The second goal guards a walk after a stand: it once started back where the
    // stream of rows had ended, seconds in the past, and the gait stopped it at once (its
    // rows far from the drives). The third is stopped mid-walk and resumed: the robot once
    // walked on to it by itself after the resume.
    require_sandbox();
    let _one = ONE_WALK.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let url = udpm_url(7811);
    let profile = setup(dir.path(), &url, FLAT, "[body]\nfall_margin = 0.1\n");
    let launcher = launch(&profile, &url, dir.path());
    let (ok, summary) = walk(&url, "1.0,0", 90.0);
    let (ok2, second) = if ok {
        walk(&url, "1.5,0", 60.0)
    } else {
        (false, String::new())
    };
    if ok2 {
        stopped_and_resumed_the_robot_stands(&url, "2.5,0");
    }
    let (st, out) = launcher.interrupt();
    assert!(ok, "{summary}\n{out}");
    for s in [&summary, &second] {
        assert!(s.contains("reached"), "{s}");
        assert!(s.contains("collisions 0;"), "{s}");
    }
    // Steps as the simulated world saw the feet land, not the gait's step counter (its
    // numbers are the gait's own, and one taken for a step never walked counts there: 13 of
    // them for the same walk's 12 touch-downs).
    let steps = number_after(&summary, "touch-downs");
    assert!(
        (4.0..=12.0).contains(&steps),
        "{steps} touch-downs: {summary}"
    );
    let err = number_after(&summary, "drives' positions): max");
    assert!(err < 0.15, "tracking error {err} rad: {summary}");
    assert!(ok2, "{second}\n{out}");
    let err = number_after(&second, "drives' positions): max");
    assert!(err < 0.15, "tracking error {err} rad: {second}");
    assert!(st.success(), "the launcher's shutdown: {out}");
}

/// Sends `goal`, stops the walk once it is under way and resumes it: the robot stands, and
/// no request for a plan goes out for 4 s after the resume.
fn stopped_and_resumed_the_robot_stands(url: &str, goal: &str) {
    use stride_lcmtypes::stride::{FootstepPlanRequestT, TrajectoryStatusT};
    let moving = |m: &TrajectoryStatusT| m.state == TrajectoryStatusT::STATE_MOVING;
    let stride = |args: &[&str]| {
        let mut c = on_bus("stride", url);
        c.args(args);
        let (ok, out) = outcome(c);
        assert!(ok, "stride {args:?}: {out}");
    };
    let waiting = std::thread::spawn({
        let url = url.to_owned();
        move || stride_tests::wait_for(&url, "GAIT_STATUS", Duration::from_secs(30), moving)
    });
    std::thread::sleep(Duration::from_millis(300));
    stride(&["goal", goal]);
    waiting.join().unwrap();
    stride(&["stop", "test"]);
    stride_tests::wait_for(
        url,
        "GAIT_STATUS",
        Duration::from_secs(20),
        |m: &TrajectoryStatusT| m.state == TrajectoryStatusT::STATE_STOPPED,
    );
    // Standing: the stand after the stop done.
    std::thread::sleep(Duration::from_secs(4));
    let lcm = lcm::Lcm::new(url).unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    let _requests = lcm
        .subscribe(
            "FOOTSTEP_PLAN_REQUEST",
            move |_, _: FootstepPlanRequestT| {
                let _ = tx.send(());
            },
        )
        .unwrap();
    let (stx, srx) = std::sync::mpsc::channel();
    let _status = lcm
        .subscribe("GAIT_STATUS", move |_, m: TrajectoryStatusT| {
            let _ = stx.send(m.state);
        })
        .unwrap();
    stride(&["resume"]);
    stride_tests::handle_until(&lcm, Duration::from_secs(4), || false);
    let states: Vec<i8> = srx.try_iter().collect();
    assert!(!states.is_empty(), "no gait status after the resume");
    assert!(
        !states.contains(&TrajectoryStatusT::STATE_MOVING),
        "the robot walked on by itself after the resume: {states:?}"
    );
    assert_eq!(rx.try_iter().count(), 0, "plans asked for after the resume");
}

const OPEN: &str = r#"
name = "open"
start = { x = 0.0, y = 0.0 }
goal = { x = 3.0, y = 0.0 }
[map]
x = [-1.0, 5.0]
y = [-2.5, 2.5]
"#;

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn kaists_b7_a_box_that_appears_a_metre_ahead_is_walked_around() {
    // KAIST's B7 in closed loop: a 0.5 x 0.5 x 1.8 m box appears 1 m ahead of the pelvis at
    // the third touch-down, on the straight way to a goal 3 m ahead. The simulated world
    // reports it to the planner (perfect perception, with its delay); the gait asks for the
    // way at every step and takes only plans in step with its own (others are dropped, and it
    // steps in place until one comes): no foot or shank may touch the box, no fall at the
    // shipped threshold, and the goal is reached.
    let summary = walk_in_closed_loop(
        7813,
        OPEN,
        "[[appear]]\nafter_touchdowns = 3\nahead = 1.0\nsize = [0.5, 0.5, 1.8]\n",
        "3.0,0",
        150.0,
    );
    assert!(summary.contains("falls 0;"), "{summary}");
    // The box stood on the straight way: the walk went round it, close (an open floor has no
    // clearance to report).
    let clearance = number_after(&summary, "from an obstacle");
    assert!(clearance > 0.0 && clearance < 0.5, "{summary}");
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn the_hexapod_walks_its_tripod_gait_through_the_dynamixel_bridge() {
    // `stride launch hexapod --sim` (the bridge's 18 simulated AX-12A servos, the gait, the
    // simulated world reading the servos' true positions) and `stride step 0.2`: the walk is
    // taken, ends, the servos follow their set-points, and the simulated body moved ahead
    // what was asked without a fall.
    require_sandbox();
    let _one = ONE_WALK.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let url = udpm_url(7815);
    let path = profile_on(
        "hexapod",
        &url,
        &dir.path().join("hexapod.toml"),
        |config| repo("config/launch").join(config),
    );
    let launcher = launch(&path, &url, dir.path());
    let out = on_bus("stride", &url)
        .args(["step", "0.2", "--timeout", "60"])
        .output()
        .unwrap();
    let summary = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let (st, log) = launcher.interrupt();
    assert!(out.status.success(), "{summary}\n{log}");
    assert!(
        summary.starts_with("the walk of 0.2 m (tripod gait) played to its end"),
        "{summary}"
    );
    let samples = number_after(&summary, "rad over");
    assert!(samples > 100.0, "{summary}");
    let ahead = number_after(&summary, "the simulated body moved ");
    assert!((ahead - 0.2).abs() <= 0.05, "{summary}");
    assert!(summary.contains("falls 0, collisions 0"), "{summary}");
    assert!(st.success(), "the launcher's shutdown: {log}");
}

/// Two computers made of network namespaces inside the test's sandbox, "robot" and "laptop",
/// each with an `eth0` (the 224.0.0.0/4 route on it) on a veth pair whose other end is here.
/// On one Wi-Fi: both ends on a bridge here, the "access point" (10.77.0.1 and .2/24).
/// Routed: each on its own subnet (10.77.1.2/24 and 10.77.2.2/24, this sandbox the router at
/// .1 of each), where unicast passes and multicast does not. Removed when dropped.
struct Hosts {
    id: u32,
}

impl Hosts {
    const NAMES: [&'static str; 2] = ["robot", "laptop"];

    fn new(routed: bool) -> Hosts {
        // Unique per set of hosts: a test's namespaces and links go away asynchronously once
        // their processes have ended, and the next test's must not meet them.
        static NEXT: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed) % 10;
        let h = Hosts {
            id: std::process::id() % 10_000 * 10 + n,
        };
        let sh = |cmd: String| {
            let out = std::process::Command::new("sh")
                .args(["-c", &cmd])
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "{cmd}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        };
        let br = h.bridge();
        if routed {
            sh("sysctl -qw net.ipv4.ip_forward=1".into());
        } else {
            sh(format!(
                "ip link add {br} type bridge mcast_snooping 0 && ip link set {br} up"
            ));
        }
        for (i, name) in Self::NAMES.iter().enumerate() {
            let ns = h.ns(name);
            let veth = h.veth(name);
            sh(format!(
                "ip netns add {ns} && ip link add {veth} type veth peer name eth0 netns {ns} && \
                 ip -n {ns} link set lo up && ip -n {ns} link set eth0 up"
            ));
            if routed {
                let net = i + 1;
                sh(format!(
                    "ip addr add 10.77.{net}.1/24 dev {veth} && ip link set {veth} up && \
                     ip -n {ns} addr add 10.77.{net}.2/24 dev eth0 && \
                     ip -n {ns} route add default via 10.77.{net}.1"
                ));
            } else {
                sh(format!(
                    "ip link set {veth} master {br} up && \
                     ip -n {ns} addr add 10.77.0.{}/24 dev eth0",
                    i + 1
                ));
            }
            sh(format!("ip -n {ns} route add 224.0.0.0/4 dev eth0"));
        }
        h
    }

    fn ns(&self, host: &str) -> String {
        format!("stride-{host}-{}", self.id)
    }

    fn veth(&self, host: &str) -> String {
        format!("v{}{}", &host[..1], self.id)
    }

    fn bridge(&self) -> String {
        format!("sbr{}", self.id)
    }

    /// `program` run on `host`.
    fn on(&self, host: &str, program: impl AsRef<std::ffi::OsStr>) -> std::process::Command {
        let mut c = std::process::Command::new("ip");
        c.args(["netns", "exec", &self.ns(host)]).arg(program);
        c
    }

    /// A stride program on `host`, on the bus `url`.
    fn stride(&self, host: &str, name: &str, url: &str) -> std::process::Command {
        let mut c = self.on(host, stride_tests::bin(name));
        c.args(["--lcm-url", url, "--log-level", "warn"]);
        c
    }

    /// The bytes that crossed `host`'s link, both ways (from /proc/net/dev: this sandbox's
    /// interfaces, where /sys shows the machine's).
    fn link_bytes(&self, host: &str) -> u64 {
        let veth = self.veth(host);
        let dev = std::fs::read_to_string("/proc/net/dev").unwrap();
        let line = dev
            .lines()
            .find_map(|l| l.trim_start().strip_prefix(&format!("{veth}:")))
            .unwrap_or_else(|| panic!("{veth} not in /proc/net/dev: {dev}"));
        let f: Vec<u64> = line
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        // Received bytes first, sent bytes ninth.
        f[0] + f[8]
    }

    /// The processes in `host` whose name (as /proc shows it, 15 characters at most) starts
    /// with `name`.
    fn pids(&self, host: &str, name: &str) -> Vec<i32> {
        let out = std::process::Command::new("ip")
            .args(["netns", "pids", &self.ns(host)])
            .output()
            .unwrap();
        String::from_utf8_lossy(&out.stdout)
            .split_whitespace()
            .filter_map(|p| p.parse::<i32>().ok())
            .filter(|p| {
                std::fs::read_to_string(format!("/proc/{p}/comm"))
                    .is_ok_and(|c| c.trim().starts_with(name))
            })
            .collect()
    }

    /// Takes `host`'s link down or up (the Wi-Fi lost and back).
    fn set_link(&self, host: &str, up: bool) {
        let st = std::process::Command::new("ip")
            .args(["link", "set", &self.veth(host)])
            .arg(if up { "up" } else { "down" })
            .status()
            .unwrap();
        assert!(st.success());
    }
}

impl Drop for Hosts {
    fn drop(&mut self) {
        for name in Self::NAMES {
            // Both ends of the link at once, then the namespace.
            let _ = std::process::Command::new("ip")
                .args(["link", "del", &self.veth(name)])
                .output();
            let _ = std::process::Command::new("ip")
                .args(["netns", "del", &self.ns(name)])
                .status();
        }
        let _ = std::process::Command::new("ip")
            .args(["link", "del", &self.bridge()])
            .output();
    }
}

/// The channels of a plan's way: the goal, the map, the request and the plan.
const PLAN_WAY: [&str; 4] = [
    "FOOTSTEP_PLAN",
    "FOOTSTEP_PLAN_REQUEST",
    "WALK_GOAL",
    "ELEVATION_MAP",
];

/// The bytes of each channel in an LCM log.
/// Bytes per channel in an LCM log, and the time from its first event to its last (s), by
/// the logger's own stamps.
fn bytes_per_channel(log: &Path) -> (std::collections::BTreeMap<String, u64>, f64) {
    let mut r = lcm::LogReader::open(log).unwrap();
    let mut out = std::collections::BTreeMap::new();
    let mut span = (i64::MAX, i64::MIN);
    while let Some(e) = r.read_event() {
        *out.entry(e.channel.clone()).or_insert(0) += e.data.len() as u64;
        span = (span.0.min(e.timestamp), span.1.max(e.timestamp));
    }
    (out, (span.1 - span.0).max(1) as f64 / 1e6)
}

/// The split profile on two computers: the robot's deputy runs the gait, the bridges, the
/// fake drives and the simulated world, the laptop's the planner, and `stride walk` on the
/// laptop sends the goal over the shared bus (ttl=1). Returns the hosts, the shared and local
/// URLs, the deputies and the working directory.
struct Split {
    hosts: Hosts,
    shared: String,
    dir: tempfile::TempDir,
    robot: Option<Proc>,
    laptop: Option<Proc>,
}

impl Split {
    fn start(port: u16, scene: &str) -> Split {
        Self::start_with(port, scene, false, |_| {})
    }

    /// [`Split::start`] on routed hosts or not, with the profile changed by `edit`.
    fn start_with(
        port: u16,
        scene: &str,
        routed: bool,
        edit: impl FnOnce(&mut toml::Table),
    ) -> Split {
        require_sandbox();
        let hosts = Hosts::new(routed);
        let dir = tempfile::tempdir().unwrap();
        let shared = format!("udpm://239.255.76.67:{port}?ttl=1&recv_buf_size=4194304");
        let local = udpm_url(port + 1);
        let profile = setup_profile("archie-split", dir.path(), &shared, scene, "");
        let mut p: toml::Table =
            toml::from_str(&std::fs::read_to_string(&profile).unwrap()).unwrap();
        p["local"]["robot"]
            .as_table_mut()
            .unwrap()
            .insert("url".into(), local.into());
        edit(&mut p);
        std::fs::write(&profile, toml::to_string(&p).unwrap()).unwrap();
        let deputy = |host: &str| {
            let mut c = hosts.stride(host, "stride", &shared);
            c.arg("launch")
                .arg(&profile)
                .args(["--host", host, "--sim", "--log-dir"])
                .arg(dir.path().join(format!("logs-{host}")));
            Proc::spawn(c)
        };
        let robot = Some(deputy("robot"));
        let laptop = Some(deputy("laptop"));
        Split {
            hosts,
            shared,
            dir,
            robot,
            laptop,
        }
    }

    /// `stride walk` on the laptop: its exit status and summary.
    fn walk(&self, goal: &str, timeout: f64) -> (bool, String) {
        let mut c = self.hosts.stride("laptop", "stride", &self.shared);
        c.args(["walk", goal, "--timeout"]).arg(timeout.to_string());
        outcome(c)
    }

    /// `stride walk` to `goal` on the laptop, in the background.
    fn walk_in_background(&self, goal: &str, timeout: f64) -> Proc {
        let mut c = self.hosts.stride("laptop", "stride", &self.shared);
        c.args(["walk", goal, "--timeout"]).arg(timeout.to_string());
        Proc::spawn(c)
    }

    /// The stock lcm-logger on `host`'s side of the shared bus, recording `channels` (a
    /// regex) into `log`, flushed every 10 ms so that a test can follow it.
    fn logger(&self, host: &str, channels: &str, log: &Path) -> Proc {
        let mut c = self.hosts.on(host, "lcm-logger");
        c.args(["-q", "-f", "-c", channels, "--flush-interval=10"])
            .arg(format!("--lcm-url={}", self.shared))
            .arg(log);
        Proc::spawn(c)
    }

    /// Stops both deputies; both must end cleanly.
    fn shut_down(&mut self) {
        for (host, p) in [("laptop", self.laptop.take()), ("robot", self.robot.take())] {
            if let Some(p) = p {
                let (st, out) = p.interrupt();
                assert!(st.success(), "the {host}'s deputy: {out}");
            }
        }
    }
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn the_split_profile_walks_the_robot_with_the_planner_on_the_laptop() {
    // Thesis's split on two network namespaces joined by a bridge: a plan crosses from the
    // laptop's planner to the robot's gait, the simulated robot walks to its goal, and only
    // the shared channels cross the link: the robot's full-rate data stays on its own bus.
    let _one = ONE_WALK.lock().unwrap_or_else(|e| e.into_inner());
    let mut split = Split::start(7821, FLAT);
    let log = split.dir.path().join("laptop.lcmlog");
    let logger = Proc::spawn({
        let mut c = split.hosts.on("laptop", "lcm-logger");
        c.args(["-q", "-f"])
            .arg(format!("--lcm-url={}", split.shared))
            .arg(&log);
        c
    });
    let bytes0 = split.hosts.link_bytes("robot");
    let (ok, summary) = split.walk("1.0,0", 90.0);
    let crossed = split.hosts.link_bytes("robot") - bytes0;
    let _ = logger.interrupt();
    split.shut_down();
    assert!(ok, "{summary}");
    assert!(summary.contains("reached"), "{summary}");
    assert!(summary.contains("collisions 0;"), "{summary}");
    // Rates over the laptop logger's own span of the walk.
    let (channels, secs) = bytes_per_channel(&log);
    let table: Vec<String> = channels
        .iter()
        .map(|(c, b)| format!("{c} {:.1} kB/s", *b as f64 / secs / 1e3))
        .collect();
    let rate = crossed as f64 / secs;
    eprintln!(
        "crossed the robot's link: {:.1} kB/s over {secs:.1} s; on the shared bus: {}",
        rate / 1e3,
        table.join(", ")
    );
    // The plan crossed, both ways of the protocol.
    for c in PLAN_WAY {
        assert!(
            channels.contains_key(c),
            "{c} not on the shared bus: {table:?}"
        );
    }
    // Nothing of the robot's own bus crossed.
    for c in channels.keys() {
        assert!(
            !(c.starts_with("JOINT_")
                || c.starts_with("CAN_")
                || c.starts_with("SIM_JOINT_STATE")
                || c == "ODOMETRY"
                || c.starts_with("ARCHIE_")),
            "{c} crossed the link: {table:?}"
        );
    }
    // Half of a 150 Mbit/s Wi-Fi.
    let budget = 150e6 / 8.0 / 2.0;
    assert!(rate < budget, "{rate} B/s crossed, budget {budget}");
}

/// When each message on `channel` was logged, µs, in log order.
fn stamps(log: &Path, channel: &str) -> Vec<i64> {
    let mut r = lcm::LogReader::open(log).unwrap();
    let mut out = vec![];
    while let Some(e) = r.read_event() {
        if e.channel == channel {
            out.push(e.timestamp);
        }
    }
    out
}

/// Each simulated world's report in an LCM log (one still being written: up to its last
/// whole event), with the time it was logged, µs.
fn sim_reports(log: &Path) -> Vec<(i64, SimReportT)> {
    let Ok(mut r) = lcm::LogReader::open(log) else {
        return vec![];
    };
    let mut out = vec![];
    while let Some(e) = r.read_event() {
        if e.channel == "SIM_REPORT" {
            if let Ok(m) = SimReportT::decode(&e.data) {
                out.push((e.timestamp, m));
            }
        }
    }
    out
}

/// The foremost foot's x: how far the robot has come on a walk along x.
fn front(r: &SimReportT) -> f64 {
    r.feet[0][0].max(r.feet[1][0])
}

/// Waits (up to `timeout` s) until the simulated world's last report in `log` satisfies
/// `ready`.
fn wait_report(log: &Path, timeout: f64, ready: impl Fn(&SimReportT) -> bool) {
    let t0 = std::time::Instant::now();
    while t0.elapsed().as_secs_f64() < timeout {
        if sim_reports(log).last().is_some_and(|(_, r)| ready(r)) {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    panic!(
        "not so within {timeout} s; the last report: {:?}",
        sim_reports(log).last()
    );
}

/// The touch-downs the reports saw from `from` (µs) on: for each, whether it took the robot
/// forward (the foremost foot more than 2 cm beyond where it stood at the touch-down before).
fn touchdowns_from(reports: &[(i64, SimReportT)], from: i64) -> Vec<bool> {
    let mut out = vec![];
    let mut count = 0;
    let mut best = f64::NEG_INFINITY;
    for (t, r) in reports {
        if r.touchdowns > count {
            count = r.touchdowns;
            if *t >= from {
                out.push(front(r) > best + 0.02);
            }
            best = best.max(front(r));
        }
    }
    out
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn on_the_split_profile_a_lost_link_stops_the_robot_within_four_touch_downs_and_it_stands() {
    // The Wi-Fi lost mid-walk: the robot walks the step under way and at most the next (the
    // last plan's), then steps in place and stands; with the link back, the gait's requests
    // reach the planner again and the walk goes on to its goal.
    let _one = ONE_WALK.lock().unwrap_or_else(|e| e.into_inner());
    let mut split = Split::start(7823, OPEN);
    let log = split.dir.path().join("robot.lcmlog");
    let logger = split.logger("robot", "SIM_REPORT", &log);

    let walk = split.walk_in_background("2.5,0", 150.0);
    wait_report(&log, 90.0, |r| front(r) > 0.6);
    let down = now_utime();
    split.hosts.set_link("robot", false);
    // The step under way, the next, the plan timeout (3 s) and the stand.
    std::thread::sleep(std::time::Duration::from_secs(12));
    split.hosts.set_link("robot", true);
    let up = now_utime();
    let reports = sim_reports(&log);
    let (st, summary) = walk.wait(std::time::Duration::from_secs(160));
    let _ = logger.interrupt();

    split.shut_down();
    let during: Vec<_> = reports.iter().filter(|(t, _)| *t < up).cloned().collect();
    let steps = touchdowns_from(&during, down);
    eprintln!("touch-downs after the link went down (forward?): {steps:?}");
    // Forward: the step under way, the step the last plan fixed, and the plan's next step,
    // which stops the walk (a stop at once would leave the measured motion, which lags the
    // pattern, no margin); the gait notices a missing plan one step late, at the earliest.
    // Four touch-downs at most: one may be landing as the link goes.
    let forward = steps.iter().filter(|f| **f).count();
    assert!(forward <= 4, "{forward} steps forward: {steps:?}");
    assert!(
        steps.len() > forward,
        "no step in place or to stand: {steps:?}"
    );
    // It stands: no touch-down in the outage's last 3 s, both feet down side by side.
    let (_, last) = during.last().unwrap();
    let before = during
        .iter()
        .rev()
        .find(|(t, _)| *t < up - 3_000_000)
        .map(|(_, r)| r.touchdowns);
    assert_eq!(before, Some(last.touchdowns), "still stepping");
    assert!(last.contact[0] && last.contact[1], "{last:?}");
    assert!((last.feet[0][0] - last.feet[1][0]).abs() < 0.03, "{last:?}");
    assert!(st.success(), "{summary}");
    assert!(summary.contains("reached"), "{summary}");
    assert!(summary.contains("collisions 0;"), "{summary}");
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn on_the_split_profile_a_killed_planner_makes_the_robot_step_in_place_until_it_is_back() {
    // The laptop's planner killed mid-walk (restarted by its deputy after 6 s, longer than
    // the four steps the robot walks on its last plan: back after 3 s, it answered while the
    // robot still walked them, and nothing stepped in place): the robot steps in place
    // meanwhile, and walks on to the goal once the restarted planner answers the gait's
    // repeated request.
    let _one = ONE_WALK.lock().unwrap_or_else(|e| e.into_inner());
    let mut split = Split::start_with(7825, OPEN, false, |p| {
        p.insert(
            "backoff".into(),
            toml::toml! { initial = 6.0 max = 6.0 }.into(),
        );
    });
    let log = split.dir.path().join("robot.lcmlog");
    let logger = split.logger("robot", "(SIM_REPORT|FOOTSTEP_PLAN)", &log);
    let walk = split.walk_in_background("2.5,0", 150.0);
    wait_report(&log, 90.0, |r| front(r) > 0.6);
    let killed = now_utime();
    let planner = split.hosts.pids("laptop", "stride-footstep");
    assert_eq!(planner.len(), 1, "one planner on the laptop: {planner:?}");
    // SAFETY: plain kill(2).
    assert_eq!(unsafe { libc::kill(planner[0], libc::SIGKILL) }, 0);
    let (st, summary) = walk.wait(std::time::Duration::from_secs(160));
    let _ = logger.interrupt();
    let restarted = split.hosts.pids("laptop", "stride-footstep");
    split.shut_down();
    assert!(st.success(), "{summary}");
    assert!(summary.contains("reached"), "{summary}");
    assert!(summary.contains("collisions 0;"), "{summary}");
    assert!(
        restarted.len() == 1 && restarted[0] != planner[0],
        "the planner was not restarted: {restarted:?}"
    );
    // Counted from the last plan the robot took before the planner's silence, both stamped
    // by the robot's logger (a plan answered as the kill came is walked as it should be).
    let plans = stamps(&log, "FOOTSTEP_PLAN");
    let last = plans
        .windows(2)
        .find(|w| w[1] > killed && w[1] - w[0] > 2_000_000)
        .map(|w| w[0])
        .expect("a silence of the planner");
    let steps = touchdowns_from(&sim_reports(&log), last);
    eprintln!(
        "touch-downs after the last plan before the planner's silence ({:.2} s before the \
         kill; forward?): {steps:?}",
        (killed - last) as f64 / 1e6
    );
    // In place after at most the step landing as the last plan came, the step it was asked
    // for, the step it fixed and the stop (as with the link lost: four touch-downs), then
    // forward again.
    let first_in_place = steps.iter().position(|f| !f);
    assert!(
        first_in_place.is_some_and(|i| i <= 4),
        "no step in place within four touch-downs: {steps:?}"
    );
    assert!(
        steps[first_in_place.unwrap()..].iter().any(|f| *f),
        "never forward again: {steps:?}"
    );
}

/// The shipped bridge configuration `name` (config/), changed by `edit`, written to `dir`.
fn bridge_config(name: &str, dir: &Path, edit: impl FnOnce(&mut toml::Table)) -> PathBuf {
    let mut t: toml::Table =
        toml::from_str(&std::fs::read_to_string(repo("config").join(name)).unwrap()).unwrap();
    edit(&mut t);
    let to = dir.join(name);
    std::fs::write(&to, toml::to_string(&t).unwrap()).unwrap();
    to
}

/// How many messages of a log are the same bytes on the same channel as one before.
fn repeated(log: &Path) -> std::collections::BTreeMap<String, u64> {
    let mut r = lcm::LogReader::open(log).unwrap();
    let mut seen = std::collections::HashSet::new();
    let mut out = std::collections::BTreeMap::new();
    while let Some(e) = r.read_event() {
        if !seen.insert((e.channel.clone(), e.data.clone())) {
            *out.entry(e.channel).or_insert(0) += 1;
        }
    }
    out
}

/// Messages per channel in a log.
fn counts(log: &Path) -> std::collections::BTreeMap<String, u64> {
    let mut r = lcm::LogReader::open(log).unwrap();
    let mut out = std::collections::BTreeMap::new();
    while let Some(e) = r.read_event() {
        *out.entry(e.channel).or_insert(0) += 1;
    }
    out
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn across_a_routed_link_two_zenoh_bridges_carry_the_walk_and_nothing_comes_back() {
    // The robot and the laptop on two subnets joined by a router: unicast passes, multicast
    // does not. The split profile's deputies run on each, each on its own LCM bus; the
    // robot's bridge listens, the laptop's connects, over TLS with certificates both ways and
    // the operator's password; the laptop's planner answers the robot's gait through both,
    // and the walk reaches its goal. Every message crosses once: none
    // comes back to its bus (the loop of two bridges does not multiply traffic), and the
    // stock stride-spy on the laptop's side knows every type it got.
    let _one = ONE_WALK.lock().unwrap_or_else(|e| e.into_inner());
    let mut split = Split::start_with(7827, FLAT, true, |_| {});
    let dir = split.dir.path().to_path_buf();
    let logs = [dir.join("robot.lcmlog"), dir.join("laptop.lcmlog")];
    let loggers: Vec<Proc> = ["robot", "laptop"]
        .iter()
        .zip(&logs)
        .map(|(h, log)| split.logger(h, ".*", log))
        .collect();
    // Without the bridges, nothing of the robot reaches the laptop.
    wait_report(&logs[0], 60.0, |_| true);
    std::thread::sleep(std::time::Duration::from_secs(1));
    assert!(
        !counts(&logs[1]).contains_key("SIM_REPORT"),
        "multicast crossed the router"
    );
    // The link as a user makes it: TLS both ways and the operator's password, the shipped
    // configurations' files made by scripts/zenoh-certs beside them.
    let certs = std::process::Command::new(repo("scripts/zenoh-certs"))
        .arg(dir.join("certs"))
        .arg("10.77.1.2")
        .output()
        .unwrap();
    assert!(certs.status.success(), "{certs:?}");
    let robot_cfg = bridge_config("zenoh-bridge-robot.toml", &dir, |t| {
        t["zenoh"]["listen"] = vec![toml::Value::from("quic/10.77.1.2:7447")].into();
    });
    let laptop_cfg = bridge_config("zenoh-bridge-operator.toml", &dir, |t| {
        t["zenoh"]["connect"] = vec![toml::Value::from("quic/10.77.1.2:7447")].into();
    });
    let bridge = |host: &str, cfg: &Path| {
        let mut c = split
            .hosts
            .stride(host, "stride-zenoh-bridge", &split.shared);
        c.arg("--config").arg(cfg);
        Proc::spawn(c)
    };
    let bridges = [bridge("robot", &robot_cfg), bridge("laptop", &laptop_cfg)];
    // The walk begins once the link carries the robot's reports to the laptop, as a user
    // waits for the bridges to connect (on a loaded machine the TLS handshake and the
    // connect retries take seconds, which the walk's deadline is not for).
    wait_report(&logs[1], 60.0, |_| true);
    let (ok, summary) = split.walk("1.0,0", 90.0);
    // The laptop's logger stops first: what reaches it crossed from the robot's bus, where
    // its logger still listens (stopped the other way round, a step counter the robot sent
    // between the two stops counted on the laptop only: 839 against 838 in a suite run).
    for l in loggers.into_iter().rev() {
        let _ = l.interrupt();
    }
    let [rb, lb] = bridges;
    let (rst, _) = rb.interrupt();
    let (lst, _) = lb.interrupt();
    split.shut_down();
    assert!(ok, "{summary}");
    assert!(summary.contains("reached"), "{summary}");
    assert!(rst.success() && lst.success(), "a bridge's exit");
    let robot = counts(&logs[0]);
    let laptop = counts(&logs[1]);
    eprintln!("robot's bus: {robot:?}\nlaptop's bus: {laptop:?}");
    // The plan went both ways.
    for c in PLAN_WAY {
        assert!(
            robot.contains_key(c) && laptop.contains_key(c),
            "{c}: robot {robot:?}, laptop {laptop:?}"
        );
    }
    // Nothing twice on either bus: no message came back, none was carried twice (but
    // liblcm's self-test, the same bytes from every instance that starts).
    for log in &logs {
        let mut again = repeated(log);
        again.remove("LCM_SELF_TEST");
        assert!(again.is_empty(), "{}: repeated {again:?}", log.display());
    }
    // What the robot says reaches the laptop once (the loggers started together; the
    // bridges a little later).
    let (r, l) = (robot["STEP_COUNTER"], laptop["STEP_COUNTER"]);
    assert!(
        l <= r && l * 10 >= r * 7,
        "STEP_COUNTER robot {r}, laptop {l}"
    );
    // The plans: every one the laptop's planner made is on the robot's bus, once.
    assert_eq!(robot["FOOTSTEP_PLAN"], laptop["FOOTSTEP_PLAN"]);
    // The robot's full-rate channels stayed home.
    assert!(
        !laptop.keys().any(|c| c.starts_with("JOINT_")),
        "{laptop:?}"
    );
    // stride-spy on the far side decodes every type it got.
    let (ok, list) = outcome({
        let mut c = std::process::Command::new(stride_tests::bin("stride-spy"));
        c.args(["list", "--log"]).arg(&logs[1]);
        c
    });
    assert!(ok, "{list}");
    assert!(
        !list.lines().any(|l| l.trim_end().ends_with('?')),
        "types stride-spy does not know: {list}"
    );
}

/// The messages of `channel` in a log, decoded, with their log times (µs).
fn decoded<M: lcm::Message>(log: &Path, channel: &str) -> Vec<(i64, M)> {
    let Ok(mut r) = lcm::LogReader::open(log) else {
        return vec![];
    };
    let mut out = vec![];
    while let Some(e) = r.read_event() {
        if e.channel == channel {
            if let Ok(m) = M::decode(&e.data) {
                out.push((e.timestamp, m));
            }
        }
    }
    out
}

/// The pid of node `name`'s newest heartbeat on `url` other than `not`, waiting up to 60 s.
fn pid_of(url: &str, name: &str, not: i32) -> i32 {
    use stride_lcmtypes::stride::NodeStatusT;
    let lcm = lcm::Lcm::new(url).unwrap();
    let pid = std::sync::Arc::new(std::sync::atomic::AtomicI32::new(0));
    let (p, node) = (pid.clone(), name.to_owned());
    let _s = lcm
        .subscribe("STRIDE_STATUS", move |_, m: NodeStatusT| {
            let up = matches!(
                m.state,
                NodeStatusT::STATE_RUNNING | NodeStatusT::STATE_DEGRADED
            );
            if m.node == node && m.pid != not && up {
                p.store(m.pid, std::sync::atomic::Ordering::Relaxed);
            }
        })
        .unwrap();
    let got = || pid.load(std::sync::atomic::Ordering::Relaxed);
    assert!(
        stride_tests::handle_until(&lcm, Duration::from_secs(60), || got() != 0),
        "no running heartbeat of a new {name}"
    );
    got()
}

/// Sends `sig` to process `pid`.
fn signal(pid: i32, sig: i32) {
    // SAFETY: kill has no memory preconditions.
    assert_eq!(unsafe { libc::kill(pid, sig) }, 0, "kill {pid}");
}

/// The soak of the reliability issue (item 10), which fails on the defects it names: the
/// simulated robot walks while a second process floods its plan channel for 3 s at 5 kHz
/// (stale plans, NaN plans, copies of the planner's plan, random bytes). The gait ticks on time
/// throughout (its step counter's stamps less than 50 ms apart: a burst silenced it for
/// seconds, D1), counts every plan (taken, refused, dropped, undecodable: each counted once),
/// and walks on. Then a stall of the gait (SIGSTOP 0.6 s) runs both bridges' streams dry: they
/// say STOPPED, and the gait stands the robot up from where the joints came to rest (its
/// stand rows were refused and the legs stayed frozen mid-step, D4). Then a SIGKILL of the
/// gait mid-walk and of a bridge, `stride resume`, and a walk that must reach its goal (the
/// restarted gait stayed FAULT for good, D3). Nothing is lost on any app that was not sent
/// (the bridges counted 1521 lost on a bus that lost nothing, item 6).
#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn a_flooded_stalled_and_killed_robot_walks_again_after_a_resume() {
    use stride_lcmtypes::stride::{
        FootstepPlanT, GaitCommandT, NodeStatusT, StepCounterT, TrajectoryStatusT,
    };
    require_sandbox();
    let _one = ONE_WALK.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let url = udpm_url(7831);
    let scene = "name = \"long\"\nstart = { x = 0.0, y = 0.0 }\ngoal = { x = 6.0, y = 0.0 }\n\
                 [map]\nx = [-1.0, 9.0]\ny = [-2.0, 2.0]\n";
    let profile = setup(dir.path(), &url, scene, "[body]\nfall_margin = 0.1\n");
    let log = dir.path().join("soak.lcmlog");
    let logger = stride_tests::lcm_logger(&url, ".*", &log, "SOAK_PROBE");
    let launcher = launch(&profile, &url, dir.path());
    let walking = |m: &TrajectoryStatusT| m.state == TrajectoryStatusT::STATE_MOVING;

    // 1. The flood, mid-walk.
    let first = std::thread::spawn({
        let url = url.clone();
        move || walk(&url, "6.0,0", 120.0)
    });
    stride_tests::wait_for(&url, "GAIT_STATUS", Duration::from_secs(90), walking);
    std::thread::sleep(Duration::from_secs(2));
    let flood = std::process::Command::new(stride_tests::bin("lcm-flood"))
        .args(["--lcm-url", &url, "--rate", "5000", "--seconds", "3"])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&flood.stdout).to_string();
    assert!(
        flood.status.success(),
        "{said}{}",
        String::from_utf8_lossy(&flood.stderr)
    );
    let sent: serde_json::Value = serde_json::from_str(said.trim()).unwrap();
    let (n, t0, t1) = (
        sent["sent"].as_i64().unwrap(),
        sent["start_utime"].as_i64().unwrap(),
        sent["end_utime"].as_i64().unwrap(),
    );
    assert_eq!(n, 15_000, "{said}");
    std::thread::sleep(Duration::from_secs(3));

    // 2. A stall: the bridges' streams run dry.
    let gait = pid_of(&url, "gait", 0);
    signal(gait, libc::SIGSTOP);
    std::thread::sleep(Duration::from_millis(600));
    signal(gait, libc::SIGCONT);
    let (_, first) = first.join().unwrap();
    // Standing up from where the joints came to rest: the gait's status says so, and then
    // that it stands, both bridges taking its rows.
    stride_tests::wait_for(
        &url,
        "GAIT_STATUS",
        Duration::from_secs(30),
        |m: &TrajectoryStatusT| {
            m.state == TrajectoryStatusT::STATE_IDLE && m.reason.is_empty() && m.recovery.is_empty()
        },
    );
    let stalled_at = now_utime();

    // 3. Kills mid-walk: the gait, then a bridge; the launcher restarts each.
    let second = std::thread::spawn({
        let url = url.clone();
        move || walk(&url, "6.0,0", 120.0)
    });
    stride_tests::wait_for(&url, "GAIT_STATUS", Duration::from_secs(60), walking);
    std::thread::sleep(Duration::from_secs(2));
    signal(gait, libc::SIGKILL);
    let new_gait = pid_of(&url, "gait", gait);
    let (_, second) = second.join().unwrap();
    let bridge = pid_of(&url, "left-leg", 0);
    signal(bridge, libc::SIGKILL);
    pid_of(&url, "left-leg", bridge);

    // 4. Resumed, the robot walks to a goal again.
    let resume = on_bus("stride", &url).arg("resume").output().unwrap();
    assert!(resume.status.success());
    let (ok, last) = walk(&url, "4.0,0", 120.0);
    let _ = logger.interrupt();
    let (st, out) = launcher.interrupt();
    eprintln!("first walk:\n{first}\nsecond walk:\n{second}\nlast walk:\n{last}");
    assert!(ok, "the walk after the kills and the resume: {last}\n{out}");
    assert!(last.contains("reached"), "{last}");
    assert!(st.success(), "the launcher's shutdown: {out}");

    // The gait ticked on time through the flood: its step counter's stamps.
    let counters: Vec<(i64, StepCounterT)> = decoded(&log, "STEP_COUNTER");
    let during: Vec<i64> = counters
        .iter()
        .map(|(_, c)| c.header.utime)
        .filter(|&u| u >= t0 && u <= t1)
        .collect();
    assert!(
        during.len() > 100,
        "{} counters during the flood",
        during.len()
    );
    let gap = during.windows(2).map(|w| w[1] - w[0]).max().unwrap();
    assert!(
        gap < 50_000,
        "the step counter paused {gap} µs during the flood"
    );
    // A flood does not multiply the set-points: the set-point bridges' channel at the
    // gait's rate (100 Hz) through it, as before it (59/s became 2144/s).
    let set_points =
        decoded::<stride_lcmtypes::stride::JointCommandT>(&log, "ARCHIE_LEFT_LEG_COMMAND")
            .iter()
            .filter(|(_, c)| c.header.utime >= t0 && c.header.utime <= t1)
            .count() as f64;
    let per_s = set_points / ((t1 - t0) as f64 * 1e-6);
    assert!(
        per_s <= 110.0,
        "{per_s:.0} set-points a second during the flood"
    );
    // Every plan counted once: the gait's counts from before the flood to after it against
    // what was sent (the flood, and the planner's answers to the requests in between).
    let statuses: Vec<(i64, TrajectoryStatusT)> = decoded(&log, "GAIT_STATUS");
    let beats: Vec<(i64, NodeStatusT)> = decoded::<NodeStatusT>(&log, "STRIDE_STATUS")
        .into_iter()
        .filter(|(_, b)| b.node == "gait" && b.pid == gait)
        .collect();
    let times = |v: &[(i64, TrajectoryStatusT)]| v.iter().map(|(t, _)| *t).collect::<Vec<_>>();
    let before = |at: &[i64], t: i64| at.iter().rposition(|a| *a < t).unwrap();
    let (st, bt) = (
        times(&statuses),
        beats.iter().map(|(t, _)| *t).collect::<Vec<_>>(),
    );
    let (s0, s1) = (before(&st, t0), before(&st, t1 + 2_500_000));
    let (h0, h1) = (before(&bt, t0), before(&bt, t1 + 2_500_000));
    let plans = |s: &TrajectoryStatusT| s.accepted + s.refused + s.dropped;
    // Taken, refused, dropped or undecodable; and what the gait counted lost (on any of its
    // channels: the flood may cost it a joint state or two, which it counts).
    let looked_at = plans(&statuses[s1].1) - plans(&statuses[s0].1)
        + (beats[h1].1.decode_errors - beats[h0].1.decode_errors);
    let lost = beats[h1].1.messages_lost - beats[h0].1.messages_lost;
    // The planner's plans in between, by their sequence numbers (the logger itself may miss
    // some in a flood; the copies carry their original's number, published before the flood).
    let (from, to) = (statuses[s0].0, statuses[s1].0);
    let planner: Vec<(i64, FootstepPlanT)> = decoded::<FootstepPlanT>(&log, "FOOTSTEP_PLAN")
        .into_iter()
        .filter(|(_, p)| p.header.frame != "flood")
        .collect();
    let copied = planner
        .iter()
        .filter(|(at, _)| *at > from && *at < to)
        .fold(std::collections::BTreeMap::new(), |mut m, (_, p)| {
            *m.entry(p.header.sequence).or_insert(0) += 1;
            m
        });
    let copied = copied.iter().max_by_key(|(_, k)| **k).map(|(s, _)| *s);
    let seqs: std::collections::BTreeSet<i64> = planner
        .iter()
        .filter(|(at, p)| {
            *at > from
                && *at < to
                && !(Some(p.header.sequence) == copied
                    && planner
                        .iter()
                        .any(|(t, q)| *t <= from && q.header.sequence == p.header.sequence))
        })
        .map(|(_, p)| p.header.sequence)
        .collect();
    let planned = match (seqs.first(), seqs.last()) {
        (Some(a), Some(b)) => b - a + 1,
        _ => 0,
    };
    assert!(
        looked_at <= n + planned + 2 && looked_at + lost >= n + planned - 2,
        "{looked_at} looked at and {lost} lost of {n} flooded and {planned} planned"
    );
    assert_eq!(
        beats[h1].1.decode_errors - beats[h0].1.decode_errors,
        sent["bytes"].as_i64().unwrap(),
        "every random message counted as undecodable"
    );
    // The stall: both bridges said their streams ran dry, and the gait stood up from there.
    for leg in ["LEFT", "RIGHT"] {
        let said: Vec<(i64, TrajectoryStatusT)> =
            decoded(&log, &format!("JOINT_TRAJECTORY_STATUS_{leg}_LEG"));
        assert!(
            said.iter()
                .any(|(_, s)| s.state == TrajectoryStatusT::STATE_STOPPED
                    && s.reason.contains("ran dry")),
            "the {leg} bridge never said its stream ran dry"
        );
    }
    assert!(
        statuses.iter().any(|(_, s)| s
            .reason
            .starts_with("standing up from where the joints are")),
        "the gait did not stand up after the stall"
    );
    // Two system stops (the killed gait, the killed bridge), both resumed.
    let stops: Vec<(i64, GaitCommandT)> = decoded(&log, "STRIDE_STOP");
    assert!(
        stops
            .iter()
            .any(|(at, s)| *at > stalled_at && s.reason.contains("gait killed")),
        "{stops:?}"
    );
    assert!(stops
        .iter()
        .any(|(_, s)| s.reason.contains("left-leg killed")));
    assert_ne!(new_gait, gait);
    // Nothing counted lost that was not: every app's last heartbeat.
    let mut last_beat = std::collections::BTreeMap::new();
    for (_, b) in decoded::<NodeStatusT>(&log, "STRIDE_STATUS") {
        last_beat.insert(b.node.clone(), b);
    }
    let lost: Vec<(&String, i64)> = last_beat
        .iter()
        .map(|(n, b)| (n, b.messages_lost))
        .filter(|(_, l)| *l > 0)
        .collect();
    assert!(lost.is_empty(), "lost on a bus that lost nothing: {lost:?}");
}

/// D9 and item 5 of the reliability issue: a goal the planner cannot reach was asked for
/// again every second until `stride walk` timed out, "NOT reached" with no word of why, its
/// figure printed in thirty digits. It ends the walk with the planner's reason, short; a goal
/// sent afterwards is walked.
#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn a_goal_the_planner_cannot_reach_ends_the_walk_with_its_reason_and_the_next_is_walked() {
    require_sandbox();
    let _one = ONE_WALK.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let url = udpm_url(7833);
    let profile = setup(dir.path(), &url, FLAT, "[body]\nfall_margin = 0.1\n");
    let launcher = launch(&profile, &url, dir.path());
    let (ok, far) = walk(&url, "1e9,0", 60.0);
    let (ok2, near) = walk(&url, "1.0,0", 90.0);
    let (st, out) = launcher.interrupt();
    assert!(!ok, "{far}");
    assert!(
        far.contains("the walk ended: goal (1.000e9, 0.000) dropped: the planner cannot reach it")
            && far.contains("beyond the 50 m a plan may reach"),
        "{far}"
    );
    // ("the walk ended" is said only of a goal the gait dropped on the planner's answer, not
    // of a walk that ran out of time.)
    assert!(far.lines().all(|l| l.len() < 300), "{far}");
    assert!(ok2, "{near}\n{out}");
    assert!(near.contains("reached"), "{near}");
    assert!(st.success(), "{out}");
}
