//! stride-zenoh-bridge between two LCM buses of one machine (two ports, no multicast between
//! them), over Zenoh on loopback TCP.

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
