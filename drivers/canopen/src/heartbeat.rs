//! Heartbeat and boot-up messages (COB-ID 0x700 + node), and the objects that set up their
//! producer (0x1017) and consumers (0x1016).

use crate::frame::{CanFrame, CobId, FrameError, Function, NodeId};
use crate::nmt::State;

/// Consumer heartbeat time (0x1016): sub 0 the number of entries, each entry a
/// [`ConsumerEntry`] (the producer's node id and the time after which its silence is an
/// error).
pub const CONSUMER_TIME: u16 = 0x1016;
/// Producer heartbeat time (0x1017), ms (0: no heartbeat).
pub const PRODUCER_TIME: u16 = 0x1017;

/// One entry of 0x1016: watch node `node`'s heartbeat, and report a heartbeat event when
/// none came for `time_ms` (0 or node 0: the entry is unused).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ConsumerEntry {
    /// The producer's node id.
    pub node: u8,
    /// The consumer time, ms.
    pub time_ms: u16,
}

impl ConsumerEntry {
    /// The entry's 32-bit value: bits 16..23 node id, bits 0..15 time.
    pub fn to_u32(self) -> u32 {
        (self.node as u32) << 16 | self.time_ms as u32
    }

    /// Reads an entry's value (bits 24..31 are reserved).
    pub fn from_u32(v: u32) -> ConsumerEntry {
        ConsumerEntry {
            node: (v >> 16) as u8,
            time_ms: v as u16,
        }
    }

    /// True when the entry watches a node.
    pub fn active(self) -> bool {
        self.node != 0 && self.time_ms != 0
    }
}

/// A node's heartbeat (or, with [`State::BootUp`], its boot-up message).
pub fn encode(node: NodeId, state: State) -> CanFrame {
    CanFrame::standard(CobId::of(Function::Heartbeat, node).raw(), &[state.code()])
        .expect("valid heartbeat")
}

/// Reads a heartbeat: the sending node and its state.
pub fn decode(frame: &CanFrame) -> Result<(NodeId, State), FrameError> {
    let cob = CobId::parse(frame.raw_id() as u16)
        .filter(|c| c.function == Function::Heartbeat && !frame.is_extended())
        .ok_or(FrameError::Unexpected("not a heartbeat"))?;
    let d = frame.data_at_least(1)?;
    let state = State::from_code(d[0]).ok_or(FrameError::Unexpected("unknown NMT state"))?;
    Ok((cob.node.expect("heartbeats have a node"), state))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heartbeat_frames() {
        let n = NodeId::new(3).unwrap();
        let f = encode(n, State::Operational);
        assert_eq!((f.raw_id(), f.data()), (0x703, &[0x05][..]));
        assert_eq!(decode(&f).unwrap(), (n, State::Operational));
        assert_eq!(encode(n, State::BootUp).data(), [0x00]);
        assert!(decode(&CanFrame::standard(0x703, &[]).unwrap()).is_err());
    }

    #[test]
    fn consumer_entries() {
        // Watch node 0x7F with a 100 ms consumer time: 0x007F0064 (CiA 301, 7.5.2.4).
        let e = ConsumerEntry {
            node: 0x7f,
            time_ms: 100,
        };
        assert_eq!(e.to_u32(), 0x007f_0064);
        assert_eq!(ConsumerEntry::from_u32(0xff7f_0064), e);
        assert!(e.active() && !ConsumerEntry::from_u32(0x007f_0000).active());
    }
}
