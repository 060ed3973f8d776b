//! Heartbeat and boot-up messages (COB-ID 0x700 + node).

use crate::frame::{CanFrame, CobId, FrameError, Function, NodeId};
use crate::nmt::State;

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
}
