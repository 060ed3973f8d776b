//! SYNC (COB-ID 0x080), with the optional counter byte of CiA 301 v4.2.

use crate::frame::{CanFrame, FrameError};

/// A SYNC frame; `counter` (1..=240) only when the network uses the SYNC counter.
pub fn encode(counter: Option<u8>) -> CanFrame {
    match counter {
        Some(c) => CanFrame::standard(0x080, &[c]).expect("valid SYNC"),
        None => CanFrame::standard(0x080, &[]).expect("valid SYNC"),
    }
}

/// Reads a SYNC frame's counter (`None` without one).
pub fn decode(frame: &CanFrame) -> Result<Option<u8>, FrameError> {
    if frame.raw_id() != 0x080 || frame.is_extended() {
        return Err(FrameError::Unexpected("not a SYNC frame"));
    }
    Ok(frame.data().first().copied())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sync_frames() {
        assert_eq!(encode(None).dlc(), 0);
        assert_eq!(decode(&encode(Some(7))).unwrap(), Some(7));
        assert!(decode(&CanFrame::standard(0x081, &[]).unwrap()).is_err());
    }
}
