//! In-process tests on `memq://` and `file://`: no network needed.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use lcm::{DecodeError, Decoder, EncodeError, Encoder, Lcm, LogReader, LogWriter, Message};

#[derive(Debug, Clone, PartialEq, Default)]
struct Counter {
    seq: i64,
    text: String,
}

impl Message for Counter {
    const FINGERPRINT: u64 = 0x0123_4567_89ab_cdef;
    const TYPE_NAME: &'static str = "test.counter_t";
    fn body_size(&self) -> usize {
        8 + 4 + self.text.len() + 1
    }
    fn encode_body(&self, e: &mut Encoder<'_>) -> Result<(), EncodeError> {
        e.put_i64(self.seq);
        e.put_str(&self.text)
    }
    fn decode_body(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        Ok(Counter {
            seq: d.get_i64()?,
            text: d.get_string()?,
        })
    }
    fn sequence(&self) -> Option<i64> {
        Some(self.seq)
    }
}

const T: Duration = Duration::from_millis(200);

#[test]
fn memq_typed_round_trip() {
    let lcm = Lcm::new("memq://").unwrap();
    let got = Arc::new(Mutex::new(Vec::new()));
    let g = got.clone();
    let sub = lcm
        .subscribe("COUNT", move |info, m: Counter| {
            assert_eq!(info.channel, "COUNT");
            assert!(info.recv_utime > 0);
            g.lock().unwrap().push(m);
        })
        .unwrap();
    for i in 0..5 {
        lcm.publish(
            "COUNT",
            &Counter {
                seq: i,
                text: format!("n{i}"),
            },
        )
        .unwrap();
    }
    assert_eq!(lcm.handle_pending().unwrap(), 5);
    let got = got.lock().unwrap();
    assert_eq!(got.len(), 5);
    assert_eq!(got[3].text, "n3");
    assert_eq!(sub.stats().received, 5);
    assert_eq!(lcm.stats().published, 5);
}

#[test]
fn raw_subscription_with_regex_and_unsubscribe_on_drop() {
    let lcm = Lcm::new("memq://").unwrap();
    let n = Arc::new(AtomicUsize::new(0));
    let n2 = n.clone();
    let sub = lcm
        .subscribe_raw("CAN_.*", move |_, data| {
            assert_eq!(data, b"abc");
            n2.fetch_add(1, Ordering::SeqCst);
        })
        .unwrap();
    lcm.publish_raw("CAN_LEFT", b"abc").unwrap();
    lcm.publish_raw("CAN_RIGHT", b"abc").unwrap();
    lcm.publish_raw("XCAN_LEFT", b"abc").unwrap(); // anchored: no match
    lcm.handle_pending().unwrap();
    assert_eq!(n.load(Ordering::SeqCst), 2);
    drop(sub);
    lcm.publish_raw("CAN_LEFT", b"abc").unwrap();
    lcm.handle_pending().unwrap();
    assert_eq!(n.load(Ordering::SeqCst), 2);
}

#[test]
fn bad_url_is_a_clear_error() {
    let err = Lcm::new("bogus://nowhere").unwrap_err();
    let text = err.to_string();
    assert!(text.contains("bogus://nowhere"), "{text}");
    assert!(Lcm::new("udpm://1.2.3.4:notaport?ttl=0").is_err());
}

#[test]
fn bad_channel_names_are_refused() {
    let lcm = Lcm::new("memq://").unwrap();
    assert!(lcm.publish_raw(&"x".repeat(64), b"").is_err());
    assert!(lcm.publish_raw("", b"").is_err());
    assert!(lcm.subscribe_raw("A\0B", |_, _| {}).is_err());
}

#[test]
fn callback_panic_is_caught_and_counted() {
    let lcm = Lcm::new("memq://").unwrap();
    let seen = Arc::new(AtomicUsize::new(0));
    let s = seen.clone();
    let sub = lcm
        .subscribe_raw("P", move |_, data| {
            s.fetch_add(1, Ordering::SeqCst);
            if data == b"boom" {
                panic!("handler exploded");
            }
        })
        .unwrap();
    lcm.publish_raw("P", b"ok").unwrap();
    lcm.publish_raw("P", b"boom").unwrap();
    lcm.publish_raw("P", b"ok").unwrap();
    assert_eq!(lcm.handle_pending().unwrap(), 3);
    assert_eq!(seen.load(Ordering::SeqCst), 3);
    assert_eq!(sub.stats().handler_panics, 1);
    assert_eq!(sub.stats().received, 2);
    assert_eq!(lcm.stats().handler_panics, 1);
}

#[test]
fn undecodable_bytes_are_counted_and_good_messages_still_arrive() {
    let lcm = Lcm::new("memq://").unwrap();
    let got = Arc::new(AtomicUsize::new(0));
    let g = got.clone();
    let sub = lcm
        .subscribe("C", move |_, _m: Counter| {
            g.fetch_add(1, Ordering::SeqCst);
        })
        .unwrap();
    let good = Counter {
        seq: 0,
        text: "x".into(),
    }
    .encode()
    .unwrap();
    lcm.publish_raw("C", &good).unwrap();
    lcm.publish_raw("C", b"garbage!").unwrap(); // wrong fingerprint
    lcm.publish_raw("C", &good[..good.len() - 1]).unwrap(); // truncated
    lcm.publish_raw("C", &[]).unwrap(); // empty
    let mut good1 = Counter {
        seq: 1,
        text: "y".into(),
    }
    .encode()
    .unwrap();
    lcm.publish_raw("C", &good1).unwrap();
    good1.push(0);
    lcm.publish_raw("C", &good1).unwrap(); // trailing byte
    lcm.handle_pending().unwrap();
    assert_eq!(got.load(Ordering::SeqCst), 2);
    let st = sub.stats();
    assert_eq!(st.decode_errors, 4);
    assert_eq!(st.received, 2);
    assert_eq!(st.lost, 0);
}

#[test]
fn sequence_gaps_are_counted_as_lost() {
    let lcm = Lcm::new("memq://").unwrap();
    let sub = lcm.subscribe("S", |_, _m: Counter| {}).unwrap();
    for seq in [0, 1, 4, 5, 9] {
        lcm.publish(
            "S",
            &Counter {
                seq,
                text: "".into(),
            },
        )
        .unwrap();
    }
    lcm.handle_pending().unwrap();
    assert_eq!(sub.stats().lost, 2 + 3);
    assert_eq!(lcm.stats().lost, 5);
}

fn publish_seqs(lcm: &Lcm, channel: &str, seqs: impl IntoIterator<Item = i64>) {
    for seq in seqs {
        let text = String::new();
        lcm.publish(channel, &Counter { seq, text }).unwrap();
    }
}

#[test]
fn a_sequence_jump_beyond_i64_is_delivered_not_a_handler_panic() {
    let lcm = Lcm::new("memq://").unwrap();
    let sub = lcm.subscribe("J", |_, _m: Counter| {}).unwrap();
    publish_seqs(&lcm, "J", [i64::MIN, i64::MAX, -1, i64::MAX / 2]);
    lcm.handle_pending().unwrap();
    let st = sub.stats();
    assert_eq!(
        (st.received, st.handler_panics, st.lost),
        (4, 0, 0),
        "{st:?}"
    );
    assert_eq!(st.sequence_streams, 4);
}

#[test]
fn a_log_replay_beside_live_traffic_is_not_counted_lost() {
    let lcm = Lcm::new("memq://").unwrap();
    let sub = lcm.subscribe("LIVE", |_, _m: Counter| {}).unwrap();
    sub.set_queue_capacity(0).unwrap();
    publish_seqs(&lcm, "LIVE", 701_000..701_100);
    // A replay from 0 joins the live publisher; then a third starts at 0 (a restarted process),
    // and each of the three skips some numbers.
    publish_seqs(&lcm, "LIVE", (0..50).flat_map(|i| [i, 701_100 + i]));
    publish_seqs(&lcm, "LIVE", [0, 52, 2, 701_152, 3, 53]);
    lcm.handle_pending().unwrap();
    let st = sub.stats();
    assert_eq!(st.lost, 2 + 2 + 1, "{st:?}");
    assert_eq!(st.sequence_streams, 3);
    assert_eq!(lcm.stats().lost, st.lost);
    assert_eq!(lcm.stats().sequence_streams, 3);
}

#[test]
fn dropping_a_subscription_inside_its_callback_is_deferred_safely() {
    let lcm = Lcm::new("memq://").unwrap();
    let slot: Arc<Mutex<Option<lcm::Subscription>>> = Arc::default();
    let s2 = slot.clone();
    let n = Arc::new(AtomicUsize::new(0));
    let n2 = n.clone();
    let sub = lcm
        .subscribe_raw("D", move |_, _| {
            n2.fetch_add(1, Ordering::SeqCst);
            s2.lock().unwrap().take(); // drops the subscription from inside its own callback
        })
        .unwrap();
    *slot.lock().unwrap() = Some(sub);
    lcm.publish_raw("D", b"1").unwrap();
    lcm.publish_raw("D", b"2").unwrap();
    lcm.handle_pending().unwrap();
    assert_eq!(n.load(Ordering::SeqCst), 1);
}

#[test]
fn publisher_works_from_other_threads() {
    let lcm = Lcm::new("memq://").unwrap();
    let n = Arc::new(AtomicUsize::new(0));
    let n2 = n.clone();
    let _sub = lcm
        .subscribe_raw("T", move |_, _| {
            n2.fetch_add(1, Ordering::SeqCst);
        })
        .unwrap();
    let threads: Vec<_> = (0..4)
        .map(|_| {
            let p = lcm.publisher();
            std::thread::spawn(move || {
                for _ in 0..10 {
                    p.publish_raw("T", b"x").unwrap();
                }
            })
        })
        .collect();
    for t in threads {
        t.join().unwrap();
    }
    lcm.handle_pending().unwrap();
    assert_eq!(n.load(Ordering::SeqCst), 40);
}

#[test]
fn lcm_moves_to_another_thread() {
    let lcm = Lcm::new("memq://").unwrap();
    let n = Arc::new(AtomicUsize::new(0));
    let n2 = n.clone();
    let sub = lcm
        .subscribe_raw("M", move |_, _| {
            n2.fetch_add(1, Ordering::SeqCst);
        })
        .unwrap();
    let p = lcm.publisher();
    let h = std::thread::spawn(move || {
        while !lcm.handle_timeout(T).unwrap() {}
        lcm
    });
    p.publish_raw("M", b"x").unwrap();
    let lcm = h.join().unwrap();
    assert_eq!(n.load(Ordering::SeqCst), 1);
    drop(sub);
    drop(lcm);
    // The publisher outlives the instance handle and still works.
    p.publish_raw("M", b"x").unwrap();
}

#[test]
fn fileno_becomes_readable() {
    let lcm = Lcm::new("memq://").unwrap();
    let _sub = lcm.subscribe_raw("F", |_, _| {}).unwrap();
    lcm.publish_raw("F", b"x").unwrap();
    let mut pfd = libc_pollfd(lcm.fileno());
    // SAFETY: one valid pollfd.
    let rc = unsafe { poll(&mut pfd, 1, 1000) };
    assert_eq!(rc, 1);
    assert!(lcm.handle_timeout(T).unwrap());
}

#[repr(C)]
struct PollFd {
    fd: i32,
    events: i16,
    revents: i16,
}
fn libc_pollfd(fd: i32) -> PollFd {
    PollFd {
        fd,
        events: 1, // POLLIN
        revents: 0,
    }
}
extern "C" {
    fn poll(fds: *mut PollFd, n: u64, timeout: i32) -> i32;
}

#[test]
fn handle_timeout_times_out() {
    let lcm = Lcm::new("memq://").unwrap();
    let _sub = lcm.subscribe_raw("NONE", |_, _| {}).unwrap();
    let t0 = std::time::Instant::now();
    assert!(!lcm.handle_timeout(Duration::from_millis(20)).unwrap());
    assert!(t0.elapsed() >= Duration::from_millis(15));
}

#[test]
fn log_write_then_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.lcmlog");
    let mut w = LogWriter::create(&path).unwrap();
    for i in 0..10i64 {
        let n = w
            .write(
                1_000_000 + i,
                &format!("CH{}", i % 3),
                &vec![i as u8; i as usize * 100],
            )
            .unwrap();
        assert_eq!(n, i);
    }
    drop(w);
    let events: Vec<_> = LogReader::open(&path).unwrap().collect();
    assert_eq!(events.len(), 10);
    assert_eq!(events[7].channel, "CH1");
    assert_eq!(events[7].timestamp, 1_000_007);
    assert_eq!(events[7].data, vec![7u8; 700]);
    let mut r = LogReader::open(&path).unwrap();
    r.seek_to_timestamp(1_000_005).unwrap();
    assert!(r.read_event().unwrap().timestamp >= 1_000_004);
    assert!(LogReader::open(dir.path().join("missing.lcmlog")).is_err());
}

#[test]
fn file_provider_records_and_replays() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rec.lcmlog");
    {
        let w = Lcm::new(&format!("file://{}?mode=w", path.display())).unwrap();
        for seq in 0..3 {
            w.publish(
                "REC",
                &Counter {
                    seq,
                    text: "r".into(),
                },
            )
            .unwrap();
        }
    }
    let r = Lcm::new(&format!("file://{}?speed=0", path.display())).unwrap();
    let got = Arc::new(Mutex::new(Vec::new()));
    let g = got.clone();
    let _s = r
        .subscribe("REC", move |_, m: Counter| g.lock().unwrap().push(m.seq))
        .unwrap();
    while r.handle().is_ok() {}
    assert_eq!(*got.lock().unwrap(), vec![0, 1, 2]);
}

#[test]
fn queue_capacity_and_size() {
    let lcm = Lcm::new("memq://").unwrap();
    let sub = lcm.subscribe_raw("Q", |_, _| {}).unwrap();
    sub.set_queue_capacity(100).unwrap();
    for _ in 0..3 {
        lcm.publish_raw("Q", b"x").unwrap();
    }
    // liblcm 1.4 and newer can tell the queue size (memq:// keeps its own queue and says 0);
    // Debian's 1.3.1 cannot.
    if lcm::HAS_QUEUE_SIZE {
        assert!(sub.queue_size().is_some());
    } else {
        assert_eq!(sub.queue_size(), None);
    }
    assert_eq!(lcm.handle_pending().unwrap(), 3);
}
