//! Helpers for the cross-process tests: the sandbox check, unique bus URLs, and child
//! processes that are stopped when the test ends; and the Rust code generated from the
//! feature-test types in `tests/lcm/` and `tests/lcm-const-dims/`.

/// Types exercising every feature of the LCM type language (`tests/lcm/`).
#[allow(clippy::all)]
pub mod features {
    include!(concat!(env!("OUT_DIR"), "/feature_types.rs"));
}

/// Arrays sized by constants, which only liblcm 1.4+ accepts (`tests/lcm-const-dims/`).
#[allow(clippy::all)]
pub mod const_dims {
    include!(concat!(env!("OUT_DIR"), "/const_dims_types.rs"));
}

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Handles `lcm`'s messages until `done` holds or `timeout` passes; whether `done` held.
pub fn handle_until(lcm: &lcm::Lcm, timeout: Duration, mut done: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        if done() {
            return true;
        }
        lcm.handle_timeout(Duration::from_millis(20)).unwrap();
    }
    done()
}

/// Fails the test unless it runs inside the private network namespace `scripts/test` makes
/// (multicast stays on its `lo`).
///
/// Tests that use `udpm://` are `#[ignore]`d, so a plain `cargo test` reports them as ignored
/// rather than passed; `scripts/test` runs them with `--include-ignored` inside the namespace
/// and fails if any test was ignored there. Run by hand on the host, they stop here: multicast
/// must never reach the host's real interfaces.
pub fn require_sandbox() {
    assert!(
        std::env::var_os("STRIDE_NETNS").is_some(),
        "this test sends multicast: run it through scripts/test (a private network namespace), \
         never on the host's interfaces"
    );
}

/// A `udpm://` URL on its own port, so tests running at once do not hear each other
/// (liblcm 1.3.1 binds the port on every group address).
pub fn udpm_url(port: u16) -> String {
    format!("udpm://239.255.76.67:{port}?ttl=0&recv_buf_size=4194304")
}

/// Path of a workspace executable (built by `cargo build --workspace` before the tests run).
pub fn bin(name: &str) -> PathBuf {
    if let Some(p) = std::env::var_os(format!("CARGO_BIN_EXE_{name}")) {
        return p.into();
    }
    let exe = std::env::current_exe().expect("test executable path");
    let dir = exe
        .parent()
        .and_then(|d| d.parent())
        .expect("target directory");
    let p = dir.join(name);
    assert!(
        p.exists(),
        "{} not found: build the workspace first (cargo build --workspace --bins)",
        p.display()
    );
    p
}

/// A workspace executable on the bus `url`, logging warnings only.
pub fn on_bus(name: &str, url: &str) -> Command {
    let mut c = Command::new(bin(name));
    c.args(["--lcm-url", url, "--log-level", "warn"]);
    c
}

/// Starts the stock `lcm-logger` recording `channels` on `url` into `path`, and returns once
/// it records (a ping on `probe`, one of those channels, is in the file).
pub fn lcm_logger(url: &str, channels: &str, path: &std::path::Path, probe: &str) -> Proc {
    let mut c = Command::new("lcm-logger");
    // liblcm 1.3.1's lcm-logger rejects the short `-l`; the long form works everywhere.
    c.args(["-q", "-f", "-c", channels, "--flush-interval=10"])
        .arg(format!("--lcm-url={url}"))
        .arg(path);
    let p = Proc::spawn(c);
    // Ready when it records: a ping on `probe` (a channel it records) until one is in the file.
    // A fixed wait was not enough on a loaded machine: the logger subscribed late and missed
    // most of a test's messages.
    let lcm = lcm::Lcm::new(url).expect("an LCM for the probe");
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(20) {
        let _ = lcm.publish(probe, &stride_lcmtypes::stride::PingT::default());
        std::thread::sleep(Duration::from_millis(20));
        if std::fs::metadata(path).is_ok_and(|m| m.len() > 0) {
            return p;
        }
    }
    panic!("lcm-logger recorded nothing on {probe} within 20 s");
}

/// Waits until a message on `channel` of `url` satisfies `ready`: a process is ready when it
/// says so on the bus, never after a fixed sleep. Panics after `timeout` (a hang guard).
pub fn wait_for<M: lcm::Message + 'static>(
    url: &str,
    channel: &str,
    timeout: Duration,
    ready: impl Fn(&M) -> bool + Send + 'static,
) {
    let lcm = lcm::Lcm::new(url).expect("an LCM for the probe");
    let seen = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flag = seen.clone();
    let _sub = lcm
        .subscribe(channel, move |_, m: M| {
            if ready(&m) {
                flag.store(true, std::sync::atomic::Ordering::Relaxed);
            }
        })
        .expect("subscribing the probe");
    assert!(
        handle_until(&lcm, timeout, || seen
            .load(std::sync::atomic::Ordering::Relaxed)),
        "no ready message on {channel} within {timeout:?}"
    );
}

/// Waits for the heartbeat in which the stride node `name` reports itself running (its
/// subscriptions are made by then).
pub fn wait_running(url: &str, name: &str) {
    use stride_lcmtypes::stride::NodeStatusT;
    let name = name.to_string();
    wait_for(
        url,
        "STRIDE_STATUS",
        Duration::from_secs(20),
        move |s: &NodeStatusT| s.node == name && s.state == NodeStatusT::STATE_RUNNING,
    );
}

/// Waits until the LCM log at `path`, written by an `lcm-logger` on `url`, holds `count`
/// events on each of `channels`, rather than sleeping a fixed time. The logger flushes only as
/// new events arrive, so a ping goes to `probe` (a channel it records) at every look. Panics
/// after 20 s.
pub fn wait_logged(
    url: &str,
    probe: &str,
    path: &std::path::Path,
    channels: &[&str],
    count: usize,
) {
    let lcm = lcm::Lcm::new(url).expect("an LCM for the probe");
    let t0 = Instant::now();
    let mut seen = vec![0; channels.len()];
    while t0.elapsed() < Duration::from_secs(20) {
        let _ = lcm.publish(probe, &stride_lcmtypes::stride::PingT::default());
        std::thread::sleep(Duration::from_millis(20));
        if let Ok(r) = lcm::LogReader::open(path) {
            seen.fill(0);
            for e in r {
                if let Some(i) = channels.iter().position(|c| *c == e.channel) {
                    seen[i] += 1;
                }
            }
            if seen.iter().all(|&n| n >= count) {
                return;
            }
        }
    }
    panic!(
        "{} holds {seen:?} events on {channels:?}, not {count} each",
        path.display()
    );
}

/// The `p`-th percentile of `v` (sorted in place; NaN when empty), for the benchmarks.
pub fn percentile(v: &mut [f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[((p / 100.0) * (v.len() - 1) as f64).round() as usize]
}

/// Starts a fake-device process (`fake-can-rig`, `fake-dynamixel-chain`, `fake-due`) with
/// `args` on a pseudo-terminal whose path it writes into `dir`; returns the process and that
/// path once it is there.
pub fn pty_rig(dir: &std::path::Path, name: &str, args: &[&str]) -> (Proc, String) {
    let tag = args.join("_").replace(['/', ':', ',', ' '], "-");
    let pty_file = dir.join(format!("{name}-{tag}.pty"));
    let mut c = Command::new(bin(name));
    c.arg("--pty-file").arg(&pty_file).args(args);
    let p = Proc::spawn(c);
    (p, wait_pty(&pty_file))
}

/// Waits (up to 10 s) until a fake device has written its terminal's path to `pty_file`;
/// returns the path.
pub fn wait_pty(pty_file: &std::path::Path) -> String {
    let t0 = Instant::now();
    while std::fs::metadata(pty_file).map_or(true, |m| m.len() == 0) {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "{} never came",
            pty_file.display()
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(Duration::from_millis(50));
    std::fs::read_to_string(pty_file).unwrap()
}

/// Starts stride-usb2can on `url` for the SLCAN dongle on terminal `pty` as bus `bus`, its
/// frames logged to `candump`, with `extra` flags.
pub fn usb2can(url: &str, bus: &str, pty: &str, candump: &std::path::Path, extra: &[&str]) -> Proc {
    let mut c = Command::new(bin("stride-usb2can"));
    c.args(["--lcm-url", url, "--log-level", "error", "--bus-name", bus])
        .arg("--device")
        .arg(format!("slcan:{pty}"))
        .arg("--candump")
        .arg(candump)
        .args(extra);
    Proc::spawn(c)
}

/// A child process killed (SIGINT, then SIGKILL) when dropped.
#[derive(Debug)]
pub struct Proc {
    child: Option<Child>,
    name: String,
}

impl Proc {
    /// Starts `cmd` with stdout captured and stderr inherited.
    pub fn spawn(mut cmd: Command) -> Proc {
        let name = format!("{:?}", cmd.get_program());
        let child = cmd
            .stdout(Stdio::piped())
            .stdin(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("starting {name}: {e}"));
        Proc {
            child: Some(child),
            name,
        }
    }

    /// The process's scheduling policy (`libc::SCHED_OTHER`, `libc::SCHED_FIFO`, ...).
    pub fn scheduling(&self) -> i32 {
        let child = self.child.as_ref().expect("running");
        // SAFETY: sched_getscheduler(2) on our own child.
        unsafe { libc::sched_getscheduler(child.id() as i32) }
    }

    /// Sends a signal (e.g. `libc::SIGUSR1`) to the process.
    pub fn signal(&self, sig: i32) {
        if let Some(child) = &self.child {
            // SAFETY: plain kill(2) on our own child.
            unsafe { libc::kill(child.id() as i32, sig) };
        }
    }

    /// Sends SIGINT and waits (up to 10 s) for the exit; returns the status and stdout.
    pub fn interrupt(self) -> (std::process::ExitStatus, String) {
        if let Some(child) = &self.child {
            // SAFETY: plain kill(2) on our own child.
            unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
        }
        self.wait(Duration::from_secs(10))
    }

    /// Waits (up to `timeout`) for the process to exit by itself; returns status and stdout.
    pub fn wait(mut self, timeout: Duration) -> (std::process::ExitStatus, String) {
        let mut child = self.child.take().expect("running");
        let deadline = Instant::now() + timeout;
        while child.try_wait().expect("wait").is_none() {
            if Instant::now() > deadline {
                let _ = child.kill();
                panic!("{} did not finish within {timeout:?}", self.name);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let out = child.wait_with_output().expect("output");
        (
            out.status,
            String::from_utf8_lossy(&out.stdout).into_owned(),
        )
    }
}

/// Runs `stride-ping` on `url` (`count` pings at `rate` Hz), checks that every echo came back
/// and returns its output.
pub fn ping_all_echoed(url: &str, count: u32, rate: u32) -> String {
    let mut ping = Command::new(bin("stride-ping"));
    ping.args(["--lcm-url", url, "--linger", "3", "--log-level", "warn"])
        .args(["--count", &count.to_string(), "--rate", &rate.to_string()]);
    let (st, out) = Proc::spawn(ping).wait(Duration::from_secs(30));
    assert!(st.success(), "stride-ping failed: {out}");
    assert!(
        out.contains(&format!("{count} sent, {count} echoed (0 lost)")),
        "{out}"
    );
    out
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}
