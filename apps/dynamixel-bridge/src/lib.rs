//! The logic of `stride-dynamixel-bridge`: configuration, bring-up, the command/read cycle,
//! limits, the hold when commands stop, and the LCM messages. The wire work is
//! `stride-dynamixel-bus`'s.

use std::time::{Duration, Instant};

use stride_dynamixel::models::{self, Encoding, Model};
use stride_dynamixel::{v1, v2, Protocol};
use stride_dynamixel_bus::{Bus, BusConfig, BusError, ReadMany};
use stride_lcmtypes::stride::{DynamixelStateT, HeaderT, JointCommandT, JointStateT};
use stride_serial::Transport;

/// One servo of the chain.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServoConfig {
    /// Joint name (as in commands and states).
    pub name: String,
    /// Servo id.
    pub id: u8,
    /// Model, e.g. `AX-12A` or `XM430-W350` (see `drivers/dynamixel/models`).
    pub model: String,
    /// Joint angle when the servo is at the middle of its range, rad.
    #[serde(default)]
    pub zero_offset: f64,
    /// +1, or -1 when the servo turns against the joint.
    #[serde(default = "one")]
    pub direction: i8,
    /// Joint limits, rad.
    pub min_position: f64,
    /// Upper joint limit, rad.
    pub max_position: f64,
    /// Speed limit, rad/s: the servo's moving speed is set to it, and faster commands are
    /// refused.
    pub max_velocity: f64,
}

fn one() -> i8 {
    1
}

/// How the positions are read each cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReadMode {
    /// Fast sync read on 2.0; bulk read on 1.0 when every servo is an MX; else one by one.
    Auto,
    /// 2.0 sync read.
    Sync,
    /// 2.0 fast sync read.
    FastSync,
    /// 1.0 bulk read (MX series).
    Bulk,
    /// One read per servo.
    OneByOne,
}

/// The bridge's TOML configuration.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BridgeConfig {
    /// Serial device (e.g. `/dev/ttyUSB0`), or `sim` for fake servos in this process.
    pub port: String,
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
    /// The servos.
    pub servo: Vec<ServoConfig>,
}

impl Default for BridgeConfig {
    fn default() -> Self {
        BridgeConfig {
            port: "sim".into(),
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
            servo: Vec::new(),
        }
    }
}

impl BridgeConfig {
    /// Checks what serde cannot; returns the chain's protocol.
    pub fn check(&self) -> Result<Protocol, String> {
        let first = self
            .servo
            .first()
            .ok_or("the configuration lists no [[servo]]")?;
        let protocol = model(&first.model)?.protocol;
        if !(1.0..=1000.0).contains(&self.rate_hz) {
            return Err(format!("rate_hz {} outside 1..=1000", self.rate_hz));
        }
        if self.return_delay_us > 508 {
            return Err("return_delay_us is at most 508".into());
        }
        let mut ids = std::collections::BTreeSet::new();
        for s in &self.servo {
            let m = model(&s.model)?;
            if m.protocol != protocol {
                return Err(format!(
                    "servo {}: {} speaks another protocol than the rest of the chain",
                    s.name, m.name
                ));
            }
            if !ids.insert(s.id) || s.id > 252 {
                return Err(format!(
                    "servo {}: id {} used twice or above 252",
                    s.name, s.id
                ));
            }
            if s.direction.abs() != 1 {
                return Err(format!("servo {}: direction is 1 or -1", s.name));
            }
            if !(s.min_position < s.max_position && s.max_velocity > 0.0) {
                return Err(format!(
                    "servo {}: limits must be ordered and positive",
                    s.name
                ));
            }
            let j = Joint::new(s.clone(), m);
            for p in [s.min_position, s.max_position] {
                let c = j.counts(p);
                if !(0..m.position_counts as i64).contains(&c) {
                    return Err(format!(
                        "servo {}: {p} rad is count {c}, outside the {}'s 0..{}",
                        s.name, m.name, m.position_counts
                    ));
                }
            }
        }
        Ok(protocol)
    }
}

fn model(name: &str) -> Result<&'static Model, String> {
    models::by_name(name).ok_or_else(|| {
        let known: Vec<&str> = models::all().iter().map(|m| m.name.as_str()).collect();
        format!("unknown model {name:?} (known: {})", known.join(", "))
    })
}

/// A configured servo with its model: conversions between joint radians and counts.
#[derive(Debug, Clone)]
pub struct Joint {
    /// Its configuration.
    pub cfg: ServoConfig,
    /// Its model.
    pub model: &'static Model,
}

impl Joint {
    /// The joint of `cfg` on a servo of `model`.
    pub fn new(cfg: ServoConfig, model: &'static Model) -> Joint {
        Joint { cfg, model }
    }

    /// Counts of joint angle `rad`.
    pub fn counts(&self, rad: f64) -> i64 {
        let d = self.cfg.direction as f64;
        self.model.center()
            + (d * (rad - self.cfg.zero_offset) / self.model.rad_per_count()).round() as i64
    }

    /// Joint angle of `counts`.
    pub fn rad(&self, counts: i64) -> f64 {
        let d = self.cfg.direction as f64;
        d * (counts - self.model.center()) as f64 * self.model.rad_per_count()
            + self.cfg.zero_offset
    }

    fn item(&self, name: &str) -> stride_dynamixel::models::Item {
        *self
            .model
            .item(name)
            .expect("every shipped model has the bridge's items")
    }
}

/// Why a command was refused (nothing of it is applied).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Reject {
    /// A joint this bridge does not drive.
    #[error("unknown joint {0}")]
    UnknownJoint(String),
    /// A mode other than position.
    #[error("joint {0}: only position commands are taken")]
    Mode(String),
    /// Beyond a limit.
    #[error("joint {joint}: {what}")]
    Limit {
        /// The joint.
        joint: String,
        /// Which limit, by how much.
        what: String,
    },
    /// Arrays of different lengths.
    #[error("malformed command: {0}")]
    Malformed(String),
}

/// What a cycle measured of one servo.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Measured {
    /// Rad.
    pub position: f64,
    /// Rad/s.
    pub velocity: f64,
    /// Load in [-1, 1] (1.0: load; 2.0: current over the current limit).
    pub load: f64,
    /// Current, A (2.0), NaN when the model reports load instead.
    pub current: f64,
    /// V.
    pub voltage: f64,
    /// °C.
    pub temperature: f64,
    /// 1.0 error bits, or the 2.0 hardware errors mapped to the same bits.
    pub errors: u8,
    /// 2.0 hardware error status.
    pub hardware: u8,
    /// When this was read (`None`: never).
    pub at: Option<Instant>,
}

/// The chain: the bus, the joints, their goals, what was last measured.
pub struct Chain<T: Transport> {
    bus: Bus<T>,
    joints: Vec<Joint>,
    goals: Vec<i64>,
    measured: Vec<Measured>,
    read: ReadMany,
    hold_timeout: Option<Duration>,
    last_command: Option<Instant>,
    holding: bool,
    port: String,
}

/// A problem found at start: the bridge refuses to run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StartError {
    /// Configured servos did not answer.
    #[error("servo(s) not on the bus: {0}")]
    Missing(String),
    /// A servo is another model than configured.
    #[error("servo {name} (id {id}) is a {found}, configured as {want}")]
    WrongModel {
        /// Joint.
        name: String,
        /// Id.
        id: u8,
        /// Model found.
        found: String,
        /// Model configured.
        want: String,
    },
    /// Setting a servo up failed.
    #[error("setting up servo {name} (id {id}): {error}")]
    Setup {
        /// Joint.
        name: String,
        /// Id.
        id: u8,
        /// The bus error.
        error: BusError,
    },
}

impl<T: Transport> Chain<T> {
    /// A chain on `line` as `cfg` describes (checked with [`BridgeConfig::check`]).
    pub fn new(line: T, cfg: &BridgeConfig) -> Result<Chain<T>, String> {
        let protocol = cfg.check()?;
        let joints: Vec<Joint> = cfg
            .servo
            .iter()
            .map(|s| Joint::new(s.clone(), model(&s.model).expect("checked")))
            .collect();
        let all_mx = joints.iter().all(|j| j.model.name.starts_with("MX"));
        let read = match (cfg.read, protocol) {
            (ReadMode::Auto, Protocol::V2) => ReadMany::FastSync,
            (ReadMode::Auto, Protocol::V1) if all_mx => ReadMany::Bulk,
            (ReadMode::Auto, Protocol::V1) => ReadMany::OneByOne,
            (ReadMode::Sync, Protocol::V2) => ReadMany::Sync,
            (ReadMode::FastSync, Protocol::V2) => ReadMany::FastSync,
            (ReadMode::Bulk, Protocol::V1) if all_mx => ReadMany::Bulk,
            (ReadMode::OneByOne, _) => ReadMany::OneByOne,
            (m, p) => {
                return Err(format!(
                    "read = {m:?} does not work with Protocol {p:?} servos"
                ))
            }
        };
        let bus_cfg = BusConfig {
            margin: Duration::from_secs_f64(cfg.margin_ms / 1000.0),
            retries: cfg.retries,
            ..BusConfig::new(protocol)
        };
        let n = joints.len();
        Ok(Chain {
            bus: Bus::new(line, bus_cfg),
            goals: joints.iter().map(|j| j.model.center()).collect(),
            joints,
            measured: vec![Measured::default(); n],
            read,
            hold_timeout: (cfg.hold_timeout_ms > 0)
                .then(|| Duration::from_millis(cfg.hold_timeout_ms)),
            last_command: None,
            holding: false,
            port: cfg.port.clone(),
        })
    }

    /// The bus (for statistics).
    pub fn bus(&self) -> &Bus<T> {
        &self.bus
    }

    /// The joints.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Checks every servo is there and the right model, then sets each up: torque off, return
    /// delay, position limits and speed limit from the configuration, goal = where it is,
    /// torque on.
    pub fn bring_up(&mut self, return_delay_us: u32) -> Result<(), StartError> {
        let ids: Vec<u8> = self.joints.iter().map(|j| j.cfg.id).collect();
        let found = self
            .bus
            .scan(ids.iter().copied(), Duration::from_millis(20));
        let missing: Vec<String> = self
            .joints
            .iter()
            .filter(|j| !found.iter().any(|(i, _)| *i == j.cfg.id))
            .map(|j| format!("{} (id {})", j.cfg.name, j.cfg.id))
            .collect();
        if !missing.is_empty() {
            return Err(StartError::Missing(missing.join(", ")));
        }
        for j in &self.joints {
            let number = found.iter().find(|(i, _)| *i == j.cfg.id).expect("found").1;
            if number != j.model.number {
                return Err(StartError::WrongModel {
                    name: j.cfg.name.clone(),
                    id: j.cfg.id,
                    found: models::by_number(number)
                        .map_or_else(|| format!("model {number}"), |m| m.name.clone()),
                    want: j.model.name.clone(),
                });
            }
        }
        for k in 0..self.joints.len() {
            let j = self.joints[k].clone();
            let setup = |e| StartError::Setup {
                name: j.cfg.name.clone(),
                id: j.cfg.id,
                error: e,
            };
            let (a, b) = (j.counts(j.cfg.min_position), j.counts(j.cfg.max_position));
            let rpm = j.cfg.max_velocity * 60.0 / std::f64::consts::TAU;
            let speed = ((rpm / j.model.velocity_unit_rpm).floor() as i64).max(1);
            let speed_item = match j.model.protocol {
                Protocol::V1 => "moving_speed",
                Protocol::V2 => "profile_velocity",
            };
            let writes = [
                ("torque_enable", 0),
                ("return_delay_time", (return_delay_us / 2) as i64),
                ("min_position_limit", a.min(b)),
                ("max_position_limit", a.max(b)),
                (
                    speed_item,
                    speed.min(j.item(speed_item).max.unwrap_or(i64::MAX)),
                ),
            ];
            for (name, value) in writes {
                let item = j.item(name);
                self.bus
                    .write(j.cfg.id, item.address, &item.encode(value))
                    .map_err(setup)?;
            }
            let pos = j.item("present_position");
            let now = self
                .bus
                .read(j.cfg.id, pos.address, pos.size as u16)
                .map_err(setup)?;
            self.goals[k] = pos.decode(&now).unwrap_or(0) as i64;
            let goal = j.item("goal_position");
            self.bus
                .write(j.cfg.id, goal.address, &goal.encode(self.goals[k]))
                .map_err(setup)?;
            let torque = j.item("torque_enable");
            self.bus
                .write(j.cfg.id, torque.address, &[1])
                .map_err(setup)?;
        }
        self.bus
            .set_return_delay(Duration::from_micros(return_delay_us as u64));
        Ok(())
    }

    /// Takes a position command: every named joint must be ours, in position mode, within
    /// its position and velocity limits; otherwise nothing of it is applied.
    pub fn command(&mut self, c: &JointCommandT, now: Instant) -> Result<(), Reject> {
        let n = c.names.len();
        if c.modes.len() != n || c.setpoints.len() != n || c.velocities.len() != n {
            return Err(Reject::Malformed("arrays of different lengths".into()));
        }
        let mut goals = Vec::with_capacity(n);
        for k in 0..n {
            let name = &c.names[k];
            let j = self
                .joints
                .iter()
                .position(|j| &j.cfg.name == name)
                .ok_or_else(|| Reject::UnknownJoint(name.clone()))?;
            if c.modes[k] != JointCommandT::MODE_POSITION {
                return Err(Reject::Mode(name.clone()));
            }
            let cfg = &self.joints[j].cfg;
            let (p, v) = (c.setpoints[k], c.velocities[k]);
            if !(cfg.min_position..=cfg.max_position).contains(&p) {
                return Err(Reject::Limit {
                    joint: name.clone(),
                    what: format!(
                        "position {p:.4} rad outside [{}, {}]",
                        cfg.min_position, cfg.max_position
                    ),
                });
            }
            if v.abs() > cfg.max_velocity || v.is_nan() {
                return Err(Reject::Limit {
                    joint: name.clone(),
                    what: format!("velocity {v:.4} rad/s beyond {}", cfg.max_velocity),
                });
            }
            goals.push((j, self.joints[j].counts(p)));
        }
        for (j, g) in goals {
            self.goals[j] = g;
        }
        self.last_command = Some(now);
        self.holding = false;
        Ok(())
    }

    /// True once when commands stopped for longer than the hold timeout: the goals are then
    /// set to where the servos are, so they stop there.
    pub fn hold_if_stale(&mut self, now: Instant) -> bool {
        let (Some(t), Some(last)) = (self.hold_timeout, self.last_command) else {
            return false;
        };
        if self.holding || now.saturating_duration_since(last) <= t {
            return false;
        }
        self.holding = true;
        for (k, j) in self.joints.iter().enumerate() {
            if self.measured[k].at.is_some() {
                self.goals[k] = j.counts(self.measured[k].position);
            }
        }
        true
    }

    /// One cycle: the goals in one sync write, then every servo's state read.
    pub fn cycle(&mut self, now: Instant) -> Result<(), BusError> {
        let goal = self.joints[0].item("goal_position");
        let data = self
            .joints
            .iter()
            .zip(&self.goals)
            .map(|(j, g)| (j.cfg.id, goal.encode(*g)))
            .collect();
        self.bus.sync_write(goal.address, goal.size as u16, data)?;
        // One contiguous block holds position, velocity, load or current, voltage and
        // temperature on every shipped model.
        let names = [
            "present_position",
            "present_velocity",
            "present_voltage",
            "present_temperature",
        ];
        let j0 = self.joints[0].clone();
        let extra = if j0.model.item("present_current").is_some() {
            "present_current"
        } else {
            "present_load"
        };
        let items: Vec<_> = names.iter().chain([&extra]).map(|n| j0.item(n)).collect();
        let start = items.iter().map(|i| i.address).min().expect("items");
        let end = items
            .iter()
            .map(|i| i.address + i.size as u16)
            .max()
            .expect("items");
        let ids: Vec<u8> = self.joints.iter().map(|j| j.cfg.id).collect();
        let mut replies = self.bus.read_many(start, end - start, &ids, self.read)?;
        // One silent servo spoils a fast sync read for all: ask again servo by servo (sync
        // read), so only the silent one goes without.
        if self.read == ReadMany::FastSync && replies.iter().all(Result::is_err) {
            replies = self
                .bus
                .read_many(start, end - start, &ids, ReadMany::Sync)?;
        }
        let mut alerts = Vec::new();
        for (k, r) in replies.into_iter().enumerate() {
            // No answer after the retries: the last measurement stands (its time says so).
            let Ok(s) = r else {
                continue;
            };
            let j = &self.joints[k];
            let at = |name: &str| {
                let i = j.item(name);
                i.decode(&s.params[(i.address - start) as usize..])
                    .unwrap_or(0)
            };
            let m = &mut self.measured[k];
            m.position = j.rad(at("present_position") as i64);
            m.velocity = j.cfg.direction as f64 * j.model.velocity_rad_s(at("present_velocity"));
            m.voltage = at("present_voltage") as f64 * j.model.voltage_unit;
            m.temperature = at("present_temperature") as f64;
            if let Some(unit) = j.model.current_unit_ma {
                let raw = Model::signed(at("present_current"), Encoding::TwosComplement, 2);
                m.current = raw as f64 * unit / 1000.0;
                let limit = j
                    .model
                    .item("current_limit")
                    .map_or(1.0, |i| i.default.max(1) as f64);
                m.load = (raw as f64 / limit).clamp(-1.0, 1.0);
            } else {
                let raw = Model::signed(at("present_load"), Encoding::SignBit10, 2);
                m.load = raw as f64 / 1023.0;
                m.current = f64::NAN;
            }
            m.at = Some(now);
            match j.model.protocol {
                Protocol::V1 => m.errors = s.error,
                Protocol::V2 => {
                    if v2::StatusError(s.error).alert() {
                        alerts.push(k);
                    } else {
                        m.hardware = 0;
                        m.errors = 0;
                    }
                }
            }
        }
        // A 2.0 alert: read the hardware error status of that servo to say why.
        for k in alerts {
            let j = self.joints[k].clone();
            let hw = j.item("hardware_error_status");
            if let Ok(d) = self.bus.read(j.cfg.id, hw.address, 1) {
                let bits = d[0];
                let m = &mut self.measured[k];
                m.hardware = bits;
                m.errors = [
                    (
                        v2::HardwareError::INPUT_VOLTAGE,
                        v1::ErrorBits::INPUT_VOLTAGE,
                    ),
                    (v2::HardwareError::OVERHEATING, v1::ErrorBits::OVERHEATING),
                    (v2::HardwareError::OVERLOAD, v1::ErrorBits::OVERLOAD),
                ]
                .iter()
                .filter(|(h, _)| bits & h != 0)
                .fold(0, |a, (_, e)| a | e);
            }
        }
        Ok(())
    }

    /// Torque off on every servo (one sync write).
    pub fn torque_off(&mut self) -> Result<(), BusError> {
        let t = self.joints[0].item("torque_enable");
        let data = self.joints.iter().map(|j| (j.cfg.id, vec![0])).collect();
        self.bus.sync_write(t.address, 1, data)
    }

    /// What was measured, per joint.
    pub fn measured(&self) -> &[Measured] {
        &self.measured
    }

    /// The joint states message.
    pub fn joint_state(&self, header: HeaderT) -> JointStateT {
        let n = self.joints.len();
        JointStateT {
            header,
            num_joints: n as i32,
            names: self.joints.iter().map(|j| j.cfg.name.clone()).collect(),
            positions: self.measured.iter().map(|m| m.position).collect(),
            velocities: self.measured.iter().map(|m| m.velocity).collect(),
            currents: self.measured.iter().map(|m| m.current).collect(),
            temperatures: self.measured.iter().map(|m| m.temperature as f32).collect(),
            faults: self
                .measured
                .iter()
                .map(|m| m.errors as i32 | (m.hardware as i32) << 8)
                .collect(),
        }
    }

    /// The servo health message.
    pub fn health(&self, header: HeaderT) -> DynamixelStateT {
        let n = self.joints.len();
        DynamixelStateT {
            header,
            port: self.port.clone(),
            num_servos: n as i32,
            ids: self.joints.iter().map(|j| j.cfg.id as i8).collect(),
            joint_names: self.joints.iter().map(|j| j.cfg.name.clone()).collect(),
            positions: self.measured.iter().map(|m| m.position).collect(),
            speeds: self.measured.iter().map(|m| m.velocity).collect(),
            loads: self.measured.iter().map(|m| m.load as f32).collect(),
            voltages: self.measured.iter().map(|m| m.voltage as f32).collect(),
            temperatures: self.measured.iter().map(|m| m.temperature as f32).collect(),
            errors: self.measured.iter().map(|m| m.errors as i8).collect(),
            hardware_alerts: self.measured.iter().map(|m| m.hardware as i8).collect(),
            timeouts: self
                .joints
                .iter()
                .map(|j| self.bus.missed(j.cfg.id) as i32)
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    use stride_fakes::dynamixel::{ChainLevers, FakeChain, Fault, Servo};
    use stride_serial::{pty_pair, Paced};

    fn shipped(name: &str) -> BridgeConfig {
        let path = format!("{}/../../config/robots/{name}", env!("CARGO_MANIFEST_DIR"));
        toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    }

    #[test]
    fn shipped_configs_check() {
        let hex = shipped("hexapod-dynamixel.toml");
        assert_eq!(hex.check(), Ok(Protocol::V1));
        assert_eq!(hex.servo.len(), 18);
        let arm = shipped("arm-xm430.toml");
        assert_eq!(arm.check(), Ok(Protocol::V2));
        let mut bad = arm.clone();
        bad.servo[1].id = bad.servo[0].id;
        assert!(bad.check().is_err());
        let mut bad = hex.clone();
        bad.servo[0].max_position = 3.0; // beyond the AX-12A's 300 degrees
        assert!(bad.check().unwrap_err().contains("outside"));
    }

    #[test]
    fn counts_and_radians() {
        let ax = models::by_name("AX-12A").unwrap();
        let mut cfg = shipped("hexapod-dynamixel.toml").servo[3].clone();
        let j = Joint::new(cfg.clone(), ax);
        assert_eq!(j.counts(0.0), 512);
        assert!((j.rad(j.counts(0.5)) - 0.5).abs() < ax.rad_per_count());
        cfg.direction = -1;
        cfg.zero_offset = 0.1;
        let j = Joint::new(cfg, ax);
        assert_eq!(j.counts(0.1), 512);
        assert!(j.counts(0.5) < 512);
    }

    struct Sim {
        chain: Chain<stride_serial::Port<serialport::TTYPort>>,
        levers: ChainLevers,
        stop: Arc<AtomicBool>,
        h: Option<std::thread::JoinHandle<FakeChain>>,
    }

    impl Drop for Sim {
        fn drop(&mut self) {
            self.stop.store(true, Ordering::Relaxed);
            let _ = self.h.take().map(|h| h.join());
        }
    }

    fn sim(cfg: &BridgeConfig, skip: Option<u8>) -> Sim {
        let (host, dev) = pty_pair(cfg.baud).unwrap();
        let servos = cfg
            .servo
            .iter()
            .filter(|s| Some(s.id) != skip)
            .map(|s| Servo::new(s.id, models::by_name(&s.model).unwrap()))
            .collect();
        let levers = ChainLevers::default();
        let stop = Arc::new(AtomicBool::new(false));
        let protocol = cfg.check().unwrap();
        let h =
            FakeChain::new(protocol, servos, levers.clone()).spawn(Paced::new(dev), stop.clone());
        let mut cfg = cfg.clone();
        cfg.margin_ms = 25.0; // a pty on a loaded test machine
        Sim {
            chain: Chain::new(host, &cfg).unwrap(),
            levers,
            stop,
            h: Some(h),
        }
    }

    fn command(names: &[&str], positions: &[f64]) -> JointCommandT {
        let n = names.len();
        JointCommandT {
            num_joints: n as i32,
            names: names.iter().map(|s| s.to_string()).collect(),
            modes: vec![JointCommandT::MODE_POSITION; n],
            setpoints: positions.to_vec(),
            velocities: vec![0.0; n],
            ..Default::default()
        }
    }

    #[test]
    fn a_missing_servo_stops_the_start_by_name() {
        let cfg = shipped("hexapod-dynamixel.toml");
        let mut s = sim(&cfg, Some(7));
        let e = s.chain.bring_up(0).unwrap_err();
        assert_eq!(e, StartError::Missing("lr_coxa (id 7)".into()));
    }

    #[test]
    fn hexapod_moves_holds_and_refuses_limits() {
        let cfg = shipped("hexapod-dynamixel.toml");
        let mut s = sim(&cfg, None);
        s.chain.bring_up(0).unwrap();
        let t0 = Instant::now();
        s.chain
            .command(&command(&["lf_femur", "rf_femur"], &[0.4, 0.4]), t0)
            .unwrap();
        // Past a limit: refused whole, the other joint's goal untouched.
        let e = s
            .chain
            .command(&command(&["lf_femur", "lf_tibia"], &[0.2, 2.5]), t0)
            .unwrap_err();
        assert!(
            matches!(&e, Reject::Limit { joint, .. } if joint == "lf_tibia"),
            "{e}"
        );
        let deadline = Instant::now() + Duration::from_secs(3);
        loop {
            s.chain.cycle(Instant::now()).unwrap();
            let m = s.chain.measured();
            if (m[1].position - 0.4).abs() < 0.01 && (m[10].position - 0.4).abs() < 0.01 {
                break;
            }
            assert!(Instant::now() < deadline, "{:?} {:?}", m[1], m[10]);
        }
        // An overheating servo: its error bits say so.
        s.levers.set(
            5,
            Fault {
                overheat: true,
                ..Fault::default()
            },
        );
        std::thread::sleep(Duration::from_millis(20));
        s.chain.cycle(Instant::now()).unwrap();
        let health = s.chain.health(HeaderT::default());
        assert_eq!(
            health.errors[4] as u8 & v1::ErrorBits::OVERHEATING,
            v1::ErrorBits::OVERHEATING
        );
        assert!(health.temperatures[4] > 70.0);
        // Commands stop: after the hold timeout the goals become where the servos are.
        s.chain
            .command(&command(&["lm_femur"], &[1.2]), Instant::now())
            .unwrap();
        s.chain.cycle(Instant::now()).unwrap();
        let later = Instant::now() + Duration::from_millis(600);
        assert!(s.chain.hold_if_stale(later));
        assert!(!s.chain.hold_if_stale(later), "holds once");
        s.chain.cycle(Instant::now()).unwrap();
        std::thread::sleep(Duration::from_millis(200));
        s.chain.cycle(Instant::now()).unwrap();
        let held = s.chain.measured()[4].position;
        assert!(held < 1.1, "kept going to its goal: {held}");
        s.chain.torque_off().unwrap();
    }

    #[test]
    fn arm_on_protocol_2_reports_alerts_and_timeouts() {
        let cfg = shipped("arm-xm430.toml");
        let mut s = sim(&cfg, None);
        s.chain.bring_up(0).unwrap();
        s.chain.cycle(Instant::now()).unwrap();
        assert!(s.chain.measured().iter().all(|m| m.at.is_some()));
        s.levers.set(
            2,
            Fault {
                overload: true,
                ..Fault::default()
            },
        );
        std::thread::sleep(Duration::from_millis(20));
        s.chain.cycle(Instant::now()).unwrap();
        let h = s.chain.health(HeaderT::default());
        assert_eq!(h.hardware_alerts[1] as u8, v2::HardwareError::OVERLOAD);
        assert_eq!(h.errors[1] as u8, v1::ErrorBits::OVERLOAD);
        // A silent servo spoils the fast sync read; the sync read that follows tells which.
        s.levers.clear(2);
        s.levers.set(
            4,
            Fault {
                silent: true,
                ..Fault::default()
            },
        );
        s.chain.cycle(Instant::now()).unwrap();
        let t = s.chain.health(HeaderT::default()).timeouts;
        assert!(
            t[3] > 0 && t.iter().enumerate().all(|(k, &n)| k == 3 || n == 0),
            "{t:?}"
        );
    }
}
