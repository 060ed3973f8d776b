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

/// The running bridge.
pub struct Bridge {
    session: zenoh::Session,
    _subscriber: zenoh::pubsub::Subscriber<()>,
    _lcm: lcm::Subscription,
    state: Arc<Mutex<State>>,
    last: Counters,
    next_log: Instant,
}

fn json_str(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_default()
}

fn json_list(v: &[String]) -> String {
    serde_json::to_string(v).unwrap_or_default()
}

/// The Zenoh configuration of `cfg`: its mode and endpoints, multicast scouting off.
pub fn zenoh_config(cfg: &BridgeConfig) -> anyhow::Result<zenoh::Config> {
    let mut z = zenoh::Config::default();
    let set = |z: &mut zenoh::Config, key: &str, value: String| {
        z.insert_json5(key, &value)
            .map_err(|e| anyhow::anyhow!("zenoh configuration {key} = {value}: {e}"))
    };
    set(&mut z, "mode", json_str(&cfg.zenoh.mode))?;
    set(&mut z, "listen/endpoints", json_list(&cfg.zenoh.listen))?;
    set(&mut z, "connect/endpoints", json_list(&cfg.zenoh.connect))?;
    set(&mut z, "scouting/multicast/enabled", "false".into())?;
    // Nothing is scouted: the session need not wait for it (a bridge that listens starts
    // before the others connect).
    set(
        &mut z,
        "open/return_conditions/connect_scouted",
        "false".into(),
    )?;
    Ok(z)
}

impl Bridge {
    /// Opens the Zenoh session and joins both sides.
    pub fn start(node: &Node, cfg: BridgeConfig) -> anyhow::Result<Bridge> {
        let session = zenoh::open(zenoh_config(&cfg)?)
            .wait()
            .map_err(|e| anyhow::anyhow!("opening the Zenoh session: {e}"))?;
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
            .map_err(|e| anyhow::anyhow!("subscribing to {}/** on Zenoh: {e}", cfg.prefix))?;

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
        let state = if c.errors > self.last.errors {
            NodeStatusT::STATE_DEGRADED
        } else {
            NodeStatusT::STATE_RUNNING
        };
        node.set_health(state, c.to_string());
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
            .map_err(|e| anyhow::anyhow!("closing the Zenoh session: {e}"))
    }
}
