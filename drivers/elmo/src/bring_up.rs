//! Bringing the drives up and taking them down: identity, heartbeats both ways (the drives
//! watch the master's, and stop on their own without it), the PDO mapping written and
//! verified, the table set up, CiA 402 enable; the quick stop, the enable again after it,
//! recovery after a bus failure or a reset, and the shutdown that decelerates before the
//! torque goes off.

use std::time::{Duration, Instant};

use stride_canbus::CanBus;
use stride_canopen::ds402::{self, AbortConnection, State as DriveState};
use stride_canopen::elmo::{Command as Interp, PvtQueue, Value};
use stride_canopen::heartbeat::{self, ConsumerEntry};
use stride_canopen::nmt::{self, ErrorBehaviour};

use crate::config::Motion;
use crate::error::MasterError;
use crate::master::{controlword_rpdo, setpoint_rpdo, state_tpdo, Master};

/// How a shutdown went.
#[derive(Debug, Clone, PartialEq)]
pub struct Shutdown {
    /// The joints stood still before the torque went off (otherwise the wait timed out).
    pub standstill: bool,
    /// How long the deceleration took.
    pub stopping: Duration,
    /// Drives that did not answer or refused, each with its error; the others were still
    /// stopped and disabled.
    pub failed: Vec<MasterError>,
}

impl<B: CanBus> Master<B> {
    /// Brings every drive up: identity (CiA 402 device), heartbeats (the drive's own, and its
    /// watch on the master's: without it for the configured time, the drive quick-stops and
    /// goes pre-operational), following-error window and quick-stop deceleration from the
    /// joint's tolerance and acceleration limit, PDO mapping written and verified, NMT
    /// operational, table set up, CiA 402 operation enabled with the motor on.
    pub fn bring_up(&mut self) -> Result<(), MasterError> {
        for a in 0..self.track.axes.len() {
            self.bring_up_axis(a)?;
        }
        self.wait_states()
    }

    /// Keeps the SYNCs going until every drive has reported where its joint stands: a
    /// motion starts from there.
    fn wait_states(&mut self) -> Result<(), MasterError> {
        let since = self.bus.now();
        let deadline = since + self.cfg.sdo_timeout * 5;
        loop {
            let now = self.bus.now();
            self.pump_states(now)?;
            let missing = self
                .track
                .axes
                .iter()
                .position(|a| a.state.updated.is_none_or(|u| u < since));
            let Some(a) = missing else {
                // Heard from at bring-up: a drive whose heartbeat never comes is lost too.
                for ax in &mut self.track.axes {
                    ax.last_heartbeat.get_or_insert(now);
                }
                return Ok(());
            };
            if now >= deadline {
                let ax = &self.track.axes[a];
                return Err(MasterError::NoAnswer {
                    joint: ax.cfg.name.clone(),
                    node: ax.node.get(),
                    what: "the SYNC (no state PDO)".into(),
                });
            }
            self.bus
                .wait_until(now + std::time::Duration::from_millis(1));
        }
    }

    fn bring_up_axis(&mut self, a: usize) -> Result<(), MasterError> {
        let (name, node) = {
            let ax = &self.track.axes[a];
            (ax.cfg.name.clone(), ax.node)
        };
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
        let hb = self.cfg.heartbeat.as_millis().min(u16::MAX as u128) as u16;
        self.write(a, heartbeat::PRODUCER_TIME, 0, hb.to_le_bytes().to_vec())?;
        // The drive watches the master: without its heartbeat it stops on its own.
        let watch = ConsumerEntry {
            node: self.cfg.master_node,
            time_ms: self
                .cfg
                .drive_watchdog
                .as_millis()
                .clamp(1, u16::MAX as u128) as u16,
        };
        self.write(
            a,
            nmt::ERROR_BEHAVIOUR,
            1,
            vec![ErrorBehaviour::PreOperational.code()],
        )?;
        self.write(
            a,
            ds402::ABORT_CONNECTION_OPTION,
            0,
            AbortConnection::QuickStop.code().to_le_bytes().to_vec(),
        )?;
        self.write(
            a,
            heartbeat::CONSUMER_TIME,
            1,
            watch.to_u32().to_le_bytes().to_vec(),
        )?;
        let (window, decel) = {
            let ax = &self.track.axes[a];
            // Both were shown to fit when the master was made; never a stand-in value.
            let field = |x: f64, f| {
                ax.units.magnitude(x, f).map_err(|e| MasterError::Setup {
                    joint: ax.cfg.name.clone(),
                    node: ax.node.get(),
                    what: format!("{f}: {e}"),
                })
            };
            (
                field(ax.cfg.tolerance, "0x6065")?,
                field(ax.cfg.max_acceleration, "0x6085")?,
            )
        };
        self.write(
            a,
            ds402::FOLLOWING_ERROR_WINDOW,
            0,
            window.to_le_bytes().to_vec(),
        )?;
        self.write(
            a,
            ds402::QUICK_STOP_DECELERATION,
            0,
            decel.to_le_bytes().to_vec(),
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
        for pdo in [
            controlword_rpdo(),
            setpoint_rpdo(self.cfg.motion),
            state_tpdo(),
        ] {
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
        self.bus.send(
            &nmt::encode(nmt::Command::Start, node.get()),
            self.deadline(),
        )?;
        self.setup_table(a)?;
        self.enable(a)?;
        let ax = &mut self.track.axes[a];
        ax.up = true;
        ax.drop_motion(self.cfg.motion);
        Ok(())
    }

    pub(crate) fn deadline(&self) -> Instant {
        self.bus.now() + self.cfg.sdo_timeout
    }

    /// Sets up the drive's table for tabulated motion (PVT, PT): rows `1..=N` as a ring
    /// (`MP[1..3]`), the PT period in position-loop samples (`MP[4]`, from the drive's `TS`),
    /// and the write pointer at row 1 (`MP[6]`), so the master's count of rows matches the
    /// drive's.
    pub(crate) fn setup_table(&mut self, a: usize) -> Result<(), MasterError> {
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
                    let ax = &self.track.axes[a];
                    return Err(MasterError::Setup {
                        joint: ax.cfg.name.clone(),
                        node: ax.node.get(),
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
        self.track.axes[a].queue = PvtQueue::new(rows);
        Ok(())
    }

    /// Walks axis `a`'s drive to operation enabled (a fault through its reset).
    pub(crate) fn enable(&mut self, a: usize) -> Result<(), MasterError> {
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
            let ax = &self.track.axes[a];
            Err(MasterError::Enable {
                joint: ax.cfg.name.clone(),
                node: ax.node.get(),
                state,
                doing: "enabling",
            })
        }
    }

    /// Forgets every row not yet played and what the drives were doing, then brings every
    /// drive up again (after a bus-off, a drive reset or a fault): a motion cut off is not
    /// resumed.
    pub fn recover(&mut self) -> Result<(), MasterError> {
        let motion = self.cfg.motion;
        self.starts.clear();
        for ax in &mut self.track.axes {
            self.counters.dropped_rows += ax.drop_motion(motion) as u64;
            ax.heartbeat_lost = false;
            ax.last_heartbeat = None;
            ax.up = false;
        }
        self.bring_up()?;
        self.stopped = None;
        Ok(())
    }

    /// After a stop: every drive enabled again (a fault reset first where one faulted) with
    /// its table set up afresh, holding where its joint stands.
    pub(crate) fn rearm(&mut self) -> Result<(), MasterError> {
        self.starts.clear();
        for a in 0..self.track.axes.len() {
            self.enable(a)?;
            self.setup_table(a)?;
            let motion = self.cfg.motion;
            self.track.axes[a].drop_motion(motion);
        }
        self.stopped = None;
        self.counters.rearms += 1;
        Ok(())
    }

    /// Quick stop on every drive at once (the controlword 0x0002 by PDO): each decelerates
    /// at its quick-stop deceleration, then holds. Each drive's state is then checked by
    /// SDO, and one that did not stop is sent the quick stop by SDO; the drives that cannot
    /// be stopped are reported, and the others stopped all the same. The drives stay stopped
    /// until the next valid trajectory (or [`Master::recover`]) enables them again.
    pub fn quick_stop(&mut self, why: &str) -> Vec<MasterError> {
        let motion = self.cfg.motion;
        let cw = ds402::Command::QuickStop.controlword();
        let mut failed = Vec::new();
        self.starts.clear();
        for a in 0..self.track.axes.len() {
            let ax = &mut self.track.axes[a];
            self.counters.dropped_rows += ax.drop_motion(motion) as u64;
            let f = ds402::controlword_frame(controlword_rpdo().cob_id(ax.node), cw);
            if let Err(e) = self.bus.send(&f, self.bus.now() + self.cfg.sdo_timeout) {
                failed.push(MasterError::Bus(e));
            }
        }
        for a in 0..self.track.axes.len() {
            let state = self.statusword(a).map(DriveState::from_statusword);
            let stopped = matches!(
                state,
                Ok(DriveState::QuickStopActive
                    | DriveState::SwitchOnDisabled
                    | DriveState::ReadyToSwitchOn
                    | DriveState::SwitchedOn
                    | DriveState::Fault
                    | DriveState::FaultReactionActive)
            );
            if stopped {
                continue;
            }
            if let Err(e) = self.write(a, ds402::CONTROLWORD, 0, cw.to_le_bytes().to_vec()) {
                failed.push(e);
            }
        }
        if self.stopped.is_none() {
            self.stopped = Some(why.to_owned());
        }
        failed
    }

    /// Disables every drive (torque off), going on past one that does not answer, then
    /// stops the nodes' PDOs (NMT pre-operational). Returns the drives that failed.
    pub fn disable(&mut self) -> Vec<MasterError> {
        let mut failed = Vec::new();
        let cw = ds402::Command::DisableVoltage.controlword();
        for a in 0..self.track.axes.len() {
            if let Err(e) = self.write(a, ds402::CONTROLWORD, 0, cw.to_le_bytes().to_vec()) {
                failed.push(e);
            }
        }
        if let Err(e) = self.bus.send(
            &nmt::encode(nmt::Command::EnterPreOperational, 0),
            self.deadline(),
        ) {
            failed.push(MasterError::Bus(e));
        }
        failed
    }

    /// The shutdown: a quick stop, the joints' deceleration watched until they stand still
    /// (or `stop_timeout`), then the torque off ([`Master::disable`]).
    pub fn shutdown(&mut self) -> Shutdown {
        let t0 = self.bus.now();
        let mut failed = self.quick_stop("shutting down");
        let standstill = self.wait_standstill(t0 + self.cfg.stop_timeout);
        let stopping = self.bus.now() - t0;
        failed.extend(self.disable());
        // The last frames must reach the bus (a gateway's batch).
        let _ = self.bus.try_recv();
        Shutdown {
            standstill,
            stopping,
            failed,
        }
    }

    /// Keeps the states coming (SYNC, heartbeats) until every joint stands still for three
    /// SYNCs, or `deadline`.
    fn wait_standstill(&mut self, deadline: Instant) -> bool {
        let mut still = 0;
        let mut last = None;
        while self.bus.now() < deadline {
            let now = self.bus.now();
            if self.pump_states(now).is_err() {
                return false;
            }
            let fresh: Vec<_> = self.track.axes.iter().map(|a| a.state.updated).collect();
            if last.as_ref() != Some(&fresh) {
                last = Some(fresh);
                let resting = self.track.axes.iter().all(|a| {
                    a.state.velocity.abs() <= a.still_speed(self.cfg.sync_period)
                        || !DriveState::from_statusword(a.state.statusword).torque()
                });
                still = if resting { still + 1 } else { 0 };
                if still >= 3 {
                    return true;
                }
            }
            self.bus.wait_until(now + Duration::from_millis(1));
        }
        false
    }
}
