//! The app frame: command line, configuration, node, loop and exit, the same for every app.
//!
//! An app's `lib.rs` holds its command line (a clap parser with [`NodeArgs`] flattened in,
//! made known by [`NodeCli`]), its configuration ([`AppConfig`]: none, optional or required,
//! with a typed check) and a state machine that implements [`Tick`]; its `main.rs` only wires
//! them:
//!
//! ```no_run
//! use std::time::{Duration, Instant};
//! use stride_node::{Launch, NoConfig, Node, NodeArgs, Tick};
//!
//! #[derive(clap::Parser)]
//! struct Cli {
//!     #[command(flatten)]
//!     node: NodeArgs,
//! }
//! stride_node::node_cli!(Cli);
//! struct App;
//! impl Tick for App {
//!     fn tick(&mut self, _node: &Node, now: Instant) -> anyhow::Result<Instant> {
//!         Ok(now + Duration::from_millis(100))
//!     }
//! }
//! fn main() -> std::process::ExitCode {
//!     stride_node::main("my-app", |l: Launch<Cli, NoConfig>| {
//!         let node = l.start()?;
//!         node.run(App)
//!     })
//! }
//! ```
//!
//! [`main`] parses the command line, refuses an unknown `--log-level`, loads and checks the
//! configuration (refusing `--config` for an app that takes none, and saying where to find one
//! for an app that needs one), and turns every error into one line on stderr and exit status 1,
//! whatever `RUST_BACKTRACE` says. A write to a closed stdout ends the program quietly.
//! [`Node::run`] drives the [`Tick`] until SIGINT/SIGTERM, [`Node::exit_with`] or a closed
//! stdout, then lets it stop gracefully.

use std::io::Write;
use std::path::Path;
use std::process::ExitCode;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::Context;
use serde::de::DeserializeOwned;

use crate::{Node, NodeArgs};

/// A command line that carries the common flags.
pub trait NodeCli: clap::Parser {
    /// The app keeps time with motors: `Some(k)` runs it at `k` below the real-time priority
    /// `--rt-priority` asks for ([`crate::realtime`]): 0 for the devices' side (bridges,
    /// gateway, fake drives: their heartbeats keep the drives' watchdogs fed), 1 for the
    /// gait, whose longer computations must not hold a bridge up. `None`: normal scheduling.
    const REALTIME: Option<u8> = None;

    /// The common flags.
    fn node_args(&self) -> &NodeArgs;
}

/// Implements [`NodeCli`] for a clap parser whose common flags are its field `node`.
#[macro_export]
macro_rules! node_cli {
    ($cli:ty) => {
        impl $crate::NodeCli for $cli {
            fn node_args(&self) -> &$crate::NodeArgs {
                &self.node
            }
        }
    };
    ($cli:ty, realtime) => {
        $crate::node_cli!($cli, realtime, 0);
    };
    ($cli:ty, realtime, $below:expr) => {
        impl $crate::NodeCli for $cli {
            const REALTIME: Option<u8> = Some($below);
            fn node_args(&self) -> &$crate::NodeArgs {
                &self.node
            }
        }
    };
}

/// Whether an app reads a configuration file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigUse {
    /// It takes none: `--config` is refused.
    None,
    /// Its defaults serve without one.
    Optional,
    /// It cannot run without one; the text says where examples are.
    Required(&'static str),
}

/// An app's configuration, read from TOML.
pub trait AppConfig: DeserializeOwned {
    /// Whether a file is needed.
    const USE: ConfigUse;
    /// The defaults, used without a file (only asked for when `USE` is not `Required`).
    fn defaults() -> Option<Self> {
        None
    }
    /// Checks what types cannot: ranges, consistency, names. The error is one line.
    fn check(&self) -> Result<(), String> {
        Ok(())
    }
}

/// The configuration of an app that takes none.
#[derive(Debug, Clone, Copy, Default, serde::Deserialize)]
pub struct NoConfig {}

impl AppConfig for NoConfig {
    const USE: ConfigUse = ConfigUse::None;
    fn defaults() -> Option<Self> {
        Some(NoConfig {})
    }
}

/// Loads `A`'s configuration as `USE` says, and checks it.
pub fn app_config<A: AppConfig>(path: Option<&Path>) -> anyhow::Result<A> {
    let cfg = match (A::USE, path) {
        (ConfigUse::None, Some(p)) => anyhow::bail!(
            "this program takes no configuration file (--config {})",
            p.display()
        ),
        (ConfigUse::None | ConfigUse::Optional, None) => {
            A::defaults().context("this program has no default configuration: --config FILE")?
        }
        (ConfigUse::Required(hint), None) => {
            anyhow::bail!("a configuration file is needed: --config FILE ({hint})")
        }
        (_, Some(p)) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("reading configuration file {}", p.display()))?;
            toml::from_str(&text)
                .map_err(|e| anyhow::anyhow!("{}", e.to_string().trim().replace('\n', " ")))
                .with_context(|| format!("in configuration file {}", p.display()))?
        }
    };
    cfg.check()
        .map_err(anyhow::Error::msg)
        .context(match path {
            Some(p) => format!("configuration {}", p.display()),
            None => "default configuration".to_owned(),
        })?;
    Ok(cfg)
}

/// What [`main`] hands the app: its parsed command line and checked configuration.
#[derive(Debug)]
pub struct Launch<C, F> {
    /// The command line.
    pub cli: C,
    /// The configuration.
    pub cfg: F,
    name: &'static str,
}

impl<C: NodeCli, F> Launch<C, F> {
    /// Starts the app's node on the bus.
    pub fn start(&self) -> anyhow::Result<Node> {
        Node::start(self.name, self.cli.node_args())
    }

    /// Starts a node under another default name (a client mode of the app, e.g. a query).
    pub fn start_as(&self, name: &str) -> anyhow::Result<Node> {
        Node::start(name, self.cli.node_args())
    }

    /// Sets up logging only, for a mode that does not join the bus.
    pub fn logging(&self) {
        crate::init_logging(&self.cli.node_args().log_level);
    }

    /// The app's name.
    pub fn name(&self) -> &'static str {
        self.name
    }
}

/// The whole life of app `name`: parses `C`, loads `F`, runs `body`, and turns its outcome
/// into the exit status (errors in one line on stderr, a closed stdout quiet).
pub fn main<C, F>(
    name: &'static str,
    body: impl FnOnce(Launch<C, F>) -> anyhow::Result<ExitCode>,
) -> ExitCode
where
    C: NodeCli,
    F: AppConfig,
{
    let cli = C::parse();
    if let (Some(below), p @ 1..) = (C::REALTIME, cli.node_args().rt_priority) {
        // Before any thread starts, so that every one of them inherits it; a refusal is
        // logged once logging is up.
        let _ = crate::realtime::request(p.saturating_sub(below).max(1));
    }
    let outcome = check_log_filter(&cli.node_args().log_level)
        .and_then(|()| app_config::<F>(cli.node_args().config.as_deref()))
        .and_then(|cfg| body(Launch { cli, cfg, name }));
    finish(name, outcome)
}

/// [`main`] for a tool that takes its own command line and no node: `body` parses nothing
/// more and runs; errors and a closed stdout are handled as in [`main`].
pub fn tool<C: clap::Parser>(
    name: &'static str,
    body: impl FnOnce(C) -> anyhow::Result<ExitCode>,
) -> ExitCode {
    finish(name, body(C::parse()))
}

/// Refuses a `--log-level` that is no tracing filter (RUST_LOG, when set, is taken instead).
pub fn check_log_filter(filter: &str) -> anyhow::Result<()> {
    if std::env::var_os("RUST_LOG").is_some() {
        return Ok(());
    }
    tracing_subscriber::EnvFilter::try_new(filter)
        .map(drop)
        .map_err(|e| anyhow::anyhow!("--log-level {filter:?}: {e}"))
}

fn finish(name: &str, outcome: anyhow::Result<ExitCode>) -> ExitCode {
    match outcome {
        Ok(code) => {
            // A stdout closed under buffered output is quiet too.
            let _ = std::io::stdout().flush();
            code
        }
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            let line = format!("{e:#}").replace('\n', " ");
            let _ = writeln!(std::io::stderr(), "{name}: error: {line}");
            ExitCode::FAILURE
        }
    }
}

/// True when the error comes from writing to a closed stdout (a reader such as `head` left).
pub fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Writes a line to stdout, returning the error (a closed stdout) instead of panicking as
/// `println!` does.
#[macro_export]
macro_rules! outln {
    ($($arg:tt)*) => {{
        use ::std::io::Write as _;
        ::std::writeln!(::std::io::stdout().lock(), $($arg)*)
    }};
}

/// True when stdout is a pipe or socket whose reader has gone.
pub fn stdout_closed() -> bool {
    let mut p = libc::pollfd {
        fd: 1,
        events: 0,
        revents: 0,
    };
    // SAFETY: one valid pollfd, no wait.
    let n = unsafe { libc::poll(&mut p, 1, 0) };
    n == 1 && p.revents & (libc::POLLERR | libc::POLLHUP) != 0 && stdout_is_pipe()
}

fn stdout_is_pipe() -> bool {
    // SAFETY: fstat on fd 1 into a zeroed struct.
    let mut st: libc::stat = unsafe { std::mem::zeroed() };
    let ok = unsafe { libc::fstat(1, &mut st) } == 0;
    let kind = st.st_mode & libc::S_IFMT;
    ok && (kind == libc::S_IFIFO || kind == libc::S_IFSOCK)
}

/// An app's state machine, driven by [`Node::run`].
pub trait Tick {
    /// Tick as soon as a message of a subscription arrives, not only when the time asked
    /// for has come (other traffic on the bus does not wake the app).
    const WAKE_ON_MESSAGE: bool = true;

    /// Does one turn of work at `now` (take queued messages, talk to devices, publish) and
    /// says when it wants the next. An error stops the loop: [`Tick::stop`] still runs.
    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant>;

    /// Asked after messages of the app's subscriptions arrived between ticks (when
    /// [`Tick::WAKE_ON_MESSAGE`] is false): true ticks at once, for messages that should not
    /// wait for the next period (a plan, a command) while the rest of the traffic does.
    fn urgent(&mut self) -> bool {
        false
    }

    /// Stops gracefully (devices to a safe state), once, after the loop ends.
    fn stop(self, _node: &Node) -> anyhow::Result<()>
    where
        Self: Sized,
    {
        Ok(())
    }
}

/// A fixed rate for [`Tick::tick`]: the next tick a period after the last deadline, a missed
/// one skipped rather than caught up in a burst. A tick before the deadline (one a message
/// caused) leaves the deadline where it is: however many messages come, the periodic ticks
/// keep their time.
#[derive(Debug, Clone, Copy)]
pub struct Period {
    period: Duration,
    next: Option<Instant>,
    missed: u64,
}

impl Period {
    /// `rate_hz` ticks a second.
    pub fn hz(rate_hz: f64) -> Period {
        Period {
            period: Duration::from_secs_f64(1.0 / rate_hz),
            next: None,
            missed: 0,
        }
    }

    /// The period.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// The deadline of the next periodic tick, after a tick at `now`: unchanged before the
    /// deadline; once it is reached, one period on (from `now` when the tick came a period or
    /// more late: the ticks in between are skipped and counted, see [`Period::missed`]).
    pub fn next(&mut self, now: Instant) -> Instant {
        let n = match self.next {
            Some(d) if now < d => d,
            Some(d) => {
                let n = d + self.period;
                if n <= now {
                    let late = now.saturating_duration_since(d).as_nanos();
                    self.missed += (late / self.period.as_nanos().max(1)) as u64;
                    now + self.period
                } else {
                    n
                }
            }
            None => now + self.period,
        };
        self.next = Some(n);
        n
    }

    /// True when a periodic tick is due at `now` (the first always is).
    pub fn due(&self, now: Instant) -> bool {
        self.next.is_none_or(|n| now >= n)
    }

    /// Periodic ticks skipped so far because the loop came too late for them.
    pub fn missed(&self) -> u64 {
        self.missed
    }
}

/// The pace of a message sent when something changes (a status): at once, but at most one
/// every `gap`; a change meanwhile waits for the gap's end (its sender asks again then), so
/// a flood of changes sends at most one message a gap. Beside it, the message's regular
/// period.
#[derive(Debug, Clone, Copy)]
pub struct Spaced {
    every: Period,
    gap: Duration,
    last: Option<Instant>,
}

impl Spaced {
    /// A message every `period`, and on change at most one every `gap`.
    pub fn new(period: Duration, gap: Duration) -> Spaced {
        Spaced {
            every: Period::hz(1.0 / period.as_secs_f64()),
            gap,
            last: None,
        }
    }

    /// True when the message goes at `now`: its period is due, or it `changed` and the gap
    /// since the last one has passed. A true answer counts it as sent.
    pub fn take(&mut self, now: Instant, changed: bool) -> bool {
        let room = self
            .last
            .is_none_or(|at| now.saturating_duration_since(at) >= self.gap);
        let go = self.every.due(now) || (changed && room);
        if go {
            self.last = Some(now);
            if self.every.due(now) {
                self.every.next(now);
            }
        }
        go
    }

    /// When the message may next go: its period's deadline, or (`changed`) a gap after the
    /// last, whichever comes first.
    pub fn wake(&self, changed: bool) -> Option<Instant> {
        let period = self.every.next;
        let gap = self.last.map(|at| at + self.gap).filter(|_| changed);
        match (period, gap) {
            (Some(p), Some(g)) => Some(p.min(g)),
            (p, g) => p.or(g),
        }
    }
}

/// A stream's pace: a message every period while there is news, every idle period while
/// nothing changes (a body at rest, a still joint). News brings the full rate back at once;
/// a missed message is skipped, not caught up in a burst.
#[derive(Debug, Clone, Copy)]
pub struct Paced {
    period: Duration,
    idle: Duration,
    last: Option<Instant>,
}

impl Paced {
    /// `rate_hz` messages a second, `idle_hz` while idle (at most `rate_hz`).
    pub fn hz(rate_hz: f64, idle_hz: f64) -> Paced {
        Paced {
            period: Duration::from_secs_f64(1.0 / rate_hz),
            idle: Duration::from_secs_f64(1.0 / idle_hz.min(rate_hz)),
            last: None,
        }
    }

    /// True when a message is due at `now` (the first always is), at the idle pace when
    /// `idle`; a true answer counts the message as sent.
    pub fn take(&mut self, now: Instant, idle: bool) -> bool {
        let every = if idle { self.idle } else { self.period };
        let due = match self.last {
            None => true,
            Some(at) => now >= at + every,
        };
        if due {
            // On the period's grid while on time, from now after a gap.
            self.last = Some(match self.last {
                Some(at) if now < at + every + every => at + every,
                _ => now,
            });
        }
        due
    }
}

/// How the frame judges its loop: the periodic ticks' lateness over a window, and what the
/// heartbeat says of it.
#[derive(Debug, Clone)]
pub(crate) struct LoopWatch {
    since: Option<Instant>,
    turns: u64,
    missed: u64,
    worst: Duration,
    note: Option<String>,
}

impl LoopWatch {
    /// The window over which lateness is told.
    pub(crate) const WINDOW: Duration = Duration::from_secs(1);

    pub(crate) fn new() -> LoopWatch {
        LoopWatch {
            since: None,
            turns: 0,
            missed: 0,
            worst: Duration::ZERO,
            note: None,
        }
    }

    /// A tick at `now` for the time `due` the app asked for, `interval` after the tick that
    /// asked: it missed its time when it came more than that interval late. Returns the
    /// heartbeat's new word on the loop when it changes at the window's end (None inside:
    /// nothing to say; Some(None): on time again).
    pub(crate) fn on_tick(
        &mut self,
        due: Instant,
        interval: Duration,
        now: Instant,
    ) -> Option<Option<String>> {
        let since = *self.since.get_or_insert(now);
        let late = now.saturating_duration_since(due);
        self.turns += 1;
        // A period late, and more than a scheduler's hiccup on a busy machine (a loop of a
        // kilohertz is not late for being 2 ms after its time).
        if late > interval.max(LATE_FLOOR) {
            self.missed += 1;
        }
        self.worst = self.worst.max(late);
        let span = now.saturating_duration_since(since);
        if span < Self::WINDOW {
            return None;
        }
        let note = (self.missed > 0).then(|| {
            format!(
                "control loop late: {} of {} turns came a period or more after their time \
                 (worst {:.0} ms) in the last {:.1} s",
                self.missed,
                self.turns,
                self.worst.as_secs_f64() * 1e3,
                span.as_secs_f64()
            )
        });
        self.since = Some(now);
        self.turns = 0;
        self.missed = 0;
        self.worst = Duration::ZERO;
        (note != self.note).then(|| {
            self.note = note.clone();
            note
        })
    }
}

/// Later than this a periodic tick is late, whatever its period.
const LATE_FLOOR: Duration = Duration::from_millis(5);

/// The most messages handled between two looks at the app's time: a flood faster than the
/// node can take keeps its periodic ticks coming.
const MESSAGES_PER_TURN: usize = 1000;

impl Node {
    /// Runs `app` until shutdown (a signal, [`Node::exit_with`], or stdout closed under a
    /// pipe), handling messages between its ticks; then stops it. Marks the node running
    /// first unless the app set another state or said what it is starting on (a launcher
    /// starts what depends on it only once it runs). Returns the exit status asked for.
    ///
    /// A tick caused by a message never puts the app's next periodic tick later than it
    /// was (only earlier, should the app ask). Periodic ticks that come a period or more
    /// late are told in the heartbeat (DEGRADED, with the figures); a loop that does not come
    /// round for [`crate::STALL_AFTER`] past its time is told as STALLED while it lasts.
    pub fn run<T: Tick>(&self, mut app: T) -> anyhow::Result<ExitCode> {
        let h = self.health();
        if h.state == stride_lcmtypes::stride::NodeStatusT::STATE_STARTING && h.detail.is_empty() {
            self.set_running();
        }
        let mut wake = Instant::now();
        let mut asked = Duration::ZERO;
        let mut watch = LoopWatch::new();
        let mut next_pipe_check = Instant::now();
        let mut result = Ok(());
        while self.running() {
            self.set_loop_deadline(Some(wake));
            let wait = wake.saturating_duration_since(Instant::now());
            let before = self.lcm().stats().received;
            let got = match self.lcm().handle_timeout(wait) {
                Ok(true) => self.handle_some(),
                other => other.map(|_| ()),
            };
            // Only a message for one of the app's subscriptions counts: the rest of the
            // bus's traffic (every process on a multicast group receives all of it) does not.
            if let Err(e) = got {
                result = Err(anyhow::Error::new(e).context("handling LCM"));
                break;
            }
            let got = self.lcm().stats().received != before;
            let now = Instant::now();
            if now >= next_pipe_check {
                next_pipe_check = now + Duration::from_millis(50);
                if stdout_closed() {
                    tracing::info!("stdout closed; stopping");
                    break;
                }
            }
            let periodic = now >= wake;
            if periodic || (got && (T::WAKE_ON_MESSAGE || app.urgent())) {
                if periodic {
                    if let Some(note) = watch.on_tick(wake, asked, now) {
                        self.set_loop_note(note);
                    }
                }
                match app.tick(self, now) {
                    Ok(w) => {
                        // A message's tick may bring the next one forward, never put it off.
                        let w = if periodic { w } else { w.min(wake) };
                        if periodic || w < wake {
                            asked = w.saturating_duration_since(now);
                        }
                        wake = w;
                    }
                    Err(e) => {
                        result = Err(e);
                        break;
                    }
                }
            }
        }
        self.set_loop_deadline(None);
        tracing::info!(node = self.name(), "shutting down");
        let stopped = app.stop(self);
        result?;
        stopped?;
        Ok(ExitCode::from(self.exit.load(Ordering::Relaxed)))
    }

    /// Handles the messages waiting, at most [`MESSAGES_PER_TURN`] (one was already): a tick
    /// sees every message that came before it (a loop that wakes late after a stall sees
    /// the news of the stall, not only the first message), and a flood still lets it tick.
    fn handle_some(&self) -> lcm::Result<()> {
        for _ in 1..MESSAGES_PER_TURN {
            if !self.lcm().handle_timeout(Duration::ZERO)? {
                break;
            }
        }
        Ok(())
    }

    /// Ends [`Node::run`] with exit status `code`.
    pub fn exit_with(&self, code: u8) {
        self.exit.store(code, Ordering::Relaxed);
        self.request_shutdown();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Default, serde::Deserialize)]
    #[serde(deny_unknown_fields, default)]
    struct Opt {
        rate_hz: f64,
    }
    impl AppConfig for Opt {
        const USE: ConfigUse = ConfigUse::Optional;
        fn defaults() -> Option<Self> {
            Some(Opt { rate_hz: 10.0 })
        }
        fn check(&self) -> Result<(), String> {
            if self.rate_hz > 0.0 {
                Ok(())
            } else {
                Err(format!("rate_hz {} must be positive", self.rate_hz))
            }
        }
    }
    #[derive(Debug, serde::Deserialize)]
    struct Req {}
    impl AppConfig for Req {
        const USE: ConfigUse = ConfigUse::Required("see config/robots/");
    }

    #[test]
    fn an_app_without_config_refuses_one() {
        let e = app_config::<NoConfig>(Some(Path::new("/nonexistent.toml"))).unwrap_err();
        assert!(format!("{e:#}").contains("takes no configuration"), "{e:#}");
        assert!(app_config::<NoConfig>(None).is_ok());
    }

    #[test]
    fn a_required_config_points_at_examples() {
        let e = format!("{:#}", app_config::<Req>(None).unwrap_err());
        assert!(
            e.contains("--config") && e.contains("config/robots/"),
            "{e}"
        );
    }

    #[test]
    fn config_is_checked_and_errors_are_one_line() {
        assert_eq!(app_config::<Opt>(None).unwrap().rate_hz, 10.0);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.toml");
        std::fs::write(&p, "rate_hz = -1.0\n").unwrap();
        let e = format!("{:#}", app_config::<Opt>(Some(&p)).unwrap_err());
        assert!(e.contains("c.toml") && e.contains("positive"), "{e}");
        std::fs::write(&p, "rate = 5.0\n").unwrap();
        let e = format!("{:#}", app_config::<Opt>(Some(&p)).unwrap_err());
        assert!(e.contains("rate") && !e.contains('\n'), "{e}");
    }

    #[test]
    fn an_unknown_log_level_is_an_error() {
        if std::env::var_os("RUST_LOG").is_some() {
            return;
        }
        assert!(check_log_filter("info,lcm=debug").is_ok());
        assert!(check_log_filter("nonsense=+==").is_err());
    }

    #[test]
    fn a_broken_pipe_is_quiet() {
        let e = anyhow::Error::new(std::io::Error::from(std::io::ErrorKind::BrokenPipe))
            .context("printing");
        assert!(is_broken_pipe(&e));
        assert!(!is_broken_pipe(&anyhow::anyhow!("other")));
    }

    #[test]
    fn a_paced_stream_slows_while_idle_and_speeds_up_at_once() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut p = Paced::hz(50.0, 10.0);
        let sent = |p: &mut Paced, from: u64, to: u64, idle: bool| {
            (from..to).filter(|&i| p.take(t0 + ms(i), idle)).count()
        };
        // 50 Hz for a second, on the grid.
        assert_eq!(sent(&mut p, 0, 1000, false), 50);
        // Idle: 10 Hz.
        assert_eq!(sent(&mut p, 1000, 2000, true), 10);
        // News: the next message a full period after the last, not an idle one.
        let mut p = Paced::hz(50.0, 10.0);
        assert!(p.take(t0, true));
        assert!(!p.take(t0 + ms(50), true));
        assert!(p.take(t0 + ms(100), true));
        assert!(p.take(t0 + ms(120), false));
        assert!(!p.take(t0 + ms(130), false));
        assert!(p.take(t0 + ms(140), false));
        // A long gap sends one, then keeps the period from it (no burst).
        assert!(p.take(t0 + ms(10_000), false));
        assert!(!p.take(t0 + ms(10_019), false));
        assert!(p.take(t0 + ms(10_020), false));
    }

    #[test]
    fn a_period_skips_missed_ticks() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut p = Period::hz(100.0);
        assert!(p.due(t0));
        assert_eq!(p.next(t0), t0 + ms(10));
        assert!(!p.due(t0 + ms(5)));
        // On time: on the grid.
        assert_eq!(p.next(t0 + ms(11)), t0 + ms(20));
        let late = t0 + ms(65);
        assert_eq!(p.next(late), late + ms(10));
        assert_eq!(p.missed(), 4);
    }

    /// D1 of the reliability findings: every message-driven tick moved the periodic deadline
    /// a period on, so a burst of 100 messages silenced a 100 Hz loop for a second.
    #[test]
    fn a_burst_of_message_ticks_does_not_move_the_periodic_deadline() {
        let t0 = Instant::now();
        let us = Duration::from_micros;
        let mut p = Period::hz(100.0);
        let first = p.next(t0);
        // 100 messages within the first period, each ticking the app.
        for i in 1..=100 {
            assert_eq!(p.next(t0 + us(i * 50)), first);
        }
        assert!(p.due(first));
        assert_eq!(p.next(first), first + Duration::from_millis(10));
        assert_eq!(p.missed(), 0);
    }

    #[test]
    fn a_change_driven_message_goes_at_most_once_a_gap() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut s = Spaced::new(Duration::from_secs(1), ms(50));
        assert!(s.take(t0, false), "the first goes");
        // A change every 10 ms for a second (a figure in a reason changing each tick): 20.
        let sent = (1..=100).filter(|i| s.take(t0 + ms(i * 10), true)).count();
        assert_eq!(sent, 20);
        // Nothing changes: once a period.
        let quiet = (101..=300)
            .filter(|i| s.take(t0 + ms(i * 10), false))
            .count();
        assert_eq!(quiet, 2);
    }

    #[test]
    fn a_loop_whose_ticks_miss_their_period_says_so_and_then_recovers() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut w = LoopWatch::new();
        let period = ms(10);
        // On time for a second: nothing to say.
        let mut said = None;
        for i in 0..=100 {
            let at = t0 + ms(i * 10);
            if let Some(n) = w.on_tick(at, period, at + ms(1)) {
                said = Some(n);
            }
        }
        assert!(said.is_none(), "{said:?}");
        // Ticks 45 ms late for a second: told, with the figure.
        let t1 = t0 + ms(1010);
        let mut said = None;
        for i in 0..=25 {
            let due = t1 + ms(i * 40);
            if let Some(n) = w.on_tick(due, period, due + ms(45)) {
                said = Some(n);
            }
        }
        let note = said.flatten().expect("late ticks are told");
        assert!(note.contains("worst 45 ms"), "{note}");
        // On time again: the word is taken back once a whole window was.
        let t2 = t1 + ms(1100);
        let mut said = None;
        for i in 0..=250 {
            let at = t2 + ms(i * 10);
            if let Some(n) = w.on_tick(at, period, at) {
                said = Some(n);
            }
        }
        assert_eq!(said, Some(None));
    }
}
