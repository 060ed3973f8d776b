//! A CAN bus carried over LCM: frames travel as `stride.can_frame_batch_t` on two channels per
//! bus, `CAN_<BUS>_TX` (to be put on the wire by a gateway) and `CAN_<BUS>_RX` (seen on the
//! wire). Anyone can sniff them with stride-spy or lcm-spy.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ::lcm::{Lcm, Subscription};
use stride_lcmtypes::stride::{CanFrameBatchT, CanFrameT, HeaderT};

use crate::{BusError, CanBus, CanFrame};

/// The channel of frames to transmit on bus `name`.
pub fn tx_channel(name: &str) -> String {
    format!("CAN_{}_TX", name.to_uppercase())
}

/// The channel of frames received on bus `name`.
pub fn rx_channel(name: &str) -> String {
    format!("CAN_{}_RX", name.to_uppercase())
}

/// A frame as its LCM message element.
pub fn frame_to_msg(f: &CanFrame, utime: i64) -> CanFrameT {
    let mut data = [0u8; 8];
    data[..f.data().len()].copy_from_slice(f.data());
    CanFrameT {
        utime,
        id: f.raw_id() as i32,
        extended: f.is_extended(),
        rtr: f.is_remote(),
        error: false,
        dlc: f.dlc() as i8,
        data,
    }
}

/// An LCM frame element as a frame (`None` for error frames or invalid ones).
pub fn msg_to_frame(m: &CanFrameT) -> Option<CanFrame> {
    if m.error || !(0..=8).contains(&m.dlc) {
        return None;
    }
    let n = m.dlc as usize;
    let f = if m.extended {
        CanFrame::extended(m.id as u32, &m.data[..n]).ok()?
    } else {
        CanFrame::standard(u16::try_from(m.id).ok()?, &m.data[..n]).ok()?
    };
    if m.rtr {
        CanFrame::remote(f.id(), m.dlc as u8).ok()
    } else {
        Some(f)
    }
}

/// A batch of frames for bus `bus`.
pub fn batch(bus: &str, header: HeaderT, frames: &[CanFrameT]) -> CanFrameBatchT {
    CanFrameBatchT {
        header,
        bus: bus.to_owned(),
        num_frames: frames.len() as i32,
        frames: frames.to_vec(),
    }
}

fn now_us() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as i64)
}

/// The client side of a bus carried over LCM: sends on `CAN_<BUS>_TX`, receives from
/// `CAN_<BUS>_RX`. It owns its LCM instance and handles it inside `recv`. Frames sent back to
/// back are batched; `recv` (and [`LcmBus::flush`]) sends what waits.
pub struct LcmBus {
    lcm: Lcm,
    name: String,
    tx: String,
    inbox: Arc<Mutex<VecDeque<CanFrame>>>,
    _sub: Subscription,
    sequence: i64,
    outbox: Vec<CanFrameT>,
}

impl std::fmt::Debug for LcmBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LcmBus").field("bus", &self.name).finish()
    }
}

impl LcmBus {
    /// Connects to bus `name` on the LCM bus at `url`.
    pub fn new(url: &str, name: &str) -> Result<LcmBus, BusError> {
        let lcm = Lcm::new(url).map_err(|e| BusError::Device(e.to_string()))?;
        let inbox: Arc<Mutex<VecDeque<CanFrame>>> = Arc::default();
        let i = inbox.clone();
        let sub = lcm
            .subscribe(&rx_channel(name), move |_, m: CanFrameBatchT| {
                let mut q = i.lock().unwrap_or_else(|p| p.into_inner());
                q.extend(m.frames.iter().filter_map(msg_to_frame));
            })
            .map_err(|e| BusError::Device(e.to_string()))?;
        sub.set_queue_capacity(1000)
            .map_err(|e| BusError::Device(e.to_string()))?;
        Ok(LcmBus {
            lcm,
            name: name.to_owned(),
            tx: tx_channel(name),
            inbox,
            _sub: sub,
            sequence: 0,
            outbox: Vec::new(),
        })
    }

    /// Publishes the frames waiting in the outbox as one batch.
    pub fn flush(&mut self) -> Result<(), BusError> {
        if self.outbox.is_empty() {
            return Ok(());
        }
        let header = HeaderT {
            utime: now_us(),
            sequence: self.sequence,
            frame: String::new(),
        };
        self.sequence += 1;
        let msg = batch(&self.name, header, &self.outbox);
        self.outbox.clear();
        self.lcm
            .publish(&self.tx, &msg)
            .map_err(|e| BusError::Device(e.to_string()))
    }

    fn pop(&self) -> Option<CanFrame> {
        self.inbox
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .pop_front()
    }
}

impl Drop for LcmBus {
    fn drop(&mut self) {
        // The last frames (an NMT command at shutdown) must not stay behind.
        let _ = self.flush();
    }
}

impl CanBus for LcmBus {
    fn send(&mut self, frame: &CanFrame, _deadline: Instant) -> Result<(), BusError> {
        // Frames sent back to back travel in one batch: flushed when 64 are waiting, or as
        // soon as the caller turns to receiving.
        self.outbox.push(frame_to_msg(frame, now_us()));
        if self.outbox.len() >= 64 {
            self.flush()?;
        }
        Ok(())
    }

    fn recv(&mut self, deadline: Instant) -> Result<CanFrame, BusError> {
        self.flush()?;
        loop {
            if let Some(f) = self.pop() {
                return Ok(f);
            }
            // Take in what already arrived, even when the deadline has passed (try_recv).
            if self
                .lcm
                .handle_pending()
                .map_err(|e| BusError::Device(e.to_string()))?
                > 0
            {
                continue;
            }
            let now = Instant::now();
            if now >= deadline {
                return Err(BusError::Timeout);
            }
            self.lcm
                .handle_timeout((deadline - now).min(Duration::from_millis(10)))
                .map_err(|e| BusError::Device(e.to_string()))?;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_convert_both_ways() {
        for f in [
            CanFrame::standard(0x181, &[1, 2, 3]).unwrap(),
            CanFrame::extended(0x1abcdef, &[0; 8]).unwrap(),
            CanFrame::remote(CanFrame::standard(0x705, &[]).unwrap().id(), 1).unwrap(),
        ] {
            assert_eq!(msg_to_frame(&frame_to_msg(&f, 5)), Some(f));
        }
        let mut bad = frame_to_msg(&CanFrame::standard(1, &[]).unwrap(), 0);
        bad.dlc = 9;
        assert_eq!(msg_to_frame(&bad), None);
        bad.dlc = 0;
        bad.id = 0x900;
        assert_eq!(msg_to_frame(&bad), None);
        assert_eq!(tx_channel("left_leg"), "CAN_LEFT_LEG_TX");
    }
}
