//! The logic of `stride-zenoh-bridge`: which LCM channels leave this bus and how often, the
//! Zenoh key each travels under, and the memory that keeps a message the bridge brought in
//! from going back out. The Zenoh session and the LCM subscription are in [`app`].
//!
//! A message leaves as its LCM bytes, unchanged, under the key `PREFIX/CHANNEL`, with the
//! name of the bus it came from attached; a bridge takes in what comes under `PREFIX/**`
//! from other buses and publishes the bytes on its own bus under the same channel. It never
//! sends out what it brought in (its own bus hands that back to it), and never takes in
//! what came from its own bus: a loop of bridges does not multiply the traffic.

use std::collections::{HashMap, VecDeque};
use std::hash::{Hash, Hasher};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use regex::Regex;
use serde::Deserialize;

pub mod app;

pub use app::{Bridge, Cli};

/// The app's TOML configuration (see config/zenoh-bridge-*.toml).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BridgeConfig {
    /// This LCM bus's name, the same for no two bridged buses: a message carries it, and a
    /// bridge never takes in a message from its own bus.
    pub bus: String,
    /// Each channel travels under the Zenoh key `prefix/CHANNEL`.
    #[serde(default = "prefix")]
    pub prefix: String,
    /// The Zenoh session.
    #[serde(default)]
    pub zenoh: ZenohConfig,
    /// The channels carried out of this bus: the first rule whose pattern matches a channel
    /// decides its rate; a channel no rule matches stays.
    #[serde(default)]
    pub out: Vec<ChannelRule>,
    /// The channels taken in from the other buses (anchored regular expressions): nothing
    /// unless named (the link is a door into the robot's bus).
    #[serde(default, rename = "in")]
    pub inbound: Vec<String>,
}

fn prefix() -> String {
    "lcm".into()
}

/// The Zenoh session: a peer that listens and connects where it is told, with multicast
/// scouting off (a bridge is for where multicast does not pass). Beyond this computer's
/// loopback, only over TLS with certificates both ways, unless `insecure` says otherwise.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZenohConfig {
    /// "peer" or "client" (a client needs a router, e.g. zenohd, to connect to).
    #[serde(default = "peer")]
    pub mode: String,
    /// Endpoints to listen on, e.g. "quic/0.0.0.0:7447".
    #[serde(default)]
    pub listen: Vec<String>,
    /// Endpoints to connect to, e.g. "quic/10.0.1.5:7447".
    #[serde(default)]
    pub connect: Vec<String>,
    /// Plain TCP beyond the loopback, which anyone who reaches the port may join and publish
    /// goals, plans and stops through: refused unless this says `true` in so many words.
    #[serde(default)]
    pub insecure: bool,
    /// TLS, mutual: each side shows a certificate the other's authority signed.
    #[serde(default)]
    pub tls: Option<TlsConfig>,
    /// User and password, checked by the side that listens.
    #[serde(default)]
    pub auth: Option<AuthConfig>,
}

/// The bridge's TLS identity and the authority it trusts (PEM files, relative to the
/// configuration file's folder): `quic/` endpoints need it.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TlsConfig {
    /// The certificate of the authority that signed both sides' certificates.
    pub ca: PathBuf,
    /// This bridge's certificate (shown when it listens and when it connects).
    pub certificate: PathBuf,
    /// Its private key.
    pub key: PathBuf,
    /// A connecting bridge checks that the peer's certificate names the address it
    /// connects to (its subjectAltName).
    #[serde(default = "yes")]
    pub verify_name: bool,
}

fn yes() -> bool {
    true
}

/// Zenoh's user and password authentication (files relative to the configuration file's
/// folder; no password in the configuration itself).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AuthConfig {
    /// The user this bridge connects as.
    #[serde(default)]
    pub user: Option<String>,
    /// A file whose first line is its password.
    #[serde(default)]
    pub password_file: Option<PathBuf>,
    /// Who may connect to this bridge: a file of `user:password` lines.
    #[serde(default)]
    pub users_file: Option<PathBuf>,
}

/// Whether an endpoint's address stays on this computer (127.0.0.0/8, ::1, localhost).
pub fn is_loopback(endpoint: &str) -> bool {
    let Some((_, addr)) = endpoint.split_once('/') else {
        return false;
    };
    // Options after '#' or '?'.
    let addr = addr.split(['#', '?']).next().unwrap_or("");
    let host = match addr.rsplit_once(':') {
        Some((h, _)) => h.trim_start_matches('[').trim_end_matches(']'),
        None => addr,
    };
    host == "localhost"
        || host
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

fn peer() -> String {
    "peer".into()
}

impl Default for ZenohConfig {
    fn default() -> Self {
        ZenohConfig {
            mode: peer(),
            listen: Vec::new(),
            connect: Vec::new(),
            insecure: false,
            tls: None,
            auth: None,
        }
    }
}

/// Channels carried out, and how often.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChannelRule {
    /// The channels (an anchored regular expression, as LCM reads subscription patterns).
    pub pattern: String,
    /// At most this many messages a second of each matching channel; the others are
    /// dropped and counted. None: all.
    #[serde(default)]
    pub max_rate_hz: Option<f64>,
    /// When the link takes no more for a moment (Zenoh's queue full), drop these channels'
    /// messages rather than wait for room: for streams whose newest message replaces the
    /// last (a pose, odometry). Otherwise (the default) the bridge waits, and what follows
    /// on the bus waits in its queue: a burst of plans or commands is never thinned.
    #[serde(default)]
    pub drop_when_congested: bool,
}

/// An anchored regular expression, or a one-line error naming `what`.
pub fn anchored(pattern: &str, what: &str) -> Result<Regex, String> {
    Regex::new(&format!("^(?:{pattern})$"))
        .map_err(|e| format!("{what} {pattern:?} is no regular expression: {e}"))
}

impl BridgeConfig {
    /// Checks what the types cannot: a bus name, a key prefix Zenoh takes, valid patterns,
    /// positive rates, a known mode, somewhere to meet the other bridges.
    pub fn check(&self) -> Result<(), String> {
        if self.bus.trim().is_empty() {
            return Err("bus: name this LCM bus (the same for no two bridged buses)".into());
        }
        if !is_key(&self.prefix) {
            return Err(format!(
                "prefix {:?} is no Zenoh key (non-empty chunks between '/', none of * $ ? #)",
                self.prefix
            ));
        }
        for r in &self.out {
            anchored(&r.pattern, "out pattern")?;
            if let Some(hz) = r.max_rate_hz {
                if !(hz.is_finite() && hz > 0.0) {
                    return Err(format!(
                        "out pattern {:?}: max_rate_hz must be positive, not {hz}",
                        r.pattern
                    ));
                }
            }
        }
        for p in &self.inbound {
            anchored(p, "in pattern")?;
        }
        if !matches!(self.zenoh.mode.as_str(), "peer" | "client") {
            return Err(format!(
                "zenoh.mode {:?}: \"peer\" or \"client\"",
                self.zenoh.mode
            ));
        }
        if self.zenoh.listen.is_empty() && self.zenoh.connect.is_empty() {
            return Err(
                "zenoh: nothing to listen on or connect to (multicast scouting is off)".into(),
            );
        }
        for e in self.zenoh.listen.iter().chain(&self.zenoh.connect) {
            let Some((proto, _)) = e.split_once('/') else {
                return Err(format!(
                    "zenoh endpoint {e:?}: PROTOCOL/ADDRESS:PORT, e.g. quic/10.0.1.5:7447"
                ));
            };
            match proto {
                "quic" if self.zenoh.tls.is_none() => {
                    return Err(format!(
                        "zenoh endpoint {e:?}: QUIC needs [zenoh.tls] (ca, certificate, key)"
                    ))
                }
                "quic" => {}
                "tls" => {
                    return Err(format!(
                        "zenoh endpoint {e:?}: Zenoh's TLS-over-TCP link reads and writes one \
                         TLS stream from two threads at once (eclipse-zenoh/zenoh#2557): under \
                         traffic both ways it fails and drops the messages in flight; use \
                         quic/ (the same [zenoh.tls] certificates)"
                    ))
                }
                "tcp" if is_loopback(e) || self.zenoh.insecure => {}
                "tcp" => {
                    return Err(format!(
                        "zenoh endpoint {e:?} is plain TCP beyond this computer: anyone who \
                         reaches it may join the robot's bus; use quic/ with [zenoh.tls] (see \
                         the README), or say insecure = true in [zenoh]"
                    ))
                }
                other => {
                    return Err(format!(
                        "zenoh endpoint {e:?}: protocol {other:?}, use quic (or tcp on the \
                         loopback)"
                    ))
                }
            }
        }
        if let Some(a) = &self.zenoh.auth {
            if a.user.is_some() != a.password_file.is_some() {
                return Err("zenoh.auth: user and password_file go together".into());
            }
            if a.user.is_none() && a.users_file.is_none() {
                return Err(
                    "zenoh.auth: give user and password_file (to connect), users_file (to be \
                     connected to), or both"
                        .into(),
                );
            }
        }
        Ok(())
    }

    /// The configuration's files made relative to `dir` (the configuration file's folder).
    pub fn rebase(&mut self, dir: &std::path::Path) {
        let at = |p: &mut PathBuf| {
            if p.is_relative() {
                *p = dir.join(&*p);
            }
        };
        if let Some(t) = &mut self.zenoh.tls {
            at(&mut t.ca);
            at(&mut t.certificate);
            at(&mut t.key);
        }
        if let Some(a) = &mut self.zenoh.auth {
            a.password_file.iter_mut().for_each(at);
            a.users_file.iter_mut().for_each(at);
        }
    }
}

/// Whether `k` is a Zenoh key without wildcards: non-empty chunks between '/', none of the
/// characters Zenoh reserves.
pub fn is_key(k: &str) -> bool {
    !k.is_empty() && k.split('/').all(|c| !c.is_empty()) && !k.contains(['*', '$', '?', '#'])
}

/// The Zenoh key of `channel` under `prefix`, or None when the channel name cannot be one.
pub fn key_of(prefix: &str, channel: &str) -> Option<String> {
    is_key(channel).then(|| format!("{prefix}/{channel}"))
}

/// The channel of a key under `prefix`.
pub fn channel_of<'a>(prefix: &str, key: &'a str) -> Option<&'a str> {
    key.strip_prefix(prefix)?
        .strip_prefix('/')
        .filter(|c| !c.is_empty())
}

/// What becomes of a message on this bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Out {
    /// Carried out.
    Send,
    /// No rule takes its channel.
    Stays,
    /// Its channel's rate is spent: dropped.
    RateLimited,
    /// The bridge brought it in: not sent back.
    Echo,
    /// Its channel name cannot be a Zenoh key.
    BadName,
}

/// The outgoing side: the rules, each channel's last send, and the echoes to expect.
#[derive(Debug)]
pub struct Outgoing {
    rules: Vec<(Regex, Option<Duration>, bool)>,
    last: HashMap<String, Instant>,
}

impl Outgoing {
    /// The rules of `cfg` (checked).
    pub fn new(rules: &[ChannelRule]) -> Result<Outgoing, String> {
        let rules = rules
            .iter()
            .map(|r| {
                Ok((
                    anchored(&r.pattern, "out pattern")?,
                    r.max_rate_hz.map(|hz| Duration::from_secs_f64(1.0 / hz)),
                    r.drop_when_congested,
                ))
            })
            .collect::<Result<_, String>>()?;
        Ok(Outgoing {
            rules,
            last: HashMap::new(),
        })
    }

    fn rule(&self, channel: &str) -> Option<&(Regex, Option<Duration>, bool)> {
        self.rules.iter().find(|(re, ..)| re.is_match(channel))
    }

    /// Whether `channel`'s messages are dropped rather than held when the link is congested
    /// (its rule's `drop_when_congested`).
    pub fn drops_when_congested(&self, channel: &str) -> bool {
        self.rule(channel).is_some_and(|r| r.2)
    }

    /// Whether a message on `channel` at `now` goes out (an echo is told apart before).
    pub fn decide(&mut self, channel: &str, now: Instant) -> Out {
        let Some((_, every, _)) = self.rule(channel) else {
            return Out::Stays;
        };
        if !is_key(channel) {
            return Out::BadName;
        }
        if let Some(every) = every {
            if let Some(t) = self.last.get(channel) {
                // A little early passes: a sender at exactly the limit is not halved.
                if now.saturating_duration_since(*t) < every.mul_f64(0.9) {
                    return Out::RateLimited;
                }
            }
            self.last.insert(channel.to_owned(), now);
        }
        Out::Send
    }
}

/// The messages a bridge published on its bus, to know them when the bus hands them back:
/// each remembered (by a hash of channel and bytes) until seen once or for `keep`.
#[derive(Debug)]
pub struct Echoes {
    keep: Duration,
    pending: VecDeque<(u64, Instant)>,
}

impl Echoes {
    /// Remembers for `keep` (longer than the bus takes to hand a message back).
    pub fn new(keep: Duration) -> Echoes {
        Echoes {
            keep,
            pending: VecDeque::new(),
        }
    }

    fn hash(channel: &str, data: &[u8]) -> u64 {
        let mut h = std::collections::hash_map::DefaultHasher::new();
        channel.hash(&mut h);
        data.hash(&mut h);
        h.finish()
    }

    /// The bridge is about to publish `data` on `channel` at `now`.
    pub fn sent(&mut self, channel: &str, data: &[u8], now: Instant) {
        self.expire(now);
        self.pending.push_back((Self::hash(channel, data), now));
    }

    /// A message on the bus at `now`: true (and forgotten) when it is one the bridge
    /// published.
    pub fn is_echo(&mut self, channel: &str, data: &[u8], now: Instant) -> bool {
        self.expire(now);
        let h = Self::hash(channel, data);
        match self.pending.iter().position(|(x, _)| *x == h) {
            Some(i) => {
                self.pending.remove(i);
                true
            }
            None => false,
        }
    }

    /// How many are remembered.
    pub fn len(&self) -> usize {
        self.pending.len()
    }

    /// None remembered.
    pub fn is_empty(&self) -> bool {
        self.pending.is_empty()
    }

    fn expire(&mut self, now: Instant) {
        while self
            .pending
            .front()
            .is_some_and(|(_, t)| now.saturating_duration_since(*t) > self.keep)
        {
            self.pending.pop_front();
        }
    }
}

/// What the bridge did, since it started.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Counters {
    /// Messages carried out.
    pub sent: u64,
    /// Bytes carried out.
    pub sent_bytes: u64,
    /// Messages taken in and published on this bus.
    pub received: u64,
    /// Dropped by a rate limit.
    pub rate_limited: u64,
    /// The bridge's own messages handed back by the bus: not sent out again.
    pub echoes: u64,
    /// From this bus's name (another bridge on the same bus, or this one): not taken in.
    pub own_bus: u64,
    /// From other buses, on channels not taken in.
    pub not_taken: u64,
    /// Channels whose names cannot be Zenoh keys, or keys without a channel.
    pub bad_names: u64,
    /// Errors publishing on either side.
    pub errors: u64,
}

impl std::fmt::Display for Counters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "out {} ({} B), in {}, rate-limited {}, echoes {}, own bus {}, not taken {}, \
             bad names {}, errors {}",
            self.sent,
            self.sent_bytes,
            self.received,
            self.rate_limited,
            self.echoes,
            self.own_bus,
            self.not_taken,
            self.bad_names,
            self.errors
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(text: &str) -> Result<BridgeConfig, String> {
        let c: BridgeConfig = toml::from_str(text).map_err(|e| e.to_string())?;
        c.check().map(|()| c)
    }

    const OK: &str = "bus = \"robot\"\n[zenoh]\nlisten = [\"tcp/127.0.0.1:7447\"]\n";

    #[test]
    fn a_configuration_is_checked_before_the_bridge_starts() {
        let c = cfg(OK).unwrap();
        assert_eq!(c.prefix, "lcm");
        assert!(c.inbound.is_empty(), "nothing comes in unless named");
        for (text, why) in [
            (
                "bus = \" \"\n[zenoh]\nlisten = [\"tcp/127.0.0.1:7447\"]\n",
                "name this LCM bus",
            ),
            ("bus = \"r\"\n", "nothing to listen on or connect to"),
            (
                "bus = \"r\"\nprefix = \"a//b\"\n[zenoh]\nlisten = [\"tcp/127.0.0.1:7447\"]\n",
                "is no Zenoh key",
            ),
            (
                "bus = \"r\"\n[zenoh]\nmode = \"router\"\nlisten = [\"tcp/127.0.0.1:7447\"]\n",
                "\"peer\" or \"client\"",
            ),
            (
                "bus = \"r\"\n[zenoh]\nconnect = [\"10.0.0.1:7447\"]\n",
                "PROTOCOL/ADDRESS:PORT",
            ),
            (
                &format!("{OK}[[out]]\npattern = \"JOINT(\"\n"),
                "out pattern \"JOINT(\" is no regular expression",
            ),
            (
                &format!("{OK}[[out]]\npattern = \"X\"\nmax_rate_hz = 0.0\n"),
                "max_rate_hz must be positive",
            ),
            (&format!("in = [\"[\"]\n{OK}"), "in pattern \"[\""),
            // Item 9 of the reliability issue: the link was plain TCP that anyone who reached
            // the port could join and publish goals, plans and stops through.
            (
                "bus = \"r\"\n[zenoh]\nlisten = [\"tcp/0.0.0.0:7447\"]\n",
                "plain TCP beyond this computer",
            ),
            (
                "bus = \"r\"\n[zenoh]\nconnect = [\"tcp/10.0.1.2:7447\"]\n",
                "say insecure = true",
            ),
            (
                "bus = \"r\"\n[zenoh]\nlisten = [\"quic/0.0.0.0:7447\"]\n",
                "QUIC needs [zenoh.tls]",
            ),
            // Zenoh's TLS-over-TCP link raced its reader and writer on one TLS stream: under
            // a stream both ways it closed and lost the messages in flight.
            (
                "bus = \"r\"\n[zenoh]\nlisten = [\"tls/0.0.0.0:7447\"]\n",
                "use quic/",
            ),
            (
                "bus = \"r\"\n[zenoh]\nlisten = [\"udp/0.0.0.0:7447\"]\n",
                "protocol \"udp\"",
            ),
            (
                "bus = \"r\"\n[zenoh]\nlisten = [\"tcp/127.0.0.1:7447\"]\n[zenoh.auth]\nuser = \"a\"\n",
                "user and password_file go together",
            ),
        ] {
            let e = cfg(text).unwrap_err();
            assert!(e.contains(why), "{text}: {e}");
        }
    }

    #[test]
    fn the_shipped_configurations_load() {
        for name in ["zenoh-bridge-robot.toml", "zenoh-bridge-operator.toml"] {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../config")
                .join(name);
            let c: BridgeConfig = stride_node::app_config(Some(&path)).unwrap();
            assert!(!c.out.is_empty() && !c.inbound.is_empty(), "{name}");
            // Named channels only, never everything.
            assert!(c.inbound.iter().all(|p| !p.contains(".*")), "{name}");
            assert!(c.zenoh.tls.is_some() && !c.zenoh.insecure, "{name}");
        }
    }

    #[test]
    fn channels_map_to_keys_and_back_and_wildcards_do_not_pass() {
        assert_eq!(key_of("lcm", "FOOTSTEP_PLAN").unwrap(), "lcm/FOOTSTEP_PLAN");
        assert_eq!(
            channel_of("lcm", "lcm/FOOTSTEP_PLAN"),
            Some("FOOTSTEP_PLAN")
        );
        assert_eq!(channel_of("lcm", "lcm/a/b"), Some("a/b"));
        assert_eq!(channel_of("lcm", "lcmx/A"), None);
        assert_eq!(channel_of("lcm", "lcm/"), None);
        for bad in ["A*", "A$B", "WHAT?", "#1", "", "/A", "A//B", "A/"] {
            assert_eq!(key_of("lcm", bad), None, "{bad}");
        }
    }

    #[test]
    fn the_first_matching_rule_decides_and_a_rate_limit_drops_the_excess() {
        let mut o = Outgoing::new(&[
            ChannelRule {
                pattern: "ELEVATION_MAP".into(),
                max_rate_hz: Some(2.0),
                drop_when_congested: true,
            },
            ChannelRule {
                pattern: "FOOTSTEP_.*|STEP_COUNTER".into(),
                max_rate_hz: None,
                drop_when_congested: false,
            },
        ])
        .unwrap();
        let t0 = Instant::now();
        assert_eq!(o.decide("JOINT_STATE_LEFT_LEG", t0), Out::Stays);
        assert_eq!(o.decide("FOOTSTEP_PLAN", t0), Out::Send);
        assert_eq!(o.decide("FOOTSTEP_PLAN", t0), Out::Send);
        // Anchored: a longer name is another channel.
        assert_eq!(o.decide("STEP_COUNTER_2", t0), Out::Stays);
        // 10 Hz offered for a second, 2 Hz let through.
        let sent = (0..10)
            .filter(|i| o.decide("ELEVATION_MAP", t0 + Duration::from_millis(100 * i)) == Out::Send)
            .count();
        assert_eq!(sent, 2);
        // Only the rule that says so drops on a congested link.
        assert!(o.drops_when_congested("ELEVATION_MAP"));
        assert!(!o.drops_when_congested("FOOTSTEP_PLAN"));
        assert!(!o.drops_when_congested("JOINT_STATE_LEFT_LEG"));
        let mut all = Outgoing::new(&[ChannelRule {
            pattern: ".*".into(),
            max_rate_hz: None,
            drop_when_congested: false,
        }])
        .unwrap();
        assert_eq!(all.decide("BAD*NAME", t0), Out::BadName);
    }

    #[test]
    fn a_message_the_bridge_published_is_known_once_when_the_bus_hands_it_back() {
        let mut e = Echoes::new(Duration::from_secs(2));
        let t0 = Instant::now();
        e.sent("PLAN", b"abc", t0);
        e.sent("PLAN", b"abc", t0);
        assert!(!e.is_echo("PLAN", b"abd", t0));
        assert!(!e.is_echo("OTHER", b"abc", t0));
        // Twice published, twice handed back; a third is someone else's.
        assert!(e.is_echo("PLAN", b"abc", t0));
        assert!(e.is_echo("PLAN", b"abc", t0));
        assert!(!e.is_echo("PLAN", b"abc", t0));
        // Forgotten after `keep`: the memory does not grow when the bus loses a message.
        e.sent("PLAN", b"x", t0);
        assert!(!e.is_echo("PLAN", b"x", t0 + Duration::from_secs(3)));
        assert!(e.is_empty());
    }

    #[test]
    fn insecure_says_so_in_so_many_words_and_loopback_needs_no_tls() {
        let c = cfg("bus = \"r\"\n[zenoh]\ninsecure = true\nconnect = [\"tcp/10.0.1.2:7447\"]\n");
        assert!(c.is_ok(), "{c:?}");
        for e in [
            "tcp/127.0.0.1:7447",
            "tcp/[::1]:7447",
            "tcp/localhost:7447",
            "tcp/127.3.4.5:1",
        ] {
            assert!(is_loopback(e), "{e}");
        }
        for e in [
            "tcp/0.0.0.0:7447",
            "tcp/10.0.1.2:7447",
            "tcp/[::]:7447",
            "tcp/robot.local:7447",
        ] {
            assert!(!is_loopback(e), "{e}");
        }
    }
}
