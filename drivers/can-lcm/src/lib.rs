//! A CAN bus carried over LCM: frames travel as `stride.can_frame_batch_t` on two channels per
//! bus, `CAN_<BUS>_TX` (to be put on the wire by a gateway, `stride-usb2can`) and
//! `CAN_<BUS>_RX` (seen on the wire). Anyone can sniff them with stride-spy or lcm-spy.
//!
//! [`LcmBus`] is the client side as a [`CanBus`]: it works on the app's own LCM instance (the
//! node's), so the app's messages and the bus's frames are handled by one instance and one
//! loop.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use lcm::{now_utime, Lcm, Subscription};
use stride_can::{CanFrame, ExtendedId, Id, StandardId};
use stride_canbus::{BusError, CanBus};
use stride_lcmtypes::stride::{CanFrameBatchT, CanFrameT, HeaderT};

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

/// Why an LCM frame element is not a frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BadFrame {
    /// An error frame (the gateway saw a bus error).
    Error,
    /// A length outside 0..=8.
    Dlc(i8),
    /// An identifier outside its 11 or 29 bits.
    Id(i32),
}

impl std::fmt::Display for BadFrame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BadFrame::Error => write!(f, "an error frame"),
            BadFrame::Dlc(d) => write!(f, "length {d} outside 0..=8"),
            BadFrame::Id(id) => write!(f, "identifier {id:#x} out of range"),
        }
    }
}

/// An LCM frame element as a frame, or why it is none.
pub fn msg_to_frame(m: &CanFrameT) -> Result<CanFrame, BadFrame> {
    if m.error {
        return Err(BadFrame::Error);
    }
    if !(0..=8).contains(&m.dlc) {
        return Err(BadFrame::Dlc(m.dlc));
    }
    let bad = || BadFrame::Id(m.id);
    let id = if m.extended {
        Id::Extended(
            u32::try_from(m.id)
                .ok()
                .and_then(ExtendedId::new)
                .ok_or_else(bad)?,
        )
    } else {
        Id::Standard(
            u16::try_from(m.id)
                .ok()
                .and_then(StandardId::new)
                .ok_or_else(bad)?,
        )
    };
    // The length was checked above: neither can fail.
    if m.rtr {
        CanFrame::remote(id, m.dlc as u8).map_err(|_| BadFrame::Dlc(m.dlc))
    } else {
        CanFrame::data_frame(id, &m.data[..m.dlc as usize]).map_err(|_| BadFrame::Dlc(m.dlc))
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

/// The client side of a bus carried over LCM, on the app's LCM instance: sends on
/// `CAN_<BUS>_TX`, receives from `CAN_<BUS>_RX`, and handles the instance while it waits in
/// `recv` (so the app's own subscriptions are served meanwhile too). Frames sent back to back
/// are batched; `recv` (and [`LcmBus::flush`]) publishes what waits.
pub struct LcmBus<'a> {
    lcm: &'a Lcm,
    name: String,
    tx: String,
    inbox: Arc<Mutex<VecDeque<CanFrame>>>,
    _sub: Subscription,
    sequence: i64,
    outbox: Vec<CanFrameT>,
}

impl std::fmt::Debug for LcmBus<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LcmBus").field("bus", &self.name).finish()
    }
}

/// Frames a batch holds at most.
pub const BATCH: usize = 64;

/// Frames that may wait in a bus's inbox for the app (beyond, the oldest are dropped).
pub const INBOX: usize = 8192;

impl<'a> LcmBus<'a> {
    /// Joins bus `name` on `lcm`.
    pub fn new(lcm: &'a Lcm, name: &str) -> Result<LcmBus<'a>, BusError> {
        let inbox: Arc<Mutex<VecDeque<CanFrame>>> = Arc::default();
        let i = inbox.clone();
        let sub = lcm
            .subscribe(&rx_channel(name), move |_, m: CanFrameBatchT| {
                let mut q = i.lock().unwrap_or_else(|p| p.into_inner());
                // A batch holds at most BATCH frames; the inbox at most INBOX (a controller's
                // receive queue overflows the same way: the oldest go).
                q.extend(
                    m.frames
                        .iter()
                        .take(BATCH)
                        .filter_map(|f| msg_to_frame(f).ok()),
                );
                while q.len() > INBOX {
                    q.pop_front();
                }
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
            utime: now_utime(),
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

impl Drop for LcmBus<'_> {
    fn drop(&mut self) {
        // The last frames (an NMT command at shutdown) must not stay behind.
        let _ = self.flush();
    }
}

impl CanBus for LcmBus<'_> {
    fn send(&mut self, frame: &CanFrame, _deadline: Instant) -> Result<(), BusError> {
        // Frames sent back to back travel in one batch: flushed when a batch is full, or as
        // soon as the caller turns to receiving.
        self.outbox.push(frame_to_msg(frame, now_utime()));
        if self.outbox.len() >= BATCH {
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
            assert_eq!(msg_to_frame(&frame_to_msg(&f, 5)), Ok(f));
        }
        let mut bad = frame_to_msg(&CanFrame::standard(1, &[]).unwrap(), 0);
        bad.dlc = 9;
        assert_eq!(msg_to_frame(&bad), Err(BadFrame::Dlc(9)));
        bad.dlc = -1;
        assert_eq!(msg_to_frame(&bad), Err(BadFrame::Dlc(-1)));
        bad.dlc = 0;
        bad.id = 0x900;
        assert_eq!(msg_to_frame(&bad), Err(BadFrame::Id(0x900)));
        bad.id = -5;
        assert_eq!(msg_to_frame(&bad), Err(BadFrame::Id(-5)));
        bad.extended = true;
        bad.id = 0x7fff_ffff;
        assert_eq!(msg_to_frame(&bad), Err(BadFrame::Id(0x7fff_ffff)));
        bad.error = true;
        assert_eq!(msg_to_frame(&bad), Err(BadFrame::Error));
        assert_eq!(tx_channel("left_leg"), "CAN_LEFT_LEG_TX");
    }

    #[test]
    fn a_bus_over_memq_shares_the_apps_instance() {
        let lcm = Lcm::new("memq://").unwrap();
        let seen: Arc<Mutex<Vec<CanFrameBatchT>>> = Arc::default();
        let s = seen.clone();
        let _tx = lcm
            .subscribe(&tx_channel("x"), move |_, m: CanFrameBatchT| {
                s.lock().unwrap().push(m)
            })
            .unwrap();
        let mut bus = LcmBus::new(&lcm, "x").unwrap();
        let f = CanFrame::standard(0x601, &[0x40, 0, 0x10, 0, 0, 0, 0, 0]).unwrap();
        bus.send(&f, Instant::now()).unwrap();
        bus.send(&f, Instant::now()).unwrap();
        // Receiving publishes the two frames as one batch, and the app's subscription is
        // served by the same instance.
        assert_eq!(
            bus.recv(Instant::now() + Duration::from_millis(20)),
            Err(BusError::Timeout)
        );
        let got = seen.lock().unwrap().clone();
        assert_eq!(got.len(), 1);
        assert_eq!(got[0].num_frames, 2);
        // What the gateway publishes on RX comes back out of recv.
        let echo = batch("x", HeaderT::default(), &[frame_to_msg(&f, 1)]);
        lcm.publish(&rx_channel("x"), &echo).unwrap();
        assert_eq!(bus.recv(Instant::now() + Duration::from_millis(100)), Ok(f));
    }
}
