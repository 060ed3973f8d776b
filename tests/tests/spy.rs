//! stride-spy against a live bus and against an lcm-logger recording.

use std::process::Command;
use std::time::{Duration, Instant};

use lcm::Lcm;
use stride_lcmtypes::stride::{HeaderT, ImuT, PingT};
use stride_tests::{bin, require_sandbox, udpm_url, Proc};

fn ping(seq: i64) -> PingT {
    PingT {
        header: HeaderT {
            sequence: seq,
            ..Default::default()
        },
        payload_size: 2,
        payload: vec![9, 8],
        ..Default::default()
    }
}

/// Publishes until the process exits by itself (or 20 s pass); returns its stdout.
fn publish_until_done(lcm: &Lcm, proc: Proc, mut publish: impl FnMut(&Lcm, i64)) -> String {
    let start = Instant::now();
    let mut i = 0;
    let handle = std::thread::spawn(move || proc.wait(Duration::from_secs(20)));
    while !handle.is_finished() && start.elapsed() < Duration::from_secs(20) {
        publish(lcm, i);
        i += 1;
        std::thread::sleep(Duration::from_millis(50));
    }
    let (st, out) = handle.join().unwrap();
    assert!(st.success(), "{out}");
    out
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn echo_prints_decoded_json_lines() {
    require_sandbox();
    let url = udpm_url(7741);
    let lcm = Lcm::new(&url).unwrap();
    let mut c = Command::new(bin("stride-spy"));
    c.args([
        "--lcm-url",
        &url,
        "echo",
        "--channel",
        "SPY_P.*",
        "--count",
        "3",
    ]);
    let out = publish_until_done(&lcm, Proc::spawn(c), |lcm, i| {
        lcm.publish("SPY_PING", &ping(i)).unwrap();
        lcm.publish_raw("OTHER", b"ignored").unwrap();
    });
    let lines: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect();
    assert_eq!(lines.len(), 3, "{out}");
    for l in &lines {
        assert_eq!(l["channel"], "SPY_PING");
        assert_eq!(l["type"], "stride.ping_t");
        assert_eq!(l["message"]["payload"], serde_json::json!([9, 8]));
    }
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn echo_keeps_nan_and_infinities_apart_in_declaration_order() {
    require_sandbox();
    let url = udpm_url(7744);
    let lcm = Lcm::new(&url).unwrap();
    let mut c = Command::new(bin("stride-spy"));
    c.args([
        "--lcm-url",
        &url,
        "echo",
        "--channel",
        "SPY_IMU",
        "--count",
        "2",
    ]);
    let imu = ImuT {
        orientation: [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.5],
        temperature: f32::NAN,
        ..Default::default()
    };
    let out = publish_until_done(&lcm, Proc::spawn(c), |lcm, _| {
        lcm.publish("SPY_IMU", &imu).unwrap();
    });
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    for l in lines {
        let v: serde_json::Value = serde_json::from_str(l).expect("a JSON line");
        let m = &v["message"];
        assert_eq!(
            m["orientation"],
            serde_json::json!(["NaN", "inf", "-inf", 0.5]),
            "{l}"
        );
        assert_eq!(m["temperature"], "NaN", "{l}");
        // Parsed maps may sort their keys: the order is read off the line.
        let at = |name: &str| l.find(&format!("\"{name}\":")).unwrap();
        let members = [
            "header",
            "orientation",
            "angular_velocity",
            "linear_acceleration",
            "temperature",
        ];
        assert!(
            members.windows(2).all(|w| at(w[0]) < at(w[1])),
            "declaration order: {l}"
        );
        assert!(
            l.starts_with(r#"{"channel":"SPY_IMU","utime":"#),
            "channel, utime, type, message: {l}"
        );
    }
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn list_shows_channels_rates_and_types() {
    require_sandbox();
    let url = udpm_url(7742);
    let lcm = Lcm::new(&url).unwrap();
    let mut c = Command::new(bin("stride-spy"));
    c.args(["--lcm-url", &url, "list", "--duration", "2.5"]);
    let out = publish_until_done(&lcm, Proc::spawn(c), |lcm, i| {
        lcm.publish("SPY_LIST", &ping(i)).unwrap();
    });
    let row = out
        .lines()
        .rev()
        .find(|l| l.starts_with("SPY_LIST"))
        .unwrap_or_else(|| panic!("no SPY_LIST row in:\n{out}"));
    assert!(row.contains("stride.ping_t"), "{row}");
    // The rate is over the spy's own window of at least a second, so whatever the machine
    // did to either side's timing it is above zero and at most the events counted in all.
    let field = |i: usize| -> f64 { row.split_whitespace().nth(i).unwrap().parse().unwrap() };
    let (events, rate) = (field(1), field(2));
    assert!(events >= 2.0, "{row}");
    assert!(rate > 0.0 && rate <= events, "{row}");
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn reads_and_exports_an_lcm_logger_recording() {
    require_sandbox();
    let url = udpm_url(7743);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rec.lcmlog");
    let logger = stride_tests::lcm_logger(&url, "SPY_.*", &path, "SPY_PROBE");
    let lcm = Lcm::new(&url).unwrap();
    for i in 0..10 {
        lcm.publish("SPY_REC", &ping(i)).unwrap();
        std::thread::sleep(Duration::from_millis(5));
    }
    stride_tests::wait_logged(&url, "SPY_PROBE", &path, &["SPY_REC"], 10);
    let (st, _) = logger.interrupt();
    assert!(st.success());

    let out = Command::new(bin("stride-spy"))
        .args(["list", "--log"])
        .arg(&path)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(
        text.lines()
            .any(|l| l.starts_with("SPY_REC") && l.contains(" 10 ") && l.contains("stride.ping_t")),
        "{text}"
    );

    let csv_dir = dir.path().join("csv");
    let out = Command::new(bin("stride-spy"))
        .arg("export")
        .arg(&path)
        .arg("--out")
        .arg(&csv_dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(csv_dir.join("SPY_REC.csv")).unwrap();
    assert_eq!(csv.lines().count(), 11, "{csv}");
    let columns = csv.lines().next().unwrap();
    assert!(
        columns.starts_with("event,log_utime,header.utime,header.sequence,header.frame,sent_utime,echoed_by,payload_size,payload[0],payload[1]"),
        "declaration order: {columns}"
    );
}
