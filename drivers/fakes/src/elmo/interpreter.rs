//! The fake drive's binary interpreter on PDO2 (RPDO2 in, TPDO2 back): `MO`, `PX`, `TS`,
//! `MP[1..6]`, `PV`, `PT`, `BG`, with Elmo-like error codes.

use std::time::Instant;

use stride_canbus::CanFrame;
use stride_canopen::ds402::{self, State as DriveState};
use stride_canopen::elmo::{Command as Interp, Reply, Value};
use stride_canopen::frame::{CobId, Function};

use super::motion::Kind;
use super::table::ERR_OUT_OF_RANGE;
use super::FakeElmo;

// Interpreter error codes of this fake (a real drive's `EC` list numbers them its own way).
/// Unknown command.
pub(super) const ERR_UNKNOWN: u32 = 2;
/// `BG` with no rows to play.
pub(super) const ERR_EMPTY: u32 = 7;
/// `BG` while the motor is off.
pub(super) const ERR_MOTOR_OFF: u32 = 21;
/// `BG` with no tabulated motion armed (`PV=n` or `PT=n` first).
pub(super) const ERR_NO_MODE: u32 = 23;
/// A motion parameter changed while a motion plays.
pub(super) const ERR_MOVING: u32 = 24;
/// `TS` changed while the motor is on.
pub(super) const ERR_MOTOR_ON: u32 = 25;
/// An array index outside the command's range.
pub(super) const ERR_BAD_INDEX: u32 = 26;

impl FakeElmo {
    pub(super) fn on_interpreter(&mut self, data: &[u8], now: Instant) {
        let Ok(cmd) = Interp::decode(data) else {
            return;
        };
        let value = |v: Option<Value>| match v {
            Some(Value::Int(i)) => i,
            Some(Value::Float(f)) => f as i32,
            None => 0,
        };
        let moving = self.motor.motion.is_some();
        let result: Result<Value, u32> = match (&cmd.name, cmd.value) {
            (b"MO", None) => Ok(Value::Int(self.motor.on as i32)),
            (b"MO", Some(v)) => {
                let on = value(Some(v)) == 1;
                // MO=1 walks the drive to operation enabled, MO=0 disables it.
                let target = if on {
                    DriveState::OperationEnabled
                } else {
                    DriveState::ReadyToSwitchOn
                };
                for _ in 0..3 {
                    if self.drive == target {
                        break;
                    }
                    let fallback = if on { 0x000f } else { 0x0006 };
                    let c = ds402::step_towards(self.drive, target)
                        .map_or(fallback, |c| c.controlword());
                    let _ = self.write_object(ds402::CONTROLWORD, 0, &c.to_le_bytes(), now);
                }
                Ok(Value::Int(self.motor.on as i32))
            }
            (b"PX", None) => Ok(Value::Int(self.motor.actual.round() as i32)),
            (b"TS", None) => Ok(Value::Int(self.motor.ts_us as i32)),
            (b"TS", Some(_)) if self.motor.on => Err(ERR_MOTOR_ON),
            (b"TS", Some(v)) => match value(Some(v)) {
                t @ 25..=1000 => {
                    self.motor.ts_us = t as u32;
                    Ok(Value::Int(t))
                }
                _ => Err(ERR_OUT_OF_RANGE),
            },
            (b"MP", _) if !(1..=6).contains(&cmd.index) => Err(ERR_BAD_INDEX),
            (b"MP", None) => Ok(Value::Int(self.table.mp[cmd.index as usize])),
            (b"MP", Some(_)) if moving => Err(ERR_MOVING),
            (b"MP", Some(v)) => {
                let v = value(Some(v));
                let r = self
                    .table
                    .set_mp(cmd.index as usize, v)
                    .map(|()| Value::Int(v));
                self.update_pointers();
                r
            }
            (b"PV", None) | (b"PT", None) => {
                Ok(Value::Int(self.table.index_of(self.table.executed) as i32))
            }
            (b"PV", Some(_)) | (b"PT", Some(_)) if moving => Err(ERR_MOVING),
            (b"PV", Some(_)) if self.table.mp[2] > self.table.pvt_rows() as i32 => {
                Err(ERR_OUT_OF_RANGE)
            }
            (name @ (b"PV" | b"PT"), Some(v)) => {
                let n = value(Some(v));
                let r = self.table.set_read_pointer(n).map(|()| {
                    self.motor.armed = Some(if name == b"PV" { Kind::Pvt } else { Kind::Pt });
                    Value::Int(n)
                });
                self.update_pointers();
                r
            }
            (b"BG", _) => {
                if self.drive != DriveState::OperationEnabled {
                    Err(ERR_MOTOR_OFF)
                } else if let Some(kind) = self.motor.armed {
                    if self.table.pending() < 2 {
                        Err(ERR_EMPTY)
                    } else {
                        self.begin_motion(kind, now);
                        Ok(Value::Int(0))
                    }
                } else {
                    Err(ERR_NO_MODE)
                }
            }
            _ => Err(ERR_UNKNOWN),
        };
        let reply = Reply {
            name: cmd.name,
            index: cmd.index,
            result,
        };
        if let Ok(f) = CanFrame::standard(
            CobId::of(Function::Tpdo(2), self.cfg.node).raw(),
            &reply.bytes(),
        ) {
            self.send(f);
        }
    }
}
