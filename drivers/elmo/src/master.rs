//! The master: its drives as it tracks them from every frame (states, tables, heartbeats,
//! emergencies), its SDO and interpreter exchanges, and what it reports.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use stride_canbus::{CanBus, CanFrame};
use stride_canopen::ds402;
use stride_canopen::elmo::{Command as Interp, PvtQueue, Reply, Value};
use stride_canopen::emcy::{ElmoEmcy, Emcy};
use stride_canopen::frame::{CobId, Function, NodeId};
use stride_canopen::pdo::{Direction, MapEntry, PdoConfig};
use stride_canopen_host::{self as host, HeartbeatProducer, HostError};

use crate::config::{JointConfig, MasterConfig, Motion};
use crate::error::MasterError;
use crate::plan::{Bounds, Interp as Curve, Plan};
use crate::units::Units;

/// What the master reports while running.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A drive sent an emergency that is not part of normal motion (queue-low refill
    /// requests and the end of a motion at its last row are not reported).
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
    /// A chunk of a stream ended in motion and nothing followed in time: its joints
    /// decelerate to a stop within their limits.
    StreamStopped {
        /// The joints that stop.
        joints: Vec<String>,
    },
    /// A drive ran out of rows while moving (they reached it too late): it stopped abruptly.
    Underflow {
        /// Joint.
        joint: String,
    },
    /// A drive did not report the end of a motion within [`END_REPORT_WAIT`] of its end by
    /// the master's clock: its next motion went ahead without it.
    EndUnreported {
        /// Joint.
        joint: String,
    },
}

impl Event {
    /// True for faults of the drives or the bus (every event the bridge stops the drives
    /// for), false for what a healthy system also sees now and then (a stream that ran dry
    /// and decelerated).
    pub fn is_fault(&self) -> bool {
        !matches!(
            self,
            Event::StreamStopped { .. } | Event::EndUnreported { .. }
        )
    }
}

/// The measured state of one joint.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointState {
    /// Position, rad.
    pub position: f64,
    /// Velocity, rad/s, from the positions of successive SYNCs.
    pub velocity: f64,
    /// CiA 402 statusword.
    pub statusword: u16,
    /// When the last TPDO arrived.
    pub updated: Option<Instant>,
}

/// Counters of the master since start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Counters {
    /// Trajectories accepted.
    pub accepted: u64,
    /// Trajectories refused.
    pub refused: u64,
    /// Queued rows dropped because a trajectory replaced them.
    pub replaced_rows: u64,
    /// Queued rows dropped by a stop (quick stop, fault, recovery).
    pub dropped_rows: u64,
    /// Streams that stopped: a chunk ended in motion and nothing followed in time.
    pub stream_stops: u64,
    /// Drives that ran out of rows while moving.
    pub underflows: u64,
    /// Times the drives were enabled again after a stop.
    pub rearms: u64,
    /// Motions the master ended on its own clock whose end no drive reported in time
    /// ([`END_REPORT_WAIT`]): the next motion went ahead without it.
    pub unreported_ends: u64,
    /// SDO and interpreter exchanges sent again after no answer came in time.
    pub sdo_retries: u64,
}

/// How long the next motion of a joint waits for its drive's report that the last one
/// ended (the EMCY that ends every motion), once the master's clock says it has: the start
/// the master counts from may have waited on the wire behind a table's worth of rows.
pub const END_REPORT_WAIT: std::time::Duration = std::time::Duration::from_millis(200);

/// What the master says of itself.
#[derive(Debug, Clone, PartialEq)]
pub struct Status {
    /// Why the drives are stopped, if they are: the next valid trajectory re-enables them
    /// from where the joints stand.
    pub stopped: Option<String>,
    /// When the queued motion ends (`None`: nothing queued).
    pub queued_until: Option<Instant>,
    /// The counters.
    pub counters: Counters,
}

pub(crate) struct Axis {
    pub cfg: JointConfig,
    pub units: Units,
    pub bounds: Bounds,
    pub node: NodeId,
    pub queue: PvtQueue,
    pub state: JointState,
    pub plan: Plan,
    /// The drive plays the plan (its start went out).
    pub playing: bool,
    /// The drive plays plan time `t` at `t + lag` µs (its start went out `lag` late).
    pub lag: i64,
    /// Table rows written since the motion started (PT points go two to a frame).
    pub written: u64,
    /// The plan time the motion loaded in the table starts at (its start is not sent yet).
    pub start_at: Option<i64>,
    /// When (master µs) the master ended the last motion on its own clock: until the drive
    /// reports that end (or [`END_REPORT_WAIT`] passes) it may still be playing, and the next
    /// motion's rows and start wait.
    pub ended_at: Option<i64>,
    pub last_heartbeat: Option<Instant>,
    pub heartbeat_lost: bool,
    /// Brought up and enabled (a boot-up message then means the drive reset).
    pub up: bool,
    /// The previous TPDO's position and the SYNC it answered (for the velocity).
    prev: Option<(Instant, f64)>,
}

/// What the master knows of its drives, updated from every frame that arrives (while it
/// waits for an SDO answer too).
pub(crate) struct Track {
    pub axes: Vec<Axis>,
    pub by_node: HashMap<u8, usize>,
    pub events: Vec<Event>,
    /// Underflows since start, counted as they are reported.
    pub underflows: u64,
    pub heartbeat: HeartbeatProducer,
    pub motion: Motion,
    pub drive_heartbeat: Duration,
    /// The SYNC's period now (longer while the drives rest).
    pub sync_period: Duration,
    /// When the last SYNC went out: the states read before the next one answer it.
    pub last_sync: Option<Instant>,
    /// When the drives' heartbeats were last watched.
    pub last_watch: Option<Instant>,
}

/// A joint slower than this, rad/s, stands still (see [`Master::resting`]).
pub const STILL_SPEED: f64 = 0.01;

/// The set-point RPDO: RPDO3 carrying object 0x2001 (a PVT row per frame), 0x2002 (two PT
/// points per frame), or 0x60C1:1 (an interpolated position set-point per frame).
pub(crate) fn setpoint_rpdo(motion: Motion) -> PdoConfig {
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
            index: stride_canopen::elmo::PT_OBJECT,
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

/// The controlword RPDO: RPDO1 carrying 0x6040 (quick stops reach every drive at once).
pub(crate) fn controlword_rpdo() -> PdoConfig {
    PdoConfig {
        direction: Direction::Receive,
        number: 1,
        transmission: 255,
        entries: vec![MapEntry {
            index: ds402::CONTROLWORD,
            sub: 0,
            bits: 16,
        }],
    }
}

/// The state TPDO: TPDO1 with statusword, actual position and the table's read pointer
/// (0x2F12, readable only through a PDO), on every SYNC.
pub(crate) fn state_tpdo() -> PdoConfig {
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
                index: stride_canopen::elmo::READ_POINTER,
                sub: 0,
                bits: 16,
            },
        ],
    }
}

/// `MP[4]=50`, `TS`: an interpreter command as the manuals write it.
pub(crate) fn command_text(cmd: &Interp) -> String {
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

/// The table mode's curve.
pub(crate) fn curve_of(motion: Motion) -> Curve {
    match motion {
        Motion::Pvt => Curve::Pvt,
        Motion::Pt { period_ms } => Curve::Pt {
            period: period_ms as i64 * 1000,
        },
        Motion::InterpolatedPosition { period_ms } => Curve::Ip {
            period: period_ms as i64 * 1000,
        },
    }
}

impl Axis {
    pub fn new(cfg: JointConfig, units: Units, node: NodeId, motion: Motion) -> Axis {
        Axis {
            bounds: Bounds {
                min: cfg.min_position,
                max: cfg.max_position,
                v: cfg.max_velocity,
                a: cfg.max_acceleration,
            },
            cfg,
            units,
            node,
            queue: PvtQueue::new(motion.table_rows()),
            state: JointState::default(),
            plan: Plan::new(curve_of(motion)),
            playing: false,
            lag: 0,
            written: 0,
            start_at: None,
            ended_at: None,
            last_heartbeat: None,
            heartbeat_lost: false,
            up: false,
            prev: None,
        }
    }

    /// The speed a joint standing still may show between two states `period` apart: the
    /// measurement's noise of a count or two.
    pub fn still_speed(&self, period: Duration) -> f64 {
        2.0 / (self.units.counts_per_rad().abs() * period.as_secs_f64())
    }

    /// The drive ended its motion at its last row: what was not played is gone from its
    /// table, and the next motion starts from rest.
    pub fn end_motion(&mut self) {
        self.playing = false;
        self.lag = 0;
        self.written = 0;
        self.queue.drain();
        self.plan.finish();
    }

    /// Forgets the motion: the drive dropped its table (a stop, a reset). Returns the rows
    /// dropped.
    pub fn drop_motion(&mut self, motion: Motion) -> usize {
        self.playing = false;
        self.lag = 0;
        self.written = 0;
        self.start_at = None;
        self.ended_at = None;
        self.queue = PvtQueue::new(motion.table_rows());
        self.plan.clear()
    }

    /// A state sampled at the SYNC sent at `sampled` (read at `now`).
    fn on_state(
        &mut self,
        statusword: u16,
        counts: i32,
        sampled: Instant,
        now: Instant,
        period: Duration,
    ) {
        let position = self.units.rad(counts as f64);
        self.state.statusword = statusword;
        if let Some((t, p)) = self.prev {
            // The drive samples its position at the SYNC: the time between two states is
            // the time between the SYNCs they answer, however late they were read (a master
            // descheduled for 100 ms after a SYNC reads its answer 100 ms late, and must not
            // take it for a tenth of the speed). Two states read after one SYNC: the first
            // answered the SYNC before, a period earlier.
            let dt = sampled.saturating_duration_since(t).as_secs_f64();
            let period = period.as_secs_f64();
            let dt = if dt < period / 2.0 { period } else { dt };
            self.state.velocity = (position - p) / dt;
        }
        self.prev = Some((sampled, position));
        self.state.position = position;
        self.state.updated = Some(now);
    }
}

impl Track {
    /// What a frame says about the drives.
    pub fn on_frame<B: CanBus + ?Sized>(&mut self, f: &CanFrame, now: Instant, bus: &mut B) {
        let Some(cob) = CobId::parse(f.raw_id() as u16) else {
            return;
        };
        let Some(&a) = cob.node.and_then(|n| self.by_node.get(&n.get())) else {
            return;
        };
        match cob.function {
            Function::Tpdo(1) => {
                if let Some(v) = state_tpdo().unpack(f.data()) {
                    let period = self.sync_period;
                    let sampled = self.last_sync.unwrap_or(now);
                    let ax = &mut self.axes[a];
                    ax.on_state(v[0] as u16, v[1] as u32 as i32, sampled, now, period);
                    if ax.playing {
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
                    self.on_emcy(a, e, bus, now);
                }
            }
            _ => {}
        }
    }

    fn on_emcy<B: CanBus + ?Sized>(&mut self, a: usize, e: Emcy, bus: &mut B, now: Instant) {
        let motion = self.motion;
        let ax = &mut self.axes[a];
        let routine = match ElmoEmcy::from_emcy(&e) {
            // A refill request: the table is tracked from the read pointer.
            Some(ElmoEmcy::QueueLow { read, .. }) => {
                ax.queue.on_read_pointer(read);
                true
            }
            // The end of a motion the master already ended on its own clock, reported late:
            // the next motion may go.
            Some(ElmoEmcy::MotionTerminated { reason: 1 | 3, .. })
                if ax.ended_at.is_some() && !ax.playing =>
            {
                ax.ended_at = None;
                true
            }
            Some(ElmoEmcy::MotionTerminated { reason: 1 | 3, .. }) => {
                // Every row written has been played: at the plan's end that is the motion's
                // normal end, before it an underflow.
                let expected = ax.plan.is_empty() || ax.plan.ended();
                ax.end_motion();
                ax.ended_at = None;
                if let Motion::InterpolatedPosition { .. } = motion {
                    // Bit 4 must fall before the next start (a rising edge starts).
                    let cw = ds402::ModeControl::InterpolatedPosition { enable: false }
                        .controlword(ds402::Command::EnableOperation, false);
                    let f = ds402::controlword_frame(controlword_rpdo().cob_id(ax.node), cw);
                    let _ = bus.send(&f, now + host::SLICE);
                }
                if !expected {
                    self.underflows += 1;
                    self.events.push(Event::Underflow {
                        joint: ax.cfg.name.clone(),
                    });
                }
                true
            }
            // The error reset after a fault reset is the good news.
            _ => e.code == Emcy::ERROR_RESET,
        };
        if !routine {
            self.events.push(Event::Emergency {
                joint: self.axes[a].cfg.name.clone(),
                text: e.describe(),
                emcy: e,
            });
        }
    }

    /// Declares lost the heartbeats of drives silent for three periods (none when the drives
    /// send none). Silence is judged only over time the master listened: after a gap in its
    /// own watch longer than a period (its process held up, its frames waiting unread), each
    /// drive is heard from no earlier than a period ago, so a drive is declared lost three
    /// periods after the master looks again, not at once.
    pub fn watch_heartbeats(&mut self, now: Instant) {
        if self.drive_heartbeat.is_zero() {
            return;
        }
        let lost_after = self.drive_heartbeat * 3;
        let away = self
            .last_watch
            .is_some_and(|w| now.saturating_duration_since(w) > self.drive_heartbeat);
        self.last_watch = Some(now);
        if away {
            let floor = now.checked_sub(self.drive_heartbeat).unwrap_or(now);
            for ax in &mut self.axes {
                if let Some(t) = &mut ax.last_heartbeat {
                    *t = (*t).max(floor);
                }
            }
        }
        for ax in &mut self.axes {
            if let Some(t) = ax.last_heartbeat {
                if !ax.heartbeat_lost && now.saturating_duration_since(t) > lost_after {
                    ax.heartbeat_lost = true;
                    self.events.push(Event::HeartbeatLost {
                        joint: ax.cfg.name.clone(),
                    });
                }
            }
        }
    }

    /// While the master waits: frames are tracked, the master's heartbeat goes on.
    pub fn aside<B: CanBus + ?Sized>(&mut self, bus: &mut B, f: Option<&CanFrame>) {
        let now = bus.now();
        if let Some(f) = f {
            self.on_frame(f, now, bus);
        }
        let _ = self.heartbeat.poll(bus, now);
    }
}

/// The wall clock's offset from plan time (µs) from readings (plan time before, wall clock,
/// plan time after): the tightest reading's, if it is tight (within 200 µs); None when every
/// reading was interrupted.
pub(crate) fn clock_offset(samples: &[(i64, i64, i64)]) -> Option<i64> {
    let &(a, w, b) = samples.iter().min_by_key(|(a, _, b)| b - a)?;
    (b - a <= 200).then(|| w - (a + b) / 2)
}

/// The CANopen master of a set of Elmo drives.
pub struct Master<B: CanBus> {
    pub(crate) bus: B,
    pub(crate) cfg: MasterConfig,
    pub(crate) track: Track,
    /// Plan time 0.
    pub(crate) epoch: Instant,
    /// The wall clock at plan time 0, µs since the Unix epoch: trajectories' start times
    /// map to plan time through this one offset, so that starts sent on one grid land on
    /// one grid (see [`Master::plan_us_of_wall`]).
    pub(crate) wall_epoch: i64,
    pub(crate) next_sync: Instant,
    /// Starts not yet sent (the controller's queue was full): each with the axis and plan
    /// time it starts, when it is a start and not a read pointer.
    pub(crate) starts: std::collections::VecDeque<(Option<(usize, i64)>, CanFrame)>,
    pub(crate) stopped: Option<String>,
    pub(crate) counters: Counters,
}

impl<B: CanBus> std::fmt::Debug for Master<B> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Master")
            .field("joints", &self.track.axes.len())
            .field("motion", &self.cfg.motion)
            .field("stopped", &self.stopped)
            .finish()
    }
}

impl<B: CanBus> Master<B> {
    /// A master for `joints` on `bus`: every joint's limits are checked to fit the drive's
    /// fields in the configured motion mode, node ids to be distinct and apart from the
    /// master's own.
    pub fn new(
        bus: B,
        joints: Vec<JointConfig>,
        cfg: MasterConfig,
    ) -> Result<Master<B>, MasterError> {
        let master_node = NodeId::new(cfg.master_node).map_err(|_| MasterError::Setup {
            joint: "master".into(),
            node: cfg.master_node,
            what: "the master's node id is outside 1..=127".into(),
        })?;
        let mut axes: Vec<Axis> = Vec::new();
        let mut by_node = HashMap::new();
        for j in joints {
            let setup = |what: String| MasterError::Setup {
                joint: j.name.clone(),
                node: j.node,
                what,
            };
            let node = NodeId::new(j.node).map_err(|_| setup("node id outside 1..=127".into()))?;
            if j.node == cfg.master_node {
                return Err(setup(format!(
                    "node id {} is the master's own (master_node)",
                    j.node
                )));
            }
            if by_node.insert(j.node, axes.len()).is_some() {
                return Err(setup("node id used twice".into()));
            }
            if axes.iter().any(|a| a.cfg.name == j.name) {
                return Err(setup("joint name used twice".into()));
            }
            let units = Units::of(&j, cfg.motion).map_err(setup)?;
            axes.push(Axis::new(j, units, node, cfg.motion));
        }
        if let Motion::Pt { period_ms } | Motion::InterpolatedPosition { period_ms } = cfg.motion {
            if period_ms == 0 || cfg.lookahead < Duration::from_millis(3 * period_ms as u64) {
                return Err(MasterError::Setup {
                    joint: "master".into(),
                    node: cfg.master_node,
                    what: format!(
                        "a lookahead of {} ms is less than three {period_ms} ms periods",
                        cfg.lookahead.as_millis()
                    ),
                });
            }
        }
        // Resting, the heartbeat goes with the SYNC: the drives' watchdog must see two.
        if cfg.idle_sync_period < cfg.sync_period || 2 * cfg.idle_sync_period > cfg.drive_watchdog {
            return Err(MasterError::Setup {
                joint: "master".into(),
                node: cfg.master_node,
                what: format!(
                    "an idle SYNC period of {} ms is outside [the SYNC period, {} ms; half of \
                     the drives' watchdog, {} ms]",
                    cfg.idle_sync_period.as_millis(),
                    cfg.sync_period.as_millis(),
                    cfg.drive_watchdog.as_millis() / 2
                ),
            });
        }
        // Plan time 0 and the wall clock then, read with nothing between them (a reading the
        // scheduler interrupted is taken again).
        let (now, wall_epoch) = (0..10)
            .map(|_| {
                let a = bus.now();
                let w = bus.utime();
                (a, w, bus.now() - a)
            })
            .min_by_key(|s| s.2)
            .map(|(a, w, _)| (a, w))
            .expect("ten readings");
        Ok(Master {
            bus,
            track: Track {
                axes,
                by_node,
                events: Vec::new(),
                underflows: 0,
                heartbeat: HeartbeatProducer::new(master_node, cfg.master_heartbeat),
                motion: cfg.motion,
                drive_heartbeat: cfg.heartbeat,
                last_watch: None,
                sync_period: cfg.sync_period,
                last_sync: None,
            },
            cfg,
            epoch: now,
            wall_epoch,
            next_sync: now,
            starts: Default::default(),
            stopped: None,
            counters: Counters::default(),
        })
    }

    /// Plan time of a wall-clock time `utime` (µs since the Unix epoch). One fixed offset
    /// maps every start, not the clocks' difference read anew each time (which moves by the
    /// time between the two readings and would shift a replacing trajectory against the
    /// rows it joins); the offset is read again when the wall clock was stepped (50 ms), or
    /// has drifted by more than a millisecond from it while nothing is queued.
    pub(crate) fn plan_us_of_wall(&mut self, utime: i64) -> i64 {
        // The wall clock between two readings of the monotonic one, three times: a reading
        // the scheduler interrupted is not taken for a step of the clock.
        let samples: Vec<(i64, i64, i64)> = (0..3)
            .map(|_| {
                let a = self.us(self.bus.now());
                let w = self.bus.utime();
                (a, w, self.us(self.bus.now()))
            })
            .collect();
        if let Some(fresh) = clock_offset(&samples) {
            let drift = (fresh - self.wall_epoch).abs();
            // While motion is queued the offset moves only for a step of the clock: moved
            // by a drift of a few milliseconds, a replacing trajectory would land that far
            // off the rows it joins.
            if drift > 50_000 || (drift > 1000 && self.idle()) {
                self.wall_epoch = fresh;
            }
        }
        utime.saturating_sub(self.wall_epoch)
    }

    /// Plan time of `t`, µs.
    pub(crate) fn us(&self, t: Instant) -> i64 {
        t.saturating_duration_since(self.epoch).as_micros() as i64
    }

    /// The instant of plan time `us`.
    pub(crate) fn instant(&self, us: i64) -> Instant {
        self.epoch + Duration::from_micros(us.max(0) as u64)
    }

    /// The joints' measured states, in configuration order.
    pub fn states(&self) -> Vec<(&str, JointState)> {
        self.track
            .axes
            .iter()
            .map(|a| (a.cfg.name.as_str(), a.state))
            .collect()
    }

    /// Events since the last call.
    pub fn take_events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.track.events)
    }

    /// The bus's time ([`CanBus::now`]): the clock the master keeps its times on.
    pub fn now(&self) -> Instant {
        self.bus.now()
    }

    /// The wall clock at [`Master::now`], µs since the Unix epoch ([`CanBus::utime`]).
    pub fn utime(&self) -> i64 {
        self.bus.utime()
    }

    /// What the master says of itself.
    pub fn status(&self) -> Status {
        let end = self
            .track
            .axes
            .iter()
            .filter_map(|a| {
                a.plan
                    .end()
                    .filter(|_| !a.plan.is_empty())
                    .map(|k| k.t + a.lag)
            })
            .max();
        Status {
            stopped: self.stopped.clone(),
            queued_until: end.map(|us| self.instant(us)),
            counters: Counters {
                underflows: self.track.underflows,
                ..self.counters
            },
        }
    }

    /// Rows each drive holds in its table and has not played yet (as the master counts them
    /// from the read pointers the drives report), in configuration order: a playing axis at 0
    /// has run dry.
    pub fn table_depths(&self) -> Vec<(bool, u64)> {
        self.track
            .axes
            .iter()
            .map(|a| (a.playing, a.queue.pending()))
            .collect()
    }

    /// True when no axis has motion queued or playing.
    pub fn idle(&self) -> bool {
        self.track
            .axes
            .iter()
            .all(|a| a.plan.is_empty() && !a.playing)
    }

    /// Nothing queued or playing, and every joint still (under [`STILL_SPEED`]).
    pub fn resting(&self) -> bool {
        self.idle()
            && self
                .track
                .axes
                .iter()
                .all(|a| a.state.velocity.abs() < STILL_SPEED)
    }

    fn host_error(&self, a: usize, e: HostError, what: impl FnOnce() -> String) -> MasterError {
        let ax = &self.track.axes[a];
        match e {
            HostError::Bus(b) => MasterError::Bus(b),
            HostError::NoAnswer => MasterError::NoAnswer {
                joint: ax.cfg.name.clone(),
                node: ax.node.get(),
                what: what(),
            },
            HostError::Sdo(error) => MasterError::Sdo {
                joint: ax.cfg.name.clone(),
                node: ax.node.get(),
                error,
            },
        }
    }

    /// Runs `exchange` again while it gets no answer, up to [`MasterConfig::sdo_retries`]
    /// more times (counted).
    fn retried<T>(
        &mut self,
        mut exchange: impl FnMut(&mut Self) -> Result<T, MasterError>,
    ) -> Result<T, MasterError> {
        let mut left = self.cfg.sdo_retries;
        loop {
            match exchange(self) {
                Err(MasterError::NoAnswer { .. }) if left > 0 => {
                    left -= 1;
                    self.counters.sdo_retries += 1;
                }
                r => return r,
            }
        }
    }

    /// Writes an object of axis `a` (sent again when no answer comes).
    pub fn write(
        &mut self,
        a: usize,
        index: u16,
        sub: u8,
        data: Vec<u8>,
    ) -> Result<(), MasterError> {
        self.retried(|m| m.write_once(a, index, sub, data.clone()))
    }

    fn write_once(
        &mut self,
        a: usize,
        index: u16,
        sub: u8,
        data: Vec<u8>,
    ) -> Result<(), MasterError> {
        let node = self.track.axes[a].node;
        let now = self.bus.now();
        let _ = self.track.heartbeat.poll(&mut self.bus, now);
        let track = &mut self.track;
        host::sdo_write(
            &mut self.bus,
            node,
            index,
            sub,
            data,
            self.cfg.sdo_timeout,
            &mut |bus: &mut B, f: Option<&CanFrame>| track.aside(bus, f),
        )
        .map_err(|e| self.host_error(a, e, || format!("a write of {index:#06x}:{sub}")))
    }

    /// Reads an object of axis `a` (asked again when no answer comes).
    pub fn read(&mut self, a: usize, index: u16, sub: u8) -> Result<Vec<u8>, MasterError> {
        self.retried(|m| m.read_once(a, index, sub))
    }

    fn read_once(&mut self, a: usize, index: u16, sub: u8) -> Result<Vec<u8>, MasterError> {
        let node = self.track.axes[a].node;
        let now = self.bus.now();
        let _ = self.track.heartbeat.poll(&mut self.bus, now);
        let track = &mut self.track;
        host::sdo_read(
            &mut self.bus,
            node,
            index,
            sub,
            self.cfg.sdo_timeout,
            &mut |bus: &mut B, f: Option<&CanFrame>| track.aside(bus, f),
        )
        .map_err(|e| self.host_error(a, e, || format!("a read of {index:#06x}:{sub}")))
    }

    /// One binary-interpreter exchange with axis `a` over PDO2 (RPDO2 out, TPDO2 back), sent
    /// again when no answer comes.
    pub fn interpret(&mut self, a: usize, cmd: Interp) -> Result<Value, MasterError> {
        self.retried(|m| m.interpret_once(a, cmd))
    }

    fn interpret_once(&mut self, a: usize, cmd: Interp) -> Result<Value, MasterError> {
        let node = self.track.axes[a].node;
        let want = CobId::of(Function::Tpdo(2), node).raw() as u32;
        let frame = cmd.encode(node).map_err(|_| MasterError::Interpreter {
            joint: self.track.axes[a].cfg.name.clone(),
            node: node.get(),
            command: command_text(&cmd),
            code: 0,
        })?;
        let now = self.bus.now();
        let _ = self.track.heartbeat.poll(&mut self.bus, now);
        let track = &mut self.track;
        let deadline = self.bus.now() + self.cfg.sdo_timeout;
        let result = host::exchange(
            &mut self.bus,
            &frame,
            deadline,
            |f| match Reply::decode(f.data()) {
                Ok(r) if f.raw_id() == want && r.name == cmd.name && r.index == cmd.index => {
                    Some(r.result)
                }
                _ => None,
            },
            &mut |bus: &mut B, f: Option<&CanFrame>| track.aside(bus, f),
        )
        .map_err(|e| self.host_error(a, e, || command_text(&cmd)))?;
        result.map_err(|code| MasterError::Interpreter {
            joint: self.track.axes[a].cfg.name.clone(),
            node: node.get(),
            command: command_text(&cmd),
            code,
        })
    }

    /// The statusword of axis `a`, read by SDO.
    pub(crate) fn statusword(&mut self, a: usize) -> Result<u16, MasterError> {
        let d = self.read(a, ds402::STATUSWORD, 0)?;
        Ok(u16::from_le_bytes([
            d.first().copied().unwrap_or(0),
            d.get(1).copied().unwrap_or(0),
        ]))
    }
}

#[cfg(test)]
mod tests {
    use super::clock_offset;

    /// A bridge held up for 234 ms under load (its drives' heartbeats waiting unread) once
    /// declared a live drive's heartbeat lost, a fault that stopped the whole robot. Silence
    /// is judged over time the master listened; a drive that really went silent is still
    /// declared lost three periods after the master looks again.
    #[test]
    fn a_master_held_up_does_not_declare_its_drives_lost_for_its_own_absence() {
        use super::{Event, Master, MasterConfig};
        use std::time::{Duration, Instant};
        let bus = stride_canbus::MemBus::new(1_000_000);
        let joint = crate::JointConfig {
            name: "j1".into(),
            node: 1,
            counts_per_rev: 4096.0,
            gear_ratio: 100.0,
            min_position: -1.5,
            max_position: 1.5,
            max_velocity: 3.0,
            max_acceleration: 60.0,
            tolerance: 0.01,
        };
        let mut m = Master::new(bus.node(), vec![joint], MasterConfig::default()).unwrap();
        let ms = Duration::from_millis;
        let t0 = Instant::now();
        m.track.axes[0].last_heartbeat = Some(t0);
        m.track.watch_heartbeats(t0 + ms(50));
        // Held up for 450 ms: nothing is declared when it looks again.
        m.track.watch_heartbeats(t0 + ms(500));
        m.track.watch_heartbeats(t0 + ms(550));
        assert!(m.take_events().is_empty());
        // Nothing heard since, while it watches every 50 ms: lost 300 ms after its return.
        let mut lost_at = None;
        for k in 12..30u64 {
            m.track.watch_heartbeats(t0 + ms(k * 50));
            if lost_at.is_none()
                && m.take_events()
                    .iter()
                    .any(|e| matches!(e, Event::HeartbeatLost { .. }))
            {
                lost_at = Some(k * 50);
            }
        }
        assert_eq!(lost_at, Some(750));
    }

    #[test]
    fn a_clock_reading_the_scheduler_interrupted_does_not_move_the_start_times() {
        // Wall clock = plan time + 1 000 000 µs. The first reading was interrupted for 3 ms
        // between the two clocks (it alone would say the offset moved by 1.5 ms); the
        // others are tight: the offset is the tight readings'.
        let samples = [
            (100, 1_000_100 + 3_000, 3_100),
            (3_200, 1_003_210, 3_220),
            (3_300, 1_003_305, 3_310),
        ];
        let off = clock_offset(&samples).unwrap();
        assert!((off - 1_000_000).abs() <= 10, "{off}");
        // Every reading interrupted: no new offset at all.
        assert_eq!(
            clock_offset(&[(0, 1_002_000, 4_000), (5_000, 1_007_000, 9_000)]),
            None
        );
    }
}
