//! The logic of `stride-dynamixel-bridge`: its configuration, LCM commands to the chain's
//! and the chain's measurements back as LCM messages, and the bridge as a state machine
//! ([`Bridge`]): commands, the hold when they stop, and the line lost and found again (logged
//! once, retried with a doubling delay, the servos brought up again holding where they are).
//! The servos are `stride-dynamixel-chain`'s.

use std::time::{Duration, Instant};

use stride_dynamixel_chain::{Chain, ChainConfig, ReadMode, ServoConfig};
use stride_lcmtypes::stride::{DynamixelStateT, HeaderT, JointCommandT, JointStateT, NodeStatusT};
use stride_serial::{LineSpec, Transport};

pub mod app;

pub use app::{open_line, Cli, DynamixelApp};

/// The bridge's TOML configuration.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BridgeConfig {
    /// Serial device (e.g. `/dev/ttyUSB0`), or `sim` for fake servos in this process.
    pub port: LineSpec,
    /// Baud rate of the line (the servos' baud rate item must match).
    pub baud: u32,
    /// Cycles per second (a goal write and a read of every servo each).
    pub rate_hz: f64,
    /// Return delay time set on every servo at start, µs (0 is fastest; factory: 500).
    pub return_delay_us: u32,
    /// Added to every reply deadline for the USB adapter and the host, ms (set the FTDI
    /// latency timer to 1 ms).
    pub margin_ms: f64,
    /// Tries after the first when a reply is lost.
    pub retries: u32,
    /// How positions are read.
    pub read: ReadMode,
    /// Channel of incoming `stride.joint_command_t` (position mode).
    pub command_channel: String,
    /// Channel of outgoing `stride.joint_state_t`.
    pub state_channel: String,
    /// Channel of outgoing `stride.dynamixel_state_t` (servo health).
    pub health_channel: String,
    /// When no command came for this long, the servos hold where they are (0: never).
    pub hold_timeout_ms: u64,
    /// Protocol 2.0 servos stop on their own when the bridge says nothing for this long, ms
    /// (their bus watchdog, 20..=2540; 0: off). Protocol 1.0 servos (AX-12A) have none.
    pub bus_watchdog_ms: u64,
    /// After the line is lost, the first attempt to open it again waits this long, ms; each
    /// failed attempt doubles it, up to 10 s.
    pub reconnect_ms: u64,
    /// The servos.
    pub servo: Vec<ServoConfig>,
}

impl Default for BridgeConfig {
    fn default() -> Self {
        BridgeConfig {
            port: LineSpec::Sim,
            baud: 1_000_000,
            rate_hz: 50.0,
            return_delay_us: 0,
            margin_ms: 3.0,
            retries: 2,
            read: ReadMode::Auto,
            command_channel: "JOINT_COMMAND".into(),
            state_channel: "JOINT_STATE".into(),
            health_channel: "DYNAMIXEL_STATE".into(),
            hold_timeout_ms: 500,
            bus_watchdog_ms: 100,
            reconnect_ms: 250,
            servo: Vec::new(),
        }
    }
}

impl BridgeConfig {
    /// Checks what serde cannot; returns the chain's protocol.
    pub fn check(&self) -> Result<stride_dynamixel::Protocol, String> {
        let protocol = stride_dynamixel_chain::check(&self.servo)?;
        if !(1.0..=1000.0).contains(&self.rate_hz) {
            return Err(format!("rate_hz {} outside 1..=1000", self.rate_hz));
        }
        if self.return_delay_us > 508 {
            return Err("return_delay_us is at most 508".into());
        }
        if self.bus_watchdog_ms != 0 {
            stride_dynamixel_chain::watchdog_units(Duration::from_millis(self.bus_watchdog_ms))
                .map_err(|e| format!("bus_watchdog_ms: {e} (0: off)"))?;
        }
        // Protocol 1.0 servos have no bus watchdog: the setting does nothing there.
        if protocol == stride_dynamixel::Protocol::V2
            && self.bus_watchdog_ms != 0
            && (self.bus_watchdog_ms as f64) < 2000.0 / self.rate_hz
        {
            return Err(format!(
                "bus_watchdog_ms {} is less than two cycles at {} Hz: the servos would stop",
                self.bus_watchdog_ms, self.rate_hz
            ));
        }
        Ok(protocol)
    }

    /// The chain's settings.
    pub fn chain(&self) -> ChainConfig {
        let ms = Duration::from_millis;
        ChainConfig {
            servos: self.servo.clone(),
            read: self.read,
            return_delay_us: self.return_delay_us,
            margin: Duration::from_secs_f64(self.margin_ms / 1000.0),
            retries: self.retries,
            hold_timeout: (self.hold_timeout_ms > 0).then(|| ms(self.hold_timeout_ms)),
            bus_watchdog: (self.bus_watchdog_ms > 0).then(|| ms(self.bus_watchdog_ms)),
        }
    }
}

/// The joint states message of `chain`.
pub fn joint_state<T: Transport>(chain: &Chain<T>, header: HeaderT) -> JointStateT {
    let (joints, m) = (chain.joints(), chain.measured());
    JointStateT {
        header,
        num_joints: joints.len() as i32,
        names: joints.iter().map(|j| j.cfg.name.clone()).collect(),
        positions: m.iter().map(|m| m.position).collect(),
        velocities: m.iter().map(|m| m.velocity).collect(),
        currents: m.iter().map(|m| m.current).collect(),
        temperatures: m.iter().map(|m| m.temperature as f32).collect(),
        faults: m
            .iter()
            .map(|m| m.errors as i32 | (m.hardware as i32) << 8)
            .collect(),
    }
}

/// The servo health message of `chain` on `port`.
pub fn health<T: Transport>(chain: &Chain<T>, port: &str, header: HeaderT) -> DynamixelStateT {
    let (joints, m) = (chain.joints(), chain.measured());
    DynamixelStateT {
        header,
        port: port.to_owned(),
        num_servos: joints.len() as i32,
        ids: joints.iter().map(|j| j.cfg.id as i8).collect(),
        joint_names: joints.iter().map(|j| j.cfg.name.clone()).collect(),
        positions: m.iter().map(|m| m.position).collect(),
        speeds: m.iter().map(|m| m.velocity).collect(),
        loads: m.iter().map(|m| m.load as f32).collect(),
        voltages: m.iter().map(|m| m.voltage as f32).collect(),
        temperatures: m.iter().map(|m| m.temperature as f32).collect(),
        errors: m.iter().map(|m| m.errors as i8).collect(),
        hardware_alerts: m.iter().map(|m| m.hardware as i8).collect(),
        timeouts: joints
            .iter()
            .map(|j| chain.bus().missed(j.cfg.id) as i32)
            .collect(),
    }
}

/// What the bridge logs, each once, in one line.
pub use stride_node::Note;

/// The line: up, or lost since and retried when.
#[derive(Debug, Clone, PartialEq)]
enum Line {
    Up,
    Lost {
        why: String,
        /// When the next attempt is due.
        next: Instant,
        /// The wait after that attempt, should it fail (it doubles each time).
        delay: Duration,
        tries: u32,
    },
}

/// Longest wait between attempts to open the line again.
pub const MAX_RECONNECT: Duration = Duration::from_secs(10);

/// The bridge: the chain, its line, its health.
pub struct Bridge<T: Transport> {
    chain: Chain<T>,
    line: Line,
    first_delay: Duration,
    state: i8,
    detail: String,
}

impl<T: Transport> Bridge<T> {
    /// A bridge on `chain` (brought up).
    pub fn new(chain: Chain<T>, reconnect_ms: u64) -> Bridge<T> {
        Bridge {
            chain,
            line: Line::Up,
            first_delay: Duration::from_millis(reconnect_ms.max(1)),
            state: NodeStatusT::STATE_RUNNING,
            detail: String::new(),
        }
    }

    /// The chain.
    pub fn chain(&self) -> &Chain<T> {
        &self.chain
    }

    /// The node's health: a `NodeStatusT::STATE_*` and why.
    pub fn health(&self) -> (i8, &str) {
        (self.state, &self.detail)
    }

    /// True while the line is up (states are fresh).
    pub fn up(&self) -> bool {
        self.line == Line::Up
    }

    /// A command from the bus: position mode only, checked whole, then the chain's goals.
    pub fn on_command(&mut self, c: &JointCommandT, now: Instant) -> Vec<Note> {
        let refused = |b: &mut Bridge<T>, why: String| {
            if b.line == Line::Up {
                b.state = NodeStatusT::STATE_DEGRADED;
                b.detail = format!("command rejected: {why}");
            }
            vec![Note::Warn(format!("command rejected: {why}"))]
        };
        if let Line::Lost { why, .. } = &self.line {
            let why = format!("the servo line is down ({why})");
            return refused(self, why);
        }
        if let Err(e) = stride_limits::lengths(c.names.len(), &[("modes", c.modes.len())]) {
            return refused(self, e.to_string());
        }
        if let Some(k) = c
            .modes
            .iter()
            .position(|m| *m != JointCommandT::MODE_POSITION)
        {
            let e = stride_limits::Reject::Mode {
                joint: c.names[k].clone(),
                what: "only position commands are taken".into(),
            };
            return refused(self, e.to_string());
        }
        match self
            .chain
            .command(&c.names, &c.setpoints, &c.velocities, now)
        {
            Ok(()) => {
                if self.state == NodeStatusT::STATE_DEGRADED {
                    self.state = NodeStatusT::STATE_RUNNING;
                    self.detail.clear();
                }
                Vec::new()
            }
            Err(e) => refused(self, e.to_string()),
        }
    }

    /// One cycle: the hold when commands stopped, the chain's cycle; while the line is lost,
    /// an attempt to open it (`open`) when one is due.
    pub fn tick(&mut self, now: Instant, open: impl FnOnce() -> std::io::Result<T>) -> Vec<Note> {
        let mut notes = Vec::new();
        if let Line::Lost { next, tries, .. } = &mut self.line {
            if now < *next {
                return notes;
            }
            *tries += 1;
            let result = open()
                .map_err(|e| e.to_string())
                .and_then(|line| self.chain.reattach(line).map_err(|e| e.to_string()));
            let Line::Lost {
                why,
                next,
                delay,
                tries,
            } = &mut self.line
            else {
                unreachable!("lost")
            };
            match result {
                Ok(()) => {
                    notes.push(Note::Info(format!(
                        "servo line back after {tries} attempt(s): servos up again, holding"
                    )));
                    self.line = Line::Up;
                    self.state = NodeStatusT::STATE_RUNNING;
                    self.detail.clear();
                }
                Err(e) => {
                    *next = now + *delay;
                    // Once in a while, not every attempt.
                    if tries.is_power_of_two() {
                        notes.push(Note::Warn(format!(
                            "servo line still down ({e}); attempt {tries}, next in {:.1} s",
                            delay.as_secs_f64()
                        )));
                    }
                    *delay = (*delay * 2).min(MAX_RECONNECT);
                    self.detail = format!("{why}; reconnecting: {e}");
                }
            }
            return notes;
        }
        if self.chain.hold_if_stale(now) {
            notes.push(Note::Warn(
                "commands stopped: holding where the servos are".into(),
            ));
            self.state = NodeStatusT::STATE_DEGRADED;
            self.detail = "commands stopped: holding".into();
        }
        if let Err(e) = self.chain.cycle(now) {
            let why = format!("servo line: {e}");
            notes.push(Note::Error(format!(
                "{why}: reconnecting (first in {} ms)",
                self.first_delay.as_millis()
            )));
            self.state = NodeStatusT::STATE_FAULT;
            self.detail = why.clone();
            self.line = Line::Lost {
                why,
                next: now + self.first_delay,
                delay: self.first_delay * 2,
                tries: 0,
            };
        }
        notes
    }

    /// Torque off on every servo, if the line is up.
    pub fn torque_off(&mut self) -> Result<(), String> {
        if let Line::Lost { why, .. } = &self.line {
            return Err(format!("the servo line is down ({why})"));
        }
        self.chain.torque_off().map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shipped(name: &str) -> BridgeConfig {
        let path = format!("{}/../../config/robots/{name}", env!("CARGO_MANIFEST_DIR"));
        toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    }

    #[test]
    fn shipped_configs_check() {
        assert!(shipped("hexapod-dynamixel.toml").check().is_ok());
        assert!(shipped("arm-xm430.toml").check().is_ok());
        assert!(BridgeConfig::default()
            .check()
            .unwrap_err()
            .contains("--config"));
        let mut bad = shipped("arm-xm430.toml");
        bad.bus_watchdog_ms = 5;
        assert!(bad.check().is_err());
    }
}
