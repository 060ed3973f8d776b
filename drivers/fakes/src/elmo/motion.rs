//! What the fake drive's motor does: tabulated motion (cubic interpolation; linear in
//! interpolated position), profile position, the quick stop at 0x6085, a first-order lag
//! behind the command, following-error faults, and the statusword that reports it all.

use std::sync::atomic::Ordering;
use std::time::Instant;

use stride_canopen::ds402::{self, State as DriveState};
use stride_canopen::elmo::{READ_POINTER, WRITE_POINTER};
use stride_canopen::emcy::{ElmoEmcy, Emcy};

use super::FakeElmo;

/// The kinds of tabulated motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    /// Elmo PVT (0x2001 rows, `PV=n`).
    Pvt,
    /// Elmo PT (0x2002 points, `PT=n`).
    Pt,
    /// CiA 402 interpolated position (0x60C1 set-points, controlword bit 4), linear.
    Ip,
}

/// The segment being played: a cubic from (p0, v0) to (p1, v1), or a line.
#[derive(Debug, Clone, Copy)]
pub(super) struct Segment {
    p0: f64,
    v0: f64,
    p1: f64,
    v1: f64,
    /// Seconds the segment lasts.
    duration: f64,
    elapsed: f64,
    linear: bool,
}

impl Segment {
    /// The position at the elapsed time: cubic Hermite (slopes in counts/s), or a line.
    fn position(&self) -> f64 {
        let s = (self.elapsed / self.duration).clamp(0.0, 1.0);
        let (p0, p1) = (self.p0, self.p1);
        if self.linear {
            return p0 + (p1 - p0) * s;
        }
        let (m0, m1) = (self.v0 * self.duration, self.v1 * self.duration);
        let s2 = s * s;
        let s3 = s2 * s;
        (2.0 * s3 - 3.0 * s2 + 1.0) * p0
            + (s3 - 2.0 * s2 + s) * m0
            + (-2.0 * s3 + 3.0 * s2) * p1
            + (s3 - s2) * m1
    }
}

/// A profile-position move: a trapezoid (or triangle) of velocity from `from` to `to`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Profile {
    pub from: f64,
    pub to: f64,
    /// Cruise velocity, acceleration and deceleration (counts/s, counts/s²), positive.
    pub v: f64,
    pub a: f64,
    pub d: f64,
    pub elapsed: f64,
}

impl Profile {
    /// Position at the elapsed time, and whether the move is over.
    fn position(&self) -> (f64, bool) {
        let dist = (self.to - self.from).abs();
        let sign = (self.to - self.from).signum();
        // The peak velocity: cruise, or lower when the move is too short to reach it.
        let peak = self
            .v
            .min((2.0 * dist * self.a * self.d / (self.a + self.d)).sqrt());
        if peak <= 0.0 {
            return (self.to, true);
        }
        let (ta, td) = (peak / self.a, peak / self.d);
        let tc =
            (dist - peak * peak / (2.0 * self.a) - peak * peak / (2.0 * self.d)).max(0.0) / peak;
        let t = self.elapsed;
        let s = if t < ta {
            self.a * t * t / 2.0
        } else if t < ta + tc {
            peak * ta / 2.0 + peak * (t - ta)
        } else if t < ta + tc + td {
            let u = ta + tc + td - t;
            dist - self.d * u * u / 2.0
        } else {
            return (self.to, true);
        };
        (self.from + sign * s, false)
    }
}

/// The motor and what commands it.
#[derive(Debug, Clone)]
pub(super) struct Motor {
    pub motion: Option<Segment>,
    pub playing: Kind,
    /// What the next `BG` starts.
    pub armed: Option<Kind>,
    /// Rows counted when the playing motion started (PT: the first point has zero slope).
    pub motion_start: u64,
    pub queue_low_sent: bool,
    pub profile: Option<Profile>,
    /// Profile position's set-point acknowledge (statusword bit 12).
    pub setpoint_ack: bool,
    /// Controlword bit 4 as last written (its rising edge starts IP and profile moves).
    pub ip_bit: bool,
    /// Speed of the command while decelerating in quick stop, counts/s.
    pub qs_velocity: f64,
    pub ts_us: u32,
    pub on: bool,
    pub commanded: f64,
    pub actual: f64,
    pub velocity: f64,
    pub last_step: Option<Instant>,
}

impl Motor {
    /// A motor off, at 0.
    pub fn new(ts_us: u32) -> Motor {
        Motor {
            motion: None,
            playing: Kind::Pvt,
            armed: None,
            motion_start: 0,
            queue_low_sent: false,
            profile: None,
            setpoint_ack: false,
            ip_bit: false,
            qs_velocity: 0.0,
            ts_us,
            on: false,
            commanded: 0.0,
            actual: 0.0,
            velocity: 0.0,
            last_step: None,
        }
    }
}

impl FakeElmo {
    /// The PT period: `MP[4]` position-controller samples of 4 × `TS` µs.
    fn pt_period(&self) -> f64 {
        self.table.mp[4].max(1) as f64 * 4.0 * self.motor.ts_us as f64 * 1e-6
    }

    /// Publishes the write and read pointers (0x2F11, 0x2F12).
    pub(super) fn update_pointers(&mut self) {
        let (w, r) = self.table.pointers();
        self.od.set_raw(WRITE_POINTER, 0, w as i64);
        self.od.set_raw(READ_POINTER, 0, r as i64);
    }

    /// The segment that starts at the `executed`-th row of the playing table.
    fn segment(&self, elapsed: f64) -> Segment {
        let t = &self.table;
        let (from, to) = (t.row_at(t.executed), t.row_at(t.executed + 1));
        let (p0, p1) = (from.position as f64, to.position as f64);
        match self.motor.playing {
            Kind::Pvt | Kind::Ip => Segment {
                p0,
                v0: from.velocity as f64,
                p1,
                v1: to.velocity as f64,
                duration: from.time_ms.max(1) as f64 / 1000.0,
                elapsed,
                linear: self.motor.playing == Kind::Ip,
            },
            Kind::Pt => {
                // Slopes from the neighbours: zero at the motion's first point, and where the
                // point after `to` has not arrived.
                let period = self.pt_period();
                let v0 = if t.executed > self.motor.motion_start {
                    (p1 - t.row_at(t.executed - 1).position as f64) / (2.0 * period)
                } else {
                    0.0
                };
                let v1 = if t.pending() >= 3 {
                    (t.row_at(t.executed + 2).position as f64 - p0) / (2.0 * period)
                } else {
                    0.0
                };
                Segment {
                    p0,
                    v0,
                    p1,
                    v1,
                    duration: period,
                    elapsed,
                    linear: false,
                }
            }
        }
    }

    /// Starts playing the table from the read pointer.
    pub(super) fn begin_motion(&mut self, kind: Kind, now: Instant) {
        if self.table.pending() < 2 {
            return;
        }
        self.motor.playing = kind;
        self.motor.motion_start = self.table.executed;
        let seg = self.segment(0.0);
        self.motor.commanded = seg.p0;
        self.motor.motion = Some(seg);
        self.motor.last_step = Some(now);
    }

    /// Advances the motor to `now`.
    pub(super) fn advance(&mut self, now: Instant) {
        let dt = self
            .motor
            .last_step
            .map_or(0.0, |t| now.saturating_duration_since(t).as_secs_f64());
        self.motor.last_step = Some(now);
        if self.levers.fault.load(Ordering::Relaxed) && self.drive != DriveState::Fault {
            self.fault(0x2310); // over-current
        }
        if let Some(mut seg) = self.motor.motion {
            seg.elapsed += dt;
            loop {
                if seg.elapsed < seg.duration {
                    break;
                }
                let elapsed = seg.elapsed - seg.duration;
                self.table.executed += 1;
                self.update_pointers();
                let pending = self.table.pending();
                // Without MP[3] bit 0 the table is not a ring: the motion ends at MP[2].
                let table_end = self.motor.playing != Kind::Ip
                    && self.table.mp[3] & 1 == 0
                    && self.table.index_of(self.table.executed) as i32 == self.table.mp[2];
                if pending < 2 || table_end {
                    // The read pointer reached the write pointer (underflow) or the table's
                    // end: the motion ends at the last point; unexpected ends are reported.
                    self.motor.commanded = seg.p1;
                    self.motor.motion = None;
                    let expected = self.motor.playing != Kind::Ip && self.table.mp[3] & 2 != 0;
                    if !expected {
                        let e = ElmoEmcy::MotionTerminated {
                            write: self.table.index_of(self.table.written),
                            reason: 3,
                        }
                        .to_emcy(self.cfg.node);
                        self.emcy(e);
                    }
                    break;
                }
                if pending <= 4 && !self.motor.queue_low_sent {
                    self.motor.queue_low_sent = true;
                    let (write, read) = self.table.pointers();
                    let e = ElmoEmcy::QueueLow { write, read }.to_emcy(self.cfg.node);
                    self.emcy(e);
                }
                seg = self.segment(elapsed);
            }
            if self.motor.motion.is_some() {
                self.motor.commanded = seg.position();
                self.motor.motion = Some(seg);
            }
        }
        // Profile position: the command follows the trapezoid.
        if let Some(mut p) = self.motor.profile {
            p.elapsed += dt;
            let (position, done) = p.position();
            self.motor.commanded = position;
            self.motor.profile = (!done).then_some(p);
        }
        // Quick stop: the command decelerates to a stop at 0x6085, then holds.
        if self.drive == DriveState::QuickStopActive && dt > 0.0 {
            let decel = self.od.get_u(ds402::QUICK_STOP_DECELERATION, 0).max(1) as f64;
            let dv = decel * dt;
            let m = &mut self.motor;
            m.qs_velocity = if m.qs_velocity.abs() <= dv {
                0.0
            } else {
                m.qs_velocity - dv * m.qs_velocity.signum()
            };
            m.commanded += m.qs_velocity * dt;
        }
        // The motor follows its command with a first-order lag.
        let m = &mut self.motor;
        if m.on && dt > 0.0 {
            let a = 1.0 - (-dt / self.cfg.lag.as_secs_f64()).exp();
            let before = m.actual;
            m.actual += (m.commanded - m.actual) * a;
            m.velocity = (m.actual - before) / dt;
        } else {
            m.velocity = 0.0;
        }
        let window = self.od.get_u(ds402::FOLLOWING_ERROR_WINDOW, 0) as f64;
        if self.motor.on && (self.motor.commanded - self.motor.actual).abs() > window {
            self.fault(Emcy::FOLLOWING_ERROR);
        }
        self.update_status();
    }

    /// Goes to fault with `code`: the motor off, the motion dropped, an emergency sent.
    pub(super) fn fault(&mut self, code: u16) {
        self.drive = DriveState::Fault;
        self.motor.on = false;
        self.motor.motion = None;
        self.motor.profile = None;
        self.update_status();
        let e = Emcy {
            node: self.cfg.node,
            code,
            register: 0x81,
            manufacturer: [0; 5],
        };
        self.emcy(e);
    }

    /// The drive's state changed to `to` from `before` (by controlword, or by its own
    /// reaction): the motor follows.
    pub(super) fn on_state_change(&mut self, before: DriveState) {
        if self.drive == DriveState::SwitchOnDisabled && before == DriveState::Fault {
            // The fault is reset: the error register clears, and CiA 301 says so by EMCY.
            self.levers.fault.store(false, Ordering::Relaxed);
            self.emcy(Emcy::error_reset(self.cfg.node, 0));
        }
        if self.drive == DriveState::QuickStopActive && before != DriveState::QuickStopActive {
            // Decelerate from the present speed (0x6085), then hold.
            self.motor.qs_velocity = self.motor.velocity;
        }
        self.motor.on = matches!(
            self.drive,
            DriveState::OperationEnabled | DriveState::QuickStopActive
        );
        if !self.motor.on {
            // Torque off: the command is where the motor is.
            self.motor.commanded = self.motor.actual;
        }
        if self.drive != DriveState::OperationEnabled {
            self.motor.motion = None;
            self.motor.profile = None;
        }
    }

    /// The statusword and the actual values, from the drive's state.
    pub(super) fn update_status(&mut self) {
        let mode = self.od.get_u(ds402::MODES_OF_OPERATION, 0) as i8;
        let m = &self.motor;
        let status = ds402::ModeStatus {
            target_reached: m.motion.is_none()
                && m.profile.is_none()
                && (m.commanded - m.actual).abs() < 1.0,
            internal_limit: false,
            // Profile position: set-point acknowledged; interpolated position: active.
            mode_bit: match mode {
                1 => m.setpoint_ack,
                7 => m.motion.is_some() && m.playing == Kind::Ip,
                _ => false,
            },
            following_error: false,
        };
        let sw = self.drive.statusword_bits() | 0x0200 /* remote */ | status.statusword_bits();
        let (actual, velocity, error) = (m.actual, m.velocity, m.commanded - m.actual);
        self.od.set_raw(ds402::STATUSWORD, 0, sw as i64);
        self.od
            .set_raw(ds402::POSITION_ACTUAL, 0, actual.round() as i64);
        self.od
            .set_raw(ds402::VELOCITY_ACTUAL, 0, velocity.round() as i64);
        self.od
            .set_raw(ds402::FOLLOWING_ERROR, 0, error.round() as i64);
    }
}

impl FakeElmo {
    /// What a write (SDO or RPDO) does besides storing the value.
    pub(super) fn after_write(&mut self, index: u16, sub: u8, data: &[u8], now: Instant) {
        use stride_canopen::elmo::{PvtRow, PT_OBJECT, PVT_OBJECT};
        match (index, sub) {
            (ds402::CONTROLWORD, 0) => {
                let cw = u16::from_le_bytes([data[0], data[1]]);
                let before = self.drive;
                self.drive = ds402::next_state(self.drive, self.prev_cw, cw);
                self.prev_cw = cw;
                if self.drive != before {
                    self.on_state_change(before);
                }
                let mode = self.od.get_u(ds402::MODES_OF_OPERATION, 0) as i8;
                let enabled = self.drive == DriveState::OperationEnabled;
                let rising = cw & 0x10 != 0 && !self.motor.ip_bit;
                // Interpolated position mode: bit 4 ("enable interpolation") starts the buffer.
                if mode == 7 && enabled && rising {
                    self.begin_motion(Kind::Ip, now);
                }
                // Profile position: bit 4 rising hands over a set-point (bit 6: relative),
                // acknowledged in statusword bit 12 until bit 4 falls. This fake takes every
                // set-point at once, as if bit 5 ("change set immediately") were set.
                if mode == 1 && enabled && rising {
                    let target = self.od.get_u(ds402::TARGET_POSITION, 0) as u32 as i32 as f64;
                    let to = if cw & 0x40 != 0 {
                        self.motor.profile.map_or(self.motor.commanded, |p| p.to) + target
                    } else {
                        target
                    };
                    let rate = |i| (self.od.get_u(i, 0) as u32).max(1) as f64;
                    self.motor.profile = Some(Profile {
                        from: self.motor.commanded,
                        to,
                        v: rate(ds402::PROFILE_VELOCITY),
                        a: rate(ds402::PROFILE_ACCELERATION),
                        d: rate(ds402::PROFILE_DECELERATION),
                        elapsed: 0.0,
                    });
                    self.motor.setpoint_ack = true;
                }
                if cw & 0x10 == 0 {
                    self.motor.setpoint_ack = false;
                }
                self.motor.ip_bit = cw & 0x10 != 0;
            }
            (ds402::MODES_OF_OPERATION, 0) => {
                self.od
                    .set_raw(ds402::MODES_DISPLAY, 0, data[0] as i8 as i64)
            }
            (PVT_OBJECT, 0) => {
                let mut b = [0u8; 8];
                b.copy_from_slice(data);
                self.push_row(PvtRow::from_bytes(&b));
            }
            (PT_OBJECT, 0) => {
                for pair in data.chunks_exact(4) {
                    let position = i32::from_le_bytes([pair[0], pair[1], pair[2], pair[3]]);
                    self.push_row(PvtRow {
                        position,
                        velocity: 0,
                        time_ms: 0,
                    });
                }
            }
            (ds402::IP_DATA, 1) => {
                // A linear interpolation set-point: one row of the fixed period (0x60C2, ms).
                let position = i32::from_le_bytes([data[0], data[1], data[2], data[3]]);
                let period = self.od.get_u(ds402::IP_PERIOD, 1).clamp(1, 255) as u8;
                self.push_row(PvtRow {
                    position,
                    velocity: 0,
                    time_ms: period,
                });
            }
            _ => {}
        }
        self.update_status();
    }

    /// A row for the table; a full table drops it and says so by EMCY.
    fn push_row(&mut self, row: stride_canopen::elmo::PvtRow) {
        match self.table.push(row) {
            Ok(()) => {
                self.update_pointers();
                if self.table.pending() > 2 {
                    self.motor.queue_low_sent = false;
                }
            }
            Err(index) => {
                let e = ElmoEmcy::QueueFull { index }.to_emcy(self.cfg.node);
                self.emcy(e);
            }
        }
    }
}
