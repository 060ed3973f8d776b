//! stride-usb2can as a process, on a pty to the fake dongle with an echo node behind it: a
//! flood from LCM faster than the wire is dropped and counted (queue full, too old) rather than
//! sent late, every frame is accounted for in `can_bus_status_t`, a batch with a bad frame in
//! it still gets its good frames through, and once the flood is over the gateway answers at
//! once (an SDO to the drive behind it).

use std::sync::{Arc, Mutex};
use std::time::Duration;

use lcm::now_utime;
use lcm::Lcm;
use stride_can::CanFrame;
use stride_can_lcm::{batch, frame_to_msg};
use stride_canopen::frame::NodeId;
use stride_lcmtypes::stride::{CanBusStatusT, CanFrameBatchT, CanFrameT, HeaderT};
use stride_tests::{handle_until, pty_rig, require_sandbox, udpm_url, usb2can};

const QUEUE: usize = 1000;
const MAX_AGE_MS: u64 = 50;

fn send(lcm: &Lcm, frames: &[CanFrameT]) {
    lcm.publish("CAN_FLOOD_TX", &batch("flood", HeaderT::default(), frames))
        .unwrap();
}

fn frame(id: u16, data: &[u8]) -> CanFrameT {
    frame_to_msg(&CanFrame::standard(id, data).unwrap(), now_utime())
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn a_flood_from_lcm_is_dropped_and_counted_never_sent_late_and_the_gateway_answers_after_it() {
    require_sandbox();
    let url = udpm_url(7791);
    let dir = tempfile::tempdir().unwrap();
    let (_rig, pty) = pty_rig(dir.path(), "fake-can-rig", &["--nodes", "1", "--echo"]);
    let dump = dir.path().join("candump.log");
    let (queue, age) = (QUEUE.to_string(), MAX_AGE_MS.to_string());
    let extra = ["--queue", &queue, "--max-age-ms", &age];
    let gateway = usb2can(&url, "flood", &pty, &dump, &extra);
    let lcm = Lcm::new(&url).unwrap();
    let rx: Arc<Mutex<Vec<CanFrame>>> = Arc::default();
    let status: Arc<Mutex<Vec<CanBusStatusT>>> = Arc::default();
    let (r, s) = (rx.clone(), status.clone());
    let _subs = (
        lcm.subscribe("CAN_FLOOD_RX", move |_, m: CanFrameBatchT| {
            r.lock().unwrap().extend(
                m.frames
                    .iter()
                    .filter_map(|f| stride_can_lcm::msg_to_frame(f).ok()),
            )
        })
        .unwrap(),
        lcm.subscribe("CAN_FLOOD_STATUS", move |_, m: CanBusStatusT| {
            s.lock().unwrap().push(m)
        })
        .unwrap(),
    );
    let echoed = |id: u32| rx.lock().unwrap().iter().any(|f| f.raw_id() == id);
    // The gateway is up when the echo node answers through it.
    let up = handle_until(&lcm, Duration::from_secs(10), || {
        if !echoed(0x6a1) {
            send(&lcm, &[frame(0x6a0, &[1])]);
        }
        echoed(0x6a1)
    });
    assert!(up, "no echo through the gateway");
    // The counters from before the flood: a status sent after the probes above settled.
    handle_until(&lcm, Duration::from_millis(300), || false);
    let seen = status.lock().unwrap().len();
    let fresh = handle_until(&lcm, Duration::from_secs(3), || {
        status.lock().unwrap().len() > seen
    });
    assert!(fresh, "no CAN_FLOOD_STATUS");
    let before = status.lock().unwrap().last().cloned().unwrap();
    assert_eq!(before.queue_depth, 0, "{before:?}");

    // The flood: 60 000 frames in about two seconds, over three times what the wire carries;
    // each frame carries its batch's number.
    let mut flood = 0;
    let mut published = Vec::new();
    for i in 0..600u16 {
        let frames: Vec<_> = (0..100u16)
            .map(|k| {
                let [a, b] = i.to_le_bytes();
                frame(0x123, &[a, b, k as u8, 0, 0, 0, 0, 0])
            })
            .collect();
        flood += frames.len() as i64;
        published.push(now_utime());
        send(&lcm, &frames);
        lcm.handle_timeout(Duration::from_millis(3)).unwrap();
    }
    // Once the flood is over, a bad frame between two good ones: the good ones go out, the
    // bad one is counted.
    handle_until(&lcm, Duration::from_millis(4 * MAX_AGE_MS), || false);
    let mut bad = frame(0x6a4, &[9]);
    bad.dlc = 9;
    send(&lcm, &[frame(0x6a2, &[2]), bad, frame(0x6a6, &[3])]);
    let answered = handle_until(&lcm, Duration::from_secs(5), || {
        echoed(0x6a3) && echoed(0x6a7)
    });
    assert!(answered, "the good frames beside a bad one were not sent");
    let drained = handle_until(&lcm, Duration::from_secs(5), || {
        status
            .lock()
            .unwrap()
            .last()
            .is_some_and(|s| s.queue_depth == 0 && s.invalid > before.invalid)
    });
    assert!(drained, "the send queue did not drain after the flood");
    let after = status.lock().unwrap().last().cloned().unwrap();
    let to_wire = after.to_wire - before.to_wire;
    let full = after.dropped_queue_full - before.dropped_queue_full;
    let stale = after.dropped_stale - before.dropped_stale;
    assert!(full > 0, "a full queue refused nothing: {after:?}");
    assert!(stale > 0, "no frame was dropped for its age: {after:?}");
    assert_eq!(after.invalid - before.invalid, 1, "{after:?}");
    // Every frame accounted for: sent, dropped with its reason, or handed to the dongle and
    // not confirmed in time (counted, never sent again; a busy machine can delay the ack).
    let unconfirmed = after.send_errors - before.send_errors;
    assert_eq!(to_wire + full + stale + unconfirmed, flood + 2, "{after:?}");
    assert_eq!(after.queue_capacity as usize, QUEUE);
    assert_eq!(after.max_age_ms as u64, MAX_AGE_MS);
    // After the flood the gateway answers: an SDO read of the drive behind it, sent again
    // when unanswered as a master does (twice at most, as the Elmo master's sdo_retries): a
    // gateway held up by a loaded machine drops a request older than its age bound, as it
    // should, rather than send it late.
    let mut bus = stride_can_lcm::LcmBus::new(&lcm, "flood").unwrap();
    let device_type = (0..3)
        .find_map(|_| {
            stride_canopen_host::sdo_read(
                &mut bus,
                NodeId::new(1).unwrap(),
                0x1000,
                0,
                Duration::from_millis(500),
                &mut stride_canopen_host::ignore,
            )
            .ok()
        })
        .expect("an SDO after the flood is answered");
    assert_eq!(device_type.len(), 4);
    drop(bus);
    let (st, out) = gateway.interrupt();
    assert!(st.success(), "{out}");
    assert!(out.contains("dropped"), "{out}");
    // Nothing was sent late: by the gateway's log of the wire, every flood frame went out
    // within its age bound of its publication, the stamp it carries (with as much again for
    // its way to the dongle; sent in arrival order, the flood's last frames would have waited
    // seconds).
    let log = std::fs::read_to_string(&dump).unwrap();
    let mut logged = 0;
    let mut worst = 0;
    for (t, _, f) in log.lines().filter_map(stride_can::dump::parse) {
        if f.raw_id() == 0x123 {
            let i = u16::from_le_bytes([f.data()[0], f.data()[1]]) as usize;
            worst = worst.max(t - published[i]);
            logged += 1;
        }
    }
    assert_eq!(logged, to_wire - 2, "the log and the status disagree");
    assert!(
        worst <= 2 * MAX_AGE_MS as i64 * 1000,
        "a frame went out {worst} µs after it was published"
    );
}
