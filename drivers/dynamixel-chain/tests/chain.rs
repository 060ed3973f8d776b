//! The chain against fake servos on a pseudo-terminal, paced at the line's baud rate.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use stride_dynamixel::{models, v1, v2};
use stride_dynamixel_chain::{Chain, ChainConfig, ReadMode, ServoConfig, StartError};
use stride_fakes::dynamixel::{ChainLevers, FakeChain, Fault, Servo};
use stride_limits::Reject;
use stride_serial::{pty_pair, Paced, Port};

#[derive(serde::Deserialize)]
struct Shipped {
    servo: Vec<ServoConfig>,
}

fn shipped(name: &str) -> Vec<ServoConfig> {
    let path = format!("{}/../../config/robots/{name}", env!("CARGO_MANIFEST_DIR"));
    let s: Shipped = toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    s.servo
}

fn cfg(servos: Vec<ServoConfig>) -> ChainConfig {
    ChainConfig {
        servos,
        read: ReadMode::Auto,
        return_delay_us: 0,
        // A pty on a loaded test machine.
        margin: Duration::from_millis(25),
        retries: 2,
        hold_timeout: Some(Duration::from_millis(500)),
        bus_watchdog: Some(Duration::from_millis(100)),
    }
}

type Line = Port<serialport::TTYPort>;

struct Sim {
    chain: Chain<Line>,
    levers: ChainLevers,
    stop: Arc<AtomicBool>,
    h: Option<std::thread::JoinHandle<FakeChain>>,
}

impl Sim {
    fn end(&mut self) -> Option<FakeChain> {
        self.stop.store(true, Ordering::Relaxed);
        self.h.take().map(|h| h.join().unwrap())
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        self.end();
    }
}

/// A fake chain of the configured servos (all but `skip`) on a new pty: its host end.
fn fakes(
    c: &ChainConfig,
    skip: Option<u8>,
    levers: &ChainLevers,
    stop: &Arc<AtomicBool>,
) -> (Line, std::thread::JoinHandle<FakeChain>) {
    let (host, dev) = pty_pair(1_000_000).unwrap();
    let protocol = stride_dynamixel_chain::check(&c.servos).unwrap();
    let servos = c
        .servos
        .iter()
        .filter(|s| Some(s.id) != skip)
        .map(|s| Servo::new(s.id, models::by_name(&s.model).unwrap()))
        .collect();
    let h = FakeChain::new(protocol, servos, levers.clone())
        .at_baud(1_000_000)
        .spawn(Paced::new(dev), stop.clone());
    (host, h)
}

fn sim(c: ChainConfig, skip: Option<u8>) -> Sim {
    let levers = ChainLevers::default();
    let stop = Arc::new(AtomicBool::new(false));
    let (host, h) = fakes(&c, skip, &levers, &stop);
    Sim {
        chain: Chain::new(host, c).unwrap(),
        levers,
        stop,
        h: Some(h),
    }
}

fn names(n: &[&str]) -> Vec<String> {
    n.iter().map(|s| s.to_string()).collect()
}

#[test]
fn shipped_configs_check() {
    let hex = shipped("hexapod-dynamixel.toml");
    assert_eq!(
        stride_dynamixel_chain::check(&hex),
        Ok(stride_dynamixel::Protocol::V1)
    );
    assert_eq!(hex.len(), 18);
    let arm = shipped("arm-xm430.toml");
    assert_eq!(
        stride_dynamixel_chain::check(&arm),
        Ok(stride_dynamixel::Protocol::V2)
    );
    let mut bad = arm.clone();
    bad[1].id = bad[0].id;
    assert!(stride_dynamixel_chain::check(&bad).is_err());
    let mut bad = hex.clone();
    bad[0].max_position = 3.0; // beyond the AX-12A's 300 degrees
    assert!(stride_dynamixel_chain::check(&bad)
        .unwrap_err()
        .contains("outside"));
    let mut twice = hex.clone();
    twice[1].name = twice[0].name.clone();
    assert!(stride_dynamixel_chain::check(&twice)
        .unwrap_err()
        .contains("named twice"));
}

#[test]
fn a_missing_servo_stops_the_start_by_name() {
    let mut s = sim(cfg(shipped("hexapod-dynamixel.toml")), Some(7));
    let e = s.chain.bring_up().unwrap_err();
    assert_eq!(e, StartError::Missing("lr_coxa (id 7)".into()));
}

#[test]
fn a_joint_named_twice_in_a_command_is_refused() {
    // The finding: lf_femur twice (0.7, -0.7) was taken, the last value winning.
    let mut s = sim(cfg(shipped("hexapod-dynamixel.toml")), None);
    s.chain.bring_up().unwrap();
    let e = s
        .chain
        .command(
            &names(&["lf_femur", "lf_femur"]),
            &[0.7, -0.7],
            &[0.0, 0.0],
            Instant::now(),
        )
        .unwrap_err();
    assert_eq!(e, Reject::DuplicateJoint("lf_femur".into()));
}

#[test]
fn hexapod_moves_holds_and_refuses_limits() {
    let mut s = sim(cfg(shipped("hexapod-dynamixel.toml")), None);
    s.chain.bring_up().unwrap();
    let t0 = Instant::now();
    s.chain
        .command(
            &names(&["lf_femur", "rf_femur"]),
            &[0.4, 0.4],
            &[0.0, 0.0],
            t0,
        )
        .unwrap();
    // Past a limit: refused whole, the other joint's goal untouched.
    let e = s
        .chain
        .command(
            &names(&["lf_femur", "lf_tibia"]),
            &[0.2, 2.5],
            &[0.0, 0.0],
            t0,
        )
        .unwrap_err();
    assert!(
        matches!(&e, Reject::Limit { joint, .. } if joint == "lf_tibia"),
        "{e}"
    );
    let deadline = Instant::now() + Duration::from_secs(3);
    loop {
        s.chain.cycle(Instant::now()).unwrap();
        let m = s.chain.measured();
        if (m[1].position - 0.4).abs() < 0.01 && (m[10].position - 0.4).abs() < 0.01 {
            break;
        }
        assert!(Instant::now() < deadline, "{:?} {:?}", m[1], m[10]);
    }
    // An overheating servo: its error bits say so.
    s.levers.set(
        5,
        Fault {
            overheat: true,
            ..Fault::default()
        },
    );
    std::thread::sleep(Duration::from_millis(20));
    s.chain.cycle(Instant::now()).unwrap();
    let m = s.chain.measured()[4];
    assert_eq!(
        m.errors & v1::ErrorBits::OVERHEATING,
        v1::ErrorBits::OVERHEATING
    );
    assert!(m.temperature > 70.0);
    s.chain.torque_off().unwrap();
}

#[test]
fn the_hold_when_commands_stop_does_not_step_back() {
    // The finding: the femur, limited to 1 rad/s, held at its last measured position (a
    // cycle old), stopped at 0.522 rad and went back to 0.501.
    let mut servos = shipped("hexapod-dynamixel.toml");
    for s in &mut servos {
        s.max_velocity = 1.0;
    }
    let mut c = cfg(servos);
    c.hold_timeout = Some(Duration::from_millis(100));
    let mut s = sim(c, None);
    s.chain.bring_up().unwrap();
    let k = s
        .chain
        .joints()
        .iter()
        .position(|j| j.cfg.name == "lm_femur")
        .unwrap();
    s.chain
        .command(&names(&["lm_femur"]), &[1.2], &[0.0], Instant::now())
        .unwrap();
    // Cycles every 20 ms, as the bridge runs at 50 Hz, until it is well on its way.
    let cycle = |s: &mut Sim| {
        s.chain.cycle(Instant::now()).unwrap();
        std::thread::sleep(Duration::from_millis(20));
    };
    while s.chain.measured()[k].position < 0.3 {
        cycle(&mut s);
    }
    // Commands stopped at once: the hold comes 100 ms after the last, as the bridge polls.
    let t0 = Instant::now();
    while !s.chain.hold_if_stale(Instant::now()) {
        assert!(t0.elapsed() < Duration::from_secs(1), "never held");
        cycle(&mut s);
    }
    assert!(!s.chain.hold_if_stale(Instant::now()), "holds once");
    let mut trace = Vec::new();
    for _ in 0..20 {
        cycle(&mut s);
        trace.push(s.chain.measured()[k].position);
    }
    let top = trace.iter().copied().fold(f64::MIN, f64::max);
    let end = *trace.last().unwrap();
    assert!(end < 1.0, "kept going to its goal: {end}");
    assert!(
        top - end < 0.004,
        "stepped back {} rad: {trace:?}",
        top - end
    );
}

#[test]
fn arm_on_protocol_2_reports_alerts_and_timeouts() {
    let mut s = sim(cfg(shipped("arm-xm430.toml")), None);
    s.chain.bring_up().unwrap();
    s.chain.cycle(Instant::now()).unwrap();
    assert!(s.chain.measured().iter().all(|m| m.at.is_some()));
    s.levers.set(
        2,
        Fault {
            overload: true,
            ..Fault::default()
        },
    );
    std::thread::sleep(Duration::from_millis(20));
    s.chain.cycle(Instant::now()).unwrap();
    let m = s.chain.measured()[1];
    assert_eq!(m.hardware, v2::HardwareError::OVERLOAD);
    assert_eq!(m.errors, v1::ErrorBits::OVERLOAD);
    // A silent servo spoils the fast sync read; the sync read that follows tells which.
    s.levers.clear(2);
    s.levers.set(
        4,
        Fault {
            silent: true,
            ..Fault::default()
        },
    );
    let missed = |s: &Sim| -> Vec<u32> {
        s.chain
            .joints()
            .iter()
            .map(|j| s.chain.bus().missed(j.cfg.id))
            .collect()
    };
    let (before, seen) = (
        missed(&s),
        s.chain.measured().iter().map(|m| m.at).collect::<Vec<_>>(),
    );
    s.chain.cycle(Instant::now()).unwrap();
    let after = missed(&s);
    // The silent servo missed its tries and kept its old state; every other one answered
    // (a try of theirs may time out and be repeated on a loaded machine, so their counts
    // are not read, their fresh states are).
    assert!(after[3] > before[3], "{before:?} -> {after:?}");
    for (k, m) in s.chain.measured().iter().enumerate() {
        if k == 3 {
            assert_eq!(m.at, seen[k], "the silent servo has a new state");
        } else {
            assert!(m.at > seen[k], "servo {k} has no new state");
        }
    }
}

#[test]
fn protocol_2_servos_stop_on_their_own_when_the_host_goes_quiet() {
    let mut s = sim(cfg(shipped("arm-xm430.toml")), None);
    s.chain.bring_up().unwrap();
    let j = s.chain.joints()[0].clone();
    let (lo, hi) = (j.cfg.min_position, j.cfg.max_position);
    let far = lo + 0.9 * (hi - lo);
    s.chain
        .command(
            std::slice::from_ref(&j.cfg.name),
            &[far],
            &[0.0],
            Instant::now(),
        )
        .unwrap();
    for _ in 0..5 {
        s.chain.cycle(Instant::now()).unwrap();
        std::thread::sleep(Duration::from_millis(20));
    }
    // The host goes quiet (a killed bridge) for 0.5 s: after its 100 ms watchdog the servo
    // stopped, far from its goal, and says so in item 98.
    std::thread::sleep(Duration::from_millis(500));
    let fake = s.end().unwrap();
    let servo = &fake.servos()[0];
    assert_eq!(servo.item("bus_watchdog"), -1);
    let p = j.rad(servo.item("present_position"));
    assert!(p < far - 0.5, "went on to {p} (goal {far})");
    assert_eq!(servo.item("goal_position"), servo.item("present_position"));
}

#[test]
fn the_chain_comes_back_holding_after_its_port_returns() {
    let c = cfg(shipped("arm-xm430.toml"));
    let mut s = sim(c.clone(), None);
    s.chain.bring_up().unwrap();
    // A move under way when the port goes: its goal must not come back with the port.
    let first = s.chain.joints()[0].cfg.name.clone();
    let goal = s.chain.joints()[0].rad(2048) + 0.3;
    s.chain
        .command(
            std::slice::from_ref(&first),
            &[goal],
            &[0.0],
            Instant::now(),
        )
        .unwrap();
    s.chain.cycle(Instant::now()).unwrap();
    // The port vanishes: every cycle fails.
    s.end();
    assert!(s.chain.cycle(Instant::now()).is_err());
    // It comes back (new servos, each where it stands): the chain reattaches, brings each
    // up again, and holds where they are.
    let stop = Arc::new(AtomicBool::new(false));
    let (line, h) = fakes(&c, None, &s.levers, &stop);
    s.stop = stop;
    s.h = Some(h);
    s.chain.reattach(line).unwrap();
    for _ in 0..10 {
        s.chain.cycle(Instant::now()).unwrap();
        std::thread::sleep(Duration::from_millis(20));
    }
    for (j, m) in s.chain.joints().iter().zip(s.chain.measured()) {
        assert!(
            (m.position - j.rad(2048)).abs() < 1e-3,
            "{}: {}",
            j.cfg.name,
            m.position
        );
    }
    s.chain
        .command(&[first], &[0.3], &[0.0], Instant::now())
        .unwrap();
}

#[test]
fn a_bus_watchdog_off_the_20_ms_grid_is_refused_not_shortened() {
    use stride_dynamixel_chain::watchdog_units;
    let ms = Duration::from_millis;
    assert_eq!(watchdog_units(ms(40)), Ok(2));
    assert_eq!(watchdog_units(ms(2540)), Ok(127));
    // 35 ms was written as one unit (20 ms): the servos stopped between cycles.
    for bad in [ms(35), ms(10), ms(2560), Duration::from_micros(40_500)] {
        assert!(watchdog_units(bad).is_err(), "{bad:?}");
    }
}

#[test]
fn a_commanded_speed_becomes_the_servos_moving_speed() {
    // The gait gives each servo the speed that brings it to its goal within the control
    // period: it goes out with the goal (one sync write of both items), rounded up to the
    // model's unit; a servo commanded without one keeps the speed set at start.
    for file in ["hexapod-dynamixel.toml", "arm-xm430.toml"] {
        let c = cfg(shipped(file));
        let mut s = sim(c.clone(), None);
        s.chain.bring_up().unwrap();
        let j: Vec<_> = s.chain.joints().iter().map(|j| j.cfg.clone()).collect();
        let names: Vec<String> = j[..3].iter().map(|j| j.name.clone()).collect();
        s.chain
            .command(&names, &[0.1, -0.1, 0.05], &[1.0, 2.0, 0.0], Instant::now())
            .unwrap();
        s.chain.cycle(Instant::now()).unwrap();
        let fakes = s.end().unwrap();
        let model = models::by_name(&j[0].model).unwrap();
        let (item, unit) = match model.protocol {
            stride_dynamixel::Protocol::V1 => ("moving_speed", model.velocity_unit_rpm),
            stride_dynamixel::Protocol::V2 => ("profile_velocity", model.velocity_unit_rpm),
        };
        let want = |v: f64| (v * 60.0 / std::f64::consts::TAU / unit).ceil() as i64;
        let servo = |id: u8| fakes.servos().iter().find(|s| s.id() == id).unwrap();
        assert_eq!(servo(j[0].id).item(item), want(1.0), "{file}");
        assert_eq!(servo(j[1].id).item(item), want(2.0), "{file}");
        let setup =
            ((j[2].max_velocity * 60.0 / std::f64::consts::TAU / unit).floor() as i64).max(1);
        assert_eq!(servo(j[2].id).item(item), setup, "{file}");
    }
}
