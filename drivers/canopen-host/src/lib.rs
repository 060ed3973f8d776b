//! The host side of CANopen over any [`CanBus`]: SDO reads and writes bounded by a deadline,
//! with every other frame that arrives meanwhile handed to the caller (a master keeps
//! tracking its drives while it waits for one of them), and the host's own heartbeat
//! ([`HeartbeatProducer`]), which drives told to consume it stop without.
//!
//! The protocol is `stride-canopen`'s pure codec; this crate only adds the waiting.

use std::time::{Duration, Instant};

use stride_canbus::{BusError, CanBus, CanFrame};
use stride_canopen::frame::{CobId, Function, NodeId};
use stride_canopen::heartbeat;
use stride_canopen::nmt::State as NmtState;
use stride_canopen::sdo::{self, Download, ServerResponse, Step, Upload};

/// Why an exchange with a node failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HostError {
    /// The bus failed.
    #[error("CAN bus: {0}")]
    Bus(#[from] BusError),
    /// No answer before the deadline.
    #[error("no answer")]
    NoAnswer,
    /// The node aborted the transfer, or answered out of protocol.
    #[error("{0}")]
    Sdo(sdo::SdoError),
}

/// What the waiting loops do with the frames that are not the answer, and with the time they
/// wait: `frame` is `Some` for a frame that arrived, `None` every few milliseconds of
/// silence (a chance to send a heartbeat that falls due).
pub trait Aside<B: ?Sized> {
    /// Called for every other frame, and every few milliseconds while waiting.
    fn aside(&mut self, bus: &mut B, frame: Option<&CanFrame>);
}

impl<B: ?Sized, F: FnMut(&mut B, Option<&CanFrame>)> Aside<B> for F {
    fn aside(&mut self, bus: &mut B, frame: Option<&CanFrame>) {
        self(bus, frame)
    }
}

/// Ignores what is not the answer.
pub fn ignore<B: ?Sized>(_: &mut B, _: Option<&CanFrame>) {}

/// How long the waiting loops wait at most between two calls of [`Aside::aside`].
pub const SLICE: Duration = Duration::from_millis(5);

/// Sends `request` and waits until `deadline` for the frame `answer` accepts.
pub fn exchange<B: CanBus + ?Sized, T>(
    bus: &mut B,
    request: &CanFrame,
    deadline: Instant,
    mut answer: impl FnMut(&CanFrame) -> Option<T>,
    aside: &mut impl Aside<B>,
) -> Result<T, HostError> {
    bus.send(request, deadline)?;
    loop {
        let now = bus.now();
        if now >= deadline {
            return Err(HostError::NoAnswer);
        }
        match bus.recv((now + SLICE).min(deadline)) {
            Ok(f) => match answer(&f) {
                Some(t) => return Ok(t),
                None => aside.aside(bus, Some(&f)),
            },
            Err(BusError::Timeout) => aside.aside(bus, None),
            Err(e) => return Err(e.into()),
        }
    }
}

/// One SDO request to `node` and its response, within `timeout`.
pub fn sdo_exchange<B: CanBus + ?Sized>(
    bus: &mut B,
    node: NodeId,
    request: &sdo::ClientRequest,
    timeout: Duration,
    aside: &mut impl Aside<B>,
) -> Result<ServerResponse, HostError> {
    let want = CobId::of(Function::SdoTx, node).raw() as u32;
    let frame = request.encode(node).map_err(|_| {
        HostError::Sdo(sdo::SdoError::Protocol {
            reason: "request not encodable",
            code: sdo::AbortCode::GENERAL,
        })
    })?;
    // An initiate names its object: an answer that names another is a late one, to an
    // earlier request that timed out (and was perhaps sent again), and is not this one's.
    let asked = match request {
        sdo::ClientRequest::InitiateDownload { index, sub, .. }
        | sdo::ClientRequest::InitiateUpload { index, sub } => Some((*index, *sub)),
        _ => None,
    };
    exchange(
        bus,
        &frame,
        bus.now() + timeout,
        |f| {
            let r = (f.raw_id() == want && !f.is_extended())
                .then(|| ServerResponse::decode(f).ok().map(|(_, r)| r))
                .flatten()?;
            let named = match &r {
                ServerResponse::DownloadInitiated { index, sub }
                | ServerResponse::UploadInitiated { index, sub, .. }
                | ServerResponse::Abort { index, sub, .. } => Some((*index, *sub)),
                _ => None,
            };
            match (asked, named) {
                (Some(a), Some(n)) if a != n => None,
                _ => Some(r),
            }
        },
        aside,
    )
}

/// Reads `index`/`sub` of `node` (expedited or segmented, at most `max_size` bytes); each
/// request waits at most `timeout` for its answer. A protocol error is answered with the
/// abort the standard asks for.
pub fn sdo_read<B: CanBus + ?Sized>(
    bus: &mut B,
    node: NodeId,
    index: u16,
    sub: u8,
    timeout: Duration,
    aside: &mut impl Aside<B>,
) -> Result<Vec<u8>, HostError> {
    let mut up = Upload::new(index, sub, 4096);
    let mut req = up.start();
    loop {
        let resp = sdo_exchange(bus, node, &req, timeout, aside)?;
        match up.on_response(&resp) {
            Ok(Step::Send(r)) => req = r,
            Ok(Step::Done(d)) => return Ok(d),
            Err(e) => return Err(protocol_abort(bus, node, index, sub, e)),
        }
    }
}

/// Writes `data` to `index`/`sub` of `node`; each request waits at most `timeout`.
pub fn sdo_write<B: CanBus + ?Sized>(
    bus: &mut B,
    node: NodeId,
    index: u16,
    sub: u8,
    data: Vec<u8>,
    timeout: Duration,
    aside: &mut impl Aside<B>,
) -> Result<(), HostError> {
    let mut dl = Download::new(index, sub, data);
    let mut req = dl.start();
    loop {
        let resp = sdo_exchange(bus, node, &req, timeout, aside)?;
        match dl.on_response(&resp) {
            Ok(Step::Send(r)) => req = r,
            Ok(Step::Done(_)) => return Ok(()),
            Err(e) => return Err(protocol_abort(bus, node, index, sub, e)),
        }
    }
}

/// After a protocol error the client aborts the transfer (CiA 301); an abort from the
/// server needs no answer.
fn protocol_abort<B: CanBus + ?Sized>(
    bus: &mut B,
    node: NodeId,
    index: u16,
    sub: u8,
    e: sdo::SdoError,
) -> HostError {
    if let sdo::SdoError::Protocol { code, .. } = e {
        if let Ok(f) = (sdo::ClientRequest::Abort { index, sub, code }).encode(node) {
            let _ = bus.send(&f, bus.now() + SLICE);
        }
    }
    HostError::Sdo(e)
}

/// The host's own heartbeat: the node id it produces it under and its period. Poll it from
/// the loop that does the host's work, so that a host that hangs stops its heartbeat too.
#[derive(Debug, Clone)]
pub struct HeartbeatProducer {
    node: NodeId,
    period: Duration,
    next: Option<Instant>,
    sent: u64,
}

impl HeartbeatProducer {
    /// A heartbeat as node `node` every `period`, the first at the first poll.
    pub fn new(node: NodeId, period: Duration) -> HeartbeatProducer {
        HeartbeatProducer {
            node,
            period,
            next: None,
            sent: 0,
        }
    }

    /// The node id of the host's heartbeat.
    pub fn node(&self) -> NodeId {
        self.node
    }

    /// The period.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// Heartbeats sent.
    pub fn sent(&self) -> u64 {
        self.sent
    }

    /// True when the heartbeat fell due more than `grace` before `now`, or has never gone out.
    pub fn overdue(&self, now: Instant, grace: Duration) -> bool {
        self.next.is_none_or(|t| now >= t + grace)
    }

    /// Sends the heartbeat when it is due at `now` (a full transmit queue skips a beat).
    pub fn poll<B: CanBus + ?Sized>(&mut self, bus: &mut B, now: Instant) -> Result<(), BusError> {
        if self.next.is_some_and(|t| now < t) {
            return Ok(());
        }
        // Due times stay on the period's grid; a long stall does not send a burst.
        let due = self.next.unwrap_or(now) + self.period;
        self.next = Some(if due <= now { now + self.period } else { due });
        match bus.send(
            &heartbeat::encode(self.node, NmtState::Operational),
            now + SLICE,
        ) {
            Ok(()) => {
                self.sent += 1;
                Ok(())
            }
            Err(BusError::TxQueueFull) => Ok(()),
            Err(e) => Err(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    use stride_canbus::MemBus;
    use stride_canopen::sdo::{AbortCode, ClientRequest, Dictionary, Server};

    struct Od(BTreeMap<(u16, u8), Vec<u8>>);

    impl Dictionary for Od {
        fn upload(&mut self, i: u16, s: u8) -> Result<Vec<u8>, AbortCode> {
            self.0.get(&(i, s)).cloned().ok_or(AbortCode::NO_OBJECT)
        }
        fn may_download(&mut self, i: u16, s: u8, _: Option<u32>) -> Result<(), AbortCode> {
            self.0.get(&(i, s)).map(|_| ()).ok_or(AbortCode::NO_OBJECT)
        }
        fn download(&mut self, i: u16, s: u8, d: &[u8]) -> Result<(), AbortCode> {
            self.may_download(i, s, None)?;
            self.0.insert((i, s), d.to_vec());
            Ok(())
        }
    }

    /// A node 5 serving `od` on `bus` until `stop`, sending a frame 0x185 between answers.
    fn serve(bus: &MemBus, mut od: Od, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<()> {
        let mut node = bus.node();
        std::thread::spawn(move || {
            let mut server = Server::new();
            let n = NodeId::new(5).unwrap();
            while !stop.load(Ordering::Relaxed) {
                let Ok(f) = node.recv(Instant::now() + Duration::from_millis(2)) else {
                    continue;
                };
                let Ok((to, req)) = ClientRequest::decode(&f) else {
                    continue;
                };
                if to != n {
                    continue;
                }
                let noise = CanFrame::standard(0x185, &[1]).unwrap();
                node.send(&noise, Instant::now()).unwrap();
                if let Some(r) = server.on_request(&req, &mut od) {
                    node.send(&r.encode(n).unwrap(), Instant::now()).unwrap();
                }
            }
        })
    }

    #[test]
    fn reads_and_writes_hand_other_frames_aside() {
        let bus = MemBus::new(1_000_000);
        let stop = Arc::new(AtomicBool::new(false));
        let od = Od(BTreeMap::from([
            ((0x1000, 0), vec![0x92, 1, 2, 0]),
            ((0x1008, 0), b"a longer device name".to_vec()),
        ]));
        let h = serve(&bus, od, stop.clone());
        let mut host = bus.node();
        let n = NodeId::new(5).unwrap();
        let t = Duration::from_millis(200);
        let mut seen = 0;
        let mut count = |_: &mut stride_canbus::MemNode, f: Option<&CanFrame>| {
            if f.is_some_and(|f| f.raw_id() == 0x185) {
                seen += 1;
            }
        };
        assert_eq!(
            sdo_read(&mut host, n, 0x1000, 0, t, &mut count).unwrap(),
            [0x92, 1, 2, 0]
        );
        sdo_write(
            &mut host,
            n,
            0x1008,
            0,
            b"renamed, and long".to_vec(),
            t,
            &mut count,
        )
        .unwrap();
        assert_eq!(
            sdo_read(&mut host, n, 0x1008, 0, t, &mut count).unwrap(),
            b"renamed, and long"
        );
        assert!(seen >= 3, "{seen}");
        let e = sdo_read(&mut host, n, 0x2222, 0, t, &mut ignore).unwrap_err();
        assert!(
            matches!(
                e,
                HostError::Sdo(sdo::SdoError::Aborted {
                    code: AbortCode::NO_OBJECT,
                    ..
                })
            ),
            "{e}"
        );
        // A node that is not there.
        let e = sdo_read(
            &mut host,
            NodeId::new(9).unwrap(),
            0x1000,
            0,
            Duration::from_millis(30),
            &mut ignore,
        )
        .unwrap_err();
        assert_eq!(e, HostError::NoAnswer);
        stop.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }

    #[test]
    fn a_late_answer_to_an_earlier_request_is_not_taken_for_this_ones() {
        // Under load an answer came after its request had timed out, and the next request's
        // exchange took it: "protocol error: answer for another object". An answer that
        // names another object is passed over; this request's own answer is taken.
        let bus = MemBus::new(1_000_000);
        let stop = Arc::new(AtomicBool::new(false));
        let od = Od(BTreeMap::from([((0x1000, 0), vec![0x92, 1, 2, 0])]));
        let h = serve(&bus, od, stop.clone());
        let mut host = bus.node();
        let mut late = bus.node();
        let n = NodeId::new(5).unwrap();
        let stale = ServerResponse::DownloadInitiated {
            index: 0x1400,
            sub: 2,
        };
        late.send(&stale.encode(n).unwrap(), Instant::now())
            .unwrap();
        let t = Duration::from_millis(200);
        assert_eq!(
            sdo_read(&mut host, n, 0x1000, 0, t, &mut ignore).unwrap(),
            [0x92, 1, 2, 0]
        );
        stop.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }

    #[test]
    fn the_heartbeat_keeps_its_period() {
        let bus = MemBus::new(1_000_000);
        let mut host = bus.node();
        let mut watch = bus.node();
        let mut hb = HeartbeatProducer::new(NodeId::new(127).unwrap(), Duration::from_millis(20));
        let t0 = Instant::now();
        for ms in [0u64, 5, 19, 20, 25, 40, 41, 200] {
            hb.poll(&mut host, t0 + Duration::from_millis(ms)).unwrap();
        }
        // Due at 0, 20, 40, then once after the stall to 200 ms.
        assert_eq!(hb.sent(), 4);
        let f = watch
            .recv(Instant::now() + Duration::from_millis(10))
            .unwrap();
        assert_eq!((f.raw_id(), f.data()), (0x77f, &[0x05][..]));
    }
}
