//! The CiA 301 predefined connection set: node ids, functions, COB-IDs; the frame itself is
//! [`stride_can`]'s.

pub use stride_can::CanFrame;

/// Why a frame could not be built or understood.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// Not a valid CAN frame (length, identifier), or too short for the protocol.
    #[error(transparent)]
    Frame(#[from] stride_can::FrameError),
    /// A node id outside 1..=127.
    #[error("node id {0} outside 1..=127")]
    BadNode(u8),
    /// A frame that is not what the protocol expects.
    #[error("unexpected frame: {0}")]
    Unexpected(&'static str),
}

impl FrameError {
    /// Fewer than `expected` data bytes.
    pub fn short(expected: usize, found: usize) -> FrameError {
        FrameError::Frame(stride_can::FrameError::Short { expected, found })
    }
}

/// A CANopen node id, 1..=127.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct NodeId(u8);

impl NodeId {
    /// Checks the range.
    pub fn new(id: u8) -> Result<NodeId, FrameError> {
        if (1..=127).contains(&id) {
            Ok(NodeId(id))
        } else {
            Err(FrameError::BadNode(id))
        }
    }

    /// The number.
    pub fn get(self) -> u8 {
        self.0
    }
}

/// The function of a frame in the predefined connection set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Function {
    /// NMT command (0x000).
    Nmt,
    /// SYNC (0x080).
    Sync,
    /// EMCY from a node (0x080 + node).
    Emcy,
    /// TIME (0x100).
    Time,
    /// Transmit PDO 1..=4 (0x180, 0x280, 0x380, 0x480 + node).
    Tpdo(u8),
    /// Receive PDO 1..=4 (0x200, 0x300, 0x400, 0x500 + node).
    Rpdo(u8),
    /// SDO server to client (0x580 + node).
    SdoTx,
    /// SDO client to server (0x600 + node).
    SdoRx,
    /// NMT error control: heartbeat or boot-up (0x700 + node).
    Heartbeat,
}

/// A COB-ID of the predefined connection set: a function and, except for broadcasts, a node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CobId {
    /// What the frame is.
    pub function: Function,
    /// The node it comes from or goes to (`None` for NMT, SYNC, TIME).
    pub node: Option<NodeId>,
}

impl CobId {
    /// The 11-bit identifier.
    pub fn raw(&self) -> u16 {
        let n = self.node.map_or(0, |n| n.get() as u16);
        match self.function {
            Function::Nmt => 0x000,
            Function::Sync => 0x080,
            Function::Emcy => 0x080 + n,
            Function::Time => 0x100,
            Function::Tpdo(k) => 0x080 + 0x100 * k as u16 + n,
            Function::Rpdo(k) => 0x100 + 0x100 * k as u16 + n,
            Function::SdoTx => 0x580 + n,
            Function::SdoRx => 0x600 + n,
            Function::Heartbeat => 0x700 + n,
        }
    }

    /// Classifies an 11-bit identifier; `None` outside the predefined set.
    pub fn parse(id: u16) -> Option<CobId> {
        let node = NodeId::new((id & 0x7f) as u8).ok();
        let (function, node) = match (id & 0x780, id & 0x7f) {
            (0x000, 0) => (Function::Nmt, None),
            (0x080, 0) => (Function::Sync, None),
            (0x080, _) => (Function::Emcy, node),
            (0x100, 0) => (Function::Time, None),
            (0x180, _) => (Function::Tpdo(1), node),
            (0x200, _) => (Function::Rpdo(1), node),
            (0x280, _) => (Function::Tpdo(2), node),
            (0x300, _) => (Function::Rpdo(2), node),
            (0x380, _) => (Function::Tpdo(3), node),
            (0x400, _) => (Function::Rpdo(3), node),
            (0x480, _) => (Function::Tpdo(4), node),
            (0x500, _) => (Function::Rpdo(4), node),
            (0x580, _) => (Function::SdoTx, node),
            (0x600, _) => (Function::SdoRx, node),
            (0x700, _) => (Function::Heartbeat, node),
            _ => return None,
        };
        if node.is_none() && !matches!(function, Function::Nmt | Function::Sync | Function::Time) {
            return None;
        }
        Some(CobId { function, node })
    }

    /// A node's COB-ID for `function`.
    pub fn of(function: Function, node: NodeId) -> CobId {
        CobId {
            function,
            node: Some(node),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cob_ids_round_trip() {
        let n = NodeId::new(5).unwrap();
        for (f, raw) in [
            (Function::Emcy, 0x085),
            (Function::Tpdo(1), 0x185),
            (Function::Rpdo(1), 0x205),
            (Function::Tpdo(2), 0x285),
            (Function::Rpdo(2), 0x305),
            (Function::Tpdo(4), 0x485),
            (Function::Rpdo(4), 0x505),
            (Function::SdoTx, 0x585),
            (Function::SdoRx, 0x605),
            (Function::Heartbeat, 0x705),
        ] {
            let c = CobId::of(f, n);
            assert_eq!(c.raw(), raw);
            assert_eq!(CobId::parse(raw), Some(c));
        }
        assert_eq!(CobId::parse(0x080).unwrap().function, Function::Sync);
        assert_eq!(CobId::parse(0x000).unwrap().function, Function::Nmt);
        assert_eq!(
            CobId::parse(0x77f),
            Some(CobId::of(Function::Heartbeat, NodeId::new(127).unwrap()))
        );
        assert_eq!(CobId::parse(0x180), None);
        assert!(NodeId::new(0).is_err() && NodeId::new(128).is_err());
    }
}
