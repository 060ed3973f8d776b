//! Drives Elmo motion controllers over CANopen, generic over the CAN bus ([`CanBus`]).
//!
//! * Bring-up ([`Master::bring_up`]): identity, heartbeats both ways (each drive watches the
//!   master's heartbeat and quick-stops on its own without it), following-error window and
//!   quick-stop deceleration from the joint's limits, PDO mapping verified by read-back, NMT
//!   start, the table set up with the interpreter's `MP[1..6]`, CiA 402 enable.
//! * Trajectories ([`Master::load`]): started at once, at a time, or after what is queued
//!   ([`Start`]); a trajectory replaces what is queued of its joints from its start on. The
//!   motion each drive will play is checked before anything is sent, between rows too
//!   (PVT's cubic, PT's own interpolation, interpolated position's lines), with the join from
//!   what the joint does at the start and the stop that follows a chunk ending in motion;
//!   past a limit the whole trajectory is refused. Values go into the drive's fields only
//!   where they fit ([`units`]).
//! * Streaming ([`Master::pump`]): rows sent within a lookahead of the drives' play, every
//!   axis of a motion started together, a stream that runs dry stopped at the acceleration
//!   limit, joint states from the SYNC-driven TPDO, emergencies as events.
//! * Stopping: [`Master::quick_stop`] (the drives stay stopped until the next valid
//!   trajectory enables them again), [`Master::shutdown`] (decelerate, wait for standstill,
//!   then torque off), [`Master::recover`] after a bus failure or a drive reset.
//!
//! The master's clock is the host's: plan times are this process's monotonic clock; a
//! trajectory's `start_utime` is the host's system clock (µs since the Unix epoch, UTC), so
//! a trajectory sent from another machine starts on time only when both clocks agree
//! (chrony, PTP).

mod bring_up;
mod config;
mod error;
mod master;
pub mod plan;
mod stream;
pub mod trajectory;
pub mod units;

pub use bring_up::Shutdown;
pub use config::{JointConfig, MasterConfig, Motion, PT_POINTS};
pub use error::MasterError;
pub use master::{Counters, Event, JointState, Master, Status, END_REPORT_WAIT, STILL_SPEED};
pub use stream::Accepted;
pub use trajectory::{Start, Trajectory};

pub use stride_canbus::CanBus;
/// The motion between rows and its check, shared with every other sender of trajectories.
pub use stride_limits::curve;
