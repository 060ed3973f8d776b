//! Drives Elmo motion controllers over CANopen, generic over the CAN bus ([`CanBus`]):
//! bring-up (boot-up, identity, heartbeat, PDO mapping verified by read-back, NMT start, table
//! set-up with the interpreter's `MP[1..6]`, CiA 402 enable), joint trajectories streamed as
//! PVT rows, PT points or CiA 402 interpolated-position set-points while each drive's table is
//! tracked, limits checked before anything is sent, joint states from the SYNC-driven TPDO,
//! emergencies turned into events, quick stop, recovery and disable.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use stride_canbus::{BusError, CanBus, CanFrame};
use stride_canopen::ds402::{self, State as DriveState};
use stride_canopen::elmo::{
    pt_bytes, Command as Interp, PvtQueue, PvtRow, Reply, Value, PT_OBJECT, PVT_ROWS,
};
use stride_canopen::emcy::{ElmoEmcy, Emcy};
use stride_canopen::frame::{CobId, Function, NodeId};
use stride_canopen::nmt;
use stride_canopen::pdo::{Direction, MapEntry, PdoConfig};
use stride_canopen::sdo::{self, Download, ServerResponse, Step, Upload};

/// One joint: its drive and the conversion from radians to encoder counts.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointConfig {
    /// Joint name (as in trajectories and joint states).
    pub name: String,
    /// CANopen node id of its drive.
    pub node: u8,
    /// Encoder counts per motor revolution.
    pub counts_per_rev: f64,
    /// Gear ratio (motor revolutions per joint revolution).
    pub gear_ratio: f64,
    /// Joint position limits, rad.
    pub min_position: f64,
    /// Upper position limit, rad.
    pub max_position: f64,
    /// Velocity limit, rad/s.
    pub max_velocity: f64,
    /// Acceleration limit, rad/s².
    pub max_acceleration: f64,
    /// Largest tracking error tolerated, rad: the drive's following-error window (0x6065) is
    /// set to it at bring-up, so a joint that falls further behind its set-point faults
    /// instead of running on.
    #[serde(default = "JointConfig::default_tolerance")]
    pub tolerance: f64,
}

impl JointConfig {
    fn default_tolerance() -> f64 {
        0.01
    }

    /// The tolerance in encoder counts (the following-error window), at least one count.
    pub fn tolerance_counts(&self) -> u32 {
        (self.tolerance * self.counts_per_rad().abs())
            .round()
            .clamp(1.0, u32::MAX as f64) as u32
    }

    /// Encoder counts per joint radian.
    pub fn counts_per_rad(&self) -> f64 {
        self.counts_per_rev * self.gear_ratio / std::f64::consts::TAU
    }
}

/// Why the master stopped or refused something.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MasterError {
    /// The bus failed.
    #[error("CAN bus: {0}")]
    Bus(#[from] BusError),
    /// A drive did not answer in time.
    #[error("{joint} (node {node}): no answer to {what}")]
    NoAnswer {
        /// Joint.
        joint: String,
        /// Node id.
        node: u8,
        /// What was asked.
        what: String,
    },
    /// A drive aborted an SDO transfer or answered out of protocol.
    #[error("{joint} (node {node}): {error}")]
    Sdo {
        /// Joint.
        joint: String,
        /// Node id.
        node: u8,
        /// The SDO error.
        error: sdo::SdoError,
    },
    /// A drive is not what the configuration says.
    #[error("{joint} (node {node}): {what}")]
    Identity {
        /// Joint.
        joint: String,
        /// Node id.
        node: u8,
        /// What differs.
        what: String,
    },
    /// A PDO mapping did not read back as written.
    #[error(
        "{joint} (node {node}): PDO mapping {index:#06x}:{sub} reads back {got:?}, wrote {want:?}"
    )]
    Mapping {
        /// Joint.
        joint: String,
        /// Node id.
        node: u8,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Expected.
        want: Vec<u8>,
        /// Read.
        got: Vec<u8>,
    },
    /// A drive did not reach operation enabled.
    #[error("{joint} (node {node}): stuck in {state:?} while enabling")]
    Enable {
        /// Joint.
        joint: String,
        /// Node id.
        node: u8,
        /// The state it stayed in.
        state: DriveState,
    },
    /// A trajectory point is beyond a joint limit: the whole trajectory is refused.
    #[error("row {row}, joint {joint}: {what}")]
    Limit {
        /// Row index.
        row: usize,
        /// Joint.
        joint: String,
        /// Which limit and by how much.
        what: String,
    },
    /// The trajectory's shape is wrong (joint names, sizes, times).
    #[error("bad trajectory: {0}")]
    BadTrajectory(String),
    /// A drive's binary interpreter refused a command.
    #[error("{joint} (node {node}): the drive refused {command} (interpreter error {code})")]
    Interpreter {
        /// Joint.
        joint: String,
        /// Node id.
        node: u8,
        /// The command, e.g. `MP[4]=50`.
        command: String,
        /// The drive's error code.
        code: u32,
    },
    /// The drive cannot be set up as configured.
    #[error("{joint} (node {node}): {what}")]
    Setup {
        /// Joint.
        joint: String,
        /// Node id.
        node: u8,
        /// What does not fit.
        what: String,
    },
}

/// A trajectory in joint space: rows of positions (and velocities) at times.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// Joint names, one per column.
    pub joints: Vec<String>,
    /// Seconds from the start to each row (strictly increasing).
    pub times: Vec<f64>,
    /// Positions, rad: `positions[row][joint]`.
    pub positions: Vec<Vec<f64>>,
    /// Velocities, rad/s (PVT), same shape; empty for PT (velocities then derived).
    pub velocities: Vec<Vec<f64>>,
}

/// What the master reports while running.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A drive sent an emergency.
    Emergency {
        /// Joint.
        joint: String,
        /// Description.
        text: String,
        /// The raw message.
        emcy: Emcy,
    },
    /// A drive's heartbeat stopped.
    HeartbeatLost {
        /// Joint.
        joint: String,
    },
    /// A drive that was up sent a boot-up message: it reset (power loss, watchdog) and has to
    /// be brought up again ([`Master::recover`]).
    Rebooted {
        /// Joint.
        joint: String,
    },
    /// A drive's interpreter answered a command sent while running (`PV`, `PT`, `BG`) with an
    /// error.
    InterpreterError {
        /// Joint.
        joint: String,
        /// The command, e.g. `BG`.
        command: String,
        /// The drive's error code.
        code: u32,
    },
}

/// The measured state of one joint.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointState {
    /// Position, rad.
    pub position: f64,
    /// CiA 402 statusword.
    pub statusword: u16,
    /// When the last TPDO arrived.
    pub updated: Option<Instant>,
}

struct Axis {
    cfg: JointConfig,
    node: NodeId,
    queue: PvtQueue,
    state: JointState,
    last_heartbeat: Option<Instant>,
    heartbeat_lost: bool,
    rows_pending: std::collections::VecDeque<PvtRow>,
    started: bool,
    /// The last row loaded: a stream that stops in motion must be stopped.
    last_row: Option<PvtRow>,
    /// Brought up and enabled (a boot-up message then means the drive reset).
    up: bool,
}

/// How trajectories reach the drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Motion {
    /// Elmo PVT: rows of position, velocity and time through object 0x2001, cubic
    /// interpolation, started with the interpreter's `BG`.
    Pvt,
    /// CiA 402 interpolated position mode (7), linear, with a fixed period: set-points through
    /// 0x60C1:1, started with controlword bit 4. Portable to other vendors' drives.
    InterpolatedPosition {
        /// The fixed time between set-points, ms (0x60C2).
        period_ms: u8,
    },
    /// Elmo PT: positions only, at a fixed period, two per frame through object 0x2002, played
    /// by the drive with cubic interpolation; started with `PT=n` and `BG`. Trajectories are
    /// resampled at the period (a chunk of a stream should span a whole number of periods).
    Pt {
        /// Time between points, ms: a whole number of the drive's position-loop samples
        /// (4 × `TS` µs), checked at bring-up; sets `MP[4]`.
        period_ms: u8,
    },
}

/// Points of the PT ring the master sets up (`MP[1]=1`, `MP[2]=PT_POINTS`).
pub const PT_POINTS: u16 = 256;

impl Motion {
    /// Rows (points) of the drive's table this mode uses.
    fn table_rows(self) -> u16 {
        match self {
            Motion::Pt { .. } => PT_POINTS,
            _ => PVT_ROWS,
        }
    }

    /// Table rows carried by one set-point frame.
    fn rows_per_frame(self) -> usize {
        match self {
            Motion::Pt { .. } => 2,
            _ => 1,
        }
    }
}

/// `MP[4]=50`, `TS`: an interpreter command as the manuals write it.
fn command_text(cmd: &Interp) -> String {
    let name = String::from_utf8_lossy(&cmd.name);
    let index = if cmd.index > 0 {
        format!("[{}]", cmd.index)
    } else {
        String::new()
    };
    match cmd.value {
        Some(Value::Int(v)) => format!("{name}{index}={v}"),
        Some(Value::Float(v)) => format!("{name}{index}={v}"),
        None => format!("{name}{index}"),
    }
}

/// Settings of the master.
#[derive(Debug, Clone)]
pub struct MasterConfig {
    /// Time allowed for each SDO exchange.
    pub sdo_timeout: Duration,
    /// Heartbeat period the drives are told to use; lost after three periods.
    pub heartbeat: Duration,
    /// PVT or interpolated position.
    pub motion: Motion,
}

impl Default for MasterConfig {
    fn default() -> Self {
        MasterConfig {
            sdo_timeout: Duration::from_millis(200),
            heartbeat: Duration::from_millis(100),
            motion: Motion::Pvt,
        }
    }
}

/// The CANopen master of a set of Elmo drives.
pub struct Master<B: CanBus> {
    bus: B,
    cfg: MasterConfig,
    axes: Vec<Axis>,
    by_node: HashMap<u8, usize>,
    events: Vec<Event>,
}

/// The set-point RPDO: RPDO3 carrying object 0x2001 (a PVT row per frame), 0x2002 (two PT
/// points per frame), or 0x60C1:1 (an interpolated position set-point per frame).
fn setpoint_rpdo(motion: Motion) -> PdoConfig {
    let entry = match motion {
        Motion::Pvt => MapEntry {
            index: stride_canopen::elmo::PVT_OBJECT,
            sub: 0,
            bits: 64,
        },
        Motion::InterpolatedPosition { .. } => MapEntry {
            index: ds402::IP_DATA,
            sub: 1,
            bits: 32,
        },
        Motion::Pt { .. } => MapEntry {
            index: PT_OBJECT,
            sub: 0,
            bits: 64,
        },
    };
    PdoConfig {
        direction: Direction::Receive,
        number: 3,
        transmission: 255,
        entries: vec![entry],
    }
}

/// The state TPDO: TPDO1 with statusword, actual position and the PVT table's read pointer
/// (0x2F12, readable only through a PDO), on every SYNC.
fn state_tpdo() -> PdoConfig {
    PdoConfig {
        direction: Direction::Transmit,
        number: 1,
        transmission: 1,
        entries: vec![
            MapEntry {
                index: ds402::STATUSWORD,
                sub: 0,
                bits: 16,
            },
            MapEntry {
                index: ds402::POSITION_ACTUAL,
                sub: 0,
                bits: 32,
            },
            MapEntry {
                index: 0x2f12,
                sub: 0,
                bits: 16,
            },
        ],
    }
}

impl<B: CanBus> Master<B> {
    /// A master for `joints` on `bus`.
    pub fn new(
        bus: B,
        joints: Vec<JointConfig>,
        cfg: MasterConfig,
    ) -> Result<Master<B>, MasterError> {
        let mut axes = Vec::new();
        let mut by_node = HashMap::new();
        for j in joints {
            let node = NodeId::new(j.node).map_err(|_| MasterError::Identity {
                joint: j.name.clone(),
                node: j.node,
                what: "node id outside 1..=127".into(),
            })?;
            if by_node.insert(j.node, axes.len()).is_some() {
                return Err(MasterError::Identity {
                    joint: j.name.clone(),
                    node: j.node,
                    what: "node id used twice".into(),
                });
            }
            axes.push(Axis {
                cfg: j,
                node,
                queue: PvtQueue::new(cfg.motion.table_rows()),
                state: JointState::default(),
                last_heartbeat: None,
                heartbeat_lost: false,
                rows_pending: std::collections::VecDeque::new(),
                started: false,
                last_row: None,
                up: false,
            });
        }
        Ok(Master {
            bus,
            cfg,
            axes,
            by_node,
            events: Vec::new(),
        })
    }

    /// The joints' measured states, in configuration order.
    pub fn states(&self) -> Vec<(&str, JointState)> {
        self.axes
            .iter()
            .map(|a| (a.cfg.name.as_str(), a.state))
            .collect()
    }

    /// Events since the last call.
    pub fn take_events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }

    fn send(&mut self, f: &CanFrame) -> Result<(), MasterError> {
        Ok(self.bus.send(f, Instant::now() + self.cfg.sdo_timeout)?)
    }

    /// Sends `frame` to axis `a` and waits for the frame `answer` accepts; other frames seen
    /// meanwhile are processed. `what` names the request in a timeout error.
    fn exchange<T>(
        &mut self,
        a: usize,
        frame: &CanFrame,
        what: impl FnOnce() -> String,
        mut answer: impl FnMut(&CanFrame) -> Option<T>,
    ) -> Result<T, MasterError> {
        self.send(frame)?;
        let deadline = Instant::now() + self.cfg.sdo_timeout;
        loop {
            let f = match self.bus.recv(deadline) {
                Ok(f) => f,
                Err(BusError::Timeout) => {
                    return Err(MasterError::NoAnswer {
                        joint: self.axes[a].cfg.name.clone(),
                        node: self.axes[a].node.get(),
                        what: what(),
                    })
                }
                Err(e) => return Err(e.into()),
            };
            match answer(&f) {
                Some(t) => return Ok(t),
                None => self.on_frame(&f, Instant::now()),
            }
        }
    }

    /// One SDO exchange with axis `a`.
    fn sdo(&mut self, a: usize, req: sdo::ClientRequest) -> Result<ServerResponse, MasterError> {
        let node = self.axes[a].node;
        let want = CobId::of(Function::SdoTx, node).raw() as u32;
        let frame = req.encode(node).expect("valid request");
        self.exchange(
            a,
            &frame,
            || format!("{req:?}"),
            |f| {
                (f.raw_id() == want)
                    .then(|| ServerResponse::decode(f).ok().map(|(_, r)| r))
                    .flatten()
            },
        )
    }

    /// One binary-interpreter exchange with axis `a` over PDO2 (RPDO2 out, TPDO2 back).
    pub fn interpret(&mut self, a: usize, cmd: Interp) -> Result<Value, MasterError> {
        let node = self.axes[a].node;
        let want = CobId::of(Function::Tpdo(2), node).raw() as u32;
        let frame = cmd.encode(node).expect("valid command");
        let result = self.exchange(
            a,
            &frame,
            || command_text(&cmd),
            |f| match Reply::decode(f.data()) {
                Ok(r) if f.raw_id() == want && r.name == cmd.name && r.index == cmd.index => {
                    Some(r.result)
                }
                _ => None,
            },
        )?;
        result.map_err(|code| MasterError::Interpreter {
            joint: self.axes[a].cfg.name.clone(),
            node: node.get(),
            command: command_text(&cmd),
            code,
        })
    }

    /// Sets up the drive's table for tabulated motion (PVT, PT): rows `1..=N` as a ring
    /// (`MP[1..3]`), the PT period in position-loop samples (`MP[4]`, from the drive's `TS`),
    /// and the write pointer at row 1 (`MP[6]`), so the master's count of rows matches the
    /// drive's.
    fn setup_table(&mut self, a: usize) -> Result<(), MasterError> {
        let rows = self.cfg.motion.table_rows();
        let mut mp = vec![(1, 1), (2, rows as i32), (3, 1)];
        match self.cfg.motion {
            Motion::InterpolatedPosition { .. } => return Ok(()),
            Motion::Pvt => {}
            Motion::Pt { period_ms } => {
                let ts = match self.interpret(a, Interp::get(b"TS", 0))? {
                    Value::Int(t) => t as i64,
                    Value::Float(t) => t as i64,
                };
                let (sample_us, period_us) = (4 * ts, period_ms as i64 * 1000);
                if ts <= 0 || period_us % sample_us != 0 || period_us / sample_us > 65535 {
                    return Err(MasterError::Setup {
                        joint: self.axes[a].cfg.name.clone(),
                        node: self.axes[a].node.get(),
                        what: format!(
                            "a PT period of {period_ms} ms is not a whole number of the drive's \
                             position-loop samples ({sample_us} µs, TS = {ts})"
                        ),
                    });
                }
                mp.push((4, (period_us / sample_us) as i32));
            }
        }
        mp.push((6, 1));
        for (i, v) in mp {
            self.interpret(a, Interp::set(b"MP", i, Value::Int(v)))?;
        }
        self.axes[a].queue = PvtQueue::new(rows);
        Ok(())
    }

    fn sdo_error(&self, a: usize, error: sdo::SdoError) -> MasterError {
        MasterError::Sdo {
            joint: self.axes[a].cfg.name.clone(),
            node: self.axes[a].node.get(),
            error,
        }
    }

    /// Writes an object of axis `a`.
    pub fn write(
        &mut self,
        a: usize,
        index: u16,
        sub: u8,
        data: Vec<u8>,
    ) -> Result<(), MasterError> {
        let mut dl = Download::new(index, sub, data);
        let mut req = dl.start();
        loop {
            let resp = self.sdo(a, req)?;
            match dl.on_response(&resp).map_err(|e| self.sdo_error(a, e))? {
                Step::Send(r) => req = r,
                Step::Done(_) => return Ok(()),
            }
        }
    }

    /// Reads an object of axis `a`.
    pub fn read(&mut self, a: usize, index: u16, sub: u8) -> Result<Vec<u8>, MasterError> {
        let mut up = Upload::new(index, sub, 1024);
        let mut req = up.start();
        loop {
            let resp = self.sdo(a, req)?;
            match up.on_response(&resp).map_err(|e| self.sdo_error(a, e))? {
                Step::Send(r) => req = r,
                Step::Done(d) => return Ok(d),
            }
        }
    }

    fn statusword(&mut self, a: usize) -> Result<u16, MasterError> {
        let d = self.read(a, ds402::STATUSWORD, 0)?;
        Ok(u16::from_le_bytes([d[0], *d.get(1).unwrap_or(&0)]))
    }

    /// Brings every drive up: identity (CiA 402 device), heartbeat, PDO mapping written and
    /// verified, NMT operational, CiA 402 operation enabled with the motor on.
    pub fn bring_up(&mut self) -> Result<(), MasterError> {
        for a in 0..self.axes.len() {
            let (name, node) = (self.axes[a].cfg.name.clone(), self.axes[a].node);
            let ident = |what: String| MasterError::Identity {
                joint: name.clone(),
                node: node.get(),
                what,
            };
            let dt = self.read(a, 0x1000, 0)?;
            let device = u32::from_le_bytes(
                dt.get(..4)
                    .and_then(|b| b.try_into().ok())
                    .ok_or_else(|| ident("short device type".into()))?,
            );
            if device & 0xffff != 402 {
                return Err(ident(format!(
                    "device type {device:#010x} is not a CiA 402 drive"
                )));
            }
            let hb = self.cfg.heartbeat.as_millis() as u16;
            self.write(a, 0x1017, 0, hb.to_le_bytes().to_vec())?;
            let window = self.axes[a].cfg.tolerance_counts();
            self.write(
                a,
                ds402::FOLLOWING_ERROR_WINDOW,
                0,
                window.to_le_bytes().to_vec(),
            )?;
            if let Motion::InterpolatedPosition { period_ms } = self.cfg.motion {
                self.write(
                    a,
                    ds402::MODES_OF_OPERATION,
                    0,
                    vec![ds402::Mode::InterpolatedPosition.code() as u8],
                )?;
                self.write(a, ds402::IP_SUBMODE, 0, 0i16.to_le_bytes().to_vec())?;
                self.write(a, ds402::IP_PERIOD, 1, vec![period_ms])?;
                self.write(a, ds402::IP_PERIOD, 2, vec![(-3i8) as u8])?;
            }
            for pdo in [setpoint_rpdo(self.cfg.motion), state_tpdo()] {
                for (i, s, v) in pdo.sdo_writes(node) {
                    self.write(a, i, s, v)?;
                }
                for (i, s, want) in pdo.verification() {
                    let got = self.read(a, i, s)?;
                    if got != want {
                        return Err(MasterError::Mapping {
                            joint: name.clone(),
                            node: node.get(),
                            index: i,
                            sub: s,
                            want,
                            got,
                        });
                    }
                }
            }
            self.send(&nmt::encode(nmt::Command::Start, node.get()))?;
            self.setup_table(a)?;
            self.enable(a)?;
            self.axes[a].up = true;
        }
        Ok(())
    }

    /// Forgets every row not yet played and what the drives were doing, then brings every
    /// drive up again (after a bus-off, a drive reset or a fault): a motion cut off is not
    /// resumed.
    pub fn recover(&mut self) -> Result<(), MasterError> {
        for ax in &mut self.axes {
            ax.rows_pending.clear();
            ax.queue = PvtQueue::new(self.cfg.motion.table_rows());
            ax.started = false;
            ax.last_row = None;
            ax.heartbeat_lost = false;
            ax.last_heartbeat = None;
            ax.up = false;
        }
        self.bring_up()
    }

    fn enable(&mut self, a: usize) -> Result<(), MasterError> {
        for _ in 0..6 {
            let state = DriveState::from_statusword(self.statusword(a)?);
            match ds402::step_towards(state, DriveState::OperationEnabled) {
                None if state == DriveState::OperationEnabled => return Ok(()),
                None => break,
                Some(cmd) => self.write(
                    a,
                    ds402::CONTROLWORD,
                    0,
                    cmd.controlword().to_le_bytes().to_vec(),
                )?,
            }
        }
        let state = DriveState::from_statusword(self.statusword(a)?);
        if state == DriveState::OperationEnabled {
            Ok(())
        } else {
            Err(MasterError::Enable {
                joint: self.axes[a].cfg.name.clone(),
                node: self.axes[a].node.get(),
                state,
            })
        }
    }

    /// Checks a trajectory against every joint's limits; nothing is clipped.
    pub fn validate(&self, t: &Trajectory) -> Result<Vec<usize>, MasterError> {
        let cols: Vec<usize> = t
            .joints
            .iter()
            .map(|j| {
                self.axes
                    .iter()
                    .position(|a| &a.cfg.name == j)
                    .ok_or_else(|| MasterError::BadTrajectory(format!("unknown joint {j}")))
            })
            .collect::<Result<_, _>>()?;
        if t.times.len() != t.positions.len() || t.times.len() < 2 {
            return Err(MasterError::BadTrajectory(
                "need at least two rows, one time per row".into(),
            ));
        }
        if !t.velocities.is_empty() && t.velocities.len() != t.positions.len() {
            return Err(MasterError::BadTrajectory(
                "velocities and positions differ in rows".into(),
            ));
        }
        for (r, row) in t.positions.iter().enumerate() {
            if row.len() != cols.len() || t.velocities.get(r).is_some_and(|v| v.len() != cols.len())
            {
                return Err(MasterError::BadTrajectory(format!(
                    "row {r} has the wrong number of joints"
                )));
            }
            if r > 0 {
                let dt = t.times[r] - t.times[r - 1];
                if !(0.001..=0.255).contains(&dt) {
                    return Err(MasterError::BadTrajectory(format!(
                        "row {r}: {dt} s between rows; PVT rows are 1 to 255 ms apart"
                    )));
                }
                if let Motion::InterpolatedPosition { period_ms } = self.cfg.motion {
                    if (dt * 1000.0 - period_ms as f64).abs() > 0.5 {
                        return Err(MasterError::BadTrajectory(format!(
                            "row {r}: {:.1} ms between rows; interpolated position mode runs at a fixed {period_ms} ms",
                            dt * 1000.0
                        )));
                    }
                }
            }
            for (c, &a) in cols.iter().enumerate() {
                let j = &self.axes[a].cfg;
                let limit = |what: String| MasterError::Limit {
                    row: r,
                    joint: j.name.clone(),
                    what,
                };
                let p = row[c];
                if !(j.min_position..=j.max_position).contains(&p) || !p.is_finite() {
                    return Err(limit(format!(
                        "position {p:.4} rad outside [{}, {}]",
                        j.min_position, j.max_position
                    )));
                }
                let v = self.velocity(t, r, c);
                if v.abs() > j.max_velocity || !v.is_finite() {
                    return Err(limit(format!(
                        "velocity {v:.4} rad/s beyond {}",
                        j.max_velocity
                    )));
                }
                if r > 0 {
                    let acc = (v - self.velocity(t, r - 1, c)) / (t.times[r] - t.times[r - 1]);
                    if acc.abs() > j.max_acceleration {
                        return Err(limit(format!(
                            "acceleration {acc:.3} rad/s² beyond {}",
                            j.max_acceleration
                        )));
                    }
                }
            }
        }
        Ok(cols)
    }

    /// Positions of column `c` (rad) every `period` s from the first row: cubic Hermite
    /// between rows (with their velocities); the last sample is the last row, so a move ends
    /// exactly where it should.
    fn pt_points(&self, t: &Trajectory, c: usize, period: f64) -> Vec<f64> {
        let (t0, t_end) = (t.times[0], t.times[t.times.len() - 1]);
        let n = ((t_end - t0) / period - 1e-9).ceil().max(1.0) as usize;
        let mut r = 0;
        (0..=n)
            .map(|i| {
                let time = (t0 + i as f64 * period).min(t_end);
                while r + 2 < t.times.len() && t.times[r + 1] <= time {
                    r += 1;
                }
                let h = t.times[r + 1] - t.times[r];
                let s = ((time - t.times[r]) / h).clamp(0.0, 1.0);
                let (p0, p1) = (t.positions[r][c], t.positions[r + 1][c]);
                let (m0, m1) = (self.velocity(t, r, c) * h, self.velocity(t, r + 1, c) * h);
                let (s2, s3) = (s * s, s * s * s);
                (2.0 * s3 - 3.0 * s2 + 1.0) * p0
                    + (s3 - 2.0 * s2 + s) * m0
                    + (-2.0 * s3 + 3.0 * s2) * p1
                    + (s3 - s2) * m1
            })
            .collect()
    }

    fn velocity(&self, t: &Trajectory, r: usize, c: usize) -> f64 {
        if let Some(v) = t.velocities.get(r) {
            return v[c];
        }
        // PT: central differences, zero at both ends.
        if r == 0 || r + 1 == t.positions.len() {
            return 0.0;
        }
        (t.positions[r + 1][c] - t.positions[r - 1][c]) / (t.times[r + 1] - t.times[r - 1])
    }

    /// Validates a trajectory and queues it for each joint (PVT rows, PT points resampled at
    /// the period, or set-points); rows go out as the drives' tables have room (see
    /// [`Master::pump`]).
    pub fn load(&mut self, t: &Trajectory) -> Result<(), MasterError> {
        let cols = self.validate(t)?;
        if let Motion::Pt { period_ms } = self.cfg.motion {
            for (c, &a) in cols.iter().enumerate() {
                let k = self.axes[a].cfg.counts_per_rad();
                let last = t.times.len() - 1;
                let v_end = self.velocity(t, last, c) * k;
                let mut points = self.pt_points(t, c, period_ms as f64 / 1000.0);
                for p in &mut points {
                    *p *= k;
                }
                let row = |p: f64| PvtRow {
                    position: p.round() as i32,
                    velocity: 0,
                    time_ms: period_ms,
                };
                let mut rows: Vec<PvtRow> = points.into_iter().map(row).collect();
                // At rest, the last point is held (and repeated to fill the last frame); in
                // motion, an odd point waits for the next chunk to share its frame.
                let end = rows[rows.len() - 1];
                if v_end.round() == 0.0 && (self.axes[a].rows_pending.len() + rows.len()) % 2 == 1 {
                    rows.push(end);
                }
                self.axes[a].last_row = Some(PvtRow {
                    velocity: v_end.round() as i32,
                    ..end
                });
                self.axes[a].rows_pending.extend(rows);
            }
            return Ok(());
        }
        for (c, &a) in cols.iter().enumerate() {
            let k = self.axes[a].cfg.counts_per_rad();
            let mut rows = Vec::with_capacity(t.times.len());
            for r in 0..t.times.len() {
                let dt = if r + 1 < t.times.len() {
                    t.times[r + 1] - t.times[r]
                } else {
                    0.010
                };
                rows.push(PvtRow {
                    position: (t.positions[r][c] * k).round() as i32,
                    velocity: (self.velocity(t, r, c) * k).round() as i32,
                    time_ms: (dt * 1000.0).round().clamp(1.0, 255.0) as u8,
                });
            }
            // A trajectory that ends at rest gets a final row holding its last position, so the
            // drive plays the last segment to the end; one that ends in motion is a chunk of a
            // stream, to be continued by the next trajectory.
            if let Some(last) = rows.last().copied() {
                if last.velocity == 0 {
                    rows.push(last);
                }
                self.axes[a].last_row = Some(last);
            }
            self.axes[a].rows_pending.extend(rows);
        }
        Ok(())
    }

    /// Sends queued rows while the drives have room, starts motion once rows are loaded,
    /// sends a SYNC, and processes what arrived. Call it every cycle.
    pub fn pump(&mut self, now: Instant) -> Result<(), MasterError> {
        // Rows go out round-robin, one per axis per pass, so that no axis starves while the
        // controller's queue is the bottleneck.
        let per_frame = self.cfg.motion.rows_per_frame();
        'fill: loop {
            let mut sent_any = false;
            for a in 0..self.axes.len() {
                if self.axes[a].rows_pending.len() < per_frame
                    || self.axes[a].queue.room() < per_frame as u64
                {
                    continue;
                }
                let cob = setpoint_rpdo(self.cfg.motion).cob_id(self.axes[a].node);
                let row = self.axes[a].rows_pending[0];
                let f = match self.cfg.motion {
                    Motion::Pvt => CanFrame::standard(cob, &row.bytes().expect("validated row")),
                    Motion::InterpolatedPosition { .. } => {
                        CanFrame::standard(cob, &row.position.to_le_bytes())
                    }
                    Motion::Pt { .. } => CanFrame::standard(
                        cob,
                        &pt_bytes(row.position, self.axes[a].rows_pending[1].position),
                    ),
                }
                .expect("valid frame");
                match self.bus.send(&f, now + self.cfg.sdo_timeout) {
                    Ok(()) => {
                        for _ in 0..per_frame {
                            self.axes[a].rows_pending.pop_front();
                            self.axes[a].queue.push();
                        }
                        sent_any = true;
                    }
                    // The controller's queue is full: the rest waits for the next cycle.
                    Err(BusError::TxQueueFull) => break 'fill,
                    Err(e) => return Err(e.into()),
                }
            }
            if !sent_any {
                break;
            }
        }
        // Every axis starts together, once all have their rows loaded (or their tables full);
        // an axis that joins a motion under way starts as soon as it is loaded.
        let moving = self.axes.iter().any(|a| a.started);
        let loaded = |a: &Axis| {
            a.queue.pending() >= 2
                && (a.rows_pending.len() < per_frame || a.queue.room() < per_frame as u64)
        };
        let waiting: Vec<usize> = (0..self.axes.len())
            .filter(|&a| !self.axes[a].started && self.axes[a].queue.pending() > 0)
            .collect();
        if !waiting.is_empty() && (moving || waiting.iter().all(|&a| loaded(&self.axes[a]))) {
            for a in waiting {
                if !loaded(&self.axes[a]) {
                    continue;
                }
                let node = self.axes[a].node;
                let tabulated = |name: &[u8; 2]| {
                    // The read pointer at the motion's first row, then begin.
                    let first = self.axes[a].queue.read_index() as i32;
                    [
                        Interp::set(name, 0, Value::Int(first)),
                        Interp::set(b"BG", 0, Value::Int(0)),
                    ]
                    .map(|c| c.encode(node).expect("valid command"))
                    .to_vec()
                };
                let start = match self.cfg.motion {
                    Motion::Pvt => tabulated(b"PV"),
                    Motion::Pt { .. } => tabulated(b"PT"),
                    // RPDO1 carries the controlword: enable operation + enable interpolation.
                    Motion::InterpolatedPosition { .. } => vec![CanFrame::standard(
                        CobId::of(Function::Rpdo(1), node).raw(),
                        &ds402::ModeControl::InterpolatedPosition { enable: true }
                            .controlword(ds402::Command::EnableOperation, false)
                            .to_le_bytes(),
                    )
                    .expect("valid frame")],
                };
                // Should the controller's queue fill between the two, both go again next cycle.
                match start
                    .iter()
                    .try_for_each(|f| self.bus.send(f, now + self.cfg.sdo_timeout))
                {
                    Ok(()) => self.axes[a].started = true,
                    Err(BusError::TxQueueFull) => break,
                    Err(e) => return Err(e.into()),
                }
            }
        }
        match self.bus.send(
            &stride_canopen::sync::encode(None),
            now + self.cfg.sdo_timeout,
        ) {
            Ok(()) | Err(BusError::TxQueueFull) => {}
            Err(e) => return Err(e.into()),
        }
        while let Ok(Some(f)) = self.bus.try_recv() {
            self.on_frame(&f, now);
        }
        let lost_after = self.cfg.heartbeat * 3;
        for a in 0..self.axes.len() {
            let ax = &mut self.axes[a];
            if let Some(t) = ax.last_heartbeat {
                if !ax.heartbeat_lost && now.saturating_duration_since(t) > lost_after {
                    ax.heartbeat_lost = true;
                    self.events.push(Event::HeartbeatLost {
                        joint: ax.cfg.name.clone(),
                    });
                }
            }
        }
        Ok(())
    }

    /// True when what is loaded ends at rest on every joint (so running out of rows is the
    /// normal end of a move, not a stream that stopped).
    pub fn ends_at_rest(&self) -> bool {
        self.axes
            .iter()
            .all(|a| a.last_row.is_none_or(|r| r.velocity == 0))
    }

    /// True when every joint has executed all its rows.
    pub fn idle(&self) -> bool {
        self.axes
            .iter()
            .all(|a| a.rows_pending.is_empty() && (!a.started || a.queue.pending() == 0))
    }

    fn on_frame(&mut self, f: &CanFrame, now: Instant) {
        let Some(cob) = CobId::parse(f.raw_id() as u16) else {
            return;
        };
        let Some(&a) = cob.node.and_then(|n| self.by_node.get(&n.get())) else {
            return;
        };
        match cob.function {
            Function::Tpdo(1) => {
                if let Some(v) = state_tpdo().unpack(f.data()) {
                    let ax = &mut self.axes[a];
                    ax.state.statusword = v[0] as u16;
                    ax.state.position = v[1] as u32 as i32 as f64 / ax.cfg.counts_per_rad();
                    ax.state.updated = Some(now);
                    if ax.started {
                        ax.queue.on_read_pointer(v[2] as u16);
                    }
                }
            }
            Function::Tpdo(2) => {
                if let Ok(Reply {
                    name,
                    index,
                    result: Err(code),
                }) = Reply::decode(f.data())
                {
                    let command = command_text(&Interp::get(&name, index));
                    self.events.push(Event::InterpreterError {
                        joint: self.axes[a].cfg.name.clone(),
                        command,
                        code,
                    });
                }
            }
            Function::Heartbeat => {
                let ax = &mut self.axes[a];
                ax.last_heartbeat = Some(now);
                ax.heartbeat_lost = false;
                if ax.up && f.data().first() == Some(&0) {
                    ax.up = false;
                    self.events.push(Event::Rebooted {
                        joint: ax.cfg.name.clone(),
                    });
                }
            }
            Function::Emcy => {
                if let Ok(e) = Emcy::decode(f) {
                    if let Some(ElmoEmcy::QueueLow { read, .. }) = ElmoEmcy::from_emcy(&e) {
                        self.axes[a].queue.on_read_pointer(read);
                    }
                    if let Some(ElmoEmcy::MotionTerminated { reason: 3, .. }) =
                        ElmoEmcy::from_emcy(&e)
                    {
                        // Underflow: every row written has been played; the next motion
                        // starts at the write pointer.
                        let ax = &mut self.axes[a];
                        ax.queue.drain();
                        ax.started = false;
                        if let Motion::InterpolatedPosition { .. } = self.cfg.motion {
                            // Bit 4 must fall before the next start (a rising edge starts).
                            let cw = CanFrame::standard(
                                CobId::of(Function::Rpdo(1), ax.node).raw(),
                                &ds402::ModeControl::InterpolatedPosition { enable: false }
                                    .controlword(ds402::Command::EnableOperation, false)
                                    .to_le_bytes(),
                            )
                            .expect("valid frame");
                            let _ = self.bus.send(&cw, now + self.cfg.sdo_timeout);
                        }
                    }
                    self.events.push(Event::Emergency {
                        joint: self.axes[a].cfg.name.clone(),
                        text: e.describe(),
                        emcy: e,
                    });
                }
            }
            _ => {}
        }
    }

    /// Quick stop on every drive (controlword 0x0002): a controlled stop.
    pub fn quick_stop(&mut self) -> Result<(), MasterError> {
        for a in 0..self.axes.len() {
            self.axes[a].rows_pending.clear();
            self.write(
                a,
                ds402::CONTROLWORD,
                0,
                ds402::Command::QuickStop
                    .controlword()
                    .to_le_bytes()
                    .to_vec(),
            )?;
        }
        Ok(())
    }

    /// Disables every drive (torque off) and stops the nodes.
    pub fn disable(&mut self) -> Result<(), MasterError> {
        for a in 0..self.axes.len() {
            self.write(
                a,
                ds402::CONTROLWORD,
                0,
                ds402::Command::DisableVoltage
                    .controlword()
                    .to_le_bytes()
                    .to_vec(),
            )?;
        }
        self.send(&nmt::encode(nmt::Command::EnterPreOperational, 0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    use stride_canbus::MemBus;
    use stride_fakes::elmo::{ElmoConfig, FakeElmo, Levers};

    fn joint(i: u8) -> JointConfig {
        JointConfig {
            name: format!("j{i}"),
            node: i,
            counts_per_rev: 4096.0,
            gear_ratio: 100.0,
            min_position: -1.5,
            max_position: 1.5,
            max_velocity: 3.0,
            max_acceleration: 60.0,
            tolerance: 0.01,
        }
    }

    /// Pumps until the master is idle, then lets the motors settle with fresh states (each
    /// SYNC's answer arrives after the pump that sent it).
    fn play<B: CanBus>(m: &mut Master<B>) {
        let deadline = Instant::now() + Duration::from_secs(10);
        while !m.idle() && Instant::now() < deadline {
            m.pump(Instant::now()).unwrap();
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(m.idle(), "trajectory not finished");
        for _ in 0..10 {
            std::thread::sleep(Duration::from_millis(10));
            m.pump(Instant::now()).unwrap();
        }
    }

    /// One period of a shape over `rows` rows 10 ms apart: joint `j` moves by
    /// `amplitude · (j + 1) / joints · p(ω, t)` at velocity `amplitude · (j + 1) / joints · v(ω, t)`.
    fn periodic(
        joints: usize,
        amplitude: f64,
        rows: usize,
        p: fn(f64, f64) -> f64,
        v: fn(f64, f64) -> f64,
    ) -> Trajectory {
        let dt = 0.01;
        let w = std::f64::consts::TAU / (dt * (rows - 1) as f64);
        let table = |f: fn(f64, f64) -> f64| -> Vec<Vec<f64>> {
            (0..rows)
                .map(|r| {
                    (0..joints)
                        .map(|j| amplitude * (j + 1) as f64 / joints as f64 * f(w, r as f64 * dt))
                        .collect()
                })
                .collect()
        };
        Trajectory {
            joints: (1..=joints).map(|i| format!("j{i}")).collect(),
            times: (0..rows).map(|r| r as f64 * dt).collect(),
            positions: table(p),
            velocities: table(v),
        }
    }

    /// A sine period of 0.3 rad (scaled per joint): it ends in motion.
    fn sine(joints: usize, rows: usize) -> Trajectory {
        periodic(
            joints,
            0.3,
            rows,
            |w, t| (w * t).sin(),
            |w, t| w * (w * t).cos(),
        )
    }

    /// A move out and back of `amplitude` rad (a cosine bump), at rest at both ends.
    fn bump(joints: usize, amplitude: f64, rows: usize) -> Trajectory {
        periodic(
            joints,
            amplitude,
            rows,
            |w, t| (1.0 - (w * t).cos()) / 2.0,
            |w, t| w * (w * t).sin() / 2.0,
        )
    }

    type Rig = (
        MemBus,
        Arc<AtomicBool>,
        Vec<std::thread::JoinHandle<FakeElmo>>,
        Master<stride_canbus::MemNode>,
    );

    /// `n` fake drives and a master in `motion` mode, brought up.
    fn rig(n: u8, motion: Motion) -> Rig {
        let bus = MemBus::new(1_000_000);
        let stop = Arc::new(AtomicBool::new(false));
        let drives = spawn_drives(&bus, &vec![Levers::default(); n as usize], &stop);
        let cfg = MasterConfig {
            motion,
            ..Default::default()
        };
        let mut m = Master::new(bus.node(), (1..=n).map(joint).collect(), cfg).unwrap();
        m.bring_up().unwrap();
        (bus, stop, drives, m)
    }

    /// Stops the fake drives and waits for them.
    fn finish(stop: &AtomicBool, drives: Vec<std::thread::JoinHandle<FakeElmo>>) {
        stop.store(true, Ordering::Relaxed);
        for d in drives {
            d.join().unwrap();
        }
    }

    /// Fake drives with node ids 1, 2, … on `bus`, one per lever set.
    fn spawn_drives(
        bus: &MemBus,
        levers: &[Levers],
        stop: &Arc<AtomicBool>,
    ) -> Vec<std::thread::JoinHandle<FakeElmo>> {
        levers
            .iter()
            .enumerate()
            .map(|(i, l)| {
                FakeElmo::new(ElmoConfig::new(i as u8 + 1), l.clone())
                    .spawn(bus.node(), stop.clone())
            })
            .collect()
    }

    #[test]
    fn six_drives_walk_a_trajectory() {
        let bus = MemBus::new(1_000_000);
        let stop = Arc::new(AtomicBool::new(false));
        let drives = spawn_drives(&bus, &vec![Levers::default(); 6], &stop);
        let mut m = Master::new(
            bus.node(),
            (1..=6).map(joint).collect(),
            MasterConfig::default(),
        )
        .unwrap();
        m.bring_up().unwrap();
        // 150 rows (1.5 s), more than the 64-row tables hold: refilled as the drives play.
        let t = sine(6, 150);
        m.load(&t).unwrap();
        play(&mut m);
        let mut max_err: f64 = 0.0;
        for (i, (name, s)) in m.states().into_iter().enumerate() {
            let want = *t.positions.last().unwrap().get(i).unwrap();
            max_err = max_err.max((s.position - want).abs());
            assert!(s.updated.is_some(), "{name}: no state");
        }
        assert!(max_err < joint(1).tolerance, "final error {max_err} rad");
        let events = m.take_events();
        // The drives' following-error windows are the configured tolerance: none tripped.
        assert!(
            !events
                .iter()
                .any(|e| matches!(e, Event::Emergency { emcy, .. } if emcy.code == 0x8611)),
            "{events:?}"
        );
        let underflows = events
            .iter()
            .filter(|e| matches!(e, Event::Emergency { emcy, .. } if matches!(ElmoEmcy::from_emcy(emcy), Some(ElmoEmcy::MotionTerminated { reason: 3, .. }))))
            .count();
        assert_eq!(underflows, 6, "each drive ends its trajectory once");
        m.disable().unwrap();
        finish(&stop, drives);
    }

    #[test]
    fn limits_refuse_the_whole_trajectory() {
        let bus = MemBus::new(1_000_000);
        let m = Master::new(
            bus.node(),
            (1..=2).map(joint).collect(),
            MasterConfig::default(),
        )
        .unwrap();
        let mut t = sine(2, 150);
        t.positions[5][1] = 2.0;
        let e = m.validate(&t).unwrap_err();
        assert!(matches!(e, MasterError::Limit { row: 5, .. }), "{e}");
        let mut t = sine(2, 150);
        t.velocities[3][0] = 10.0;
        assert!(matches!(
            m.validate(&t),
            Err(MasterError::Limit { row: 3, .. })
        ));
        let mut t = sine(2, 150);
        t.joints[1] = "nope".into();
        assert!(matches!(m.validate(&t), Err(MasterError::BadTrajectory(_))));
        assert!(m.validate(&sine(2, 150)).is_ok());
    }

    #[test]
    fn a_missing_drive_is_a_clear_error() {
        let bus = MemBus::new(1_000_000);
        let cfg = MasterConfig {
            sdo_timeout: Duration::from_millis(50),
            ..Default::default()
        };
        let mut m = Master::new(bus.node(), vec![joint(9)], cfg).unwrap();
        let e = m.bring_up().unwrap_err();
        assert!(matches!(e, MasterError::NoAnswer { node: 9, .. }), "{e}");
        assert!(e.to_string().contains("j9 (node 9)"));
    }

    #[test]
    fn faults_become_events_and_errors() {
        let bus = MemBus::new(1_000_000);
        let stop = Arc::new(AtomicBool::new(false));
        let levers: Vec<Levers> = (0..2).map(|_| Levers::default()).collect();
        let drives = spawn_drives(&bus, &levers, &stop);
        let mut m = Master::new(
            bus.node(),
            (1..=2).map(joint).collect(),
            MasterConfig::default(),
        )
        .unwrap();
        m.bring_up().unwrap();
        let run = |m: &mut Master<stride_canbus::MemNode>, ms: u64| {
            let end = Instant::now() + Duration::from_millis(ms);
            while Instant::now() < end {
                m.pump(Instant::now()).unwrap();
                std::thread::sleep(Duration::from_millis(5));
            }
        };
        run(&mut m, 300);
        assert!(m.take_events().is_empty());
        // A drive in fault: its emergency is reported, its statusword shows it.
        levers[0].fault.store(true, Ordering::Relaxed);
        run(&mut m, 100);
        let ev = m.take_events();
        assert!(
            ev.iter().any(|e| matches!(e, Event::Emergency { joint, text, .. } if joint == "j1" && text == "current")),
            "{ev:?}"
        );
        let s = m.states()[0].1;
        assert_eq!(DriveState::from_statusword(s.statusword), DriveState::Fault);
        // A drive that stops answering: its heartbeat is declared lost.
        levers[1].silent.store(true, Ordering::Relaxed);
        run(&mut m, 500);
        let ev = m.take_events();
        assert!(
            ev.iter()
                .any(|e| matches!(e, Event::HeartbeatLost { joint } if joint == "j2")),
            "{ev:?}"
        );
        // An SDO to it times out with a clear error.
        let e = m.read(1, 0x1000, 0).unwrap_err();
        assert!(matches!(e, MasterError::NoAnswer { node: 2, .. }), "{e}");
        // Bus-off: every call fails with it, nothing panics.
        bus.set_bus_off(true);
        assert_eq!(
            m.pump(Instant::now()),
            Err(MasterError::Bus(BusError::BusOff))
        );
        assert!(m.recover().is_err());
        // The bus comes back (and the silent drive with it): recovery brings both drives up
        // again, the faulted one through a fault reset, and they move.
        bus.set_bus_off(false);
        levers[1].silent.store(false, Ordering::Relaxed);
        m.recover().unwrap();
        let t = bump(2, 0.2, 60);
        m.load(&t).unwrap();
        play(&mut m);
        for (name, s) in m.states() {
            assert_eq!(
                DriveState::from_statusword(s.statusword),
                DriveState::OperationEnabled,
                "{name}"
            );
            assert!(s.position.abs() < 1e-3, "{name}: {}", s.position);
        }
        // A drive that resets (here by NMT, as a power cycle would) is reported once.
        m.take_events();
        bus.node()
            .send(&nmt::encode(nmt::Command::ResetNode, 2), Instant::now())
            .unwrap();
        run(&mut m, 100);
        let rebooted: Vec<Event> = m
            .take_events()
            .into_iter()
            .filter(|e| matches!(e, Event::Rebooted { .. }))
            .collect();
        assert_eq!(rebooted, [Event::Rebooted { joint: "j2".into() }]);
        m.recover().unwrap();
        finish(&stop, drives);
    }

    #[test]
    fn interpolated_position_mode_walks_the_same_trajectory() {
        let (_bus, stop, drives, mut m) = rig(3, Motion::InterpolatedPosition { period_ms: 10 });
        let t = sine(3, 150);
        m.load(&t).unwrap();
        play(&mut m);
        for (i, (_, s)) in m.states().into_iter().enumerate() {
            let want = t.positions.last().unwrap()[i];
            assert!(
                (s.position - want).abs() < 1e-3,
                "joint {i}: {} vs {want}",
                s.position
            );
        }
        // A trajectory whose rows are not the fixed period apart is refused.
        let mut uneven = sine(3, 150);
        uneven.times[10] += 0.004;
        assert!(matches!(
            m.validate(&uneven),
            Err(MasterError::BadTrajectory(_))
        ));
        finish(&stop, drives);
    }

    #[test]
    fn pt_mode_walks_a_move_resampled_at_its_period() {
        let (_bus, stop, drives, mut m) = rig(6, Motion::Pt { period_ms: 8 });
        // 3 s out and back at 10 ms rows, played as 8 ms PT points (376 of them, more than
        // the 256-point rings hold): resampled, refilled, ended at rest.
        let t = bump(6, 0.4, 301);
        m.load(&t).unwrap();
        let mut peak = [0f64; 6];
        let deadline = Instant::now() + Duration::from_secs(10);
        while !m.idle() && Instant::now() < deadline {
            m.pump(Instant::now()).unwrap();
            for (i, (_, s)) in m.states().into_iter().enumerate() {
                peak[i] = peak[i].max(s.position);
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        play(&mut m);
        for (i, (name, s)) in m.states().into_iter().enumerate() {
            let top = 0.4 * (i + 1) as f64 / 6.0;
            assert!(s.position.abs() < 1e-3, "{name} ends at {}", s.position);
            assert!(
                (peak[i] - top).abs() < 0.02 * top,
                "{name} peaked at {}",
                peak[i]
            );
        }
        let refused: Vec<Event> = m
            .take_events()
            .into_iter()
            .filter(|e| matches!(e, Event::InterpreterError { .. }))
            .collect();
        assert!(refused.is_empty(), "{refused:?}");
        m.disable().unwrap();
        finish(&stop, drives);
    }

    #[test]
    fn a_pt_period_off_the_drive_sample_grid_is_refused_at_bring_up() {
        let bus = MemBus::new(1_000_000);
        let stop = Arc::new(AtomicBool::new(false));
        let mut drive = ElmoConfig::new(1);
        drive.ts_us = 75; // position loop every 300 µs: 10 ms is not a whole number of them
        let h = FakeElmo::new(drive, Levers::default()).spawn(bus.node(), stop.clone());
        let cfg = MasterConfig {
            motion: Motion::Pt { period_ms: 10 },
            ..Default::default()
        };
        let mut m = Master::new(bus.node(), vec![joint(1)], cfg).unwrap();
        let e = m.bring_up().unwrap_err();
        assert!(
            matches!(&e, MasterError::Setup { node: 1, what, .. } if what.contains("300 µs")),
            "{e}"
        );
        stop.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }
}
