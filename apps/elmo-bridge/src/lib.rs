//! The logic of `stride-elmo-bridge`: its configuration, LCM trajectories to the master's and
//! joint states back, and the bridge as a state machine ([`Bridge`]): what it does with each
//! trajectory, and with each event of the drives (a fault or a lost drive stops every axis;
//! a bus failure or a reset brings the drives up again), and what it reports, in its health
//! and in `stride.trajectory_status_t`. The CANopen work is `stride-elmo`'s.

mod app;

pub use app::{open_bus, Cli, ElmoApp};

use std::time::{Duration, Instant};

use stride_canbus::{BusSpec, CanBus};
use stride_elmo::{Event, JointConfig, Master, MasterConfig, Start, Trajectory};
use stride_lcmtypes::stride::{
    HeaderT, JointStateT, JointTrajectoryT, NodeStatusT, TrajectoryStatusT,
};

/// The bridge's TOML configuration.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BridgeConfig {
    /// `sim` (fake drives in this process), `slcan:PATH` (a USB2CAN dongle), `lcm:NAME` (a
    /// CAN bus behind a stride-usb2can gateway) or `socketcan:IFACE` (with the feature).
    pub bus: BusSpec,
    /// CAN bit rate.
    pub bitrate: u32,
    /// Channel of incoming `stride.joint_trajectory_t`.
    pub trajectory_channel: String,
    /// Channel of outgoing `stride.joint_state_t`.
    pub state_channel: String,
    /// Channel of outgoing `stride.trajectory_status_t`.
    pub trajectory_status_channel: String,
    /// The system stop (`stride.gait_command_t` STOP and RESUME from the launcher or `stride
    /// estop`): STOP quick-stops every axis and refuses trajectories until RESUME.
    pub stop_channel: String,
    /// Joint state rate (and SYNC rate), Hz.
    pub state_rate_hz: f64,
    /// Joint state rate while no motion is queued or playing and every joint is still, Hz.
    pub idle_state_rate_hz: f64,
    /// Meanwhile the SYNC (and the bridge's heartbeat with it) goes every this many ms: at
    /// most half of drive_watchdog_ms, at least a period of state_rate_hz. A trajectory
    /// brings the full rate back at once (its join is checked against states at most five
    /// of these old).
    pub idle_sync_ms: u64,
    /// How far ahead of the drives' play rows are sent, ms: a trajectory replaces what is
    /// queued no sooner than this after it arrives, and a stream's next chunk has to arrive
    /// this long before the queued motion ends, or the joints stop.
    pub lookahead_ms: u64,
    /// The longest a trajectory may reach ahead of now, ms: the queue's bound.
    pub max_queue_ms: u64,
    /// The drives quick-stop on their own when the bridge's heartbeat stops for this long,
    /// ms (their consumer heartbeat time, 0x1016): a killed bridge, a pulled cable.
    pub drive_watchdog_ms: u64,
    /// Period of the bridge's own heartbeat on the bus, ms.
    pub heartbeat_ms: u64,
    /// The node id of the bridge's heartbeat (no drive's).
    pub master_node: u8,
    /// On shutdown, the longest to wait for the joints to stand still after the quick stop
    /// before the torque goes off, ms.
    pub stop_timeout_ms: u64,
    /// `pvt` (Elmo PVT tables, cubic), `pt` (Elmo PT tables: positions every `pt_period_ms`,
    /// cubic) or `ip` (CiA 402 interpolated position, linear, fixed period `ip_period_ms`).
    pub motion: String,
    /// The fixed set-point period in `ip` mode, ms.
    pub ip_period_ms: u8,
    /// The point period in `pt` mode, ms (a whole number of the drives' position-loop samples).
    pub pt_period_ms: u8,
    /// After a bus failure (bus-off, a dongle unplugged), the first attempt to bring the
    /// drives up again waits this long; each failed attempt doubles it, up to 10 s.
    pub recovery_delay_ms: u64,
    /// The joints.
    pub joint: Vec<JointConfig>,
}

impl Default for BridgeConfig {
    fn default() -> Self {
        BridgeConfig {
            bus: BusSpec::Sim,
            bitrate: 1_000_000,
            trajectory_channel: "JOINT_TRAJECTORY".into(),
            state_channel: "JOINT_STATE".into(),
            trajectory_status_channel: "JOINT_TRAJECTORY_STATUS".into(),
            stop_channel: "STRIDE_STOP".into(),
            state_rate_hz: 100.0,
            idle_state_rate_hz: 10.0,
            idle_sync_ms: 40,
            lookahead_ms: 100,
            max_queue_ms: 10_000,
            drive_watchdog_ms: 100,
            heartbeat_ms: 20,
            master_node: 127,
            stop_timeout_ms: 2000,
            motion: "pvt".into(),
            ip_period_ms: 10,
            pt_period_ms: 10,
            recovery_delay_ms: 500,
            joint: Vec::new(),
        }
    }
}

impl BridgeConfig {
    /// Checks what serde cannot: at least one joint, sane rates and times (the joints' own
    /// limits and units are checked by the master).
    pub fn check(&self) -> Result<(), String> {
        if self.joint.is_empty() {
            return Err(
                "the configuration lists no [[joint]] (give one with --config, e.g. \
                 config/robots/archie-left-leg.toml)"
                    .into(),
            );
        }
        self.motion()?;
        if !(1.0..=1000.0).contains(&self.state_rate_hz) {
            return Err(format!(
                "state_rate_hz {} outside 1..=1000",
                self.state_rate_hz
            ));
        }
        if !(self.idle_state_rate_hz > 0.0 && self.idle_state_rate_hz <= self.state_rate_hz) {
            return Err(format!(
                "idle_state_rate_hz {} outside (0, state_rate_hz]",
                self.idle_state_rate_hz
            ));
        }
        if (self.idle_sync_ms as f64) < 1000.0 / self.state_rate_hz - 1e-9
            || 2 * self.idle_sync_ms > self.drive_watchdog_ms
        {
            return Err(format!(
                "idle_sync_ms {} must be at least a period of state_rate_hz ({:.1} ms) and at most half of drive_watchdog_ms ({} ms)",
                self.idle_sync_ms,
                1000.0 / self.state_rate_hz,
                self.drive_watchdog_ms
            ));
        }
        if self.heartbeat_ms == 0 || self.drive_watchdog_ms < 2 * self.heartbeat_ms {
            return Err(format!(
                "drive_watchdog_ms {} must be at least two heartbeats ({} ms each)",
                self.drive_watchdog_ms, self.heartbeat_ms
            ));
        }
        if self.drive_watchdog_ms > u16::MAX as u64 {
            return Err("drive_watchdog_ms is at most 65535".into());
        }
        if self.max_queue_ms > 60_000 {
            return Err(format!(
                "max_queue_ms {} is more than a minute (60000): the queue's rows are sized by it",
                self.max_queue_ms
            ));
        }
        if self.lookahead_ms == 0 || self.max_queue_ms < self.lookahead_ms {
            return Err(format!(
                "lookahead_ms {} must be positive and max_queue_ms {} at least that",
                self.lookahead_ms, self.max_queue_ms
            ));
        }
        Ok(())
    }

    /// The motion mode the configuration asks for.
    pub fn motion(&self) -> Result<stride_elmo::Motion, String> {
        match self.motion.as_str() {
            "pvt" => Ok(stride_elmo::Motion::Pvt),
            "ip" if self.ip_period_ms > 0 => Ok(stride_elmo::Motion::InterpolatedPosition {
                period_ms: self.ip_period_ms,
            }),
            "pt" if self.pt_period_ms > 0 => Ok(stride_elmo::Motion::Pt {
                period_ms: self.pt_period_ms,
            }),
            other => Err(format!(
                "motion {other:?}: use \"pvt\", \"pt\" (with pt_period_ms 1..=255) or \"ip\" \
                 (with ip_period_ms 1..=255)"
            )),
        }
    }

    /// The master's settings.
    pub fn master(&self) -> Result<MasterConfig, String> {
        let ms = Duration::from_millis;
        Ok(MasterConfig {
            motion: self.motion()?,
            master_node: self.master_node,
            master_heartbeat: ms(self.heartbeat_ms),
            drive_watchdog: ms(self.drive_watchdog_ms),
            lookahead: ms(self.lookahead_ms),
            max_queue: ms(self.max_queue_ms),
            sync_period: Duration::from_secs_f64(1.0 / self.state_rate_hz),
            idle_sync_period: ms(self.idle_sync_ms),
            stop_timeout: ms(self.stop_timeout_ms),
            ..MasterConfig::default()
        })
    }
}

/// A `stride.joint_trajectory_t` as the master's trajectory: its mode (PT rows carry no
/// velocities) and queueing honoured, or refused.
pub fn trajectory_from_msg(m: &JointTrajectoryT) -> Result<Trajectory, String> {
    let velocities = match m.mode {
        JointTrajectoryT::MODE_PVT => m.velocities.clone(),
        JointTrajectoryT::MODE_PT => Vec::new(),
        other => {
            return Err(format!(
                "mode {other}: use {} (PT) or {} (PVT)",
                JointTrajectoryT::MODE_PT,
                JointTrajectoryT::MODE_PVT
            ))
        }
    };
    let start = match (m.queue, m.start_utime) {
        (JointTrajectoryT::QUEUE_REPLACE, 0) => Start::Now,
        (JointTrajectoryT::QUEUE_REPLACE, t) => Start::At(t),
        (JointTrajectoryT::QUEUE_APPEND, 0) => Start::Append,
        (JointTrajectoryT::QUEUE_APPEND, _) => {
            return Err("an appended trajectory starts where the queue ends: start_utime 0".into())
        }
        (other, _) => {
            return Err(format!(
                "queue {other}: use {} (replace) or {} (append)",
                JointTrajectoryT::QUEUE_REPLACE,
                JointTrajectoryT::QUEUE_APPEND
            ))
        }
    };
    Ok(Trajectory {
        joints: m.joint_names.clone(),
        times: m.time_from_start.clone(),
        positions: m.positions.clone(),
        velocities,
        start,
    })
}

/// The joint states as a `stride.joint_state_t` (current and temperature NaN: the state PDO
/// carries position and statusword; the velocity is the positions' change per SYNC; the
/// fault bit of the statusword per joint).
pub fn state_msg(states: &[(&str, stride_elmo::JointState)], header: HeaderT) -> JointStateT {
    let n = states.len();
    JointStateT {
        header,
        num_joints: n as i32,
        names: states.iter().map(|(name, _)| name.to_string()).collect(),
        positions: states.iter().map(|(_, s)| s.position).collect(),
        velocities: states.iter().map(|(_, s)| s.velocity).collect(),
        currents: vec![f64::NAN; n],
        temperatures: vec![f32::NAN; n],
        faults: states
            .iter()
            .map(|(_, s)| stride_canopen::ds402::fault_bit(s.statusword) as i32)
            .collect(),
    }
}

/// When to try bringing the drives up again after the bus failed: after a delay that doubles
/// with every failed attempt (up to 10 s), so a dongle plugged back in or a bus that recovers
/// from bus-off is picked up without flooding it.
#[derive(Debug, Clone)]
pub struct Recovery {
    first: Duration,
    delay: Duration,
    next: Option<Instant>,
}

impl Recovery {
    /// Longest wait between attempts.
    pub const MAX_DELAY: Duration = Duration::from_secs(10);

    /// A policy whose first retry comes `first_ms` after a failure.
    pub fn new(first_ms: u64) -> Recovery {
        let first = Duration::from_millis(first_ms.max(1));
        Recovery {
            first,
            delay: first,
            next: None,
        }
    }

    /// The bus failed (or an attempt to recover did): the next attempt is due after the
    /// current delay, which then doubles.
    pub fn failed(&mut self, now: Instant) {
        self.next = Some(now + self.delay);
        self.delay = (self.delay * 2).min(Self::MAX_DELAY);
    }

    /// True while the drives are to be considered down.
    pub fn pending(&self) -> bool {
        self.next.is_some()
    }

    /// When the next attempt is due (`None`: nothing to recover).
    pub fn next(&self) -> Option<Instant> {
        self.next
    }

    /// True when an attempt is due now.
    pub fn due(&self, now: Instant) -> bool {
        self.next.is_some_and(|t| now >= t)
    }

    /// The current delay between attempts.
    pub fn delay(&self) -> Duration {
        self.delay
    }

    /// The drives are up again: back to the first delay.
    pub fn succeeded(&mut self) {
        self.next = None;
        self.delay = self.first;
    }
}

/// What the bridge logs, each once, in one line; and the node's health it keeps.
pub use stride_node::{Health, Note};

/// How the bridge comes back from a stop, as its status and its heartbeat say.
pub const REARM: &str =
    "automatic: the next valid trajectory, starting where the joints stand, enables the drives again";

/// How the bridge comes back from the system stop.
pub const RESUME: &str =
    "stride resume, then a valid trajectory starting where the joints stand enables the drives again";

/// How the bridge comes back from a stream run dry.
pub const REARM_DRY: &str =
    "automatic: the next valid trajectory, starting where the joints come to rest, moves them again";

/// The bridge: the master, and what to do when.
pub struct Bridge<B: CanBus> {
    master: Master<B>,
    recovery: Recovery,
    /// The health, made from what the status says (see [`Bridge::condition`]).
    health: Health,
    /// The master's stop is a fault of the drives (an emergency, an underflow), not an order.
    fault: bool,
    /// The stream ran dry (a chunk ended in motion, none came in time): the joints
    /// decelerated to a stop; until the next trajectory is taken.
    dry: Option<String>,
    /// The last refusal, while no trajectory was taken since.
    refusal: Option<String>,
    /// Why the drives are down (bus, reset), while recovery runs.
    down: Option<String>,
    last_refusal: String,
    last_refused: i64,
    last_accepted: i64,
    /// Trajectories refused before the master saw them (a mode, the drives down).
    refused_here: u64,
    /// The system stop in force, and why.
    held: Option<String>,
    /// Something a status should say at once.
    changed: bool,
}

fn ok() -> Health {
    Health {
        state: NodeStatusT::STATE_RUNNING,
        detail: String::new(),
    }
}

impl<B: CanBus> Bridge<B> {
    /// A bridge around `master` (brought up).
    pub fn new(master: Master<B>, recovery_delay_ms: u64) -> Bridge<B> {
        Bridge {
            master,
            recovery: Recovery::new(recovery_delay_ms),
            health: ok(),
            fault: false,
            dry: None,
            refusal: None,
            down: None,
            last_refusal: String::new(),
            last_refused: -1,
            last_accepted: -1,
            refused_here: 0,
            held: None,
            changed: true,
        }
    }

    /// The system stop: every axis quick-stops (decelerating within its limits) and holds;
    /// trajectories are refused until [`Bridge::resume`].
    pub fn system_stop(&mut self, why: &str) -> Vec<Note> {
        let mut notes = Vec::new();
        if self.held.is_none() {
            self.held = Some(why.to_owned());
            if self.down.is_none() {
                self.stop(format!("system stop ({why})"), false, &mut notes);
            }
            self.update();
        }
        notes
    }

    /// The system stop lifted: the next valid trajectory enables the drives again.
    pub fn resume(&mut self) -> Vec<Note> {
        match self.held.take() {
            Some(_) => {
                self.changed = true;
                self.update();
                vec![Note::Info("system stop lifted".into())]
            }
            None => Vec::new(),
        }
    }

    /// The master.
    pub fn master(&self) -> &Master<B> {
        &self.master
    }

    /// The node's health now.
    pub fn health(&self) -> &Health {
        &self.health
    }

    /// When the bridge next has something to do.
    pub fn next_wake(&self) -> Instant {
        // While the drives are down the master is not pumped: the next attempt is what comes.
        self.recovery
            .next()
            .unwrap_or_else(|| self.master.next_wake())
    }

    /// What the status and the heartbeat both say: the status's state, reason and recovery,
    /// and the heartbeat's state (their words are the same).
    fn condition(&self) -> (i8, String, String, i8) {
        let s = self.master.status();
        let (stopped, moving, idle) = (
            TrajectoryStatusT::STATE_STOPPED,
            TrajectoryStatusT::STATE_MOVING,
            TrajectoryStatusT::STATE_IDLE,
        );
        let (fault, degraded) = (NodeStatusT::STATE_FAULT, NodeStatusT::STATE_DEGRADED);
        if let Some(why) = &self.down {
            let recovery = format!(
                "automatic: the drives are brought up again when they answer (next try \
                 within {:.1} s)",
                self.recovery.delay().as_secs_f64()
            );
            return (
                TrajectoryStatusT::STATE_RECOVERING,
                why.clone(),
                recovery,
                fault,
            );
        }
        if let Some(why) = &self.held {
            let reason = format!("system stop ({why}): every axis quick-stopped and held");
            return (stopped, reason, RESUME.into(), degraded);
        }
        if let Some(why) = &s.stopped {
            let state = if self.fault { fault } else { degraded };
            return (
                stopped,
                format!("{why}: quick-stopped"),
                REARM.into(),
                state,
            );
        }
        if let Some(why) = &self.dry {
            return (stopped, why.clone(), REARM_DRY.into(), degraded);
        }
        let state = if s.queued_until.is_some() || !self.master.idle() {
            moving
        } else {
            idle
        };
        let health = if self.refusal.is_some() {
            degraded
        } else {
            NodeStatusT::STATE_RUNNING
        };
        (state, String::new(), String::new(), health)
    }

    /// Makes the health from the condition; a change is published at once.
    fn update(&mut self) {
        let (_, reason, recovery, state) = self.condition();
        let detail = match (reason.is_empty(), recovery.is_empty()) {
            (true, _) => self.refusal.clone().unwrap_or_default(),
            (false, true) => reason,
            (false, false) => format!("{reason}; {recovery}"),
        };
        let detail = if state == NodeStatusT::STATE_RUNNING {
            String::new()
        } else {
            detail
        };
        if self.health.state != state || self.health.detail != detail {
            self.health = Health { state, detail };
            self.changed = true;
        }
    }

    /// A trajectory from the bus: converted, checked and queued, or refused whole (the
    /// reason in the health and the status, counted).
    pub fn on_trajectory(&mut self, m: &JointTrajectoryT, now: Instant) -> Vec<Note> {
        if let Some(why) = &self.held {
            let e = format!("trajectory refused: system stop ({why}) until resumed");
            self.refused_here += 1;
            self.refused(m, e.clone());
            return vec![Note::Warn(e)];
        }
        if let Some(why) = &self.down {
            let e = format!("trajectory refused: the drives are down ({why})");
            self.refused_here += 1;
            self.refused(m, e.clone());
            return vec![Note::Warn(e)];
        }
        let t = match trajectory_from_msg(m) {
            Ok(t) => t,
            Err(e) => {
                let e = format!("trajectory refused: {e}");
                self.refused_here += 1;
                self.refused(m, e.clone());
                return vec![Note::Warn(e)];
            }
        };
        match self.master.load(&t, now) {
            Ok(a) => {
                self.last_accepted = m.header.sequence;
                self.refusal = None;
                self.dry = None;
                if a.rearmed {
                    self.fault = false;
                }
                self.changed = true;
                self.update();
                if a.rearmed {
                    vec![Note::Info("drives enabled again".into())]
                } else {
                    Vec::new()
                }
            }
            Err(e) => {
                let e = format!("trajectory refused: {e}");
                self.refused(m, e.clone());
                vec![Note::Warn(e)]
            }
        }
    }

    fn refused(&mut self, m: &JointTrajectoryT, why: String) {
        self.last_refusal = why.clone();
        self.last_refused = m.header.sequence;
        self.refusal = Some(why);
        self.changed = true;
        self.update();
    }

    /// Stops every axis for `why` (the drives stay stopped until the next valid trajectory);
    /// `fault`: a fault of the drives, not an order.
    fn stop(&mut self, why: String, fault: bool, notes: &mut Vec<Note>) {
        for e in self.master.quick_stop(&why) {
            notes.push(Note::Error(format!("quick stop: {e}")));
        }
        notes.push(Note::Error(format!("{why}: every axis quick-stopped")));
        self.fault = fault;
        self.dry = None;
        self.update();
    }

    /// The bus or a drive is down for `why`: recovery runs, first after its delay from now
    /// (after the stop, which may have waited on silent drives).
    fn go_down(&mut self, why: String) {
        self.recovery.failed(self.master.now());
        self.down = Some(why);
        self.update();
    }

    /// One cycle: recovery when due, the master's pump, and what its events mean.
    pub fn tick(&mut self, now: Instant) -> Vec<Note> {
        let mut notes = Vec::new();
        if self.recovery.pending() {
            if !self.recovery.due(now) {
                return notes;
            }
            match self.master.recover() {
                Ok(()) => {
                    self.recovery.succeeded();
                    self.down = None;
                    self.refusal = None;
                    notes.push(Note::Info("drives up again".into()));
                    self.update();
                }
                Err(e) => {
                    self.recovery.failed(self.master.now());
                    notes.push(Note::Warn(format!("drives still down: {e}")));
                    self.update();
                    return notes;
                }
            }
        }
        if let Err(e) = self.master.pump(now) {
            // Bus-off or a dead interface: the drives stop on their own without the
            // bridge's heartbeat; they are brought up again once the bus answers.
            notes.push(Note::Error(format!("CAN cycle failed: {e}")));
            self.go_down(format!("CAN: {e}"));
            return notes;
        }
        for e in self.master.take_events() {
            match e {
                Event::Emergency { joint, text, emcy } => {
                    let why = format!("{joint}: emergency {:#06x} ({text})", emcy.code);
                    self.stop(why, true, &mut notes);
                }
                Event::Underflow { joint } => {
                    let why = format!("{joint} ran out of rows while moving");
                    self.stop(why, true, &mut notes);
                }
                Event::InterpreterError {
                    joint,
                    command,
                    code,
                } => {
                    let why = format!("{joint}: the drive refused {command} (error {code})");
                    self.stop(why, true, &mut notes);
                }
                Event::HeartbeatLost { joint } => {
                    let why = format!("{joint}: heartbeat lost");
                    self.stop(why.clone(), true, &mut notes);
                    self.go_down(why);
                }
                Event::Rebooted { joint } => {
                    let why = format!("{joint}: drive reset");
                    self.stop(why.clone(), true, &mut notes);
                    self.go_down(why);
                }
                Event::EndUnreported { joint } => notes.push(Note::Warn(format!(
                    "{joint}: the drive did not report the end of its last motion; the next \
                     one went ahead"
                ))),
                Event::StreamStopped { joints } => {
                    let why = format!(
                        "trajectory stream ran dry: {} decelerating to a stop",
                        joints.join(", ")
                    );
                    notes.push(Note::Warn(why.clone()));
                    self.dry = Some(why);
                    self.changed = true;
                }
            }
        }
        // The health follows what the status says (a motion that ended, an idle master).
        self.update();
        notes
    }

    /// True while no motion is queued or playing and every joint is still (below 0.01 rad/s):
    /// the joint states may go out at the idle rate.
    pub fn still(&self) -> bool {
        self.master.resting()
    }

    /// The joint states.
    pub fn states(&self, header: HeaderT) -> JointStateT {
        state_msg(&self.master.states(), header)
    }

    /// True once when a status should go out at once.
    pub fn take_changed(&mut self) -> bool {
        std::mem::take(&mut self.changed)
    }

    /// The trajectory status.
    pub fn status(&self, header: HeaderT, node: &str) -> TrajectoryStatusT {
        let s = self.master.status();
        let c = s.counters;
        let (state, reason, recovery, _) = self.condition();
        let (now, utime) = (self.master.now(), self.master.utime());
        let wall = |t: Instant| utime + t.saturating_duration_since(now).as_micros() as i64;
        TrajectoryStatusT {
            header,
            node: node.to_owned(),
            state,
            reason,
            recovery,
            queued_until_utime: s.queued_until.map_or(0, wall),
            accepted: c.accepted as i64,
            refused: (c.refused + self.refused_here) as i64,
            replaced_rows: c.replaced_rows as i64,
            dropped_rows: c.dropped_rows as i64,
            stream_stops: c.stream_stops as i64,
            underflows: c.underflows as i64,
            rearms: c.rearms as i64,
            last_refusal: self.last_refusal.clone(),
            last_refused_sequence: self.last_refused,
            last_accepted_sequence: self.last_accepted,
            dropped: 0,
        }
    }

    /// The shutdown: decelerate, wait for standstill, then the torque off.
    pub fn shutdown(&mut self) -> stride_elmo::Shutdown {
        self.master.shutdown()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_config_parses_and_checks() {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/robots/archie-left-leg.toml"
        ))
        .unwrap();
        let cfg: BridgeConfig = toml::from_str(&text).unwrap();
        cfg.check().unwrap();
        assert_eq!(cfg.joint.len(), 6);
        assert_eq!(cfg.joint[3].name, "left_knee");
        assert!(BridgeConfig::default()
            .check()
            .unwrap_err()
            .contains("--config"));
        let mut bad = cfg.clone();
        bad.drive_watchdog_ms = 10;
        assert!(bad.check().is_err());
        // Resting, the heartbeat goes with the SYNC: at most half of the drives' watchdog.
        let mut bad = cfg.clone();
        bad.idle_sync_ms = bad.drive_watchdog_ms / 2 + 1;
        assert!(bad.check().unwrap_err().contains("idle_sync_ms"));
        let mut bad = cfg.clone();
        bad.idle_sync_ms = 5;
        assert!(bad.check().unwrap_err().contains("idle_sync_ms"));
    }

    #[test]
    fn recovery_backs_off_and_resets() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut r = Recovery::new(100);
        assert!(!r.pending() && !r.due(t0));
        r.failed(t0);
        assert!(r.pending() && !r.due(t0 + ms(99)) && r.due(t0 + ms(100)));
        // Each failed attempt doubles the wait, up to the ceiling.
        r.failed(t0 + ms(100));
        assert!(!r.due(t0 + ms(299)) && r.due(t0 + ms(300)));
        for _ in 0..10 {
            r.failed(t0);
        }
        assert!(!r.due(t0 + ms(9999)) && r.due(t0 + Recovery::MAX_DELAY));
        r.succeeded();
        assert!(!r.pending());
        r.failed(t0);
        assert!(r.due(t0 + ms(100)));
    }

    fn msg(mode: i8, queue: i8, start: i64) -> JointTrajectoryT {
        JointTrajectoryT {
            mode,
            queue,
            start_utime: start,
            num_joints: 1,
            joint_names: vec!["a".into()],
            num_rows: 2,
            time_from_start: vec![0.0, 0.01],
            positions: vec![vec![0.0], vec![0.1]],
            velocities: vec![vec![0.0], vec![0.0]],
            ..Default::default()
        }
    }

    #[test]
    fn every_mode_and_queue_value_is_honoured_or_refused() {
        let pt = trajectory_from_msg(&msg(JointTrajectoryT::MODE_PT, 0, 0)).unwrap();
        assert!(pt.velocities.is_empty());
        assert_eq!(pt.start, Start::Now);
        let pvt = trajectory_from_msg(&msg(JointTrajectoryT::MODE_PVT, 0, 5)).unwrap();
        assert_eq!((pvt.velocities.len(), pvt.start), (2, Start::At(5)));
        let app = trajectory_from_msg(&msg(1, JointTrajectoryT::QUEUE_APPEND, 0)).unwrap();
        assert_eq!(app.start, Start::Append);
        // Mode 7 was played as PT: now it is refused, as are unknown queue values.
        assert!(trajectory_from_msg(&msg(7, 0, 0))
            .unwrap_err()
            .contains("mode 7"));
        assert!(trajectory_from_msg(&msg(1, 9, 0))
            .unwrap_err()
            .contains("queue 9"));
        assert!(trajectory_from_msg(&msg(1, 1, 5)).is_err());
    }

    #[test]
    fn a_bridge_whose_drives_are_down_sleeps_until_its_next_attempt() {
        use std::sync::atomic::Ordering;
        use stride_fakes::elmo::{ElmoConfig, FakeElmo, Levers};
        let bus = stride_canbus::MemBus::modelled(1_000_000);
        let levers = Levers::default();
        bus.attach(
            FakeElmo::new(ElmoConfig::new(1), levers.clone()),
            Duration::from_millis(1),
        );
        let cfg: BridgeConfig = toml::from_str(
            &std::fs::read_to_string(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../config/robots/archie-left-leg.toml"
            ))
            .unwrap(),
        )
        .unwrap();
        let joint = cfg.joint[0].clone();
        let mut master = Master::new(bus.node(), vec![joint], MasterConfig::default()).unwrap();
        master.bring_up().unwrap();
        let mut b = Bridge::new(master, 500);
        // The drive dies: its heartbeat stops, the bridge goes down and waits to recover.
        levers.silent.store(true, Ordering::Relaxed);
        let t0 = bus.now();
        while b.health().state != NodeStatusT::STATE_FAULT {
            assert!(
                bus.now() - t0 < Duration::from_secs(3),
                "no fault: {:?}",
                b.health()
            );
            b.tick(bus.now());
            bus.advance_to(bus.now() + Duration::from_millis(1));
        }
        // Its next wake is the attempt, not a SYNC that is never sent while it is down.
        let now = bus.now();
        assert!(
            b.next_wake() > now + Duration::from_millis(400),
            "{:?} {:?}",
            b.next_wake().checked_duration_since(now),
            b.health()
        );
    }

    /// D3 of the reliability findings: a bridge's heartbeat said "quick-stopped; automatic:
    /// the next valid trajectory enables the drives again" while its trajectory status said
    /// "stride resume, then a valid trajectory". Both say the same thing now, from one place.
    #[test]
    fn a_bridges_heartbeat_and_trajectory_status_say_the_same_of_how_it_comes_back() {
        use stride_fakes::elmo::{ElmoConfig, FakeElmo, Levers};
        let bus = stride_canbus::MemBus::modelled(1_000_000);
        bus.attach(
            FakeElmo::new(ElmoConfig::new(1), Levers::default()),
            Duration::from_millis(1),
        );
        let cfg: BridgeConfig = toml::from_str(
            &std::fs::read_to_string(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../config/robots/archie-left-leg.toml"
            ))
            .unwrap(),
        )
        .unwrap();
        let mut master = Master::new(
            bus.node(),
            vec![cfg.joint[0].clone()],
            MasterConfig::default(),
        )
        .unwrap();
        master.bring_up().unwrap();
        let mut b = Bridge::new(master, 500);
        let said = |b: &Bridge<_>| {
            let s = b.status(HeaderT::default(), "left-leg");
            (s.state, s.reason, s.recovery, b.health().clone())
        };
        b.system_stop("operator");
        let (state, reason, recovery, health) = said(&b);
        assert_eq!(state, TrajectoryStatusT::STATE_STOPPED);
        assert_eq!(recovery, RESUME);
        assert_eq!(
            health.state,
            NodeStatusT::STATE_DEGRADED,
            "an order, not a fault"
        );
        assert_eq!(health.detail, format!("{reason}; {recovery}"));
        b.resume();
        b.tick(bus.now());
        let (state, reason, recovery, health) = said(&b);
        assert_eq!(state, TrajectoryStatusT::STATE_STOPPED);
        assert_eq!(recovery, REARM);
        assert_eq!(health.detail, format!("{reason}; {recovery}"));
    }

    #[test]
    fn states_carry_the_fault_bit_and_the_velocity() {
        let s = state_msg(
            &[(
                "a",
                stride_elmo::JointState {
                    position: 0.5,
                    velocity: 0.25,
                    statusword: 0x0218,
                    updated: None,
                },
            )],
            HeaderT::default(),
        );
        assert_eq!(
            (s.positions[0], s.velocities[0], s.faults[0]),
            (0.5, 0.25, 1)
        );
    }
}
