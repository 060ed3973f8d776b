//! Classic CAN frames and the CiA 301 predefined connection set.

use embedded_can::{ExtendedId, Id, StandardId};

/// Why a frame could not be built or understood.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// More than 8 data bytes.
    #[error("{0} data bytes; classic CAN carries at most 8")]
    TooLong(usize),
    /// An identifier outside the 11-bit or 29-bit range.
    #[error("identifier {0:#x} out of range")]
    BadId(u32),
    /// A node id outside 1..=127.
    #[error("node id {0} outside 1..=127")]
    BadNode(u8),
    /// A frame too short for the protocol.
    #[error("expected at least {expected} data bytes, found {found}")]
    Short {
        /// Bytes needed.
        expected: usize,
        /// Bytes present.
        found: usize,
    },
    /// A frame that is not what the protocol expects.
    #[error("unexpected frame: {0}")]
    Unexpected(&'static str),
}

/// A classic CAN frame: identifier, up to 8 data bytes, remote flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: Id,
    rtr: bool,
    len: u8,
    data: [u8; 8],
}

impl CanFrame {
    /// A data frame with a standard (11-bit) identifier.
    pub fn standard(id: u16, data: &[u8]) -> Result<CanFrame, FrameError> {
        let sid = StandardId::new(id).ok_or(FrameError::BadId(id as u32))?;
        Self::data_frame(Id::Standard(sid), data)
    }

    /// A data frame with an extended (29-bit) identifier.
    pub fn extended(id: u32, data: &[u8]) -> Result<CanFrame, FrameError> {
        let eid = ExtendedId::new(id).ok_or(FrameError::BadId(id))?;
        Self::data_frame(Id::Extended(eid), data)
    }

    /// A data frame with any identifier.
    pub fn data_frame(id: Id, data: &[u8]) -> Result<CanFrame, FrameError> {
        if data.len() > 8 {
            return Err(FrameError::TooLong(data.len()));
        }
        let mut d = [0u8; 8];
        d[..data.len()].copy_from_slice(data);
        Ok(CanFrame {
            id,
            rtr: false,
            len: data.len() as u8,
            data: d,
        })
    }

    /// A remote (RTR) frame asking for `dlc` bytes.
    pub fn remote(id: Id, dlc: u8) -> Result<CanFrame, FrameError> {
        if dlc > 8 {
            return Err(FrameError::TooLong(dlc as usize));
        }
        Ok(CanFrame {
            id,
            rtr: true,
            len: dlc,
            data: [0; 8],
        })
    }

    /// The identifier.
    pub fn id(&self) -> Id {
        self.id
    }

    /// The identifier as a number (11 or 29 bits).
    pub fn raw_id(&self) -> u32 {
        match self.id {
            Id::Standard(s) => s.as_raw() as u32,
            Id::Extended(e) => e.as_raw(),
        }
    }

    /// True for a 29-bit identifier.
    pub fn is_extended(&self) -> bool {
        matches!(self.id, Id::Extended(_))
    }

    /// True for a remote frame.
    pub fn is_remote(&self) -> bool {
        self.rtr
    }

    /// Data length code.
    pub fn dlc(&self) -> usize {
        self.len as usize
    }

    /// The data bytes (empty for remote frames).
    pub fn data(&self) -> &[u8] {
        if self.rtr {
            &[]
        } else {
            &self.data[..self.len as usize]
        }
    }

    /// The data, checked to be at least `n` bytes long.
    pub fn data_at_least(&self, n: usize) -> Result<&[u8], FrameError> {
        let d = self.data();
        if d.len() < n {
            Err(FrameError::Short {
                expected: n,
                found: d.len(),
            })
        } else {
            Ok(d)
        }
    }

    /// Bits this frame occupies on the wire at most (with worst-case bit stuffing and the
    /// 3-bit interframe space): 55 + 10 per data byte for standard frames, 80 + 10 for extended.
    pub fn max_wire_bits(&self) -> u32 {
        let data_bits = if self.rtr { 0 } else { 8 * self.len as u32 };
        // Stuffable bits: SOF..CRC (34 + data for standard, 54 + data for extended).
        let (fixed, stuffable) = if self.is_extended() {
            (67, 54)
        } else {
            (47, 34)
        };
        let stuff = (stuffable + data_bits - 1) / 4;
        fixed + data_bits + stuff
    }

    /// Bits this frame occupies on the wire without bit stuffing (interframe space included).
    pub fn min_wire_bits(&self) -> u32 {
        let data_bits = if self.rtr { 0 } else { 8 * self.len as u32 };
        (if self.is_extended() { 67 } else { 47 }) + data_bits
    }
}

impl embedded_can::Frame for CanFrame {
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        Self::data_frame(id.into(), data).ok()
    }
    fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        Self::remote(id.into(), u8::try_from(dlc).ok()?).ok()
    }
    fn is_extended(&self) -> bool {
        CanFrame::is_extended(self)
    }
    fn is_remote_frame(&self) -> bool {
        self.rtr
    }
    fn id(&self) -> Id {
        self.id
    }
    fn dlc(&self) -> usize {
        self.len as usize
    }
    fn data(&self) -> &[u8] {
        CanFrame::data(self)
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

    #[test]
    fn frames_and_wire_time() {
        let f = CanFrame::standard(0x601, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]).unwrap();
        assert_eq!(f.dlc(), 8);
        assert_eq!(f.min_wire_bits(), 111);
        assert_eq!(f.max_wire_bits(), 135);
        let sync = CanFrame::standard(0x080, &[]).unwrap();
        assert_eq!((sync.min_wire_bits(), sync.max_wire_bits()), (47, 55));
        let ext = CanFrame::extended(0x1234567, &[0; 8]).unwrap();
        assert_eq!((ext.min_wire_bits(), ext.max_wire_bits()), (131, 160));
        assert!(CanFrame::standard(0x800, &[]).is_err());
        assert!(CanFrame::standard(1, &[0; 9]).is_err());
        let r = CanFrame::remote(Id::Standard(StandardId::new(0x705).unwrap()), 1).unwrap();
        assert!(r.is_remote() && r.data().is_empty() && r.dlc() == 1);
    }
}
