//! Why the master stopped or refused something.

use stride_canbus::BusError;
use stride_canopen::ds402::State as DriveState;
use stride_canopen::sdo;

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
    /// A drive did not reach the state it was sent to.
    #[error("{joint} (node {node}): stuck in {state:?} while {doing}")]
    Enable {
        /// Joint.
        joint: String,
        /// Node id.
        node: u8,
        /// The state it stayed in.
        state: DriveState,
        /// What the master was doing ("enabling", "stopping").
        doing: &'static str,
    },
    /// The motion a trajectory asks for is beyond a joint's limit, between or at rows: the
    /// whole trajectory is refused.
    #[error("row {row}, joint {joint}: {what}")]
    Limit {
        /// Row index (of the trajectory's rows).
        row: usize,
        /// Joint.
        joint: String,
        /// Which limit, by how much, and when.
        what: String,
    },
    /// The trajectory's shape, timing or start cannot be played (joint names, sizes, times,
    /// start time, the queue's bound).
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
    /// The drive cannot be set up as configured, or the configuration cannot be represented
    /// in the drive's fields.
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
