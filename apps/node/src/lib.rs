//! The runtime shared by every stride executable.
//!
//! It gives each app the same command-line flags ([`NodeArgs`]: `--lcm-url`, `--config`,
//! `--log-level`, `--name`), `tracing` logs, TOML configuration with a typed check
//! ([`AppConfig`]), a [`stride.node_status_t`](stride_lcmtypes::stride::NodeStatusT) heartbeat
//! published at 1 Hz on `STRIDE_STATUS` (and at once when the app's health changes), queues of
//! incoming messages ([`Node::queue`]), the loop that drives an app's state machine ([`Tick`],
//! [`Node::run`]) and a clean shutdown on SIGINT/SIGTERM or a closed stdout. [`main`] (and
//! [`tool`] for programs that do not join the bus) turns the whole run into an exit status,
//! errors in one line. An app's `main.rs` only wires its lib.rs to the frame (the example at
//! [`main`]).

mod app;
mod config;
mod heartbeat;
pub mod realtime;
mod stamp;
mod throttle;
mod worker;

pub use app::{
    app_config, check_log_filter, is_broken_pipe, main, stdout_closed, tool, AppConfig, ConfigUse,
    Launch, NoConfig, NodeCli, Paced, Period, Spaced, Tick,
};
pub use config::load_config;
pub use stamp::Stamper;
pub use throttle::{Note, Throttle};
pub use worker::{Done, Worker};

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use lcm::Lcm;

/// Default channel of the heartbeat.
pub const STATUS_CHANNEL: &str = "STRIDE_STATUS";

/// A node's loop that has not come round for this long past the time its app asked for is
/// stalled: its heartbeat says STALLED while it lasts (and a launcher stops the robot). A
/// shorter hiccup is the devices' to absorb: a gait's rows run out after its lookahead and
/// the bridges bring the joints to rest; a bridge's drives stop on their own watchdog.
pub const STALL_AFTER: Duration = Duration::from_secs(1);

/// Command-line flags every stride executable accepts (flatten them into the app's parser).
#[derive(Debug, Clone, clap::Args)]
pub struct NodeArgs {
    /// LCM URL of the bus, e.g. udpm://239.255.76.67:7667?ttl=0 (same machine only) or
    /// udpm://239.255.76.67:7667?ttl=1 (the local network). Empty: $LCM_DEFAULT_URL, then
    /// liblcm's default (ttl=0).
    #[arg(long, env = "STRIDE_LCM_URL", default_value = "", value_name = "URL")]
    pub lcm_url: String,

    /// A second bus on this computer for the channels of --local (the robot's full-rate data),
    /// e.g. udpm://239.255.76.67:7668?ttl=0 beside a shared --lcm-url with ttl=1 that other
    /// hosts join. Empty: one bus.
    #[arg(long, env = "STRIDE_LOCAL_URL", default_value = "", value_name = "URL")]
    pub local_url: String,

    /// The channels that go to the local bus: regular expressions, comma-separated (e.g.
    /// `JOINT_.*,CAN_.*`). Publishing and subscribing pick the bus by the channel's name.
    #[arg(
        long = "local",
        env = "STRIDE_LOCAL_CHANNELS",
        value_delimiter = ',',
        value_name = "REGEX,..."
    )]
    pub local_channels: Vec<String>,

    /// TOML configuration file of this app.
    #[arg(long, short = 'c', value_name = "FILE")]
    pub config: Option<PathBuf>,

    /// Log filter: error, warn, info, debug, trace, or a tracing directive such as
    /// `info,lcm=debug`. RUST_LOG, when set, takes precedence. A launcher passes its own to
    /// the apps it starts.
    #[arg(
        long,
        env = "STRIDE_LOG_LEVEL",
        default_value = "info",
        value_name = "FILTER"
    )]
    pub log_level: String,

    /// Node name in logs and heartbeats (default: the app's name). Must be unique on the bus.
    #[arg(long, value_name = "NAME")]
    pub name: Option<String>,

    /// Channel of the 1 Hz heartbeat (stride.node_status_t).
    #[arg(long, default_value = STATUS_CHANNEL, value_name = "CHANNEL")]
    pub status_channel: String,

    /// Real-time priority (SCHED_FIFO, 1 to 99) of the apps that keep time with motors (the
    /// gait, the bridges, the CAN gateway, the fake devices); 0: normal scheduling. Others
    /// ignore it. Refused without CAP_SYS_NICE or an rtprio limit: a warning, no error.
    #[arg(
        long,
        env = "STRIDE_RT_PRIORITY",
        default_value_t = 0,
        value_name = "PRIORITY",
        value_parser = clap::value_parser!(u8).range(0..=99)
    )]
    pub rt_priority: u8,
}

impl Default for NodeArgs {
    fn default() -> Self {
        NodeArgs {
            lcm_url: String::new(),
            local_url: String::new(),
            local_channels: Vec::new(),
            config: None,
            log_level: "info".into(),
            name: None,
            status_channel: STATUS_CHANNEL.into(),
            rt_priority: 0,
        }
    }
}

/// The LCM instance the flags ask for: one bus, or a shared one with a local one beside it.
pub fn bus(args: &NodeArgs) -> anyhow::Result<Lcm> {
    let channels: Vec<String> = args
        .local_channels
        .iter()
        .map(|c| c.trim().to_owned())
        .filter(|c| !c.is_empty())
        .collect();
    match (args.local_url.is_empty(), channels.is_empty()) {
        (true, true) => Ok(Lcm::new(&args.lcm_url)?),
        (true, false) => anyhow::bail!("--local {} needs --local-url", channels.join(",")),
        (false, true) => anyhow::bail!(
            "--local-url {} needs --local CHANNELS (the channels that go there)",
            args.local_url
        ),
        (false, false) => Ok(Lcm::with_local(&args.lcm_url, &args.local_url, &channels)?),
    }
}

/// Installs the `tracing` subscriber (stderr, `RUST_LOG` or `filter`). Safe to call twice.
pub fn init_logging(filter: &str) {
    let env = tracing_subscriber::EnvFilter::try_from_default_env()
        .or_else(|_| tracing_subscriber::EnvFilter::try_new(filter))
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    use std::io::IsTerminal;
    let _ = tracing_subscriber::fmt()
        .with_env_filter(env)
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .try_init();
}

/// A flag that SIGINT or SIGTERM sets; a second signal while it is set exits at once.
pub fn shutdown_on_signals() -> anyhow::Result<Arc<AtomicBool>> {
    let flag = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register_conditional_shutdown(sig, 1, flag.clone())
            .context("installing the signal handler")?;
        signal_hook::flag::register(sig, flag.clone()).context("installing the signal handler")?;
    }
    Ok(flag)
}

/// What a node reports about itself in its heartbeat.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Health {
    /// One of `NodeStatusT::STATE_*`.
    pub state: i8,
    /// Why, in words ("" when running normally).
    pub detail: String,
}

/// A running stride node: its LCM instance, heartbeat and shutdown flag.
///
/// Dropping it stops the heartbeat after publishing a final `STATE_STOPPING` status.
pub struct Node {
    name: String,
    lcm: Lcm,
    shutdown: Arc<AtomicBool>,
    health: Arc<Mutex<Health>>,
    heartbeat: Option<heartbeat::Heartbeat>,
    started: Instant,
    exit: AtomicU8,
    /// How the loop keeps its time (see [`LoopState`]).
    loop_state: Arc<LoopState>,
}

/// What [`Node::run`] tells the heartbeat of its loop.
#[derive(Debug, Default)]
pub(crate) struct LoopState {
    /// The time the loop waits for, ns after the node's start, plus one (0: no loop runs).
    deadline: AtomicU64,
    /// The loop's lateness, in words, while it misses its period.
    note: Mutex<Option<String>>,
}

impl LoopState {
    /// How long the loop has been overdue at `now` (the node started at `started`), when it
    /// runs and is.
    pub(crate) fn overdue(&self, started: Instant, now: Instant) -> Option<Duration> {
        let d = self.deadline.load(Ordering::Relaxed);
        let since = now.saturating_duration_since(started).as_nanos() as u64 + 1;
        (d > 0 && since > d).then(|| Duration::from_nanos(since - d))
    }

    /// The time the loop waits for (None: no loop runs).
    pub(crate) fn deadline(&self, started: Instant) -> Option<Instant> {
        match self.deadline.load(Ordering::Relaxed) {
            0 => None,
            d => Some(started + Duration::from_nanos(d - 1)),
        }
    }

    pub(crate) fn note(&self) -> Option<String> {
        self.note.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }
}

impl std::fmt::Debug for Node {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Node")
            .field("name", &self.name)
            .field("url", &self.lcm.url())
            .finish()
    }
}

impl Node {
    /// Sets up logging, creates the LCM instance, installs the SIGINT/SIGTERM handlers and
    /// starts the heartbeat. `default_name` is used unless `--name` was given.
    pub fn start(default_name: &str, args: &NodeArgs) -> anyhow::Result<Node> {
        init_logging(&args.log_level);
        realtime::log_outcome();
        let name = args.name.clone().unwrap_or_else(|| default_name.to_owned());
        let lcm = bus(args)?;
        let shutdown = shutdown_on_signals()?;
        let health = Arc::new(Mutex::new(Health {
            state: stride_lcmtypes::stride::NodeStatusT::STATE_STARTING,
            detail: String::new(),
        }));
        let started = Instant::now();
        let loop_state = Arc::new(LoopState::default());
        let heartbeat = heartbeat::Heartbeat::spawn(
            lcm.publisher(),
            args.status_channel.clone(),
            name.clone(),
            health.clone(),
            loop_state.clone(),
            started,
            Duration::from_secs(1),
        )?;
        match lcm.local_bus() {
            Some((local, channels)) => tracing::info!(
                node = name.as_str(),
                url = lcm.url(),
                local,
                channels = channels.join(",").as_str(),
                "node started"
            ),
            None => tracing::info!(node = name.as_str(), url = lcm.url(), "node started"),
        }
        Ok(Node {
            name,
            lcm,
            shutdown,
            health,
            heartbeat: Some(heartbeat),
            started,
            exit: AtomicU8::new(0),
            loop_state,
        })
    }

    /// The node's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The node's LCM instance (subscribe and handle here).
    pub fn lcm(&self) -> &Lcm {
        &self.lcm
    }

    /// A thread-safe publisher on the node's bus.
    pub fn publisher(&self) -> lcm::Publisher {
        self.lcm.publisher()
    }

    /// Time since the node started.
    pub fn uptime(&self) -> Duration {
        self.started.elapsed()
    }

    /// Sets the state and detail the heartbeat reports; a change is published at once.
    pub fn set_health(&self, state: i8, detail: impl Into<String>) {
        let detail = detail.into();
        let mut h = self.health.lock().unwrap_or_else(|p| p.into_inner());
        if h.state == state && h.detail == detail {
            return;
        }
        h.state = state;
        h.detail = detail;
        drop(h);
        if let Some(hb) = &self.heartbeat {
            hb.poke();
        }
    }

    /// The time the loop waits for next (None: it has ended).
    pub(crate) fn set_loop_deadline(&self, at: Option<Instant>) {
        let v = at.map_or(0, |t| {
            t.saturating_duration_since(self.started).as_nanos() as u64 + 1
        });
        self.loop_state.deadline.store(v, Ordering::Relaxed);
    }

    /// What the loop's lateness is, in words (None: on time); a change is published at once.
    pub(crate) fn set_loop_note(&self, note: Option<String>) {
        // Said on the console when it begins and ends; the heartbeat carries the figures.
        let was = self.loop_state.note().is_some();
        match &note {
            Some(n) if !was => tracing::warn!("{n}"),
            Some(n) => tracing::debug!("{n}"),
            None if was => tracing::info!("control loop on time again"),
            None => {}
        }
        *self
            .loop_state
            .note
            .lock()
            .unwrap_or_else(|p| p.into_inner()) = note;
        if let Some(hb) = &self.heartbeat {
            hb.poke();
        }
    }

    /// The state and detail the app set (the heartbeat adds what it knows of the loop).
    pub fn health(&self) -> Health {
        self.health
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }

    /// Marks the node running (the state most apps report after start-up).
    pub fn set_running(&self) {
        self.set_health(stride_lcmtypes::stride::NodeStatusT::STATE_RUNNING, "");
    }

    /// False once SIGINT/SIGTERM arrived or [`Node::request_shutdown`] was called.
    pub fn running(&self) -> bool {
        !self.shutdown.load(Ordering::Relaxed)
    }

    /// Asks the loop to stop, as a signal would.
    pub fn request_shutdown(&self) {
        self.shutdown.store(true, Ordering::Relaxed);
    }

    /// The flag the signal handlers set; share it with worker threads.
    pub fn shutdown_flag(&self) -> Arc<AtomicBool> {
        self.shutdown.clone()
    }

    /// Subscribes to `channel` and queues each decoded message for the main loop (a loop that
    /// does its work between [`Ticker`] ticks takes them with `try_recv`).
    pub fn queue<M>(
        &self,
        channel: &str,
    ) -> anyhow::Result<(lcm::Subscription, std::sync::mpsc::Receiver<M>)>
    where
        M: lcm::Message + Send + 'static,
    {
        let (tx, rx) = std::sync::mpsc::channel();
        let sub = self.lcm.subscribe(channel, move |_, m: M| {
            let _ = tx.send(m);
        })?;
        Ok((sub, rx))
    }

    /// Handles messages until shutdown is requested. Marks the node running first.
    pub fn spin(&self) -> anyhow::Result<()> {
        self.spin_with(Duration::from_millis(100), || Ok(()))
    }

    /// Handles messages until shutdown, calling `tick` after each message and at least every
    /// `period`.
    pub fn spin_with(
        &self,
        period: Duration,
        mut tick: impl FnMut() -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        self.set_running();
        while self.running() {
            self.lcm.handle_timeout(period)?;
            tick()?;
        }
        tracing::info!(node = self.name.as_str(), "shutting down");
        Ok(())
    }
}

impl Drop for Node {
    fn drop(&mut self) {
        self.set_health(
            stride_lcmtypes::stride::NodeStatusT::STATE_STOPPING,
            "shutting down",
        );
        if let Some(hb) = self.heartbeat.take() {
            hb.stop();
        }
        let s = self.lcm.stats();
        tracing::info!(
            node = self.name.as_str(),
            published = s.published,
            received = s.received,
            decode_errors = s.decode_errors,
            handler_panics = s.handler_panics,
            lost = s.lost,
            "node stopped"
        );
    }
}

/// A loop at a fixed rate that handles LCM messages while it waits for the next tick.
#[derive(Debug, Clone)]
pub struct Ticker {
    period: Duration,
    next: Instant,
}

impl Ticker {
    /// Ticks `rate_hz` times a second, the first one now.
    pub fn new(rate_hz: f64) -> Ticker {
        Ticker {
            period: Duration::from_secs_f64(1.0 / rate_hz),
            next: Instant::now(),
        }
    }

    /// Handles `node`'s messages until the next tick and returns its time; `None` once the
    /// node is shutting down. A tick missed by more than a period is skipped, not caught up in
    /// a burst.
    pub fn wait(&mut self, node: &Node) -> anyhow::Result<Option<Instant>> {
        loop {
            if !node.running() {
                return Ok(None);
            }
            let now = Instant::now();
            if now >= self.next {
                self.next += self.period;
                if self.next < now {
                    self.next = now + self.period;
                }
                return Ok(Some(now));
            }
            node.lcm().handle_timeout(self.next - now)?;
        }
    }
}
