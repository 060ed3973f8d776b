//! What every executable does with its command line, its errors and its stdout: the habits
//! a user expects of a Unix tool. All on `memq://`, so no network is touched.

use std::io::Read;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use stride_tests::bin;

/// The apps that join the bus, each with arguments that parse.
const NODES: &[(&str, &[&str])] = &[
    ("stride-echo", &[]),
    ("stride-ping", &["--count", "1"]),
    ("stride-footstep-planner", &[]),
    ("stride-joint-move", &["--move", "j=0"]),
    ("stride-usb2can", &["--device", "slcan:/dev/null"]),
    ("stride-elmo-bridge", &[]),
    ("stride-dynamixel-bridge", &[]),
    ("stride-arduino-link", &[]),
];

/// Runs `name` to its end (at most 20 s), with RUST_BACKTRACE=1 as on these machines; returns
/// (exit code, stdout, stderr).
fn run(name: &str, args: &[&str]) -> (Option<i32>, String, String) {
    let mut child = Command::new(bin(name))
        .args(["--lcm-url", "memq://"])
        .args(args)
        .env("RUST_BACKTRACE", "1")
        .env_remove("RUST_LOG")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("starting {name}: {e}"));
    let deadline = Instant::now() + Duration::from_secs(20);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("{name} {args:?} did not end within 20 s");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// An error as users should see it: status 1, one line naming the program, no backtrace.
fn assert_one_line_error(name: &str, (code, _, err): &(Option<i32>, String, String)) -> String {
    assert_eq!(*code, Some(1), "{name}: {err}");
    // Log lines (timestamped) may come first; the error itself is one line.
    let is_log = |l: &&str| l.len() > 20 && l.starts_with("20") && l.as_bytes()[10] == b'T';
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| !l.trim().is_empty() && !is_log(l))
        .collect();
    assert_eq!(lines.len(), 1, "{name} printed more than one line:\n{err}");
    assert!(lines[0].starts_with(&format!("{name}: error: ")), "{err}");
    assert!(
        !err.contains("backtrace") && !err.contains("panicked"),
        "{err}"
    );
    lines[0].to_owned()
}

#[test]
fn an_unknown_log_level_is_an_error_in_every_app() {
    for (name, args) in NODES {
        let mut a = args.to_vec();
        a.extend(["--log-level", "nonsense=+=="]);
        let line = assert_one_line_error(name, &run(name, &a));
        assert!(line.contains("--log-level"), "{line}");
    }
}

#[test]
fn apps_that_take_no_config_refuse_one() {
    let takes_none = [
        "stride-echo",
        "stride-ping",
        "stride-joint-move",
        "stride-usb2can",
    ];
    for (name, args) in NODES.iter().filter(|(n, _)| takes_none.contains(n)) {
        let mut a = args.to_vec();
        a.extend(["--config", "/nonexistent/app.toml"]);
        let line = assert_one_line_error(name, &run(name, &a));
        assert!(line.contains("takes no configuration"), "{line}");
    }
}

#[test]
fn a_bridge_without_config_says_it_needs_one_and_where_to_look() {
    for (name, _) in &NODES[5..] {
        let line = assert_one_line_error(name, &run(name, &[]));
        assert!(
            line.contains("--config") && line.contains("config/robots/"),
            "{line}"
        );
    }
}

#[test]
fn a_missing_config_file_is_one_line_without_a_backtrace() {
    for (name, _) in &NODES[5..] {
        let line = assert_one_line_error(name, &run(name, &["--config", "/nonexistent/r.toml"]));
        assert!(line.contains("/nonexistent/r.toml"), "{line}");
    }
}

#[test]
fn the_planners_shipped_config_is_taken_and_a_bad_one_refused() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("p.toml");
    std::fs::write(&bad, "max_steps = 0\n").unwrap();
    let line = assert_one_line_error(
        "stride-footstep-planner",
        &run(
            "stride-footstep-planner",
            &["--config", bad.to_str().unwrap()],
        ),
    );
    assert!(line.contains("max_steps"), "{line}");
    let shipped = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../config/footstep-planner.toml"
    );
    let text = std::fs::read_to_string(shipped).unwrap();
    let cfg: stride_footstep_planner::app::PlannerConfig = toml::from_str(&text).unwrap();
    assert_eq!(
        cfg,
        Default::default(),
        "the shipped file shows the defaults"
    );
}

#[test]
fn a_failing_client_is_one_line_without_a_backtrace() {
    // Nobody answers on memq://: the ask and the move end with their reason, once.
    let ask = run(
        "stride-footstep-planner",
        &["--ask", "2,0", "--wait-s", "0.3"],
    );
    let line = assert_one_line_error("stride-footstep-planner", &ask);
    assert!(line.contains("no answer"), "{line}");
    let nan = run("stride-joint-move", &["--move", "left_knee=nan"]);
    let line = assert_one_line_error("stride-joint-move", &nan);
    assert!(line.contains("finite"), "{line}");
}

/// Starts `name` with its stdout a pipe whose reader is already gone.
fn with_closed_stdout(name: &str, args: &[&str]) -> std::process::Child {
    let mut child = Command::new(bin(name))
        .args(args)
        .env("RUST_BACKTRACE", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    child
}

fn wait_quiet(name: &str, mut child: std::process::Child, within: Duration) {
    let deadline = Instant::now() + within;
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("{name} did not notice its closed stdout within {within:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    let status = child.wait().unwrap();
    assert!(status.success(), "{name}: {status}: {err}");
    assert!(
        !err.contains("Broken pipe") && !err.contains("panicked") && !err.contains("error:"),
        "{name}: {err}"
    );
}

#[test]
fn a_closed_stdout_ends_a_program_quietly() {
    let scenes = concat!(env!("CARGO_MANIFEST_DIR"), "/../config/scenes/archie");
    let out = tempfile::tempdir().unwrap();
    let plan = with_closed_stdout(
        "stride-plan",
        &[scenes, "--no-svg", "--out", out.path().to_str().unwrap()],
    );
    wait_quiet("stride-plan", plan, Duration::from_secs(60));
    // A live echo that receives nothing still notices the reader has gone.
    let spy = with_closed_stdout("stride-spy", &["echo", "--lcm-url", "memq://"]);
    wait_quiet("stride-spy", spy, Duration::from_secs(3));
    // A node with nothing to print stops as on SIGINT.
    let echo = with_closed_stdout("stride-echo", &["--lcm-url", "memq://"]);
    wait_quiet("stride-echo", echo, Duration::from_secs(3));
}

#[test]
fn the_arduino_link_says_on_its_console_when_its_port_is_missing() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("link.toml");
    let shipped = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../config/robots/archie-arduino-left-leg.toml"
    ))
    .unwrap();
    std::fs::write(
        &cfg,
        shipped.replace("port = \"sim\"", "port = \"/dev/ttyNONE9\""),
    )
    .unwrap();
    let mut child = Command::new(bin("stride-arduino-link"))
        .args(["--lcm-url", "memq://", "--config", cfg.to_str().unwrap()])
        .env_remove("RUST_LOG")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    // SAFETY: kill(2) on our own child.
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert!(child.wait().unwrap().success(), "{err}");
    let said: Vec<&str> = err
        .lines()
        .filter(|l| l.contains("/dev/ttyNONE9"))
        .collect();
    // Said once, not at every retry.
    assert_eq!(said.len(), 1, "{err}");
    assert!(
        said[0].contains("WARN") && said[0].contains("retrying"),
        "{err}"
    );
}

#[test]
fn stride_report_says_in_one_line_what_it_cannot_read() {
    let out = Command::new(bin("stride-report"))
        .arg("/nonexistent/walk.lcmlog")
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    let line = assert_one_line_error("stride-report", &(out.status.code(), String::new(), err));
    assert!(
        line.contains("cannot read /nonexistent/walk.lcmlog"),
        "{line}"
    );
}
