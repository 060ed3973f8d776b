//! The node runtime on an in-process bus.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use stride_lcmtypes::stride::NodeStatusT;
use stride_node::{Node, NodeArgs};

#[test]
fn heartbeat_reports_state_and_counters_then_stopping() {
    let args = NodeArgs {
        lcm_url: "memq://".into(),
        name: Some("unit-node".into()),
        log_level: "warn".into(),
        ..NodeArgs::default()
    };
    let node = Node::start("default-name", &args).unwrap();
    assert_eq!(node.name(), "unit-node");
    let got = Arc::new(Mutex::new(Vec::new()));
    let g = got.clone();
    let _sub = node
        .lcm()
        .subscribe(stride_node::STATUS_CHANNEL, move |_, m: NodeStatusT| {
            g.lock().unwrap().push(m)
        })
        .unwrap();
    node.set_health(NodeStatusT::STATE_DEGRADED, "one sensor missing");
    // Wait for a DEGRADED beat after the first one (which may have gone out before).
    let first = std::sync::OnceLock::new();
    let later_degraded = |m: &NodeStatusT| {
        let first = *first.get_or_init(|| m.header.sequence);
        m.state == NodeStatusT::STATE_DEGRADED && m.header.sequence > first
    };
    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline && !got.lock().unwrap().iter().any(later_degraded) {
        node.lcm()
            .handle_timeout(Duration::from_millis(50))
            .unwrap();
    }
    let beats = got.lock().unwrap().clone();
    let degraded = beats
        .iter()
        .find(|m| later_degraded(m))
        .expect("a DEGRADED heartbeat");
    assert_eq!(degraded.node, "unit-node");
    assert_eq!(degraded.detail, "one sensor missing");
    assert_eq!(degraded.pid, std::process::id() as i32);
    assert!(degraded.messages_published >= 1);
    assert!(beats
        .windows(2)
        .all(|w| w[1].header.sequence == w[0].header.sequence + 1));
}

#[test]
fn spin_returns_when_shutdown_is_requested() {
    let args = NodeArgs {
        lcm_url: "memq://".into(),
        log_level: "warn".into(),
        ..NodeArgs::default()
    };
    let node = Node::start("spinner", &args).unwrap();
    let mut ticks = 0;
    node.spin_with(Duration::from_millis(5), || {
        ticks += 1;
        if ticks == 3 {
            node.request_shutdown();
        }
        Ok(())
    })
    .unwrap();
    assert_eq!(ticks, 3);
    assert!(!node.running());
}

#[test]
fn a_bad_url_fails_with_the_url_in_the_message() {
    let args = NodeArgs {
        lcm_url: "nope://".into(),
        ..NodeArgs::default()
    };
    let err = Node::start("x", &args).unwrap_err().to_string();
    assert!(err.contains("nope://"), "{err}");
}
