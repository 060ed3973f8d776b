//! The configuration of the master and of each joint.

use std::time::Duration;

use stride_limits::Limits;

/// One joint: its drive, the conversion from radians to encoder counts, its limits.
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
    /// Acceleration limit, rad/s²: no motion the drive plays accelerates harder, and the
    /// drives' quick stop (0x6085) and the stop of a stream that ran dry decelerate at it.
    pub max_acceleration: f64,
    /// Largest tracking error tolerated, rad: the drive's following-error window (0x6065) is
    /// set to it at bring-up, so a joint that falls further behind its set-point faults
    /// instead of running on; a motion from rest starts within it of where the joint stands.
    #[serde(default = "JointConfig::default_tolerance")]
    pub tolerance: f64,
}

impl JointConfig {
    fn default_tolerance() -> f64 {
        0.01
    }

    /// Encoder counts per joint radian.
    pub fn counts_per_rad(&self) -> f64 {
        self.counts_per_rev * self.gear_ratio / std::f64::consts::TAU
    }

    /// The joint's position and velocity limits.
    pub fn limits(&self) -> Limits {
        Limits {
            min_position: self.min_position,
            max_position: self.max_position,
            max_velocity: self.max_velocity,
        }
    }
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
    /// by the drive with cubic interpolation (each point's slope from its neighbours);
    /// started with `PT=n` and `BG`.
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
    pub(crate) fn table_rows(self) -> u16 {
        match self {
            Motion::Pt { .. } => PT_POINTS,
            _ => stride_canopen::elmo::PVT_ROWS,
        }
    }

    /// Table rows carried by one set-point frame.
    pub(crate) fn rows_per_frame(self) -> usize {
        match self {
            Motion::Pt { .. } => 2,
            _ => 1,
        }
    }

    /// The fixed period of the table's rows, µs (PVT rows are free, on a 1 ms grid).
    pub(crate) fn grid_us(self) -> i64 {
        match self {
            Motion::Pvt => 1000,
            Motion::Pt { period_ms } | Motion::InterpolatedPosition { period_ms } => {
                period_ms as i64 * 1000
            }
        }
    }
}

/// Settings of the master.
#[derive(Debug, Clone)]
pub struct MasterConfig {
    /// Time allowed for each SDO exchange.
    pub sdo_timeout: Duration,
    /// An SDO or interpreter exchange that got no answer in `sdo_timeout` is sent again this
    /// many times before the drive counts as silent: a frame lost on a busy bus or a slow
    /// gateway is no reason to give a drive up (each is idempotent: a write of the same
    /// value, a read).
    pub sdo_retries: u32,
    /// Heartbeat period the drives are told to use; lost after three periods.
    pub heartbeat: Duration,
    /// PVT, PT or interpolated position.
    pub motion: Motion,
    /// The node id the master's own heartbeat goes out under (not a joint's).
    pub master_node: u8,
    /// Period of the master's heartbeat.
    pub master_heartbeat: Duration,
    /// The drives stop on their own (quick stop, 0x6007) when the master's heartbeat stops
    /// for this long (their consumer heartbeat time, 0x1016).
    pub drive_watchdog: Duration,
    /// How far ahead of the drives' play rows are sent: a trajectory replaces what is queued
    /// no sooner than this, and a stream's next chunk must arrive this long before the end
    /// of the queued motion.
    pub lookahead: Duration,
    /// The longest a trajectory may reach ahead (its end after now): the queue's bound.
    pub max_queue: Duration,
    /// Time between SYNCs (and so between joint states).
    pub sync_period: Duration,
    /// Time between SYNCs (and the heartbeats that go with them) while the drives rest:
    /// nothing queued or playing and every joint still. A trajectory brings `sync_period`
    /// back at once. At most half of `drive_watchdog`.
    pub idle_sync_period: Duration,
    /// On shutdown, the longest to wait for the joints to stand still after the quick stop
    /// before the torque goes off.
    pub stop_timeout: Duration,
}

impl Default for MasterConfig {
    fn default() -> Self {
        MasterConfig {
            sdo_timeout: Duration::from_millis(200),
            sdo_retries: 2,
            heartbeat: Duration::from_millis(100),
            motion: Motion::Pvt,
            master_node: 127,
            master_heartbeat: Duration::from_millis(20),
            drive_watchdog: Duration::from_millis(100),
            lookahead: Duration::from_millis(100),
            max_queue: Duration::from_secs(10),
            sync_period: Duration::from_millis(10),
            idle_sync_period: Duration::from_millis(10),
            stop_timeout: Duration::from_secs(2),
        }
    }
}
