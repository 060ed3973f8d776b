//! A fake chain of Dynamixel servos on a serial line (a pty in tests): each servo has its
//! model's control table (EEPROM and RAM items, defaults, ranges, read-only items), answers
//! after its return delay time as its status return level says, moves towards its goal when
//! its torque is on, and reports the errors a real one does: input voltage, angle limit,
//! overheating (with the shutdown that follows), overload, range, instruction, checksum (1.0)
//! and CRC and data length (2.0). A reboot resets its RAM and keeps its EEPROM; a factory
//! reset keeps what its option says (2.0: 0xFF nothing, 0x01 the id, 0x02 the id and the baud
//! rate; 1.0 nothing), and a broadcast reset of everything is ignored, as X firmware does; the
//! baud-rate item says the line's rate. Levers ([`ChainLevers`]) make a servo overheat,
//! overload, sag in voltage, answer late or fall silent, as on a bench. Protocol 1.0 or 2.0,
//! the whole chain alike.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use stride_dynamixel::models::{Access, Area, Model};
use stride_dynamixel::v1::ErrorBits;
use stride_dynamixel::v2::HardwareError;
use stride_dynamixel::{v1, v2, Instruction, Protocol, Split, Status, BROADCAST};
use stride_serial::Transport;

/// Faults a test puts on a servo.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Fault {
    /// Answers nothing (a cut cable).
    pub silent: bool,
    /// Its temperature climbs above its limit.
    pub overheat: bool,
    /// It carries more than it can: it stalls at its torque limit (AX/MX `torque_limit`, X
    /// `current_limit`) and reports the overload.
    pub overload: bool,
    /// Extra delay before each answer.
    pub late: Duration,
    /// Supply voltage, V (`None`: 12 V).
    pub voltage: Option<f64>,
}

/// The levers of a chain, shared with the test.
#[derive(Debug, Clone, Default)]
pub struct ChainLevers(Arc<Mutex<BTreeMap<u8, Fault>>>);

impl ChainLevers {
    /// Puts `fault` on servo `id` (replacing what was there).
    pub fn set(&self, id: u8, fault: Fault) {
        self.0.lock().unwrap().insert(id, fault);
    }

    /// Clears servo `id`'s faults.
    pub fn clear(&self, id: u8) {
        self.0.lock().unwrap().remove(&id);
    }

    fn get(&self, id: u8) -> Fault {
        self.0.lock().unwrap().get(&id).copied().unwrap_or_default()
    }
}

/// The servos' true positions (counts, fractional while moving), as the chain last moved
/// them: what an instrument on the robot would measure, read while the chain runs on its
/// thread (the simulated world's input).
#[derive(Debug, Clone, Default)]
pub struct ChainProbe(Arc<Mutex<BTreeMap<u8, f64>>>);

impl ChainProbe {
    /// Each servo's id and true position, counts (empty before the chain first moves).
    pub fn positions(&self) -> BTreeMap<u8, f64> {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }
}

/// One fake servo.
#[derive(Debug)]
pub struct Servo {
    id: u8,
    model: &'static Model,
    table: Vec<u8>,
    /// Position, counts (fractional while moving).
    position: f64,
    registered: Option<(u16, Vec<u8>)>,
    /// Error bits of the last instruction (Protocol 1.0 angle limit, range, instruction).
    transient: u8,
    /// Seconds since an instruction last concerned this servo (its bus watchdog's clock).
    silent_for: f64,
}

impl Servo {
    /// A servo of `model` with id `id`, factory settings otherwise.
    pub fn new(id: u8, model: &'static Model) -> Servo {
        let end = model
            .items
            .values()
            .map(|i| i.address as usize + i.size as usize)
            .max()
            .unwrap_or(0);
        let mut s = Servo {
            id,
            model,
            table: vec![0; end],
            position: 0.0,
            registered: None,
            transient: 0,
            silent_for: 0.0,
        };
        for item in model.items.values() {
            let b = item.encode(item.default);
            s.table[item.address as usize..][..b.len()].copy_from_slice(&b);
        }
        s.set("id", id as i64);
        s.position = s.get("present_position") as f64;
        s
    }

    /// The servo's id.
    pub fn id(&self) -> u8 {
        self.id
    }

    /// Sets the baud-rate item to the model's value for `baud` (as the servo on a line at
    /// that rate reads it).
    pub fn at_baud(mut self, baud: u32) -> Servo {
        if let Some(v) = self.model.baud_value(baud) {
            self.set("baud_rate", v as i64);
        }
        self
    }

    /// A reboot: the RAM back to its power-on values (torque off, the goal where the servo
    /// is), the EEPROM kept.
    fn reboot(&mut self) {
        let fresh = Servo::new(self.id, self.model);
        for item in self.model.items.values() {
            let sensor = item.access == Access::Read;
            if item.area == Area::Ram && !sensor {
                let (a, n) = (item.address as usize, item.size as usize);
                self.table[a..a + n].copy_from_slice(&fresh.table[a..a + n]);
            }
        }
        self.set("goal_position", self.position.round() as i64);
        self.set("registered", 0);
        self.registered = None;
    }

    /// A factory reset keeping what `option` says (2.0: 0x01 the id, 0x02 the id and the
    /// baud rate; anything else, and every 1.0 reset, nothing).
    fn factory_reset(&mut self, option: u8) {
        let (id, baud) = (self.get("id"), self.get("baud_rate"));
        let position = self.position;
        let mut fresh = Servo::new(
            self.model.item("id").map_or(1, |i| i.default as u8),
            self.model,
        );
        if self.protocol() == Protocol::V2 {
            if option == 0x01 || option == 0x02 {
                fresh.set("id", id);
            }
            if option == 0x02 {
                fresh.set("baud_rate", baud);
            }
        }
        fresh.id = fresh.get("id") as u8;
        fresh.position = position;
        fresh.set("present_position", position.round() as i64);
        fresh.set("goal_position", position.round() as i64);
        *self = fresh;
    }

    /// The value of control-table item `name` (0 when the model has none), as the servo
    /// holds it: a bench instrument's view.
    pub fn item(&self, name: &str) -> i64 {
        self.get(name)
    }

    /// True while its torque is on.
    pub fn torque_on(&self) -> bool {
        self.get("torque_enable") == 1
    }

    fn get(&self, name: &str) -> i64 {
        self.model.item(name).map_or(0, |i| {
            let v = i.decode(&self.table[i.address as usize..]).unwrap_or(0);
            if i.min.is_some_and(|m| m < 0) {
                Model::signed(
                    v,
                    stride_dynamixel::models::Encoding::TwosComplement,
                    i.size,
                )
            } else {
                v as i64
            }
        })
    }

    fn set(&mut self, name: &str, value: i64) {
        if let Some(i) = self.model.item(name) {
            let b = i.encode(value);
            self.table[i.address as usize..][..b.len()].copy_from_slice(&b);
        }
    }

    fn protocol(&self) -> Protocol {
        self.model.protocol
    }

    /// The 1.0 error bits or the 2.0 hardware error bits the servo's state sets now.
    fn condition(&self, fault: &Fault) -> (u8, u8) {
        let (mut v1e, mut hw) = (0u8, 0u8);
        let volts = fault.voltage.unwrap_or(12.0);
        let unit = self.model.voltage_unit;
        let (lo, hi) = (
            self.get("min_voltage_limit") as f64 * unit,
            self.get("max_voltage_limit") as f64 * unit,
        );
        if volts < lo || volts > hi {
            v1e |= ErrorBits::INPUT_VOLTAGE;
            hw |= HardwareError::INPUT_VOLTAGE;
        }
        if self.get("present_temperature") > self.get("temperature_limit") {
            v1e |= ErrorBits::OVERHEATING;
            hw |= HardwareError::OVERHEATING;
        }
        if fault.overload {
            v1e |= ErrorBits::OVERLOAD;
            hw |= HardwareError::OVERLOAD;
        }
        (v1e, hw)
    }

    /// The bus watchdog (2.0, item 98, in 20 ms): when no instruction concerned the servo
    /// for that long while its torque is on, it stops where it is and reports -1; its goals
    /// stay refused until the item is written 0.
    fn watch_bus(&mut self, dt: f64) {
        self.silent_for += dt;
        let units = self.get("bus_watchdog");
        if units > 0 && self.torque_on() && self.silent_for > units as f64 * 0.020 {
            self.set("bus_watchdog", -1);
            self.set("goal_position", self.position.round() as i64);
        }
    }

    /// Advances the servo by `dt` under `fault`: sensors, motion, shutdown.
    fn advance(&mut self, dt: f64, fault: &Fault) {
        self.watch_bus(dt);
        let volts = fault.voltage.unwrap_or(12.0);
        self.set(
            "present_voltage",
            (volts / self.model.voltage_unit).round() as i64,
        );
        let limit = self.get("temperature_limit");
        self.set(
            "present_temperature",
            if fault.overheat { limit + 5 } else { 32 },
        );
        let (v1e, hw) = self.condition(fault);
        // Shutdown: the conditions the shutdown item names turn the torque off.
        let shutdown = self.get("shutdown") as u8;
        let tripped = match self.protocol() {
            Protocol::V1 => v1e & shutdown != 0,
            Protocol::V2 => hw & shutdown != 0,
        };
        if self.protocol() == Protocol::V2 {
            self.set("hardware_error_status", hw as i64);
        }
        if tripped {
            self.set("torque_enable", 0);
        }
        let goal = self.get("goal_position") as f64;
        let on = self.get("torque_enable") == 1;
        let counts_per_rev =
            self.model.position_counts as f64 * 360.0 / self.model.position_range_deg;
        let speed_item = match self.protocol() {
            Protocol::V1 => self.get("moving_speed") & 0x3ff,
            Protocol::V2 => self.get("profile_velocity"),
        };
        // Unset speed: the servo's top speed, about 1 rev/s.
        let rpm = if speed_item > 0 {
            speed_item as f64 * self.model.velocity_unit_rpm
        } else {
            60.0
        };
        let step = rpm / 60.0 * counts_per_rev * dt;
        let before = self.position;
        // Overloaded, the motor gives no more than its torque limit and stalls there.
        if on && !fault.overload {
            let d = goal - self.position;
            self.position += d.clamp(-step, step);
        }
        let velocity_counts = if dt > 0.0 {
            (self.position - before) / dt
        } else {
            0.0
        };
        let raw_v =
            (velocity_counts / counts_per_rev * 60.0 / self.model.velocity_unit_rpm).round() as i64;
        let v = match self.model.velocity_encoding {
            stride_dynamixel::models::Encoding::SignBit10 => {
                raw_v.unsigned_abs().min(1023) as i64 | if raw_v < 0 { 0x400 } else { 0 }
            }
            stride_dynamixel::models::Encoding::TwosComplement => raw_v,
        };
        self.set("present_velocity", v);
        self.set("present_position", self.position.round() as i64);
        self.set("moving", (on && (goal - self.position).abs() > 1.0) as i64);
        let (torque_limit, current_limit) = (self.get("torque_limit"), self.get("current_limit"));
        self.set(
            "present_load",
            if fault.overload && on {
                torque_limit
            } else {
                0
            },
        );
        self.set(
            "present_current",
            if fault.overload && on {
                current_limit
            } else {
                0
            },
        );
    }

    /// Reads `length` bytes at `address`.
    fn read(&self, address: u16, length: u16) -> Result<Vec<u8>, u8> {
        let (a, n) = (address as usize, length as usize);
        self.table.get(a..a + n).map(<[u8]>::to_vec).ok_or(4)
    }

    /// Writes `data` at `address` as the servo would: every item touched must be writable,
    /// EEPROM only with the torque off (2.0), values within range, goals within the angle
    /// limits. Errors: the 2.0 error number (the 1.0 bits are set in `transient`).
    fn write(&mut self, address: u16, data: &[u8]) -> Result<(), u8> {
        let (a, n) = (address as usize, data.len());
        if a + n > self.table.len() {
            self.transient |= ErrorBits::RANGE;
            return Err(4);
        }
        let torque_on = self.get("torque_enable") == 1;
        let watchdog_tripped = self.get("bus_watchdog") == -1;
        let mut next = self.table.clone();
        next[a..a + n].copy_from_slice(data);
        for (name, item) in &self.model.items {
            let (ia, isz) = (item.address as usize, item.size as usize);
            if ia + isz <= a || ia >= a + n {
                continue;
            }
            if item.access == Access::Read {
                self.transient |= ErrorBits::RANGE;
                return Err(7);
            }
            if watchdog_tripped && name.starts_with("goal_") {
                return Err(7);
            }
            // 2.0 writes whole items: less than one is a data length error.
            if self.protocol() == Protocol::V2 && (ia < a || ia + isz > a + n) {
                return Err(5);
            }
            if item.area == Area::Eeprom && torque_on && self.protocol() == Protocol::V2 {
                return Err(7);
            }
            let v = item.decode(&next[ia..]).unwrap_or(0) as i64;
            if !item.accepts(v) {
                self.transient |= ErrorBits::RANGE;
                return Err(6);
            }
            if name == "goal_position"
                && !(self.get("min_position_limit")..=self.get("max_position_limit")).contains(&v)
            {
                self.transient |= ErrorBits::ANGLE_LIMIT;
                return Err(6);
            }
        }
        self.table = next;
        self.id = self.get("id") as u8;
        if self
            .model
            .item("bus_watchdog")
            .is_some_and(|w| (a..a + n).contains(&(w.address as usize)))
        {
            // A new watchdog time (or 0, which clears its error) counts from now.
            self.silent_for = 0.0;
        }
        Ok(())
    }

    /// The status error byte for an answer now.
    fn error_byte(&mut self, fault: &Fault, number: u8) -> u8 {
        let (v1e, hw) = self.condition(fault);
        match self.protocol() {
            Protocol::V1 => std::mem::take(&mut self.transient) | v1e,
            Protocol::V2 => {
                self.transient = 0;
                number | if hw != 0 { 0x80 } else { 0 }
            }
        }
    }
}

/// A chain of fake servos on one line.
pub struct FakeChain {
    protocol: Protocol,
    servos: Vec<Servo>,
    levers: ChainLevers,
    last: Option<Instant>,
    probe: ChainProbe,
}

impl FakeChain {
    /// A chain of `servos` (all speaking `protocol`), with `levers`.
    pub fn new(protocol: Protocol, servos: Vec<Servo>, levers: ChainLevers) -> FakeChain {
        FakeChain {
            protocol,
            servos,
            levers,
            last: None,
            probe: ChainProbe::default(),
        }
    }

    /// The servos' true positions, shared with the chain once it runs.
    pub fn probe(&self) -> ChainProbe {
        self.probe.clone()
    }

    /// Runs the chain on its own thread, on `line` (wrap it in [`stride_serial::Paced`] for
    /// real wire timing), until `stop` is set.
    pub fn spawn(
        mut self,
        mut line: impl Transport + 'static,
        stop: Arc<AtomicBool>,
    ) -> JoinHandle<FakeChain> {
        std::thread::spawn(move || {
            let mut s1 = v1::Splitter::new();
            let mut s2 = v2::Splitter::new();
            let mut buf = [0u8; 1024];
            // Answers wait for their time here, while the line is still listened to: a late
            // servo does not hold back the others' answers to later instructions.
            let mut due: std::collections::VecDeque<(Instant, Vec<u8>)> = Default::default();
            while !stop.load(Ordering::Relaxed) {
                let wake = due
                    .front()
                    .map_or(Instant::now() + Duration::from_millis(2), |(t, _)| *t)
                    .min(Instant::now() + Duration::from_millis(2));
                let n = match line.read_until(&mut buf, wake) {
                    Ok(n) => n,
                    Err(_) => {
                        std::thread::sleep(Duration::from_millis(2));
                        0
                    }
                };
                self.advance(Instant::now());
                let packets: Vec<Result<Vec<u8>, u8>> = match self.protocol {
                    Protocol::V1 => {
                        s1.push(&buf[..n]);
                        std::iter::from_fn(|| s1.next_item()).collect::<Vec<_>>()
                    }
                    Protocol::V2 => {
                        s2.push(&buf[..n]);
                        std::iter::from_fn(|| s2.next_item()).collect::<Vec<_>>()
                    }
                }
                .into_iter()
                .filter_map(|s| match s {
                    Split::Packet(p) => Some(Ok(p)),
                    Split::Skipped { id: Some(id), .. } => Some(Err(id)),
                    Split::Skipped { .. } => None,
                })
                .collect();
                for p in packets {
                    let answers = match p {
                        Ok(p) => self.handle(&p),
                        Err(id) => self.bad_checksum(id).into_iter().collect(),
                    };
                    // Answers to one instruction follow each other, each after its delay.
                    let mut t = Instant::now();
                    for (delay, bytes) in answers {
                        t += delay;
                        let at = due.partition_point(|(d, _)| *d <= t);
                        due.insert(at, (t, bytes));
                    }
                }
                while due.front().is_some_and(|(t, _)| *t <= Instant::now()) {
                    let (_, bytes) = due.pop_front().expect("front");
                    let _ = line.write_all(&bytes);
                }
            }
            self
        })
    }

    /// The servos' baud-rate items set to the line's `baud`.
    pub fn at_baud(mut self, baud: u32) -> FakeChain {
        self.servos = self.servos.into_iter().map(|s| s.at_baud(baud)).collect();
        self
    }

    /// The servos, as they are now.
    pub fn servos(&self) -> &[Servo] {
        &self.servos
    }

    /// A servo's answer to a packet with a bad checksum (1.0) or CRC (2.0) addressed to it.
    fn bad_checksum(&mut self, id: u8) -> Option<(Duration, Vec<u8>)> {
        self.error_status(id, ErrorBits::CHECKSUM, 3)
    }

    /// A servo's answer to an instruction it does not know, or whose parameters do not fit
    /// it (2.0: instruction error 2, data length error 5; 1.0: the instruction bit).
    fn bad_instruction(&mut self, packet: &[u8]) -> Option<(Duration, Vec<u8>)> {
        let ((id, code), err) = match self.protocol {
            Protocol::V1 => {
                let (id, code, _) = v1::unframe(packet).ok()?;
                ((id, code), v1::decode_instruction(packet).err())
            }
            Protocol::V2 => {
                let (id, code, _) = v2::unframe(packet).ok()?;
                ((id, code), v2::decode_instruction(packet).err())
            }
        };
        let unknown =
            matches!(err, Some(stride_dynamixel::CodecError::UnknownInstruction(c)) if c == code);
        self.error_status(id, ErrorBits::INSTRUCTION, if unknown { 2 } else { 5 })
    }

    /// Servo `id`'s status with no parameters for a packet it refused: `bit` in its error
    /// (1.0), error number `v2_error` (2.0); none for the broadcast id.
    fn error_status(&mut self, id: u8, bit: u8, v2_error: u8) -> Option<(Duration, Vec<u8>)> {
        if id == BROADCAST {
            return None;
        }
        let delay = self.delay(id);
        let fault = self.levers.get(id);
        let s = self.servo(id)?;
        s.transient |= bit;
        let status = Status {
            id,
            error: s.error_byte(&fault, v2_error),
            params: Vec::new(),
        };
        Some((delay, self.encode(&status)))
    }

    fn advance(&mut self, now: Instant) {
        let dt = self
            .last
            .map_or(0.0, |t| now.saturating_duration_since(t).as_secs_f64());
        // The servos' physics runs at 1 kHz at most, as their firmware's loop does.
        if self.last.is_some() && dt < 0.001 {
            return;
        }
        self.last = Some(now);
        for s in &mut self.servos {
            let f = self.levers.get(s.id);
            s.advance(dt, &f);
        }
        let mut probe = self.probe.0.lock().unwrap_or_else(|p| p.into_inner());
        for s in &self.servos {
            probe.insert(s.id, s.position);
        }
    }

    /// The answers to one instruction packet: (delay before it, bytes), in order.
    fn handle(&mut self, packet: &[u8]) -> Vec<(Duration, Vec<u8>)> {
        let decoded = match self.protocol {
            Protocol::V1 => v1::decode_instruction(packet),
            Protocol::V2 => v2::decode_instruction(packet),
        };
        let Ok((id, ins)) = decoded else {
            return self.bad_instruction(packet).into_iter().collect();
        };
        let concerned: Vec<u8> = match &ins {
            Instruction::SyncWrite { data, .. } => data.iter().map(|d| d.0).collect(),
            Instruction::BulkWrite { writes } => writes.iter().map(|w| w.0).collect(),
            Instruction::SyncRead { ids, .. } | Instruction::FastSyncRead { ids, .. } => {
                ids.clone()
            }
            Instruction::BulkRead { reads } | Instruction::FastBulkRead { reads } => {
                reads.iter().map(|r| r.0).collect()
            }
            _ if id == BROADCAST => self.servos.iter().map(|s| s.id).collect(),
            _ => vec![id],
        };
        let levers = &self.levers;
        for s in self
            .servos
            .iter_mut()
            .filter(|s| concerned.contains(&s.id) && !levers.get(s.id).silent)
        {
            s.silent_for = 0.0;
        }
        let mut out = Vec::new();
        match &ins {
            Instruction::SyncWrite { address, data, .. } => {
                for (sid, d) in data {
                    if let Some(s) = self.servo(*sid) {
                        let _ = s.write(*address, d);
                    }
                }
            }
            Instruction::BulkWrite { writes } => {
                for (sid, address, d) in writes {
                    if let Some(s) = self.servo(*sid) {
                        let _ = s.write(*address, d);
                    }
                }
            }
            Instruction::SyncRead {
                address,
                length,
                ids,
            } => {
                for sid in ids {
                    out.extend(self.answer_read(*sid, *address, *length));
                }
            }
            Instruction::BulkRead { reads } => {
                for (sid, address, length) in reads {
                    // AX servos do not know bulk read.
                    if self
                        .servo(*sid)
                        .is_some_and(|s| s.model.name.starts_with("AX"))
                    {
                        continue;
                    }
                    out.extend(self.answer_read(*sid, *address, *length));
                }
            }
            Instruction::FastSyncRead {
                address,
                length,
                ids,
            } => {
                let reads: Vec<(u8, u16, u16)> =
                    ids.iter().map(|&i| (i, *address, *length)).collect();
                out.extend(self.fast_read(&reads));
            }
            Instruction::FastBulkRead { reads } => out.extend(self.fast_read(reads)),
            // X firmware ignores a broadcast reset of everything (ids would collide).
            Instruction::FactoryReset { option: 0xff }
                if id == BROADCAST && self.protocol == Protocol::V2 => {}
            _ if id == BROADCAST => {
                let ids: Vec<u8> = self.servos.iter().map(|s| s.id).collect();
                for sid in ids {
                    let reply = self.single(sid, &ins);
                    // Only pings are answered through the broadcast id (2.0).
                    if matches!(ins, Instruction::Ping) && self.protocol == Protocol::V2 {
                        out.extend(reply);
                    }
                }
            }
            _ => out.extend(self.single(id, &ins)),
        }
        out
    }

    fn servo(&mut self, id: u8) -> Option<&mut Servo> {
        let silent = self.levers.get(id).silent;
        self.servos.iter_mut().find(|s| s.id == id && !silent)
    }

    fn encode(&self, s: &Status) -> Vec<u8> {
        match self.protocol {
            Protocol::V1 => v1::encode_status(s).expect("status fits"),
            Protocol::V2 => v2::encode_status(s),
        }
    }

    /// The delay before servo `id` answers: its return delay time, and any lateness.
    fn delay(&mut self, id: u8) -> Duration {
        let late = self.levers.get(id).late;
        self.servo(id).map_or(Duration::ZERO, |s| {
            Duration::from_micros(2 * s.get("return_delay_time") as u64) + late
        })
    }

    fn answer_read(&mut self, id: u8, address: u16, length: u16) -> Option<(Duration, Vec<u8>)> {
        let delay = self.delay(id);
        let fault = self.levers.get(id);
        let s = self.servo(id)?;
        let (params, number) = match s.read(address, length) {
            Ok(d) => (d, 0),
            Err(e) => (Vec::new(), e),
        };
        let status = Status {
            id,
            error: s.error_byte(&fault, number),
            params,
        };
        Some((delay, self.encode(&status)))
    }

    fn fast_read(&mut self, reads: &[(u8, u16, u16)]) -> Vec<(Duration, Vec<u8>)> {
        let mut replies = Vec::new();
        let mut delay = Duration::ZERO;
        for (sid, address, length) in reads {
            let d = self.delay(*sid);
            let fault = self.levers.get(*sid);
            let Some(s) = self.servo(*sid) else {
                // A missing servo breaks the chain of answers: the rest stay silent.
                break;
            };
            delay += d;
            let (params, number) = match s.read(*address, *length) {
                Ok(d) => (d, 0),
                Err(e) => (vec![0; *length as usize], e),
            };
            replies.push(Status {
                id: *sid,
                error: s.error_byte(&fault, number),
                params,
            });
        }
        if replies.len() == reads.len() {
            vec![(delay, v2::encode_fast_status(&replies))]
        } else {
            Vec::new()
        }
    }

    /// One servo's answer to an instruction addressed to it.
    fn single(&mut self, id: u8, ins: &Instruction) -> Option<(Duration, Vec<u8>)> {
        let delay = self.delay(id);
        let fault = self.levers.get(id);
        let protocol = self.protocol;
        let s = self.servo(id)?;
        let level = s.get("status_return_level");
        let (params, number, answer) = match ins {
            Instruction::Ping => {
                let p = if protocol == Protocol::V2 {
                    let mut p = s.model.number.to_le_bytes().to_vec();
                    p.push(s.get("firmware_version") as u8);
                    p
                } else {
                    Vec::new()
                };
                (p, 0, true)
            }
            Instruction::Read { address, length } => match s.read(*address, *length) {
                Ok(d) => (d, 0, level >= 1),
                Err(e) => (Vec::new(), e, level >= 1),
            },
            Instruction::Write { address, data } => {
                let r = s.write(*address, data);
                (Vec::new(), r.err().unwrap_or(0), level >= 2)
            }
            Instruction::RegWrite { address, data } => {
                s.registered = Some((*address, data.clone()));
                s.set("registered", 1);
                (Vec::new(), 0, level >= 2)
            }
            Instruction::Action => {
                let r = match s.registered.take() {
                    Some((a, d)) => s.write(a, &d),
                    None => {
                        s.transient |= ErrorBits::INSTRUCTION;
                        Err(2)
                    }
                };
                s.set("registered", 0);
                (Vec::new(), r.err().unwrap_or(0), level >= 2)
            }
            Instruction::Reboot => {
                s.reboot();
                (Vec::new(), 0, level >= 2)
            }
            Instruction::FactoryReset { option } => {
                s.factory_reset(*option);
                (Vec::new(), 0, level >= 2)
            }
            Instruction::Clear { .. } => (Vec::new(), 0, level >= 2),
            _ => {
                s.transient |= ErrorBits::INSTRUCTION;
                (Vec::new(), 2, level >= 2)
            }
        };
        if !answer {
            return None;
        }
        let status = Status {
            id,
            error: s.error_byte(&fault, number),
            params,
        };
        Some((delay, self.encode(&status)))
    }
}
