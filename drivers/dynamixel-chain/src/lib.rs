//! The master of a chain of Dynamixel servos on one line, generic over the serial
//! [`Transport`]: bring-up (every servo there and the configured model, its return delay,
//! position limits from the joint's, speed limit and, on Protocol 2.0, its bus watchdog, so
//! it stops on its own when the host stops talking), then each cycle one sync write of every
//! goal and one read of every servo's state block; commands checked whole against every
//! joint's limits (`stride-limits`); the hold where the servos are when commands stop;
//! [`Chain::reattach`] after the port vanished and came back. The wire work is
//! `stride-dynamixel-bus`'s; the LCM side is the bridge's.
//!
//! AX-12A and the other Protocol 1.0 models have no bus watchdog: when the host dies they
//! keep their last goal, torque on.

use std::time::{Duration, Instant};

use stride_dynamixel::models::{self, Encoding, Model};
use stride_dynamixel::{v1, v2, Protocol};
use stride_dynamixel_bus::{Bus, BusConfig, BusError, ReadMany};
use stride_limits::{Limits, Reject};
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

/// The chain's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainConfig {
    /// The servos.
    pub servos: Vec<ServoConfig>,
    /// How positions are read.
    pub read: ReadMode,
    /// Return delay time set on every servo at bring-up, µs (0 is fastest; factory: 500).
    pub return_delay_us: u32,
    /// Added to every reply deadline for the USB adapter and the host.
    pub margin: Duration,
    /// Tries after the first when a reply is lost.
    pub retries: u32,
    /// When no command came for this long, the servos hold where they are (`None`: never).
    pub hold_timeout: Option<Duration>,
    /// Protocol 2.0 servos stop on their own when the host says nothing for this long
    /// (their bus watchdog, item 98, in 20 ms units up to 2.54 s; `None`: off).
    pub bus_watchdog: Option<Duration>,
}

/// A bus watchdog time as the servos' item 98 holds it: whole 20 ms units, 1..=127; any
/// other time is refused (never rounded to a shorter one the servos would stop on).
pub fn watchdog_units(w: Duration) -> Result<u8, String> {
    let ms = w.as_millis();
    if !(20..=2540).contains(&ms)
        || !ms.is_multiple_of(20)
        || !w.subsec_nanos().is_multiple_of(1_000_000)
    {
        return Err(format!(
            "a bus watchdog of {} ms is not a whole number of 20 ms units in 20..=2540",
            w.as_secs_f64() * 1e3
        ));
    }
    Ok((ms / 20) as u8)
}

/// Checks a chain's servos; returns their protocol.
pub fn check(servos: &[ServoConfig]) -> Result<Protocol, String> {
    let first = servos
        .first()
        .ok_or("the configuration lists no [[servo]] (give one with --config, e.g. config/robots/hexapod-dynamixel.toml)")?;
    let protocol = model(&first.model)?.protocol;
    let mut ids = std::collections::BTreeSet::new();
    let mut names = std::collections::BTreeSet::new();
    for s in servos {
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
        if !names.insert(s.name.as_str()) {
            return Err(format!("joint {} named twice", s.name));
        }
        if s.direction.abs() != 1 {
            return Err(format!("servo {}: direction is 1 or -1", s.name));
        }
        Joint::limits_of(s).check(&s.name)?;
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
    /// Its limits.
    pub limits: Limits,
}

impl Joint {
    fn limits_of(cfg: &ServoConfig) -> Limits {
        Limits {
            min_position: cfg.min_position,
            max_position: cfg.max_position,
            max_velocity: cfg.max_velocity,
        }
    }

    /// The joint of `cfg` on a servo of `model`.
    pub fn new(cfg: ServoConfig, model: &'static Model) -> Joint {
        Joint {
            limits: Joint::limits_of(&cfg),
            cfg,
            model,
        }
    }

    /// The speed written at start, the model's units: the joint's speed limit.
    fn setup_speed(&self) -> i64 {
        let rpm = self.cfg.max_velocity * 60.0 / std::f64::consts::TAU;
        let speed = ((rpm / self.model.velocity_unit_rpm).floor() as i64).max(1);
        let item = match self.model.protocol {
            Protocol::V1 => "moving_speed",
            Protocol::V2 => "profile_velocity",
        };
        let max = self
            .model
            .item(item)
            .and_then(|i| i.max)
            .unwrap_or(i64::MAX);
        speed.min(max)
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

    fn item(&self, name: &str) -> Result<stride_dynamixel::models::Item, BusError> {
        self.model
            .item(name)
            .copied()
            .ok_or_else(|| BusError::Refused {
                id: self.cfg.id,
                what: format!("the {} has no item {name}", self.model.name),
            })
    }
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

/// A problem found at bring-up: the chain refuses to run.
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

/// The chain: the bus, the joints, their goals, what was last measured.
pub struct Chain<T: Transport> {
    bus: Bus<T>,
    cfg: ChainConfig,
    joints: Vec<Joint>,
    goals: Vec<i64>,
    /// Each servo's speed for the move to its goal (moving speed or profile velocity, in the
    /// model's units), when the last command gave one.
    speeds: Vec<Option<i64>>,
    measured: Vec<Measured>,
    read: ReadMany,
    last_command: Option<Instant>,
    holding: bool,
    /// The bus watchdog in item 98's units (`None`: off).
    watchdog: Option<u8>,
}

impl<T: Transport> Chain<T> {
    /// A chain on `line` as `cfg` describes (checked with [`check`]).
    pub fn new(line: T, cfg: ChainConfig) -> Result<Chain<T>, String> {
        let protocol = check(&cfg.servos)?;
        let joints: Vec<Joint> = cfg
            .servos
            .iter()
            .map(|s| model(&s.model).map(|m| Joint::new(s.clone(), m)))
            .collect::<Result<_, _>>()?;
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
        let watchdog = cfg.bus_watchdog.map(watchdog_units).transpose()?;
        let bus_cfg = BusConfig {
            margin: cfg.margin,
            retries: cfg.retries,
            ..BusConfig::new(protocol)
        };
        let n = joints.len();
        Ok(Chain {
            bus: Bus::new(line, bus_cfg),
            goals: joints.iter().map(|j| j.model.center()).collect(),
            speeds: vec![None; n],
            joints,
            measured: vec![Measured::default(); n],
            read,
            last_command: None,
            holding: false,
            watchdog,
            cfg,
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

    /// What was measured, per joint.
    pub fn measured(&self) -> &[Measured] {
        &self.measured
    }

    /// The protocol of the chain.
    pub fn protocol(&self) -> Protocol {
        self.bus.config().protocol
    }

    /// Puts the chain on a new line (the port came back) and brings every servo up again:
    /// each holds where it stands.
    pub fn reattach(&mut self, line: T) -> Result<(), StartError> {
        self.bus.replace_line(line);
        self.last_command = None;
        self.holding = false;
        self.bring_up()
    }

    /// Checks every servo is there and the right model, then sets each up: torque off, return
    /// delay, position limits and speed limit from the configuration, the bus watchdog (2.0),
    /// goal = where it is, torque on.
    pub fn bring_up(&mut self) -> Result<(), StartError> {
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
            let Some(&(_, number)) = found.iter().find(|(i, _)| *i == j.cfg.id) else {
                continue;
            };
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
            self.setup(k, &j).map_err(setup)?;
        }
        self.bus
            .set_return_delay(Duration::from_micros(self.cfg.return_delay_us as u64));
        Ok(())
    }

    fn setup(&mut self, k: usize, j: &Joint) -> Result<(), BusError> {
        let (a, b) = (j.counts(j.cfg.min_position), j.counts(j.cfg.max_position));
        let speed = j.setup_speed();
        let speed_item = match j.model.protocol {
            Protocol::V1 => "moving_speed",
            Protocol::V2 => "profile_velocity",
        };
        let mut writes = vec![
            ("torque_enable", 0),
            ("return_delay_time", (self.cfg.return_delay_us / 2) as i64),
            ("min_position_limit", a.min(b)),
            ("max_position_limit", a.max(b)),
            (speed_item, speed),
        ];
        if j.model.item("bus_watchdog").is_some() {
            // 0 first: it clears a watchdog that tripped while the host was away.
            writes.push(("bus_watchdog", 0));
            if let Some(units) = self.watchdog {
                writes.push(("bus_watchdog", units as i64));
            }
        }
        for (name, value) in writes {
            let item = j.item(name)?;
            self.bus
                .write(j.cfg.id, item.address, &item.encode(value))?;
        }
        let pos = j.item("present_position")?;
        let now = self.bus.read(j.cfg.id, pos.address, pos.size as u16)?;
        self.goals[k] = pos.decode(&now).unwrap_or(0) as i64;
        self.measured[k].position = j.rad(self.goals[k]);
        let goal = j.item("goal_position")?;
        self.bus
            .write(j.cfg.id, goal.address, &goal.encode(self.goals[k]))?;
        let torque = j.item("torque_enable")?;
        self.bus.write(j.cfg.id, torque.address, &[1])
    }

    /// Takes a position command (`velocities`: the speeds it is passed at, checked against
    /// the limit): every named joint must be ours, named once, within its position and
    /// velocity limits; otherwise nothing of it is applied.
    pub fn command(
        &mut self,
        names: &[String],
        positions: &[f64],
        velocities: &[f64],
        now: Instant,
    ) -> Result<(), Reject> {
        let joints = &self.joints;
        let cols = stride_limits::check_setpoints(
            names,
            positions,
            Some(velocities),
            |n| joints.iter().position(|j| j.cfg.name == n),
            |k| &joints[k].limits,
        )?;
        for (k, &j) in cols.iter().enumerate() {
            self.goals[j] = self.joints[j].counts(positions[k]);
            // A speed given: the servo moves at it (rounded up, so it arrives in time; at
            // least one unit, which is the slowest; 0 would mean no speed control at all).
            let v = velocities.get(k).copied().unwrap_or(0.0).abs();
            let joint = &self.joints[j];
            self.speeds[j] = (v > 0.0).then(|| {
                let units =
                    (v * 60.0 / std::f64::consts::TAU / joint.model.velocity_unit_rpm).ceil();
                let top = (joint.cfg.max_velocity * 60.0
                    / std::f64::consts::TAU
                    / joint.model.velocity_unit_rpm)
                    .floor();
                units.clamp(1.0, top.max(1.0)) as i64
            });
        }
        self.last_command = Some(now);
        self.holding = false;
        Ok(())
    }

    /// True once when commands stopped for longer than the hold timeout: each servo's goal
    /// becomes where it is now (its last position carried on by its speed to now, never past
    /// its goal), so it stops there without stepping back.
    pub fn hold_if_stale(&mut self, now: Instant) -> bool {
        let (Some(t), Some(last)) = (self.cfg.hold_timeout, self.last_command) else {
            return false;
        };
        if self.holding || now.saturating_duration_since(last) <= t {
            return false;
        }
        self.holding = true;
        for (k, j) in self.joints.iter().enumerate() {
            let m = self.measured[k];
            let Some(at) = m.at else {
                continue;
            };
            let ahead = m.velocity * now.saturating_duration_since(at).as_secs_f64();
            let here = j.counts(m.position + ahead);
            let (from, goal) = (j.counts(m.position), self.goals[k]);
            // Between where it was measured and its goal: the servo does not reverse.
            self.goals[k] = here.clamp(from.min(goal), from.max(goal));
        }
        true
    }

    /// One cycle: the goals in one sync write, then every servo's state read.
    pub fn cycle(&mut self, now: Instant) -> Result<(), BusError> {
        let goal = self.joints[0].item("goal_position")?;
        if self.speeds.iter().any(Option::is_some) {
            // Goals and speeds in one sync write: the two items are neighbours (Protocol 1.0:
            // goal position then moving speed; 2.0: profile velocity then goal position). A
            // servo without a speed keeps the one set at start.
            let speed = self.joints[0].item(match self.joints[0].model.protocol {
                Protocol::V1 => "moving_speed",
                Protocol::V2 => "profile_velocity",
            })?;
            let start = goal.address.min(speed.address);
            let len = goal.size as u16 + speed.size as u16;
            let data = self
                .joints
                .iter()
                .enumerate()
                .map(|(k, j)| {
                    let v = self.speeds[k].unwrap_or_else(|| j.setup_speed());
                    let (g, s) = (goal.encode(self.goals[k]), speed.encode(v));
                    let bytes = if goal.address < speed.address {
                        [g, s].concat()
                    } else {
                        [s, g].concat()
                    };
                    (j.cfg.id, bytes)
                })
                .collect();
            self.bus.sync_write(start, len, data)?;
        } else {
            let data = self
                .joints
                .iter()
                .zip(&self.goals)
                .map(|(j, g)| (j.cfg.id, goal.encode(*g)))
                .collect();
            self.bus.sync_write(goal.address, goal.size as u16, data)?;
        }
        // One contiguous block holds position, velocity, load or current, voltage and
        // temperature on every shipped model.
        let j0 = self.joints[0].clone();
        let extra = if j0.model.item("present_current").is_some() {
            "present_current"
        } else {
            "present_load"
        };
        let items = [
            "present_position",
            "present_velocity",
            "present_voltage",
            "present_temperature",
            extra,
        ]
        .iter()
        .map(|n| j0.item(n))
        .collect::<Result<Vec<_>, _>>()?;
        let start = items.iter().map(|i| i.address).min().unwrap_or(0);
        let end = items
            .iter()
            .map(|i| i.address + i.size as u16)
            .max()
            .unwrap_or(start);
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
                j.model.item(name).map_or(0, |i| {
                    s.params
                        .get((i.address - start) as usize..)
                        .and_then(|b| i.decode(b))
                        .unwrap_or(0)
                })
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
            let hw = j.item("hardware_error_status")?;
            if let Ok(d) = self.bus.read(j.cfg.id, hw.address, 1) {
                let bits = d.first().copied().unwrap_or(0);
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
        let t = self.joints[0].item("torque_enable")?;
        let data = self.joints.iter().map(|j| (j.cfg.id, vec![0])).collect();
        self.bus.sync_write(t.address, 1, data)
    }
}
