//! CANopen, as pure codecs: CAN frames in, meaning out, and back. No I/O, no clocks.
//!
//! * [`frame`]: the CiA 301 predefined connection set (COB-IDs by function and node) over
//!   `stride_can`'s classic frame ([`CanFrame`]).
//! * [`nmt`], [`sync`], [`emcy`], [`heartbeat`]: the network services.
//! * [`sdo`]: the SDO client protocol (expedited and segmented transfers, abort codes).
//! * [`pdo`]: PDO mapping entries and communication parameters.
//! * [`ds402`]: the CiA 402 drive state machine (statusword, controlword, modes, objects).
//! * [`elmo`]: Elmo's binary interpreter over PDO2 and its PT/PVT motion objects.

pub mod ds402;
pub mod elmo;
pub mod emcy;
pub mod frame;
pub mod heartbeat;
pub mod nmt;
pub mod pdo;
pub mod sdo;
pub mod sync;

pub use frame::{CobId, FrameError, Function, NodeId};
pub use stride_can::CanFrame;
