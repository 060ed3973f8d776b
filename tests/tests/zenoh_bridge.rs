//! stride-zenoh-bridge between two LCM buses of one machine (two ports, no multicast between
//! them), over Zenoh on loopback TCP and over the secured link (QUIC, certificates both
//! ways, a password).

use std::time::{Duration, Instant};

use stride_lcmtypes::stride::PingT;
use stride_tests::{bin, require_sandbox, udpm_url, Proc};

/// A bridge on bus `url` named `bus`, listening or connecting on `endpoint`, carrying
/// `channels` both ways.
fn bridge(dir: &std::path::Path, url: &str, bus: &str, endpoint: &str, listen: bool) -> Proc {
    let (listen, connect) = if listen {
        (format!("[\"{endpoint}\"]"), "[]".to_owned())
    } else {
        ("[]".to_owned(), format!("[\"{endpoint}\"]"))
    };
    let cfg = dir.join(format!("{bus}.toml"));
    std::fs::write(
        &cfg,
        format!(
            "bus = \"{bus}\"\nprefix = \"lcm\"\nin = [\"BURST\"]\n\
             [zenoh]\nmode = \"peer\"\nlisten = {listen}\nconnect = {connect}\n\
             [[out]]\npattern = \"BURST\"\n"
        ),
    )
    .unwrap();
    let mut c = std::process::Command::new(bin("stride-zenoh-bridge"));
    c.args(["--lcm-url", url, "--log-level", "warn", "--name", bus])
        .arg("--config")
        .arg(&cfg);
    Proc::spawn(c)
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn a_burst_of_messages_crosses_the_zenoh_bridges_whole() {
    // Regression: liblcm queues 30 messages for a subscription by default, and the bridge's
    // side on the bus dropped the rest of a burst of 32 or more before it reached Zenoh.
    require_sandbox();
    let dir = tempfile::tempdir().unwrap();
    let (a_url, b_url) = (udpm_url(7851), udpm_url(7852));
    let endpoint = "tcp/127.0.0.1:7457";
    let _a = bridge(dir.path(), &a_url, "near", endpoint, true);
    let _b = bridge(dir.path(), &b_url, "far", endpoint, false);
    let a = lcm::Lcm::new(&a_url).unwrap();
    let b = lcm::Lcm::new(&b_url).unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    let sub = b
        .subscribe("BURST", move |_, m: PingT| {
            let _ = tx.send(m.sent_utime);
        })
        .unwrap();
    sub.set_queue_capacity(0).unwrap();
    // The bridges are joined once a probe crosses.
    let probe = PingT {
        sent_utime: -1,
        ..Default::default()
    };
    let t0 = Instant::now();
    let mut joined = false;
    while !joined && t0.elapsed() < Duration::from_secs(30) {
        a.publish("BURST", &probe).unwrap();
        b.handle_timeout(Duration::from_millis(100)).unwrap();
        joined = rx.try_iter().any(|s| s == -1);
    }
    assert!(joined, "nothing crossed the bridges within 30 s");
    std::thread::sleep(Duration::from_millis(300));
    while b.handle_timeout(Duration::from_millis(50)).unwrap() {}
    rx.try_iter().for_each(drop);
    // 300 messages back to back (well inside a socket's receive buffer).
    const N: i64 = 300;
    for i in 0..N {
        let m = PingT {
            sent_utime: i,
            ..Default::default()
        };
        a.publish("BURST", &m).unwrap();
    }
    let mut got = std::collections::BTreeSet::new();
    let deadline = Instant::now() + Duration::from_secs(20);
    while (got.len() as i64) < N && Instant::now() < deadline {
        b.handle_timeout(Duration::from_millis(50)).unwrap();
        got.extend(rx.try_iter().filter(|&s| s >= 0));
    }
    let missing: Vec<i64> = (0..N).filter(|s| !got.contains(s)).collect();
    assert!(
        missing.is_empty(),
        "{} of {N} did not cross: {:?}",
        missing.len(),
        &missing[..missing.len().min(20)]
    );
}

/// Makes the link's certificates and passwords as a user does (scripts/zenoh-certs) in `dir`,
/// the robot's certificate naming `addresses`.
fn credentials(dir: &std::path::Path, addresses: &[&str]) {
    let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/zenoh-certs");
    let out = std::process::Command::new(script)
        .arg(dir)
        .args(addresses)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// How a bridge of the secured tests meets the other.
struct Side<'a> {
    bus: &'a str,
    url: &'a str,
    /// `listen` or `connect`, and the endpoint.
    endpoint: (&'a str, &'a str),
    /// The [zenoh.tls] and [zenoh.auth] sections, and whatever else [zenoh] says.
    security: String,
    channels: &'a str,
}

fn secured(dir: &std::path::Path, s: &Side) -> Proc {
    let cfg = dir.join(format!("{}.toml", s.bus));
    let list = s
        .channels
        .split('|')
        .map(|c| format!("{c:?}"))
        .collect::<Vec<_>>()
        .join(", ");
    std::fs::write(
        &cfg,
        format!(
            "bus = \"{}\"\nin = [{list}]\n[[out]]\npattern = \"{}\"\n\
             [zenoh]\nmode = \"peer\"\n{} = [\"{}\"]\n{}",
            s.bus, s.channels, s.endpoint.0, s.endpoint.1, s.security
        ),
    )
    .unwrap();
    let mut c = std::process::Command::new(bin("stride-zenoh-bridge"));
    c.args(["--lcm-url", s.url, "--log-level", "warn", "--name", s.bus])
        .arg("--config")
        .arg(&cfg);
    Proc::spawn(c)
}

/// The [zenoh.tls] section for `name`'s certificate in `certs`, and its [zenoh.auth].
fn tls(certs: &std::path::Path, name: &str, auth: &str) -> String {
    format!(
        "[zenoh.tls]\nca = \"{c}/ca.pem\"\ncertificate = \"{c}/{name}.pem\"\nkey = \"{c}/{name}-key.pem\"\n{auth}",
        c = certs.display()
    )
}

/// The robot's bridge as shipped: listening on `endpoint` with its certificate from `certs`,
/// letting in the users of `robot-users.txt`.
fn robot_side(
    dir: &std::path::Path,
    certs: &std::path::Path,
    url: &str,
    endpoint: &str,
    channels: &str,
) -> Proc {
    let users = format!(
        "[zenoh.auth]\nusers_file = \"{}\"\n",
        certs.join("robot-users.txt").display()
    );
    secured(
        dir,
        &Side {
            bus: "robot",
            url,
            endpoint: ("listen", endpoint),
            security: tls(certs, "robot", &users),
            channels,
        },
    )
}

/// The operator's bridge as shipped: connecting to `endpoint` with its certificate and
/// password from `certs`.
fn operator_side(
    dir: &std::path::Path,
    certs: &std::path::Path,
    url: &str,
    endpoint: &str,
    channels: &str,
) -> Proc {
    secured(
        dir,
        &Side {
            bus: "operator",
            url,
            endpoint: ("connect", endpoint),
            security: tls(
                certs,
                "operator",
                &password(&certs.join("operator.password")),
            ),
            channels,
        },
    )
}

/// The [zenoh.auth] section of the operator's user with the password in `file`.
fn password(file: &std::path::Path) -> String {
    format!(
        "[zenoh.auth]\nuser = \"operator\"\npassword_file = \"{}\"\n",
        file.display()
    )
}

/// Publishes `m` on `from` every 100 ms for `secs` s and says whether any reached `to` on
/// `channel`.
fn crosses(from: &lcm::Lcm, to: &lcm::Lcm, channel: &str, secs: f64) -> bool {
    let (tx, rx) = std::sync::mpsc::channel();
    let _sub = to
        .subscribe(channel, move |_, m: PingT| {
            let _ = tx.send(m.sent_utime);
        })
        .unwrap();
    let t0 = Instant::now();
    let probe = PingT {
        sent_utime: 42,
        ..Default::default()
    };
    while t0.elapsed() < Duration::from_secs_f64(secs) {
        from.publish(channel, &probe).unwrap();
        to.handle_timeout(Duration::from_millis(100)).unwrap();
        if rx.try_iter().any(|s| s == 42) {
            return true;
        }
    }
    false
}

/// Item 9 of the reliability issue: the link was plain TCP that anyone who reached the port
/// could join, and publish goals, plans and stops through. Over TLS both ways with a user and
/// password, a peer with the right certificate and password carries a footstep plan whole; a
/// peer without them connects to nothing and nothing it sends reaches the robot's bus.
#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn only_a_peer_with_the_links_certificate_and_password_reaches_the_robots_bus() {
    use stride_lcmtypes::stride::{FootstepPlanT, FootstepT, NodeStatusT};
    require_sandbox();
    let dir = tempfile::tempdir().unwrap();
    let (certs, other) = (dir.path().join("certs"), dir.path().join("other"));
    credentials(&certs, &["127.0.0.1"]);
    credentials(&other, &["127.0.0.1"]);
    let robot_url = udpm_url(7853);
    let endpoint = "quic/127.0.0.1:7458";
    let channels = "FOOTSTEP_PLAN|STRIDE_STOP";
    let _robot = robot_side(dir.path(), &certs, &robot_url, endpoint, channels);
    let robot = lcm::Lcm::new(&robot_url).unwrap();
    let wrong = dir.path().join("wrong.password");
    std::fs::write(&wrong, "not-the-password\n").unwrap();
    // The intruders, each on a bus of its own: another authority's certificate with the
    // right password, the right certificate with a wrong password or none, and plain TCP.
    let intruders = [
        (
            "other-ca",
            tls(
                &other,
                "operator",
                &password(&certs.join("operator.password")),
            ),
        ),
        ("wrong-password", tls(&certs, "operator", &password(&wrong))),
        ("no-password", tls(&certs, "operator", "")),
    ];
    for (k, (name, security)) in intruders.iter().enumerate() {
        let url = udpm_url(7860 + k as u16);
        let p = secured(
            dir.path(),
            &Side {
                bus: name,
                url: &url,
                endpoint: ("connect", endpoint),
                security: security.clone(),
                channels,
            },
        );
        let bus = lcm::Lcm::new(&url).unwrap();
        for ch in ["FOOTSTEP_PLAN", "STRIDE_STOP"] {
            assert!(
                !crosses(&bus, &robot, ch, 3.0),
                "{name}: {ch} reached the robot"
            );
        }
        // The intruder's bridge says it is connected to no one.
        let node = name.to_string();
        stride_tests::wait_for(
            &url,
            "STRIDE_STATUS",
            Duration::from_secs(5),
            move |m: &NodeStatusT| {
                m.node == node
                    && m.state == NodeStatusT::STATE_DEGRADED
                    && m.detail.contains("connected to no peer")
            },
        );
        drop(p);
    }
    // Plain TCP to the link's port: no link either.
    let tcp_url = udpm_url(7864);
    let _plain = secured(
        dir.path(),
        &Side {
            bus: "plain",
            url: &tcp_url,
            endpoint: ("connect", "tcp/127.0.0.1:7458"),
            security: String::new(),
            channels,
        },
    );
    let plain = lcm::Lcm::new(&tcp_url).unwrap();
    assert!(
        !crosses(&plain, &robot, "STRIDE_STOP", 3.0),
        "plain TCP reached the robot"
    );
    // The operator with the link's certificate and password: a plan crosses whole.
    let op_url = udpm_url(7865);
    let _operator = operator_side(dir.path(), &certs, &op_url, endpoint, channels);
    let operator = lcm::Lcm::new(&op_url).unwrap();
    assert!(
        crosses(&operator, &robot, "STRIDE_STOP", 20.0),
        "the operator's bridge never joined"
    );
    let plan = FootstepPlanT {
        request_id: 7,
        step_number: 3,
        status: FootstepPlanT::STATUS_OK,
        detail: "a plan over TLS".into(),
        num_steps: 3,
        steps: (0..3)
            .map(|i| FootstepT {
                step_number: 4 + i,
                swing_height: 0.03,
                ..Default::default()
            })
            .collect(),
        cost: 1.25,
        ..Default::default()
    };
    let (tx, rx) = std::sync::mpsc::channel();
    let _sub = robot
        .subscribe("FOOTSTEP_PLAN", move |_, m: FootstepPlanT| {
            let _ = tx.send(m);
        })
        .unwrap();
    operator.publish("FOOTSTEP_PLAN", &plan).unwrap();
    let mut got = None;
    stride_tests::handle_until(&robot, Duration::from_secs(10), || {
        got = got.take().or_else(|| rx.try_recv().ok());
        got.is_some()
    });
    assert_eq!(got.as_ref(), Some(&plan), "the plan did not cross whole");
}

/// Regression: the shipped link was Zenoh's TLS over TCP, whose reader and writer share one
/// TLS stream unguarded (eclipse-zenoh/zenoh#2557). With messages flowing both ways the link
/// failed every second or so ("handshake not complete"), Zenoh opened a new one, and what was
/// in flight was lost: the bench's streams stalled with most messages unacknowledged (and the
/// walk through two routed bridges once stood still in CI, its steps not reported back). Over the link as shipped (QUIC, certificates both
/// ways, the operator's password), a stream answered message by message crosses whole; over
/// the old link this test stalled within the first 40 of 4000 messages.
#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn a_stream_answered_message_by_message_crosses_the_secured_link_whole() {
    require_sandbox();
    let dir = tempfile::tempdir().unwrap();
    let certs = dir.path().join("certs");
    credentials(&certs, &["127.0.0.1"]);
    let (robot_url, op_url) = (udpm_url(7866), udpm_url(7867));
    let endpoint = "quic/127.0.0.1:7459";
    let channels = "UP|DOWN";
    let _robot = robot_side(dir.path(), &certs, &robot_url, endpoint, channels);
    let _operator = operator_side(dir.path(), &certs, &op_url, endpoint, channels);
    let (robot, operator) = (
        lcm::Lcm::new(&robot_url).unwrap(),
        lcm::Lcm::new(&op_url).unwrap(),
    );
    assert!(
        crosses(&operator, &robot, "UP", 20.0) && crosses(&robot, &operator, "DOWN", 20.0),
        "the bridges never joined"
    );
    drop(operator);
    // The operator streams N messages with at most 8 unanswered, the robot answers each at
    // once (as lcm_perf's sink acknowledges): both directions busy all the time.
    const N: u64 = 4000;
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let echo = {
        let (stop, url) = (stop.clone(), robot_url.clone());
        std::thread::spawn(move || {
            let bus = lcm::Lcm::new(&url).unwrap();
            let p = bus.publisher();
            let sub = bus
                .subscribe_raw("UP", move |_, data| {
                    let _ = p.publish_raw("DOWN", data);
                })
                .unwrap();
            sub.set_queue_capacity(0).unwrap();
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                let _ = bus.handle_timeout(Duration::from_millis(50));
            }
        })
    };
    drop(robot);
    // The robot's side is listening once a message comes back.
    let bus = lcm::Lcm::new(&op_url).unwrap();
    let answered = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
    let a = answered.clone();
    let sub = bus
        .subscribe_raw("DOWN", move |_, data| {
            if data.len() == 100 {
                a.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
        })
        .unwrap();
    sub.set_queue_capacity(0).unwrap();
    let mut buf = [0u8; 100];
    let mut sent = 0u64;
    while answered.load(std::sync::atomic::Ordering::Relaxed) < N {
        while sent < N && sent < answered.load(std::sync::atomic::Ordering::Relaxed) + 8 {
            buf[..8].copy_from_slice(&sent.to_le_bytes());
            bus.publish_raw("UP", &buf).unwrap();
            sent += 1;
        }
        // A message lost on the way stalls the stream for good.
        if !bus.handle_timeout(Duration::from_secs(2)).unwrap() {
            break;
        }
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    echo.join().unwrap();
    assert_eq!(
        answered.load(std::sync::atomic::Ordering::Relaxed),
        N,
        "the stream stalled over {endpoint}: a message or its answer was lost"
    );
}

/// A bridge refuses plain TCP beyond the loopback in one line, unless told `insecure = true`.
#[test]
fn a_bridge_refuses_plain_tcp_beyond_the_loopback_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("open.toml");
    std::fs::write(
        &cfg,
        "bus = \"robot\"\n[zenoh]\nlisten = [\"tcp/0.0.0.0:7447\"]\n",
    )
    .unwrap();
    let out = std::process::Command::new(bin("stride-zenoh-bridge"))
        .args(["--lcm-url", "memq://", "--config"])
        .arg(&cfg)
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("plain TCP beyond this computer"), "{err}");
}
