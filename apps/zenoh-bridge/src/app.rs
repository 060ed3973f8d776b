//! The running bridge: a Zenoh session beside the node's LCM instance, each side's messages
//! handed to the other in the callback that receives them (no queue between: the hop adds
//! what Zenoh and liblcm take, nothing more).

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use regex::Regex;
use stride_lcmtypes::stride::NodeStatusT;
use stride_node::{AppConfig, ConfigUse, Node, NodeArgs, Tick};
use zenoh::qos::CongestionControl;
use zenoh::Wait;

use crate::{anchored, channel_of, key_of, BridgeConfig, Counters, Echoes, Out, Outgoing};

/// Carries chosen LCM channels between buses that share no multicast (another subnet, a
/// routed Wi-Fi link, a remote operator), over Zenoh: each message's LCM bytes unchanged,
/// under the key PREFIX/CHANNEL. Run one on each bus, each with its own `bus` name; a
/// message never goes back to the bus it came from, so any number of buses may be joined.
///
/// See config/zenoh-bridge-robot.toml and config/zenoh-bridge-operator.toml.
#[derive(clap::Parser, Debug)]
#[command(name = "stride-zenoh-bridge", version, about, long_about)]
pub struct Cli {
    #[command(flatten)]
    node: NodeArgs,
}

stride_node::node_cli!(Cli);

impl Cli {
    /// The configuration file given (its folder is where relative paths start).
    pub fn config_file(&self) -> Option<&std::path::Path> {
        self.node.config.as_deref()
    }

    /// Zenoh's own warnings held back (unless RUST_LOG or the filter speaks of zenoh): what
    /// they say comes as the bridge's one-line error or its heartbeat.
    pub fn quiet_zenoh(&mut self) {
        if !self.node.log_level.contains("zenoh") {
            self.node.log_level.push_str(",zenoh=error");
        }
    }
}

/// A Zenoh error in one line, without the places in Zenoh's sources it names (" at
/// /…/src/tcp.rs:61.").
pub fn one_line(e: impl std::fmt::Display) -> String {
    let text = e.to_string().replace('\n', " ");
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(i) = rest.find(" at ") {
        out.push_str(&rest[..i]);
        let after = &rest[i + 4..];
        let end = after.find(char::is_whitespace).unwrap_or(after.len());
        let word = &after[..end];
        if word.contains(".rs:") {
            rest = &after[end..];
        } else {
            out.push_str(" at ");
            rest = after;
        }
    }
    out.push_str(rest);
    out.trim().trim_end_matches('.').to_owned()
}

impl AppConfig for BridgeConfig {
    const USE: ConfigUse = ConfigUse::Required(
        "the bus's name, the Zenoh endpoints and the channels; see config/zenoh-bridge-robot.toml",
    );
    fn check(&self) -> Result<(), String> {
        BridgeConfig::check(self)
    }
}

/// What both sides share.
struct State {
    outgoing: Outgoing,
    echoes: Echoes,
    counters: Counters,
}

fn lock(s: &Mutex<State>) -> std::sync::MutexGuard<'_, State> {
    s.lock().unwrap_or_else(|e| e.into_inner())
}

/// How long a message the bridge published is remembered, waiting for the bus to hand it
/// back (liblcm loops it back in well under a millisecond).
const ECHO_MEMORY: Duration = Duration::from_secs(2);

/// Messages from the bus that may wait for the bridge (liblcm's queue of the subscription).
const BUS_QUEUE: usize = 10_000;

/// The most channels carried out (a Zenoh publisher each).
const MAX_CHANNELS: usize = 4096;

/// The running bridge.
pub struct Bridge {
    session: zenoh::Session,
    _subscriber: zenoh::pubsub::Subscriber<()>,
    _lcm: lcm::Subscription,
    state: Arc<Mutex<State>>,
    last: Counters,
    next_log: Instant,
    /// Where it listens and connects, in words.
    endpoints: String,
    /// Whether it was last connected to no peer (None: not looked at yet).
    alone: Option<bool>,
}

fn json_str(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_default()
}

fn json_list(v: &[String]) -> String {
    serde_json::to_string(v).unwrap_or_default()
}

/// The Zenoh configuration of `cfg` (its paths already relative to where it runs): its mode
/// and endpoints, TLS both ways and the users, multicast scouting off.
pub fn zenoh_config(cfg: &BridgeConfig) -> anyhow::Result<zenoh::Config> {
    let mut z = zenoh::Config::default();
    let set = |z: &mut zenoh::Config, key: &str, value: String| {
        z.insert_json5(key, &value)
            .map_err(|e| anyhow::anyhow!("zenoh configuration {key}: {}", one_line(e)))
    };
    set(&mut z, "mode", json_str(&cfg.zenoh.mode))?;
    set(&mut z, "listen/endpoints", json_list(&cfg.zenoh.listen))?;
    set(&mut z, "connect/endpoints", json_list(&cfg.zenoh.connect))?;
    let file = |p: &std::path::Path, what: &str| -> anyhow::Result<String> {
        if !p.is_file() {
            anyhow::bail!("{what} {} not found", p.display());
        }
        Ok(json_str(&p.to_string_lossy()))
    };
    if let Some(t) = &cfg.zenoh.tls {
        let (ca, cert, key) = (
            file(&t.ca, "zenoh.tls.ca")?,
            file(&t.certificate, "zenoh.tls.certificate")?,
            file(&t.key, "zenoh.tls.key")?,
        );
        let tls = "transport/link/tls";
        set(&mut z, &format!("{tls}/root_ca_certificate"), ca)?;
        set(&mut z, &format!("{tls}/listen_certificate"), cert.clone())?;
        set(&mut z, &format!("{tls}/listen_private_key"), key.clone())?;
        set(&mut z, &format!("{tls}/connect_certificate"), cert)?;
        set(&mut z, &format!("{tls}/connect_private_key"), key)?;
        // Mutual: a peer without a certificate of the authority is not let in.
        set(&mut z, &format!("{tls}/enable_mtls"), "true".into())?;
        set(
            &mut z,
            &format!("{tls}/verify_name_on_connect"),
            t.verify_name.to_string(),
        )?;
    }
    if let Some(a) = &cfg.zenoh.auth {
        let auth = "transport/auth/usrpwd";
        if let (Some(user), Some(pw)) = (&a.user, &a.password_file) {
            let text = std::fs::read_to_string(pw)
                .map_err(|e| anyhow::anyhow!("zenoh.auth.password_file {}: {e}", pw.display()))?;
            let password = text.lines().next().unwrap_or("").trim().to_owned();
            if password.is_empty() {
                anyhow::bail!("zenoh.auth.password_file {}: no password", pw.display());
            }
            set(&mut z, &format!("{auth}/user"), json_str(user))?;
            set(&mut z, &format!("{auth}/password"), json_str(&password))?;
        }
        if let Some(users) = &a.users_file {
            set(
                &mut z,
                &format!("{auth}/dictionary_file"),
                file(users, "zenoh.auth.users_file")?,
            )?;
        }
    }
    set(&mut z, "scouting/multicast/enabled", "false".into())?;
    // Nothing is scouted: the session need not wait for it (a bridge that listens starts
    // before the others connect).
    set(
        &mut z,
        "open/return_conditions/connect_scouted",
        "false".into(),
    )?;
    // A QUIC connect to a peer that is gone meets no refusal (no TCP reset): it waits out the
    // handshake's timeout, and closing the session waits for it. Zenoh's 10 s held a stopping
    // bridge that long; 3 s is several round trips of a poor Wi-Fi.
    set(&mut z, "transport/unicast/open_timeout", "3000".into())?;
    Ok(z)
}

impl Bridge {
    /// Opens the Zenoh session and joins both sides; `config_file` is where the
    /// configuration came from (its relative paths start in its folder).
    pub fn start(
        node: &Node,
        mut cfg: BridgeConfig,
        config_file: Option<&std::path::Path>,
    ) -> anyhow::Result<Bridge> {
        if let Some(dir) = config_file.and_then(std::path::Path::parent) {
            cfg.rebase(dir);
        }
        let session = zenoh::open(zenoh_config(&cfg)?)
            .wait()
            .map_err(|e| anyhow::anyhow!("opening the Zenoh session: {}", one_line(e)))?;
        let state = Arc::new(Mutex::new(State {
            outgoing: Outgoing::new(&cfg.out).map_err(anyhow::Error::msg)?,
            echoes: Echoes::new(ECHO_MEMORY),
            counters: Counters::default(),
        }));
        let bus: Arc<[u8]> = cfg.bus.as_bytes().into();

        // In: what the other buses send, on this bus.
        let inbound: Vec<Regex> = cfg
            .inbound
            .iter()
            .map(|p| anchored(p, "in pattern"))
            .collect::<Result<_, _>>()
            .map_err(anyhow::Error::msg)?;
        let publisher = node.publisher();
        let (st, prefix, own) = (state.clone(), cfg.prefix.clone(), bus.clone());
        let subscriber = session
            .declare_subscriber(format!("{}/**", cfg.prefix))
            // Not what this session sends itself.
            .allowed_origin(zenoh::sample::Locality::Remote)
            .callback(move |sample| {
                let Some(channel) = channel_of(&prefix, sample.key_expr().as_str()) else {
                    lock(&st).counters.bad_names += 1;
                    return;
                };
                if sample.attachment().is_some_and(|a| *a.to_bytes() == *own) {
                    lock(&st).counters.own_bus += 1;
                    return;
                }
                if !inbound.iter().any(|re| re.is_match(channel)) {
                    lock(&st).counters.not_taken += 1;
                    return;
                }
                let data = sample.payload().to_bytes();
                // Remembered first: the bus hands it back to this bridge at once.
                lock(&st).echoes.sent(channel, &data, Instant::now());
                let ok = publisher.publish_raw(channel, &data).is_ok();
                let mut s = lock(&st);
                if ok {
                    s.counters.received += 1;
                } else {
                    s.counters.errors += 1;
                }
            })
            .wait()
            .map_err(|e| {
                anyhow::anyhow!("subscribing to {}/** on Zenoh: {}", cfg.prefix, one_line(e))
            })?;

        // Out: what this bus says, to the others.
        let (st, z, prefix) = (state.clone(), session.clone(), cfg.prefix.clone());
        let mut publishers: HashMap<String, zenoh::pubsub::Publisher<'static>> = HashMap::new();
        let lcm_sub = node
            .lcm()
            .subscribe_raw(".*", move |info, data| {
                let now = Instant::now();
                let (decision, drop) = {
                    let mut s = lock(&st);
                    if s.echoes.is_echo(info.channel, data, now) {
                        s.counters.echoes += 1;
                        return;
                    }
                    let d = s.outgoing.decide(info.channel, now);
                    match d {
                        Out::RateLimited => s.counters.rate_limited += 1,
                        Out::BadName => s.counters.bad_names += 1,
                        _ => {}
                    }
                    (d, s.outgoing.drops_when_congested(info.channel))
                };
                if decision != Out::Send {
                    return;
                }
                let p = match publishers.get(info.channel) {
                    Some(p) => p,
                    // A publisher a channel: at most MAX_CHANNELS (a bus of ever new names
                    // grows nothing beyond).
                    None if publishers.len() >= MAX_CHANNELS => {
                        lock(&st).counters.bad_names += 1;
                        return;
                    }
                    None => {
                        let Some(key) = key_of(&prefix, info.channel) else {
                            return;
                        };
                        // Batched (a burst shares the link's frames) and, unless the
                        // rule says drop, waiting for room when the link is congested:
                        // Zenoh's default drops a message that finds its queue (two
                        // frames) full for 1 ms, which a burst of small messages sent one
                        // frame each did on a busy machine.
                        let congestion = if drop {
                            CongestionControl::Drop
                        } else {
                            CongestionControl::Block
                        };
                        match z
                            .declare_publisher(key)
                            .congestion_control(congestion)
                            .wait()
                        {
                            Ok(p) => publishers.entry(info.channel.to_owned()).or_insert(p),
                            Err(e) => {
                                tracing::warn!("declaring {}: {e}", info.channel);
                                lock(&st).counters.errors += 1;
                                return;
                            }
                        }
                    }
                };
                let ok = p.put(data).attachment(&*bus).wait().is_ok();
                let mut s = lock(&st);
                if ok {
                    s.counters.sent += 1;
                    s.counters.sent_bytes += data.len() as u64;
                } else {
                    s.counters.errors += 1;
                }
            })
            .context("subscribing to the bus")?;
        // A burst from the bus waits for the callback in liblcm's queue: its default of 30
        // messages dropped the rest of a burst of 32 or more before it reached Zenoh.
        lcm_sub
            .set_queue_capacity(BUS_QUEUE)
            .context("sizing the bus's queue")?;
        tracing::info!(
            "bridging bus {:?} under {}/**: listening on {:?}, connecting to {:?}",
            cfg.bus,
            cfg.prefix,
            cfg.zenoh.listen,
            cfg.zenoh.connect
        );
        Ok(Bridge {
            session,
            _subscriber: subscriber,
            _lcm: lcm_sub,
            state,
            last: Counters::default(),
            next_log: Instant::now() + Duration::from_secs(10),
            endpoints: format!(
                "listening on {:?}, connecting to {:?}",
                cfg.zenoh.listen, cfg.zenoh.connect
            ),
            alone: None,
        })
    }

    /// What the bridge did since it started.
    pub fn counters(&self) -> Counters {
        lock(&self.state).counters
    }
}

impl Tick for Bridge {
    const WAKE_ON_MESSAGE: bool = false;

    fn tick(&mut self, node: &Node, now: Instant) -> anyhow::Result<Instant> {
        let c = self.counters();
        // A link down looks like an idle one in the counters: the peers say which.
        let peers = self.session.info().peers_zid().wait().count()
            + self.session.info().routers_zid().wait().count();
        let alone = peers == 0;
        // Said on the console once it lasts (a bridge that starts waits a moment for its peer).
        let lasting = node.uptime() > Duration::from_secs(3);
        if lasting && self.alone != Some(alone) {
            if alone {
                tracing::warn!("connected to no peer ({})", self.endpoints);
            } else {
                tracing::info!("connected to {peers} peer(s)");
            }
            self.alone = Some(alone);
        }
        let (state, detail) = if alone {
            (
                NodeStatusT::STATE_DEGRADED,
                format!("connected to no peer ({}); {c}", self.endpoints),
            )
        } else if c.errors > self.last.errors {
            (NodeStatusT::STATE_DEGRADED, c.to_string())
        } else {
            (NodeStatusT::STATE_RUNNING, c.to_string())
        };
        node.set_health(state, detail);
        if now >= self.next_log {
            tracing::info!("{c}");
            self.next_log = now + Duration::from_secs(10);
        }
        self.last = c;
        Ok(now + Duration::from_secs(1))
    }

    fn stop(self, _node: &Node) -> anyhow::Result<()> {
        tracing::info!("{}", self.counters());
        drop(self._lcm);
        drop(self._subscriber);
        self.session
            .close()
            .wait()
            .map_err(|e| anyhow::anyhow!("closing the Zenoh session: {}", one_line(e)))
    }
}

#[cfg(test)]
mod tests {
    use super::one_line;

    /// D13 of the reliability findings: Zenoh's errors carried the build machine's paths.
    #[test]
    fn a_zenoh_error_is_one_line_without_source_paths() {
        let e = "Can not create a new TCP listener bound to tcp/127.0.0.1:7447: Address \
                 already in use (os error 98) at /root/.cargo/registry/src/index.crates.io-19/\
                 zenoh-link-commons-1.10.2/src/tcp.rs:61.";
        assert_eq!(
            one_line(e),
            "Can not create a new TCP listener bound to tcp/127.0.0.1:7447: Address already \
             in use (os error 98)"
        );
        assert_eq!(one_line("look at the\nport"), "look at the port");
    }
}
