//! Cross-process tests over `udpm://` inside the private network namespace, and with the
//! stock LCM tools (lcm-logger, lcm-logplayer).

use std::process::Command;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use lcm::{Lcm, LogReader, LogWriter, Message};
use stride_lcmtypes::stride::{HeaderT, PingT};
use stride_tests::{bin, handle_until, require_sandbox, udpm_url, Proc};

fn ping(seq: i64, size: usize) -> PingT {
    PingT {
        header: HeaderT {
            utime: 1_700_000_000_000_000 + seq,
            sequence: seq,
            frame: "test".into(),
        },
        sent_utime: seq,
        echoed_by: String::new(),
        payload_size: size as i32,
        payload: (0..size).map(|i| (i * 7 + seq as usize) as u8).collect(),
    }
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn two_process_round_trip_with_stride_apps() {
    require_sandbox();
    let url = udpm_url(7711);
    let mut echo = Command::new(bin("stride-echo"));
    echo.args(["--lcm-url", &url, "--log-level", "warn"]);
    let echo = Proc::spawn(echo);
    stride_tests::wait_running(&url, "stride-echo");
    stride_tests::ping_all_echoed(&url, 50, 200);
    let (st, out) = echo.interrupt();
    assert!(st.success(), "stride-echo did not shut down cleanly: {out}");
    assert!(out.contains("echoed 50 pings"), "{out}");
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn multi_megabyte_message_crosses_processes_intact() {
    require_sandbox();
    let url = udpm_url(7712);
    let peer = {
        let mut c = Command::new(bin("lcm-peer"));
        c.args([
            "--lcm-url",
            &url,
            "echo",
            "--channel",
            "BIG",
            "--reply",
            "BIG_BACK",
        ]);
        Proc::spawn(c)
    };
    let lcm = Lcm::new(&url).unwrap();
    let msg = ping(1, 3 * 1024 * 1024 + 12345);
    let got: Arc<Mutex<Option<PingT>>> = Arc::default();
    let g = got.clone();
    let sub = lcm
        .subscribe("BIG_BACK", move |_, m: PingT| {
            *g.lock().unwrap() = Some(m);
        })
        .unwrap();
    // The peer may not be subscribed yet: send until the echo comes back.
    let deadline = Instant::now() + Duration::from_secs(20);
    while got.lock().unwrap().is_none() && Instant::now() < deadline {
        lcm.publish("BIG", &msg).unwrap();
        handle_until(&lcm, Duration::from_millis(500), || {
            got.lock().unwrap().is_some()
        });
    }
    let back = got
        .lock()
        .unwrap()
        .take()
        .expect("the 3 MB message never came back");
    assert_eq!(back, msg);
    assert_eq!(sub.stats().decode_errors, 0);
    let (st, out) = peer.wait(Duration::from_secs(10));
    assert!(st.success(), "{out}");
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn lcm_logger_log_is_read_by_our_crate() {
    require_sandbox();
    let url = udpm_url(7713);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rec.lcmlog");
    let logger = stride_tests::lcm_logger(&url, "REC_.*", &path, "REC_PROBE");
    let lcm = Lcm::new(&url).unwrap();
    for i in 0..20 {
        lcm.publish("REC_PING", &ping(i, 64)).unwrap();
        lcm.publish_raw("REC_RAW", &[i as u8; 10]).unwrap();
        std::thread::sleep(Duration::from_millis(2));
    }
    stride_tests::wait_logged(&url, "REC_PROBE", &path, &["REC_PING", "REC_RAW"], 20);
    let (st, out) = logger.interrupt();
    assert!(st.success(), "lcm-logger: {st:?} {out}");
    let events: Vec<_> = LogReader::open(&path).unwrap().collect();
    let pings: Vec<PingT> = events
        .iter()
        .filter(|e| e.channel == "REC_PING")
        .map(|e| PingT::decode(&e.data).expect("logged ping decodes"))
        .collect();
    assert_eq!(pings.len(), 20);
    assert_eq!(pings[13], ping(13, 64));
    assert_eq!(events.iter().filter(|e| e.channel == "REC_RAW").count(), 20);
    assert!(events.windows(2).all(|w| w[0].number + 1 == w[1].number));
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn our_log_is_replayed_by_lcm_logplayer_into_our_subscriber() {
    require_sandbox();
    let url = udpm_url(7714);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ours.lcmlog");
    let mut w = LogWriter::create(&path).unwrap();
    // Lead-in events give lcm-logplayer's subscriber time to come up before the real ones.
    let t0 = 1_700_000_000_000_000i64;
    for i in 0..30 {
        w.write(t0 + i * 10_000, "WARMUP", b"w").unwrap();
    }
    for i in 0..25i64 {
        let bytes = ping(i, 100 + i as usize).encode().unwrap();
        w.write(t0 + 300_000 + i * 1000, "REPLAY", &bytes).unwrap();
    }
    drop(w);
    let lcm = Lcm::new(&url).unwrap();
    let got = Arc::new(Mutex::new(Vec::new()));
    let g = got.clone();
    let sub = lcm
        .subscribe("REPLAY", move |_, m: PingT| g.lock().unwrap().push(m))
        .unwrap();
    sub.set_queue_capacity(1000).unwrap();
    let player = {
        let mut c = Command::new("lcm-logplayer");
        c.args(["-l", &url, "-s", "1"]).arg(&path);
        Proc::spawn(c)
    };
    assert!(handle_until(&lcm, Duration::from_secs(10), || got
        .lock()
        .unwrap()
        .len()
        == 25));
    let got = got.lock().unwrap();
    for (i, m) in got.iter().enumerate() {
        assert_eq!(*m, ping(i as i64, 100 + i));
    }
    assert_eq!(sub.stats().lost, 0);
    drop(player);
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn a_subscriber_that_falls_behind_counts_what_it_lost() {
    require_sandbox();
    let url = udpm_url(7715);
    let rx = Lcm::new(&url).unwrap();
    let seqs = Arc::new(Mutex::new(Vec::new()));
    let s = seqs.clone();
    let sub = rx
        .subscribe("BURST", move |_, m: PingT| {
            s.lock().unwrap().push(m.header.sequence)
        })
        .unwrap();
    sub.set_queue_capacity(5).unwrap();
    let warm = Arc::new(AtomicU64::new(0));
    let w = warm.clone();
    let _warm = rx
        .subscribe_raw("BURST_WARMUP", move |_, _| {
            w.fetch_add(1, Ordering::Relaxed);
        })
        .unwrap();
    let tx = Lcm::new(&url).unwrap();
    // Make sure the receive side is up before the burst.
    assert!(handle_until(&rx, Duration::from_secs(5), || {
        tx.publish_raw("BURST_WARMUP", b"w").unwrap();
        warm.load(Ordering::Relaxed) > 0
    }));
    for i in 0..200 {
        tx.publish("BURST", &ping(i, 8)).unwrap();
    }
    std::thread::sleep(Duration::from_millis(300));
    rx.handle_pending().unwrap();
    // A later message reveals the gap the overflow left.
    tx.publish("BURST", &ping(200, 8)).unwrap();
    assert!(handle_until(&rx, Duration::from_secs(5), || seqs
        .lock()
        .unwrap()
        .contains(&200)));
    let st = sub.stats();
    let seqs = seqs.lock().unwrap();
    let delivered = seqs.len() as u64;
    assert!(
        delivered < 100,
        "the queue should have overflowed: {delivered} delivered"
    );
    assert!(st.lost > 0);
    // Every message from the first one seen to #200 is either delivered or counted lost.
    let first = seqs[0] as u64;
    assert_eq!(delivered + st.lost, 201 - first, "{st:?}, {seqs:?}");
    assert_eq!(rx.stats().lost, st.lost);
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn heartbeat_is_published_and_decodes() {
    require_sandbox();
    let url = udpm_url(7716);
    let lcm = Lcm::new(&url).unwrap();
    let got = Arc::new(Mutex::new(Vec::new()));
    let g = got.clone();
    let _sub = lcm
        .subscribe(
            "STRIDE_STATUS",
            move |_, m: stride_lcmtypes::stride::NodeStatusT| g.lock().unwrap().push(m),
        )
        .unwrap();
    let echo = {
        let mut c = Command::new(bin("stride-echo"));
        c.args([
            "--lcm-url",
            &url,
            "--name",
            "echo-under-test",
            "--log-level",
            "warn",
        ]);
        Proc::spawn(c)
    };
    assert!(handle_until(&lcm, Duration::from_secs(5), || got
        .lock()
        .unwrap()
        .iter()
        .any(
            |m| m.state == stride_lcmtypes::stride::NodeStatusT::STATE_RUNNING
        )));
    let (st, _) = echo.interrupt();
    assert!(st.success());
    assert!(handle_until(&lcm, Duration::from_secs(5), || got
        .lock()
        .unwrap()
        .iter()
        .any(
            |m| m.state == stride_lcmtypes::stride::NodeStatusT::STATE_STOPPING
        )));
    let got = got.lock().unwrap();
    assert!(got.iter().all(|m| m.node == "echo-under-test" && m.pid > 0));
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn a_local_bus_keeps_its_channels_off_the_shared_one() {
    require_sandbox();
    let shared_url = udpm_url(7721);
    let local_url = udpm_url(7722);
    let both = Lcm::with_local(
        &shared_url,
        &local_url,
        &["JOINT_.*".into(), "CAN_.*".into()],
    )
    .unwrap();
    assert_eq!(
        both.local_bus(),
        Some((
            local_url.as_str(),
            &["JOINT_.*".to_string(), "CAN_.*".to_string()][..]
        ))
    );
    // Plain instances on each bus see what crosses it.
    let seen = |url: &str| {
        let lcm = Lcm::new(url).unwrap();
        let log = Arc::new(Mutex::new(Vec::<String>::new()));
        let l = log.clone();
        let sub = lcm
            .subscribe_raw(".*", move |info, _| {
                l.lock().unwrap().push(info.channel.into())
            })
            .unwrap();
        (lcm, sub, log)
    };
    let (on_shared, _s1, shared_log) = seen(&shared_url);
    let (on_local, _s2, local_log) = seen(&local_url);
    // The routed instance hears both buses, each subscription on its own.
    let heard = Arc::new(Mutex::new(Vec::<String>::new()));
    let subs: Vec<_> = ["JOINT_STATE", "PLAN"]
        .iter()
        .map(|ch| {
            let h = heard.clone();
            both.subscribe(ch, move |info, _: PingT| {
                h.lock().unwrap().push(info.channel.into())
            })
            .unwrap()
        })
        .collect();
    for i in 0..3 {
        both.publish("JOINT_STATE", &ping(i, 16)).unwrap();
        both.publish("PLAN", &ping(i, 16)).unwrap();
        on_local.publish("JOINT_STATE", &ping(10 + i, 16)).unwrap();
        on_shared.publish("PLAN", &ping(10 + i, 16)).unwrap();
    }
    let deadline = Instant::now() + Duration::from_secs(3);
    while Instant::now() < deadline && heard.lock().unwrap().len() < 12 {
        both.handle_timeout(Duration::from_millis(20)).unwrap();
        on_shared.handle_timeout(Duration::ZERO).unwrap();
        on_local.handle_timeout(Duration::ZERO).unwrap();
    }
    handle_until(&on_shared, Duration::from_millis(200), || false);
    handle_until(&on_local, Duration::from_millis(200), || false);
    let count = |log: &Mutex<Vec<String>>, ch: &str| {
        log.lock()
            .unwrap()
            .iter()
            .filter(|c| c.as_str() == ch)
            .count()
    };
    assert_eq!(
        count(&heard, "JOINT_STATE"),
        6,
        "{:?}",
        heard.lock().unwrap()
    );
    assert_eq!(count(&heard, "PLAN"), 6, "{:?}", heard.lock().unwrap());
    assert_eq!(
        count(&shared_log, "JOINT_STATE"),
        0,
        "a local channel crossed"
    );
    assert_eq!(count(&shared_log, "PLAN"), 6);
    assert_eq!(count(&local_log, "JOINT_STATE"), 6);
    assert_eq!(count(&local_log, "PLAN"), 0, "a shared channel went local");
    assert_eq!(both.stats().published, 6);
    drop(subs);
    // A pattern that is no regular expression is one error naming it.
    let e = Lcm::with_local(&shared_url, &local_url, &["JOINT_(".into()]).unwrap_err();
    assert!(e.to_string().contains("JOINT_("), "{e}");
}

/// How many UDP sockets of this network namespace are bound to `port`.
fn bound_to(port: u16) -> usize {
    let table = std::fs::read_to_string("/proc/net/udp").unwrap();
    let suffix = format!(":{port:04X}");
    table
        .lines()
        .skip(1)
        .filter(|l| {
            l.split_whitespace()
                .nth(1)
                .is_some_and(|local| local.ends_with(&suffix))
        })
        .count()
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn a_bus_without_a_subscription_is_not_received() {
    // A process that only listens on its local bus (fake drives on their CAN bus) woke for
    // every message of the shared one: waiting on both asked liblcm for the shared bus's
    // descriptor, which sets up its receiving.
    require_sandbox();
    let (shared_url, local_url) = (udpm_url(7723), udpm_url(7724));
    let both = Lcm::with_local(&shared_url, &local_url, &["CAN_.*".into()]).unwrap();
    let heard = Arc::new(AtomicU64::new(0));
    let h = heard.clone();
    let _can = both
        .subscribe("CAN_TX", move |_, _: PingT| {
            h.fetch_add(1, Ordering::Relaxed);
        })
        .unwrap();
    both.publish("STATUS", &ping(0, 16)).unwrap();
    both.publish("CAN_TX", &ping(1, 16)).unwrap();
    handle_until(&both, Duration::from_secs(3), || {
        heard.load(Ordering::Relaxed) == 1
    });
    assert_eq!(heard.load(Ordering::Relaxed), 1);
    assert_eq!(bound_to(7724), 1, "the local bus receives");
    assert_eq!(bound_to(7723), 0, "the shared bus is received for nothing");
    // A subscription on the shared bus: it is received and handled.
    let h = heard.clone();
    let _status = both
        .subscribe("STATUS", move |_, _: PingT| {
            h.fetch_add(10, Ordering::Relaxed);
        })
        .unwrap();
    both.handle_timeout(Duration::from_millis(10)).unwrap();
    assert_eq!(bound_to(7723), 1);
    both.publish("STATUS", &ping(2, 16)).unwrap();
    handle_until(&both, Duration::from_secs(3), || {
        heard.load(Ordering::Relaxed) == 11
    });
    assert_eq!(heard.load(Ordering::Relaxed), 11);
}
