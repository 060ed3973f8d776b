//! The deputy's supervision of its apps: each in its own process group, started when what it
//! depends on says RUNNING, its console lines tagged, logged and forwarded, restarted by its
//! policy with backoff and a cap, marked lost when its heartbeats stop, a system stop when a
//! critical one dies or goes silent, and the ordered shutdown: stage by stage, SIGINT, then
//! SIGTERM, then SIGKILL.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Write};
use std::os::unix::process::CommandExt;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::time::{Duration, Instant};

use stride_lcmtypes::stride::{LaunchAppT, LaunchConsoleT, NodeStatusT};

use crate::profile::{App, Backoff, OnFault, Profile, Restart};

/// A line an app wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Line {
    /// The app.
    pub app: String,
    /// LaunchConsoleT::STREAM_*.
    pub stream: i8,
    /// The text, without its newline.
    pub text: String,
}

/// Something the deputy must act on or tell.
#[derive(Debug, Clone, PartialEq)]
pub enum Note {
    /// A critical app died or went silent: stop the robot.
    SystemStop(String),
    /// An app changed state (for the log and an early status).
    Changed {
        /// The app.
        app: String,
        /// Its new state, LaunchAppT::STATE_*.
        state: i8,
        /// Why.
        detail: String,
    },
}

/// The last heartbeat of a node.
#[derive(Debug, Clone)]
struct Beat {
    at: Instant,
    status: NodeStatusT,
    /// The one before it, for the rates.
    previous: Option<(Instant, NodeStatusT)>,
}

/// One app's life.
struct Proc {
    app: App,
    state: i8,
    detail: String,
    child: Option<Child>,
    started: Option<Instant>,
    /// When the restart is due (state BACKOFF).
    due: Option<Instant>,
    restarts: u32,
    /// Restarts since it last ran long enough to start the backoff afresh.
    streak: u32,
    exit_code: i32,
    /// Stop it and do not restart it (an order, the shutdown).
    held: bool,
    /// While stopping: when SIGINT went out, and whether SIGTERM and SIGKILL did.
    stopping: Option<(Instant, bool, bool)>,
    /// CPU time (s) at the last sample, and when.
    cpu_sample: Option<(CpuTime, Instant)>,
    cpu: f64,
    memory: i64,
    log: Option<std::fs::File>,
}

/// Everything the deputy runs on its host.
pub struct Supervisor {
    profile: Profile,
    procs: Vec<Proc>,
    beats: BTreeMap<String, Beat>,
    lines_tx: Sender<Line>,
    lines: Receiver<Line>,
    log_dir: Option<PathBuf>,
    /// The log filter the apps are given (absent: their own default).
    log_level: Option<String>,
    /// The shutdown under way: the stage being stopped.
    shutdown: Option<u8>,
}

/// A system configuration value, or `default` when the system gives none.
fn sysconf(name: libc::c_int, default: i64) -> i64 {
    // SAFETY: sysconf has no preconditions.
    let v = unsafe { libc::sysconf(name) };
    if v > 0 {
        v as i64
    } else {
        default
    }
}

/// A process's CPU time so far, as /proc counts it.
#[derive(Debug, Clone, PartialEq)]
struct CpuTime {
    /// User + system time, s, in whole clock ticks (10 ms: a 1 s sample of a light app
    /// would read 0 % or 1 %); it keeps the time of threads that have ended.
    ticks: f64,
    /// The scheduler's own count, s, to the nanosecond, summed over the threads alive now
    /// (/proc/PID/task/*/schedstat), with their ids; None where the kernel keeps none.
    threads: Option<(f64, Vec<u32>)>,
}

impl CpuTime {
    /// The share of a core used between `earlier` and this, over `secs`: from the
    /// scheduler's count when every thread of then still runs, else from the ticks.
    fn share_since(&self, earlier: &CpuTime, secs: f64) -> f64 {
        let spent = match (&self.threads, &earlier.threads) {
            (Some((now, alive)), Some((then, before)))
                if before.iter().all(|t| alive.binary_search(t).is_ok()) =>
            {
                now - then
            }
            _ => self.ticks - earlier.ticks,
        };
        spent.max(0.0) / secs
    }
}

/// A process's CPU time and resident pages, from /proc.
fn proc_usage(pid: u32, ticks_per_s: f64) -> Option<(CpuTime, i64)> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command may hold spaces: the fields after its closing parenthesis.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let (utime, stime): (u64, u64) = (f.get(11)?.parse().ok()?, f.get(12)?.parse().ok()?);
    let rss: i64 = f.get(21)?.parse().ok()?;
    let time = CpuTime {
        ticks: (utime + stime) as f64 / ticks_per_s,
        threads: thread_times(pid),
    };
    Some((time, rss))
}

/// The time the live threads of `pid` have run, s, and their ids (sorted), from their
/// schedstat.
fn thread_times(pid: u32) -> Option<(f64, Vec<u32>)> {
    let mut ns = 0u64;
    let mut ids = Vec::new();
    for task in std::fs::read_dir(format!("/proc/{pid}/task")).ok()? {
        let task = task.ok()?;
        // A thread that ended since the listing is left out (the ids then differ).
        let Ok(text) = std::fs::read_to_string(task.path().join("schedstat")) else {
            continue;
        };
        ns += text.split_whitespace().next()?.parse::<u64>().ok()?;
        ids.push(task.file_name().to_str()?.parse().ok()?);
    }
    ids.sort_unstable();
    Some((ns as f64 / 1e9, ids))
}

/// Sends `sig` to the process group `pid` leads.
fn signal_group(pid: u32, sig: i32) {
    // SAFETY: kill has no memory preconditions; a group that is gone gives ESRCH, ignored.
    unsafe {
        libc::kill(-(pid as i32), sig);
    }
}

/// The name of a launch state.
pub fn state_word(s: i8) -> &'static str {
    match s {
        LaunchAppT::STATE_WAITING => "waiting",
        LaunchAppT::STATE_STARTING => "starting",
        LaunchAppT::STATE_RUNNING => "running",
        LaunchAppT::STATE_LOST => "lost",
        LaunchAppT::STATE_BACKOFF => "backoff",
        LaunchAppT::STATE_STOPPING => "stopping",
        LaunchAppT::STATE_EXITED => "exited",
        LaunchAppT::STATE_FAILED => "failed",
        LaunchAppT::STATE_FAULT => "FAULT",
        _ => "?",
    }
}

impl Supervisor {
    /// Supervises the apps of `profile` that run on `host` (None: every app, here); each
    /// app's console goes to `log_dir/<app>.log` as well.
    pub fn new(profile: Profile, host: Option<&str>, log_dir: Option<PathBuf>) -> Supervisor {
        let (lines_tx, lines) = channel();
        let procs = profile
            .apps
            .iter()
            .filter(|a| host.is_none_or(|h| a.host == h))
            .map(|a| Proc {
                app: a.clone(),
                state: LaunchAppT::STATE_WAITING,
                detail: String::new(),
                child: None,
                started: None,
                due: None,
                restarts: 0,
                streak: 0,
                exit_code: -1,
                held: false,
                stopping: None,
                cpu_sample: None,
                cpu: 0.0,
                memory: 0,
                log: None,
            })
            .collect();
        Supervisor {
            profile,
            procs,
            beats: BTreeMap::new(),
            lines_tx,
            lines,
            log_dir,
            log_level: None,
            shutdown: None,
        }
    }

    /// The log filter every app is started with (its own `--log-level` in the profile wins).
    pub fn set_log_level(&mut self, filter: &str) {
        self.log_level = Some(filter.to_owned());
    }

    /// The profile.
    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    /// Takes a heartbeat from the bus (of the profile's apps only: a bus full of other names
    /// grows nothing here).
    pub fn heartbeat(&mut self, status: NodeStatusT, now: Instant) {
        if !self.profile.apps.iter().any(|a| a.name == status.node) {
            return;
        }
        let previous = self.beats.remove(&status.node).map(|b| (b.at, b.status));
        self.beats.insert(
            status.node.clone(),
            Beat {
                at: now,
                status,
                previous,
            },
        );
    }

    /// Lines written since the last call.
    pub fn lines(&mut self) -> Vec<Line> {
        let lines: Vec<Line> = self.lines.try_iter().collect();
        for l in &lines {
            if let Some(p) = self.procs.iter_mut().find(|p| p.app.name == l.app) {
                if let Some(f) = &mut p.log {
                    let _ = writeln!(f, "{}", l.text);
                }
            }
        }
        lines
    }

    /// True when `name`'s heartbeat is fresh and says RUNNING (or DEGRADED: it runs) (an app without heartbeats:
    /// when its process runs here, or when it runs on another host).
    fn ready(&self, name: &str, now: Instant) -> bool {
        let app = self.profile.apps.iter().find(|a| a.name == name);
        if app.is_some_and(|a| !a.node) {
            return match self.procs.iter().find(|p| p.app.name == name) {
                Some(p) => p.child.is_some(),
                None => true,
            };
        }
        let fresh = Duration::from_secs_f64(self.profile.file.lost_after);
        self.beats.get(name).is_some_and(|b| {
            matches!(
                b.status.state,
                NodeStatusT::STATE_RUNNING | NodeStatusT::STATE_DEGRADED
            ) && now.saturating_duration_since(b.at) < fresh
        })
    }

    fn set(p: &mut Proc, state: i8, detail: String, notes: &mut Vec<Note>) {
        if p.state != state || p.detail != detail {
            tracing::info!(
                app = p.app.name.as_str(),
                "{}{}{}",
                state_word(state),
                if detail.is_empty() { "" } else { ": " },
                detail
            );
            p.state = state;
            p.detail = detail.clone();
            notes.push(Note::Changed {
                app: p.app.name.clone(),
                state,
                detail,
            });
        }
    }

    fn spawn(
        p: &mut Proc,
        lines: &Sender<Line>,
        log_dir: &Option<PathBuf>,
        log_level: &Option<String>,
        now: Instant,
    ) -> Result<(), String> {
        let mut c = Command::new(&p.app.program);
        c.args(&p.app.args).env("STRIDE_LCM_URL", &p.app.lcm_url);
        if let Some(l) = log_level {
            c.env("STRIDE_LOG_LEVEL", l);
        }
        match &p.app.local {
            Some(l) => c
                .env("STRIDE_LOCAL_URL", &l.url)
                .env("STRIDE_LOCAL_CHANNELS", l.channels.join(",")),
            None => c
                .env_remove("STRIDE_LOCAL_URL")
                .env_remove("STRIDE_LOCAL_CHANNELS"),
        };
        c.stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .process_group(0);
        let mut child = c
            .spawn()
            .map_err(|e| format!("{}: {e}", p.app.program.display()))?;
        for (stream, reader) in [
            (
                LaunchConsoleT::STREAM_STDOUT,
                child
                    .stdout
                    .take()
                    .map(|s| Box::new(s) as Box<dyn std::io::Read + Send>),
            ),
            (
                LaunchConsoleT::STREAM_STDERR,
                child
                    .stderr
                    .take()
                    .map(|s| Box::new(s) as Box<dyn std::io::Read + Send>),
            ),
        ] {
            let Some(reader) = reader else { continue };
            let tx = lines.clone();
            let app = p.app.name.clone();
            std::thread::spawn(move || {
                for text in BufReader::new(reader).lines().map_while(Result::ok) {
                    if tx
                        .send(Line {
                            app: app.clone(),
                            stream,
                            text,
                        })
                        .is_err()
                    {
                        break;
                    }
                }
            });
        }
        if p.log.is_none() {
            if let Some(d) = log_dir {
                let _ = std::fs::create_dir_all(d);
                p.log = std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(d.join(format!("{}.log", p.app.name)))
                    .ok();
            }
        }
        p.child = Some(child);
        p.started = Some(now);
        p.cpu_sample = None;
        Ok(())
    }

    /// The wait before restart number `streak` (0-based).
    fn backoff(b: &Backoff, streak: u32) -> Duration {
        Duration::from_secs_f64((b.initial * 2f64.powi(streak.min(30) as i32)).min(b.max))
    }

    /// One turn: reaps exits, restarts or gives up by policy, marks the silent lost, starts
    /// what waits and is ready, and (during a shutdown) moves it on. Returns what happened.
    pub fn step(&mut self, now: Instant) -> Vec<Note> {
        let mut notes = Vec::new();
        let lost_after = Duration::from_secs_f64(self.profile.file.lost_after);
        let backoff = self.profile.file.backoff;
        let shutting = self.shutdown.is_some();
        // What each app still waits for, before any borrow of the processes.
        let waiting: Vec<Vec<String>> = self
            .procs
            .iter()
            .map(|p| {
                p.app
                    .depends
                    .iter()
                    .filter(|d| !self.ready(d, now))
                    .cloned()
                    .collect()
            })
            .collect();
        for (k, p) in self.procs.iter_mut().enumerate() {
            // An exit.
            let exited = match p.child.as_mut().map(|c| c.try_wait()) {
                Some(Ok(Some(status))) => Some(status),
                _ => None,
            };
            if let Some(status) = exited {
                use std::os::unix::process::ExitStatusExt;
                p.child = None;
                p.stopping = None;
                p.exit_code = status
                    .code()
                    .unwrap_or_else(|| 128 + status.signal().unwrap_or(0));
                let failed = !status.success();
                let how = match (status.code(), status.signal()) {
                    (Some(c), _) => format!("exited with status {c}"),
                    (None, Some(s)) => format!("killed by signal {s}"),
                    _ => "ended".to_string(),
                };
                if p.held || shutting {
                    Self::set(p, LaunchAppT::STATE_EXITED, how, &mut notes);
                    continue;
                }
                if p.app.critical {
                    notes.push(Note::SystemStop(format!(
                        "critical app {} {how}",
                        p.app.name
                    )));
                }
                if p.started.is_some_and(|s| {
                    now.saturating_duration_since(s).as_secs_f64() >= backoff.reset_after
                }) {
                    p.streak = 0;
                }
                let again = match p.app.restart {
                    Restart::Never => false,
                    Restart::OnFailure => failed,
                    Restart::Always => true,
                };
                if !again {
                    let state = if failed {
                        LaunchAppT::STATE_FAILED
                    } else {
                        LaunchAppT::STATE_EXITED
                    };
                    Self::set(p, state, how, &mut notes);
                } else if p.restarts >= backoff.max_restarts {
                    Self::set(
                        p,
                        LaunchAppT::STATE_FAILED,
                        format!(
                            "{how}; restarted {} times, the most allowed: left down",
                            p.restarts
                        ),
                        &mut notes,
                    );
                } else {
                    let wait = Self::backoff(&backoff, p.streak);
                    p.due = Some(now + wait);
                    Self::set(
                        p,
                        LaunchAppT::STATE_BACKOFF,
                        format!("{how}; restarting in {:.1} s", wait.as_secs_f64()),
                        &mut notes,
                    );
                }
                continue;
            }
            if shutting || p.held {
                continue;
            }
            match p.state {
                LaunchAppT::STATE_WAITING if waiting[k].is_empty() => {
                    match Self::spawn(p, &self.lines_tx, &self.log_dir, &self.log_level, now) {
                        Ok(()) => {
                            Self::set(p, LaunchAppT::STATE_STARTING, String::new(), &mut notes)
                        }
                        Err(e) => Self::set(p, LaunchAppT::STATE_FAILED, e, &mut notes),
                    }
                }
                LaunchAppT::STATE_WAITING => {
                    Self::set(
                        p,
                        LaunchAppT::STATE_WAITING,
                        format!("for {} to run", waiting[k].join(", ")),
                        &mut notes,
                    );
                }
                LaunchAppT::STATE_BACKOFF if p.due.is_some_and(|d| now >= d) => {
                    p.restarts += 1;
                    p.streak += 1;
                    p.due = None;
                    match Self::spawn(p, &self.lines_tx, &self.log_dir, &self.log_level, now) {
                        Ok(()) => Self::set(
                            p,
                            LaunchAppT::STATE_STARTING,
                            format!("restart {}", p.restarts),
                            &mut notes,
                        ),
                        Err(e) => Self::set(p, LaunchAppT::STATE_FAILED, e, &mut notes),
                    }
                }
                LaunchAppT::STATE_STARTING
                | LaunchAppT::STATE_RUNNING
                | LaunchAppT::STATE_LOST
                | LaunchAppT::STATE_FAULT => {
                    let started = p.started.unwrap_or(now);
                    if !p.app.node {
                        Self::set(p, LaunchAppT::STATE_RUNNING, String::new(), &mut notes);
                        continue;
                    }
                    let beat = self.beats.get(&p.app.name).filter(|b| b.at >= started);
                    let silent = match beat {
                        Some(b) => now.saturating_duration_since(b.at) > lost_after,
                        None => now.saturating_duration_since(started) > lost_after * 3,
                    };
                    // A loop that does not come round is as good as silent, whatever its
                    // heartbeat thread still says.
                    let stalled = beat
                        .filter(|b| !silent && b.status.state == NodeStatusT::STATE_STALLED)
                        .map(|b| b.status.detail.clone());
                    if silent || stalled.is_some() {
                        if p.state != LaunchAppT::STATE_LOST {
                            let how = stalled.unwrap_or_else(|| {
                                format!("no heartbeat for {:.0} s", lost_after.as_secs_f64())
                            });
                            if p.app.critical {
                                notes.push(Note::SystemStop(format!(
                                    "critical app {} is {}",
                                    p.app.name,
                                    if silent { "silent" } else { "stalled" }
                                )));
                            }
                            Self::set(p, LaunchAppT::STATE_LOST, how, &mut notes);
                            if p.app.restart != Restart::Never {
                                // Killed: its exit restarts it by the policy.
                                if let Some(c) = &p.child {
                                    signal_group(c.id(), libc::SIGKILL);
                                }
                            }
                        }
                    } else if let Some(b) = beat {
                        let state = match b.status.state {
                            NodeStatusT::STATE_RUNNING | NodeStatusT::STATE_DEGRADED => {
                                LaunchAppT::STATE_RUNNING
                            }
                            NodeStatusT::STATE_FAULT => LaunchAppT::STATE_FAULT,
                            _ => LaunchAppT::STATE_STARTING,
                        };
                        // A critical app that turns to a fault: the system stop, and a
                        // restart when its profile asks for one.
                        if state == LaunchAppT::STATE_FAULT
                            && p.state != LaunchAppT::STATE_FAULT
                            && p.app.critical
                        {
                            notes.push(Note::SystemStop(format!(
                                "critical app {} reports a fault: {}",
                                p.app.name, b.status.detail
                            )));
                            if p.app.on_fault == OnFault::Restart && p.app.restart != Restart::Never
                            {
                                if let Some(c) = &p.child {
                                    signal_group(c.id(), libc::SIGKILL);
                                }
                            }
                        }
                        Self::set(p, state, b.status.detail.clone(), &mut notes);
                    }
                }
                _ => {}
            }
        }
        self.sample_usage(now);
        if self.shutdown.is_some() {
            self.shutdown_step(now, &mut notes);
        }
        notes
    }

    fn sample_usage(&mut self, now: Instant) {
        let tps = sysconf(libc::_SC_CLK_TCK, 100) as f64;
        let page = sysconf(libc::_SC_PAGESIZE, 4096);
        for p in &mut self.procs {
            let Some(c) = &p.child else {
                p.cpu = 0.0;
                p.memory = 0;
                continue;
            };
            // /proc is read once a second at most (the deputy ticks at 20 Hz).
            let last = p.cpu_sample.as_ref().map(|(_, at)| *at);
            let dt = last.map(|at| now.saturating_duration_since(at).as_secs_f64());
            if dt.is_some_and(|dt| dt < 1.0) {
                continue;
            }
            if let Some((time, rss)) = proc_usage(c.id(), tps) {
                if let (Some((t0, _)), Some(dt)) = (&p.cpu_sample, dt) {
                    p.cpu = time.share_since(t0, dt);
                }
                p.cpu_sample = Some((time, now));
                p.memory = rss * page;
            }
        }
    }

    /// Stops one app for good (an order): SIGINT, then SIGTERM and SIGKILL after its timeout.
    pub fn stop_app(&mut self, name: &str, now: Instant) -> bool {
        let Some(p) = self.procs.iter_mut().find(|p| p.app.name == name) else {
            return false;
        };
        p.held = true;
        p.due = None;
        if let Some(c) = &p.child {
            signal_group(c.id(), libc::SIGINT);
            p.stopping = Some((now, false, false));
            p.state = LaunchAppT::STATE_STOPPING;
            p.detail = "stopped by order".into();
        } else {
            p.state = LaunchAppT::STATE_EXITED;
            p.detail = "stopped by order".into();
        }
        true
    }

    /// Starts an app again (an order), from waiting for its dependencies.
    pub fn start_app(&mut self, name: &str) -> bool {
        let Some(p) = self.procs.iter_mut().find(|p| p.app.name == name) else {
            return false;
        };
        p.held = false;
        if p.child.is_none() {
            p.state = LaunchAppT::STATE_WAITING;
            p.detail = "started by order".into();
            p.streak = 0;
        }
        true
    }

    /// Begins the ordered shutdown.
    pub fn begin_shutdown(&mut self, now: Instant) {
        if self.shutdown.is_none() {
            self.shutdown = Some(0);
            let mut notes = Vec::new();
            self.shutdown_step(now, &mut notes);
        }
    }

    /// True once the shutdown began.
    pub fn shutting_down(&self) -> bool {
        self.shutdown.is_some()
    }

    /// True when nothing runs any more.
    pub fn all_down(&self) -> bool {
        self.procs.iter().all(|p| p.child.is_none())
    }

    /// Moves the shutdown on: the lowest stage with processes left gets SIGINT, then SIGTERM
    /// after its timeout, then SIGKILL after half as long again.
    fn shutdown_step(&mut self, now: Instant, notes: &mut Vec<Note>) {
        for p in &mut self.procs {
            p.due = None;
            if p.child.is_none()
                && matches!(
                    p.state,
                    LaunchAppT::STATE_WAITING | LaunchAppT::STATE_BACKOFF
                )
            {
                Self::set(
                    p,
                    LaunchAppT::STATE_EXITED,
                    "not started: shutting down".into(),
                    notes,
                );
            }
        }
        let Some(stage) = self
            .procs
            .iter()
            .filter(|p| p.child.is_some())
            .map(|p| p.app.stage)
            .min()
        else {
            return;
        };
        self.shutdown = Some(stage);
        for p in self.procs.iter_mut().filter(|p| p.app.stage == stage) {
            let Some(c) = &p.child else { continue };
            let pid = c.id();
            let timeout = Duration::from_secs_f64(p.app.stop_timeout);
            match &mut p.stopping {
                None => {
                    signal_group(pid, libc::SIGINT);
                    p.stopping = Some((now, false, false));
                    Self::set(p, LaunchAppT::STATE_STOPPING, "SIGINT".into(), notes);
                }
                Some((since, term, kill)) => {
                    let waited = now.saturating_duration_since(*since);
                    if !*term && waited >= timeout {
                        *term = true;
                        signal_group(pid, libc::SIGTERM);
                        tracing::warn!(
                            app = p.app.name.as_str(),
                            "still running {:.1} s after SIGINT: SIGTERM",
                            waited.as_secs_f64()
                        );
                    } else if !*kill && waited >= timeout + timeout / 2 {
                        *kill = true;
                        signal_group(pid, libc::SIGKILL);
                        tracing::warn!(
                            app = p.app.name.as_str(),
                            "still running after SIGTERM: SIGKILL"
                        );
                    }
                }
            }
        }
    }

    /// The apps' report.
    pub fn report(&self, now: Instant) -> Vec<LaunchAppT> {
        self.procs
            .iter()
            .map(|p| {
                let beat = self.beats.get(&p.app.name);
                let (pub_rate, recv_rate) = beat
                    .and_then(|b| {
                        let (at0, s0) = b.previous.as_ref()?;
                        let dt = b.at.saturating_duration_since(*at0).as_secs_f64();
                        (dt > 0.0).then(|| {
                            (
                                (b.status.messages_published - s0.messages_published) as f64 / dt,
                                (b.status.messages_received - s0.messages_received) as f64 / dt,
                            )
                        })
                    })
                    .unwrap_or((0.0, 0.0));
                LaunchAppT {
                    name: p.app.name.clone(),
                    state: p.state,
                    detail: p.detail.clone(),
                    pid: p.child.as_ref().map_or(0, |c| c.id() as i32),
                    restarts: p.restarts as i32,
                    exit_code: p.exit_code,
                    heartbeat_age: beat
                        .map_or(-1.0, |b| now.saturating_duration_since(b.at).as_secs_f64()),
                    node_state: beat.map_or(-1, |b| b.status.state),
                    cpu: p.cpu,
                    memory: p.memory,
                    publish_rate: pub_rate,
                    receive_rate: recv_rate,
                    critical: p.app.critical,
                }
            })
            .collect()
    }
}

impl Drop for Supervisor {
    fn drop(&mut self) {
        // Nothing outlives the deputy.
        for p in &mut self.procs {
            if let Some(c) = &mut p.child {
                signal_group(c.id(), libc::SIGKILL);
                let _ = c.wait();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::{Profile, ProfileFile};

    #[test]
    fn an_apps_cpu_share_is_the_schedulers_count_unless_a_thread_ended() {
        let at = |ticks: f64, ns: Option<(f64, &[u32])>| CpuTime {
            ticks,
            threads: ns.map(|(s, ids)| (s, ids.to_vec())),
        };
        // Every thread of then still runs: to the nanosecond, not in 10 ms ticks.
        let a = at(1.00, Some((1.000_000, &[10, 11])));
        let b = at(1.00, Some((1.003_500, &[10, 11, 12])));
        assert!((b.share_since(&a, 1.0) - 0.0035).abs() < 1e-9);
        // Thread 11 ended (its schedstat with it): the ticks, which keep its time.
        let c = at(1.02, Some((1.001_000, &[10, 12])));
        assert!((c.share_since(&b, 2.0) - 0.01).abs() < 1e-9);
        // No schedstat: the ticks. Never a negative share.
        assert!((at(1.05, None).share_since(&at(1.0, None), 1.0) - 0.05).abs() < 1e-9);
        assert_eq!(at(1.0, None).share_since(&at(1.1, None), 1.0), 0.0);
        // What this machine's /proc gives: this process, this thread among its own.
        let (t, rss) = proc_usage(std::process::id(), 100.0).unwrap();
        let (secs, ids) = t.threads.expect("schedstat");
        // SAFETY: gettid has no preconditions.
        let me = unsafe { libc::gettid() } as u32;
        assert!(
            secs > 0.0 && rss > 0 && ids.binary_search(&me).is_ok(),
            "{ids:?}"
        );
    }

    fn profile(apps: &str) -> Profile {
        let text = format!(
            "lcm_url = \"memq://\"\nlost_after = 1.0\n\
             [backoff]\ninitial = 0.05\nmax = 0.2\nmax_restarts = 2\nreset_after = 30.0\n{apps}"
        );
        let file: ProfileFile = toml::from_str(&text).unwrap();
        let dir = tempfile::tempdir().unwrap();
        Profile::check("t".into(), file, dir.path(), false, None).unwrap()
    }

    /// Steps the supervisor until `done` or `secs`, collecting its notes.
    fn run(sup: &mut Supervisor, secs: f64, done: impl Fn(&Supervisor) -> bool) -> Vec<Note> {
        let until = Instant::now() + Duration::from_secs_f64(secs);
        let mut notes = Vec::new();
        while Instant::now() < until && !done(sup) {
            notes.extend(sup.step(Instant::now()));
            std::thread::sleep(Duration::from_millis(10));
        }
        notes
    }

    fn state(sup: &Supervisor, name: &str) -> (i8, u32, String) {
        let p = sup.procs.iter().find(|p| p.app.name == name).unwrap();
        (p.state, p.restarts, p.detail.clone())
    }

    #[test]
    fn a_failing_app_is_restarted_with_backoff_up_to_its_cap_and_a_critical_one_stops_the_robot() {
        let mut sup = Supervisor::new(
            profile(
                "[[app]]\nname = \"crash\"\ncommand = \"/bin/sh\"\nargs = [\"-c\", \"echo up; exit 3\"]\n\
                 node = false\ncritical = true\n",
            ),
            None,
            None,
        );
        let notes = run(&mut sup, 10.0, |s| {
            state(s, "crash").0 == LaunchAppT::STATE_FAILED
        });
        let (st, restarts, detail) = state(&sup, "crash");
        assert_eq!((st, restarts), (LaunchAppT::STATE_FAILED, 2), "{detail}");
        assert!(
            detail.contains("exited with status 3") && detail.contains("restarted 2 times"),
            "{detail}"
        );
        // Each death of the critical app stops the robot.
        let stops = notes
            .iter()
            .filter(|n| matches!(n, Note::SystemStop(_)))
            .count();
        assert_eq!(stops, 3, "{notes:?}");
        let backoffs: Vec<&String> = notes
            .iter()
            .filter_map(|n| match n {
                Note::Changed { state, detail, .. } if *state == LaunchAppT::STATE_BACKOFF => {
                    Some(detail)
                }
                _ => None,
            })
            .collect();
        assert_eq!(backoffs.len(), 2, "{backoffs:?}");
        assert!(
            backoffs[0].contains("0.1 s") && backoffs[1].contains("0.1 s"),
            "{backoffs:?}"
        );
        let lines = sup.lines();
        assert_eq!(
            lines.iter().filter(|l| l.text == "up").count(),
            3,
            "{lines:?}"
        );
    }

    #[test]
    fn an_app_waits_for_its_dependency_and_a_clean_exit_is_not_restarted() {
        let mut sup = Supervisor::new(
            profile(
                "[[app]]\nname = \"second\"\ncommand = \"/bin/sh\"\nargs = [\"-c\", \"exit 0\"]\n\
                 node = false\ndepends = [\"first\"]\n\
                 [[app]]\nname = \"first\"\ncommand = \"/bin/sh\"\nargs = [\"-c\", \"sleep 0.3\"]\n\
                 node = false\nrestart = \"never\"\n",
            ),
            None,
            None,
        );
        let notes = run(&mut sup, 5.0, |s| {
            state(s, "first").0 == LaunchAppT::STATE_EXITED
                && state(s, "second").0 == LaunchAppT::STATE_EXITED
        });
        // "second" started only after "first" ran.
        let order: Vec<&str> = notes
            .iter()
            .filter_map(|n| match n {
                Note::Changed { app, state, .. } if *state == LaunchAppT::STATE_STARTING => {
                    Some(app.as_str())
                }
                _ => None,
            })
            .collect();
        assert_eq!(order, ["first", "second"], "{notes:?}");
        assert_eq!(state(&sup, "second").1, 0, "a clean exit is not restarted");
        assert!(!notes.iter().any(|n| matches!(n, Note::SystemStop(_))));
    }

    #[test]
    fn a_silent_node_is_marked_lost_and_the_shutdown_stops_every_stage() {
        // A stride app is passed --name: a script that takes any arguments and never beats.
        let dir = tempfile::tempdir().unwrap();
        let quiet = dir.path().join("quiet.sh");
        std::fs::write(&quiet, "#!/bin/sh\nsleep 30\n").unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&quiet, std::fs::Permissions::from_mode(0o755)).unwrap();
        let mut sup = Supervisor::new(
            profile(&format!(
                "[[app]]\nname = \"quiet\"\ncommand = \"{}\"\n\
                 restart = \"never\"\ncritical = true\nstage = 1\n\
                 [[app]]\nname = \"stubborn\"\ncommand = \"/bin/sh\"\n\
                 args = [\"-c\", \"trap '' INT TERM; sleep 30\"]\nnode = false\nstop_timeout = 0.2\n",
                quiet.display()
            )),
            None,
            None,
        );
        // A node that never beats: lost after three times lost_after, a system stop.
        let notes = run(&mut sup, 8.0, |s| {
            state(s, "quiet").0 == LaunchAppT::STATE_LOST
        });
        assert_eq!(state(&sup, "quiet").0, LaunchAppT::STATE_LOST, "{notes:?}");
        assert!(notes
            .iter()
            .any(|n| matches!(n, Note::SystemStop(w) if w.contains("silent"))));
        // The shutdown: SIGINT ends "quiet"; "stubborn" ignores SIGINT and SIGTERM and is
        // killed.
        sup.begin_shutdown(Instant::now());
        run(&mut sup, 10.0, Supervisor::all_down);
        assert!(sup.all_down());
        assert_eq!(state(&sup, "stubborn").0, LaunchAppT::STATE_EXITED);
        assert!(
            state(&sup, "stubborn").2.contains("signal 9"),
            "{:?}",
            state(&sup, "stubborn")
        );
    }

    /// D6 of the reliability findings: `stride status` showed a node in FAULT as "starting",
    /// and a critical app in FAULT was neither restarted nor a system stop. A loop that stalls
    /// (its heartbeat thread beating on) is as good as silent.
    #[test]
    fn a_critical_apps_fault_or_stalled_loop_stops_the_robot_as_its_profile_asks() {
        let dir = tempfile::tempdir().unwrap();
        let quiet = dir.path().join("quiet.sh");
        std::fs::write(&quiet, "#!/bin/sh\nsleep 30\n").unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&quiet, std::fs::Permissions::from_mode(0o755)).unwrap();
        let mut sup = Supervisor::new(
            profile(&format!(
                "[[app]]\nname = \"bridge\"\ncommand = \"{q}\"\ncritical = true\n\
                 [[app]]\nname = \"gait\"\ncommand = \"{q}\"\ncritical = true\n\
                 on_fault = \"restart\"\n\
                 [[app]]\nname = \"planner\"\ncommand = \"{q}\"\ncritical = true\n",
                q = quiet.display()
            )),
            None,
            None,
        );
        let beat = |sup: &mut Supervisor, node: &str, state: i8, detail: &str| {
            sup.heartbeat(
                NodeStatusT {
                    node: node.into(),
                    state,
                    detail: detail.into(),
                    ..Default::default()
                },
                Instant::now(),
            );
        };
        let mut notes = Vec::new();
        for _ in 0..20 {
            for n in ["bridge", "gait", "planner"] {
                beat(&mut sup, n, NodeStatusT::STATE_RUNNING, "");
            }
            notes.extend(sup.step(Instant::now()));
            std::thread::sleep(Duration::from_millis(10));
        }
        assert_eq!(state(&sup, "bridge").0, LaunchAppT::STATE_RUNNING);
        assert!(!notes.iter().any(|n| matches!(n, Note::SystemStop(_))));
        beat(
            &mut sup,
            "bridge",
            NodeStatusT::STATE_FAULT,
            "left_knee: emergency",
        );
        beat(
            &mut sup,
            "gait",
            NodeStatusT::STATE_FAULT,
            "no joint states",
        );
        beat(
            &mut sup,
            "planner",
            NodeStatusT::STATE_STALLED,
            "control loop stalled: no turn for 1.2 s past its time",
        );
        let notes = sup.step(Instant::now());
        let stops: Vec<&String> = notes
            .iter()
            .filter_map(|n| match n {
                Note::SystemStop(w) => Some(w),
                _ => None,
            })
            .collect();
        assert_eq!(stops.len(), 3, "{notes:?}");
        assert!(stops
            .iter()
            .any(|w| w.contains("bridge reports a fault: left_knee")));
        assert!(stops.iter().any(|w| w.contains("planner is stalled")));
        // Shown as FAULT, and the word says so.
        assert_eq!(state(&sup, "bridge").0, LaunchAppT::STATE_FAULT);
        assert_eq!(state_word(LaunchAppT::STATE_FAULT), "FAULT");
        let (st, _, detail) = state(&sup, "planner");
        assert_eq!(st, LaunchAppT::STATE_LOST);
        assert!(detail.contains("stalled"), "{detail}");
        // The gait asked for a restart: it is killed and comes back; the bridge runs on.
        let notes = run(&mut sup, 5.0, |s| state(s, "gait").1 == 1);
        assert_eq!(state(&sup, "gait").1, 1, "{notes:?}");
        assert_eq!(state(&sup, "bridge").1, 0);
        // The fault is told once, not at every beat that repeats it.
        beat(
            &mut sup,
            "bridge",
            NodeStatusT::STATE_FAULT,
            "left_knee: emergency",
        );
        let again = sup.step(Instant::now());
        assert!(
            !again
                .iter()
                .any(|n| matches!(n, Note::SystemStop(w) if w.contains("bridge"))),
            "{again:?}"
        );
    }

    /// D7 of the reliability findings: `stride --log-level warn launch` did not reach the
    /// apps, whose logs were full of INFO lines.
    #[test]
    fn the_launchers_log_level_reaches_its_apps() {
        let mut sup = Supervisor::new(
            profile(
                "[[app]]\nname = \"tell\"\ncommand = \"/bin/sh\"\n\
                 args = [\"-c\", \"echo level=$STRIDE_LOG_LEVEL\"]\nnode = false\n\
                 restart = \"never\"\n",
            ),
            None,
            None,
        );
        sup.set_log_level("warn");
        run(&mut sup, 5.0, |s| {
            state(s, "tell").0 == LaunchAppT::STATE_EXITED
        });
        let lines = sup.lines();
        assert!(lines.iter().any(|l| l.text == "level=warn"), "{lines:?}");
    }
}
